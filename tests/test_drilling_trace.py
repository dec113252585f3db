"""Traces of a drill string (rodcont.drilling): the branch file of a trace in the force at the bit keeps the hook
load and the surface torque of every point and the clearance's steps; a trip in bit depth
(rodcont.drivers.trip) against independent solves at fixed depths."""

import os

import numpy as np
import pytest

from rodcont.branchfile import load_branch
from rodcont.contact import Wall
from rodcont.drilling import DrillString, Section, SteppedWall, Well, torque_and_drag, trace_bit_force
from rodcont.ends import hook_load, surface_torque

# a short build-and-hold well (vertical to 100 m, 20 degrees at 250 m) and a collar under drill pipe
STATIONS = np.array([[0.0, 0, 0], [100.0, 0, 0], [250.0, 20.0, 30.0], [300.0, 20.0, 30.0]])
COLLAR = Section("collar", 50.0, 1.71e7, 1.32e7, 5.88e9, 2189.0, 0.0889)
PIPE = Section("pipe", None, 1.23e6, 9.5e5, 7.05e8, 285.0, 0.0635)


@pytest.fixture(scope="module")
def short_well():
    return Well(STATIONS, hole_diameter=0.2159, friction=0.25), DrillString((COLLAR, PIPE), 0.847)


def test_stepped_wall_survives_its_spec():
    wall = SteppedWall(((0.0, 0.05), (250.0, 0.02), (300.0, 0.02)), eps=1e-5, force_scale=10.0)
    back = Wall.from_spec(wall.spec)
    assert type(back) is SteppedWall and back == wall
    assert back.clearance_at(np.array([249.9, 250.1])).tolist() == [0.05, 0.02]   # a step, not a taper
    assert type(Wall.from_spec(Wall(0.05).spec)) is Wall


def test_bit_force_trace_file_keeps_hook_load_torque_and_steps(short_well, tmp_path):
    """Rotating off bottom, then the weight on bit from 0 to 20 kN as a trace in T: the file's hook_load and
    surface_torque columns equal the trace's in memory and the axial force and torque recomputed at S = 0 from
    each stored solution; the first point is the solve's, the last an independent solve drilling with 20 kN
    (to 1e-6); the wall reads back as the SteppedWall it was."""
    well, string = short_well
    td = torque_and_drag(well, string, 300.0, "rotate")
    out = str(tmp_path / "wob.h5")
    br = trace_bit_force(td, (-2e4, 0.0), out)
    back = load_branch(out)
    assert type(back.wall) is SteppedWall and back.wall == td.system.wall
    for name in ("hook_load", "surface_torque"):
        assert back.table[name] == br.table[name]
    sysm = td.system
    for i in range(len(back)):
        sy = sysm.with_mesh(back.meshes[i])
        x = sy.expanded(back.coefficients[i])
        p = sy.params(back.table["T"][i])
        assert back.table["hook_load"][i] == pytest.approx(hook_load(sy.model, sy.disc, x, p), rel=1e-12)
        assert back.table["surface_torque"][i] == pytest.approx(surface_torque(sy.model, sy.disc, x, p), rel=1e-12)
    assert back.table["hook_load"][0] == pytest.approx(td.hook_load, rel=1e-12)
    assert back.table["T"][-1] == -2e4
    drill = torque_and_drag(well, string, 300.0, "drill", wob=2e4)
    assert back.table["hook_load"][-1] == pytest.approx(drill.hook_load, rel=1e-6)
    assert back.table["surface_torque"][-1] == pytest.approx(drill.surface_torque, rel=1e-6)


def test_files_without_drilling_columns_still_read():
    """A file written before the drilling columns (tests/data/old_trace_g1.h5) reads, without them."""
    b = load_branch(os.path.join(os.path.dirname(__file__), "data", "old_trace_g1.h5"))
    assert len(b) > 0 and "hook_load" not in b.table and "phi_L" in b.table


