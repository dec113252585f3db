"""A broomstick keeps every equilibrium it finished: its file is published again after each one, an interrupted
run says what it holds, and ``--resume`` (``rodcont.drivers.broomstick.resume_broomstick``) solves only the cells
still missing, to the same numbers as a run never interrupted (each depth is its own cold start)."""

import json
import os
import signal
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
import pytest

from rodcont.drilling import DrillString, Section, Well
from rodcont.drivers.broomstick import Broomstick, broomstick, read_broomstick, resume_broomstick, write_broomstick

HERE = os.path.dirname(__file__)
# a straight hole inclined 80 degrees, a light pipe (tests/test_broomstick_jobs.py's): a cheap broomstick
PIPE = Section("light pipe", None, 1e4, 7.7e3, 1e8, 100.0, 0.05)
STRING = DrillString((PIPE,), 1.0)
WELL = Well(np.array([[0.0, 80.0, 0.0], [400.0, 80.0, 0.0]]), hole_diameter=0.3, friction=0.4)
DEPTHS, MUS, OPS = np.array([100.0, 150.0, 200.0]), (0.2, 0.4), ("pick-up", "rotate")


class Counting(ThreadPoolExecutor):
    """One worker thread; records each job's (operation, mu, depths)."""

    def __init__(self):
        super().__init__(max_workers=1)
        self.submitted = []

    def submit(self, fn, *args, **kwargs):
        self.submitted.append((args[3], args[4], tuple(args[2])))
        return super().submit(fn, *args, **kwargs)


class StopAfter:
    """A callback that interrupts (as Ctrl-C does) once ``n`` equilibria are in."""

    def __init__(self, n):
        self.n, self.seen = n, []

    def __call__(self, b, cell):
        self.seen.append((cell, int(b.complete.sum())))
        if len(self.seen) == self.n:
            raise KeyboardInterrupt


@pytest.fixture(scope="module")
def whole():
    with ThreadPoolExecutor(max_workers=1) as ex:
        return broomstick(WELL, STRING, DEPTHS, MUS, OPS, executor=ex)


def test_an_interrupted_broomstick_keeps_what_it_solved_and_its_resume_solves_only_the_rest(tmp_path, whole):
    path = str(tmp_path / "b.h5")
    with Counting() as ex, pytest.raises(KeyboardInterrupt):
        broomstick(WELL, STRING, DEPTHS, MUS, OPS, executor=ex, callback=StopAfter(3), out=path, meta={"note": "x"})
    part = read_broomstick(path)
    assert part.attrs["status"] == "interrupted" and part.attrs["note"] == "x"
    assert int(part.complete.sum()) == 3   # the file as the third equilibrium left it: published after each one
    for key in whole.data:   # the cells it holds are the whole run's, the others NaN
        np.testing.assert_array_equal(part.data[key][part.complete], whole.data[key][part.complete], err_msg=key)
        assert np.isnan(part.data[key][~part.complete]).all(), key
    with Counting() as ex:
        done = resume_broomstick(path, executor=ex)
        submitted = ex.submitted
    assert len(submitted) == part.complete.size - 3   # only the missing cells were solved again
    missing = {(op, mu, (float(DEPTHS[k]),)) for k, i, j in zip(*np.nonzero(~part.complete))
               for op, mu in [(OPS[i], MUS[j])]}
    assert set(submitted) == missing
    back = read_broomstick(path)
    assert back.attrs["status"] == "complete" and back.complete.all() and back.attrs["note"] == "x"
    for b in (done, back):
        for key in whole.data:   # bit for bit: each depth is a cold start, whatever run solved it
            np.testing.assert_array_equal(b.data[key], whole.data[key], err_msg=key)


