"""Every file a user had is kept, every input is read safely, every restart goes on as it was traced
(issue 22, items 9-14). Each test here failed on the code before it (/work/old, commit 0ee0293):

* an output onto an input (a survey read through --reference well:, through a conduit file or through a
  branch file's reference curve; a --config or conduit file) replaced it, --overwrite or not;
* plot, shape, animate and export wrote in place (a full disk truncated the old file) and export replaced
  any existing file;
* a device, a FIFO or a huge file as a survey, a conduit or a config file was read (to gigabytes, or
  forever);
* a branch file without its checksum read as valid, silently;
* a restart ran with the default options, not the file's; the last point of a branch stopped by a guard
  could not be restarted, even back along the branch; an interrupted trace could only be restarted into
  another file; an interrupted diagram read as complete and could not be finished.
"""

from __future__ import annotations

import errno
import hashlib
import os
import resource
import shutil
import subprocess
import sys
import warnings

import h5py
import numpy as np
import pytest

import rodcont
from conftest import run
from rodcont.branchfile import UnverifiedFileWarning

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"), OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
CLI = [sys.executable, os.path.join(ROOT, "cli.py")]
SURVEY = os.path.join(ROOT, "examples", "well_build_and_hold.csv")
# the README's drill pipe in the build-and-hold well (its span is the survey's chord)
PIPE = ["--T", "1e5", "--L", "973.077121578337", "--EI", "1.25e6", "--GJ", "9.6e5", "--EA", "7.15e8", "--w", "235"]


def one_line_error(code, out, err, *fragments):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    return (code == 2 and len(lines) == 1 and lines[0].startswith("rodcont: error:")
            and "Traceback" not in err + out and all(f in lines[0] for f in fragments))


def digest(path) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def tree(d) -> dict:
    """Every file under ``d`` with its digest (hidden temporary and lock files included)."""
    out = {}
    for root, _, names in os.walk(d):
        for n in names:
            p = os.path.join(root, n)
            out[os.path.relpath(p, d)] = digest(p) if os.path.isfile(p) else "special"
    return out


@pytest.fixture(scope="module")
def g1(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("g1") / "g1.h5")
    rodcont.trace(1.0, stretch_max=0.3, out=path)
    return path


