"""The rod's other controls through the engine (issue 21 item 5), and the engine's edges (issue 22 items 4, 5, 11).

References, all independent of rodcont: ``tests/twisted_reference.py`` (the straight rod under length control,
the localized helix of van der Heijden & Thompson and the finite clamped rod by multiple shooting, Maddocks'
torque maximum on the Gamma = 1 branch by Lagrangian shooting), ``tests/closed_forms.py`` (critical twists),
``tests/data/lagrangian_folds.json`` (folds of the Lagrangian formulation).
"""

import json
import os
import re
import warnings

import numpy as np
import pytest

import closed_forms as cf
import rodcont
import twisted_reference as tw
from conftest import run
from rodcont.contact import MAX_PENETRATION, Wall, default_force_scale, penetration
from rodcont.rod import RodParameters
from rodcont.stability import branch_unstable_modes
from rodcont.system import RodSystem

HERE = os.path.dirname(os.path.abspath(__file__))

with open(os.path.join(HERE, "data", "lagrangian_folds.json")) as fh:
    PRIMARY = {r["gamma"]: r for r in json.load(fh)["primary_folds"]}

WEIGHTLESS = RodParameters(w=0.0)
with open(os.path.join(os.path.dirname(HERE), "README.md"), encoding="utf-8") as fh:
    README = fh.read()
SECTION = README[README.index("## Other controls"):README.index("## A rod inside a conduit")]


def _readme_number(pattern: str) -> float:
    """The number the README's controls section prints after ``pattern`` (a regular expression)."""
    return float(re.search(pattern + r"\s*([-0-9.e]+)", SECTION).group(1))


# --------------------------------------------------------------------------
# Length control: the straight weightless rod (twisted_reference A)
# --------------------------------------------------------------------------
@pytest.mark.parametrize("l0", [0.97, 1.0, 1.05])
def test_critical_twists_under_length_control_match_the_closed_form(l0):
    """The pencil of the rod with its unstressed length prescribed (the tension an unknown, l0 an integral
    condition) is singular at the closed form's twists of the tension-controlled rod at T = EA (L/l0 - 1)."""
    mine = rodcont.critical_twists(WEIGHTLESS, l0=l0, phi_max=40.0)
    ref = [tw.critical_twist_length_control(l0, n=n) for n in range(1, 5)]
    assert len(mine) == 4
    np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-8)


def test_straight_rod_buckles_at_the_closed_form_twist_under_length_control():
    """A trace in Phi at fixed l0 from the straight weightless rod: the tension stays EA (L/l0 - 1) exactly and
    the stability, counted under length control, goes from 0 to 2 unstable modes (the circle of helical modes)
    across the closed-form critical twist, 1e-6 on either side of it."""
    l0 = 0.97
    phi_c = tw.critical_twist_length_control(l0)
    near = (phi_c * (1 - 1e-6), phi_c * (1 + 1e-6))
    with pytest.warns(RuntimeWarning, match="cross in pairs"):  # a double crossing: no branch point is flagged
        br = rodcont.trace(None, rod=WEIGHTLESS, l0=l0, from_straight=5.0, forced=near, phi_max=phi_c + 1.0)
    T = np.asarray(br.table["T"], float)
    assert np.allclose(T, 255.0 * (1.0 / l0 - 1.0), rtol=1e-12)
    counts = {round(p, 9): n for p, n, k in zip(br.table["phi_L"], br.table["unstable_modes"], br.table["kind"])
              if k == "forced"}
    assert [counts[round(p, 9)] for p in near] == [0, 2]


