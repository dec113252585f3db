"""The generic tracker on problems with known answers (no rod involved)."""

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq

from rodcont.collocation import BVProblem, Collocation
from rodcont.continuation import ContinuationSettings, Event, continuation
from rodcont.linalg import LU, bordered
from rodcont.result import Status

BRATU_FOLD = 3.513830719125  # lambda* of u'' + lambda e^u = 0, u(0) = u(1) = 0


class Bratu:
    """Bratu's problem on the collocation core, continued in lambda."""

    def __init__(self, N=10, k=5):
        pb = BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                       bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"])
        self.disc = Collocation(pb, N, k)

    def residual(self, x, lam):
        return self.disc.residual(x, [lam])

    def tangent(self, x, lam):
        _, J, (Fp,) = self.disc.linearise(x, [lam], [0])
        return J, Fp

    def u_mid(self, x, lam):
        return {"u_mid": float(self.disc.evaluate(x, 0.5, 0))}


def bratu_exact_fold():
    """lambda* from the closed form: lambda = 8 (t / cosh t)^2 maximal where t tanh t = 1."""
    t = brentq(lambda t: t * math.tanh(t) - 1.0, 0.5, 2.0)
    return 8 * (t / math.cosh(t)) ** 2


def test_bratu_closed_form_matches_published_value():
    assert bratu_exact_fold() == pytest.approx(BRATU_FOLD, abs=1e-12)


def test_bratu_fold_located():
    pb = Bratu()
    s = ContinuationSettings(ds=0.1, ds_max=0.5, p_max=3.6, p_min=-0.1, max_steps=200)
    res = continuation(pb, np.zeros(pb.disc.size), 0.0, s, monitor=pb.u_mid, param="lam",
                       events=[Event("u_mid = 4", lambda q: 4.0 - q.data["u_mid"], stop=True, label="u_mid_4")])
    folds = res.folds
    assert len(folds) == 1 and folds[0]["label"] == "F1"
    assert folds[0]["lam"] == pytest.approx(bratu_exact_fold(), abs=1e-9)
    assert folds["lam"][0] == folds[0]["lam"] and res.point("F1")["lam"] == folds[0]["lam"]
    assert abs(res.tangents[folds[0]["index"]][-1]) < 1e-10
    # the upper branch is reached: u(1/2) grows past the fold and the event stops the trace there
    assert res.stop_reason == "u_mid = 4" and res.status == Status.EVENT
    assert res.table["u_mid"][-1] == pytest.approx(4.0, abs=1e-9)
    end = res.special[-1]
    assert (end.kind, end.label, end.message, end.index) == ("event", "u_mid_4", "u_mid = 4", len(res) - 1)
    assert res.table["kind"][-1] == "event:u_mid_4"
    # the arclength increases along the branch and p turns exactly once
    arc = np.array([a for a, k in zip(res.table["arclength"], res.table["kind"]) if k == "regular"])
    assert np.all(np.diff(arc) > 0)


def test_forced_points_and_bounds():
    pb = Bratu()
    s = ContinuationSettings(ds=0.3, ds_max=0.5, p_max=3.0, max_steps=100, forced=(0.5, 1.25, 2.0))
    res = continuation(pb, np.zeros(pb.disc.size), 0.0, s)
    forced = [sp.value for sp in res.special if sp.kind == "forced"]
    assert forced == pytest.approx([0.5, 1.25, 2.0], abs=1e-12)
    assert [sp.label for sp in res.special if sp.kind == "forced"] == ["P1", "P2", "P3"]
    assert res.table["kind"][-1] == "bound" and res.table["p"][-1] == pytest.approx(3.0, abs=1e-12)
    assert "p_max" in res.stop_reason and res.status == Status.BOUND
    # each forced point solves the problem at that parameter
    for x, p in zip(res.coefficients, res.table["p"]):
        assert np.max(np.abs(pb.residual(x, p))) < 1e-9


class Pitchfork:
    """x^3 - p x = 0 (with a spectator y' s.t. y - p = 0): branch point at p = 0 on the trivial branch."""

    def residual(self, x, p):
        return np.array([x[0] ** 3 - p * x[0], x[1] - p])

    def tangent(self, x, p):
        J = sp.csc_matrix(np.array([[3 * x[0] ** 2 - p, 0.0], [0.0, 1.0]]))
        return J, np.array([-x[0], -1.0])


def test_branch_point_detected_and_located():
    s = ContinuationSettings(ds=0.13, ds_max=0.2, p_min=-1.0, p_max=1.0, max_steps=100)
    res = continuation(Pitchfork(), np.array([0.0, -1.0]), -1.0, s)
    bps = res.branch_points
    assert len(bps) == 1 and res.point("BP1")["index"] == bps[0]["index"]
    assert abs(bps[0]["p"]) < 1e-9 and bps[0]["located"]
    assert not res.folds