def test_resuming_a_complete_broomstick_solves_nothing(tmp_path, whole):
    path = str(tmp_path / "b.h5")
    with ThreadPoolExecutor(max_workers=1) as ex:
        broomstick(WELL, STRING, DEPTHS[:1], MUS[:1], OPS[:1], executor=ex, out=path)
    before = os.stat(path).st_mtime_ns
    with Counting() as ex:
        b = resume_broomstick(path, executor=ex)
        assert ex.submitted == []
    assert os.stat(path).st_mtime_ns == before and b.complete.all()
    assert b.hook_load[0, 0, 0] == whole.hook_load[0, 0, 0]


def test_a_failed_cell_is_kept_as_an_answer_with_its_reason(tmp_path):
    shape = (2, 1, 1)
    data = {key: np.full(shape, 1.0) for key in ("hook_load", "surface_torque")}
    data["hook_load"][1] = np.nan
    b = Broomstick(np.array([10.0, 20.0]), ("rotate",), (0.3,), data, [("rotate", 0.3, 20.0, "no equilibrium")])
    path = str(tmp_path / "f.h5")
    write_broomstick(b, path)
    back = read_broomstick(path)
    assert back.failures == [("rotate", 0.3, 20.0, "no equilibrium")] and back.complete.all()
    assert back.attrs["status"] == "complete"


def test_a_broomstick_file_it_cannot_finish_is_one_line(tmp_path, whole):
    path = str(tmp_path / "old.h5")
    write_broomstick(whole, path)   # no record of its well and string (as files before resume were)
    with pytest.raises(ValueError, match="no record of its well and string"):
        resume_broomstick(path)
    good = str(tmp_path / "b.h5")
    with ThreadPoolExecutor(max_workers=1) as ex:
        broomstick(WELL, STRING, DEPTHS[:1], MUS[:1], OPS[:1], executor=ex, out=good)
    with h5py.File(good, "r+") as f:
        rec = json.loads(f.attrs["drilling"])
        f.attrs["drilling"] = json.dumps(dict(rec, version=rec["version"] + 1))
    with pytest.raises(ValueError, match="newer than this rodcont"):
        resume_broomstick(good)
    with h5py.File(good, "r+") as f:
        f.attrs["drilling"] = "{not json"
    with pytest.raises(ValueError, match="damaged broomstick record"):
        resume_broomstick(good)


def test_starting_from_a_broomstick_of_other_cases_is_refused(whole):
    with pytest.raises(ValueError, match="other depths, operations or friction factors"):
        broomstick(WELL, STRING, DEPTHS[:2], MUS, OPS, start=whole, jobs=1)


# ------------------------------------------------------------------ the command line