def test_the_branch_from_a_critical_twist_under_length_control():
    """From the first critical twist of the weightless rod at fixed l0 = L (a phase condition fixes the circle's
    turn): the start is the closed-form twist with T = 0; the helix takes length the span does not give, so the
    rod stretches and its tension rises with the stretch (about EA (l/l0 - 1)); Phi rises with it (supercritical)
    and the branch, one helical wave, is stable under length control."""
    l0 = 1.0
    br = rodcont.trace(None, rod=WEIGHTLESS, l0=l0, from_critical=1, phi_max=20.0)
    assert br.table["phi_L"][0] == pytest.approx(tw.critical_twist_length_control(l0), abs=1e-8)
    assert json.loads(br.attrs["controls"]) == {"twist": "rotation", "axial": "l0", "l0": 1.0, "phase": True}
    T, phi = np.asarray(br.table["T"], float), np.asarray(br.table["phi_L"], float)
    stretch = np.asarray(br.table["stretch"], float)
    assert T[0] == pytest.approx(0.0, abs=1e-9) and np.all(np.diff(T) > 0) and np.all(np.diff(phi) > 0)
    assert T[-1] == pytest.approx(255.0 * stretch[-1], rel=0.3) and br.table["phi_L"][-1] == 20.0
    assert np.allclose(br.table["l0"], l0, atol=1e-12)
    assert set(br.table["helical_waves"][1:]) == {1} and set(br.table["unstable_modes"]) == {0}


# --------------------------------------------------------------------------
# Maddocks: stability under the controls in force (twisted_reference C)
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def torque_branch():
    return rodcont.trace(1.0, param="torque", p_range=(-1.0, 20.0))


def test_under_torque_control_the_primary_branch_loses_stability_at_its_torque_maximum(torque_branch):
    """trace --param torque (the distinguished diagram under torque control): the torque maximum is the
    trace's fold, at Maddocks' Phi = 12.6959184929163, torque 9.51146503319671 (Lagrangian shooting); the count
    under torque control (the end rotation free) goes 0 -> 1 there and stays 1 through the Phi maximum."""
    br = torque_branch
    (f,) = br.folds
    assert f["phi_L"] == pytest.approx(12.6959184929163, abs=1e-8)
    assert f["torque"] == pytest.approx(9.51146503319671, abs=1e-9)
    assert (f["unstable_before"], f["unstable_after"]) == (0, 1)
    i = f["index"]
    assert set(br.table["unstable_modes"][:i]) == {0} and set(br.table["unstable_modes"][i + 1:]) == {1}
    phi = np.asarray(br.table["phi_L"])
    top = int(np.argmax(phi))
    assert top > i + 1 and 13.0 < phi[top] <= PRIMARY[1.0]["phi_L"] + 1e-9  # stored points near the Phi fold


def test_under_rotation_control_the_same_branch_loses_stability_at_its_phi_maximum(torque_branch):
    """The same points counted with Phi imposed (the stored solutions read as the canonical problem): 0 up to
    the Phi fold (13.0999938), 1 past it: the count changes where dPhi/ds changes sign, not at the torque
    maximum."""
    br = torque_branch
    counts = branch_unstable_modes(br, T=10.0)
    dphi = np.asarray(br.table["dphi_ds"], float)
    turn = int(np.flatnonzero(dphi[1:] < 0)[0]) + 1  # the first point past the Phi maximum
    assert set(counts[:turn]) == {0} and set(counts[turn:]) == {1}
    assert br.table["phi_L"][turn - 1] < PRIMARY[1.0]["phi_L"] and br.folds[0]["index"] < turn - 1


def test_the_readme_prints_what_the_controls_give(torque_branch):
    """The numbers of the README's controls section: the torque trace's fold row (its printed digits), the
    length-control start at the first critical twist."""
    (f,) = torque_branch.folds
    row = re.search(r"^F1\s+(\d+)\s+([-0-9.e]+)\s+([-0-9.e]+)", SECTION, re.MULTILINE)
    assert int(row.group(1)) == f["index"]
    assert float(row.group(2)) == pytest.approx(f["torque"], abs=1e-11)
    # the fold located to its guard (1e-9): its last printed digits are the machine's (1.1e-12 apart on two CPUs)
    assert float(row.group(3)) == pytest.approx(f["phi_L"], abs=1e-10)
    assert _readme_number(r"torque maximum, Φ =") == pytest.approx(f["phi_L"], abs=1e-10)
    br = rodcont.trace(None, rod=WEIGHTLESS, l0=0.97, from_critical=1, phi_max=14.0)
    assert _readme_number(r"l0 = 0.97`: Φ =") == pytest.approx(br.table["phi_L"][0], abs=1e-12)
    assert _readme_number(r"closed form") == pytest.approx(tw.critical_twist_length_control(0.97), abs=1e-12)


