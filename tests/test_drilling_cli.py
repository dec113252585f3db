"""The torque-and-drag command line (rodcont.cli_drilling), through the CLI once the lead has registered it
(skipped before: the CLI package is being split; cli_drilling.register(main_group) wires it in)."""

import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(__file__)
EXAMPLES = os.path.join(HERE, "..", "examples")
WELL, STRING = os.path.join(EXAMPLES, "well_s3d.toml"), os.path.join(EXAMPLES, "drill_string.toml")


def _registered() -> bool:
    try:
        from rodcont.cli import main_group
    except Exception:  # noqa: BLE001 - the package mid-split
        return False
    return "broomstick" in getattr(main_group, "commands", {})


pytestmark = pytest.mark.skipif(not _registered(), reason="rodcont broomstick is not registered in the CLI yet")


def _run(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))
    return subprocess.run([sys.executable, "-m", "rodcont", *args], capture_output=True, text=True, env=env, cwd=cwd)


def test_broomstick_writes_the_plot_and_the_points(tmp_path):
    png, h5 = tmp_path / "broom.png", tmp_path / "b.h5"
    r = _run("broomstick", WELL, "--string", STRING, "--friction", "0.2", "0.3", "--depth", "300", "400",
             "--points", "2", "-o", str(png), "--out", str(h5))
    assert r.returncode == 0, r.stderr
    import h5py
    with h5py.File(h5) as f:
        assert f["hook_load"].shape == (2, 3, 2)
        assert list(f["friction"][:]) == [0.2, 0.3]
        # 300 m of vertical hole: no friction, hook load = buoyed weight of the string (200 m collars, 100 m HWDP)
        bf = 1 - 1200 / 7850
        assert f["hook_load"][0, 2, 0] == pytest.approx(bf * (200 * 2189 + 100 * 624), rel=2e-3)
    assert png.stat().st_size > 10000
    assert "hook_load pick-up 0.2 " in r.stdout
    assert f"wrote {h5}" in r.stderr.splitlines() and "wrote" not in r.stdout   # stdout keeps its name value lines
    lines = r.stdout.splitlines()   # the README's: hook_load per operation and mu, the rotating torque, the plot
    names = [f"hook_load {op} {mu}" for op in ("pick-up", "slack-off", "rotate") for mu in ("0.2", "0.3")]
    assert [ln.rsplit(" ", 1)[0] for ln in lines] == names + ["surface_torque rotate 0.2", "surface_torque rotate 0.3",
                                                              "plot"]
    assert lines[-1] == f"plot {png}"


@pytest.mark.parametrize("args, message", [
    (["--friction", "-0.1", "--depth", "300", "400"], "--friction must be"),
    (["--friction", "0.2", "--depth", "400", "300"], "0 < A < B"),
    (["--friction", "0.2", "--depth", "300", "9000"], "beyond the survey"),
])
def test_broomstick_user_errors_are_one_line(tmp_path, args, message):
    r = _run("broomstick", WELL, "--string", STRING, *args, "-o", str(tmp_path / "b.png"))
    assert r.returncode == 2
    assert r.stderr.startswith("rodcont: error:") and message in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "b.png").exists()