def test_det_sign_from_sparse_lu():
    rng = np.random.default_rng(0)
    for _ in range(20):
        A = rng.standard_normal((7, 7))
        sign, log = LU(sp.csc_matrix(A)).det()
        d = np.linalg.det(A)
        assert sign == np.sign(d)
        assert log == pytest.approx(math.log(abs(d)), rel=1e-10)


def test_bordered_matrix():
    rng = np.random.default_rng(1)
    J = sp.random(6, 6, density=0.5, random_state=2, format="csc") + sp.eye(6)
    b, c, d = rng.standard_normal(6), rng.standard_normal(6), 0.7
    A = bordered(J, b, c, d).toarray()
    ref = np.block([[J.toarray(), b[:, None]], [c[None, :], np.array([[d]])]])
    assert np.array_equal(A, ref)


def test_step_size_collapse_is_a_stop_reason_not_an_exception():
    class Nowhere:  # F = x^2 + 1 + p^2 has no real zero: the start fails
        def residual(self, x, p):
            return np.array([x[0] ** 2 + 1 + p * p])

        def tangent(self, x, p):
            return sp.csc_matrix([[2 * x[0]]]), np.array([2 * p])

    res = continuation(Nowhere(), np.array([0.3]), 0.0, ContinuationSettings())
    assert len(res) == 0 and "no convergence at the starting point" in res.stop_reason
    assert res.status == Status.START_FAILED


def test_settings_are_validated():
    with pytest.raises(ValueError):
        ContinuationSettings(ds=-1).validate()
    with pytest.raises(ValueError):
        ContinuationSettings(ds=1.0, ds_max=0.5).validate()


class _Line:
    """``x = p``: the simplest branch, for the event machinery alone."""

    def residual(self, x, p):
        return x - p

    def tangent(self, x, p):
        return sp.identity(1, format="csc"), np.array([-1.0])


def test_an_event_just_ahead_of_the_start_is_located_to_a_reachable_tolerance():
    # g is 1e-9 at the start and about -0.06 a step later: its tolerance is relative to that change,
    # not to 1e-9 (1e-20, below the rounding of g, which the secant used to chase for many iterations)
    calls = []

    def g(q):
        calls.append(q.p)
        return 0.5 + 1e-9 - q.p - 3.0 * (q.p - 0.5) ** 2

    s = ContinuationSettings(ds=0.05, ds_max=0.05, max_steps=10)
    res = continuation(_Line(), np.array([0.5]), 0.5, s, events=[Event("g", g, stop=True)])
    assert res.stop_reason == "g"
    root = 0.5 + (-1.0 + math.sqrt(1.0 + 12e-9)) / 6.0
    assert res.table["p"][-1] == pytest.approx(root, abs=1e-14)
    assert len(calls) <= 9  # 8, and the start's probe one smallest step ahead (Tracker._leaves)


def test_a_residual_at_rounding_is_told_from_a_stagnated_one():
    """The corrector takes a stalled residual for rounding only where every row is within 1e3 times its
    noise (machine epsilon times the size of its terms): a trace in a pipe once stored a point whose residual
    was 2e9 times its noise (its neighbours: 1.3 times). Here: Bratu's solution converged by Newton passes,
    the same solution moved by 1e-9 of its size does not."""
    from rodcont.continuation import _at_rounding
    b = Bratu(N=20)
    x0 = b.disc.project([lambda S: 0.1 * np.sin(np.pi * S)])
    r = b.disc.newton(x0, [2.0])
    assert r.converged
    F, J, (Fp,) = b.disc.linearise(r.x, [2.0], [0])
    assert _at_rounding(F, J, Fp, r.x, 2.0)
    x = r.x * (1 + 1e-9)
    F, J, (Fp,) = b.disc.linearise(x, [2.0], [0])
    assert not _at_rounding(F, J, Fp, x, 2.0)


def test_a_detected_branch_point_whose_location_fails_is_reported_not_dropped(monkeypatch):
    """The determinant changes sign in a step, but no point of the bracket converges (seen on a helix in a
    pipe, where the bordered matrix is singular to rounding near the crossing): the crossing is recorded
    with its bracket and warned of; before, the detector returned nothing and the branch point vanished."""
    from rodcont.continuation import Tracker
    monkeypatch.setattr(Tracker, "locate", lambda self, *a, **k: None)
    s = ContinuationSettings(ds=0.13, ds_max=0.2, p_min=-1.0, p_max=1.0, max_steps=100)
    tr = Tracker(Pitchfork(), np.array([0.0, -1.0]), -1.0, s)
    with pytest.warns(RuntimeWarning, match="branch point between p = .* was detected but could not be located"):
        pts = list(tr)
    assert not [q for q in pts if q.kind == "branch_point"]
    (kind, a, b), = tr.unlocated
    assert kind == "branch_point" and a < 0 < b  # the step across the branch point at p = 0