def test_a_torque_trace_file_reads_back_and_restarts(tmp_path, capsys):
    """The file of a trace in the torque: its torque column is the parameter, phi_L solved for, the solutions
    stored as every branch stores them (export reads them)."""
    path = str(tmp_path / "m.h5")
    rodcont.trace(1.0, param="torque", p_range=(-1.0, 9.0), out=path)
    d = rodcont.load_branch(path)
    assert d.param == "torque" and json.loads(d.attrs["controls"])["twist"] == "torque"
    # the bound torque = 9 is the equilibrium solve finds there by loading the torque (natural continuation)
    assert d.table["torque"][-1] == 9.0
    assert d.table["phi_L"][-1] == pytest.approx(rodcont.solve(gamma=1.0, torque=9.0).outputs["phi_L"], abs=1e-8)
    code, out, err = run(["export", f"{path}:-1", "--format", "csv", "-o", str(tmp_path / "m.csv")], capsys)
    assert code == 0, err


# --------------------------------------------------------------------------
# The localized helix (twisted_reference B)
# --------------------------------------------------------------------------
HELIX = dict(EI=1.345, GJ=0.789, EA=1e9, L=37.0, l0=40.0, phi=68.85641215297314)
HELIX_COMMAND = ["trace", "--w", "0", "--T", "0.390889897704039", "--L", "37", "--EI", "1.345", "--GJ", "0.789",
                 "--EA", "1e9", "--from-critical", "1", "--forced", "68.85641215297314", "--phi-min", "60",
                 "--phi-max", "75", "--stretch-max", "0.09"]


@pytest.fixture(scope="module")
def clamped_helix_reference():
    """The finite clamped rod (multiple shooting of the Lagrangian equations, length control) at l0 = 40, span 37,
    Phi = 68.856..., EA = 1e9: its tension is the one the trace is given."""
    return tw.clamped_helix(HELIX["l0"], HELIX["L"], HELIX["phi"], HELIX["EI"], HELIX["GJ"], EA=HELIX["EA"],
                            segments=10)