def test_trip_in_depth_against_fixed_depth_solves(short_well, tmp_path):
    """A slack-off trip from 280 to 300 m (3 depths) as one branch in ``depth``: its file reads back with the
    depth, hook load and surface torque of each point, each the solve at that fixed depth (to 1e-12: the march
    places the string, its sections and its law afresh at every depth); against a solve started on a mesh
    twice as fine the hook load agrees to 1e-4 (measured 2.9e-5 at 300 m: the spread of the adapted solves,
    contact law and mesh, not of the trip)."""
    from rodcont.drilling import first_mesh, place_string
    from rodcont.drivers.trip import trip
    well, string = short_well
    out = str(tmp_path / "trip.h5")
    br = trip(well, string, (280.0, 300.0), "slack-off", points=3, out=out)
    back = load_branch(out)
    assert back.param == "depth" and back.table["depth"] == [280.0, 290.0, 300.0]
    assert back.table["kind"] == ["start", "regular", "bound"] and str(back.status) == "bound"
    assert back.table["hook_load"] == br.table["hook_load"]
    assert np.all(np.diff(back.table["hook_load"]) > 0)     # more pipe in a hole of 20 degrees: heavier
    for d, H in zip(back.table["depth"][1:], back.table["hook_load"][1:]):
        assert torque_and_drag(well, string, d, "slack-off").hook_load == pytest.approx(H, rel=1e-12)
    N = 2 * first_mesh(place_string(well, string, 300.0), 0.0)
    fine = torque_and_drag(well, string, 300.0, "slack-off", N=N).hook_load
    assert fine == pytest.approx(back.table["hook_load"][-1], rel=1e-4)


def test_trip_command_checks_its_input():
    import click

    from rodcont.cli_drilling import run_drilling_trace
    well = os.path.join(os.path.dirname(__file__), "..", "examples", "well_s3d.toml")
    string = os.path.join(os.path.dirname(__file__), "..", "examples", "drill_string.toml")
    with pytest.raises(click.UsageError, match="--param depth"):
        run_drilling_trace(well, {"string": string}, "T", (1.0, 2.0), None)
    with pytest.raises(click.UsageError, match="0 < A < B"):
        run_drilling_trace(well, {"string": string}, "depth", (2000.0, 1000.0), None)
    with pytest.raises(click.UsageError, match="needs the well"):
        run_drilling_trace(None, {"string": string}, "depth", (1000.0, 2000.0), None)


def test_lock_up_of_a_horizontal_section_against_the_derived_estimate(tmp_path):
    """Vertical to 10 m, a 90-degree build of radius R = 150 m, then horizontal; 5" drill pipe (buoyed w), mu 0.3.
    The estimate (soft string, no buckling): slack-off with F(0) = 0 at lock-up, the compression P = -F is w 10 at
    the kick-off, on the build dP/dI = R w (cos I - mu sin I) - mu P (pressed to the low side by P/R + w sin I),
    solved in closed form, and on the horizontal it falls by mu w per metre to 0 at the bit: L_h = P(90) / (mu w).
    Nowhere does the compression reach the Dawson-Paslay (or, vertical, Lubinski) load (buckling ratio < 1), so
    the estimate needs no helical term. The trip from 480 to 560 m stops at its lock-up event, the hook load 0
    there (to 1e-3 of its scale), its horizontal length 1.0-1.04 times L_h (measured 1.021: the stiff string's drag
    is smaller, it leaves the wall at the build's ends, as in tests/test_friction.py)."""
    import math

    from rodcont.drivers.trip import trip
    R, mu = 150.0, 0.3
    stations = np.array([[0.0, 0, 0], [10.0, 0, 0], [10 + math.pi / 2 * R, 90.0, 0.0], [900.0, 90.0, 0.0]])
    well = Well(stations, hole_diameter=0.2159, friction=mu)
    string = DrillString((PIPE,), 0.847)
    w = PIPE.w_air * 0.847
    e = math.exp(mu * math.pi / 2)
    P90 = (10 * w + R * w * (e * (1 - mu**2) - 2 * mu) / (1 + mu**2)) / e
    Lh = P90 / (mu * w)
    br = trip(well, string, (480.0, 560.0), "slack-off", points=2, out=str(tmp_path / "lock.h5"))
    assert br.table["kind"] == ["start", "event:lock_up"] and str(br.status) == "event"
    assert abs(br.table["hook_load"][-1]) < 1e-3 * br.table["hook_load"][0]
    assert max(br.table["buckling_ratio"]) < 1
    ratio = (br.table["depth"][-1] - 10 - math.pi / 2 * R) / Lh
    assert 1.0 < ratio < 1.04, ratio
    assert load_branch(str(tmp_path / "lock.h5")).table["kind"][-1] == "event:lock_up"
