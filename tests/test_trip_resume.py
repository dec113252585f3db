"""A trip in bit depth interrupted keeps its depths on disk, and ``rodcont trace --resume F.h5``
(``rodcont.drivers.trip.resume_trip``) goes on from its last depth with the file's own well, string, operation,
range and options: the finished file holds the same points as a trip never interrupted (each depth its own cold
start, so to the last bit)."""

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from rodcont.branchfile import load_branch
from rodcont.drilling import DrillString, Section, Well
from rodcont.drivers.trip import resume_trip, trip

HERE = os.path.dirname(__file__)
# a straight hole inclined 80 degrees, a light pipe (tests/test_broomstick_jobs.py's): cheap equilibria
PIPE = Section("light pipe", None, 1e4, 7.7e3, 1e8, 100.0, 0.05)
STRING = DrillString((PIPE,), 1.0)
WELL = Well(np.array([[0.0, 80.0, 0.0], [400.0, 80.0, 0.0]]), hole_diameter=0.3, friction=0.4)
COLUMNS = ("depth", "hook_load", "surface_torque", "side_force", "max_joint_side_force", "buckling_ratio", "kind")


class StopAfter:
    """A trip's callback that interrupts (as Ctrl-C does) once ``n`` points are recorded."""

    def __init__(self, n):
        self.n, self.rows = n, []

    def __call__(self, r, row):
        self.rows.append(row)
        if len(self.rows) == self.n:
            raise KeyboardInterrupt


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    return trip(WELL, STRING, (100.0, 200.0), "pick-up", points=4, out=str(tmp_path_factory.mktemp("w") / "t.h5"),
                N_max=3000)


def test_an_interrupted_trip_resumed_holds_the_points_of_one_never_interrupted(tmp_path, whole):
    out = str(tmp_path / "t.h5")
    stop = StopAfter(2)
    with pytest.raises(KeyboardInterrupt):
        trip(WELL, STRING, (100.0, 200.0), "pick-up", points=4, out=out, N_max=3000, callback=stop)
    part = load_branch(out)
    assert str(part.status) == "interrupted" and len(part) == 2
    assert [r["depth"] for r in stop.rows] == part.table["depth"] == list(np.linspace(100, 200, 4)[::-1][:2])  # upward
    seen = []
    done = resume_trip(out, callback=lambda r, row: seen.append(row["depth"]))
    assert seen == whole.table["depth"][2:]   # only the depths still to do were solved
    back = load_branch(out)
    assert str(back.status) == str(whole.status) == "bound" and back.message == whole.message
    for name in COLUMNS:
        assert back.table[name] == whole.table[name] == done.table[name], name
    for i in range(len(back)):   # the solutions too, and the trip's record of its run
        np.testing.assert_array_equal(back.coefficients[i], whole.coefficients[i])
        np.testing.assert_array_equal(back.meshes[i], whole.meshes[i])
    assert json.loads(back.attrs["trip_run"])["options"] == {"N_max": 3000}


def test_a_trip_whose_last_point_is_an_event_goes_on_from_the_depth_before_it(tmp_path):
    """An interrupt right after an event is recorded (before the depth that brackets it): the event is located
    again from the last depth of the march, not kept twice."""
    from rodcont.drivers.trip import _kept
    out = str(tmp_path / "t.h5")
    with pytest.raises(KeyboardInterrupt):
        trip(WELL, STRING, (100.0, 200.0), "pick-up", points=4, out=out, callback=StopAfter(2))
    b = load_branch(out)
    depths = np.linspace(100.0, 200.0, 4)[::-1]
    assert _kept(b, depths) == (2, 2)
    b.table["kind"][1] = "event:sinusoidal_buckling"   # as if point 1 were an event between depths 0 and 1
    assert _kept(b, depths) == (1, 1)


def test_a_trip_it_cannot_resume_is_one_line(tmp_path, monkeypatch):
    from rodcont.drivers import trip as trip_module
    out = str(tmp_path / "t.h5")
    trip(WELL, STRING, (100.0, 150.0), "pick-up", points=2, out=out)
    with pytest.raises(ValueError, match="is a finished trip"):
        resume_trip(out)
    attrs = trip_module._attrs   # a trip's file as rodcont wrote it before it recorded its run
    monkeypatch.setattr(trip_module, "_attrs", lambda *a, **k: {key: v for key, v in attrs(*a, **k).items()
                                                                 if key != "trip_run"})
    with pytest.raises(KeyboardInterrupt):
        trip(WELL, STRING, (100.0, 150.0), "pick-up", points=2, out=out, overwrite=True, callback=StopAfter(1))
    with pytest.raises(ValueError, match="written before trips could be resumed: run the trip again"):
        resume_trip(out)


