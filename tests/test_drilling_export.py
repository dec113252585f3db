"""Export of a drill string's stored equilibria (issue 23): a trip's file (and ``solve --string --out``) keeps the
drilling record, ``export`` rebuilds each point's string at its own depth and writes ``S`` = MD with the columns
``axial_force``, ``torque``, ``pressure``, ``gap``, ``in_contact``; checked against the values the solves stored
(hook load, surface torque, side force), the rebuilt system's own residual, and clearances computed here."""

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from rodcont.branchfile import load_branch
from rodcont.contact import MAX_PENETRATION
from rodcont.drilling import DrillingError, DrillString, Well, read_record, torque_and_drag, trace_bit_force
from rodcont.drivers.trip import trip
from rodcont.export import drill_point, export_point
from short_well import COLLAR, DEPTHS, HOLE, PIPE, STATIONS

HERE = os.path.dirname(__file__)


def _run(*args):
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))
    return subprocess.run([sys.executable, "-m", "rodcont", *args], capture_output=True, text=True, env=env)


def _read_csv(path):
    with open(path) as f:
        lines = [ln for ln in f if not ln.startswith("#")]
    names = lines[0].strip().split(",")
    table = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    return {n: table[:, j] for j, n in enumerate(names)}


@pytest.fixture(scope="module")
def trip_file(tmp_path_factory):
    """Rotating off bottom at 290 and 300 m (2 depths): a torque along the string, the collar's top on the wall."""
    out = str(tmp_path_factory.mktemp("trip") / "trip.h5")
    trip(Well(STATIONS, hole_diameter=HOLE, friction=0.25), DrillString((COLLAR, PIPE), 0.847), DEPTHS, "rotate",
         points=2, out=out)
    return out


def _clearance(S, depth):
    """The hole's radius less the outer radius of the section at MD ``S`` (the collar's 50 m above the bit)."""
    return np.where(S >= depth - COLLAR.length, HOLE / 2 - COLLAR.radius, HOLE / 2 - PIPE.radius)


@pytest.mark.parametrize("point", [0, -1])
def test_an_exported_trip_point_is_the_stored_equilibrium_at_its_depth(trip_file, tmp_path, point):
    """Points 0 and -1 (290 and 300 m) exported as CSV on the solution's mesh grid: S runs from 0 to the point's
    depth; the axial force and the torque at S = 0 are the stored hook load and surface torque (1e-8); the
    rebuilt point's side force is the stored one (1e-10, the collocation rule of both: only the rebuilt wall and
    solution can differ) and the exported pressure its law (on a uniform grid a point contact of a millimetre, the
    collar's top on the wall at 290 m, is stepped over, hence the mesh grid); Newton on the rebuilt system does
    not move the stored solution (the friction, the sections, the loads and the law are the solved ones); the gap
    is above minus the penetration guard times a clearance computed here from the hole and the pipes; in_contact
    is the gap below 1 % of it, so it is 1 exactly where the pressure is above its level off the wall in each
    pipe's hole. The VTK file carries the same axial force."""
    data = load_branch(trip_file)
    i = data.resolve(point)
    depth = float(data.branch["depth"][i])
    assert depth == DEPTHS[i]
    csv = str(tmp_path / "p.csv")
    export_point(data, point, csv, "csv", grid="mesh")
    f = _read_csv(csv)
    S = f["S"]
    assert S[0] == 0.0 and S[-1] == depth and np.all(np.diff(S) > 0)
    hook, torque = float(data.branch["hook_load"][i]), float(data.branch["surface_torque"][i])
    assert abs(torque) > 100.0   # rotating: the friction builds a torque the rig must supply
    assert f["axial_force"][0] == pytest.approx(hook, rel=1e-8)
    assert f["torque"][0] == pytest.approx(torque, rel=1e-8)
    P = f["pressure"]
    td = drill_point(data, i)
    _assert_stored_side_force(td, S, P, float(data.branch["side_force"][i]))
    r = td.system.disc.newton(td.x, td.system.base, tol=1e-10)
    # the trip's solves stop at their own Newton/chord tolerance (measured 1.5e-9 of max|x| with the chord
    # homotopy, below 1e-9 without it); a wrongly rebuilt law, section or load moves the solution by O(1)
    assert r.converged and np.max(np.abs(r.x - td.x)) <= 1e-8 * np.max(np.abs(td.x))
    c = _clearance(S, depth)
    assert np.all(f["gap"] >= -MAX_PENETRATION * c)
    on = f["in_contact"] == 1.0
    assert np.array_equal(on, f["gap"] <= 0.01 * c) and 0 < on.sum() < on.size
    for pipe in (S < depth - COLLAR.length, S >= depth - COLLAR.length):
        if on[pipe].any() and (~on[pipe]).any():
            assert P[pipe & on].min() > P[pipe & ~on].max()
    vtp = str(tmp_path / "p.vtp")
    export_point(data, point, vtp, "vtk", samples=50)
    arrays = {a.get("Name"): a.text.split() for a in ET.parse(vtp).iter("DataArray")}
    assert float(arrays["axial_force"][0]) == pytest.approx(hook, rel=1e-8)
    assert float(arrays["S"][-1]) == depth