@pytest.mark.slow
def test_localized_helix_of_a_long_twisted_rod(tmp_path, capsys, clamped_helix_reference):
    """The README's command: the weightless rod (span 37, PyElastica's stiffnesses) under the tension of the
    clamped reference, from its first critical twist along the helical branch (up to its fold, then down):
    at Phi = 68.856 the unstressed length is 40 (the reference's), the torque and the envelope those of the
    clamped rod; the infinite rod's closed form (van der Heijden & Thompson) at the same (D, Phi, l) is 1.8e-3
    away in T and 1.9 % in its envelope A = 1.5 (the finite rod's tails: both shrink like exp(-c l/2), the
    reference's own check at l = 100)."""
    ref = clamped_helix_reference
    assert ref["T"] == pytest.approx(0.390889897704039, rel=1e-12)
    path = str(tmp_path / "helix.h5")
    code, out, err = run(HELIX_COMMAND + ["--out", path, "--quiet"], capsys)
    assert code == 0, err
    d = rodcont.load_branch(path)
    at = [i for i, k in enumerate(d.table["kind"]) if k == "forced"]
    assert len(at) == 2  # on the way up (a slight helix) and, past the fold, the localized helix
    i = at[1]
    assert d.table["l0"][i] == pytest.approx(HELIX["l0"], abs=1e-9)
    assert d.table["torque"][i] == pytest.approx(ref["torque"], rel=1e-9)
    pt = d.point(i)
    s = RodSystem(d.rod, T=d.tension, k=d.k, breakpoints=pt["breakpoints"])
    S = np.linspace(0.0, HELIX["L"], 3701)
    envelope = np.hypot(s.disc.evaluate(pt["x"], S, 0), s.disc.evaluate(pt["x"], S, 1)).max()
    assert envelope == pytest.approx(ref["envelope_max"], rel=1e-6)
    inf = tw.localized_helix_loads(HELIX["l0"] - HELIX["L"], HELIX["phi"], HELIX["l0"], HELIX["EI"], HELIX["GJ"])
    assert abs(ref["T"] / inf["T"] - 1) < 3e-3
    A = 2 * np.sqrt(HELIX["EI"] / inf["T"]) * np.sqrt(1 - inf["mu"] ** 2)
    assert A == pytest.approx(1.5, rel=1e-9) and 0.015 < envelope / A - 1 < 0.025
    folds = d.folds
    assert len(folds) == 1 and (folds[0]["unstable_before"], folds[0]["unstable_after"]) == (0, 1)
    # the README: its command is this one, its table and fold what this run and the references give
    line = re.search(r"\$ (rodcont trace --w 0 .*?) --out helix.h5", SECTION.replace("\\\n", ""), re.DOTALL).group(1)
    assert line.split()[1:] == HELIX_COMMAND
    cells = {r.split("|")[1].strip(): [float(c) for c in r.split("|")[2:-1]] for r in SECTION.splitlines()
             if r.startswith("| ") and r.split("|")[2].strip()[:1].isdigit()}
    # (to the digits printed)
    assert cells["unstressed length `l0`"][0] == pytest.approx(d.table["l0"][i], abs=1e-9)
    assert cells["torque"] == [pytest.approx(d.table["torque"][i], abs=1e-12),
                               pytest.approx(ref["torque"], abs=1e-12), pytest.approx(inf["M"], abs=1e-12)]
    assert cells["envelope (largest deflection from the axis)"][:2] == [pytest.approx(envelope, abs=1e-10),
                                               pytest.approx(ref["envelope_max"], abs=1e-10)]
    assert _readme_number(r"folds at Φ =") == pytest.approx(folds[0]["phi_L"], abs=1e-9)


# --------------------------------------------------------------------------
# solve --out: one equilibrium as a branch file
# --------------------------------------------------------------------------
def test_solve_out_writes_a_point_that_export_shape_and_trace_read(tmp_path, capsys):
    """`solve --gamma 1 --torque M --out s.h5`: a one-point branch file holding the equilibrium (phi_L = 5, the
    torque and T as printed); export and shape read it, and trace --start s.h5:0 traces on from it in Phi (the
    rotation then imposed): its first point is the solved one."""
    path = str(tmp_path / "s.h5")
    code, out, err = run(["solve", "--gamma", "1", "--torque", "3.89224684363973", "--out", path], capsys)
    assert code == 0, err
    printed = dict(line.split()[:2] for line in out.splitlines() if len(line.split()) == 2)
    d = rodcont.load_branch(path)
    assert len(d) == 1 and d.table["phi_L"][0] == pytest.approx(float(printed["phi_L"]), abs=1e-12)
    assert d.table["phi_L"][0] == pytest.approx(5.0, abs=1e-8)
    assert d.table["torque"][0] == pytest.approx(3.89224684363973, abs=1e-10)
    assert d.tension == pytest.approx(10.0) and d.table["unstable_modes"][0] == 0
    code, out, err = run(["export", f"{path}:0", "--format", "csv", "-o", str(tmp_path / "s.csv")], capsys)
    assert code == 0, err
    code, out, err = run(["shape", path, "-o", str(tmp_path / "s.png")], capsys)
    assert code == 0, err
    t = str(tmp_path / "t.h5")
    code, out, err = run(["trace", "--start", f"{path}:0", "--phi-max", "6", "--out", t, "--quiet"], capsys)
    assert code == 0, err
    b = rodcont.load_branch(t)
    assert b.table["phi_L"][0] == pytest.approx(5.0, abs=1e-8) and b.table["phi_L"][-1] == 6.0
    assert b.table["torque"][0] == pytest.approx(3.89224684363973, abs=1e-9)


