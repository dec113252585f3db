"""Adversarial checks of the README's torque-and-drag promises (helper-written; each test fails on the code it was
written against and says what the user sees). Shallow, vertical-hole cases only: each runs in a few seconds."""

import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(__file__)
EXAMPLES = os.path.join(HERE, "..", "examples")
WELL, STRING = os.path.join(EXAMPLES, "well_s3d.toml"), os.path.join(EXAMPLES, "drill_string.toml")


def _run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))
    return subprocess.run([sys.executable, "-m", "rodcont", *args], capture_output=True, text=True, env=env, cwd=cwd)


def _value(stdout: str, name: str) -> str:
    return next(line.split(" ", 1)[1] for line in stdout.splitlines() if line.startswith(name + " "))


def _damaged_string(tmp_path, old: str, new: str) -> str:
    text = open(STRING).read()
    assert old in text
    path = tmp_path / "s.toml"
    path.write_text(text.replace(old, new))
    return str(path)


@pytest.mark.parametrize("old,new", [("E = 207e9", 'E = "abc"'),
                                     ("mud_density = 1200.0", 'mud_density = "heavy"'),
                                     ("mud_density = 1200.0", 'buoyancy_factor = "x"'),
                                     ("density = 7850.0", "density = 0")])
def test_a_bad_value_in_the_string_header_is_a_user_error(tmp_path, old, new):
    # seen: exit 1, 'unexpected failure (ValueError: could not convert string to float ...); please report it'
    # (ZeroDivisionError for density = 0): a typo in the user's file reported as a rodcont bug
    s = _damaged_string(tmp_path, old, new)
    r = _run("solve", "--conduit", WELL, "--string", s, "--depth", "300", "--operation", "static")
    assert r.returncode == 2, r.stderr
    assert "unexpected failure" not in r.stderr


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_bit_torque_is_refused_as_wob_is(value):
    # seen: exit 1, 'unexpected failure (TypeError: Torque.M must be a finite number, got nan)'; --wob nan gives
    # exit 2 '--wob must be a non-negative finite number'
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--operation", "drill",
             "--wob", "1000", "--bit-torque", value)
    assert r.returncode == 2, r.stderr
    assert "unexpected failure" not in r.stderr


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_friction_in_the_well_file_is_refused_when_read(tmp_path, value):
    # seen: accepted, then 'no equilibrium found inside the conduit ...: residual is not finite' (no word of friction)
    from rodcont.drilling import DrillingError, Well
    text = open(WELL).read().replace("friction = 0.25", f"friction = {value}")
    path = tmp_path / "well_s3d.toml"
    path.write_text(text)
    (tmp_path / "well_s3d.csv").write_text(open(os.path.join(EXAMPLES, "well_s3d.csv")).read())
    with pytest.raises(DrillingError, match="friction"):
        Well.from_toml(str(path))


def test_a_typo_in_the_first_survey_station_is_not_taken_for_a_header(tmp_path):
    # seen: '0,0,O' (letter O) skipped as a header, the survey starts at MD 400 and --depth 500 puts the bit at
    # MD 900 in the 45 deg hold: hook load 433.7 kN instead of 485.9 kN, exit 0, no word said
    from rodcont.drilling import DrillingError, Well
    (tmp_path / "s.csv").write_text("0,0,O\n400,0,0\n460,4,30\n1000,45,66\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "s.csv"\n')
    with pytest.raises(DrillingError):
        Well.from_toml(str(tmp_path / "w.toml"))


def test_a_survey_not_starting_at_md_0_takes_depth_as_md(tmp_path):
    # seen: a survey from MD 100 to 1000 (DRILLING.md: MD runs from the rig floor) refuses --depth 950 with
    # 'the bit depth 950 m lies outside the survey (0 .. 900 m)', and --depth 300 puts the bit at MD 400
    from rodcont.drilling import DrillingError, Well
    (tmp_path / "s.csv").write_text("100,0,0\n1000,0,0\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "s.csv"\n')
    try:
        well = Well.from_toml(str(tmp_path / "w.toml"))
        well.curve(950.0)
    except DrillingError as exc:
        assert "0 .. 900" not in str(exc), str(exc)


def test_the_printed_operation_is_the_motion_solved(tmp_path):
    # seen: '--operation pick-up --trip-speed -0.5' prints 'operation pick-up' with the slack-off hook load
    # (423709.33 N against pick-up's 423714.89 N at 300 m): the trip speed's sign silently overrides the operation
    up = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--operation", "pick-up")
    mixed = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--operation", "pick-up",
                 "--trip-speed", "-0.5")
    assert up.returncode == 0, up.stderr
    if mixed.returncode == 0:
        assert _value(mixed.stdout, "hook_load") == _value(up.stdout, "hook_load")


def test_rotation_alone_is_not_printed_as_static():
    # seen: '--rpm 120' (no --operation) prints 'operation static' and surface_torque 0.247 N m
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--rpm", "120")
    assert r.returncode == 0, r.stderr
    if float(_value(r.stdout, "surface_torque")) != 0.0:
        assert _value(r.stdout, "operation") != "static"


def test_broomstick_refuses_one_file_for_the_plot_and_the_points(tmp_path):
    # seen: '-o b.h5 --out b.h5' exit 0, prints 'plot b.h5', and only the HDF5 file is left (solve refuses
    # '--out and --joints name the same file')
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.25", "--depth", "100", "150", "--points", "2",
             "-o", "b.h5", "--out", "b.h5", cwd=tmp_path)
    assert r.returncode == 2, r.stdout


