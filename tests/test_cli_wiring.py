"""The command line's wiring to the library: options made from the settings dataclasses, warnings and names
the library gives reaching the user, columns of plot and export, drilling, Dask and process pools."""

from dataclasses import fields

import numpy as np
import pytest

from conftest import run
from rodcont.cli import main_group
from rodcont.settings import TraceOptions


def assert_one_line_error(code, out, err, *fragments):
    assert code == 2, (code, out, err)
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("rodcont: error:"), err
    for f in fragments:
        assert f in lines[0], (f, lines[0])


# --------------------------------------------------------------------------
# Trace options from TraceOptions' fields (issue 21 item 4)
# --------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["trace", "diagram", "sweep"])
def test_trace_options_are_the_fields_of_trace_options(command):
    params = {p.name: p for p in main_group.commands[command].params}
    shared = [f for f in fields(TraceOptions) if f.metadata["option"]]
    assert len(shared) == 13
    for f in shared:
        p = params["uniform" if f.name == "adapt" else f.name]
        assert p.help == f.metadata["help"]
        if f.name == "adapt":
            assert p.is_flag and f.default is True  # --uniform turns adapt off
        elif f.name == "forced":
            assert p.multiple and f.default == ()
        else:
            assert p.default == f.default, f.name


@pytest.mark.parametrize("option, value, field", [
    ("--min-alignment", "1", "min_alignment"), ("--min-alignment", "-0.1", "min_alignment"),
    ("--ds", "0", "ds"), ("--fold-error", "-1e-9", "fold_error"), ("--forced", "inf", "forced"),
    ("--N-max", "20001", "N_max"), ("--max-steps", "0", "max_steps"),
])
def test_a_value_the_field_refuses_the_option_refuses(option, value, field, tmp_path, capsys):
    number = float(value)
    with pytest.raises(ValueError if field not in ("N_max", "max_steps") else (ValueError, TypeError)):
        TraceOptions(**{field: (number,) if field == "forced" else
                        int(number) if field in ("N_max", "max_steps") else number})
    code, out, err = run(["trace", "--gamma", "1", option, value, "--out", tmp_path / "t.h5"], capsys)
    assert_one_line_error(code, out, err, option)
    assert not (tmp_path / "t.h5").exists()


def test_relations_between_options_are_the_library_s_named_as_options(tmp_path, capsys):
    with pytest.raises(ValueError, match="need ds_min <= ds <= ds_max"):
        TraceOptions(ds=1.0)
    code, out, err = run(["trace", "--gamma", "1", "--ds", "1", "--out", tmp_path / "t.h5"], capsys)
    assert_one_line_error(code, out, err, "need --ds-min <= --ds <= --ds-max, got 1e-06, 1, 0.5")
    code, out, err = run(["diagram", "--gamma", "1", "--phi-min", "3", "--phi-max", "2", "--out", tmp_path / "d.h5"],
                         capsys)
    assert_one_line_error(code, out, err, "--phi-min must be below --phi-max")


# --------------------------------------------------------------------------
# Warnings reach the user (issue 22 item 15)
# --------------------------------------------------------------------------
def test_the_library_s_warnings_are_said_and_numpy_s_noise_is_not(capsys):
    import warnings

    import click
    import numpy as np

    @main_group.command("warns-for-the-test")
    def warns():
        with np.errstate(over="warn"):
            np.float64(1e308) * np.float64(10.0)  # numpy: "overflow encountered in scalar multiply"
        warnings.warn("the library's own\n   warning", RuntimeWarning, stacklevel=1)
        click.echo("done")

    try:
        code, out, err = run(["warns-for-the-test"], capsys)
    finally:
        del main_group.commands["warns-for-the-test"]
    assert code == 0 and out == "done\n"
    assert err == "rodcont: warning: the library's own warning\n"


def test_a_weightless_rod_is_told_why_its_crossings_hide(tmp_path, capsys):
    """The straight weightless rod under length control buckles at its critical twist (13.4626) with two
    eigenvalues at once (a circle of helical modes): the library says so and what separates them (a weight
    across the axis), and the command line passes that on, not the advice of a smaller step."""
    code, out, err = run(["trace", "--w", "0", "--l0", "0.97", "--from-straight", "5", "--phi-max", "18",
                          "--out", tmp_path / "w0.h5", "--quiet"], capsys)
    assert code == 0, err
    line, = [ln for ln in out.splitlines() if ln.startswith("warning      unstable modes 0 -> 2")]
    assert "cross in pairs: a weight across the axis" in line and "--ds-max" not in line
    said = [ln for ln in err.splitlines() if ln.startswith("rodcont: warning: the number of unstable modes")]
    assert len(said) == 1 and "cross in pairs" in said[0]
    a, b = (float(v) for v in line.split("between phi_L = ")[1].split(":")[0].split(" and "))
    assert a < 13.462584514002 < b  # the closed-form critical twist (rodcont critical --w 0 --T 7.8866)