def test_solve_out_under_length_control_restarts_at_fixed_length(tmp_path, capsys):
    """`solve --l0 L0 --phi 5 --w 10 --out l.h5`: T = 10 stored (a column of the restart); a trace from it keeps
    the unstressed length (the file's controls) and solves for T at each point."""
    path, t = str(tmp_path / "l.h5"), str(tmp_path / "t.h5")
    code, out, err = run(["solve", "--l0", "0.963014577275618", "--phi", "5", "--w", "10", "--out", path], capsys)
    assert code == 0, err
    assert json.loads(rodcont.load_branch(path).attrs["controls"]) == {"twist": "rotation", "axial": "l0",
                                                                      "l0": 0.963014577275618}
    code, out, err = run(["trace", "--start", f"{path}:0", "--phi-max", "6", "--out", t, "--quiet"], capsys)
    assert code == 0, err
    b = rodcont.load_branch(t)
    assert b.table["T"][0] == pytest.approx(10.0, abs=1e-8)
    assert np.allclose(b.table["l0"], 0.963014577275618, atol=1e-12) and b.table["T"][-1] > 10.0


# --------------------------------------------------------------------------
# Conduits in trace (issue 22 item 4)
# --------------------------------------------------------------------------
GUIDEWIRE = RodParameters(EI=1e-5, GJ=7.7e-6, EA=5800.0, w=6e-6, L=0.3)


def test_trace_takes_the_problems_force_scale_and_meets_the_penetration_guard():
    """The guidewire of issue 22 (an arc of clearance 0.001): with the old default P = w it sat 6.5 % of the
    clearance in the wall; a trace now takes default_force_scale (T kappa here) and starts within the guard."""
    from rodcont.curves import parse_reference
    curve = parse_reference("arc:0.6", 0.3)
    wall = Wall(0.001)
    br = rodcont.trace(None, rod=GUIDEWIRE, T=0.01, curve=curve, wall=wall, phi_max=0.5)
    P = default_force_scale(GUIDEWIRE, 0.01, curve, wall)
    assert P > 10 * GUIDEWIRE.w and br.wall.force_scale == pytest.approx(P, rel=1e-12)
    s = RodSystem(GUIDEWIRE, T=0.01, k=br.k, breakpoints=br.meshes[0], curve=curve, wall=br.wall)
    assert penetration(s.model, s.disc, br.coefficients[0], s.params(0.0)) <= MAX_PENETRATION


def test_a_start_deeper_than_the_guard_is_stiffened_and_a_given_law_is_kept_and_warned_of(tmp_path):
    """The Gamma = 0.1 rod lying on the floor of a pipe under a law too soft for it (force_scale 0.005: it sits
    2.4e-2 of the clearance in the wall). The trace's own law would be stiffened at the start as solve's is
    (trace._within_penetration_guard, to within the guard, with a note); a law the conduit gives is the
    user's: kept along the branch, and the trace warns from where the rod is deeper than the guard (here its
    start; the file keeps the interval)."""
    from rodcont.drivers.solve import settle_in_conduit
    from rodcont.drivers.trace import _within_penetration_guard
    wall = Wall(0.02, force_scale=0.005)
    s = RodSystem(RodParameters(), gamma=0.1, N=40, wall=wall)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        x = settle_in_conduit(s, s.model.initial_guess(s.disc, 1.0), s.params(0.0))
    assert penetration(s.model, s.disc, x, s.params(0.0)) > 10 * MAX_PENETRATION
    notes: list = []
    x = _within_penetration_guard(s, x, notes)
    assert "stiffened" in notes[0] and s.model.contact_scale > 0.1
    assert penetration(s.model, s.disc, x, s.params(0.0)) <= MAX_PENETRATION
    out = str(tmp_path / "w.h5")
    with pytest.warns(RuntimeWarning, match="penetration guard"):
        br = rodcont.trace(0.1, wall=wall, phi_max=1.0, out=out)
    assert br.wall.force_scale == 0.005 and "notes" not in br.attrs
    a, b, depth = json.loads(rodcont.load_branch(out).attrs["penetration_guard"])
    assert a == b == 0.0 and depth > 10 * MAX_PENETRATION