def test_broomstick_with_an_unwritable_out_is_a_one_line_error_leaving_no_file(tmp_path):
    # seen: exit 1, 'rodcont: error: FileNotFoundError: [Errno 2] Unable to synchronously create file (... h5py
    # ...)' after every solve has run, and b.png left behind
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.25", "--depth", "100", "150", "--points", "2",
             "-o", "b.png", "--out", str(tmp_path / "nonexist" / "b.h5"), cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert os.listdir(tmp_path) == []


def test_an_interrupted_trip_file_does_not_claim_its_bound(tmp_path, interrupt_solve):
    # seen: Ctrl-C (or SIGTERM) during 'rodcont trace --param depth --range 300 600' leaves a file with points to
    # 420 m whose status is 'bound' and stop_reason 'parameter bound depth = 600 reached'
    import h5py

    import rodcont.drilling as drilling
    from rodcont.drivers.trip import trip
    well, string = drilling.Well.from_toml(WELL), drilling.DrillString.from_toml(STRING)
    interrupt_solve(3)
    out = str(tmp_path / "t.h5")
    with pytest.raises(KeyboardInterrupt):
        trip(well, string, (100.0, 200.0), "slack-off", points=5, out=out)
    with h5py.File(out) as f:
        assert f["branch/depth"].shape[0] == 2
        assert f.attrs["status"] != "bound", f.attrs["stop_reason"]
        assert (f.attrs["status"], f.attrs["stop_reason"]) == ("interrupted", "interrupted")


# ---- 2026-12-03 (stop 35): an adversary's findings on 1c65bd3, each seen as described ----------------------------
def _one_line_error(r, *words):
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in r.stderr, r.stderr


def test_broomstick_refuses_a_friction_factor_given_twice(tmp_path):
    # seen: exit 0, 'hook_load pick-up 0.25 8.063e-320': the second copy's cells were never filled
    from rodcont.drivers.broomstick import broomstick
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.25", "0.25", "--depth", "300", "400",
             "--points", "2", "-o", str(tmp_path / "b.png"), "--out", str(tmp_path / "b.h5"))
    _one_line_error(r, "--friction 0.25 is given twice")
    assert not os.listdir(tmp_path)
    with pytest.raises(ValueError, match="given twice"):
        broomstick(None, None, [300.0], [0.2, 0.2])


def test_broomstick_refuses_a_negative_number_of_jobs(tmp_path):
    # seen: exit 1, 'unexpected failure (ValueError: max_workers must be greater than 0); please report it'
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.25", "--depth", "300", "400", "--points", "2",
             "-o", str(tmp_path / "b.png"), "--jobs", "-1")
    _one_line_error(r, "--jobs")
    assert not os.listdir(tmp_path)


def test_a_weight_on_bit_beyond_the_pipes_axial_stiffness_is_refused(tmp_path):
    # seen: exit 0, hook_load -999386316.67 with the stretch 1 + F/EA at -0.42 (the pipe shortened past zero)
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "400", "--operation", "drill", "--wob", "1e9",
             "--out", str(tmp_path / "p.h5"))
    _one_line_error(r, "compressed past zero length", "weight on bit 1e+09 N")
    assert not os.listdir(tmp_path)


