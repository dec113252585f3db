"""The command line as a user meets it: outputs, bad input, interrupts, restarts."""

import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

import rodcont
from conftest import assert_picture, run
from rodcont.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def assert_one_line_error(code, out, err):
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("rodcont: error:")
    assert "Traceback" not in err + out


# --------------------------------------------------------------------------
# solve
# --------------------------------------------------------------------------
def test_solve_prints_name_value_pairs(capsys):
    code, out, err = run(["solve", "--gamma", "1", "--phi", "10"], capsys)
    assert code == 0
    values = dict(line.split() for line in out.strip().splitlines() if not line.startswith("#"))
    for name in ("stretch", "torque", "l0", "helical_waves", "min_alignment", "newton_iterations", "residual_norm"):
        assert name in values
    assert float(values["stretch"]) == pytest.approx(3.1059074e-3, abs=1e-10)
    assert len(values["stretch"].replace("-", "").replace(".", "").lstrip("0").split("e")[0]) >= 10


@pytest.mark.parametrize("args", [
    ["solve", "--gamma", "1", "--phi", "abc"],
    ["solve", "--gamma", "nan", "--phi", "1"],
    ["solve", "--gamma", "1", "--phi", "1", "--EI", "-1"],
    ["solve", "--gamma", "1", "--phi", "1", "--GJ", "0"],
    ["solve", "--gamma", "1", "--phi", "1", "--EA", "inf"],
    ["solve", "--gamma", "1", "--phi", "1", "--L", "0"],
    ["solve", "--gamma", "1", "--phi", "1", "--w", "-3"],
    ["solve", "--gamma", "1", "--phi", "1", "--k", "0"],
    ["solve", "--gamma", "1", "--phi", "1", "--k", "8"],
    ["solve", "--gamma", "1", "--phi", "1", "--N", "0"],
    ["solve", "--gamma", "1", "--phi", "1", "--N", "x"],
    ["solve", "--gamma", "-5", "--phi", "1"],  # below the Euler load -4 pi^2 EI / (w L^3) = -3.948
    ["solve", "--phi", "1"],
    ["solve", "--gamma", "1", "--phi", "14"],  # beyond the first fold: natural loading cannot get there
    ["nonsense"],
])
def test_solve_bad_input(args, capsys):
    code, out, err = run(args, capsys)
    assert_one_line_error(code, out, err)


def test_compressed_start_above_the_euler_load_is_accepted(capsys):
    code, out, err = run(["solve", "--gamma", "-2", "--phi", "1"], capsys)
    assert code == 0, err


# --------------------------------------------------------------------------
# trace, folds, plot, shape
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def g1_file(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("br") / "g1.h5")
    with pytest.raises(SystemExit) as exc:
        main(["trace", "--gamma", "1", "--out", path, "--quiet"])
    assert exc.value.code == 0
    return path


def test_trace_writes_a_branch_file(g1_file, capsys):
    with h5py.File(g1_file, "r") as f:
        for name in ("rodcont_version", "gamma", "w", "EI", "GJ", "EA", "L", "N", "k", "stop_reason"):
            assert name in f.attrs
        n = f["branch/phi_L"].shape[0]
        for name in ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "arclength"):
            assert f["branch"][name].shape == (n,)
        assert f["branch/helical_waves"].dtype.kind == "i"
        for name in ("phi_L", "stretch", "torque", "l0", "waves_before", "waves_after", "index"):
            assert f["folds"][name].shape == (1,)
        assert f["folds/phi_L"][0] == pytest.approx(13.0999938, abs=1e-6)
        assert f.attrs["stop_reason"].startswith("validity guard")  # the adaptive mesh gets there
    code, out, err = run(["folds", g1_file], capsys)
    assert code == 0 and "13.0999938" in out


def test_plot_and_shape(g1_file, tmp_path, capsys):
    png = tmp_path / "d.png"
    code, out, err = run(["plot", g1_file, "-o", str(png)], capsys)
    assert code == 0
    assert_picture(png)
    png2 = tmp_path / "s.png"
    code, out, err = run(["shape", g1_file, "--point", "F1", "--point", "0", "-o", str(png2)], capsys)
    assert code == 0
    assert_picture(png2)