# --------------------------------------------------------------------------
# Names (issue 22 item 16)
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def g1_fold(tmp_path_factory):
    """The primary branch at Gamma = 1 through its first fold."""
    import contextlib
    import io

    from rodcont.cli import main
    path = tmp_path_factory.mktemp("names") / "g1.h5"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()), \
            pytest.raises(SystemExit) as exc:
        main(["trace", "--gamma", "1", "--phi-max", "15", "--out", str(path), "--quiet"])
    assert exc.value.code == 0
    return path


def test_fold_curve_takes_the_fold_labels_folds_prints(g1_fold, tmp_path, capsys):
    import h5py
    code, out, err = run(["folds", g1_fold], capsys)
    assert code == 0 and out.splitlines()[2].startswith("F1 ")
    rows = {}
    for spec in ("0", "F1"):
        code, out, err = run(["fold-curve", f"{g1_fold}:{spec}", "--range", "0.95", "1.05", "--out",
                              tmp_path / f"c{spec}.h5", "--quiet"], capsys)
        assert code == 0, err
        assert "stop reasons down: parameter bound gamma_min = 0.95 reached; up: parameter bound gamma_max = 1.05" \
            in out
        with h5py.File(tmp_path / f"c{spec}.h5", "r") as f:
            rows[spec] = (f["branch/gamma"][()], f["branch/phi_L"][()])
    assert (rows["0"][0] == rows["F1"][0]).all() and (rows["0"][1] == rows["F1"][1]).all()
    code, out, err = run(["fold-curve", f"{g1_fold}:F2", "--range", "0.95", "1.05", "--out", tmp_path / "x.h5"],
                         capsys)
    assert_one_line_error(code, out, err, "F2")


def test_a_trace_in_T_speaks_of_T(tmp_path, capsys):
    code, out, err = run(["trace", "--gamma", "1", "--phi-max", "2", "--out", tmp_path / "a.h5", "--quiet"], capsys)
    assert code == 0, err
    code, out, err = run(["trace", "--start", f"{tmp_path / 'a.h5'}:-1", "--param", "T", "--range", "5", "12",
                          "--out", tmp_path / "b.h5"], capsys)
    assert code == 0, err
    assert "stop reason  parameter bound T_max = 12 reached" in out
    assert "  bound          at T = 12, stretch = " in err and "Phi =" not in err
    assert "point     1  T        10  Phi   2.00000" in err  # the start: T = gamma w L = 10, at Phi = 2
    code, out, err = run(["trace", "--start", f"{tmp_path / 'a.h5'}:-1", "--param", "T", "--range", "20", "30",
                          "--out", tmp_path / "c.h5"], capsys)
    assert_one_line_error(code, out, err, "the start T = 10 is outside the bounds [20, 30]")


# --------------------------------------------------------------------------
# Plot and export columns in a conduit (issue 22 item 17, issue 23)
# --------------------------------------------------------------------------
CONDUIT = __import__("os").path.join(__import__("os").path.dirname(__file__), "..", "examples", "conduit_straight.toml")


@pytest.fixture(scope="module")
def in_pipe(tmp_path_factory):
    """The paper's rod at Gamma = 1 in a straight pipe of clearance 0.01 (README): one equilibrium at Phi = 0
    (its printed name value lines and its file) and a short trace up to Phi = 2."""
    import contextlib
    import io

    from rodcont.cli import main
    work = tmp_path_factory.mktemp("pipe")
    said = {}
    for name, argv in (("eq", ["solve", "--gamma", "1", "--phi", "0", "--conduit", CONDUIT, "--out", work / "eq.h5"]),
                       ("tr", ["trace", "--gamma", "1", "--conduit", CONDUIT, "--phi-max", "2", "--out",
                               work / "pipe.h5", "--quiet"])):
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()), \
                pytest.raises(SystemExit) as exc:
            main([str(a) for a in argv])
        assert exc.value.code == 0
        said[name] = out.getvalue()
    values = {}
    for line in said["eq"].splitlines():
        parts = line.split()
        if not line.startswith("#") and parts[0] != "contact":
            values[parts[0]] = float(parts[1])
        elif parts[0] == "contact":
            values["zone"] = (float(parts[1]), float(parts[2]))
    return work, values


