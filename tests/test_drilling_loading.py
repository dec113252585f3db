"""The friction loading of a compressed string (rodcont.drilling._loaded_gradually): raised under the softer law
RAMP_EPS and stiffened to the well's at the full load, it reaches the equilibrium the wall's own law reaches
raised the same way (the path it replaced: ~27 damped Newton iterations a step instead of five)."""

import os

import numpy as np
import pytest

from rodcont import drilling
from rodcont.ends import hook_load
from rodcont.loads import Operation

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "examples")


def test_the_softer_laws_loading_reaches_the_wall_laws_equilibrium(monkeypatch):
    # the 2875 m slack-off of well_s3d, whose straight start fails, on 300 subintervals (the CLI's at N 2412)
    well = drilling.Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    placed = drilling.place_string(well, string, 2875.0)
    from rodcont.loads import Friction
    P = drilling.build_system(placed, None, 0.0, 0.0, well.eps, 300, 5).model.contact_scale
    solved, raised, raise_load, build = {}, [], drilling._raise_load, drilling.build_system
    monkeypatch.setattr(drilling, "_raise_load", lambda *a: raised.append(a[2]) or raise_load(*a))
    # one system scaled in place: a system built per step of the load made the 3000 m slack-off discretise 19
    # times instead of 7 (README)
    ramping = [False]
    monkeypatch.setattr(drilling, "build_system", lambda *a, **k: pytest.fail("a system built per step of the load")
                        if ramping[0] else build(*a, **k))
    for ramp in (drilling.RAMP_EPS, well.eps):
        monkeypatch.setattr(drilling, "RAMP_EPS", ramp)
        friction = Friction(0.25, placed.radius, Operation.named("slack-off"))
        sysm = drilling.build_system(placed, friction, 0.0, 0.0, well.eps, 300, 5, force_scale=P)
        ramping[0] = True
        s, x = drilling._loaded_gradually(sysm, friction, 1e-10)
        ramping[0] = False
        # the ramp scaled the one system in place: its law, friction factor and bit loads are its own again
        assert s is sysm and s.model.wall.eps == well.eps and friction.mu(1000.0) == 0.25
        solved[ramp] = (hook_load(s.model, s.disc, x, s.base), x)
    assert raised == [1e-3, well.eps]   # each path its own law, no fallback from the softer one
    (soft, xs), (own, xo) = solved.values()
    assert soft == pytest.approx(own, rel=1e-10)
    assert np.max(np.abs(xs - xo)) <= 1e-10 * np.max(np.abs(xo))


def _slack_2875():
    well = drilling.Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    placed, op = drilling.place_string(well, string, 2875.0), Operation.named("slack-off")
    return placed, op, well.eps


def _recorded_homotopies(monkeypatch):
    import rodcont.drivers.solve as solve_driver
    calls, homotopy = [], solve_driver._homotopy
    monkeypatch.setattr(solve_driver, "_homotopy", lambda s, x, p, tol, stages, confirm: calls.append(
        (s.disc.N, stages[0])) or homotopy(s, x, p, tol, stages, confirm))
    return calls


def test_a_cold_start_whose_softest_law_fails_on_the_coarse_mesh_raises_the_load_without_retrying_it(monkeypatch):
    from rodcont.drivers.solve import ConvergenceError
    from rodcont.loads import Friction
    placed, op, eps = _slack_2875()
    friction = Friction(0.25, placed.radius, op)
    calls = _recorded_homotopies(monkeypatch)
    with np.errstate(all="ignore"):
        s, x = drilling._cold_start(placed, friction, 0.0, 0.0, eps, 300, 5, None, 1e-10)
        assert calls[0] == (159, 0.1) and (300, 0.1) not in calls   # the coarse mesh's softest stage failed
        assert s.model.wall.eps == eps and np.max(np.abs(s.disc.residual(x, s.base))) < 1e-6
        # what the skip spares: the same soft law from the same guess on the mesh itself fails as well
        sysm = drilling.build_system(placed, friction, 0.0, 0.0, eps, 300, 5)
        with pytest.raises(ConvergenceError, match="eps = 0.1"):
            drilling.settle(sysm, sysm.model.initial_guess(sysm.disc, 0.0), 1e-10, coarsen=1)


def test_where_the_load_cannot_be_raised_the_cold_start_runs_the_homotopy_it_skipped(monkeypatch):
    from rodcont.drivers.solve import ConvergenceError
    from rodcont.loads import Friction
    placed, op, eps = _slack_2875()

    def fails(*a):
        raise ConvergenceError("no equilibrium with the load raised")
    monkeypatch.setattr(drilling, "_loaded_gradually", fails)
    calls = _recorded_homotopies(monkeypatch)
    with np.errstate(all="ignore"), pytest.raises(ConvergenceError, match="eps = 0.1"):
        drilling._cold_start(placed, Friction(0.25, placed.radius, op), 0.0, 0.0, eps, 300, 5, None, 1e-10)
    assert calls == [(159, 0.1), (300, 0.1)]


def test_a_load_ramp_that_fails_leaves_its_system_as_it_was(monkeypatch):
    # the ramp scales the friction factor, the bit's loads and the law of the one system in place: a failed step
    # must not leave a fraction of them behind for the fallback that follows (_cold_start's homotopy on the mesh)
    from rodcont.collocation import Collocation
    from rodcont.drivers.solve import ConvergenceError
    from rodcont.linalg import NewtonResult
    from rodcont.loads import Friction
    placed, op, eps = _slack_2875()
    friction = Friction(0.25, placed.radius, op)
    sysm = drilling.build_system(placed, friction, -2.0e4, 500.0, eps, 300, 5)
    before = (sysm.base.copy(), friction.mu_table, sysm.model.wall)
    monkeypatch.setattr(drilling, "settle", lambda s, x, tol, **kw: x)  # at no load: the guess, as it is
    monkeypatch.setattr(Collocation, "newton", lambda self, x, p, **kw: NewtonResult(x, False, 1, 1.0, 1.0, "refused"))
    with np.errstate(all="ignore"), pytest.raises(ConvergenceError, match="raised from 0 past 0 of theirs"):
        drilling._raise_load(sysm, friction, 1e-3, 1e-10, 0.25)
    assert np.array_equal(sysm.base, before[0]) and friction.mu_table is before[1] and sysm.model.wall is before[2]
    names = sysm.model.param_names
    assert sysm.base[names.index("T")] == -2.0e4 and sysm.base[names.index("torque")] == -500.0