def test_trace_in_depth_refuses_what_a_trip_cannot_take(tmp_path):
    """`trace --param depth` is a trip of a drill string: without --string, without --range, with a rod's
    start option, a rod's trace option (it would be ignored), a weight on bit off bottom, or a drilling option on
    a rod's trace, one line and exit 2, no file."""
    out = str(tmp_path / "trip.h5")
    cases = [(["--param", "depth", "--range", "100", "200"], "--string"),
             (["--string", STRING, "--conduit", WELL, "--param", "depth"], "--range A B"),
             (["--string", STRING, "--conduit", WELL, "--param", "depth", "--range", "100", "200",
               "--from-straight", "5"], "--from-straight"),
             (["--string", STRING, "--conduit", WELL, "--param", "T", "--range", "1", "2"], "--param depth"),
             (["--gamma", "1", "--friction", "0.2"], "--friction"),
             (["--string", STRING, "--conduit", WELL, "--param", "depth", "--range", "100", "200", "--ds", "0.2"],
              "--ds"),
             (["--string", STRING, "--conduit", WELL, "--param", "depth", "--range", "100", "200", "--EI", "5"],
              "--EI"),
             (["--string", STRING, "--conduit", WELL, "--param", "depth", "--range", "100", "200", "--wob", "1e4"],
              "drilling")]
    for args, word in cases:
        r = _run("trace", *args, "--out", out)
        assert r.returncode == 2, (args, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("rodcont: error:") and word in lines[0], (args, r.stderr)
        assert not os.path.exists(out)


def test_the_survey_a_well_file_names_is_an_input_of_trips_and_broomsticks(tmp_path):
    """`--out` / `-o` onto the survey CSV that the well file names is refused even with --overwrite (one line,
    exit 2), and the survey stays byte for byte what it was (before: a trip replaced it with its branch file)."""
    import shutil
    for name in ("well_s3d.toml", "well_s3d.csv", "drill_string.toml"):
        shutil.copy(os.path.join(EXAMPLES, name), tmp_path / name)
    survey = tmp_path / "well_s3d.csv"
    before = survey.read_bytes()
    well, string = str(tmp_path / "well_s3d.toml"), str(tmp_path / "drill_string.toml")
    for args in (["trace", "--string", string, "--conduit", well, "--param", "depth", "--range", "200", "210",
                  "--out", str(survey), "--overwrite"],
                 ["broomstick", well, "--string", string, "--friction", "0.2", "--depth", "200", "210",
                  "-o", str(survey), "--overwrite"]):
        r = _run(*args)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("rodcont: error:") and "input" in lines[0], r.stderr
        assert survey.read_bytes() == before


def test_a_trip_echoes_what_it_uses_and_a_string_at_rest_no_negative_zero(tmp_path):
    """A slack-off trip through the vertical top of the well (300-310 m, 11 depths): the problem echoed names the
    string, the well, the joint length, the operation and the depth range, none of a rod's trace options (phi_max,
    ds, ...) nor a weight on bit; the surface torque of a string that does not turn, with no bit torque and no wall
    contact, is printed 0.0 (was -0.0, the sign of M = -m at m = 0)."""
    r = _run("trace", "--string", STRING, "--conduit", WELL, "--param", "depth", "--range", "300", "310",
             "--out", str(tmp_path / "trip.h5"))
    assert r.returncode == 0, r.stderr
    echoed = {line[4:].split(" = ")[0] for line in r.stdout.splitlines() if line.startswith("#   ")}
    assert echoed == {"[drilling]", "string", "joint_length", "[trace]", "conduit", "param", "prange"}, echoed
    assert "surface_torque 0.0" in r.stdout.splitlines()


def test_solve_prints_the_side_force_per_joint_and_writes_the_joints(tmp_path):
    """`solve --string ... --joint-length 10 --joints J.csv` at 505 m (the build from 400 m on, in contact): one row
    per joint from the bit up (51: the top one 5 m), MD from the bit to the rig; the printed largest joint force
    and its MD are the table's, the printed side force its sum (to 1e-3: the printed total is a trapezoid rule); a
    bad joint length: one line, exit 2, no file."""
    import numpy as np
    out = tmp_path / "j.csv"
    r = _run("solve", "--string", STRING, "--conduit", WELL, "--depth", "505", "--joint-length", "10",
             "--joints", str(out))
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.splitlines() if not line.startswith("#"))
    t = np.genfromtxt(out, delimiter=",", names=True)
    assert t["joint"].tolist() == list(range(1, 52)) and t["md_bottom"][0] == 505.0 and t["md_top"][-1] == 0.0
    assert np.allclose(t["md_bottom"] - t["md_top"], [10.0] * 50 + [5.0], rtol=0, atol=1e-9)
    k = int(np.argmax(t["side_force"]))
    assert float(lines["max_joint_side_force"]) == t["side_force"][k]
    assert [float(v) for v in lines["max_joint_side_force_md"].split()] == [t["md_top"][k], t["md_bottom"][k]]
    assert float(lines["side_force"]) == pytest.approx(t["side_force"].sum(), rel=1e-3)
    # the printed largest force per length is a row's, at an MD inside that row's joint (it had been the profile's
    # own maximum, 7e-5 above every row at 500 m pick-up)
    m = int(np.argmax(t["max_side_force_per_length"]))
    assert float(lines["max_side_force_per_length"]) == t["max_side_force_per_length"][m] > 0
    assert t["md_top"][m] <= float(lines["max_side_force_per_length_md"]) <= t["md_bottom"][m]
    bad = tmp_path / "bad.csv"
    r = _run("solve", "--string", STRING, "--conduit", WELL, "--depth", "305", "--joint-length", "0",
             "--joints", str(bad))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--joint-length" in r.stderr
    assert not bad.exists()