def test_every_point_is_within_the_tolerance_and_its_tangent_within_near_sqrt_tol():
    """The corrector's contract, checked point by point on Bratu's branch through its fold: each stored
    point is within newton_tol (1 + |y|) of the solution Newton at its own lambda converges to, and its
    tangent within 10 NEAR sqrt(newton_tol) of the unit null vector of [J, F_p] there (the tangent comes
    from the factorisation before the last Newton step, which the corrector takes at NEAR sqrt(tol); a last
    correction with that factorisation checks the point to tol)."""
    from rodcont.continuation import NEAR
    pb = Bratu(N=12)
    s = ContinuationSettings(ds=0.1, ds_max=0.5, p_max=3.6, p_min=-0.1, max_steps=200)
    res = continuation(pb, np.zeros(pb.disc.size), 0.0, s, monitor=pb.u_mid,
                       events=[Event("u_mid = 4", lambda q: 4.0 - q.data["u_mid"], stop=True)])
    regular = [i for i, k in enumerate(res.table["kind"]) if k == "regular"]
    assert len(regular) > 10
    worst_x = worst_t = 0.0
    for i in regular:
        x, p, t0 = res.coefficients[i], res.table["p"][i], res.tangents[i]
        tx, tp = t0[:-1], t0[-1]
        y = np.append(x, p)
        if abs(tp) > 0.05:  # Newton at fixed lambda: regular away from the fold
            r = pb.disc.newton(x, [p], tol=1e-14)
            assert r.converged
            worst_x = max(worst_x, np.max(np.abs(r.x - x)) / (1 + np.max(np.abs(y))))
        F, J, (Fp,) = pb.disc.linearise(x, [p], [0])
        t = LU(bordered(J, Fp, tx, tp)).solve(np.append(np.zeros(x.size), 1.0))
        t /= np.linalg.norm(t) * np.sign(t @ t0)
        worst_t = max(worst_t, np.max(np.abs(t - t0 / np.linalg.norm(t0))))
    assert worst_x <= s.newton_tol
    assert worst_t <= 10 * NEAR * math.sqrt(s.newton_tol)


def test_the_heap_trimmer_trims_only_above_its_size_and_at_most_once_per_interval(monkeypatch):
    """The trace's guard against the C heap's fragmentation (rodcont.linalg.HeapTrimmer): malloc_trim is
    called only while the process holds more than ``above`` bytes, at most once per ``interval``; with
    ``interval=None`` never. (What it saves is a benchmark figure: benchmarks/bench.py, section long.)"""
    import rodcont.linalg as la
    calls = []
    t = la.HeapTrimmer(interval=0.0, above=0)
    if t._trim is None:
        pytest.skip("no malloc_trim in this C library")
    t._trim = lambda pad: calls.append(pad)
    t(), t()
    assert calls == [0, 0]
    big = la.HeapTrimmer(interval=0.0, above=2**62)
    big._trim = t._trim
    big()
    assert calls == [0, 0]
    slow = la.HeapTrimmer(interval=3600.0, above=0)
    slow._trim = t._trim
    slow.last -= 7200.0
    slow(), slow()
    assert calls == [0, 0, 0]
    off = la.HeapTrimmer(interval=None, above=0)
    off._trim = t._trim
    off()
    assert calls == [0, 0, 0]
    assert la.resident_bytes() > 10 * 2**20  # this process, as /proc/self/statm tells it


class Crossing:
    """(x - p^2)(x - 2 p) = 0 (and a spectator y = p): a parabola and a line crossing at p = 0, a branch point
    of each; the parabola is traced from p = -1."""

    def residual(self, x, p):
        return np.array([(x[0] - p * p) * (x[0] - 2 * p), x[1] - p])

    def tangent(self, x, p):
        a, b = x[0] - p * p, x[0] - 2 * p
        return sp.csc_matrix(np.array([[a + b, 0.0], [0.0, 1.0]])), np.array([-2 * p * b - 2 * a, -1.0])


def test_a_branch_point_whose_test_function_jumps_is_bracketed_not_located():
    """At a crossing the corrector near the branch point may land on either branch: the determinant's secant
    search then shrank its bracket to rounding 5e-5 from the crossing (the two sides of the bracket on
    different branches) and called the point located. A continuous test function that jumps is not a zero:
    such a point is now kept as bracketed. Every branch point still called located is within 1e-9 of the
    crossing, and every located point of the trace is on the parabola (exact solution), past the crossing too."""
    reported = 0
    for ds_max in (0.1, 0.3, 0.5):
        s = ContinuationSettings(ds=0.05, ds_max=ds_max, p_min=-1.0, p_max=1.5, max_steps=200)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a crossing detected but not located, warned
            res = continuation(Crossing(), np.array([1.0, -1.0]), -1.0, s)
        # (a bracketed branch point is a point near the crossing on either branch: here on the line, 1e-4 off)
        t = res.table
        assert t["p"][-1] == 1.5 and max(abs(x[0] - p ** 2) for x, p, ok in zip(res.coefficients, t["p"], t["located"])
                                         if ok) < 1e-10
        for bp in res.branch_points:
            reported += 1
            assert not bp["located"] or abs(bp["p"]) < 1e-9, (ds_max, bp["p"])
    assert reported >= 2