def test_resuming_a_solves_point_file_is_refused_in_one_line(tmp_path):
    # seen: exit 2, 'param must be one of phi_L, T, w, EI, GJ, EA, gamma, torque, l0, got 'depth''; a trip's file
    # is resumed (tests/test_trip_resume.py), a solve's one equilibrium in the same layout is not a trip
    p = str(tmp_path / "p.h5")
    assert _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--operation", "pick-up",
                "--out", p).returncode == 0
    before = open(p, "rb").read()
    _one_line_error(_run("trace", "--resume", p), "holds one equilibrium (rodcont solve --out), not a trip")
    assert open(p, "rb").read() == before


def test_export_refuses_the_well_survey_and_string_files_its_point_was_solved_from(tmp_path):
    # seen: exit 0, the survey replaced by the export's CSV (the next solve on that well: 'expected MD, ...')
    import shutil
    for name in ("well_s3d.toml", "well_s3d.csv", "drill_string.toml"):
        shutil.copy(os.path.join(EXAMPLES, name), tmp_path)
    p = str(tmp_path / "p.h5")
    assert _run("solve", "--conduit", str(tmp_path / "well_s3d.toml"), "--string", str(tmp_path / "drill_string.toml"),
                "--depth", "300", "--operation", "pick-up", "--out", p).returncode == 0
    for name in ("well_s3d.toml", "well_s3d.csv", "drill_string.toml"):
        before = (tmp_path / name).read_bytes()
        r = _run("export", p, "--point", "0", "--format", "csv", "-o", str(tmp_path / name), "--overwrite")
        _one_line_error(r, "is the input file")
        assert (tmp_path / name).read_bytes() == before
    assert _run("export", p, "--point", "0", "-o", str(tmp_path / "ok.csv")).returncode == 0


@pytest.mark.parametrize("option", [["--weight-direction", "1,0,0"], ["--reference", "arc:0.5"], ["--load-step", "7"]])
def test_rod_options_that_a_drill_string_would_ignore_are_refused(option):
    # seen: exit 0 and the hook load of the run without them (423714.8939192088 at 300 m pick-up)
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "300", "--operation", "pick-up", *option)
    _one_line_error(r, f"{option[0]} is not an option of a drill string")


@pytest.mark.parametrize("which", ["well", "string"])
def test_an_unknown_table_in_a_well_or_string_file_is_refused(tmp_path, which):
    # seen: exit 0, a [casing] table in the well file (an [extra] one in the string file) read as nothing
    import shutil
    shutil.copy(os.path.join(EXAMPLES, "well_s3d.csv"), tmp_path)
    well, string = tmp_path / "w.toml", tmp_path / "s.toml"
    well.write_text(open(WELL).read() + ("\n[casing]\ndepth = 500.0\n" if which == "well" else ""))
    string.write_text(open(STRING).read() + ("\n[extra]\nx = 1\n" if which == "string" else ""))
    r = _run("solve", "--conduit", str(well), "--string", str(string), "--depth", "300", "--operation", "pick-up")
    _one_line_error(r, "unknown table(s) or key(s)", "casing" if which == "well" else "extra")


def test_solves_two_outputs_are_published_together(tmp_path, monkeypatch):
    # seen: Ctrl-C 4.6 s into solve --out a.h5 --joints a.csv left a.csv complete and no a.h5 (exit 130)
    import numpy as np

    import rodcont.drivers.trip as trip
    from rodcont.cli.drilling import _write_outputs

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(trip, "write_point", interrupted)
    table = dict(top=np.array([0.0]), bottom=np.array([9.14]), side_force=np.array([1.0]), max_pressure=np.array([2.0]))
    with pytest.raises(KeyboardInterrupt):
        _write_outputs(None, None, None, str(tmp_path / "a.h5"), str(tmp_path / "a.csv"), table, 9.14, False, {},
                       print)
    assert not os.listdir(tmp_path)
    monkeypatch.setattr(trip, "write_point", lambda *a, **k: open(a[3], "w").close())
    _write_outputs(None, None, None, str(tmp_path / "a.h5"), str(tmp_path / "a.csv"), table, 9.14, False, {}, print)
    assert sorted(os.listdir(tmp_path)) == ["a.csv", "a.h5"]
    assert (tmp_path / "a.csv").read_text().splitlines()[1] == "1,0.0,9.14,1.0,2.0"