@pytest.fixture()
def well_dir(tmp_path, monkeypatch):
    """A directory with the survey, a conduit file naming it, a config file and a short trace in the well."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(SURVEY, "well.csv")
    (tmp_path / "pipe.toml").write_text('[conduit]\nreference = "well:well.csv"\nclearance = 0.05\neps = 1e-5\n')
    (tmp_path / "problem.toml").write_text("[trace]\nmax_steps = 2\n")
    return tmp_path


def _well_trace(capsys) -> None:
    code, _, err = run(["trace", *PIPE, "--reference", "well:well.csv", "--max-steps", "2", "--out", "wt.h5",
                        "--quiet"], capsys)
    assert code == 0, err


# --------------------------------------------------------------------------
# Item 9: no output onto an input, through any name, --overwrite or not
# --------------------------------------------------------------------------
ALIASES = {
    "same name": lambda name: name,
    "relative path": lambda name: os.path.join("..", os.path.basename(os.getcwd()), name),
    "double slash": lambda name: os.getcwd() + "//" + name,
    "symlink": lambda name: (os.symlink(name, "alias-" + name), "alias-" + name)[1],
    "hard link": lambda name: (os.link(name, "hard-" + name), "hard-" + name)[1],
}


@pytest.mark.parametrize("alias", sorted(ALIASES))
@pytest.mark.parametrize("case", [
    "trace --reference well:FILE", "trace --conduit (its survey)", "trace --conduit (the file)",
    "trace --config", "trace --start (the survey of its reference)", "plot (the survey a file reads)",
    "export (the survey a file reads)", "fold-curve (the start file)"])
def test_no_output_replaces_an_input_of_any_kind(well_dir, capsys, g1, case, alias):
    _well_trace(capsys)
    shutil.copy(g1, "g1.h5")
    target = {"trace --conduit (the file)": "pipe.toml", "trace --config": "problem.toml",
              "fold-curve (the start file)": "g1.h5"}.get(case, "well.csv")
    if case.startswith("plot") or case.startswith("export"):
        # plot and export check their suffix first: the survey under a name with theirs
        os.symlink("well.csv", "well.png" if case.startswith("plot") else "notes.csv")
        target = "well.png" if case.startswith("plot") else "notes.csv"
    out = ALIASES[alias](target)
    before = tree(well_dir)
    args = {
        "trace --reference well:FILE": ["trace", *PIPE, "--reference", "well:well.csv", "--out", out],
        "trace --conduit (its survey)": ["trace", *PIPE, "--conduit", "pipe.toml", "--out", out],
        "trace --conduit (the file)": ["trace", *PIPE, "--conduit", "pipe.toml", "--out", out],
        "trace --config": ["trace", "--gamma", "1", "--config", "problem.toml", "--out", out],
        "trace --start (the survey of its reference)": ["trace", "--start", "wt.h5:-1", "--out", out],
        "plot (the survey a file reads)": ["plot", "wt.h5", "-o", out],
        "export (the survey a file reads)": ["export", "wt.h5", "--point", "0", "-o", out],
        "fold-curve (the start file)": ["fold-curve", "g1.h5:F1", "--range", "0.9", "1.1", "--out", out],
    }[case]
    code, o, e = run(args + ["--overwrite", "--quiet" if args[0] in ("trace", "fold-curve") else "--overwrite"],
                     capsys)
    assert one_line_error(code, o, e, "is the input file"), e
    assert tree(well_dir) == before


def test_the_library_refuses_a_trace_onto_its_survey(tmp_path):
    """rodcont.trace(out=...) checks its target against the survey its reference curve was read from."""
    survey = str(tmp_path / "well.csv")
    shutil.copy(SURVEY, survey)
    from rodcont.curves import parse_reference
    curve = parse_reference(f"well:{survey}", 1.0)
    assert curve.source == survey
    rod = rodcont.RodParameters(EI=1.25e6, GJ=9.6e5, EA=7.15e8, w=235, L=curve.span)
    before = digest(survey)
    with pytest.raises(rodcont.BranchFileError, match="is the input file"):
        rodcont.trace(rod=rod, T=1e5, curve=curve, out=str(tmp_path / "." / "well.csv"), overwrite=True,
                      max_steps=2)
    assert digest(survey) == before


def test_command_inputs_collects_every_file_a_command_reads(well_dir, capsys):
    from rodcont.safeio import command_inputs
    _well_trace(capsys)
    data = rodcont.load_branch("wt.h5")
    got = command_inputs(config="problem.toml", reference="well:other.csv", conduit="pipe.toml",
                         branch_files=["g.h5"], loaded=[data])
    assert got == ["problem.toml", "other.csv", "pipe.toml", os.path.join(str(well_dir), "well.csv"), "g.h5",
                   "wt.h5", "well.csv"]


# --------------------------------------------------------------------------
# Item 10: images and exports atomic, an existing file kept unless --overwrite
# --------------------------------------------------------------------------
OUTPUTS = {
    "plot": (["plot", "g1.h5"], "old.png"),
    "shape": (["shape", "g1.h5"], "old.png"),
    "animate": (["animate", "short.h5", "--max-frames", "3"], "old.gif"),
    "export csv": (["export", "g1.h5", "--point", "3"], "old.csv"),
    "export npz": (["export", "g1.h5", "--all"], "old.npz"),
    "export vtk": (["export", "g1.h5", "--point", "3"], "old.vtp"),
}


@pytest.fixture()
def out_dir(tmp_path, monkeypatch, g1):
    monkeypatch.chdir(tmp_path)
    shutil.copy(g1, "g1.h5")
    rodcont.trace(1.0, stretch_max=0.01, out="short.h5")
    return tmp_path


@pytest.mark.parametrize("what", sorted(OUTPUTS))
def test_an_existing_output_is_kept_unless_overwrite(out_dir, capsys, what):
    args, name = OUTPUTS[what]
    with open(name, "w") as fh:
        fh.write("my notes, not an output of rodcont\n")
    code, o, e = run(args + ["-o", name], capsys)
    assert one_line_error(code, o, e, "exists", "--overwrite"), e
    assert open(name).read() == "my notes, not an output of rodcont\n"
    code, o, e = run(args + ["-o", name, "--overwrite"], capsys)
    assert code == 0 and o.strip().splitlines()[-1].startswith(f"wrote {name}"), e
    assert open(name, "rb").read(7) != b"my note"
    assert not [p for p in os.listdir(out_dir) if p.startswith(".rodcont-")]


def test_a_series_is_kept_unless_overwrite_and_replaced_whole(out_dir, capsys):
    code, o, e = run(["export", "g1.h5", "--all", "-o", "s.pvd"], capsys)
    assert code == 0, e
    first = tree(out_dir / "s_vtp")
    n = len(rodcont.load_branch("g1.h5"))
    assert len(first) == n
    code, o, e = run(["export", "g1.h5", "--all", "-o", "s.pvd"], capsys)
    assert one_line_error(code, o, e, "exists", "--overwrite"), e
    os.remove("s.pvd")  # the series files alone are kept too
    code, o, e = run(["export", "g1.h5", "--all", "-o", "s.pvd"], capsys)
    assert one_line_error(code, o, e, "exists", "--overwrite"), e
    assert tree(out_dir / "s_vtp") == first
    # replaced by a shorter series: the files past its end are removed, the others rewritten
    code, o, e = run(["export", "short.h5", "--all", "-o", "s.pvd", "--overwrite"], capsys)
    assert code == 0, e
    m = len(rodcont.load_branch("short.h5"))
    assert m < n and len(tree(out_dir / "s_vtp")) == m
    assert open("s.pvd").read().count("<DataSet ") == m


def _limited(args, limit, cwd):
    def preexec():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run(CLI + args, env=ENV, cwd=cwd, capture_output=True, text=True, timeout=300,
                          preexec_fn=preexec)


@pytest.mark.parametrize("what", ["plot", "shape", "animate", "export csv", "export npz"])
def test_a_full_disk_leaves_the_old_output_whole(out_dir, capsys, what):
    """RLIMIT_FSIZE (as a full disk: a write past the limit fails, EFBIG) below the new file's size: the
    command fails in one line and the old file is byte for byte what it was (the code before wrote in
    place: the old image was left truncated at the limit)."""
    args, name = OUTPUTS[what]
    code, o, e = run(args + ["-o", name], capsys)  # the old file: a complete output
    assert code == 0, e
    old = digest(name)
    size = os.path.getsize(name)
    args = args + (["--title", "another title"] if what in ("plot", "animate") else [])
    if what == "shape":
        args = args + ["--point", "0"]
    if what.startswith("export"):
        args = args + ["--samples", "400"]
    r = _limited(args + ["-o", name, "--overwrite"], min(size // 2, 20000), out_dir)
    assert one_line_error(r.returncode, r.stdout, r.stderr, "file size limit"), r.stderr
    assert digest(name) == old
    assert not [p for p in os.listdir(out_dir) if p.startswith(".rodcont-")]


def test_a_full_disk_within_a_series_leaves_the_old_series_whole(out_dir, capsys, monkeypatch):
    """The disk fills at the fifth file of a series: every old file, the .pvd and the .vtp, as it was."""
    code, o, e = run(["export", "g1.h5", "--all", "-o", "s.pvd"], capsys)
    assert code == 0, e
    before = tree(out_dir)
    import rodcont.safeio as safeio
    real, calls = safeio._write_all, []

    def full(fd, parts):
        calls.append(1)
        if len(calls) == 5:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(fd, parts)

    monkeypatch.setattr(safeio, "_write_all", full)
    code, o, e = run(["export", "g1.h5", "--all", "-o", "s.pvd", "--samples", "50", "--overwrite"], capsys)
    assert one_line_error(code, o, e, "no space left"), e
    assert tree(out_dir) == before


def test_a_failed_branch_publication_leaves_the_old_file(tmp_path, monkeypatch):
    """Branch files and every other output share the publication (rodcont.safeio): synced, renamed."""
    import rodcont.safeio as safeio
    target = tmp_path / "t.csv"
    target.write_text("old\n")

    def full(fd, parts):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(safeio, "_write_all", full)
    with pytest.raises(safeio.OutputFileError, match="no space left on the device"):
        safeio.publish(str(target), b"new contents")
    assert target.read_text() == "old\n" and os.listdir(tmp_path) == ["t.csv"]


# --------------------------------------------------------------------------
# Item 11: devices, FIFOs and huge files are refused unread
# --------------------------------------------------------------------------
@pytest.fixture()
def odd_files(tmp_path):
    os.mkfifo(tmp_path / "fifo")
    with open(tmp_path / "huge", "wb") as fh:  # sparse: 4 GB on paper, nothing on the disk
        fh.truncate(4 << 30)
    return tmp_path


@pytest.mark.parametrize("which", ["/dev/zero", "fifo", "huge"])
@pytest.mark.parametrize("how", ["--reference well:", "--conduit", "--config"])
def test_devices_fifos_and_huge_files_are_refused_unread(odd_files, which, how):
    path = which if which.startswith("/") else str(odd_files / which)
    if how == "--reference well:":
        args = ["solve", "--gamma", "1", "--phi", "1", "--reference", f"well:{path}"]
    else:
        args = ["solve", "--gamma", "1", "--phi", "1", how, path]
    try:  # the code before read /dev/zero to gigabytes and waited on the FIFO forever
        r = subprocess.run(CLI + args, env=ENV, capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{how} {which}: still reading after 60 s")
    assert one_line_error(r.returncode, r.stdout, r.stderr), r.stderr
    said = r.stderr.lower()
    assert ("not a regular file" in said) if which != "huge" else ("larger than" in said), r.stderr


def test_read_input_bounds_what_it_reads(tmp_path):
    from rodcont.safeio import InputFileError, read_input
    p = tmp_path / "t.toml"
    p.write_bytes(b"x" * 100)
    assert read_input(str(p), "toml") == b"x" * 100
    with pytest.raises(InputFileError, match="larger than"):
        read_input(str(p), "toml", limit=99)
    with pytest.raises(InputFileError, match="a directory"):
        read_input(str(tmp_path), "toml")


# --------------------------------------------------------------------------
# Item 12: a branch file without its checksum reads unverified, and says so
# --------------------------------------------------------------------------
def _without_checksum(src, dst, drop="folds"):
    shutil.copy(src, dst)
    with open(dst, "r+b") as fh:  # the magic spoiled: as a file rewritten by another program
        fh.write(b"\0" * 20)
    with h5py.File(dst, "r+") as f:
        del f[drop]


def test_a_file_without_its_checksum_reads_unverified(g1, tmp_path, capsys):
    edited = str(tmp_path / "edited.h5")
    _without_checksum(g1, edited)
    with pytest.warns(UnverifiedFileWarning, match="edited.h5 has no rodcont checksum"):
        d = rodcont.load_branch(edited)
    assert d.unverified and len(d.folds) == 0
    with pytest.warns(UnverifiedFileWarning):
        assert rodcont.load_diagram(edited).unverified
    code, o, e = run(["folds", edited], capsys)
    assert code == 0 and "no folds" in o
    assert e.strip().splitlines() == [f"rodcont: warning: {edited} has no rodcont checksum (written by another "
                                      f"program, or rewritten by hand): it is read as it is, unverified"]
    # an error still ends in its one line alone
    code, o, e = run(["trace", "--start", f"{edited}:999", "--out", str(tmp_path / "x.h5")], capsys)
    assert one_line_error(code, o, e, "out of range"), e


@pytest.mark.parametrize("name", ["tests/data/old_trace_g1.h5"] + [f"branches/{f}" for f in sorted(
    os.listdir(os.path.join(ROOT, "branches"))) if f.endswith(".h5")])
def test_files_written_before_read_verified(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnverifiedFileWarning)
        d = rodcont.load_diagram(os.path.join(ROOT, name))
    assert not d.unverified and not any(b.unverified for b in d.branches)


# --------------------------------------------------------------------------
# Item 13: restarts carry the file's options; the last point restarts back; --resume
# --------------------------------------------------------------------------
def test_a_restart_carries_the_files_options_unless_given(tmp_path, capsys):
    a, b, c = (str(tmp_path / n) for n in ("a.h5", "b.h5", "c.h5"))
    assert run(["trace", "--gamma", "1", "--ds-max", "0.02", "--phi-max", "8", "--out", a, "--quiet"], capsys)[0] == 0
    code, o, e = run(["trace", "--start", f"{a}:100", "--out", b, "--quiet"], capsys)
    assert code == 0, e
    d = rodcont.load_branch(b)
    assert d.settings["trace"]["ds_max"] == 0.02 and d.settings["trace"]["phi_max"] == 8.0
    assert d.status == "bound" and max(d.table["phi_L"]) == pytest.approx(8.0, abs=1e-12)
    assert np.max(np.diff(d.table["arclength"])) <= 0.02 * (1 + 1e-9)
    assert "the trace options not given are those of --start" in o
    code, o, e = run(["trace", "--start", f"{a}:100", "--ds-max", "0.05", "--phi-max", "9", "--out", c, "--quiet"],
                     capsys)
    assert code == 0, e
    d = rodcont.load_branch(c)
    assert d.settings["trace"]["ds_max"] == 0.05 and max(d.table["phi_L"]) == pytest.approx(9.0, abs=1e-12)


def test_a_restart_in_a_conduit_keeps_its_bound(tmp_path, capsys):
    a, b = str(tmp_path / "a.h5"), str(tmp_path / "b.h5")
    conduit = os.path.join(ROOT, "examples", "conduit_straight.toml")
    assert run(["trace", "--gamma", "1", "--conduit", conduit, "--phi-max", "3", "--out", a, "--quiet"],
               capsys)[0] == 0
    code, o, e = run(["trace", "--start", f"{a}:2", "--out", b, "--quiet"], capsys)
    assert code == 0, e
    d = rodcont.load_branch(b)
    assert d.status == "bound" and max(d.table["phi_L"]) == pytest.approx(3.0, abs=1e-12)


def test_the_last_point_of_a_finished_branch_restarts_back_along_it(tmp_path, capsys):
    """Its last point is located on the validity guard to the guard's tolerance, often a hair outside: it was
    refused even with --direction down ('already at the start'). Back along the branch it goes, through the
    fold; on past the guard it is refused in one line."""
    a, b = str(tmp_path / "a.h5"), str(tmp_path / "b.h5")
    assert run(["trace", "--gamma", "1", "--out", a, "--quiet"], capsys)[0] == 0
    d = rodcont.load_branch(a)
    assert d.status == "validity_guard"
    code, o, e = run(["trace", "--start", f"{a}:-1", "--direction", "down", "--out", b, "--quiet"], capsys)
    assert code == 0, e
    back = rodcont.load_branch(b)
    assert back.status == "bound" and len(back.folds) == 1
    assert back.folds[0]["phi_L"] == pytest.approx(d.folds[0]["phi_L"], abs=1e-8)
    code, o, e = run(["trace", "--start", f"{a}:-1", "--out", str(tmp_path / "c.h5"), "--quiet"], capsys)
    assert one_line_error(code, o, e, "already at the start", "--direction down"), e


def test_restart_checks_are_in_the_library(g1):
    from rodcont.restart import restart_from
    d = rodcont.load_branch(g1)
    for kw, fragment in ((dict(changes={"gamma": 2.0}), "--param gamma"), (dict(changes={"L": 2.0}), "span"),
                         (dict(k=3), "spline degree"), (dict(switch=True), "needs a branch point"),
                         (dict(conduit="c.toml"), "conduit"), (dict(reference="arc:1"), "reference curve")):
        with pytest.raises(ValueError, match=fragment):
            restart_from(d, "F1", **kw)
    args = restart_from(d, 10, changes={"gamma": 1.0, "w": 10.0}, N=30)  # the file's own values are no change
    assert args["N"] == 30 and args["breakpoints"].size == 31 and args["stretch_max"] == 0.3
    br = rodcont.trace(**args)
    assert br.table["phi_L"][0] == pytest.approx(d.table["phi_L"][10], abs=1e-9)
    assert br.status == "event" and br.stop_reason.startswith("stretch_max = 0.3")


def _interrupted_trace(out, at, **kw):
    n = [0]

    def stop(pt):
        n[0] += 1
        if n[0] == at:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        rodcont.trace(1.0, out=out, callback=stop, **kw)


def test_resume_continues_an_interrupted_trace_in_its_file(tmp_path, capsys):
    out = str(tmp_path / "r.h5")
    whole = rodcont.trace(1.0, ds=0.05, ds_max=0.05, phi_max=20)
    _interrupted_trace(out, 120, ds=0.05, ds_max=0.05, phi_max=20)
    part = rodcont.load_branch(out)
    assert part.status == "interrupted" and len(part) == 120
    code, o, e = run(["trace", "--resume", out, "--quiet"], capsys)
    assert code == 0, e
    d = rodcont.load_branch(out)
    assert os.listdir(tmp_path) == ["r.h5"]
    assert len(d) == len(whole) and d.status == whole.status == "validity_guard"
    assert list(d.table["kind"]) == list(whole.table["kind"])
    for name in ("phi_L", "stretch", "arclength"):
        np.testing.assert_allclose(d.table[name], whole.table[name], rtol=0, atol=1e-8)
    assert d.table["unstable_modes"] == whole.table["unstable_modes"]
    assert d.folds[0]["phi_L"] == pytest.approx(whole.folds[0]["phi_L"], abs=1e-9)
    np.testing.assert_array_equal(d.table["phi_L"][:119], part.table["phi_L"][:119])  # kept as they were
    # finished now: refused, unless asked to extend it
    code, o, e = run(["trace", "--resume", out], capsys)
    assert one_line_error(code, o, e, "finished", "--extend"), e
    code, o, e = run(["trace", "--resume", out, "--out", str(tmp_path / "other.h5")], capsys)
    assert one_line_error(code, o, e, "in place"), e


def test_extend_goes_on_past_the_end_of_a_finished_branch(tmp_path, capsys):
    out = str(tmp_path / "e.h5")
    assert run(["trace", "--gamma", "1", "--phi-max", "8", "--out", out, "--quiet"], capsys)[0] == 0
    n = len(rodcont.load_branch(out))
    code, o, e = run(["trace", "--resume", out, "--extend", "--phi-max", "12", "--quiet"], capsys)
    assert code == 0, e
    d = rodcont.load_branch(out)
    assert len(d) > n and max(d.table["phi_L"]) == pytest.approx(12.0, abs=1e-12) and d.status == "bound"
    assert d.table["kind"][n - 1] == "regular"  # the old end, a bound no more
    assert d.settings["trace"]["phi_max"] == 12.0


def test_a_kill_while_resuming_leaves_the_old_file(tmp_path):
    """The resumed file is published only once it holds every old point again: a run that fails to go on
    leaves it as it was."""
    out = str(tmp_path / "r.h5")
    _interrupted_trace(out, 30, phi_max=20, ds_max=0.05, ds=0.05)
    before = digest(out)
    from rodcont.restart import resume
    with pytest.raises(ValueError, match="min_alignment"):  # a guard the last point is outside of
        resume(out, options=dict(min_alignment=0.999))
    assert digest(out) == before and sorted(os.listdir(tmp_path)) == ["r.h5"]


# --------------------------------------------------------------------------
# Item 14: an interrupted diagram is marked so, and --resume finishes it
# --------------------------------------------------------------------------
def test_an_interrupted_diagram_is_marked_and_resume_finishes_it(tmp_path, capsys):
    whole = rodcont.diagram(1.0, phi_max=25)
    out = str(tmp_path / "d.h5")
    first = len(whole.branches[0].branch)
    n = [0]

    def stop(pt):  # in the second branch (the callback sees the up run of each)
        n[0] += 1
        if n[0] == first + 20:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        rodcont.diagram(1.0, phi_max=25, out=out, callback=stop)
    d = rodcont.load_diagram(out)
    assert d.attrs["status"] == "interrupted" and d.attrs["stop_reason"].startswith("interrupted")
    assert [str(b.status) for b in d.branches] == [str(whole.branches[0].branch.status), "interrupted"]
    code, o, e = run(["folds", out], capsys)
    assert code == 0 and "INTERRUPTED" in o and "branch 1 unfinished" in o and f"--resume {out}" in o
    before = digest(out)
    code, o, e = run(["diagram", "--resume", out, "--ds-max", "0.1"], capsys)
    assert one_line_error(code, o, e, "--ds-max differs from the diagram file's"), e
    assert digest(out) == before
    _assert_resume_finishes_as_the_whole(out, whole, capsys)
    code, o, e = run(["diagram", "--resume", out], capsys)
    assert one_line_error(code, o, e, "complete diagram"), e


def _assert_resume_finishes_as_the_whole(out, whole, capsys) -> None:
    """``diagram --resume OUT`` completes the interrupted file with the uninterrupted run's folds (1e-9) and
    point counts."""
    code, o, e = run(["diagram", "--resume", out, "--quiet"], capsys)
    assert code == 0, e
    d = rodcont.load_diagram(out)
    assert d.attrs["status"] == "complete" and len(d.branches) == len(whole.branches)
    np.testing.assert_allclose(d.folds["phi_L"], whole.folds["phi_L"], rtol=0, atol=1e-9)
    assert [len(b) for b in d.branches] == [len(b.branch) for b in whole.branches]


def test_a_diagram_interrupted_while_its_workers_trace_keeps_its_complete_branches(tmp_path, capsys):
    """The default run traces on a process pool: an interrupt while it waits on its workers (the callback's
    ``idle()``, where the command line takes Ctrl-C) leaves the branches kept so far in the file, marked
    interrupted, and no worker running; --resume finishes it with the serial run's folds and points."""
    import multiprocessing
    whole = rodcont.diagram(1.0, phi_max=25, jobs=1)
    out = str(tmp_path / "d.h5")

    class StopAfterTheFirstBranch:
        points = 0

        def __call__(self, pt):
            self.points += 1

        def idle(self):  # the primary branch is kept once its points were seen
            if self.points:
                raise KeyboardInterrupt

    stop = StopAfterTheFirstBranch()
    with pytest.raises(KeyboardInterrupt):
        rodcont.diagram(1.0, phi_max=25, out=out, callback=stop, jobs=2)
    assert multiprocessing.active_children() == []
    assert stop.points == len(whole.branches[0].branch)
    d = rodcont.load_diagram(out)
    assert d.attrs["status"] == "interrupted" and len(d.branches) == 1
    assert str(d.branches[0].status) == str(whole.branches[0].branch.status)
    _assert_resume_finishes_as_the_whole(out, whole, capsys)


