"""The contact homotopy of settle_in_conduit on a coarser mesh (issues 23, 24): fewer factorisations of the mesh's
own Jacobian, the same equilibrium as the homotopy run on the mesh itself."""

import os

import numpy as np
import pytest

import rodcont.drivers.solve as solve_driver
import rodcont.linalg as linalg
from rodcont import drilling
from rodcont.loads import Friction, Operation
from short_well import COLLAR, HOLE, PIPE, STATIONS

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "examples")


@pytest.fixture(scope="module")
def slack_string():
    """The short well's string at 300 m sliding down (mu 0.25: compressed by its friction near the bit), N = 400."""
    placed = drilling.place_string(drilling.Well(STATIONS, hole_diameter=HOLE, friction=0.25),
                                   drilling.DrillString((COLLAR, PIPE), 0.847), 300.0)
    sysm = drilling.build_system(placed, Friction(0.25, placed.radius, Operation.named("slack-off")), 0.0, 0.0,
                                 1e-5, 400)
    return sysm, sysm.model.initial_guess(sysm.disc, 0.0)


def _settled(sysm, guess, monkeypatch, **kw):
    """``(x, sizes)``: the settled state and the size of every Jacobian factorised (rodcont.linalg.LU)."""
    sizes = []

    class Counted(linalg.LU):
        def __init__(self, A, *a, **k):
            sizes.append(A.shape[0])
            super().__init__(A, *a, **k)
    monkeypatch.setattr(linalg, "LU", Counted)
    with np.errstate(all="ignore"):
        x = solve_driver.settle_in_conduit(sysm, guess, sysm.base, 1e-10, factor=10.0, **kw)
    monkeypatch.undo()
    return x, sizes


def _contact(sysm, x):
    return sysm.model.contact(sysm.disc, x, sysm.base)


def test_the_homotopy_on_every_fourth_breakpoint_factorises_the_mesh_twice_as_rarely_for_the_same_equilibrium(
        slack_string, monkeypatch):
    sysm, guess = slack_string
    full, full_sizes = _settled(sysm, guess, monkeypatch, coarsen=1)
    fast, fast_sizes = _settled(sysm, guess, monkeypatch, coarsen=4)
    n = sysm.disc.size
    assert set(full_sizes) == {n}
    # measured: 23 LUs of the 12 022 x 12 022 Jacobian on the mesh itself; up the ladder 2 of them, 6 of 6082 and
    # 18 of 3082 (a banded LU's work grows as its size: 0.42 of the unknowns factorised)
    assert fast_sizes.count(n) <= full_sizes.count(n) / 2
    assert sum(fast_sizes) <= 0.6 * sum(full_sizes)
    # one root, whichever start its last Newton had: the same to Newton's tolerance (1e-10 relative to |x|)
    assert np.max(np.abs(fast - full)) <= 1e-8 * (1 + np.max(np.abs(full)))
    a, b = _contact(sysm, full), _contact(sysm, fast)
    assert b["side_force"] == pytest.approx(a["side_force"], rel=1e-8)
    assert len(b["zones"]) == len(a["zones"]) >= 1
    assert np.allclose(np.asarray(b["zones"], float), np.asarray(a["zones"], float), rtol=1e-8)


def test_where_the_coarse_homotopy_fails_the_one_on_the_mesh_itself_gives_its_very_answer(slack_string, monkeypatch):
    sysm, guess = slack_string
    full, _ = _settled(sysm, guess, monkeypatch, coarsen=1)
    homotopy = solve_driver._homotopy

    def fails_coarse(s, *a):
        if s.disc.N != sysm.disc.N:
            raise solve_driver.ConvergenceError("no equilibrium on the coarse mesh")
        return homotopy(s, *a)
    monkeypatch.setattr(solve_driver, "_homotopy", fails_coarse)
    with np.errstate(all="ignore"):
        x = solve_driver.settle_in_conduit(sysm, guess, sysm.base, 1e-10, factor=10.0, coarsen=4)
    assert np.array_equal(x, full)


def test_a_mesh_too_small_to_coarsen_runs_the_homotopy_on_itself():
    assert solve_driver._coarse_system(type("S", (), {"disc": type("D", (), {"N": 2 * solve_driver.COARSE_MIN - 1})})(),
                                       None) is None


def _two_rungs(sysm, coarsen, stages):
    """The ladder before its middle rung: every c-th breakpoint, then the mesh itself at the last stage."""
    c = solve_driver._coarsening(sysm.disc.N, coarsen)
    return [(solve_driver._coarse_system(sysm, c), stages), (sysm, stages[-1:])]


def test_the_middle_rung_spares_the_mesh_itself_where_the_coarse_mesh_misplaced_the_contacts(monkeypatch):
    # examples/well_s3d.toml's 1000 m slack-off (mu 0.25) on its first mesh, as torque_and_drag starts it
    well = drilling.Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    placed = drilling.place_string(well, string, 1000.0)
    sysm = drilling.build_system(placed, Friction(0.25, placed.radius, Operation.named("slack-off")), 0.0, 0.0,
                                 well.eps, drilling.first_mesh(placed, 0.0))
    guess = sysm.model.initial_guess(sysm.disc, 0.0)
    n = sysm.disc.size
    ladder, sizes = _settled(sysm, guess, monkeypatch)
    own, _ = _settled(sysm, guess, monkeypatch, coarsen=1)
    monkeypatch.setattr(solve_driver, "_ladder", _two_rungs)
    straight, straight_sizes = _settled(sysm, guess, monkeypatch)
    # measured: 5 LUs of the mesh itself with the middle rung; carried straight from every 8th breakpoint its
    # last stage took 27 and failed, and the homotopy on the mesh itself followed (61 in all)
    assert sizes.count(n) <= 8 < 3 * 8 <= straight_sizes.count(n)
    for x in (ladder, straight):
        assert np.max(np.abs(x - own)) <= 1e-8 * (1 + np.max(np.abs(own)))