def test_plot_draws_the_contact_columns_where_the_files_hold_them(in_pipe, tmp_path, capsys):
    import numpy as np

    import rodcont
    from rodcont.plots import response_diagram
    work, _ = in_pipe
    for y in ("side_force", "min_gap"):
        code, out, err = run(["plot", work / "pipe.h5", "--y", y, "-o", tmp_path / f"{y}.png"], capsys)
        assert code == 0, err
    data = rodcont.load_diagram(str(work / "pipe.h5"))
    fig = response_diagram([data], str(tmp_path / "lib.png"), y="side_force", x="phi_L")
    drawn = np.concatenate([ln.get_ydata() for ln in fig.axes[0].lines if len(ln.get_ydata()) > 1])
    assert np.array_equal(np.sort(drawn), np.sort(np.asarray(data.branches[0].branch["side_force"], float)))
    code, out, err = run(["trace", "--gamma", "1", "--phi-max", "1", "--out", tmp_path / "free.h5", "--quiet"],
                         capsys)
    assert code == 0, err
    code, out, err = run(["plot", work / "pipe.h5", tmp_path / "free.h5", "--y", "side_force", "-o",
                          tmp_path / "x.png"], capsys)
    assert_one_line_error(code, out, err, "--y side_force", "free.h5 holds no side_force")
    assert not (tmp_path / "x.png").exists()