def test_bad_files_and_paths(g1_file, tmp_path, capsys):
    not_h5 = tmp_path / "text.h5"
    not_h5.write_text("hello")
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.arange(3)
    cases = [
        ["folds", str(tmp_path / "missing.h5")],
        ["folds", str(not_h5)],
        ["folds", str(foreign)],
        ["folds", str(tmp_path)],
        ["plot", str(not_h5), "-o", str(tmp_path / "p.png")],
        ["plot", g1_file, "-o", str(tmp_path / "nodir" / "p.png")],
        ["shape", g1_file, "--point", "999", "-o", str(tmp_path / "s.png")],
        ["shape", g1_file, "--point", "F7", "-o", str(tmp_path / "s.png")],
        ["shape", g1_file, "--point", "abc", "-o", str(tmp_path / "s.png")],
        ["trace", "--gamma", "1", "--out", str(tmp_path / "nodir" / "t.h5")],
        ["trace", "--gamma", "1", "--k", "9", "--out", str(tmp_path / "t.h5")],
        ["trace", "--gamma", "-10", "--out", str(tmp_path / "t.h5")],
        ["trace", "--gamma", "1", "--ds", "1", "--ds-max", "0.1", "--out", str(tmp_path / "t.h5")],
        ["trace", "--gamma", "1", "--ds", "0.01", "--ds-min", "0.1", "--out", str(tmp_path / "t.h5")],
        ["trace", "--gamma", "1", "--min-alignment", "1.5", "--out", str(tmp_path / "t.h5")],
        ["trace", "--start", str(not_h5) + ":0", "--out", str(tmp_path / "t.h5")],
        ["trace", "--start", str(foreign) + ":0", "--out", str(tmp_path / "t.h5")],
        ["trace", "--start", g1_file, "--out", str(tmp_path / "t.h5")],
        ["trace", "--start", g1_file + ":BP1", "--out", str(tmp_path / "t.h5")],
        ["trace", "--out", str(tmp_path / "t.h5")],
    ]
    for args in cases:
        code, out, err = run(args, capsys)
        assert_one_line_error(code, out, err)
    assert not (tmp_path / "t.h5").exists()
    assert not (tmp_path / "p.png").exists()


def test_non_convergence_is_a_stop_reason(tmp_path, capsys):
    """An absurd step that may not shrink (ds = ds_min = 5) cannot converge past the first points:
    the trace stops, keeps what it had, and says why, in the file and to the user."""
    out = tmp_path / "bad.h5"
    code, stdout, err = run(["trace", "--gamma", "1", "--ds", "5", "--ds-max", "5", "--ds-min", "5",
                             "--out", str(out), "--quiet"], capsys)
    data = rodcont.load_branch(str(out))
    assert code == 0
    reason = data.attrs["stop_reason"]
    assert reason.startswith("step size fell below ds_min = 5 (the corrector")
    assert reason in stdout
    assert len(data) >= 1