def _assert_stored_side_force(td, S, P, stored):
    """The rebuilt point's side force (the collocation rule, rod.contact) is the stored one to 1e-10 (only the
    rebuilt wall and solution can differ) and the exported pressure is the rebuilt solution's law at S."""
    sysm = td.system
    con = sysm.model.contact(sysm.disc, td.x, td.params, S=S)
    assert con["side_force"] == pytest.approx(stored, rel=1e-10)
    assert np.allclose(P, con["pressure"], rtol=1e-12, atol=1e-12 * np.max(np.abs(P)))


@pytest.fixture(scope="module")
def wob_trace(tmp_path_factory):
    """Rotating off bottom at 300 m, then a trace in the force at the bit T from 0 to -20 kN (the weight on bit)."""
    well, string = Well(STATIONS, hole_diameter=HOLE, friction=0.25), DrillString((COLLAR, PIPE), 0.847)
    out = str(tmp_path_factory.mktemp("wob") / "wob.h5")
    trace_bit_force(torque_and_drag(well, string, 300.0, "rotate"), (-2e4, 0.0), out)
    return out, well, string


@pytest.mark.parametrize("point", [1, -1])
def test_an_exported_point_of_a_trace_in_the_bit_force_is_the_stored_equilibrium(wob_trace, tmp_path, point):
    """A trace in T (rodcont.drilling.trace_bit_force) keeps the drilling record: export rebuilds its points at the
    file's depth with each point's own T. On the mesh grid the axial force and the torque at S = 0 are the stored
    hook load and surface torque (1e-8), the rebuilt point's side force the stored one (1e-10),
    S runs from 0 to 300 m; Newton on the rebuilt system does not move the stored solution (a rebuild with the
    record's WOB 0 instead of the point's T moves it by O(1)); the last point's hook load is an independent solve
    drilling with 20 kN (1e-6, as the trace's own test)."""
    out, well, string = wob_trace
    data = load_branch(out)
    i = data.resolve(point)
    csv = str(tmp_path / "p.csv")
    export_point(data, point, csv, "csv", grid="mesh")
    f = _read_csv(csv)
    S, P = f["S"], f["pressure"]
    assert S[0] == 0.0 and S[-1] == 300.0 and np.all(np.diff(S) > 0)
    hook = float(data.branch["hook_load"][i])
    assert f["axial_force"][0] == pytest.approx(hook, rel=1e-8)
    assert f["torque"][0] == pytest.approx(float(data.branch["surface_torque"][i]), rel=1e-8)
    td = drill_point(data, i)
    _assert_stored_side_force(td, S, P, float(data.branch["side_force"][i]))
    assert td.wob == -float(data.branch["T"][i]) > 0
    r = td.system.disc.newton(td.x, td.system.base, tol=1e-10)
    assert r.converged and np.max(np.abs(r.x - td.x)) <= 1e-8 * np.max(np.abs(td.x))
    with open(csv) as fh:
        head = [ln for ln in fh if ln.startswith("# ")]
    assert "# param: T\n" in head and "# depth: 300.0\n" in head
    if point == -1:
        assert data.branch["T"][i] == -2e4
        assert hook == pytest.approx(torque_and_drag(well, string, 300.0, "drill", wob=2e4).hook_load, rel=1e-6)