@pytest.mark.parametrize("gamma,N,c", [(0.1, 40, 0.02), (1.0, 60, 0.05), (0.1, 200, 0.01)])
def test_the_chord_homotopy_settles_where_newtons_does(gamma, N, c):
    """settle_in_conduit solves its stages in the smoothing by the chord (a frozen Jacobian, issue 24): the
    equilibrium in the pipe is the one the same stages solved by damped Newton give, to 1e-10 of its size."""
    import dataclasses

    from rodcont.drivers.solve import settle_in_conduit
    s = RodSystem(RodParameters(), gamma=gamma, N=N, wall=Wall(c))
    p, wall = s.params(0.0), s.model.wall
    x0 = s.model.initial_guess(s.disc, s.base[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        x = settle_in_conduit(s, x0, p)
        y = x0
        for eps in (0.1, 1e-3, wall.eps):
            s.model.wall = dataclasses.replace(wall, eps=eps)
            r = s.disc.newton(y, p, max_iter=60)
            assert r.converged, r.message
            y = r.x
        s.model.wall = wall
    assert wall.eps == 1e-5 and np.max(np.abs(x - y)) <= 1e-10 * np.max(np.abs(y))


def test_a_stage_the_chord_fails_is_newtons(monkeypatch):
    """Where the chord does not converge (here: made to fail at once), settle_in_conduit solves the stage by
    Newton from the stage's start: the equilibrium is then bitwise that of the stages solved by Newton."""
    import dataclasses

    import rodcont.drivers.solve as solve_driver
    from rodcont.linalg import NewtonResult
    failed = []

    def chord_fails(linearise, residual, x0, **kw):
        failed.append(1)
        return NewtonResult(x0, False, 60, 1.0, 1.0, "no convergence in 60 iterations")

    monkeypatch.setattr(solve_driver, "chord_solve", chord_fails)
    s = RodSystem(RodParameters(), gamma=0.1, N=40, wall=Wall(0.02))
    p, wall = s.params(0.0), s.model.wall
    x0 = s.model.initial_guess(s.disc, s.base[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        x = solve_driver.settle_in_conduit(s, x0, p)
        y = x0
        for eps in (0.1, 1e-3, wall.eps):
            s.model.wall = dataclasses.replace(wall, eps=eps)
            y = s.disc.newton(y, p, max_iter=60).x
        s.model.wall = wall
    assert len(failed) == 3 and np.array_equal(x, y)


def test_a_trace_says_where_the_rod_goes_deeper_than_the_guard(tmp_path):
    """The Gamma = 1 rod in a pipe of clearance 0.02 under the trace's own law (eps = 1e-3, P = w), traced in w
    from the sag twisted by Phi = 1: its point contact presses harder and, between two stored points, goes deeper
    than 1e-3 of the clearance; the trace warns with that interval (its file keeps it) and goes on under its law."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sag = rodcont.trace(1.0, wall=Wall(0.02, eps=1e-3), phi_max=1.0)
    P, pt = sag.wall.force_scale, sag.point(-1)
    assert P == 10.0
    out = str(tmp_path / "w.h5")
    with pytest.warns(RuntimeWarning, match="penetration guard"):
        br = rodcont.trace(None, rod=sag.rod, T=10.0, wall=sag.wall, param="w", p_range=(0.0, 30.0), phi_L=1.0,
                           start=(pt["x"], 10.0, None), breakpoints=pt["breakpoints"], out=out)
    assert br.status == "bound" and br.wall.force_scale == P
    a, b, depth = json.loads(rodcont.load_branch(out).attrs["penetration_guard"])
    assert 10.0 <= a < b < 30.0 and depth > MAX_PENETRATION
    for w in (a, b):
        i = list(br.table["w"]).index(w)
        s = RodSystem(RodParameters(w=w), T=10.0, k=br.k, breakpoints=br.meshes[i], wall=br.wall, phi_L=1.0)
        d = penetration(s.model, s.disc, br.coefficients[i], s.params(1.0))
        assert (d <= MAX_PENETRATION) == (w == a)


# --------------------------------------------------------------------------
# API edges (issue 22 items 5 and 11)
# --------------------------------------------------------------------------
def test_a_mesh_that_does_not_span_the_rod_is_refused():
    """trace(breakpoints=[0, 0.3, 0.6, 0.9]) on the span 1 solved a shorter rod (fold 12.824): refused."""
    with pytest.raises(ValueError, match="span"):
        rodcont.trace(1.0, breakpoints=[0.0, 0.3, 0.6, 0.9])
    with pytest.raises(ValueError, match="span"):
        RodSystem(RodParameters(), gamma=1.0, breakpoints=[0.1, 0.5, 1.0])
    wall = Wall(((0.0, 0.002), (0.4, 0.003), (1.0, 0.004)))
    with pytest.raises(ValueError, match="station"):
        RodSystem(RodParameters(), gamma=1.0, breakpoints=np.linspace(0.0, 1.0, 4), wall=wall)
    RodSystem(RodParameters(), gamma=1.0, breakpoints=[0.0, 0.4, 1.0], wall=wall)  # with its station: fine


def test_critical_twists_at_a_huge_tension(capsys):
    """T = 1e20 (EA = 255): tau -> EA L^2/EI = 255, the closed form has no twist below 42.58 (code before: 24.99
    printed); above it the tension's terms swamp the bending ones by 1e20 and the roots are rounding: refused."""
    assert cf.critical_twists(1e20, phi_max=40.0).size == 0
    assert rodcont.critical_twists(RodParameters(), 1e20, phi_max=40.0) == []
    with pytest.raises(ValueError, match="rounding"):
        rodcont.critical_twists(RodParameters(), 1e20, phi_max=50.0)
    np.testing.assert_allclose(rodcont.critical_twists(RodParameters(), 1e9, phi_max=50.0),
                               cf.critical_twists(1e9, phi_max=50.0), rtol=0, atol=1e-8)
    code, out, err = run(["critical", "--T", "1e20"], capsys)
    assert code == 0 and "none below phi_max = 40" in out


def test_sizes_the_machine_cannot_hold_and_zero_sizes_are_refused():
    with pytest.raises(ValueError, match="GiB"):
        rodcont.critical_twists(RodParameters(), 10.0, N_fine=10**7)
    with pytest.raises(ValueError, match="N_fine"):
        rodcont.critical_twists(RodParameters(), 10.0, N_fine=0)
    with pytest.raises(ValueError, match="GiB"):
        rodcont.solve(gamma=1.0, phi_L=1.0, N=10**9, N_max=10**9)
    br = rodcont.trace(1.0, phi_max=2.0)
    from rodcont.drivers.foldcurve import fold_curve
    with pytest.raises(ValueError, match="N_max"):
        fold_curve(rodcont.trace(1.0, stretch_max=0.2), 0, "gamma", 0.9, 1.1, N_max=0)
    assert len(br) > 1


@pytest.mark.slow
@pytest.mark.parametrize("k", [2, 3])
def test_low_k_fold_estimates_bound_their_errors(k):
    """Gamma = 0.5, 1, 2: every fold's stored estimate is at least its distance from the Lagrangian fold (the
    code before, k = 2: 3.7e-9 off, estimate 8.2e-10); where it exceeds fold_error (k = 2 at N_max) a warning
    says so."""
    for gamma in (0.5, 1.0, 2.0):
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", RuntimeWarning)
            br = rodcont.trace(gamma, k=k)
        f = br.folds[0]
        off = abs(f["phi_L"] - PRIMARY[gamma]["phi_L"])
        floor = 2 * PRIMARY[gamma]["accuracy"]["phi_L"]  # the reference's own accuracy
        assert off <= max(f["error"], floor), (gamma, off, f["error"])
        if f["error"] > 1e-9:
            assert any("above fold_error" in str(w.message) for w in said)