def test_interrupted_trace_leaves_a_valid_file_and_restarts(tmp_path):
    """SIGINT mid-run: the branch file loads and holds every completed point; --start continues."""
    out = tmp_path / "int.h5"
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"), OPENBLAS_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, os.path.join(ROOT, "cli.py"), "trace", "--gamma", "1", "--N", "40",
                             "--ds-max", "0.05", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    deadline = time.monotonic() + 600  # only bounds a hung run: the wait is for points on disk, not for a time
    n = 0
    while time.monotonic() < deadline and proc.poll() is None:  # wait until some points are on disk
        time.sleep(0.05)
        try:
            with h5py.File(out, "r", locking=False) as f:
                n = f["branch/phi_L"].shape[0]
        except (OSError, KeyError):
            continue
        if n >= 5:
            break
    assert n >= 5, "the trace wrote no points"
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert "Traceback" not in stderr
    data = rodcont.load_branch(str(out))
    assert data.attrs["stop_reason"] == "interrupted"
    assert len(data) >= n
    # every stored point is a solution
    from rodcont.linalg import LU, bordered
    from rodcont.system import RodSystem
    for i in range(len(data)):
        # on its own mesh (the trace adapts it: N may have grown from 40), a Newton step of the
        # continuation (bordered by the stored tangent: regular at folds too) moves the stored point by
        # less than the corrector's tolerance: it is a converged solution (the raw residual grows like
        # 1/h^2 on refined meshes, so it says less)
        pt = data.point(i)
        sysm = RodSystem(data.rod, data.gamma, k=5, breakpoints=pt["breakpoints"])
        F, J, Fp = sysm.linearise(pt["x"], data.branch["phi_L"][i])
        tx, tp = pt["direction"]
        step = LU(bordered(J, Fp, tx, tp)).solve(np.append(F, 0.0))
        assert np.max(np.abs(step)) < 1e-9 * (1 + np.max(np.abs(pt["x"])))
    # and a second run continues from the last point
    out2 = tmp_path / "cont.h5"
    r = subprocess.run([sys.executable, os.path.join(ROOT, "cli.py"), "trace", "--start", f"{out}:-1",
                        "--phi-max", str(data.branch["phi_L"][-1] + 1.0), "--out", str(out2), "--quiet"],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    cont = rodcont.load_branch(str(out2))
    assert cont.branch["phi_L"][0] == pytest.approx(data.branch["phi_L"][-1], abs=1e-9)
    # it goes on, not back: the stretch grows monotonically along this branch (Phi does not: if the
    # interrupt came close to the fold at 13.10, the continuation passes it and Phi falls again)
    # (the last point may be the validity guard, located to 1e-6 of the step's change of min d3.K3: when
    # the point before it already lay within that band, the located guard can sit a hair before it)
    stretch = cont.branch["stretch"]
    assert len(cont) > 2 and np.all(np.diff(stretch[:-1]) > 0) and stretch[-1] > stretch[-2] * (1 - 1e-6)


def test_python_cli_entry_matches_console_script():
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"))
    r = subprocess.run([sys.executable, os.path.join(ROOT, "cli.py"), "solve", "--gamma", "1", "--phi", "0"],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0
    assert "stretch 0.000924497" in r.stdout


def test_restart_from_a_fold_goes_on_past_it(g1_file, tmp_path, capsys):
    """--start FILE:F1: the start is regular at the fold (bordered Newton), the fold is not reported
    twice, and the trace goes on along the branch, beyond the fold."""
    out = tmp_path / "f1.h5"
    code, stdout, err = run(["trace", "--start", f"{g1_file}:F1", "--max-steps", "5", "--out", str(out),
                             "--quiet"], capsys)
    assert code == 0, err
    d = rodcont.load_branch(str(out))
    ref = rodcont.load_branch(g1_file)
    assert d.branch["phi_L"][0] == pytest.approx(ref.folds["phi_L"][0], abs=1e-10)
    assert len(d.folds.get("index", [])) == 0
    assert np.all(np.diff(d.branch["stretch"]) > 0) and d.branch["phi_L"][-1] < d.branch["phi_L"][0]


def test_a_restart_on_another_mesh_keeps_the_reference_curve(tmp_path, capsys):
    """--start F:i --N 30 from a trace on a bump reference: the point is moved to the new mesh of the same
    curve (it was moved to a straight-line mesh and re-solved there: stretch -5.2e-3 for 9.7e-4)."""
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    code, _, err = run(["trace", "--gamma", "1", "--phi-max", "3", "--reference", "bump:0.05,0.3",
                        "--out", str(a), "--quiet"], capsys)
    assert code == 0, err
    code, _, err = run(["trace", "--start", f"{a}:5", "--N", "30", "--phi-max", "4", "--out", str(b),
                        "--quiet"], capsys)
    assert code == 0, err
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert fb.attrs["reference"] == "bump:0.05,0.3"
        # the same equilibrium, to the discretisation error of the coarser mesh
        assert abs(fb["branch/stretch"][0] - fa["branch/stretch"][5]) < 1e-8
        assert abs(fb["branch/phi_L"][0] - fa["branch/phi_L"][5]) < 1e-8


def test_a_restart_echoes_the_start_files_problem_not_the_defaults(tmp_path, capsys):
    a = tmp_path / "a.h5"
    code, _, err = run(["trace", "--gamma", "1", "--EI", "2", "--phi-max", "1", "--out", str(a), "--quiet"],
                       capsys)
    assert code == 0, err
    code, out, err = run(["trace", "--start", f"{a}:1", "--phi-max", "2", "--out", str(tmp_path / "b.h5"),
                          "--quiet"], capsys)
    assert code == 0, err
    echo = [line for line in out.splitlines() if line.startswith("#")]
    assert any(f"those of --start {a}:1" in line for line in echo)
    assert not any(line.split("=")[0].strip("# ") in ("EI", "w", "gamma", "reference", "L") for line in echo)


def test_a_restart_refuses_another_k_instead_of_ignoring_it(tmp_path, capsys):
    a = tmp_path / "a.h5"
    code, _, err = run(["trace", "--gamma", "1", "--phi-max", "1", "--out", str(a), "--quiet"], capsys)
    assert code == 0, err
    code, out, err = run(["trace", "--start", f"{a}:1", "--k", "7", "--out", str(tmp_path / "b.h5")], capsys)
    assert code == 2 and "--k 7 differs from the start file's k = 5" in err
    assert "k = 7" not in out  # the problem echoed before the refusal does not claim the refused degree


def test_a_restart_refuses_a_new_weight_direction_and_span_with_advice_that_runs(tmp_path, capsys):
    a = tmp_path / "a.h5"
    code, _, err = run(["trace", "--gamma", "1", "--phi-max", "1", "--out", str(a), "--quiet"], capsys)
    assert code == 0, err
    code, _, err = run(["trace", "--start", f"{a}:1", "--weight-direction", "0,1,0", "--out", str(tmp_path / "b.h5")],
                       capsys)
    assert code == 2 and "--weight-direction differs" in err and "--param" not in err
    code, _, err = run(["trace", "--start", f"{a}:1", "--L", "2", "--out", str(tmp_path / "b.h5")], capsys)
    assert code == 2 and "--L differs" in err and "--param L" not in err
    code, _, err = run(["trace", "--start", f"{a}:1", "--w", "3", "--out", str(tmp_path / "b.h5")], capsys)
    assert code == 2 and "--param w --range A B" in err


def test_the_fold_table_of_a_branch_in_t_gives_the_tension_of_each_fold(tmp_path, capsys):
    """A branch traced in T folds in T: `folds` leads each row with T, the value a user restarts or
    compares at (the Phi-fold of the Gamma = 1 branch, seen from fixed Phi just below it, folds in T
    just below the branch's T = 10, where the point's own stored T says)."""
    a, t = tmp_path / "a.h5", tmp_path / "t.h5"
    assert run(["trace", "--gamma", "1", "--phi-max", "14", "--out", str(a), "--quiet"], capsys)[0] == 0
    from rodcont.branchfile import load_branch
    before = int(load_branch(str(a)).folds["index"][0]) - 1  # the stored point just before the Phi-fold
    code, _, err = run(["trace", "--start", f"{a}:{before}", "--param", "T", "--range", "-40", "30",
                        "--direction", "down",
                        "--out", str(t), "--quiet"], capsys)
    assert code == 0, err
    code, out, _ = run(["folds", str(t)], capsys)
    head, row = [line.split() for line in out.splitlines()[1:3]]
    assert head[:4] == ["fold", "index", "T", "phi_L"]
    d = load_branch(str(t))
    assert float(row[2]) == pytest.approx(float(d.point(int(row[1]))["T"]), rel=1e-11)
    assert 9.9 < float(row[2]) < 10.0 and float(row[3]) == pytest.approx(13.0995, abs=1e-3)


def test_a_trace_in_t_starts_at_a_fold_in_phi_where_its_jacobian_is_singular(tmp_path, capsys):
    """At a Phi-fold, J (at fixed Phi) is singular, so the start of a trace in T can neither solve at
    fixed T nor border the tangent with (0, 1) (it once stopped: "no convergence at the starting point").
    It starts along the null vector of [J, F_T] instead; up and down leave the fold on either side."""
    a = tmp_path / "a.h5"
    assert run(["trace", "--gamma", "1", "--phi-max", "14", "--out", str(a), "--quiet"], capsys)[0] == 0
    from rodcont.branchfile import load_branch
    sides = []
    for way in ("up", "down"):
        t = tmp_path / f"{way}.h5"
        code, _, err = run(["trace", "--start", f"{a}:F1", "--param", "T", "--range", "-40", "30", "--direction", way,
                            "--out", str(t), "--quiet"], capsys)
        assert code == 0, err
        assert "is a fold in T too" in err  # the user is told why --direction picks a side, not a way
        d = load_branch(str(t))
        assert not any(int(i) <= 1 for i in d.folds.get("index", []))  # the start is not reported as a fold
        p0, p1 = d.point(0), d.point(1)
        assert float(p0["T"]) == pytest.approx(10.0, abs=1e-9)
        assert float(p0["phi_L"]) == pytest.approx(13.0999938, abs=1e-6)
        sides.append(np.sign(float(p1["stretch"]) - float(p0["stretch"])))
    assert sides[0] == -sides[1]
    # in w the start once reported a fold 2e-12 from itself, "stable on both sides"
    code, _, err = run(["trace", "--start", f"{a}:F1", "--param", "w", "--range", "5", "20", "--out",
                        str(tmp_path / "w.h5"), "--quiet"], capsys)
    assert code == 0, err
    assert not len(load_branch(str(tmp_path / "w.h5")).folds.get("index", []))
    # on a finer mesh the fold moves (by 1e-9): the start corrects the point near it along the null vector
    t = tmp_path / "fine.h5"
    code, _, err = run(["trace", "--start", f"{a}:F1", "--param", "T", "--range", "-40", "30", "--N", "30",
                        "--out", str(t), "--quiet"], capsys)
    assert code == 0, err
    assert float(load_branch(str(t)).point(0)["T"]) == pytest.approx(10.0, abs=1e-6)


def test_a_tension_that_stretches_the_rod_by_half_its_length_is_warned_as_a_forgotten_ea(capsys):
    """A 100 kN pull on a rod with the paper's dimensionless EA = 255 stretches it 392-fold: the answer is
    right for that rod and useless for a drill pipe; the user is told which option they likely forgot."""
    code, _, err = run(["solve", "--T", "200", "--phi", "0"], capsys)
    assert code == 0 and "T/EA = 0.784" in err and "the paper default" in err and "--EA" in err
    code, _, err = run(["solve", "--T", "200", "--EA", "1e6", "--phi", "0"], capsys)
    assert code == 0 and "warning" not in err
    code, _, err = run(["solve", "--gamma", "5", "--phi", "0"], capsys)  # T/EA = 0.2: a rubber rod, not warned
    assert code == 0 and "warning" not in err
    # a refused command gives its one-line error alone; every command that builds a rod warns, sweep too
    code, _, err = run(["solve", "--T", "200", "--phi", "1", "--conduit", "/nonexistent.toml"], capsys)
    assert code == 2 and "warning" not in err and err.count("\n") == 1
    code, _, err = run(["sweep", "--gamma", "20", "--phi-max", "0.2", "--out", "/nonexistent-dir/x"], capsys)
    assert code == 2 and "warning" not in err


def test_a_trace_in_t_whose_range_passes_half_of_ea_is_warned(tmp_path, capsys):
    a = tmp_path / "a.h5"
    assert run(["trace", "--gamma", "1", "--phi-max", "1", "--out", str(a), "--quiet"], capsys)[0] == 0
    code, _, err = run(["trace", "--start", f"{a}:3", "--param", "T", "--range", "0", "1000", "--out",
                        str(tmp_path / "t.h5"), "--quiet"], capsys)
    assert code == 0 and "T = 1000 stretches the rod by T/EA = 3.92" in err
    code, _, err = run(["trace", "--start", f"{a}:3", "--param", "T", "--range", "0", "100", "--out",
                        str(tmp_path / "u.h5"), "--quiet"], capsys)
    assert code == 0 and "warning" not in err


def test_a_restart_in_another_parameter_starts_at_the_stored_point_of_a_trace_in_a_parameter(tmp_path, capsys):
    """A point of a trace in w has its own w: a trace in T from it starts there, with that w (it once took
    the file's starting w = 10 and began at another point of the branch, without a word)."""
    g, w, t = tmp_path / "g.h5", tmp_path / "w.h5", tmp_path / "t.h5"
    assert run(["trace", "--gamma", "1", "--phi-max", "6", "--out", str(g), "--quiet"], capsys)[0] == 0
    assert run(["trace", "--start", f"{g}:10", "--param", "w", "--range", "2", "30", "--out", str(w), "--quiet"],
               capsys)[0] == 0
    code, _, err = run(["trace", "--start", f"{w}:-1", "--param", "T", "--range", "0", "100", "--out", str(t),
                        "--quiet"], capsys)
    assert code == 0, err
    a, b = rodcont.load_branch(str(w)), rodcont.load_branch(str(t))
    last, first = a.point(len(a) - 1), b.point(0)
    assert float(last["w"]) == pytest.approx(30.0) and b.rod.w == pytest.approx(30.0)
    assert float(first["stretch"]) == pytest.approx(float(last["stretch"]), abs=1e-9)
    assert float(first["phi_L"]) == pytest.approx(float(last["phi_L"]), abs=1e-12)


def test_a_restart_accepts_options_equal_to_the_stored_point_and_refuses_others(tmp_path, capsys):
    """A script that always passes the rod's options restarts without a 'differs' (it once refused
    --gamma 1 on a Gamma = 1 file); a value that does differ is still refused."""
    a = tmp_path / "a.h5"
    assert run(["trace", "--gamma", "1", "--phi-max", "2", "--out", str(a), "--quiet"], capsys)[0] == 0
    code, _, err = run(["trace", "--start", f"{a}:3", "--gamma", "1", "--w", "10", "--EA", "255", "--phi-max", "3",
                        "--out", str(tmp_path / "b.h5"), "--quiet"], capsys)
    assert code == 0, err
    code, _, err = run(["trace", "--start", f"{a}:3", "--gamma", "1", "--EI", "2", "--out", str(tmp_path / "c.h5")],
                       capsys)
    assert code == 2 and err.startswith("rodcont: error: --EI differs")


def test_a_fold_detected_but_not_located_is_said_in_the_summary_and_the_file(tmp_path, capsys, monkeypatch):
    """A fold whose location fails (no point of the bracket converges) is not dropped silently: the summary
    warns with its bracket and the branch file keeps it in the ``unlocated`` attribute."""
    import json

    from rodcont.continuation import Tracker
    monkeypatch.setattr(Tracker, "locate", lambda self, *a, **k: None)
    out = tmp_path / "b.h5"
    code, stdout, err = run(["trace", "--gamma", "1", "--phi-max", "14", "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    assert "folds        0" in stdout
    line, = [s for s in stdout.splitlines() if s.startswith("warning      a fold between phi_L = ")]
    a, b = (float(v) for v in line.split("phi_L = ")[1].split(" was")[0].split(" and "))
    # the step that turned: both ends just below the fold's Phi (13.0999938230 where it is located)
    assert 13.09 < min(a, b) and max(a, b) < 13.0999938231 and a != b
    with h5py.File(out, "r") as f:
        (kind, fa, fb), = json.loads(f.attrs["unlocated"])
    assert kind == "fold" and fa == pytest.approx(a, rel=1e-9) and fb == pytest.approx(b, rel=1e-9)