def _files(tmp_path):
    (tmp_path / "w.csv").write_text("0,80,0\n400,80,0\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "w.csv"\nhole_diameter = 0.3\nfriction = 0.4\n')
    (tmp_path / "s.toml").write_text('[string]\nbuoyancy_factor = 1.0\n[[section]]\nname = "light pipe"\n'
                                     'EI = 1e4\nGJ = 7.7e3\nEA = 1e8\nw_air = 100.0\nradius = 0.05\n')
    return str(tmp_path / "w.toml"), str(tmp_path / "s.toml")


def _command(*args, **kw):
    env = dict(os.environ, PYTHONPATH=os.path.join(HERE, "..", "src"))
    return [sys.executable, "-m", "rodcont", "broomstick", *args], env


def _terminated_after_first_line(args, cwd):
    """The broomstick's process group sent SIGTERM (as a batch system stops a job) when its first progress line
    (after its first equilibrium) is on stderr: ``(returncode, stderr)``."""
    cmd, env = _command(*args)
    p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    try:
        first = p.stderr.readline()
        assert first.startswith("equilibrium    1 of "), first
    finally:
        os.killpg(p.pid, signal.SIGTERM)
    out, err = p.communicate(timeout=300)
    return p.returncode, first + err, out


def test_the_command_interrupted_keeps_its_file_and_resume_finishes_it(tmp_path, whole):
    well, string = _files(tmp_path)
    args = (well, "--string", string, "--friction", "0.2", "0.4", "--depth", "100", "200", "--points", "3",
            "-o", "b.png", "--out", "b.h5", "--jobs", "1")
    code, err, out = _terminated_after_first_line(args, tmp_path)
    assert code == 143 and out == "", (code, err)
    held = read_broomstick(str(tmp_path / "b.h5"))
    n = int(held.complete.sum())
    assert 1 <= n < held.complete.size and held.attrs["status"] == "interrupted"
    assert f"interrupted: b.h5 holds {n} of the {held.complete.size} equilibria; finish it with rodcont " \
           f"broomstick --resume b.h5" in err.splitlines()
    assert not (tmp_path / "b.png").exists()   # the plot is drawn once the broomstick is whole
    cmd, env = _command(*args)   # the same command again: refused as existing, and told how to finish it
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and f"b.h5 is an interrupted broomstick, {n} of {held.complete.size} equilibria: " \
        f"finish it with rodcont broomstick --resume b.h5" in r.stderr, r.stderr
    cmd, env = _command("--resume", "b.h5", "-o", "b.png", "--quiet")
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines() == ["wrote b.h5"]
    done = read_broomstick(str(tmp_path / "b.h5"))
    assert done.complete.all() and done.attrs["status"] == "complete"
    k = [OPS.index(op) if op in OPS else None for op in done.operations]
    for i, op in enumerate(done.operations):   # the rows this module's whole run has, to the last bit
        if k[i] is not None:
            np.testing.assert_array_equal(done.hook_load[:, i, :], whole.hook_load[:, k[i], :], err_msg=op)
    assert f"hook_load pick-up 0.4 {float(whole.hook_load[-1, 0, 1])!r}" in r.stdout.splitlines()
    assert (tmp_path / "b.png").stat().st_size > 10000


def test_the_command_interrupted_without_out_says_nothing_was_kept(tmp_path):
    well, string = _files(tmp_path)
    code, err, out = _terminated_after_first_line((well, "--string", string, "--friction", "0.4", "--depth", "100",
                                                   "200", "--points", "3", "-o", "b.png", "--jobs", "1"), tmp_path)
    assert code == 143 and "interrupted: nothing kept (--out B.h5 keeps each equilibrium as it is solved)" in err
    assert sorted(os.listdir(tmp_path)) == ["s.toml", "w.csv", "w.toml"]


@pytest.mark.parametrize("extra, message", [
    (("{well}",), "drop WELL.toml"),
    (("--friction", "0.3"), "drop --friction"),
    (("--points", "4"), "drop --points"),
    (("--out", "other.h5"), "finishes b.h5 in place: drop --out other.h5"),
    (("-o", "b.h5"), "-o b.h5 is the input file b.h5"),
])
def test_resume_refuses_what_would_change_the_broomstick(tmp_path, whole, extra, message):
    well, _ = _files(tmp_path)
    with ThreadPoolExecutor(max_workers=1) as ex:
        broomstick(WELL, STRING, DEPTHS[:1], MUS[:1], OPS[:1], executor=ex, out=str(tmp_path / "b.h5"))
    before = sorted(os.listdir(tmp_path))
    cmd, env = _command(*[a.format(well=well) for a in extra], "--resume", "b.h5")
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert sorted(os.listdir(tmp_path)) == before


# ------------------------------------------------------------------ what a resume may not trust or touch

def _interrupted(path):
    """A broomstick file interrupted after the first of its two equilibria (pick-up, mu 0.2, 100 and 150 m)."""
    with ThreadPoolExecutor(max_workers=1) as ex, pytest.raises(KeyboardInterrupt):
        broomstick(WELL, STRING, DEPTHS[:2], MUS[:1], OPS[:1], executor=ex, callback=StopAfter(1), out=path)
    return path


def _edit_record(f, change):
    rec = json.loads(f.attrs["drilling"])
    change(rec)
    f.attrs["drilling"] = json.dumps(rec)


def _replace(f, name, value):
    del f[name]
    f[name] = value


DAMAGES = {   # each as the adversary of 2026-12-04 made it; each had been exit 1, or a file 'finished' unsolved
    "a section's EI as text": lambda f: _edit_record(f, lambda r: r["string"]["sections"][0].update(EI="1e4")),
    "no survey stations": lambda f: _edit_record(f, lambda r: r["well"].update(stations=[])),
    "an unknown option": lambda f: _edit_record(f, lambda r: r.update(options={"bogus": 1})),
    "a negative N_max": lambda f: _edit_record(f, lambda r: r.update(options={"N_max": -3})),
    "a hook load of another shape": lambda f: _replace(f, "hook_load", np.zeros((3, 1, 1))),
    "an operation it does not know": lambda f: _replace(f, "operations", np.array(["trip"], dtype=h5py.string_dtype())),
    "a negative friction factor": lambda f: _replace(f, "friction", np.array([-0.4])),
    "cells complete without an equilibrium": lambda f: _replace(f, "complete", np.ones((2, 1, 1), bool)),
    "its complete cells deleted": lambda f: f.__delitem__("complete"),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_damaged_broomstick_file_is_refused_before_it_is_touched(tmp_path, damage):
    """A file edited by hand (broomstick files carry no checksum) is refused in one line (a ValueError, which the
    command says as a usage error) before any job runs or the file is written again."""
    path = _interrupted(str(tmp_path / "b.h5"))
    with h5py.File(path, "r+") as f:
        DAMAGES[damage](f)
    before = open(path, "rb").read()
    with Counting() as ex, pytest.raises(ValueError, match=r"damaged broomstick|friction factor|operation") as exc:
        resume_broomstick(path, executor=ex)
    assert ex.submitted == [] and "\n" not in str(exc.value)
    assert open(path, "rb").read() == before


def test_a_second_writer_of_a_broomstick_is_refused(tmp_path):
    """One writer per file, as for traces: the lock beside it (rodcont.branchfile.OutputLock) is held while the
    broomstick runs, and a second run onto the same file is refused before any job."""
    from rodcont.branchfile import OutputLock
    path = _interrupted(str(tmp_path / "b.h5"))
    before = open(path, "rb").read()
    held = OutputLock(path)
    try:
        with Counting() as ex, pytest.raises(ValueError, match="is being written by another rodcont process"):
            resume_broomstick(path, executor=ex)
        assert ex.submitted == [] and open(path, "rb").read() == before
    finally:
        held.release()
    with Counting() as ex:
        resume_broomstick(path, executor=ex)   # and once it is free, the resume goes on
    assert read_broomstick(path).complete.all() and not os.path.exists(held.lock_path)


@pytest.mark.parametrize("extra, message", [
    (("-o", "w.csv", "--overwrite"), "-o w.csv is the input file"),   # the well's survey, named by its record
    (("-o", "s.toml", "--overwrite"), "-o s.toml is the input file"),
    (("--mud-density", "0"), "drop --mud-density"),                    # 0 is given too
    (("--friction", "0.2", "0.4"), "drop --friction"),                 # 0.4 is parsed as WELL.toml
])
def test_a_resume_of_the_commands_file_refuses_its_inputs_as_outputs(tmp_path, extra, message):
    well, string = _files(tmp_path)
    path = str(tmp_path / "b.h5")
    with ThreadPoolExecutor(max_workers=1) as ex:
        broomstick(Well.from_toml(well), DrillString.from_toml(string), DEPTHS[:1], MUS[:1], OPS[:1], executor=ex,
                   out=path, meta=dict(well=well, string=string))
    before = {name: (tmp_path / name).read_bytes() for name in sorted(os.listdir(tmp_path))}
    cmd, env = _command("--resume", "b.h5", *extra)
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert {name: (tmp_path / name).read_bytes() for name in sorted(os.listdir(tmp_path))} == before