def test_export_writes_the_contact_fields_of_the_equilibrium(in_pipe, tmp_path, capsys):
    """The columns against what they are: the axial force and the torque are the force's and moment's director
    components N = F.d3 and M3 (computed another way); the gap is c - |(y, z)| of the centreline about the
    axis e1; the pressure integrates to the side force solve printed, is in contact on the zone it printed
    and the least gap is its min_gap."""
    import xml.etree.ElementTree as ET

    import numpy as np
    work, said = in_pipe
    code, out, err = run(["export", f"{work / 'eq.h5'}:0", "--samples", "4001", "-o", tmp_path / "eq.csv"], capsys)
    assert code == 0, err
    rows = [ln for ln in (tmp_path / "eq.csv").read_text().splitlines() if not ln.startswith("#")]
    cols = dict(zip(rows[0].split(","), np.loadtxt(rows[1:], delimiter=",", unpack=True)))
    S = cols["S"]
    assert {"S", "axial_force", "torque", "pressure", "gap", "in_contact"} <= set(cols)
    np.testing.assert_allclose(cols["axial_force"], cols["N"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cols["torque"], cols["M3"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(cols["gap"], 0.01 - np.hypot(cols["y"], cols["z"]), rtol=0, atol=1e-12)
    side = float(np.sum(0.5 * (cols["pressure"][1:] + cols["pressure"][:-1]) * np.diff(S)))
    assert side == pytest.approx(said["side_force"], rel=1e-4)
    on = S[cols["in_contact"] == 1]
    a, b = said["zone"]
    h = S[1] - S[0]
    assert abs(on[0] - a) <= h and abs(on[-1] - b) <= h
    assert cols["gap"].min() == pytest.approx(said["min_gap"], rel=1e-2)
    code, out, err = run(["export", f"{work / 'eq.h5'}:0", "--samples", "4001", "-o", tmp_path / "eq.vtp"], capsys)
    assert code == 0, err
    arrays = {a.get("Name"): np.array(a.text.split(), float) for a in ET.parse(tmp_path / "eq.vtp").iter("DataArray")}
    for name in ("axial_force", "torque", "pressure", "gap", "in_contact"):
        np.testing.assert_allclose(arrays[name], cols[name], rtol=1e-15, atol=0)


def test_export_without_a_conduit_has_no_contact_columns(tmp_path, capsys):
    code, out, err = run(["trace", "--gamma", "1", "--phi-max", "1", "--out", tmp_path / "free.h5", "--quiet"],
                         capsys)
    assert code == 0, err
    code, out, err = run(["export", f"{tmp_path / 'free.h5'}:-1", "-o", tmp_path / "f.csv"], capsys)
    assert code == 0, err
    header = [ln for ln in (tmp_path / "f.csv").read_text().splitlines() if not ln.startswith("#")][0].split(",")
    assert header[0] == "S" and not {"axial_force", "pressure", "gap", "in_contact"} & set(header)


# --------------------------------------------------------------------------
# Drilling on the command line (issue 23)
# --------------------------------------------------------------------------
EXAMPLES = __import__("os").path.join(__import__("os").path.dirname(__file__), "..", "examples")
WELL, STRING = (__import__("os").path.join(EXAMPLES, f) for f in ("well_s3d.toml", "drill_string.toml"))


def _values(out):
    return {ln.split()[0]: ln.split()[1] for ln in out.splitlines() if ln and not ln.startswith("#")}


def test_solve_a_drill_string_in_the_vertical_hole(capsys):
    """300 m of the S-shaped well's vertical top: no contact, so the hook load is the buoyed weight of the
    string (200 m of collars at 2189 N/m, 100 m of heavy-weight pipe at 624 N/m) for any friction, and
    scales with the buoyancy factor 1 - rho_mud / rho_steel."""
    loads = {}
    for rho in ("1200", "1000"):
        code, out, err = run(["solve", "--conduit", WELL, "--string", STRING, "--operation", "pick-up",
                              "--friction", "0.3", "--depth", "300", "--mud-density", rho], capsys)
        assert code == 0, err
        v = _values(out)
        assert v["operation"] == "pick-up" and float(v["depth"]) == 300.0 and int(v["contact_zones"]) == 0
        loads[rho] = float(v["hook_load"])
        assert "[drilling]" in out and "[rod]" not in out  # the problem as run: the string's, not the rod's
    assert loads["1200"] == pytest.approx((1 - 1200 / 7850) * (200 * 2189 + 100 * 624), rel=2e-3)
    # (1.7e-6 apart: the string stretches by its buoyed weight over EA, more in the lighter mud)
    assert loads["1000"] / loads["1200"] == pytest.approx((1 - 1000 / 7850) / (1 - 1200 / 7850), rel=1e-5)


@pytest.mark.parametrize("args, message", [
    (["--gamma", "1", "--phi", "1", "--wob", "1000"], "--wob is an option of a drill string"),
    (["--gamma", "1", "--phi", "1", "--operation", "drill"], "--operation is an option of a drill string"),
    (["--gamma", "1", "--conduit", WELL, "--string", STRING], "--gamma is not an option of a drill string"),
    (["--string", STRING], "--string needs the well"),
    (["--conduit", WELL, "--string", STRING, "--friction", "-0.1"], "--friction must be"),
])
def test_drilling_options_go_with_a_string(args, message, capsys):
    code, out, err = run(["solve", *args], capsys)
    assert_one_line_error(code, out, err, message)


def test_rodcont_cli_drilling_is_still_importable():
    import rodcont.cli.drilling as moved
    import rodcont.cli_drilling as old
    from rodcont.loads import OPERATIONS
    assert old.run_drilling_solve is moved.run_drilling_solve and "broomstick" in main_group.commands
    assert moved.OPERATIONS == tuple(OPERATIONS)  # its copy of the names (no numpy at import)


# --------------------------------------------------------------------------
# sweep on a Dask scheduler (issue 22 item 19)
# --------------------------------------------------------------------------
def test_sweep_runs_on_a_dask_scheduler(tmp_path, capsys):
    """The same family on a running scheduler (a LocalCluster of threads started here) as on the sweep's own
    processes: the same first folds, to the digits printed."""
    distributed = pytest.importorskip("dask.distributed")
    tables = {}
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as c:
        for how, extra in (("dask", ["--scheduler", c.scheduler_address]), ("pool", ["--jobs", "2"])):
            code, out, err = run(["sweep", "--gamma", "0.5", "1", "--stretch-max", "0.2", *extra, "--out",
                                  tmp_path / how, "--quiet"], capsys)
            assert code == 0, err
            tables[how] = [ln for ln in out.splitlines() if ln.strip().split(" ")[0] in ("0.5", "1")]
            assert sorted(p.name for p in (tmp_path / how).iterdir()) == ["gamma_0.5.h5", "gamma_1.h5",
                                                                          "response_diagram.png"]
            where = f"(on the Dask scheduler {c.scheduler_address})" if how == "dask" else "(2 processes)"
            assert where in out
    assert len(tables["dask"]) == 2 and tables["dask"] == tables["pool"]
    assert " 13.0999938" in tables["dask"][1]  # Gamma = 1's first fold (the README's, the Lagrangian reference's)


def test_sweep_scheduler_errors_are_one_line(tmp_path, capsys):
    code, out, err = run(["sweep", "--gamma", "1", "--scheduler", "tcp://127.0.0.1:1", "--jobs", "2", "--out",
                          tmp_path / "s"], capsys)
    assert_one_line_error(code, out, err, "not both")
    assert not (tmp_path / "s").exists()


# --------------------------------------------------------------------------
# diagram --jobs (issue 24)
# --------------------------------------------------------------------------
def test_diagram_on_two_processes_finds_the_serial_folds(tmp_path, capsys):
    import os
    tables, cpu = {}, {}
    for jobs in ("1", "2"):
        before = os.times()
        code, out, err = run(["diagram", "--gamma", "1", "--phi-max", "22", "--jobs", jobs, "--out",
                              tmp_path / f"d{jobs}.h5", "--quiet"], capsys)
        after = os.times()
        assert code == 0, err
        lines = [ln for ln in out.splitlines() if not ln.startswith("#")]
        tables[jobs] = lines[lines.index(next(ln for ln in lines if ln.startswith("branch "))):]
        cpu[jobs] = float(next(ln for ln in lines if ln.startswith("cpu_time")).split()[1])
        workers = after.children_user + after.children_system - before.children_user - before.children_system
        if jobs == "2":  # the workers' CPU time is counted: they traced the branches
            assert workers > 0 and cpu[jobs] >= workers - 0.02
    assert len(tables["1"]) == 3 and tables["1"] == tables["2"]  # the header and the folds at 13.1 and 21.02
    assert tables["1"][1].split()[:2] == ["0", "13.099993823047"]


def test_diagram_by_default_runs_on_the_usable_cores_and_finds_the_folds_of_jobs_1(tmp_path, capsys):
    """Without --jobs the branches go to a pool of one process per usable core (issue 24); its branches and
    folds are those of --jobs 1, the folds to 1e-12 in every column (file and printed table alike)."""
    import os

    import h5py

    from rodcont.drivers.diagram import usable_cores
    printed, folds = {}, {}
    for name, extra in (("default", []), ("serial", ["--jobs", "1"])):
        before = os.times()
        code, out, err = run(["diagram", "--gamma", "1", "--phi-max", "22", "--out", tmp_path / f"{name}.h5",
                              "--quiet"] + extra, capsys)
        after = os.times()
        assert code == 0, err
        workers = after.children_user + after.children_system - before.children_user - before.children_system
        assert (workers > 1e-6) == (name == "default" and usable_cores() > 1)  # child CPU time: workers ran
        lines = out.splitlines()
        printed[name] = [ln for ln in lines if ln.startswith("branches ")] + \
            lines[lines.index(next(ln for ln in lines if ln.startswith("branch "))):]
        with h5py.File(tmp_path / f"{name}.h5", "r") as f:
            folds[name] = {c: f["folds"][c][()] for c in f["folds"]}
            folds[name]["groups"] = np.array(sorted(f["branches"]))
    assert printed["default"] == printed["serial"] and printed["serial"][0].split() == ["branches", "3"]
    assert folds["default"].keys() == folds["serial"].keys() and len(folds["serial"]["phi_L"]) == 2
    for c, v in folds["serial"].items():
        if v.dtype.kind == "f":
            np.testing.assert_allclose(folds["default"][c], v, rtol=1e-12, atol=0, err_msg=c)
        else:
            np.testing.assert_array_equal(folds["default"][c], v, err_msg=c)


@pytest.mark.parametrize("failure", [SystemError("gstrf was called with invalid arguments"),
                                     RuntimeError("SUPERLU_MALLOC fails for buf in intCalloc()")])
def test_an_lu_that_cannot_get_its_memory_is_a_memory_error(monkeypatch, capsys, failure):
    # fuzz #2473 (--max-error 1e-300 under an 8 GB limit): SuperLU's failed malloc came out as "unexpected
    # failure (SystemError: gstrf ...)" exit 1, or as a "singular Jacobian"; it is the size asked for
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from rodcont.linalg import LU, SingularMatrix

    def no_memory(*args, **kwargs):
        raise failure

    monkeypatch.setattr(spla, "splu", no_memory)
    with pytest.raises(MemoryError, match=r"the sparse LU of a 3 x 3 matrix did not fit in memory"):
        LU(sp.identity(3, format="csc"))
    code, out, err = run(["solve", "--gamma", "1", "--phi", "1"], capsys)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("rodcont: error: out of memory (the sparse LU of a ") and "--N-max" in err
    monkeypatch.setattr(spla, "splu", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("Factor is exactly singular")))
    with pytest.raises(SingularMatrix):
        LU(sp.identity(3, format="csc"))