def test_ctrl_c_stops_a_parallel_diagram_at_once_and_resume_finishes_it(tmp_path):
    """SIGINT to `rodcont diagram` (its default: the branches on a process pool) once its first branch is
    kept: exit 130, the --resume line, no traceback; the file holds that branch, marked interrupted, and
    --resume finishes it with every branch."""
    import signal
    out = str(tmp_path / "d.h5")
    p = subprocess.Popen(CLI + ["diagram", "--gamma", "1", "--out", out, "--jobs", "2"], env=ENV,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    for line in p.stderr:  # an event, not a time: the primary branch's progress line
        lines.append(line)
        if line.lstrip().startswith("branch 0:"):
            break
    p.send_signal(signal.SIGINT)
    stdout, err = p.communicate(timeout=300)
    err = "".join(lines) + err
    assert p.returncode == 130, err
    assert "Traceback" not in err + stdout and f"rodcont diagram --resume {out}" in err
    d = rodcont.load_diagram(out)
    assert d.attrs["status"] == "interrupted" and 1 <= len(d.branches) < 5
    r = subprocess.run(CLI + ["diagram", "--resume", out, "--quiet"], env=ENV, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    d = rodcont.load_diagram(out)
    assert d.attrs["status"] == "complete" and len(d.branches) == 5