def test_a_trip_file_rewritten_by_hand_is_not_resumed(tmp_path):
    """A trip whose file lost rodcont's checksum (h5py keeps none) is refused before it is touched: its record
    (well, string, range) would be trusted, a failure had rewritten it one point shorter, and a success had
    stamped the edited record with a valid checksum."""
    import warnings

    import h5py
    first, out = str(tmp_path / "first.h5"), str(tmp_path / "t.h5")
    with pytest.raises(KeyboardInterrupt):
        trip(WELL, STRING, (100.0, 200.0), "pick-up", points=3, out=first, callback=StopAfter(1))
    with h5py.File(first, "r") as src, h5py.File(out, "w") as f:   # copied by h5py: no checksum
        for name in src:
            src.copy(name, f)
        f.attrs.update(src.attrs)
        f.attrs["trip_run"] = json.dumps(dict(json.loads(src.attrs["trip_run"]), range=[100.0, 900.0]))
    before = open(out, "rb").read()
    with warnings.catch_warnings(), pytest.raises(ValueError, match="has lost rodcont's checksum"):
        warnings.simplefilter("ignore")
        resume_trip(out)
    assert open(out, "rb").read() == before


# ------------------------------------------------------------------ the command line

def _files(tmp_path):
    (tmp_path / "w.csv").write_text("0,80,0\n400,80,0\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "w.csv"\nhole_diameter = 0.3\nfriction = 0.4\n')
    (tmp_path / "s.toml").write_text('[string]\nbuoyancy_factor = 1.0\n[[section]]\nname = "light pipe"\n'
                                     'EI = 1e4\nGJ = 7.7e3\nEA = 1e8\nw_air = 100.0\nradius = 0.05\n')
    return str(tmp_path / "w.toml"), str(tmp_path / "s.toml")


def _rodcont(*args):
    return [sys.executable, "-m", "rodcont", *args], dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))


def test_the_trip_command_interrupted_says_how_to_go_on_and_resume_finishes_it(tmp_path, whole):
    well, string = _files(tmp_path)
    cmd, env = _rodcont("trace", "--conduit", well, "--string", string, "--param", "depth", "--range", "100", "200",
                        "--operation", "pick-up", "--out", "t.h5")
    p = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        first = p.stderr.readline()   # after its first depth is on disk
        assert first.startswith("depth 1 of 11 "), first
    finally:
        os.killpg(p.pid, signal.SIGTERM)
    out, err = p.communicate(timeout=300)
    held = load_branch(str(tmp_path / "t.h5"))
    assert p.returncode == 143 and str(held.status) == "interrupted", (p.returncode, err)
    assert f"interrupted: t.h5 holds the {len(held)} completed depth(s) of the trip; go on with rodcont trace " \
           f"--resume t.h5" in err.splitlines()
    cmd, env = _rodcont("trace", "--resume", "t.h5", "--param", "depth")   # its own parameter may be said
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    depths = [ln for ln in r.stderr.splitlines() if ln.startswith("depth ")]   # the first is printed at once
    assert depths[0].startswith(f"depth {len(held) + 1} of 11 "), depths   # counted on from the file's depths
    back = load_branch(str(tmp_path / "t.h5"))
    assert len(back) == 11 and str(back.status) == "bound"
    ref = trip(WELL, STRING, (100.0, 200.0), "pick-up", points=11)
    for name in COLUMNS:
        assert back.table[name] == ref.table[name], name
    lines = [ln for ln in r.stdout.splitlines() if not ln.startswith("#")]   # after the problem as run
    assert lines[:2] == ["points 11", "status bound"]
    # the problem as run names none of a rod trace's defaults (it said param = "phi_L" of a trip in depth)
    assert [ln for ln in r.stdout.splitlines() if ln.startswith("#")] == [
        "# rodcont trace: the problem as run",
        "#   (the problem and every option not given here are those of --resume t.h5)",
        "#   [trace]", '#   param = "depth"']
    assert f"hook_load {ref.table['hook_load'][-1]!r}" in lines


@pytest.mark.parametrize("extra, message", [
    (("--operation", "rotate"), "drop --operation"),
    (("--range", "100", "300"), "drop --range"),
    (("--points", "5"), "drop --points"),
    (("--param", "phi_L"), "drop --param"),   # had been taken silently
])
def test_resuming_a_trip_refuses_what_would_change_it(tmp_path, extra, message):
    out = str(tmp_path / "t.h5")
    with pytest.raises(KeyboardInterrupt):
        trip(WELL, STRING, (100.0, 200.0), "pick-up", points=3, out=out, callback=StopAfter(1))
    before = os.stat(out).st_mtime_ns
    cmd, env = _rodcont("trace", "--resume", "t.h5", *extra)
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert os.stat(out).st_mtime_ns == before


def test_a_trips_depths_are_points_from_a_to_b_and_only_a_trip_takes_points(tmp_path):
    well, string = _files(tmp_path)
    cmd, env = _rodcont("trace", "--conduit", well, "--string", string, "--param", "depth", "--range", "100", "200",
                        "--points", "3", "--operation", "pick-up", "--out", "t.h5", "--quiet")
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0 and r.stderr.splitlines() == [], r.stderr
    assert load_branch(str(tmp_path / "t.h5")).table["depth"] == [200.0, 150.0, 100.0]
    assert "#   points = 3" in r.stdout.splitlines()   # the problem as run says it
    cmd, env = _rodcont("trace", "--gamma", "1", "--points", "3", "--out", "x.h5")
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and "--points is the number of depths of a trip" in r.stderr, r.stderr
    assert not (tmp_path / "x.h5").exists()
