"""Issue 24, the first trace's cost: events counted, not clocks (sparse LU factorisations of every kind).

The corrector takes chord steps on each Newton factorisation before the next one, so the factorisation that
gives a regular point's tangent comes one Newton step sooner; a special point is located starting from the
step's end (on its factorisation), not a whole step back from the base. Both are checked on a problem with a
closed form (Bratu's) and on the Gamma = 1 branch, whose fold is the independent Lagrangian reference's.
"""

import json
import math
import os
import sys

import numpy as np
import pytest
import scipy.sparse.linalg as spla

import rodcont
import rodcont.continuation as cont
from rodcont.continuation import ContinuationSettings, Tracker
from rodcont.result import Status

sys.path.insert(0, os.path.dirname(__file__))
from test_continuation import Bratu, bratu_exact_fold  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
with open(os.path.join(ROOT, "tests", "data", "lagrangian_folds.json")) as fh:
    PRIMARY = {r["gamma"]: r for r in json.load(fh)["primary_folds"]}

#: every sparse LU of rodcont.trace(1.0) to the validity guard: 163 at 0ee0293 (and before this change)
MAX_LU_GAMMA1 = 145


def _bratu_lambda(theta):
    """Bratu's branch in closed form: u = -2 log(cosh((x - 1/2) theta / 2) / cosh(theta / 4)) at
    lambda = theta^2 / (2 cosh^2(theta / 4))."""
    return theta**2 / (2.0 * math.cosh(theta / 4.0) ** 2)


def test_a_long_bratu_step_takes_three_factorisations_not_five():
    """From lambda = 0 a step of 2.5 (the chord on the base's matrix breaks off at contraction 0.57): Newton with
    chord steps on each factorisation converges with 3 factorisations (Newton alone took 5) onto Bratu's branch."""
    pb = Bratu()
    tr = Tracker(pb, np.zeros(pb.disc.size), 0.0, ContinuationSettings(ds=0.1, ds_max=5.0))
    base = tr.start()
    base.solver = tr._tangent_at(base.x, base.p, base.tx, base.tp)[4]
    before = tr.factorisations
    pt, info = tr._correct(base, 2.5)
    assert pt is not None and info["chord_after_newton"] > 0
    assert tr.factorisations - before <= 3
    F = pb.residual(pt.x, pt.p)
    assert np.max(np.abs(F)) <= 1e-10 * (1 + pt.p)
    # on the closed-form branch: theta from u(1/2) = 2 log cosh(theta / 4), its lambda the point's
    u_mid = float(pb.disc.evaluate(pt.x, 0.5, 0))
    theta = 4.0 * math.acosh(math.exp(u_mid / 2.0))
    assert pt.p == pytest.approx(_bratu_lambda(theta), abs=1e-8)
    assert pt.p < bratu_exact_fold()


def test_a_chord_step_that_does_not_contract_is_not_taken():
    """``_chord_on`` returns the point it was given when the first chord step is not below CHORD_RATE of the
    Newton step before it (a matrix from too far away), and stops at the first step below ``accept``."""
    pb = Bratu()
    tr = Tracker(pb, np.zeros(pb.disc.size), 0.0, ContinuationSettings(ds=0.1))
    base = tr.start()
    lu = tr._tangent_at(base.x, base.p, base.tx, base.tp)[4]
    y = np.append(base.x + 2.5 * base.tx, base.p + 2.5 * base.tp)  # far from the base: its matrix is a poor chord
    same, prev, steps = tr._chord_on(lu, y, base, 2.5, 1e-12, 1e-6)
    assert steps == 0 and prev == 1e-12 and same is y
    near = np.append(base.x + 1e-3 * base.tx, base.p + 1e-3 * base.tp)
    done, prev, steps = tr._chord_on(lu, near, base, 1e-3, 1.0, 1e-6)
    assert steps >= 1 and prev <= 1e-6 * (1 + tr._ymax(done))


def test_the_gamma1_trace_to_the_guard_makes_at_most_145_factorisations(monkeypatch):
    """Every sparse LU of the first Gamma = 1 trace to the validity guard (steps, locations, error estimates,
    stability counts; not the remesh's transfer, 6 small ones): 163 at 0ee0293, 140 now. The validity guard is
    located from the step's end with at most 4 factorisations (6 from the base). The fold is the Lagrangian
    reference's (to its 1e-6)."""
    count = {"lu": 0, "guard": 0}
    orig, locate = spla.splu, cont.Tracker.locate

    def splu(*args, **kwargs):
        # not the remesh's transfer (its normal equations, solved by spsolve at 0ee0293, uncounted there)
        if sys._getframe(1).f_code.co_name != "_transfer_parts":
            count["lu"] += 1
        return orig(*args, **kwargs)

    def counted_locate(self, base, ds_hi, g, g0, g1, tol, kind, *args, **kwargs):
        before = self.factorisations
        out = locate(self, base, ds_hi, g, g0, g1, tol, kind, *args, **kwargs)
        if kind == "event:validity_guard":
            count["guard"] += self.factorisations - before
        return out

    monkeypatch.setattr(spla, "splu", splu)
    monkeypatch.setattr(cont.Tracker, "locate", counted_locate)
    br = rodcont.trace(1.0)
    assert br.status == Status.VALIDITY_GUARD
    assert 0 < count["lu"] <= MAX_LU_GAMMA1, count
    assert 0 < count["guard"] <= 4, count
    ref = PRIMARY[1.0]
    assert len(br.folds) == 1
    for name in ("phi_L", "stretch", "torque", "l0"):
        assert br.folds[0][name] == pytest.approx(ref[name], abs=1e-6), name


def test_the_error_estimate_reads_lengths_and_torque_without_the_output_grids():
    """The richer twin's stretch, l0 and torque (rod.integral_outputs) are the outputs' own, to the bit, on the
    coarse and the richer mesh of a point past the Gamma = 1 fold; estimating builds no output grids there."""
    from rodcont.mesh import ErrorEstimator
    from rodcont.system import point_system
    br = rodcont.trace(1.0, stretch_max=0.2)
    i = len(br) - 1
    s = point_system(br, i)
    x, value = s.expanded(br.point(i)["x"]), float(br.table["phi_L"][i])
    est = ErrorEstimator(s)
    assert est.estimate(x, value, (np.asarray(br.tangents[i][:-1]), float(br.tangents[i][-1]))) < 1e-6
    assert getattr(est.fine.disc, "_rod_outputs", None) is None
    for system, y in ((s, x), (est.fine, est._to_fine(x))):
        p = system.params(value)
        o = system.model.outputs(system.disc, y, p)
        assert system.model.integral_outputs(system.disc, y, p) == (o["stretch"], o["l0"], o["torque"])