def test_solve_of_a_string_reads_its_guard_and_cap_and_refuses_the_rods_options(tmp_path):
    """`solve --string` read neither --max-error nor --N-max (a guard of 1e-12 returned 2.7e-9 on N 1016, rc 0,
    silent) and dropped --EI: the guard and the cap now reach the solve, which says where it stops above its guard
    (the mesh at its cap); a rod's own option is refused in one line. The echoed problem runs again as --config."""
    common = ("solve", "--conduit", WELL, "--string", STRING, "--depth", "500", "--operation", "rotate")
    r = _run(*common, "--N-max", "1100", "--max-error", "1e-12")
    assert r.returncode == 0, r.stderr
    out = dict(line.split(" ", 1) for line in r.stdout.splitlines() if not line.startswith("#"))
    assert int(out["N"]) <= 1110 and float(out["error"]) > 1e-12
    assert "above its guard" in r.stderr and "max_error 1e-12" in r.stderr
    assert "#   N_max = 1100" in r.stdout and "#   max_error = 1e-12" in r.stdout
    for bad in (["--EI", "3"], ["--uniform"]):
        r = _run(*common, *bad, "--out", str(tmp_path / "p.h5"))
        assert r.returncode == 2 and r.stderr.startswith("rodcont: error:") and r.stderr.count("\n") == 1, r.stderr
        assert f"{bad[0]} is not an option of a drill string" in r.stderr
        assert not (tmp_path / "p.h5").exists()
    r = _run(*common, "--max-error", "1e-7")
    conf = tmp_path / "as_run.toml"
    conf.write_text("\n".join(line[4:] for line in r.stdout.splitlines() if line.startswith("#   ")))
    again = _run("solve", "--config", str(conf))
    assert again.returncode == 0, again.stderr
    assert [ln for ln in again.stdout.splitlines() if not ln.startswith("#")] == \
        [ln for ln in r.stdout.splitlines() if not ln.startswith("#")]


def test_a_first_mesh_above_the_cap_is_refused_in_one_line(tmp_path):
    """--N 5000 with the default --N-max 4000 started a mesh above the cap (the cap then none); the rod's solve
    refuses it, and so does a drill string's, in the API (DrillingError) and in one line at exit 2, no file."""
    from rodcont import drilling
    well = drilling.Well.from_toml(WELL)
    string = drilling.DrillString.from_toml(STRING)
    with pytest.raises(drilling.DrillingError, match=r"N = 5000 must lie in 1 \.\. N_max = 4000"):
        drilling.torque_and_drag(well, string, 500.0, "rotate", mu=0.25, N=5000)
    with pytest.raises(drilling.DrillingError, match="N_max must be an integer >= 1"):
        drilling.torque_and_drag(well, string, 500.0, N_max=0)
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "500", "--N", "5000",
             "--out", str(tmp_path / "p.h5"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "N = 5000 must lie in 1 .. N_max = 4000 (raise N_max for a larger mesh)" in r.stderr
    assert not (tmp_path / "p.h5").exists()


def test_an_interrupted_trip_says_how_many_depths_its_file_holds(tmp_path, interrupt_solve, capsys):
    from rodcont.cli.drilling import DRILLING_KEYS, run_drilling_trace
    interrupt_solve(3)
    values = {key: None for key in DRILLING_KEYS}
    values["string"] = STRING
    out = str(tmp_path / "t.h5")
    with pytest.raises(SystemExit) as stop:
        run_drilling_trace(WELL, values, "depth", (100.0, 200.0), out, points=5)
    assert stop.value.code == 130
    assert "interrupted: " + out + " holds the 2 completed depth(s) of the trip; go on with rodcont trace " \
        "--resume " + out in capsys.readouterr().err
    interrupt_solve(1)
    with pytest.raises(SystemExit):
        run_drilling_trace(WELL, values, "depth", (100.0, 200.0), str(tmp_path / "u.h5"), points=5)
    assert "interrupted before the first depth" in capsys.readouterr().err


def test_a_joint_length_giving_too_many_joints_is_refused_first(tmp_path):
    # --joint-length 1e-4 at 600 m solved (4 s), then asked 45.8 GiB for 6 million joints and advised a smaller mesh
    r = _run("solve", "--conduit", WELL, "--string", STRING, "--depth", "600", "--joint-length", "1e-4",
             "--joints", str(tmp_path / "j.csv"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "a joint length of 0.0001 m makes 6e+06 joints over 600 m: at most 100000" in r.stderr
    assert not (tmp_path / "j.csv").exists() and "hook_load" not in r.stdout
    r = _run("trace", "--conduit", WELL, "--string", STRING, "--param", "depth", "--range", "300", "600",
             "--joint-length", "1e-4", "--out", str(tmp_path / "t.h5"))   # a trip too, before its first depth
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "makes 6e+06 joints over 600 m" in r.stderr and not (tmp_path / "t.h5").exists()