def test_the_trip_file_records_the_well_and_the_string(trip_file):
    """The drilling record reads back as the well, the string and the operation the trip ran with."""
    data = load_branch(trip_file)
    rec = read_record(data.attrs["drilling"])
    assert np.array_equal(rec["well"].stations, STATIONS) and rec["well"].hole_diameter == HOLE
    assert rec["string"] == DrillString((COLLAR, PIPE), 0.847)
    assert rec["operation"].name == "rotate" and rec["operation"].rpm > 0 and rec["mu"] == 0.25
    newer = json.dumps(dict(json.loads(data.attrs["drilling"]), version=99))
    with pytest.raises(DrillingError, match="newer"):
        read_record(newer)


def test_solve_string_out_writes_a_point_export_reads(tmp_path):
    """``solve --string --out`` on a 60 m vertical hole at 50 m, picking up: export reads its one point; the axial
    force at S = 0 is the printed hook load (1e-8) and, the string hanging free of the wall, the buoyed weight of
    its unstressed length ``w l0`` (``l0`` the exported ``s`` at the bit, stretched by its own weight) plus the
    pick-up friction ``mu integral p dS`` on the smoothed law's small force off the wall (1e-9)."""
    (tmp_path / "s.csv").write_text("0, 0, 0\n60, 0, 0\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "s.csv"\nhole_diameter = 0.2159\nfriction = 0.25\n')
    (tmp_path / "p.toml").write_text("[string]\nbuoyancy_factor = 0.847\n[[section]]\nname = 'pipe'\nEI = 1.23e6\n"
                                     "GJ = 9.5e5\nEA = 7.05e8\nw_air = 285.0\nradius = 0.0635\n")
    h5, csv = str(tmp_path / "one.h5"), str(tmp_path / "one.csv")
    r = _run("solve", "--conduit", str(tmp_path / "w.toml"), "--string", str(tmp_path / "p.toml"), "--depth", "50",
             "--operation", "pick-up", "--out", h5)
    assert r.returncode == 0, r.stderr
    hook = float(next(ln.split()[1] for ln in r.stdout.splitlines() if ln.startswith("hook_load ")))
    r = _run("export", h5 + ":0", "-o", csv)
    assert r.returncode == 0, r.stderr
    f = _read_csv(csv)
    assert f["S"][-1] == 50.0
    assert f["axial_force"][0] == pytest.approx(hook, rel=1e-8)
    # hanging free of the wall: the weight of its unstressed length l0 = s(L) and the friction on the law's force
    # off the wall (constant here, so the trapezoid rule is exact)
    l0, drag = f["s"][-1], 0.25 * np.sum(0.5 * (f["pressure"][1:] + f["pressure"][:-1]) * np.diff(f["S"]))
    assert l0 < 50.0 and drag > 0
    assert f["axial_force"][0] == pytest.approx(285.0 * 0.847 * l0 + drag, rel=1e-9)
    assert np.allclose(f["x"], 0) and np.allclose(f["y"], 0) and f["z"][-1] == pytest.approx(-50.0, rel=1e-9)


def test_a_trip_file_older_than_the_record_is_refused_in_one_line(tmp_path):
    """tests/data/old_trip_tiny.h5 (a 2-point trip written by the code at 6d9dd9b, before the record): export
    refuses it in one line, exit 2, no file written."""
    out = tmp_path / "t.csv"
    r = _run("export", os.path.join(HERE, "data", "old_trip_tiny.h5") + ":-1", "-o", str(out))
    assert r.returncode == 2 and "predates" in r.stderr and "re-run the trip" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert not out.exists()
