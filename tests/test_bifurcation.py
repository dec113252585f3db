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
    res = continuation(InLam(two, 0.0), np.zeros(two.disc.size), 0.0,
                       ContinuationSettings(ds=0.2, ds_max=0.5, p_max=3.6, max_steps=60), param="lam")
    fold = res.point("F1")
    fp = FoldProblem(two, fold["x"], fold["lam"], 0.0, v0=fold["direction"][0])
    assert abs(fp.test_function(fold["x"], fold["lam"], 0.0)) < 1e-8
    X0 = np.append(fold["x"], fold["lam"])
    s = ContinuationSettings(ds=0.1, ds_max=0.3, p_min=-1.0, p_max=1.0, max_steps=80, forced=(-0.5, 0.5),
                             detect_folds=False, detect_branch_points=False)
    for direction in (1, -1):
        s.direction = direction
        res2 = continuation(fp, X0, 0.0, s, param="a")
        assert "bound" in res2.stop_reason and res2.status == "bound"
        assert len(res2) > 3
        for X, a in zip(res2.coefficients, res2.table["a"]):
            assert X[-1] == pytest.approx(bratu_exact_fold() * math.exp(-a), abs=1e-9), a
        assert any(sp.kind == "forced" for sp in res2.special)


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
    res = continuation(el, np.zeros(el.disc.size), 1.0, s, param="lam")
    assert len(res.branch_points) == 1
    bp = res.point("BP1")
    assert bp["lam"] == pytest.approx(math.pi**2, abs=1e-8)
    tr = Tracker(el, bp["x"], bp["lam"], s)
    _, J, (Fp,) = el.disc.linearise(bp["x"], [bp["lam"]], [0])
    tx, tp = bifurcating_direction(J, Fp, *bp["direction"], tr.wx, tr.wp)
    # the new direction is orthogonal to the trivial branch and points into u != 0
    assert abs(tp) < 1e-6 and np.max(np.abs(el.disc.evaluate(tx, np.linspace(0, 1, 11), 0))) > 0
    s2 = ContinuationSettings(ds=0.1, ds_max=0.5, p_min=0.0, p_max=14.0, max_steps=40, detect_branch_points=False)
    new = continuation(el, bp["x"], bp["lam"], s2, tangent0=(tx, tp), exact_start=True, param="lam")
    assert len(new) > 10
    amp = []
    for x, lam in list(zip(new.coefficients, new.table["lam"]))[3:]:
        umid = float(el.disc.evaluate(x, 0.5, 0))
        amp.append(abs(umid))
        assert lam == pytest.approx(4 * ellipk(math.sin(umid / 2) ** 2) ** 2, abs=1e-8)
    assert max(amp) > 1.0  # well onto the buckled branch
