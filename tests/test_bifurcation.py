"""Fold curves and branch switching on problems with exact answers (generic layer, no rod)."""

import math

import numpy as np
import pytest
from scipy.special import ellipk

from rodcont.bifurcation import FoldProblem, bifurcating_direction
from rodcont.collocation import BVProblem, Collocation
from rodcont.continuation import ContinuationSettings, Tracker, continuation

from test_continuation import bratu_exact_fold


class BratuTwoParam:
    """u'' + lam e^u = 0, u(0) = u(1) = a. The shift u = v + a gives lam e^a = lambda*: the
    fold curve is lam(a) = lambda* e^-a exactly."""

    def __init__(self, N=10, k=5):
        pb = BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                       bc=lambda za, zb, p: np.stack([za[0] - p[1], zb[0] - p[1]]), interval=(0.0, 1.0),
                       params=["lam", "a"])
        self.disc = Collocation(pb, N, k)

    def residual(self, x, lam, a):
        return self.disc.residual(x, [lam, a])

    def tangent(self, x, lam, a):
        _, J, (F1, F2) = self.disc.linearise(x, [lam, a], [0, 1])
        return J, F1, F2


class InLam:
    """The one-parameter slice at fixed a, for the tracker."""

    def __init__(self, two, a):
        self.two, self.a = two, a

    def residual(self, x, lam):
        return self.two.residual(x, lam, self.a)

    def tangent(self, x, lam):
        J, F1, _ = self.two.tangent(x, lam, self.a)
        return J, F1


def test_bratu_fold_curve_is_exact():
    two = BratuTwoParam()
    pts, _ = continuation(InLam(two, 0.0), np.zeros(two.disc.size), 0.0,
                          ContinuationSettings(ds=0.2, ds_max=0.5, p_max=3.6, max_steps=60))
    fold = next(q for q in pts if q.kind == "fold")
    fp = FoldProblem(two, fold.x, fold.p, 0.0, v0=fold.tx)
    assert abs(fp.test_function(fold.x, fold.p, 0.0)) < 1e-8
    X0 = np.append(fold.x, fold.p)
    s = ContinuationSettings(ds=0.1, ds_max=0.3, p_min=-1.0, p_max=1.0, max_steps=80, forced=(-0.5, 0.5),
                             detect_folds=False, detect_branch_points=False)
    for direction in (1, -1):
        s.direction = direction
        pts2, reason = continuation(fp, X0, 0.0, s)
        assert "bound" in reason
        assert len(pts2) > 3
        for q in pts2:
            lam = q.x[-1]
            assert lam == pytest.approx(bratu_exact_fold() * math.exp(-q.p), abs=1e-9), q.p
        assert any(q.kind == "forced" for q in pts2)


class Elastica:
    """u'' + lam sin u = 0, u(0) = u(1) = 0: trivial branch u = 0 with a pitchfork at lam = pi^2.
    On the buckled branch lam = 4 K(k)^2, k = sin(u(1/2) / 2) (half a pendulum period)."""

    def __init__(self, N=16, k=5):
        pb = BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.sin(z[0]),
                       bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"])
        self.disc = Collocation(pb, N, k)

    def residual(self, x, lam):
        return self.disc.residual(x, [lam])

    def tangent(self, x, lam):
        _, J, (F1,) = self.disc.linearise(x, [lam], [0])
        return J, F1


def test_pitchfork_located_and_switched():
    el = Elastica()
    s = ContinuationSettings(ds=0.5, ds_max=1.0, p_min=0.0, p_max=12.0, max_steps=50)
    pts, _ = continuation(el, np.zeros(el.disc.size), 1.0, s)
    bps = [q for q in pts if q.kind == "branch_point"]
    assert len(bps) == 1
    bp = bps[0]
    assert bp.p == pytest.approx(math.pi**2, abs=1e-8)
    tr = Tracker(el, bp.x, bp.p, s)
    _, J, (Fp,) = el.disc.linearise(bp.x, [bp.p], [0])
    tx, tp = bifurcating_direction(J, Fp, bp.tx, bp.tp, tr.wx, tr.wp)
    # the new direction is orthogonal to the trivial branch and points into u != 0
    assert abs(tp) < 1e-6 and np.max(np.abs(el.disc.evaluate(tx, np.linspace(0, 1, 11), 0))) > 0
    s2 = ContinuationSettings(ds=0.1, ds_max=0.5, p_min=0.0, p_max=14.0, max_steps=40, detect_branch_points=False)
    new, reason = continuation(el, bp.x, bp.p, s2, tangent0=(tx, tp), exact_start=True)
    assert len(new) > 10
    amp = []
    for q in new[3:]:
        umid = float(el.disc.evaluate(q.x, 0.5, 0))
        amp.append(abs(umid))
        assert q.p == pytest.approx(4 * ellipk(math.sin(umid / 2) ** 2) ** 2, abs=1e-8)
    assert max(amp) > 1.0  # well onto the buckled branch