def test_a_workers_sigterm_is_silent():
    # seen: SIGTERM to a broomstick's process group printed 'rodcont: interrupted' three times (the command and
    # its 2 workers, which inherit the command line's handler); a worker now stops without a word
    code = ("import os, signal, sys, time\n"
            "from rodcont import _interrupted\n"
            "signal.signal(signal.SIGTERM, _interrupted)\n"   # the command line's handler, as a worker inherits it
            "from rodcont.drivers.sweep import _worker_init\n"
            "_worker_init()\n"
            "os.kill(os.getpid(), signal.SIGTERM)\n"
            "time.sleep(30)\n")
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 143 and r.stderr == "", (r.returncode, r.stderr)


@pytest.mark.parametrize("depth", ["1e-300", "0.01", "0.2159"])
def test_a_bit_depth_within_the_holes_diameter_is_refused(tmp_path, depth):
    # seen: --depth 1e-300 'a well needs at least two survey stations', 0.01 'no equilibrium found inside the
    # conduit (contact smoothing eps = 0.0001): singular Jacobian', each after the solve had started
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", depth, "--operation", "pick-up")
    assert r.returncode == 2 and "within the hole's diameter (0.2159 m)" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "hook_load" not in r.stdout
    r = _run("trace", "--param", "depth", "--range", depth, "100", "--conduit", WELL, "--string", STRING,
             "--out", str(tmp_path / "t.h5"))
    assert r.returncode == 2 and "within the hole's diameter" in r.stderr, r.stderr
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.25", "--depth", depth, "100",
             "-o", str(tmp_path / "b.png"))
    assert r.returncode == 2 and "within the hole's diameter" in r.stderr, r.stderr
    assert os.listdir(tmp_path) == []


def test_a_bit_just_deeper_than_the_hole_is_wide_is_solved():
    # the floor is the hole's diameter, not some length above it: 0.22 m of collars hangs in its hole
    from rodcont import drilling
    from rodcont.drivers.broomstick import broomstick
    well, string = drilling.Well.from_toml(WELL), drilling.DrillString.from_toml(STRING)
    with pytest.raises(drilling.DrillingError, match="within the hole's diameter"):
        drilling.torque_and_drag(well, string, 0.2159, "static")
    with pytest.raises(drilling.DrillingError, match="within the hole's diameter"):
        broomstick(well, string, [0.1, 100.0], [0.25], jobs=1)
    r = drilling.torque_and_drag(well, string, 0.22, "static")
    # the top of a vertical hole without friction: the hook load is the buoyed weight of the collars' unstressed
    # length, 0.22 m of hole less their stretch under their own weight (dF/dS = w / (1 + F/EA), F(L) = 0)
    w, EA = 2189.0 * (1 - 1200.0 / 7850.0), 5.88e9
    assert r.hook_load == pytest.approx(w * 0.22 * (1 - w * 0.22 / (2 * EA)), rel=1e-11)


def test_a_solid_section_may_say_id_0_as_it_may_leave_it_out(tmp_path):
    # seen: 'section 1: id must be a positive number, got 0' for a solid bar, whose id left out was read as 0
    from rodcont import drilling
    head = "[string]\nmud_density = 1200.0\nE = 207e9\nG = 80e9\ndensity = 7850.0\n\n[[section]]\nod = 0.1\n"
    strings = []
    for extra in ("id = 0\n", "id = 0.0\n", ""):
        (tmp_path / "s.toml").write_text(head + extra)
        strings.append(drilling.DrillString.from_toml(str(tmp_path / "s.toml")).sections[0])
    assert strings[0] == strings[1] == strings[2]
    # a solid steel rod of 0.1 m: EA = E pi d^2 / 4
    assert strings[0].EA == pytest.approx(207e9 * 3.141592653589793 * 0.01 / 4, rel=1e-14)
    (tmp_path / "s.toml").write_text(head + "id = -0.01\n")
    with pytest.raises(drilling.DrillingError, match="id must be a non-negative number"):
        drilling.DrillString.from_toml(str(tmp_path / "s.toml"))
