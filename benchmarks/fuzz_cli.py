#!/usr/bin/env python3
"""Adversarial fuzz of the rodcont command line: does every error end the way the CLI promises?

The promise (``src/rodcont/cli.py``): every error a user can cause (bad numbers,
missing, foreign or damaged files, an output that exists or is an input, no
convergence) ends in ONE line on stderr starting ``rodcont: error:`` and exit
status 2; no traceback, no half-written output file, no input file changed;
Ctrl-C / SIGTERM end a trace between two points (exit 130 / 143) with every
point on disk.

This script builds a set of fixture files with rodcont itself (a valid branch
file made by ``rodcont trace --gamma 1 --stretch-max 0.1 --out X.h5 --quiet``,
a branch with a fold, a diagram file, a fold-curve file), derives damaged and
foreign variants from them, and runs *probes*: one rodcont command line each,
in a fresh directory of its own, in a subprocess with a timeout (two at a time
at most). Each probe states what it expects:

  err  the input is wrong: exit 2 and exactly one non-empty stderr line
       ``rodcont: error: <message>``;
  ok   the input is valid and ordinary: exit 0;
  any  the input is valid by the documented rules but extreme (1e308, 1e-300,
       a hand-edited value that may or may not be harmful, a random byte flip
       that may land in padding): exit 0, or a clean error as for ``err``;
  env  the failure comes from the machine, not from the command line (stdout
       on a full device): rodcont's own policy is exit 1 for those, so 1 or 2
       are accepted, still as one clean line (env0: 0 too, for a closed stdout);
  sig  a signal is sent mid-run: exit 130/143 (or 0 if the run finished
       first), every output left on disk complete and readable.

For every probe it checks: the exit status; the stderr rule above on any
non-zero exit; no ``Traceback`` in stdout or stderr; no hang (timeout); on a
failure the probe directory is byte-for-byte what it was before (no new file,
no temporary or lock file, no input changed); on success no input changed and
no temporary or lock file left behind. A probe may also check the answer itself
(``check``: folds, torques, stability counts, contact values, columns; issue 22's
classes: the same answer in other units, at default settings, in conduits, with a
tighter guard), a phrase it must or must not print, or be a call of the Python API
(``python``: a TypeError/ValueError is its clean one-line error, anything else a
traceback).

Usage::

    python benchmarks/fuzz_cli.py            # full run (2546 probes, 32 minutes on 2 cores shared with other work)
    python benchmarks/fuzz_cli.py --quick    # ~165-probe stratified subset, about 70 s
    python benchmarks/fuzz_cli.py --list     # print the probes, run nothing
    python benchmarks/fuzz_cli.py --filter damaged --keep   # a subset; keep the probe directories

Exit status: 0 if every probe passed, 1 otherwise.

Children run with OPENBLAS_NUM_THREADS=1, MPLBACKEND=Agg and an address-space
limit (``--mem-limit``, default 8 GB each) so that a probe that asks for a
gigantic mesh fails in a bounded way instead of taking the machine down.
Probes that need an unwritable directory run as root without CAP_DAC_OVERRIDE (root
bypasses permission bits; ``setpriv`` drops it); skipped when that is not possible.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import re
import shlex
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections import OrderedDict, defaultdict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CLI = os.path.join(REPO, "cli.py")
PREFIX = "rodcont: error:"
# root ignores permission bits; these probes run as root without the capabilities that bypass them
NOCAP = ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner,-linux_immutable", "--"]

# --------------------------------------------------------------------------
# Probes
# --------------------------------------------------------------------------


@dataclass
class Probe:
    group: str                      # category (used for the quick subset and the report)
    args: list                      # rodcont arguments (after the program name)
    expect: str                     # err | ok | any | env | sig
    why: str = ""                   # justification of the expectation / what is being attacked
    files: tuple = ()               # fixture names copied into the probe directory
    setup: Callable | None = None   # setup(probe_dir): extra preparation (symlinks, modes...)
    setup_desc: str = ""            # the setup in words / shell (for the reproducer)
    user: str | None = None         # "nocap": run without root's permission bypass (setpriv drops CAP_DAC_*)
    fsize: int | None = None        # RLIMIT_FSIZE in bytes (a "full disk")
    stdout_path: str | None = None  # stdout redirected there (/dev/full), or "CLOSED", or "BROKENPIPE"
    timeout: float = 60.0
    signal_after: tuple | None = None   # (signum, seconds)
    changes_ok: tuple = ()          # pre-existing names that may change on success (--overwrite targets)
    partial_ok: tuple = ()          # outputs that may stay after a failure if they are complete branch files
    heavy: bool = False             # skipped by --quick
    ro_cwd: bool = False            # with user: the probe directory itself is read-only for that user
    must_say: str = ""              # a phrase stdout or stderr must hold (what a carried option, a warning says)
    must_not_say: str = ""          # a phrase neither may hold (a warning an accurate answer has no cause for)
    check: Callable | None = None   # check(result) -> None, or what is wrong with the answer (values, files)
    python: str | None = None       # a call of the Python API instead of a command line (see _api_code)
    id: int = 0

    def probe_cmd(self) -> str:
        return next((a for a in self.args if not a.startswith("-")), "")


def _shell(args) -> str:
    if args[:2] == ["python", "-c"]:
        return "python -c " + shlex.quote(args[2])
    return "rodcont " + " ".join(shlex.quote(a) for a in args)


# ---- numeric value sets ---------------------------------------------------
HUGE_INT = "9" * 30                 # 1e30 as a float, out of range as a count
HUGER = "9" * 400                   # overflows a float to inf; 400 digits as an int
FLOAT_VALUES = ["nan", "inf", "-inf", "1e308", "-1e308", "1e-300", "-0", "0", "", "abc", HUGE_INT, "-5"]
FLOAT_EXTRA = ["1e309", HUGER, "5e-324", "0x10", "1,5", "NaN", "-Infinity", " 7 ", "1_0"]
INT_VALUES = ["nan", "inf", "", "abc", "1.5", "1e3", "0", "-0", "-1", "-5", HUGE_INT, "2147483648", "1"]
INT_EXTRA = [HUGER, "0x10", "\uff11"]          # fullwidth digit one: int() accepts it
# options that critical/diagram/sweep share with solve/trace go through the same click callbacks: there they get
# one value of each class (non-finite, empty, not a number, negative, zero, huge, tiny, huge integer)
FLOAT_SHARED = ["nan", "", "abc", "-5", "0", "1e308", "1e-300", "-1e308", HUGE_INT]
INT_SHARED = ["abc", "", "0", "-1", HUGE_INT, "1", "1.5"]


def _float(s):
    try:
        return float(s)
    except ValueError:
        return None


def _int(s):
    try:
        return int(s)
    except ValueError:
        return None


def float_expect(s: str, valid: Callable[[float], bool]):
    """err when the text is not a finite number satisfying ``valid``; any otherwise (valid but extreme)."""
    v = _float(s)
    if v is None or v != v or v in (float("inf"), float("-inf")):
        return "err", "not a finite number"
    return ("any", "a valid number (extreme values may be refused cleanly)") if valid(v) else \
        ("err", "violates the documented constraint")


def int_expect(s: str, lo: int, hi: int):
    v = _int(s)
    if v is None:
        return "err", "not an integer"
    return ("any", f"in {lo}..{hi}") if lo <= v <= hi else ("err", f"outside {lo}..{hi}")


POS = lambda v: v > 0          # noqa: E731
NONNEG = lambda v: v >= 0      # noqa: E731
FINITE = lambda v: True        # noqa: E731

ROD_FLOATS = OrderedDict([("--w", NONNEG), ("--EI", POS), ("--GJ", POS), ("--EA", POS), ("--L", POS)])
ROD_INTS = OrderedDict([("--N", (1, 100000)), ("--k", (1, 7))])


def trace_floats():
    """Float options of trace/diagram/sweep with validity given the base command's other values
    (phi-min -1, phi-max 40, ds 0.1, ds-max 0.5, ds-min 1e-6)."""
    return OrderedDict([
        ("--phi-max", lambda v: v > -1.0),
        ("--phi-min", lambda v: v < 40.0),
        ("--stretch-max", FINITE),
        ("--ds", lambda v: 1e-6 <= v <= 0.5),
        ("--ds-max", lambda v: v >= 1e-6),          # --ds (default) is clamped to --ds-max when only it is given
        ("--ds-min", lambda v: 0 < v <= 0.1),
        ("--min-alignment", lambda v: 0 <= v < 1),
        ("--max-error", POS),
        ("--max-defect", POS),
        ("--fold-error", POS),
        ("--forced", FINITE),
    ])


TRACE_INTS = OrderedDict([("--max-steps", (1, 10**7)), ("--N-max", (1, 100000))])


def replace_opt(base: list, opt: str, value: str) -> list:
    """``base`` with ``opt value`` (replacing an existing ``opt x``)."""
    out = list(base)
    if opt in out:
        i = out.index(opt)
        out[i + 1] = value
        return out
    return out + [opt, value]


# ---- base command lines (short runs when the input is valid) ---------------
BASE = {
    "solve": ["solve", "--gamma", "1", "--phi", "1"],
    "trace": ["trace", "--gamma", "1", "--stretch-max", "0.02", "--max-steps", "12", "--out", "out.h5", "--quiet"],
    "critical": ["critical", "--gamma", "1", "--phi-max", "15"],
    "diagram": ["diagram", "--gamma", "1", "--phi-max", "5", "--stretch-max", "0.02", "--max-steps", "12",
                "--out", "out.h5", "--quiet"],
    "sweep": ["sweep", "--gamma", "1", "--stretch-max", "0.02", "--max-steps", "8", "--jobs", "1",
              "--out", "outdir", "--quiet"],
    "fold-curve": ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--max-steps", "3", "--out", "out.h5",
                   "--quiet"],
    "animate": ["animate", "X.h5", "-o", "a.gif", "--max-frames", "3", "--samples", "20"],
    "export": ["export", "X.h5", "--point", "0", "-o", "e.csv"],
    "plot": ["plot", "X.h5", "-o", "p.png"],
    "shape": ["shape", "X.h5", "-o", "s.png"],
    "folds": ["folds", "X.h5"],
}
BASE_FILES = {"fold-curve": ("F.h5",), "animate": ("X.h5",), "export": ("X.h5",), "plot": ("X.h5",),
              "shape": ("X.h5",), "folds": ("X.h5",)}
COVERED: dict = defaultdict(set)     # command -> options the curated probes cover (the rest are discovered)


def numeric_probes() -> list[Probe]:
    P = []

    def add(cmd, opt, s, exp, why, files=(), args=None, group=None):
        COVERED[cmd].add(opt.split()[0])
        a = args if args is not None else replace_opt(BASE[cmd], opt, s)
        # a diagram whose --phi-max is past the 200 rad the critical twists reach traces every branch up to
        # there (22 at Gamma = 1: a minute on a busy machine)
        long = cmd == "diagram" and opt == "--phi-max" and _float(s) is not None and _float(s) > 200
        P.append(Probe(group or f"numeric:{cmd}", a, exp, f"{opt} {s!r}: {why}",
                       files=files or BASE_FILES.get(cmd, ()), **(dict(heavy=True, timeout=400) if long else {})))

    # -- solve
    for opt, valid in [("--gamma", FINITE), ("--phi", FINITE), ("--load-step", POS)] + list(ROD_FLOATS.items()):
        for s in FLOAT_VALUES + FLOAT_EXTRA:
            add("solve", opt, s, *float_expect(s, valid))
    for opt, (lo, hi) in ROD_INTS.items():
        for s in INT_VALUES + INT_EXTRA:
            add("solve", opt, s, *int_expect(s, lo, hi))
    # -- critical (phi-min 0 by default, phi-max 15 in the base)
    for opt, valid in [("--gamma", FINITE), ("--phi-max", lambda v: v > 0), ("--phi-min", lambda v: v < 15)]:
        for s in FLOAT_VALUES:
            add("critical", opt, s, *float_expect(s, valid))
    for opt, valid in ROD_FLOATS.items():
        for s in FLOAT_SHARED:
            add("critical", opt, s, *float_expect(s, valid))
    for opt, (lo, hi) in ROD_INTS.items():
        for s in INT_SHARED:
            add("critical", opt, s, *int_expect(s, lo, hi))
    # -- trace
    tf = trace_floats()
    for opt, valid in [("--gamma", FINITE)] + list(tf.items()) + list(ROD_FLOATS.items()):
        for s in FLOAT_VALUES + (FLOAT_EXTRA if opt in ("--gamma", "--ds", "--phi-max") else []):
            add("trace", opt, s, *float_expect(s, valid))
    for opt, (lo, hi) in list(TRACE_INTS.items()) + list(ROD_INTS.items()):
        for s in INT_VALUES + (INT_EXTRA if opt == "--N" else []):
            add("trace", opt, s, *int_expect(s, lo, hi))
    # --from-straight PHI (a start near the straight state), --range A B with --param EI
    fs_base = ["trace", "--gamma", "1", "--from-straight", "1", "--stretch-max", "0.05", "--max-steps", "5",
               "--out", "out.h5", "--quiet"]
    for s in FLOAT_VALUES:
        add("trace", "--from-straight", s, *float_expect(s, FINITE), args=replace_opt(fs_base, "--from-straight", s))
    rg = ["trace", "--gamma", "1", "--from-straight", "1", "--param", "EI", "--max-steps", "4", "--out", "out.h5",
          "--quiet", "--range"]
    for s in FLOAT_VALUES:
        add("trace", "--range A", s, *float_expect(s, lambda v: v < 2.0), args=rg + [s, "2"])
        add("trace", "--range B", s, *float_expect(s, lambda v: v > 0.5), args=rg + ["0.5", s])
    # -- diagram
    for opt, valid in [("--gamma", FINITE), ("--deflate", FINITE)]:
        for s in FLOAT_VALUES:
            add("diagram", opt, s, *float_expect(s, valid))
    for opt, valid in list(tf.items()) + list(ROD_FLOATS.items()):
        for s in FLOAT_SHARED:
            add("diagram", opt, s, *float_expect(s, valid))
    for opt, (lo, hi) in list(TRACE_INTS.items()) + list(ROD_INTS.items()):
        for s in INT_SHARED:
            add("diagram", opt, s, *int_expect(s, lo, hi))
    # -- sweep (one process per Gamma: failures inside the workers are the interesting part)
    for s in FLOAT_VALUES:
        add("sweep", "--gamma", s, *float_expect(s, FINITE))
    for opt, valid in list(tf.items()) + list(ROD_FLOATS.items()):
        for s in FLOAT_SHARED:
            add("sweep", opt, s, *float_expect(s, valid))
    for opt, (lo, hi) in list(TRACE_INTS.items()) + list(ROD_INTS.items()):
        for s in INT_SHARED:
            add("sweep", opt, s, *int_expect(s, lo, hi))
    for s in INT_VALUES:
        add("sweep", "--jobs", s, *int_expect(s, 1, 1024))
    for s in ["nan", "", "abc", "-5", "1e308"]:
        a = list(BASE["sweep"])
        a[a.index("--gamma") + 1:a.index("--gamma") + 2] = ["1", s]
        add("sweep", "--gamma 1 X", s, *float_expect(s, FINITE), args=a)
    # -- fold-curve
    for s in FLOAT_VALUES:
        add("fold-curve", "--range A", s, *float_expect(s, lambda v: v <= 1.0),
            args=["fold-curve", "F.h5:0", "--range", s, "1.1", "--max-steps", "3", "--out", "out.h5", "--quiet"])
        add("fold-curve", "--range B", s, *float_expect(s, lambda v: v >= 1.0),
            args=["fold-curve", "F.h5:0", "--range", "0.9", s, "--max-steps", "3", "--out", "out.h5", "--quiet"])
    for opt, valid in [("--ds", lambda v: 0 < v <= 0.5), ("--ds-max", lambda v: v >= 0.05), ("--max-error", POS),
                       ("--forced", FINITE)]:
        for s in FLOAT_VALUES:
            add("fold-curve", opt, s, *float_expect(s, valid))
    for s in INT_VALUES:
        add("fold-curve", "--max-steps", s, *int_expect(s, 1, 10**6))
    return P


def spec_probes(n: int) -> list[Probe]:
    """Positional and textual point specs: FILE.h5:POINT, FILE.h5:BRANCH:POINT, --point, --branch.
    ``n``: the number of points of X.h5."""
    P = []
    tr = ["--stretch-max", "0.03", "--max-steps", "4", "--out", "out.h5", "--quiet"]
    # X.h5 has n points (0..n-1), no fold, no branch point; F.h5 has one fold; D.h5 one branch "0".
    start_cases = [
        ("X.h5:0", "ok", "first point"), ("X.h5:-1", "any", "last point (sits on the stretch_max bound)"),
        (f"X.h5:{n - 1}", "any", "last index"), (f"X.h5:-{n}", "ok", "first point from the end"),
        (f"X.h5:{n}", "err", "index one past the end"), (f"X.h5:-{n + 1}", "err", "one before the start"),
        ("X.h5:-0", "ok", "-0 is 0"), ("X.h5: 3", "ok", "int() strips blanks"),
        ("X.h5:F1", "err", "no fold"), ("X.h5:F0", "err", "folds count from 1"), ("X.h5:BP1", "err", "no BP"),
        ("X.h5:BP", "err", "no number"), ("X.h5:F", "err", "no number"), ("X.h5:f1", "err", "no fold"),
        ("X.h5:nan", "err", "not an index"), ("X.h5:1e3", "err", "not an index"), ("X.h5:1.0", "err", "not an index"),
        ("X.h5:0x1", "err", "not an index"), ("X.h5:", "err", "empty point"), ("X.h5", "err", "no point"),
        (":0", "err", "empty file name"), ("missing.h5:0", "err", "missing file"),
        ("X.h5:" + HUGE_INT, "err", "huge index"), ("X.h5:" + "9" * 5000, "err", "5000-digit index"),
        ("X.h5:0:0", "err", "a branch file is not a diagram"), ("X.h5:0:0:0", "err", "no such file X.h5:0"),
        ("X.h5:\uff13", "ok", "fullwidth 3: int() accepts it"),
        ("F.h5:F1", "any", "the fold"), ("F.h5:F2", "err", "one fold only"), ("F.h5:BP1", "err", "no BP"),
        ("D.h5:0:0", "ok", "branch 0 of the diagram, point 0"), ("D.h5:0", "any", "a one-branch diagram"),
        ("D.h5:1:0", "err", "no branch 1"), ("D.h5::0", "err", "empty branch name"),
        ("D.h5:0:999", "err", "no point 999"), ("D.h5:-1:0", "err", "no branch -1"),
        ("C.h5:0", "err", "a fold-curve file cannot start a trace"),
        ("a:b.h5:0", "ok", "a colon in the file name (copy of X.h5)"),
        ("text.txt:0", "err", "a text file"), ("pic.png:0", "err", "a PNG"), ("empty.h5:0", "err", "empty file"),
        ("adir:0", "err", "a directory"),
    ]
    for spec, exp, why in start_cases:
        files = tuple(sorted({f for f in ("X.h5", "F.h5", "D.h5", "C.h5", "text.txt", "pic.png", "empty.h5")
                              if spec.startswith(f)}))
        setup, desc = None, ""
        if spec.startswith("a:b.h5"):
            files, desc = ("X.h5",), "cp X.h5 a:b.h5"
            setup = lambda d: shutil.copy(os.path.join(d, "X.h5"), os.path.join(d, "a:b.h5"))  # noqa: E731
        if spec.startswith("adir"):
            setup, desc = (lambda d: os.mkdir(os.path.join(d, "adir"))), "mkdir adir"
        P.append(Probe("spec:--start", ["trace", "--start", spec] + tr, exp, f"--start {spec!r}: {why}",
                       files=files, setup=setup, setup_desc=desc))
    # fold-curve SPEC (FILE.h5:I, I-th fold from 0)
    fc = ["--range", "0.9", "1.1", "--max-steps", "3", "--out", "out.h5", "--quiet"]
    for spec, exp, why in [("F.h5:0", "ok", "the fold"), ("F.h5:1", "err", "one fold"),
                           ("F.h5:-1", "err", "folds count from 0"), ("F.h5:F1", "ok", "F<j>, the j-th fold from 1 (issue 22, 16)"),
                           ("F.h5:nan", "err", "not an integer"), ("F.h5:", "err", "empty"),
                           ("F.h5", "err", "no fold number"), ("F.h5:" + "9" * 5000, "err", "5000 digits"),
                           ("F.h5: 0 ", "ok", "int() strips blanks"), ("X.h5:0", "err", "no fold"),
                           ("D.h5:0:0", "ok", "fold 0 of branch 0 of a diagram"), ("D.h5:0", "any", "one-branch diagram"),
                           ("D.h5:7:0", "err", "no branch 7"), ("C.h5:0", "err", "a fold curve has no folds to continue"),
                           ("missing.h5:0", "err", "missing")]:
        files = tuple(f for f in ("X.h5", "F.h5", "D.h5", "C.h5") if spec.startswith(f))
        P.append(Probe("spec:fold-curve", ["fold-curve", spec] + fc, exp, f"SPEC {spec!r}: {why}", files=files))
    for p in ["gamma", "T", "w", "EI", "GJ", "EA"]:
        P.append(Probe("spec:fold-curve", ["fold-curve", "F.h5:0", "--param", p, "--range", "-1e3", "1e3",
                                           "--max-steps", "3", "--out", "out.h5", "--quiet"],
                       "any", f"--param {p} over a wide range containing the fold's value", files=("F.h5",)))
    # shape --point / --branch
    for pt, exp in [("0", "ok"), ("-1", "ok"), (str(n - 1), "ok"), (str(n), "err"), (str(-n - 1), "err"), ("F1", "err"),
                    ("BP1", "err"), ("", "err"), (" ", "err"), ("nan", "err"), ("1e1", "err"), ("-0", "ok"),
                    (HUGE_INT, "err"), ("9" * 5000, "err"), ("F", "err"), ("BP-1", "err"), ("F-1", "err"),
                    ("\uff10", "ok")]:
        P.append(Probe("spec:shape", ["shape", "X.h5", "--point", pt, "-o", "s.png"], exp,
                       f"--point {pt[:20]!r}", files=("X.h5",)))
    P.append(Probe("spec:shape", ["shape", "F.h5", "--point", "F1", "--point", "0", "--point", "-1", "-o", "s.png"],
                   "ok", "three valid points", files=("F.h5",)))
    for br, f, exp in [("0", "D.h5", "ok"), ("7", "D.h5", "err"), ("", "D.h5", "err"), ("-1", "D.h5", "err"),
                       ("0", "X.h5", "err"), ("../0", "D.h5", "err"), ("branches", "D.h5", "err")]:
        P.append(Probe("spec:shape", ["shape", f, "--branch", br, "-o", "s.png"], exp, f"--branch {br!r} of {f}",
                       files=(f,)))
    # plot titles (matplotlib parses $...$ as mathtext)
    for title, exp in [("", "ok"), ("plain", "ok"), ("$x$", "ok"), ("$\\undefinedcmd$", "err"), ("$", "ok"),
                       ("$\\frac{$", "err"), ("a" * 20000, "ok"), ("\x00", "any"), ("\u202e\U0001F600", "ok")]:
        if "\x00" in title:
            continue  # argv cannot hold NUL
        P.append(Probe("spec:plot", ["plot", "X.h5", "--title", title, "-o", "p.png"], exp,
                       f"--title {title[:30]!r}: a bad mathtext title is bad user input", files=("X.h5",)))
    return P


def _symlink(name, target):
    def f(d):
        os.symlink(target, os.path.join(d, name))
    return f


def _devnode(name, minor):
    """A private character device in the probe directory: minor 7 is a full device (like /dev/full), 3 a null one.
    Output probes never name the machine's /dev/full or /dev/null: a tool that replaces its output atomically
    (temporary file + rename) would replace the system's device node (rodcont export/animate did)."""
    def f(d):
        os.mknod(os.path.join(d, name), 0o666 | stat.S_IFCHR, os.makedev(1, minor))
    return f


FULL = _devnode("devfull", 7)
NULL = _devnode("devnull", 3)


def _chain(*fs):
    def f(d):
        for g in fs:
            g(d)
    return f


def _mkdir(name, mode=0o755):
    def f(d):
        p = os.path.join(d, name)
        os.mkdir(p)
        os.chmod(p, mode)
    return f


def _touch(name, data=b"old"):
    def f(d):
        with open(os.path.join(d, name), "wb") as fh:
            fh.write(data)
    return f


def _chmod(name, mode):
    def f(d):
        os.chmod(os.path.join(d, name), mode)
    return f


def _hardlink(name, target):
    def f(d):
        os.link(os.path.join(d, target), os.path.join(d, name))
    return f


def _fifo(name):
    def f(d):
        os.mkfifo(os.path.join(d, name))
    return f


def _sparse(name, size):
    def f(d):
        with open(os.path.join(d, name), "wb") as fh:
            fh.truncate(size)
    return f


# --------------------------------------------------------------------------
# Options found in --help that the curated probes do not cover (the CLI grows)
# --------------------------------------------------------------------------
def discover_options(env: dict, cwd: str) -> dict:
    """command -> [(option, kind, (lo, hi) | None)] for every FLOAT / INTEGER option its --help lists."""
    r = run_cli(["--help"], cwd, env, timeout=60)
    cmds, on = [], False
    for ln in r.stdout.splitlines():
        if ln.startswith("Commands:"):
            on = True
            continue
        if on and ln.startswith("  ") and ln.strip():
            name = ln.split()[0]
            if re.fullmatch(r"[a-z][\w-]*", name) and not ln.startswith("   "):
                cmds.append(name)
    out = {}
    for cmd in cmds:
        h = run_cli([cmd, "--help"], cwd, env, timeout=60).stdout
        entries, cur = [], None
        for ln in h.splitlines():
            if re.match(r"^  (-\w, )?--[\w-]", ln):
                cur = [ln]
                entries.append(cur)
            elif cur is not None and ln.startswith("    "):
                cur.append(ln)
            else:
                cur = None
        opts = []
        for e in entries:
            text = " ".join(x.strip() for x in e)
            m = re.match(r"(?:-\w, )?(--[\w-]+)(?: / --[\w-]+)?\s+(FLOAT\.\.\.|FLOAT|INTEGER RANGE|INTEGER)\b", text)
            if not m:
                continue
            opt, kind = m.group(1), m.group(2)
            rng = None
            mr = re.search(r"(-?\d+)<=x<=(-?\d+)", text)
            if mr:
                rng = (int(mr.group(1)), int(mr.group(2)))
            elif re.search(r"x>=(-?\d+)", text):
                rng = (int(re.search(r"x>=(-?\d+)", text).group(1)), 10**18)
            opts.append((opt, kind, rng))
        out[cmd] = opts
    return out


def discovered_probes(found: dict) -> list[Probe]:
    P = []
    full = ("solve", "trace", "animate", "export", "fold-curve", "plot", "shape", "folds")
    for cmd, opts in found.items():
        base = list(BASE.get(cmd, [cmd]))
        for opt, kind, rng in opts:
            if opt in COVERED.get(cmd, ()) or kind == "FLOAT...":
                continue
            b = base
            if opt == "--T" and "--gamma" in b:      # the tension instead of gamma
                i = b.index("--gamma")
                b = b[:i] + b[i + 2:]
            if kind == "FLOAT":
                for v in (FLOAT_VALUES if cmd in full else FLOAT_SHARED):
                    exp, why = float_expect(v, FINITE)
                    P.append(Probe(f"discovered:{cmd}", replace_opt(b, opt, v), exp,
                                   f"{opt} {v!r} (found in --help, no curated rule): {why}",
                                   files=BASE_FILES.get(cmd, ())))
            else:
                lo, hi = rng or (-(10**18), 10**18)
                for v in (INT_VALUES if cmd in full else INT_SHARED):
                    exp, why = int_expect(v, lo, hi)
                    P.append(Probe(f"discovered:{cmd}", replace_opt(b, opt, v), exp,
                                   f"{opt} {v!r} (found in --help): {why}", files=BASE_FILES.get(cmd, ())))
    return P


def text_option_probes() -> list[Probe]:
    """Options that carry numbers inside text: --weight-direction, --reference, --config, plot/export/animate."""
    P = []
    S = BASE["solve"]
    T = ["trace", "--gamma", "1", "--stretch-max", "0.02", "--max-steps", "6", "--out", "o.h5", "--quiet"]
    for v, exp in [("0,0,-1", "ok"), ("0,0,0", "err"), ("-0,-0,-0", "err"), ("nan,0,-1", "err"), ("inf,0,0", "err"),
                   ("1,2", "err"), ("1,2,3,4", "err"), ("a,b,c", "err"), ("", "err"), (",,", "err"),
                   ("1e308,1e308,1e308", "any"), ("1e-300,0,0", "any"), ("0,0,1", "any"), (" 0 , 0 , -1 ", "ok"),
                   ("0;0;-1", "err"), ("1,0,0", "any"), ("0,1e-300,-1", "any"), ("1e309,0,0", "err")]:
        P.append(Probe("text:weight-direction", S + ["--weight-direction", v], exp, f"--weight-direction {v!r}"))
        if exp != "ok" and v in ("0,0,0", "nan,0,-1", "1e308,1e308,1e308", "1,0,0", ""):
            P.append(Probe("text:weight-direction", T + ["--weight-direction", v], exp, f"--weight-direction {v!r}"))
    refs = [("straight", "ok"), ("", "err"), ("bogus", "err"), ("straight:1", "any"), (":", "err"), ("bump", "err"),
            ("bump:0.1,0", "ok"), ("bump:nan,0", "err"), ("bump:inf,0", "err"), ("bump:1e308,0", "any"),
            ("bump:0.1", "any"), ("bump:0.1,0,5", "any"), ("bump:,", "err"), ("bump:a,b", "err"),
            ("wiggle:0.01,0.01", "ok"), ("wiggle:1e-300,-1e-300", "any"), ("arc:nan", "err"), ("arc:1e308", "any"),
            ("arc:0", "any"), ("arc:3.2", "any"), ("arc:0.5,1e308", "any"), ("helix:0,0", "any"), ("helix:-1,1", "any"),
            ("helix:1e-300,1e308", "any"), ("helix:0.1,1", "any"), ("well:missing.txt", "err"), ("well:", "err"),
            ("well:text.txt", "any"), ("well:X.h5", "any"), ("well:adir", "err"), ("BUMP:0.1,0", "any"),
            ("bump:0x1,0", "err"), ("bump:" + HUGER + ",0", "err")]
    for v, exp in refs:
        fx = tuple(f for f in ("text.txt", "X.h5") if f in v)
        setup = _mkdir("adir") if "adir" in v else None
        P.append(Probe("text:reference", S + ["--reference", v], exp, f"--reference {v!r}", files=fx, setup=setup,
                       setup_desc="mkdir adir" if setup else ""))
        if v in ("bump:nan,0", "bump:1e308,0", "arc:1e308", "helix:0,0", "well:text.txt", "bump:0.1,0", "bogus"):
            P.append(Probe("text:reference", T + ["--reference", v], "any" if exp == "ok" else exp,
                           f"--reference {v!r} in a trace", files=fx))
    # --config TOML files
    tomls = [
        ("empty", "", "ok", "an empty TOML file: nothing set"),
        ("valid", "[rod]\nEI = 1.0\n[loads]\ngamma = 1.0\n[mesh]\nN = 15\n", "ok", "a valid file"),
        ("badtoml", "[rod\nEI = ", "err", "not TOML"),
        ("ei_nan", "[rod]\nEI = nan\n", "err", "EI = nan (TOML has nan)"),
        ("ei_inf", "[rod]\nEI = inf\n", "err", "EI = inf"),
        ("ei_minf", "[rod]\nEI = -inf\n", "err", "EI = -inf"),
        ("ei_str", "[rod]\nEI = \"abc\"\n", "err", "EI a string"),
        ("ei_neg", "[rod]\nEI = -1.0\n", "err", "EI < 0"),
        ("ei_bool", "[rod]\nEI = true\n", "err", "EI = true: a boolean is not a stiffness"),
        ("ei_array", "[rod]\nEI = [1.0, 2.0]\n", "err", "EI an array"),
        ("ei_table", "[rod]\nEI = {a = 1}\n", "err", "EI a table"),
        ("ei_date", "[rod]\nEI = 1979-05-27\n", "err", "EI a date"),
        ("gamma_big", "[loads]\ngamma = 1e308\n", "any", "gamma = 1e308"),
        ("gamma_bool", "[loads]\ngamma = true\n", "err", "gamma = true"),
        ("n_zero", "[mesh]\nN = 0\n", "err", "N = 0"),
        ("n_frac", "[mesh]\nN = 2.7\n", "err", "N = 2.7: not an integer (must not be truncated to 2)"),
        ("n_huge", "[mesh]\nN = 99999999999999999999999\n", "err", "N beyond 64 bits"),
        ("n_str", "[mesh]\nN = \"15\"\n", "any", "N as a string \"15\""),
        ("k_frac", "[mesh]\nk = 4.5\n", "err", "k = 4.5"),
        ("k_eight", "[mesh]\nk = 8\n", "err", "k = 8"),
        ("uniform_str", "[mesh]\nuniform = \"maybe\"\n", "err", "uniform = \"maybe\""),
        ("unknown_section", "[bogus]\nx = 1\n", "err", "unknown section"),
        ("unknown_key", "[rod]\nbogus = 1\n", "err", "unknown key"),
        ("not_section", "EI = 1.0\n", "err", "a key outside any section"),
        ("wd_zero", "[rod]\nweight_direction = [0, 0, 0]\n", "err", "weight_direction = [0, 0, 0]"),
        ("wd_nan", "[rod]\nweight_direction = [nan, 0, -1]\n", "err", "weight_direction with nan"),
        ("wd_nested", "[rod]\nweight_direction = [[0], 0, -1]\n", "err", "weight_direction nested"),
        ("ref_bogus", "[rod]\nreference = \"bogus\"\n", "err", "reference = bogus"),
        ("ref_num", "[rod]\nreference = 5\n", "err", "reference a number"),
        ("trace_out", "[trace]\nout = \"X.h5\"\noverwrite = true\n", "ok",
         "a config that names the output and overwrite (solve --out writes a one-point branch file)"),
        ("dup", "[rod]\nEI = 1.0\nEI = 2.0\n", "err", "a duplicate key"),
        ("utf16", "\ufeff[rod]\nEI = 1.0\n", "any", "a BOM"),
        ("big", "# " + "x" * 2_000_000 + "\n[rod]\nEI = 1.0\n", "err", "a 2 MB file (a problem file is under 1 MB)"),
        ("deep", "a = " + "[" * 5000 + "]" * 5000 + "\n", "err", "5000 nested arrays (recursion)"),
    ]

    def writer(name, text):
        def f(d):
            with open(os.path.join(d, name), "w", encoding="utf-8") as fh:
                fh.write(text)
        return f

    for name, text, exp, why in tomls:
        fn = f"{name}.toml"
        P.append(Probe("text:config", S + ["--config", fn], exp, f"--config: {why}", setup=writer(fn, text),
                       setup_desc=f"printf {shlex.quote(text[:80])} > {fn}"))
    for name in ("ei_nan", "n_frac", "deep", "trace_out", "badtoml"):
        text = dict((t[0], t[1]) for t in tomls)[name]
        exp = dict((t[0], t[2]) for t in tomls)[name]
        if name == "trace_out":
            exp, why = "err", "a config that sets --out to the start file and --overwrite"
            args = ["trace", "--start", "X.h5:3", "--max-steps", "3", "--quiet", "--config", "c.toml"]
            P.append(Probe("text:config", args, exp, why, files=("X.h5",), setup=writer("c.toml", text),
                           setup_desc="printf '[trace]\\nout = \"X.h5\"\\noverwrite = true\\n' > c.toml"))
            continue
        P.append(Probe("text:config", T + ["--config", "c.toml"], exp, f"--config in a trace: {name}",
                       setup=writer("c.toml", text), setup_desc=f"printf {shlex.quote(text[:60])} > c.toml"))
    for fn, exp, why, fx, setup, desc in [
            ("missing.toml", "err", "missing", (), None, ""),
            ("adir", "err", "a directory", (), _mkdir("adir"), "mkdir adir"),
            ("X.h5", "err", "an HDF5 file as TOML", ("X.h5",), None, ""),
            ("pic.png", "err", "a PNG as TOML", ("pic.png",), None, ""),
            ("/dev/zero", "err", "/dev/zero (endless)", (), None, ""),
            ("fifo.toml", "err", "a FIFO nobody writes to", (), _fifo("fifo.toml"), "mkfifo fifo.toml"),
            ("", "err", "'' as the config", (), None, "")]:
        P.append(Probe("text:config", S + ["--config", fn], exp, f"--config {why}", files=fx, setup=setup,
                       setup_desc=desc, timeout=30))
    P.append(Probe("text:config", ["trace", "--gamma", "1", "--stretch-max", "0.02", "--quiet", "--config", "c.toml",
                                   "--out", "c.toml", "--overwrite"], "err", "--out is the config file",
                   setup=writer("c.toml", "[mesh]\nN = 15\n"), setup_desc="printf '[mesh]\\nN = 15\\n' > c.toml"))
    # plot variables, labels, scales
    PL = ["plot", "X.h5", "-o", "p.png"]
    for extra, exp, why in [(["--x", "bogus"], "err", "unknown variable"), (["--y", ""], "err", "empty variable"),
                            (["--x", "phi_L", "--y", "phi_L"], "any", "the same variable twice"),
                            (["--x", "helical_waves"], "ok", "an integer variable"),
                            (["--x", "torque", "--y", "phi_L"], "ok", "the distinguished diagram"),
                            (["--x", "EI"], "err", "a parameter the branch does not have"),
                            (["--x", "coefficients"], "err", "a matrix"), (["--x", "kind"], "err", "strings"),
                            (["--label", "a", "--label", "b"], "err", "two labels for one file"),
                            (["--label", ""], "any", "an empty label"),
                            (["--label", "$\\undefinedcmd$"], "err", "a label that is bad mathtext"),
                            (["--log", "--x", "phi_L"], "any", "log scale over Phi that starts at 0"),
                            (["--log", "--x", "min_alignment"], "ok", "log scale of a positive variable"),
                            (["--log", "--x", "dphi_ds"], "any", "log scale of a signed variable")]:
        P.append(Probe("text:plot", PL + extra, exp, why, files=("X.h5",)))
    P.append(Probe("text:plot", ["plot", "X.h5", "C.h5", "--x", "gamma", "-o", "p.png"], "any",
                   "a parameter only the fold curve has", files=("X.h5", "C.h5")))
    # export: formats, points, outputs
    EX = ["export", "X.h5"]
    for extra, exp, why, fx, setup, desc, kw in [
            (["--point", "0", "-o", "e.csv"], "ok", "csv", (), None, "", {}),
            (["--point", "0", "-o", "e.vtp"], "ok", "vtk", (), None, "", {}),
            (["--point", "0", "-o", "e.npz"], "ok", "npz", (), None, "", {}),
            (["--point", "0", "-o", "e.txt"], "err", "unknown suffix, no --format", (), None, "", {}),
            (["--point", "0", "-o", "e.csv", "--format", "npz"], "any", "suffix and --format disagree", (), None, "",
             {}),
            (["--point", "0", "-o", ""], "err", "'' as -o", (), None, "", {}),
            (["--point", "0", "-o", "adir"], "err", "a directory", (), _mkdir("adir"), "mkdir adir", {}),
            (["--point", "0", "-o", "X.h5"], "err", "-o is the input", (), None, "", {}),
            (["--point", "0", "-o", "X.h5", "--format", "csv"], "err", "-o is the input (format given)", (), None,
             "", {}),
            (["--point", "0", "-o", "link.csv"], "err", "-o is the input through a symlink", (),
             _symlink("link.csv", "X.h5"), "ln -s X.h5 link.csv", {}),
            (["--point", "0", "-o", "full.csv"], "err", "a symlink to a full device: the device must stay", (),
             _chain(FULL, _symlink("full.csv", "devfull")), "mknod devfull c 1 7; ln -s devfull full.csv", {}),
            (["--point", "0", "--format", "csv", "-o", "devnull"], "any",
             "a null device as -o: written to or refused, never replaced", (), NULL, "mknod devnull c 1 3", {}),
            (["--point", "0", "--format", "csv", "-o", "devfull"], "err", "a full device as -o", (), FULL,
             "mknod devfull c 1 7", {}),
            (["--point", "0", "-o", "nodir/e.csv"], "err", "missing directory", (), None, "", {}),
            (["--point", "0", "-o", "e.csv"], "err", "RLIMIT_FSIZE 4 kB", (), None, "", {"fsize": 4000}),
            (["--all", "--format", "vtk", "-o", "s.pvd"], "ok", "every point as a .pvd series", (), None, "", {}),
            (["--all", "--format", "vtk", "-o", "s.pvd"], "err", "RLIMIT_FSIZE 20 kB during a .pvd series", (), None,
             "", {"fsize": 20000}),
            (["--all", "-o", "all.npz"], "ok", "every point, npz", (), None, "", {}),
            (["--all", "-o", "all.csv"], "err", "every point as one CSV?", (), None, "", {}),
            (["--all", "--point", "3", "-o", "e.csv"], "err", "--all and --point", (), None, "", {}),
            (["--all", "--format", "vtk", "-o", "s.pvd"], "err", "the series' directory exists as a file", (),
             _touch("s_vtp"), "echo old > s_vtp", {}),
            (["--point", "F1", "-o", "e.csv"], "err", "no fold", (), None, "", {}),
            (["--point", "0", "--grid", "s", "-o", "e.csv"], "ok", "--grid s", (), None, "", {}),
            (["--point", "0", "--samples", "1000000", "-o", "e.npz"], "any",
             "the top of --samples (about a minute, a 250 MB file)", (), None, "", {"timeout": 200, "heavy": True}),
            (["--point", "0", "--branch", "0", "-o", "e.csv"], "err", "--branch on a branch file", (), None, "", {}),
    ]:
        P.append(Probe("text:export", EX + extra, exp, f"export: {why}", files=("X.h5",) + fx, setup=setup,
                       setup_desc=desc, **kw))
    for spec, exp in [("D.h5:0", "ok"), ("D.h5:0:3", "ok"), ("D.h5:7", "err"), ("D.h5", "any"), ("X.h5:0", "any")]:
        f = spec.split(":")[0]
        P.append(Probe("text:export", ["export", spec, "-o", "e.csv"] + (["--point", "0"] if spec.count(":") < 2 else []),
                       exp, f"export {spec}", files=(f,)))
    # animate: outputs and inputs
    AN = ["animate", "X.h5", "--max-frames", "3", "--samples", "20", "-o"]
    for out, exp, why, setup, desc, kw in [
            ("a.gif", "ok", "a GIF", None, "", {}), ("a.mp4", "any", "MP4: needs ffmpeg", None, "", {}),
            ("a.png", "err", "a PNG is not an animation", None, "", {}), ("", "err", "''", None, "", {}),
            ("X.h5", "err", "the input", None, "", {}), ("adir", "err", "a directory", _mkdir("adir"), "mkdir adir", {}),
            ("link.gif", "err", "the input through a symlink", _symlink("link.gif", "X.h5"), "ln -s X.h5 link.gif", {}),
            ("full.gif", "err", "a symlink to a full device: the device must stay",
             _chain(FULL, _symlink("full.gif", "devfull")), "mknod devfull c 1 7; ln -s devfull full.gif", {}),
            ("nodir/a.gif", "err", "missing directory", None, "", {}),
            ("a.gif", "err", "RLIMIT_FSIZE 8 kB", None, "", {"fsize": 8000})]:
        P.append(Probe("text:animate", AN + [out], exp, f"animate -o: {why}", files=("X.h5",), setup=setup,
                       setup_desc=desc, **kw))
    for f, exp in [("D.h5", "any"), ("D.h5:0", "ok"), ("D.h5:3", "err"), ("C.h5", "any"), ("E.h5", "any"),
                   ("X.h5:0", "err"), ("empty.h5", "err"), ("flipN000.h5", "any"), ("edit_empty.h5", "err"),
                   ("edit_one_point.h5", "any")]:
        P.append(Probe("text:animate", ["animate", f, "--max-frames", "3", "--samples", "20", "-o", "a.gif"], exp,
                       f"animate {f}", files=(f.split(":")[0],)))
    return P


def contradiction_probes(is_root: bool) -> list[Probe]:
    P = []
    q = ["--quiet"]
    short = ["--stretch-max", "0.02", "--max-steps", "8"]

    def add(group, args, exp, why, **kw):
        P.append(Probe(group, args, exp, why, **kw))

    T = ["trace", "--gamma", "1"] + short
    # -- contradictory numbers
    add("contra", T + ["--phi-min", "5", "--phi-max", "5", "--out", "o.h5"] + q, "err", "phi-min == phi-max")
    add("contra", T + ["--phi-min", "6", "--phi-max", "5", "--out", "o.h5"] + q, "err", "phi-min > phi-max")
    add("contra", T + ["--ds", "1", "--ds-max", "0.5", "--out", "o.h5"] + q, "err", "ds > ds-max, both explicit")
    add("contra", T + ["--ds-max", "0.01", "--out", "o.h5"] + q, "ok", "only ds-max: ds is clamped (documented)")
    add("contra", T + ["--ds-min", "0.2", "--ds", "0.1", "--out", "o.h5"] + q, "err", "ds-min > ds")
    add("contra", T + ["--ds-min", "0.6", "--out", "o.h5"] + q, "err", "ds-min > ds-max (default)")
    add("contra", T + ["--ds", "0.3", "--ds-max", "0.2", "--ds-min", "0.4", "--out", "o.h5"] + q, "err", "all three")
    add("contra", T + ["--stretch-max", "-1", "--out", "o.h5"] + q, "err", "start already beyond stretch-max")
    add("contra", T + ["--phi-min", "1", "--phi-max", "2", "--out", "o.h5"] + q, "any",
        "start Phi = 0 outside [phi-min, phi-max]")
    add("contra", T + ["--min-alignment", "0.9999", "--out", "o.h5"] + q, "any", "guard right at the start")
    add("contra", T + ["--N", "20", "--N-max", "10", "--out", "o.h5"] + q, "any", "N > N-max")
    add("contra", T + ["--max-error", "1e-300", "--out", "o.h5"] + q, "any", "unreachable accuracy")
    add("contra", ["trace", "--gamma", "1", "--from-straight", "1", "--start", "X.h5:0", "--out", "o.h5"] + q,
        "err", "--start with --from-straight", files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:0", "--from-straight", "1", "--out", "o.h5"] + q,
        "err", "--start with --from-straight (no gamma)", files=("X.h5",))
    add("contra", T + ["--param", "EI", "--out", "o.h5"] + q, "err", "--param without --range")
    add("contra", T + ["--range", "1", "2", "--out", "o.h5"] + q, "err", "--range without --param")
    add("contra", T + ["--param", "EI", "--range", "1", "2", "--out", "o.h5"] + q, "err",
        "--param EI needs --start or --from-straight")
    add("contra", ["trace", "--gamma", "1", "--from-straight", "1", "--param", "EI", "--range", "2", "1",
                   "--out", "o.h5"] + q, "err", "range A > B")
    add("contra", ["trace", "--gamma", "1", "--from-straight", "1", "--param", "EI", "--range", "1", "1",
                   "--out", "o.h5"] + q, "err", "range A == B")
    add("contra", ["trace", "--gamma", "1", "--from-straight", "1", "--param", "EI", "--range", "2", "3",
                   "--max-steps", "4", "--out", "o.h5"] + q, "any", "EI = 1 outside the range [2, 3]")
    add("contra", ["trace", "--start", "X.h5:3", "--param", "gamma", "--range", "0.5", "2", "--max-steps", "4",
                   "--out", "o.h5"] + q, "ok", "a restart in gamma", files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:3", "--param", "phi_L", "--range", "0.5", "2", "--out", "o.h5"] + q,
        "err", "--range with phi_L", files=("X.h5",))
    add("contra", T + ["--switch", "--out", "o.h5"] + q, "err", "--switch without --start")
    add("contra", ["trace", "--start", "X.h5:3", "--switch", "--out", "o.h5"] + q, "err", "--switch at a regular point",
        files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:BP1", "--switch", "--out", "o.h5"] + q, "err", "--switch, no BP",
        files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:3", "--gamma", "2", "--out", "o.h5"] + q, "err",
        "--gamma differs from the start file", files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:3", "--EI", "2", "--out", "o.h5"] + q, "err",
        "--EI differs from the start file", files=("X.h5",))
    add("contra", ["trace", "--start", "X.h5:3", "--N", "20", "--max-steps", "4", "--out", "o.h5"] + q, "ok",
        "restart on another mesh (documented)", files=("X.h5",))
    add("contra", ["trace", "--start", "F.h5:F1", "--direction", "down", "--max-steps", "4", "--out", "o.h5"] + q,
        "ok", "restart at the fold, going down", files=("F.h5",))
    add("contra", ["trace", "--start", "X.h5:3", "--k", "3", "--max-steps", "4", "--out", "o.h5"] + q, "any",
        "--k with --start (the file's k is used)", files=("X.h5",))
    add("contra", ["trace", "--out", "o.h5"] + q, "err", "no --gamma and no --start")
    add("contra", ["trace", "--gamma", "1"] + q, "err", "no --out")
    add("contra", ["trace", "--gamma", "-100", "--out", "o.h5"] + q, "err", "below the Euler load")
    add("contra", ["solve", "--gamma", "1"], "err", "--phi missing")
    add("contra", ["solve", "--gamma", "1", "--phi", "20"], "err", "beyond the first fold: no convergence")
    add("contra", ["solve", "--gamma", "1", "--phi", "1", "--w", "0"], "any", "weightless rod, gamma given")
    add("contra", ["critical", "--gamma", "1", "--phi-min", "20", "--phi-max", "10"], "err", "phi-min > phi-max")
    add("contra", ["critical", "--gamma", "1", "--phi-min", "10", "--phi-max", "10"], "err", "phi-min == phi-max")
    add("contra", ["critical", "--gamma", "1", "--w", "0"], "err", "gamma needs a weight (documented)")
    add("contra", ["diagram", "--gamma", "1", "--phi-min", "5", "--phi-max", "4", "--out", "o.h5"] + q, "err",
        "phi-min > phi-max")
    add("contra", ["diagram", "--gamma", "1", "--ds", "1", "--ds-max", "0.1", "--out", "o.h5"] + q, "err", "ds > ds-max")
    add("contra", ["fold-curve", "F.h5:0", "--range", "1.1", "0.9", "--out", "o.h5"] + q, "err", "range A > B",
        files=("F.h5",))
    add("contra", ["fold-curve", "F.h5:0", "--range", "1", "1", "--out", "o.h5"] + q, "err", "range A == B",
        files=("F.h5",))
    add("contra", ["fold-curve", "F.h5:0", "--range", "2", "3", "--out", "o.h5"] + q, "err",
        "range not containing the fold's gamma = 1", files=("F.h5",))
    add("contra", ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--ds", "1", "--ds-max", "0.5", "--out",
                   "o.h5"] + q, "err", "ds > ds-max", files=("F.h5",))
    add("contra", ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--ds-max", "0.01", "--max-steps", "3",
                   "--out", "o.h5"] + q, "any", "only ds-max below the default ds", files=("F.h5",))
    S = ["sweep"] + short + ["--jobs", "1"] + q
    add("contra", ["sweep", "--gamma", "1", "1"] + S[1:] + ["--out", "od"], "err", "the same gamma twice")
    add("contra", ["sweep", "--gamma", "1", "1.0"] + S[1:] + ["--out", "od"], "err", "1 and 1.0 are the same gamma")
    add("contra", ["sweep", "--gamma", "0", "-0"] + S[1:] + ["--out", "od"], "any", "0 and -0")
    add("contra", ["sweep", "--gamma", "1", "--phi-min", "3", "--phi-max", "2"] + S[1:] + ["--out", "od"], "err",
        "phi-min > phi-max")
    add("contra", ["sweep", "--gamma", "1", "--stretch-max", "-1", "--max-steps", "8", "--jobs", "1", "--out", "od"]
        + q, "err", "every gamma fails at its start (guard violated): no convergence -> exit 2, no directory left")
    add("contra", ["sweep", "--gamma", "1", "1e300", "--stretch-max", "0.02", "--max-steps", "8", "--jobs", "1",
                   "--out", "od"] + q, "any", "gamma 1e300: T = 1e301 is finite but far outside the working range; "
        "the failing Gamma is reported (exit 2) and the other one is kept",
        partial_ok=("od", "od/gamma_1.h5", "od/response_diagram.png"))
    add("contra", ["sweep", "--gamma", "1e308", "--stretch-max", "0.02", "--max-steps", "8", "--jobs", "1",
                   "--out", "od"] + q, "err", "T = 1e308 * 10 = inf")
    add("contra", ["sweep", "--gamma", "-100", "--out", "od"] + q, "err", "below the Euler load")
    add("contra", ["sweep", "--gamma", "1", "--diagram", "--phi-max", "3", "--stretch-max", "0.02", "--max-steps",
                   "8", "--jobs", "1", "--out", "od"] + q, "ok", "a diagram sweep")
    add("contra", ["sweep", "--gamma", "-h", "--out", "od"] + q, "err", "-h swallowed as a gamma value")
    add("contra", ["sweep", "--gamma", "--out", "od"] + q, "err", "--gamma with no value")
    # -- unknown things
    add("usage", ["tracee"], "err", "unknown command")
    add("usage", ["trace", "--bogus", "1", "--gamma", "1", "--out", "o.h5"], "err", "unknown option")
    add("usage", ["solve", "--gamma", "1", "--phi", "1", "extra"], "err", "extra argument")
    add("usage", ["plot", "-o", "p.png"], "err", "no input file")
    add("usage", ["folds"], "err", "no input file")
    add("usage", ["folds", "X.h5", "Y.h5"], "err", "two files", files=("X.h5",))
    add("usage", ["trace", "--param", "bogus", "--gamma", "1", "--out", "o.h5"], "err", "bad --param choice")
    add("usage", ["trace", "--direction", "sideways", "--gamma", "1", "--out", "o.h5"], "err", "bad --direction")
    add("usage", ["fold-curve", "F.h5:0", "--range", "1", "--out", "o.h5"], "err", "--range with one number",
        files=("F.h5",))
    add("usage", ["trace", "--gamma", "1", "--out"], "err", "--out with no value")
    add("usage", ["--version"], "ok", "version")
    add("usage", ["trace", "--help"], "ok", "help")
    add("usage", [], "any", "no command: help (exit 0) or a one-line usage error")
    add("usage", ["--debug", "solve", "--gamma", "nan", "--phi", "1"], "err", "--debug does not change user errors")

    # -- outputs: '', directories, devices, symlinks onto inputs, existing files
    for cmd, base in [("trace", ["trace", "--gamma", "1"] + short + q + ["--out"]),
                      ("diagram", ["diagram", "--gamma", "1", "--phi-max", "3"] + short + q + ["--out"]),
                      ("fold-curve", ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--max-steps", "3"] + q
                       + ["--out"])]:
        fx = ("F.h5",) if cmd == "fold-curve" else ()
        g = f"output:{cmd}"
        add(g, base + [""], "err", "'' as --out", files=fx)
        add(g, base + ["   "], "err", "blanks as --out", files=fx)
        add(g, base + ["adir"], "err", "a directory as --out", files=fx, setup=_mkdir("adir"), setup_desc="mkdir adir")
        add(g, base + ["adir/"], "err", "a directory (trailing slash)", files=fx, setup=_mkdir("adir"),
            setup_desc="mkdir adir")
        add(g, base + ["new.h5/"], "any", "trailing slash on a new name: refuse it, or write new.h5 and say so "
            "(a failure must leave nothing)", files=fx)
        add(g, base + ["devfull"], "err", "a full device exists (no --overwrite)", files=fx, setup=FULL,
            setup_desc="mknod devfull c 1 7")
        add(g, base + ["devfull", "--overwrite"], "err", "a full device is not a regular file", files=fx, setup=FULL,
            setup_desc="mknod devfull c 1 7")
        add(g, base + ["devnull", "--overwrite"], "err", "a null device is not a regular file", files=fx, setup=NULL,
            setup_desc="mknod devnull c 1 3")
        add(g, base + ["full.h5", "--overwrite"], "err", "a symlink to a full device", files=fx,
            setup=_chain(FULL, _symlink("full.h5", "devfull")), setup_desc="mknod devfull c 1 7; ln -s devfull full.h5")
        add(g, base + ["nodir/o.h5"], "err", "the directory does not exist", files=fx)
        add(g, base + ["afile/o.h5"], "err", "a file as the directory", files=fx, setup=_touch("afile"),
            setup_desc="echo old > afile")
        add(g, base + ["old.h5"], "err", "an existing file without --overwrite", files=fx, setup=_touch("old.h5"),
            setup_desc="echo old > old.h5")
        add(g, base + ["old.h5", "--overwrite"], "ok", "--overwrite replaces a non-input file", files=fx,
            setup=_touch("old.h5"), setup_desc="echo old > old.h5", changes_ok=("old.h5",))
        add(g, base + ["dangling.h5"], "err", "a dangling symlink exists (lexists) without --overwrite", files=fx,
            setup=_symlink("dangling.h5", "nowhere/x.h5"), setup_desc="ln -s nowhere/x.h5 dangling.h5")
        add(g, base + ["dangling.h5", "--overwrite"], "err", "a dangling symlink into a missing directory",
            files=fx, setup=_symlink("dangling.h5", "nowhere/x.h5"), setup_desc="ln -s nowhere/x.h5 dangling.h5")
        add(g, base + ["loop.h5", "--overwrite"], "any", "a symlink loop: --overwrite may replace the link",
            files=fx, setup=_symlink("loop.h5", "loop.h5"), setup_desc="ln -s loop.h5 loop.h5",
            changes_ok=("loop.h5",))
        add(g, base + ["o" * 250 + ".h5"], "ok", "a valid 253-byte file name (NAME_MAX is 255)", files=fx)
        add(g, base + ["o" * 252 + ".h5"], "any", "a 255-byte file name: valid, but no room for a lock/temp name",
            files=fx)
        add(g, base + ["o" * 256 + ".h5"], "err", "a file name longer than NAME_MAX", files=fx)
        add(g, base + ["o.h5"], "err", "RLIMIT_FSIZE 30 kB: the disk is full", files=fx, fsize=30_000,
            partial_ok=("o.h5",))
        if is_root:
            add(g, base + ["ro/o.h5"], "err", "read-only directory (run without CAP_DAC_OVERRIDE (setpriv))", files=fx, user="nocap",
                setup=_mkdir("ro", 0o555), setup_desc="mkdir -m 555 ro; run without CAP_DAC_OVERRIDE (setpriv)")
            add(g, base + ["o.h5"], "err", "read-only working directory (run without CAP_DAC_OVERRIDE (setpriv))", files=fx, user="nocap",
                ro_cwd=True, setup_desc="cwd mode 555; run without CAP_DAC_OVERRIDE (setpriv)")
    # through symlinks / links / other spellings onto the input file of a restart or a fold curve
    for spec_file, cmd_base in [("X.h5", ["trace", "--start", "X.h5:3", "--max-steps", "3"] + q),
                                ("F.h5", ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--max-steps", "3"] + q)]:
        g = "output:is-input"
        add(g, cmd_base + ["--out", spec_file], "err", "--out is the input (no --overwrite)", files=(spec_file,))
        add(g, cmd_base + ["--out", spec_file, "--overwrite"], "err", "--overwrite onto the input",
            files=(spec_file,))
        add(g, cmd_base + ["--out", "./" + spec_file, "--overwrite"], "err", "./input", files=(spec_file,))
        add(g, cmd_base + ["--out", "sub/../" + spec_file, "--overwrite"], "err", "sub/../input", files=(spec_file,),
            setup=_mkdir("sub"), setup_desc="mkdir sub")
        add(g, cmd_base + ["--out", "/proc/self/cwd/" + spec_file, "--overwrite"], "err", "/proc/self/cwd/input",
            files=(spec_file,))
        add(g, cmd_base + ["--out", "link.h5", "--overwrite"], "err", "a symlink to the input", files=(spec_file,),
            setup=_symlink("link.h5", spec_file), setup_desc=f"ln -s {spec_file} link.h5")
        add(g, cmd_base + ["--out", "hard.h5", "--overwrite"], "err", "a hard link to the input", files=(spec_file,),
            setup=_hardlink("hard.h5", spec_file), setup_desc=f"ln {spec_file} hard.h5")
        add(g, cmd_base + ["--out", "dl/" + spec_file, "--overwrite"], "err", "via a symlinked directory",
            files=(spec_file,), setup=_symlink("dl", "."), setup_desc="ln -s . dl")
        add(g, cmd_base + ["--out", "chain.h5", "--overwrite"], "err", "a chain of two symlinks", files=(spec_file,),
            setup=_chain(_symlink("link.h5", spec_file), _symlink("chain.h5", "link.h5")),
            setup_desc=f"ln -s {spec_file} link.h5; ln -s link.h5 chain.h5")
        # the input given through the symlink and the output as the real file
        alt = [("link.h5:" + a.split(":", 1)[1]) if a.startswith(spec_file + ":") else a for a in cmd_base]
        add(g, alt + ["--out", spec_file, "--overwrite"], "err", "input through a symlink, --out the real file",
            files=(spec_file,), setup=_symlink("link.h5", spec_file), setup_desc=f"ln -s {spec_file} link.h5")
    # image outputs
    for cmd, base in [("plot", ["plot", "X.h5", "-o"]), ("shape", ["shape", "X.h5", "-o"])]:
        g = f"output:{cmd}"
        add(g, base + [""], "err", "'' as -o", files=("X.h5",))
        add(g, base + ["adir"], "err", "a directory", files=("X.h5",), setup=_mkdir("adir"), setup_desc="mkdir adir")
        add(g, base + ["X.h5"], "err", "-o is the input", files=("X.h5",))
        add(g, base + ["link.png"], "err", "-o is the input through a symlink", files=("X.h5",),
            setup=_symlink("link.png", "X.h5"), setup_desc="ln -s X.h5 link.png")
        add(g, base + ["p.txt"], "err", "not a .png name", files=("X.h5",))
        add(g, base + ["devfull"], "err", "a full device (not .png)", files=("X.h5",), setup=FULL,
            setup_desc="mknod devfull c 1 7")
        add(g, base + ["full.png"], "err", "a .png symlink to a full device: the write fails (publish maps ENOSPC "
            "to exit 2 for branch files; a PNG should not differ) and the device stays", files=("X.h5",),
            setup=_chain(FULL, _symlink("full.png", "devfull")), setup_desc="mknod devfull c 1 7; ln -s devfull full.png")
        add(g, base + ["nodir/p.png"], "err", "missing directory", files=("X.h5",))
        add(g, base + ["p.png"], "err", "RLIMIT_FSIZE 8 kB: the PNG cannot be written whole", files=("X.h5",),
            fsize=8_000)
        add(g, base + ["old.png"], "any", "an existing PNG (no --overwrite option exists)", files=("X.h5",),
            setup=_touch("old.png"), setup_desc="echo old > old.png", changes_ok=("old.png",))
        add(g, base + ["P.PNG"], "ok", "upper-case suffix", files=("X.h5",))
        add(g, base + ["o" * 251 + ".png"], "ok", "a 255-byte name", files=("X.h5",))
        if is_root:
            add(g, base + ["ro/p.png"], "err", "read-only directory (root without CAP_DAC_OVERRIDE)", files=("X.h5",), user="nocap",
                setup=_mkdir("ro", 0o555), setup_desc="mkdir -m 555 ro; run without CAP_DAC_OVERRIDE (setpriv)")
    add("output:plot", ["plot", "X.h5", "X.h5", "-o", "p.png"], "any", "the same file twice", files=("X.h5",))
    add("output:plot", ["plot", "X.h5", "empty.h5", "-o", "p.png"], "err", "a valid file then an empty one: no PNG",
        files=("X.h5", "empty.h5"))
    add("output:plot", ["plot", "X.h5", "text.txt", "-o", "p.png"], "err", "a valid file then a text file: no PNG",
        files=("X.h5", "text.txt"))
    add("output:plot", ["plot", "X.h5", "pic.png", "-o", "pic.png"], "err", "-o is one of the inputs (a PNG)",
        files=("X.h5", "pic.png"))
    add("output:plot", ["plot", "X.h5", "F.h5", "D.h5", "C.h5", "-o", "p.png"], "ok", "every kind of file",
        files=("X.h5", "F.h5", "D.h5", "C.h5"))
    # sweep output directories
    SW = ["sweep", "--gamma", "1"] + short + ["--jobs", "1"] + q + ["--out"]
    g = "output:sweep"
    add(g, SW + [""], "err", "'' as --out")
    add(g, SW + ["afile"], "err", "an existing file", setup=_touch("afile"), setup_desc="echo old > afile")
    add(g, SW + ["devfull"], "err", "a device as the directory", setup=FULL, setup_desc="mknod devfull c 1 7")
    add(g, SW + ["nodir/sub"], "err", "missing parent")
    add(g, SW + ["od"], "err", "gamma_1.h5 exists in the directory (no --overwrite)",
        setup=_chain(_mkdir("od"), _touch("od/gamma_1.h5")), setup_desc="mkdir od; echo old > od/gamma_1.h5")
    add(g, SW + ["od", "--overwrite"], "ok", "--overwrite",
        setup=_chain(_mkdir("od"), _touch("od/gamma_1.h5")), setup_desc="mkdir od; echo old > od/gamma_1.h5",
        changes_ok=("od/gamma_1.h5",))
    add(g, SW + ["od"], "err", "od/gamma_1.h5 is a directory",
        setup=_chain(_mkdir("od"), _mkdir("od/gamma_1.h5")), setup_desc="mkdir -p od/gamma_1.h5")
    add(g, SW + ["od"], "err", "od/response_diagram.png is a directory: the plot cannot be written",
        setup=_chain(_mkdir("od"), _mkdir("od/response_diagram.png")), setup_desc="mkdir -p od/response_diagram.png",
        partial_ok=("od/gamma_1.h5",))
    add(g, SW + ["od"], "err", "RLIMIT_FSIZE 30 kB", fsize=30_000, partial_ok=("od", "od/gamma_1.h5"))
    add(g, SW + ["dl"], "err", "a dangling symlink as the directory", setup=_symlink("dl", "nowhere"),
        setup_desc="ln -s nowhere dl")
    if is_root:
        add(g, SW + ["ro/sub"], "err", "read-only parent (root without CAP_DAC_OVERRIDE)", user="nocap", setup=_mkdir("ro", 0o555),
            setup_desc="mkdir -m 555 ro; run without CAP_DAC_OVERRIDE (setpriv)")
        add(g, SW + ["ro"], "err", "an existing read-only directory (root without CAP_DAC_OVERRIDE)", user="nocap",
            setup=_mkdir("ro", 0o555), setup_desc="mkdir -m 555 ro; run without CAP_DAC_OVERRIDE (setpriv)")
    # stdout on a full device (machine error: rodcont's policy is exit 1 for disk errors)
    for args, fx in [(["folds", "X.h5"], ("X.h5",)), (["solve", "--gamma", "1", "--phi", "1"], ()),
                     (["critical", "--gamma", "1"], ()),
                     (["trace", "--gamma", "1"] + short + ["--out", "o.h5", "--quiet"], ())]:
        add("output:stdout", args, "env", "stdout is /dev/full", files=fx, stdout_path="/dev/full",
            partial_ok=("o.h5",))
        add("output:stdout", args, "ok", "stdout is a pipe whose reader is gone: documented as not an error",
            files=fx, stdout_path="BROKENPIPE", changes_ok=("o.h5",))
        add("output:stdout", args, "env0", "stdout closed (>&-)", files=fx, stdout_path="CLOSED",
            partial_ok=("o.h5",))
    # branch files traced in a rod parameter (E.h5 in EI, G.h5 in gamma): restarts go back to phi_L
    for f, par in (("E.h5", "EI"), ("G.h5", "gamma")):
        g = "spec:param-files"
        add(g, ["folds", f], "ok", f"a branch traced in {par}", files=(f,))
        add(g, ["plot", f, "X.h5", "-o", "p.png"], "ok", f"a branch traced in {par}, plotted with X.h5",
            files=(f, "X.h5"))
        add(g, ["shape", f, "--point", "0", "--point", "-1", "-o", "s.png"], "ok", f"a branch traced in {par}",
            files=(f,))
        add(g, ["trace", "--start", f + ":-1", "--max-steps", "3", "--out", "o.h5", "--quiet"], "ok",
            f"restart in phi_L from a branch traced in {par}", files=(f,))
        add(g, ["trace", "--start", f + ":-1", "--param", par, "--range", "0.1", "5", "--max-steps", "3",
                "--out", "o.h5", "--quiet"], "any", f"restart in {par} again", files=(f,))
        add(g, ["trace", "--start", f + ":0", "--param", "GJ", "--range", "0.1", "5", "--max-steps", "3",
                "--out", "o.h5", "--quiet"], "any", f"restart in GJ from a branch traced in {par}", files=(f,))
        add(g, ["fold-curve", f + ":0", "--range", "0.5", "2", "--out", "o.h5", "--quiet"], "err",
            f"a branch in {par} has no folds in phi_L", files=(f,))
    # file names: not UTF-8, leading dash, newline, colon
    g = "input:names"
    ff = "\udcff.h5"             # the byte 0xff: not UTF-8
    cpx = lambda name: (lambda d: shutil.copy(os.path.join(d, "X.h5"), os.path.join(d, name)))  # noqa: E731
    add(g, ["folds", ff], "ok", "a file name that is not UTF-8", files=("X.h5",), setup=cpx(ff),
        setup_desc="cp X.h5 $'\\xff.h5'")
    add(g, ["plot", ff, "-o", "\udcfe.png"], "ok", "non-UTF-8 input and output names", files=("X.h5",),
        setup=cpx(ff), setup_desc="cp X.h5 $'\\xff.h5'")
    add(g, ["trace", "--start", ff + ":3", "--max-steps", "3", "--out", "\udcfd.h5", "--quiet"], "ok",
        "non-UTF-8 names in a restart", files=("X.h5",), setup=cpx(ff), setup_desc="cp X.h5 $'\\xff.h5'")
    add(g, ["folds", "\udcffmissing.h5"], "err", "a missing non-UTF-8 name (the message must print)")
    add(g, ["trace", "--gamma", "1", "--out", "nodir\udcff/x.h5", "--quiet"], "err",
        "a missing non-UTF-8 directory")
    add(g, ["folds", "--", "-X.h5"], "ok", "a name starting with a dash, after --", files=("X.h5",),
        setup=cpx("-X.h5"), setup_desc="cp X.h5 ./-X.h5")
    add(g, ["folds", "a\nb.h5"], "ok", "a newline in the name", files=("X.h5",), setup=cpx("a\nb.h5"),
        setup_desc="cp X.h5 $'a\\nb.h5'")
    add(g, ["folds", "miss\ning.h5"], "err", "a missing name with a newline: still one line")
    add(g, ["trace", "--gamma", "1", "--stretch-max", "0.02", "--max-steps", "5", "--out", "o\nut.h5", "--quiet"],
        "ok", "an output name with a newline")
    # input oddities
    g = "input:odd"
    add(g, ["folds", "fifo.h5"], "err", "a FIFO", setup=_fifo("fifo.h5"), setup_desc="mkfifo fifo.h5", timeout=30)
    add(g, ["folds", "/dev/zero"], "err", "a character device")
    add(g, ["folds", "/dev/stdin"], "err", "stdin (here /dev/null)")
    add(g, ["folds", "loop.h5"], "err", "a symlink loop", setup=_symlink("loop.h5", "loop.h5"),
        setup_desc="ln -s loop.h5 loop.h5")
    add(g, ["folds", "sparse.h5"], "err", "a 4 GB sparse file of zeros", setup=_sparse("sparse.h5", 4 << 30),
        setup_desc="truncate -s 4G sparse.h5")
    add(g, ["folds", "link.h5"], "ok", "a symlink to a valid file", files=("X.h5",), setup=_symlink("link.h5", "X.h5"),
        setup_desc="ln -s X.h5 link.h5")
    add(g, ["folds", "/proc/self/cwd/X.h5"], "ok", "an absolute /proc path", files=("X.h5",))
    add(g, ["folds", ""], "err", "an empty file name")
    add(g, ["folds", "-"], "err", "'-' (no stdin reading)")
    if is_root:
        add(g, ["folds", "X.h5"], "err", "unreadable (mode 000, root without CAP_DAC_OVERRIDE)", files=("X.h5",), user="nocap",
            setup=_chmod("X.h5", 0o000), setup_desc="chmod 000 X.h5; run without CAP_DAC_OVERRIDE (setpriv)")
        add(g, ["folds", "X.h5"], "ok", "read-only input (mode 444, root without CAP_DAC_OVERRIDE)", files=("X.h5",), user="nocap",
            setup=_chmod("X.h5", 0o444), setup_desc="chmod 444 X.h5; run without CAP_DAC_OVERRIDE (setpriv)")
        add(g, ["trace", "--start", "X.h5:3", "--max-steps", "3", "--out", "o.h5", "--quiet"], "ok",
            "restart from a read-only input (root without CAP_DAC_OVERRIDE)", files=("X.h5",), user="nocap",
            setup=_chmod("X.h5", 0o444), setup_desc="chmod 444 X.h5; run without CAP_DAC_OVERRIDE (setpriv)")
    return P


def heavy_probes() -> list[Probe]:
    """Valid-by-interface inputs that ask for a lot: they must end, and end cleanly."""
    P = [
        Probe("heavy", ["solve", "--gamma", "1", "--phi", "1", "--N", "100000"], "any",
              "--N at the top of its documented range 1..100000", heavy=True, timeout=120),
        Probe("heavy", ["solve", "--gamma", "1", "--phi", "1", "--N", "3000", "--k", "7"], "any",
              "a fine but accepted mesh", heavy=True, timeout=120),
        Probe("heavy", ["critical", "--gamma", "1", "--phi-max", "1e4"], "any", "critical twists up to 1e4 rad",
              heavy=True, timeout=120),
        Probe("heavy", ["solve", "--gamma", "1", "--phi", "4e4", "--load-step", "0.5"], "any",
              "1e5 natural load steps: the documented limit", heavy=True, timeout=120),
        Probe("heavy", ["trace", "--gamma", "1", "--N", "2000", "--max-steps", "3", "--out", "o.h5", "--quiet"],
              "any", "a large first mesh", heavy=True, timeout=120),
        Probe("heavy", ["trace", "--gamma", "1", "--uniform", "--N", "1", "--k", "1", "--max-steps", "20", "--out",
                        "o.h5", "--quiet"], "any", "the coarsest mesh", timeout=60),
        Probe("heavy", ["diagram", "--gamma", "0", "--phi-max", "1e308", "--max-steps", "5", "--out", "o.h5",
                        "--quiet"], "any", "a diagram to 1e308 rad", heavy=True, timeout=120),
    ]
    return P


def _interrupt_hook() -> str:
    sys.path.insert(0, os.path.join(REPO, "tests"))
    from sigint_hook import HOOK
    return HOOK


_CONSOLE_SCRIPT = "import re, sys\nfrom rodcont._entry import main\nif __name__ == '__main__':\n    sys.exit(main())\n"


def _interrupt_at(entry: str, at: str) -> str:
    """API-probe code: rodcont started through ``entry``, sent SIGINT by a sitecustomize import hook as the import
    of module ``at`` begins; it must end with exit 130 and at most one line, no traceback."""
    cmd = {"console script": "[sys.executable, os.path.join(d, 'rodcont')]",
           "cli.py": f"[sys.executable, {os.path.join(REPO, 'cli.py')!r}]",
           "python -m rodcont": "[sys.executable, '-m', 'rodcont']"}[entry]
    return (f"import os, shutil, subprocess, sys, tempfile\nd = tempfile.mkdtemp()\n"
            f"open(os.path.join(d, 'sitecustomize.py'), 'w').write({_interrupt_hook()!r})\n"
            f"open(os.path.join(d, 'rodcont'), 'w').write({_CONSOLE_SCRIPT!r})\n"
            f"env = dict(os.environ, RODCONT_SIGINT_AT={at!r}, "
            f"PYTHONPATH=os.pathsep.join([d, {os.path.join(REPO, 'src')!r}]))\n"
            f"r = subprocess.run({cmd} + ['trace', '--gamma', '1', '--N', '60', '--uniform', '--max-error', '1', "
            f"'--out', os.path.join(d, 'o.h5'), '--quiet'], env=env, capture_output=True, text=True, timeout=100)\n"
            f"shutil.rmtree(d)\n"
            f"assert r.returncode == 130 and 'Traceback' not in r.stderr and len(r.stderr.strip().splitlines()) <= 1, "
            f"(r.returncode, r.stderr)")


def signal_probes() -> list[Probe]:
    long_trace = ["trace", "--gamma", "1", "--N", "60", "--uniform", "--max-error", "1", "--out", "o.h5", "--quiet"]
    early = [Probe("signal:startup", long_trace, "sig", f"{sig.name} {t:g} s after exec (during interpreter start "
                   "and imports; timing-dependent): no traceback", signal_after=(sig, t), partial_ok=("o.h5",), timeout=60)
             # Not probed: the first ~30 ms, while the interpreter itself starts, before the first line of
             # rodcont runs (a Python traceback there is the interpreter's, out of rodcont's reach).
             for sig, t in [(signal.SIGINT, 0.04), (signal.SIGINT, 0.09), (signal.SIGTERM, 0.05), (signal.SIGTERM, 0.1)]]
    event = [Probe("signal:startup-event", ["python", "-c", _interrupt_at(entry, at)], "ok",
                   f"SIGINT as the import of {at} begins ({entry}; an event, not a moment): exit 130, one line",
                   python=_interrupt_at(entry, at), timeout=120)
             for entry in ("console script", "cli.py", "python -m rodcont")
             for at in ("rodcont._entry", "numpy", "rodcont.cli.app", "rodcont.drivers.trace")]
    return early + event + [
        Probe("signal", long_trace, "sig", "SIGTERM after 2.5 s: exit 143, the file holds every point",
              signal_after=(signal.SIGTERM, 2.5), partial_ok=("o.h5",), timeout=60),
        Probe("signal", long_trace, "sig", "SIGINT (to the group, as Ctrl-C) after 2.5 s: exit 130",
              signal_after=(signal.SIGINT, 2.5), partial_ok=("o.h5",), timeout=60),
        Probe("signal", long_trace, "sig", "SIGTERM during start-up (0.05 s)", signal_after=(signal.SIGTERM, 0.05),
              partial_ok=("o.h5",), timeout=60),
        Probe("signal", long_trace, "sig", "SIGINT during start-up (0.3 s)", signal_after=(signal.SIGINT, 0.3),
              partial_ok=("o.h5",), timeout=60),
        Probe("signal", ["fold-curve", "F.h5:0", "--range", "0", "50", "--out", "o.h5", "--quiet"], "sig",
              "SIGTERM during a fold curve", files=("F.h5",), signal_after=(signal.SIGTERM, 2.0),
              partial_ok=("o.h5",), timeout=60),
        Probe("signal", ["diagram", "--gamma", "1", "--phi-max", "30", "--N", "40", "--out", "o.h5", "--quiet"], "sig",
              "SIGTERM during a diagram", signal_after=(signal.SIGTERM, 3.0), partial_ok=("o.h5",), timeout=60),
        Probe("signal", ["sweep", "--gamma", "0", "1", "--N", "60", "--uniform", "--max-error", "1", "--jobs", "2",
                         "--out", "od", "--quiet"], "sig", "SIGTERM during a sweep",
              signal_after=(signal.SIGTERM, 3.0), partial_ok=("od", "od/gamma_0.h5", "od/gamma_1.h5"), timeout=90),
    ]


# --------------------------------------------------------------------------
# Issue 22, items 9-14: inputs never outputs, outputs atomic and kept, bounded inputs, unverified files,
# restarts with their options, --resume of traces and diagrams
# --------------------------------------------------------------------------
PIPE_ROD = ["--T", "1e5", "--L", "973.077121578337", "--EI", "1.25e6", "--GJ", "9.6e5", "--EA", "7.15e8", "--w", "235"]
SAFETY_FILES = ("well.csv", "pipe.toml", "problem.toml", "W.h5")
_INTERRUPTED = """
import sys, rodcont
out, at, kind = sys.argv[1], int(sys.argv[2]), sys.argv[3]
n = [0]
def stop(pt):
    n[0] += 1
    if n[0] == at:
        raise KeyboardInterrupt
try:
    if kind == "diagram":
        rodcont.diagram(1.0, phi_max=25, out=out, callback=stop)
    else:
        rodcont.trace(1.0, ds_max=0.05, ds=0.05, phi_max=20, out=out, callback=stop)
except KeyboardInterrupt:
    pass
"""


def build_safety_fixtures(fixdir: str, env: dict) -> None:
    """A survey, a conduit file naming it, a config file, a trace in the well (W), a trace stopped by its validity
    guard (V), one with its own steps and bound (S), a conduit trace with its bound (P), interrupted traces (I, and
    a long one, L) and an interrupted diagram (DI), a header-less file whose fold table was deleted (XF)."""
    shutil.copy(os.path.join(REPO, "examples", "well_build_and_hold.csv"), os.path.join(fixdir, "well.csv"))
    with open(os.path.join(fixdir, "pipe.toml"), "w") as fh:
        fh.write('[conduit]\nreference = "well:well.csv"\nclearance = 0.05\neps = 1e-5\n')
    with open(os.path.join(fixdir, "problem.toml"), "w") as fh:
        fh.write("[trace]\nmax_steps = 2\n")
    conduit = os.path.join(REPO, "examples", "conduit_straight.toml")
    steps = [
        (["trace", *PIPE_ROD, "--reference", "well:well.csv", "--max-steps", "2", "--out", "W.h5", "--quiet"], "W.h5"),
        (["trace", "--gamma", "1", "--out", "V.h5", "--quiet"], "V.h5"),
        (["trace", "--gamma", "1", "--ds-max", "0.05", "--phi-max", "8", "--out", "S.h5", "--quiet"], "S.h5"),
        (["trace", "--gamma", "1", "--conduit", conduit, "--phi-max", "3", "--out", "P.h5", "--quiet"], "P.h5"),
    ]
    for args, out in steps:
        r = run_cli(args, fixdir, env)
        if r.returncode != 0 or not os.path.exists(os.path.join(fixdir, out)):
            sys.exit(f"fuzz_cli: cannot build the fixture {out}: {_shell(args)} -> {r.returncode}\n{r.stderr}")
    for out, at, kind in (("I.h5", 60, "trace"), ("L.h5", 40, "trace"), ("DI.h5", 80, "diagram")):
        r = subprocess.run([sys.executable, "-c", _INTERRUPTED, out, str(at), kind], cwd=fixdir, env=env,
                           capture_output=True, text=True, timeout=600)
        if r.returncode != 0 or not os.path.exists(os.path.join(fixdir, out)):
            sys.exit(f"fuzz_cli: cannot build the interrupted fixture {out}: {r.stderr}")
    import h5py
    d = bytearray(open(os.path.join(fixdir, "F.h5"), "rb").read())
    d[0] ^= 0xFF
    with open(os.path.join(fixdir, "XF.h5"), "wb") as fh:
        fh.write(d)
    with h5py.File(os.path.join(fixdir, "XF.h5"), "r+") as f:
        del f["folds"]


def _series(name):
    """An export series already in the probe directory (built by rodcont itself)."""
    def f(d):
        r = subprocess.run([sys.executable, CLI, "export", "X.h5", "--all", "-o", name], cwd=d,
                           capture_output=True, text=True, timeout=120, env=dict(os.environ, MPLBACKEND="Agg"))
        if r.returncode != 0:
            raise OSError(f"cannot build the series: {r.stderr}")
    return f


def safety_probes() -> list[Probe]:
    P = []
    # -- outputs onto inputs, through any name, --overwrite or not (the snapshot proves the input unchanged)
    aliases = [("same name", lambda n: n, None, ""), ("./ and //", lambda n: ".//" + n, None, ""),
               ("symlink", lambda n: "alias-" + n, lambda n: _symlink("alias-" + n, n), "ln -s {n} alias-{n}"),
               ("hard link", lambda n: "hard-" + n, lambda n: _hardlink("hard-" + n, n), "ln {n} hard-{n}")]
    writers = {
        "survey of --reference": (lambda o: ["trace", *PIPE_ROD, "--reference", "well:well.csv", "--out", o,
                                             "--overwrite", "--quiet"], "well.csv"),
        "survey of --conduit": (lambda o: ["trace", *PIPE_ROD, "--conduit", "pipe.toml", "--out", o, "--overwrite",
                                           "--quiet"], "well.csv"),
        "the --config file": (lambda o: ["trace", "--gamma", "1", "--config", "problem.toml", "--out", o,
                                         "--overwrite", "--quiet"], "problem.toml"),
        "conduit file of a trace": (lambda o: ["trace", *PIPE_ROD, "--conduit", "pipe.toml", "--out", o,
                                               "--overwrite", "--quiet"], "pipe.toml"),
        "survey of a restart's file": (lambda o: ["trace", "--start", "W.h5:-1", "--out", o, "--overwrite",
                                                  "--quiet"], "well.csv"),
        "the restart's file": (lambda o: ["trace", "--start", "W.h5:-1", "--out", o, "--overwrite", "--quiet"],
                               "W.h5"),
        "survey read by export": (lambda o: ["export", "W.h5", "--point", "0", "--format", "csv", "-o", o,
                                             "--overwrite"], "well.csv"),
        "the fold curve's file": (lambda o: ["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--out", o,
                                             "--overwrite", "--quiet"], "F.h5"),
    }
    for what, (make, target) in writers.items():
        for alias, name, setup, desc in aliases:
            out = name(target)
            kw = {}
            if setup is not None:
                kw = dict(setup=setup(target), setup_desc=desc.format(n=target))
            P.append(Probe("safety:input-as-output", make(out), "err",
                           f"--out onto {what} ({target}) by {alias}: refused, the input untouched",
                           files=SAFETY_FILES + ("F.h5",), **kw))
    for img, args in (("plot", ["plot", "W.h5"]), ("shape", ["shape", "W.h5"])):  # a survey named like an image
        P.append(Probe("safety:input-as-output", args + ["-o", "survey.png", "--overwrite"], "err",
                       f"{img} -o onto the survey its file reads (a symlink named .png)", files=SAFETY_FILES,
                       setup=_symlink("survey.png", "well.csv"), setup_desc="ln -s well.csv survey.png"))
    P.append(Probe("safety:input-as-output", ["animate", "W.h5", "-o", "survey.gif", "--overwrite"], "err",
                   "animate -o onto the survey its file reads", files=SAFETY_FILES,
                   setup=_symlink("survey.gif", "well.csv"), setup_desc="ln -s well.csv survey.gif"))
    # -- devices, FIFOs, huge and odd files as inputs: refused unread (a hang is a failure)
    odd = [("/dev/zero", None, "/dev/zero"), ("a FIFO", _fifo("fifo"), "fifo"),
           ("a 4 GB sparse file", _sparse("huge", 4 << 30), "huge"), ("a directory", _mkdir("adir"), "adir"),
           ("/dev/null", None, "/dev/null")]
    for desc, setup, path in odd:
        for how in (["--reference", f"well:{path}"], ["--conduit", path], ["--config", path]):
            for cmd in (["solve", "--gamma", "1", "--phi", "1"], ["trace", "--gamma", "1", "--out", "o.h5", "--quiet"]):
                P.append(Probe("safety:odd-input", cmd + how, "err", f"{how[0]} {desc}: refused before reading",
                               setup=setup, setup_desc=desc, timeout=60))
    # -- outputs kept unless --overwrite, replaced whole (a full disk leaves the old one)
    kept = [(["plot", "X.h5", "-o", "pic.png"], "pic.png"), (["shape", "X.h5", "-o", "pic.png"], "pic.png"),
            (["export", "X.h5", "--point", "0", "-o", "notes.csv"], "notes.csv"),
            (["export", "X.h5", "--all", "-o", "notes.npz"], "notes.npz"),
            (["animate", "X.h5", "--max-frames", "3", "-o", "old.gif"], "old.gif")]
    for args, name in kept:
        setup = None if name == "pic.png" else _touch(name, b"my notes\n")
        files = ("X.h5", "pic.png") if name == "pic.png" else ("X.h5",)
        P.append(Probe("safety:output-kept", args, "err", f"{args[0]} onto an existing {name} without --overwrite",
                       files=files, setup=setup, setup_desc=f"an existing {name}"))
        P.append(Probe("safety:output-kept", args + ["--overwrite"], "ok", f"{args[0]} --overwrite replaces {name}",
                       files=files, setup=setup, setup_desc=f"an existing {name}", changes_ok=(name,)))
        P.append(Probe("safety:full-disk", args + ["--overwrite"], "env",
                       f"{args[0]} --overwrite on a full disk (ulimit -f): the old {name} stays whole",
                       files=files, setup=setup, setup_desc=f"an existing {name}", fsize=8192))
    P.append(Probe("safety:output-kept", ["export", "X.h5", "--all", "-o", "s.pvd"], "err",
                   "a series onto an existing one without --overwrite", files=("X.h5",), setup=_series("s.pvd"),
                   setup_desc="rodcont export X.h5 --all -o s.pvd"))
    P.append(Probe("safety:full-disk", ["export", "X.h5", "--all", "-o", "s.pvd", "--overwrite", "--samples", "2000"],
                   "env", "a series replaced on a full disk: every old file whole", files=("X.h5",),
                   setup=_series("s.pvd"), setup_desc="rodcont export X.h5 --all -o s.pvd", fsize=200_000))
    P.append(Probe("safety:output-kept", ["export", "X.h5", "--all", "-o", "s.pvd", "--overwrite"], "ok",
                   "a series replaced with --overwrite", files=("X.h5",), setup=_series("s.pvd"),
                   setup_desc="rodcont export X.h5 --all -o s.pvd", changes_ok=("s.pvd",) + tuple(
                       f"s_vtp/s_{i:06d}.vtp" for i in range(200))))
    # -- files without their checksum: read, said so on success; an error stays one line
    for args, exp, say in ((["folds", "XF.h5"], "ok", "unverified"), (["folds", "XN.h5"], "ok", "unverified"),
                           (["plot", "XN.h5", "-o", "p.png"], "ok", "unverified"),
                           (["export", "XN.h5", "--point", "0", "-o", "e.csv"], "ok", "unverified"),
                           (["trace", "--start", "XN.h5:999", "--out", "o.h5"], "err", ""),
                           (["trace", "--start", "XN.h5:1", "--max-steps", "2", "--out", "o.h5", "--quiet"], "ok",
                            "unverified")):
        P.append(Probe("safety:unverified", args, exp, "a header-less branch file: read, unverified, and said so",
                       files=("XF.h5", "XN.h5"), must_say=say))
    # -- restarts carry the file's options; the last point restarts back along the branch
    restarts = [
        (["trace", "--start", "S.h5:20", "--out", "o.h5", "--quiet"], "ok", "p_max = 8 reached",
         "the file's --phi-max 8, not the default 40"),
        (["trace", "--start", "S.h5:20", "--phi-max", "9", "--out", "o.h5", "--quiet"], "ok", "p_max = 9 reached",
         "a bound given overrides the file's"),
        (["trace", "--start", "S.h5:-1", "--out", "o.h5", "--quiet"], "any", "p_max = 8 reached",
         "the last point, on the file's bound, upwards: stops there at once, or is refused (rounding decides "
         "which side of the bound it converges to), with the file's bound"),
        (["trace", "--start", "P.h5:2", "--out", "o.h5", "--quiet"], "ok", "p_max = 3 reached",
         "a conduit restart keeps its --phi-max 3"),
        (["trace", "--start", "V.h5:-1", "--direction", "down", "--out", "o.h5", "--quiet"], "ok", "p_min = -1",
         "the last point of a branch its guard stopped, back along it"),
        (["trace", "--start", "V.h5:-1", "--out", "o.h5", "--quiet"], "err", "--direction down",
         "the last point on its guard, on past it: refused"),
        (["trace", "--start", "S.h5:20", "--gamma", "2", "--out", "o.h5", "--quiet"], "err", "--param gamma",
         "another rod: refused by the library's checks"),
    ]
    for args, exp, say, why in restarts:
        P.append(Probe("safety:restart", args, exp, why, files=("S.h5", "P.h5", "V.h5"), must_say=say, timeout=120))
    # -- --resume of a trace, into its own file
    resumes = [
        (["trace", "--resume", "I.h5", "--quiet"], "ok", "stop reason  validity guard", ("I.h5",),
         "an interrupted trace goes on in its file"),
        (["trace", "--resume", "I.h5", "--out", "o.h5"], "err", "in place", (), "--resume with another --out"),
        (["trace", "--resume", "I.h5", "--gamma", "2"], "err", "differs", (), "--resume with another rod"),
        (["trace", "--resume", "I.h5", "--start", "X.h5:1"], "err", "drop --start", (), "--resume with --start"),
        (["trace", "--resume", "I.h5", "--direction", "down"], "err", "--direction", (), "--resume backwards"),
        (["trace", "--resume", "X.h5"], "err", "--extend", (), "a finished branch"),
        (["trace", "--resume", "X.h5", "--extend", "--stretch-max", "0.15", "--quiet"], "ok", "stretch_max = 0.15",
         ("X.h5",), "--extend past its end"),
        (["trace", "--resume", "D.h5"], "err", "diagram --resume", (), "a diagram file"),
        (["trace", "--resume", "C.h5"], "err", "cannot be resumed", (), "a fold-curve file"),
        (["trace", "--resume", "missing.h5"], "err", "no such file", (), "no file"),
        (["trace", "--resume", "text.txt"], "err", "", (), "not a branch file"),
        (["trace", "--resume", "XN.h5"], "err", "", (), "a header-less, finished branch"),
    ]
    for args, exp, say, changes, why in resumes:
        P.append(Probe("safety:resume", args, exp, why, files=("I.h5", "X.h5", "D.h5", "C.h5", "XN.h5", "text.txt"),
                       must_say=say, changes_ok=changes, timeout=120))
    P.append(Probe("signal", ["trace", "--resume", "L.h5", "--quiet"], "sig",
                   "SIGTERM 1.5 s into a resumed trace: the file keeps its points", files=("L.h5",),
                   signal_after=(signal.SIGTERM, 1.5), partial_ok=("L.h5",), changes_ok=("L.h5",), timeout=120))
    # -- interrupted diagrams: marked, and finished by --resume
    dres = [
        (["folds", "DI.h5"], "ok", "INTERRUPTED", (), "an interrupted diagram says so"),
        (["diagram", "--resume", "DI.h5", "--quiet"], "ok", "branches", ("DI.h5",), "--resume finishes it"),
        (["diagram", "--resume", "DI.h5", "--ds-max", "0.1"], "err", "differs", (), "--resume with other options"),
        (["diagram", "--resume", "DI.h5", "--out", "o.h5"], "err", "in place", (), "--resume with another --out"),
        (["diagram", "--resume", "D.h5"], "err", "complete diagram", (), "a complete diagram"),
        (["diagram", "--resume", "X.h5"], "err", "not a diagram", (), "a trace file"),
    ]
    for args, exp, say, changes, why in dres:
        P.append(Probe("safety:diagram-resume", args, exp, why, files=("DI.h5", "D.h5", "X.h5"), must_say=say,
                       changes_ok=changes, timeout=300))
    P.append(Probe("signal", ["diagram", "--resume", "DI.h5", "--quiet"], "sig",
                   "SIGTERM 4 s into a resumed diagram: the file holds its complete branches", files=("DI.h5",),
                   signal_after=(signal.SIGTERM, 4.0), partial_ok=("DI.h5",), changes_ok=("DI.h5",), timeout=120))
    return P


# --------------------------------------------------------------------------
# Issue 22, items 1-8 and 15-19: right values in any units, at default settings, in conduits; the API's edges;
# honest lines, warnings, names and columns. A probe here checks the answer too (check: values, files).
# --------------------------------------------------------------------------
LAGRANGE = {"F1": 13.099993823462134, "T1": 8.313547463421958,      # Gamma = 1, primary fold (tests/data)
            "F2": 21.022797120653017, "T2": 14.959167916299174,     # Gamma = 1, the 1 -> 2 fold
            "S": 29.24198617625434, "TS": 21.56391782887474,        # Gamma = 1, the 2 -> 3 fold (seed 25.778)
            "G5": 39.754157511598976}                                # Gamma = 5, the 3 -> 4 fold (below 40)
# (name, --T --w --EI --GJ --EA --L, length unit, force unit): the canonical rod (T 10, w 10, EI 1, GJ 0.75,
# EA 255, L 1) in other units; every dimensionless group the same, Phi the same, torques times F L
UNITS = [("length x10", 10.0, 1.0), ("force x1e6", 1.0, 1e6), ("length x1e-3, force x1e3", 1e-3, 1e3),
         ("length x1e3", 1e3, 1.0)]
WELL = ["--T", "1e5", "--phi", "0", "--L", "973.077121578337", "--EI", "1.25e6", "--GJ", "9.6e5", "--EA", "7.15e8",
        "--w", "235"]
WELL_SIDE_FORCE = 136440.6     # the README's drill pipe in conduit_well.toml at N = 2000 (issue 22 item 3)
GUIDEWIRE = ["--T", "0.01", "--w", "6e-6", "--EI", "1e-5", "--GJ", "7.7e-6", "--EA", "5800", "--L", "0.3"]


def _rod(lu: float, fu: float) -> list:
    return ["--T", f"{10 * fu:.17g}", "--w", f"{10 * fu / lu:.17g}", "--EI", f"{fu * lu * lu:.17g}",
            "--GJ", f"{0.75 * fu * lu * lu:.17g}", "--EA", f"{255 * fu:.17g}", "--L", f"{lu:.17g}"]


def _values(text: str) -> dict:
    """The ``name value`` lines of a summary (solve's), as floats where they read as one."""
    out = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 2 and not line.startswith("#"):
            try:
                out[parts[0]] = float(parts[1])
            except ValueError:
                pass
    return out


def _folds(res, name="o.h5") -> list:
    """The folds of a branch or diagram file the probe wrote (rodcont's own reader)."""
    sys.path.insert(0, os.path.join(REPO, "src"))
    import rodcont
    return list(rodcont.load_diagram(os.path.join(res.cwd, name)).folds)


def _fold_check(phi: float, torque: float | None, scale: float, counts: tuple | None, waves: tuple | None,
                tol: float = 1e-8, name: str = "o.h5"):
    """One fold near ``phi`` (within 0.05): its Phi within ``tol``, torque / scale within 1e-8 relative,
    the unstable counts before | after and the waves before -> after as given."""
    def check(res):
        near = [f for f in _folds(res, name) if abs(f["phi_L"] - phi) < 0.05]
        if len(near) != 1:
            return f"{len(near)} folds near Phi = {phi} (expected 1)"
        f = near[0]
        if abs(f["phi_L"] - phi) > tol:
            return f"fold at Phi = {f['phi_L']!r}, {abs(f['phi_L'] - phi):.2g} from {phi!r} (> {tol:g})"
        if torque is not None and abs(f["torque"] / scale / torque - 1) > 1e-8:
            return f"fold torque {f['torque']!r}, not {torque * scale!r} (torque x F L = {scale:g})"
        if counts is not None and (int(f["unstable_before"]), int(f["unstable_after"])) != counts:
            return f"stable counts {f['unstable_before']} | {f['unstable_after']}, not {counts[0]} | {counts[1]}"
        if waves is not None and (int(f["waves_before"]), int(f["waves_after"])) != waves:
            return f"waves {f['waves_before']} -> {f['waves_after']}, not {waves[0]} -> {waves[1]}"
        return None
    return check


def _both(*checks):
    def check(res):
        return next((w for w in (c(res) for c in checks) if w), None)
    return check


def _conduit_file(name: str, clearance: float):
    def f(d):
        with open(os.path.join(d, name), "w") as fh:
            fh.write(f'[conduit]\nclearance = {clearance!r}\neps = 1e-5\n')
    return f


def _last_point_like(ref: str, lu: float, fu: float):
    """The last point of the trace (o.h5) is the reference file's in other units: torque x F L, side force x F,
    gap x L (to 1e-6 of the clearance), the same stretch, waves, unstable modes and contact zones."""
    def check(res):
        import h5py
        with h5py.File(os.path.join(res.cwd, ref), "r") as f0, h5py.File(os.path.join(res.cwd, "o.h5"), "r") as f1:
            a, b = ({k: g["branch"][k][-1] for k in ("phi_L", "torque", "side_force", "min_gap", "stretch",
                                                      "helical_waves", "unstable_modes", "contact_zones")}
                    for g in (f0, f1))
        for k, scale in (("phi_L", 1.0), ("torque", fu * lu), ("side_force", fu), ("stretch", 1.0)):
            if abs(b[k] / scale - a[k]) > 1e-6 * max(abs(a[k]), 1e-12):
                return f"{k} {b[k]!r} at the end, not {a[k] * scale!r} ({ref}'s x {scale:g})"
        if abs(b["min_gap"] / lu - a["min_gap"]) > 1e-6 * 0.01:
            return f"min_gap {b['min_gap']!r}, not {a['min_gap'] * lu!r}"
        for k in ("helical_waves", "unstable_modes", "contact_zones"):
            if int(b[k]) != int(a[k]):
                return f"{k} {int(b[k])} at the end, not {int(a[k])} as in {ref}"
        return None
    return check


def _counts_follow_greenhill(res):
    """The weightless straight rod under T = 10 (EI 1, GJ 0.75, EA 255): unstable_modes 0 below the first
    critical torque (tests/closed_forms.py), 2 above it, at every stored point (2 % away from it)."""
    import h5py
    sys.path.insert(0, os.path.join(REPO, "tests"))
    from closed_forms import critical_twists as closed_form
    phi_c = closed_form(10.0, phi_max=20.0)[0]
    with h5py.File(os.path.join(res.cwd, "o.h5"), "r") as f:
        phi, n = f["branch/phi_L"][()], f["branch/unstable_modes"][()]
    below, above = n[phi < 0.98 * phi_c], n[phi > 1.02 * phi_c]
    if below.size and below.max() != 0:
        return f"unstable_modes {int(below.max())} stored below the critical twist {phi_c:.6f}"
    if above.size and not (above == 2).all():
        return f"unstable_modes {sorted(set(above.tolist()))} stored above the critical twist {phi_c:.6f} (2)"
    return None if above.size else "the trace did not pass the critical twist"


def _solve_accurate(side_force: float | None = None, rel: float = 1e-3, min_gap: float | None = None):
    """A solve's summary: error and side_force_error below their guards (1e-6, 1e-3), the side force within
    ``rel`` of ``side_force``, the gap above ``min_gap`` (a penetration guard)."""
    def check(res):
        if res.rc != 0:
            return None
        v = _values(res.stdout)
        if v.get("error", 1.0) > 1e-6 or v.get("side_force_error", 0.0) > 1e-3:
            return f"error {v.get('error')} / side_force_error {v.get('side_force_error')} above the guards"
        if side_force is not None and abs(v["side_force"] / side_force - 1) > rel:
            return f"side_force {v['side_force']!r}, not within {rel:g} of {side_force!r}"
        if min_gap is not None and v["min_gap"] < min_gap:
            return f"min_gap {v['min_gap']!r}: deeper in the wall than {min_gap:g} (1e-3 of the clearance)"
        return None
    return check


def _no_defect_line(res):
    return "prints a 'defect' line beside 'error'" if re.search(r"^defect\b", res.stdout, re.M) else None


def _csv_columns(*names):
    def check(res):
        with open(os.path.join(res.cwd, "e.csv")) as fh:
            head = next(ln for ln in fh if not ln.startswith("#"))
        cols = re.split(r"[,\s]+", head.strip())
        missing = [c for c in names if c not in cols]
        return f"export has no column(s) {', '.join(missing)} (has {', '.join(cols)})" if missing else None
    return check


def _warning_with_cause(cause: str):
    def check(res):
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("rodcont: warning:")]
        return None if any(cause in ln for ln in lines) else f"no 'rodcont: warning:' line saying {cause!r}"
    return check


def _progress_names(param: str):
    def check(res):
        text = res.stdout + res.stderr
        if re.search(r"\bp_(max|min)\b|\bp = ", text):
            return "stop message says p (the engine's name), not " + param
        if re.search(r"^point\s+\d+\s+Phi\b", text, re.M):
            return f"progress prints Phi for a trace in {param}"
        return None
    return check


_API_CODE = """import sys, warnings
sys.path.insert(0, {src!r})
warnings.simplefilter("ignore")
import rodcont
try:
{body}
except (TypeError, ValueError, rodcont.BranchFileError) as exc:
    sys.stderr.write(f"rodcont: error: {{type(exc).__name__}}: {{exc}}\\n")
    sys.exit(2)
"""


def _api_code(call: str) -> str:
    """A Python API call as a probe: a TypeError/ValueError (a BranchFileError for a file) is the clean error
    (one line, exit 2, as the CLI's); anything else raised is a traceback (a failure); a return is exit 0."""
    return _API_CODE.format(src=os.path.join(REPO, "src"), body="\n".join("    " + ln for ln in call.splitlines()))


# (call, expectation, a phrase the message must hold, why)
API_EDGES = [
    ('rodcont.sweep("1", out_dir="s")', "err", "gammas", "a string for the Gamma values"),
    ('rodcont.sweep(1.0, out_dir="s")', "err", "gammas", "one number for the Gamma values"),
    ('rodcont.sweep([1.0], out_dir=3)', "err", "out_dir", "a number for the directory"),
    ('rodcont.sweep([1.0], out_dir="s", N="abc")', "err", "N must be", "a string mesh, before any job"),
    ('rodcont.sweep([1.0], out_dir="s", executor="abc")', "err", "executor", "not an executor"),
    ('rodcont.sweep([1.0], out_dir="F.h5")', "err", "not a directory", "a file as out_dir"),
    ('rodcont.RodParameters(weight_direction="x")', "err", "weight_direction", "a letter for the direction"),
    ('rodcont.RodParameters(weight_direction=(0, 1))', "err", "weight_direction", "a 2-vector"),
    ('rodcont.trace(1.0, breakpoints="abc")', "err", "breakpoints", "a string mesh"),
    ('rodcont.trace(1.0, breakpoints=[0, 0.3, 0.6, 0.9])', "err", "span", "a mesh short of the span (item 5)"),
    ('rodcont.solve(gamma=1.0, phi=5.0)', "err", "phi_L", "phi for phi_L: named, no internal function (16)"),
    ('rodcont.solve(gamma=1.0, phi_L=1.0, T=10.0)', "err", "gamma", "gamma and T both (item 5)"),
    ('assert rodcont.critical_twists(T=1e20) == []', "ok", "", "no critical twist under a huge tension (5)"),
    ('rodcont.critical_twists(N_fine=0)', "err", "N_fine", "an empty refining mesh (item 11)"),
    ('rodcont.critical_twists(N_fine=10**7)', "err", "GiB", "a mesh the machine cannot hold (11)"),
    ('rodcont.solve(gamma=1.0, phi_L=1.0, N=10**9)', "err", "N", "a mesh the machine cannot hold (11)"),
    ('rodcont.fold_curve(rodcont.load_branch("F.h5"), 0, "gamma", 0.9, 1.1, N_max=0)', "err", "N_max", "(11)"),
    ('rodcont.fold_curve("F.h5", 0, "gamma", 0.9, 1.1)', "err", "load_branch", "a path for the branch"),
    ('rodcont.fold_curve(rodcont.load_branch("F.h5"), 0, "gamma", 0.9, 1.1, forced=1.0)', "err", "forced",
     "one number for the forced values"),
    ('d = rodcont.load_diagram("F.h5")\nassert len(d.branches) == 1 and len(d.folds) == 1', "ok", "",
     "a branch file read as a diagram: its one branch and its fold (16)"),
    ('rodcont.load_branch(None)', "err", "path", "no file name"),
    ('rodcont.trace(1.0, out=3)', "err", "out", "a number for the output"),
    ('rodcont.trace(1.0, resume="X.h5")', "err", "resume", "a path for the branch to resume"),
    ('rodcont.trace(1.0, meta=3)', "err", "meta", "a number for the metadata"),
    ('rodcont.diagram(1.0, deflate_at=12.0)', "err", "deflate_at", "one number for the deflation twists"),
    ('rodcont.diagram(1.0, callback=3)', "err", "callback", "a number for the callback"),
    ('rodcont.RodSystem("rod", gamma=1.0)', "err", "rod", "a string for the rod"),
    ('rodcont.StraightReference(K1=(1,))', "err", "K1", "a 1-vector frame (one line, not numpy's two)"),
    ('rodcont.solve(gamma=1.0, phi_L=1.0, curve="helix:1e300,1")', "err", "too large", "a helix beyond floats"),
    ('import types, rodcont.continuation as m\nassert m is rodcont.continuation and isinstance(m, types.ModuleType)'
     '\nassert m.Tracker is rodcont.Tracker and callable(rodcont.continuation)', "ok", "",
     "rodcont.continuation: the module, callable as the function"),
    ('b = rodcont.trace(1.0, k=2, stretch_max=0.2)\nf = b.folds[0]\n'
     f'assert abs(f["phi_L"] - {LAGRANGE["F1"]!r}) <= b.table["error"][f["index"]], f', "ok", "",
     "k = 2: the fold's stored estimate bounds its error (item 5)"),
]


def issue22_probes() -> list[Probe]:
    P = []
    # -- 1. units: folds, torques, waves and stability counts of a trace and a diagram, a conduit trace
    for name, lu, fu in UNITS:
        P.append(Probe("issue22:units", ["trace", *_rod(lu, fu), "--from-straight", "25.778", "--out", "o.h5",
                                         "--quiet"], "ok", f"the Gamma = 1 branch from 25.778 in {name}",
                       check=_fold_check(LAGRANGE["S"], LAGRANGE["TS"], fu * lu, (4, 5), (2, 3)),
                       must_not_say="warning", timeout=180))
    for name, lu, fu in UNITS[:2]:
        P.append(Probe("issue22:units", ["diagram", *_rod(lu, fu), "--phi-max", "25", "--out", "o.h5", "--quiet"],
                       "ok", f"the Gamma = 1 diagram to 25 in {name}", must_not_say="warning", timeout=300,
                       check=_both(_fold_check(LAGRANGE["F1"], LAGRANGE["T1"], fu * lu, (0, 1), (0, 1)),
                                   _fold_check(LAGRANGE["F2"], LAGRANGE["T2"], fu * lu, (2, 3), (1, 2)))))
        P.append(Probe("issue22:units", ["trace", *_rod(lu, fu), "--conduit", "c.toml", "--phi-max", "3", "--out",
                                         "o.h5", "--quiet"], "ok",
                       f"the straight conduit trace (P.h5) in {name}: the same point at Phi = 3", files=("P.h5",),
                       setup=_conduit_file("c.toml", 0.01 * lu), setup_desc=f"conduit_straight.toml, clearance "
                       f"{0.01 * lu:g}", check=_last_point_like("P.h5", lu, fu), timeout=180))
    # -- 2. the stored count at every point, not only where it was computed
    P.append(Probe("issue22:stored-counts", ["trace", "--T", "10", "--w", "0", "--phi-max", "20", "--out", "o.h5",
                                             "--quiet"], "ok", "the weightless rod past Greenhill's twist",
                   check=_counts_follow_greenhill, timeout=180))
    # -- 3. conduits at their default mesh: every shipped example as its file says, accurate and quiet
    ex = lambda n: os.path.join(REPO, "examples", n)  # noqa: E731
    for n in ("conduit_arc.toml", "conduit_bump.toml", "conduit_helix.toml", "conduit_taper.toml"):
        P.append(Probe("issue22:conduit-defaults", ["solve", "--gamma", "1", "--phi", "0", "--conduit", ex(n)], "ok",
                       f"{n}'s documented solve: within its guards, no warning", must_not_say="warning",
                       check=_solve_accurate(), timeout=180))
    P.append(Probe("issue22:conduit-defaults", ["solve", *WELL, "--conduit", ex("conduit_well.toml")], "ok",
                   "the README's drill pipe in conduit_well.toml at the default mesh", must_not_say="warning",
                   check=_solve_accurate(WELL_SIDE_FORCE), timeout=180))
    P.append(Probe("issue22:conduit-defaults", ["solve", *WELL, "--conduit", ex("conduit_well.toml"), "--uniform",
                                                "--N", "20"], "any",
                   "the well on a uniform mesh of 20 that cannot see its stations: refused, or right",
                   check=_solve_accurate(WELL_SIDE_FORCE), timeout=180))
    P.append(Probe("issue22:conduit-defaults", ["trace", "--gamma", "1", "--conduit", ex("conduit_taper.toml"),
                                                "--phi-max", "25", "--out", "o.h5", "--quiet"], "ok",
                   "conduit_taper.toml's documented trace", must_not_say="warning", timeout=400))
    # -- 4. penetration: the guidewire at the default force scale
    arc = lambda d: open(os.path.join(d, "g.toml"), "w").write(  # noqa: E731
        '[conduit]\nreference = "arc:0.6"\nclearance = 0.001\neps = 1e-5\n')
    for cmd in (["solve", "--phi", "0"], ["trace", "--phi-max", "2", "--out", "o.h5", "--quiet"]):
        P.append(Probe("issue22:penetration", cmd + GUIDEWIRE + ["--conduit", "g.toml"], "ok",
                       f"a guidewire in an arc of clearance 0.001 ({cmd[0]}): within 1e-3 of it of the wall",
                       setup=arc, setup_desc="g.toml: arc:0.6, clearance 0.001", must_not_say="warning",
                       check=_solve_accurate(min_gap=-1e-6) if cmd[0] == "solve" else None, timeout=180))
    # -- 5, 11, 16. the Python API's edges: a TypeError or ValueError in one line, or the right answer
    for call, exp, say, why in API_EDGES:
        P.append(Probe("issue22:api-edges", ["python", "-c", call], exp, why, python=call, must_say=say,
                       files=("F.h5", "X.h5"), must_not_say="solve_equilibrium", timeout=120))
    P.append(Probe("issue22:api-edges", ["critical", "--T", "1e20"], "ok", "no critical twist where the closed "
                   "form has none", must_say="none below"))
    # -- 6. solve prints what to trust
    P.append(Probe("issue22:defect-line", ["solve", "--gamma", "1", "--phi", "10"], "ok",
                   "no unexplained defect beside the error", check=_no_defect_line))
    # -- 7. the fold inside the window whose branch straddles --phi-max
    P.append(Probe("issue22:window-edge", ["diagram", "--gamma", "5", "--phi-max", "40", "--out", "o.h5", "--quiet"],
                   "ok", "Gamma = 5: the 3 -> 4 fold at 39.754 (the branch from the last interval)",
                   check=_fold_check(LAGRANGE["G5"], None, 1.0, None, (3, 4), tol=1e-6), timeout=400))
    # -- 8. a tighter guard: the fold still to --fold-error
    for guard in ("1e-8", "1e-6"):
        P.append(Probe("issue22:tight-guard", ["trace", "--gamma", "1", "--from-straight", "25.778", "--max-error",
                                               guard, "--stretch-max", "0.0863", "--out", "o.h5", "--quiet"], "ok",
                       f"the 2 -> 3 fold with --max-error {guard}: within --fold-error 1e-9 of the reference",
                       check=_fold_check(LAGRANGE["S"], LAGRANGE["TS"], 1.0, None, (2, 3), tol=1e-9), timeout=180))
    # -- 15. warnings: the library's cause, on the CLI's warning line
    P.append(Probe("issue22:warnings", ["trace", "--T", "10", "--w", "0", "--phi-max", "20", "--out", "o.h5",
                                        "--quiet"], "ok", "the axisymmetric rod: the library's cause, printed",
                   check=_warning_with_cause("cross in pairs"), timeout=180))
    # -- 16. names: F<j> for fold-curve, the parameter's name in a trace in T, one line for a huge helix
    P.append(Probe("issue22:names", ["fold-curve", "F.h5:F1", "--range", "0.9", "1.1", "--max-steps", "3", "--out",
                                     "o.h5", "--quiet"], "ok", "F1 as everywhere else", files=("F.h5",)))
    P.append(Probe("issue22:names", ["trace", "--start", "X.h5:3", "--param", "T", "--range", "5", "20",
                                     "--max-steps", "30", "--out", "o.h5"], "ok",
                   "a trace in T says T (progress and stop message), not Phi or p", files=("X.h5",),
                   check=_progress_names("T"), timeout=120))
    P.append(Probe("issue22:names", ["solve", "--gamma", "1", "--phi", "1", "--reference", "helix:1e300,1"], "err",
                   "a helix too large to represent: one line, no errno tuple", must_say="too large",
                   must_not_say="Errno"))
    # -- 17. plot and export: the contact columns the file holds
    for y in ("side_force", "min_gap"):
        P.append(Probe("issue22:columns", ["plot", "P.h5", "--y", y, "-o", "p.png"], "ok",
                       f"plot --y {y} of a conduit trace", files=("P.h5",)))
    P.append(Probe("issue22:columns", ["export", "P.h5", "--point", "-1", "-o", "e.csv"], "ok",
                   "export of a conduit point: its contact columns", files=("P.h5",),
                   check=_csv_columns("S", "axial_force", "torque", "pressure", "gap", "in_contact")))
    # -- 19. Dask: a scheduler that is not there is one line; diagrams in parallel
    P.append(Probe("issue22:dask", ["sweep", "--gamma", "1", "--stretch-max", "0.02", "--max-steps", "8",
                                    "--scheduler", "tcp://127.0.0.1:9", "--out", "sd", "--quiet"], "err",
                   "sweep --scheduler with no scheduler at the address", timeout=120))
    P.append(Probe("issue22:dask", ["diagram", "--gamma", "1", "--phi-max", "15", "--jobs", "2", "--out", "o.h5",
                                    "--quiet"], "ok", "diagram --jobs 2",
                   check=_fold_check(LAGRANGE["F1"], LAGRANGE["T1"], 1.0, (0, 1), (0, 1)), timeout=300))
    return P


# --------------------------------------------------------------------------
# Damaged, foreign and hand-edited files
# --------------------------------------------------------------------------
MAGIC_LEN = 20      # rodcont's header: a 20-byte magic string, version, length, checksum, in a 512-byte user block


def _readers(name: str, with_fold_curve: bool = False) -> list[tuple[list, str]]:
    """Commands that read ``name`` (and where they write)."""
    r = [(["folds", name], "folds"),
         (["plot", name, "-o", "p.png"], "plot"),
         (["shape", name, "--point", "-1", "-o", "s.png"], "shape"),
         (["trace", "--start", name + ":-1", "--max-steps", "3", "--out", "o.h5", "--quiet"], "trace")]
    if with_fold_curve:
        r.append((["fold-curve", name + ":0", "--range", "0.9", "1.1", "--max-steps", "3", "--out", "o.h5",
                   "--quiet"], "fold-curve"))
    return r


def make_damaged(fixdir: str, rng: random.Random, n_flips: int, n_flips_sum: int) -> list[Probe]:
    """Write damaged variants into ``fixdir`` and return the probes that read them."""
    P = []
    X = open(os.path.join(fixdir, "X.h5"), "rb").read()
    XN = open(os.path.join(fixdir, "XN.h5"), "rb").read()
    F = open(os.path.join(fixdir, "F.h5"), "rb").read()

    def put(name, data):
        with open(os.path.join(fixdir, name), "wb") as fh:
            fh.write(data)

    # 1. byte flips on the header-less copy: HDF5 and rodcont's checks see the damage (the interesting case)
    for i in range(n_flips):
        d = bytearray(XN)
        nflip = rng.choice([1, 1, 1, 2, 4, 16])
        for _ in range(nflip):
            if rng.random() < 0.6:
                pos = rng.randrange(512, min(len(d), 512 + 6144))     # HDF5 superblock and early metadata
            else:
                pos = rng.randrange(512, len(d))
            d[pos] ^= rng.randrange(1, 256)
        name = f"flipN{i:03d}.h5"
        put(name, bytes(d))
        args, cmd = _readers(name)[(0, 0, 1, 0, 2, 0, 3)[i % 7]]      # mostly folds (the cheapest reader)
        P.append(Probe("damaged:flip-hdf5", args, "any",
                       f"{nflip} random byte flip(s) in a header-less copy of X.h5 (HDF5 reads it directly); a flip "
                       "may land in unused bytes, so exit 0 is acceptable", files=(name,)))
    # 2. byte flips on the checksummed original (anywhere, header included)
    for i in range(n_flips_sum):
        d = bytearray(X)
        pos = rng.randrange(0, len(d)) if i % 3 else rng.randrange(0, 512)
        d[pos] ^= rng.randrange(1, 256)
        name = f"flipC{i:03d}.h5"
        put(name, bytes(d))
        args, cmd = _readers(name)[i % 4]
        # header: magic [0, 20), format version [20, 24), length [24, 32), BLAKE2 digest [32, 64), padding to 512
        if pos >= 512 or 24 <= pos < 64:
            exp = "err"   # the image or its length/digest no longer match
        else:
            exp = "any"   # magic spoiled (read as plain HDF5, intact), version or padding (not covered)
        P.append(Probe("damaged:flip-checksummed", args, exp, f"one byte flipped at offset {pos} of X.h5",
                       files=(name,)))
    # 3. truncations and appended garbage
    for src, data, tag in [("X", X, "checksummed"), ("XN", XN, "header-less")]:
        for n in [0, 1, 19, 100, 511, 512, 513, 1000, 2048, 4096, len(data) // 4, len(data) // 2, len(data) - 100,
                  len(data) - 1]:
            name = f"trunc{src}{n}.h5"
            put(name, data[:n])
            for args, cmd in _readers(name)[:2] if n in (len(data) - 1, len(data) // 2) else _readers(name)[:1]:
                P.append(Probe("damaged:truncated", args, "err", f"{tag} X.h5 truncated to {n} bytes", files=(name,)))
        name = f"append{src}.h5"
        put(name, data + b"garbage" * 100)
        P.append(Probe("damaged:truncated", ["folds", name], "err" if src == "X" else "any",
                       f"{tag} X.h5 with 700 bytes appended", files=(name,)))
    # 4. not HDF5 at all
    png = open(os.path.join(fixdir, "pic.png"), "rb").read()
    others = {"empty.h5": b"", "text.txt": b"phi_L stretch\n1 2\n", "pic.png": png,
              "zeros.h5": b"\0" * 4096, "magiconly.h5": X[:512], "hdf5sig.h5": b"\x89HDF\r\n\x1a\n" + b"\0" * 100,
              "utf16.h5": "ÿþ text".encode("utf-16"), "random.h5": bytes(rng.randrange(256) for _ in range(5000))}
    for name, data in others.items():
        if name != "pic.png":
            put(name, data)
        for args, cmd in [_readers(name)[0], _readers(name)[3 if len(name) % 2 else 2]]:
            P.append(Probe("damaged:not-hdf5", args, "err", f"{name}: not a branch file", files=(name,)))
    for args, cmd in _readers("adir"):
        P.append(Probe("damaged:not-hdf5", args, "err", "a directory as the input", setup=_mkdir("adir"),
                       setup_desc="mkdir adir"))
    return P


def make_foreign(fixdir: str, rng: random.Random, n_random: int) -> list[Probe]:
    """Foreign HDF5 files (h5py, random groups) and rodcont-lookalikes."""
    import h5py
    import numpy as np
    P = []
    dtypes = ["f8", "f4", "i8", "i1", "u2", "c16", "S5", "bool"]

    def rand_ds(g, name):
        kind = rng.choice(["num", "num", "str", "scalar", "empty", "2d", "vlen", "compound"])
        if kind == "num":
            g.create_dataset(name, data=np.asarray(np.random.default_rng(rng.randrange(1 << 30)).normal(
                size=rng.randrange(0, 40)) * 10, dtype=rng.choice(dtypes[:6])))
        elif kind == "str":
            g.create_dataset(name, data=np.array([b"regular", b"fold", b"\xff\xfe"] * rng.randrange(1, 5)))
        elif kind == "scalar":
            g.create_dataset(name, data=rng.random())
        elif kind == "empty":
            g.create_dataset(name, shape=(0,), dtype="f8")
        elif kind == "2d":
            g.create_dataset(name, data=np.ones((rng.randrange(1, 5), rng.randrange(1, 500))))
        elif kind == "vlen":
            g.create_dataset(name, data=["a", "bb"], dtype=h5py.string_dtype())
        else:
            g.create_dataset(name, data=np.zeros(3, dtype=[("a", "f8"), ("b", "i4")]))

    def rand_attrs(o):
        for j in range(rng.randrange(0, 4)):
            o.attrs[rng.choice(["gamma", "EI", "k", "x", "rodcont_version", "param", "kind"])] = rng.choice(
                [1.0, -1, "text", np.nan, [1, 2, 3], b"\xff", True, 0])

    names = ["branch", "branches", "folds", "mesh", "branch_points", "x", "phi_L", "coefficients", "0", "kind"]
    for i in range(n_random):
        name = f"foreign{i:02d}.h5"
        with h5py.File(os.path.join(fixdir, name), "w") as f:
            rand_attrs(f)
            if i % 2 == 0:   # rodcont's root attributes, copied: the structure is what is random
                with h5py.File(os.path.join(fixdir, "X.h5"), "r") as x:
                    for k, v in x.attrs.items():
                        f.attrs[k] = v
            for _ in range(rng.randrange(1, 6)):
                path = "/".join(rng.choice(names) for _ in range(rng.randrange(1, 4)))
                try:
                    if rng.random() < 0.5:
                        g = f.require_group(path)
                        rand_attrs(g)
                        for _ in range(rng.randrange(0, 5)):
                            try:
                                rand_ds(g, rng.choice(names + ["stretch", "torque", "l0", "breakpoints"]))
                            except (ValueError, TypeError):
                                pass
                    else:
                        rand_ds(f, path)
                except (ValueError, TypeError, KeyError):
                    pass
        args, cmd = _readers(name)[i % 4]
        P.append(Probe("foreign:random", args, "err", "an HDF5 file with random groups, datasets and attributes"
                       + (" (rodcont's root attributes copied)" if i % 2 == 0 else ""), files=(name,)))
    # hand-made lookalikes
    looks = {}
    looks["plainfile.h5"] = lambda f: f.create_dataset("data", data=np.arange(10))
    looks["versiononly.h5"] = lambda f: f.attrs.__setitem__("rodcont_version", "0.2.0")

    def attrs_only(f):
        with h5py.File(os.path.join(fixdir, "X.h5"), "r") as x:
            for k, v in x.attrs.items():
                f.attrs[k] = v
    looks["attrsonly.h5"] = attrs_only
    looks["branchdataset.h5"] = lambda f: (attrs_only(f), f.create_dataset("branch", data=np.zeros(3)))
    looks["branchempty.h5"] = lambda f: (attrs_only(f), f.create_group("branch"))
    looks["branchesempty.h5"] = lambda f: (attrs_only(f), f.create_group("branches"))
    looks["branchesdataset.h5"] = lambda f: (attrs_only(f), f.create_dataset("branches", data=np.zeros(3)))
    for name, fn in looks.items():
        with h5py.File(os.path.join(fixdir, name), "w") as f:
            fn(f)
        for args, cmd in _readers(name):
            P.append(Probe("foreign:lookalike", args, "err", f"{name}: an HDF5 file that is not a branch file",
                           files=(name,)))
    return P


def make_edits(fixdir: str, n: int) -> list[Probe]:
    """Hand-edited copies (h5py in place, as a user would): attributes, datasets, links."""
    import h5py
    import numpy as np
    P = []

    def A(key, value):
        def f(h):
            h.attrs[key] = value
        return f

    def D(key):
        def f(h):
            del h.attrs[key]
        return f

    def delete(path):
        def f(h):
            del h[path]
        return f

    def replace(path, data, **kw):
        def f(h):
            if path in h:
                del h[path]
            h.create_dataset(path, data=data, **kw)
        return f

    def setitem(path, index, value):
        def f(h):
            ds = h[path]
            a = ds[()]
            a[index] = value
            ds[...] = a
        return f

    def truncate_branch(n):
        def f(h):
            for k in list(h["branch"].keys()):
                ds = h["branch"][k]
                for_dt = ds.dtype
                a = ds[()][:n]
                del h["branch"][k]
                h["branch"].create_dataset(k, data=a, dtype=for_dt, maxshape=(None,) + a.shape[1:])
        return f

    def switch_kind(i, kind):
        def f(h):
            a = h["branch/kind"][()]
            a = [x.decode() if isinstance(x, bytes) else str(x) for x in a]
            a[i] = kind
            del h["branch/kind"]
            h["branch"].create_dataset("kind", data=a, dtype=h5py.string_dtype())
        return f

    # (name, source, edit, expectation, why). Expectations: err = the file is now wrong in a way the reader checks
    # or must check; any = a value the reader may accept.
    E = [
        ("gamma_nan", "XN", A("gamma", np.nan), "err", "gamma = nan"),
        ("gamma_inf", "XN", A("gamma", np.inf), "err", "gamma = inf"),
        ("gamma_str", "XN", A("gamma", "abc"), "err", "gamma a string"),
        ("gamma_arr", "XN", A("gamma", np.array([1.0, 2.0])), "err", "gamma an array"),
        ("gamma_big", "XN", A("gamma", 1e308), "any", "gamma = 1e308 (T stored separately)"),
        ("gamma_bool", "XN", A("gamma", True), "err", "gamma a boolean"),
        ("EI_zero", "XN", A("EI", 0.0), "err", "EI = 0"),
        ("EI_neg", "XN", A("EI", -1.0), "err", "EI < 0"),
        ("EI_tiny", "XN", A("EI", 1e-300), "any", "EI = 1e-300: positive, but outside rodcont's working range"),
        ("EI_huge", "XN", A("EI", 1e308), "any", "EI = 1e308"),
        ("EI_int", "XN", A("EI", np.int64(2)), "any", "EI an integer"),
        ("EI_missing", "XN", D("EI"), "err", "EI missing"),
        ("EA_bool", "XN", A("EA", True), "err", "EA a boolean"),
        ("L_two", "XN", A("L", 2.0), "any", "L = 2 while the mesh spans [0, 1]"),
        ("L_huge", "XN", A("L", 1e300), "any", "L = 1e300"),
        ("w_neg", "XN", A("w", -1.0), "err", "w < 0"),
        ("w_zero", "XN", A("w", 0.0), "any", "w = 0"),
        ("k_zero", "XN", A("k", 0), "err", "k = 0"),
        ("k_eight", "XN", A("k", 8), "err", "k = 8"),
        ("k_half", "XN", A("k", 2.5), "err", "k = 2.5"),
        ("k_three", "XN", A("k", 3), "err", "k = 3 does not fit the coefficients"),
        ("k_str", "XN", A("k", "5"), "err", "k a string"),
        ("N_neg", "XN", A("N", -5), "any", "N = -5 (the breakpoints say 15)"),
        ("N_str", "XN", A("N", "many"), "any", "N a string"),
        ("T_nan", "XN", A("T", np.nan), "err", "T = nan"),
        ("T_str", "XN", A("T", "x"), "err", "T a string"),
        ("T_euler", "XN", A("T", -1e3), "any", "T below the Euler load"),
        ("wd_zero", "XN", A("weight_direction", np.zeros(3)), "err", "weight_direction = 0"),
        ("wd_short", "XN", A("weight_direction", np.ones(2)), "err", "weight_direction of 2 components"),
        ("wd_str", "XN", A("weight_direction", "down"), "err", "weight_direction a string"),
        ("wd_nan", "XN", A("weight_direction", np.array([np.nan, 0, -1.0])), "err", "weight_direction nan"),
        ("wd_huge", "XN", A("weight_direction", np.array([1e308, 1e308, 1e308])), "any", "weight_direction 1e308"),
        ("wd_up", "XN", A("weight_direction", np.array([0, 0, 1.0])), "any", "weight pointing up"),
        ("param_bogus", "XN", A("param", "bogus"), "any", "param = bogus"),
        ("param_EI", "XN", A("param", "EI"), "any", "param = EI without a /branch/EI column"),
        ("param_int", "XN", A("param", 7), "any", "param a number"),
        ("kind_fold", "XN", A("kind", "fold_curve"), "any", "kind = fold_curve, param phi_L"),
        ("kind_diagram", "XN", A("kind", "diagram"), "any", "kind = diagram on a branch file"),
        ("version_gone", "XN", D("rodcont_version"), "err", "rodcont_version deleted"),
        ("version_num", "XN", A("rodcont_version", 99.5), "any", "rodcont_version a number"),
        ("stop_bytes", "XN", A("stop_reason", np.bytes_(b"\xff\xfe\x00x")), "any", "stop_reason invalid UTF-8"),
        ("stop_gone", "XN", D("stop_reason"), "any", "stop_reason deleted"),
        ("settings_bad", "XN", A("settings", "{not json"), "any", "settings not JSON"),
        ("guard_str", "FN", A("min_alignment_guard", "x"), "any", "min_alignment_guard a string"),
        ("kind_gone", "XN", delete("branch/kind"), "err", "/branch/kind deleted"),
        ("coef_gone", "XN", delete("branch/coefficients"), "err", "/branch/coefficients deleted"),
        ("bp_mesh_gone", "XN", lambda h: (h.__delitem__("branch/breakpoints"), h.__delitem__("mesh")), "err",
         "/branch/breakpoints and /mesh deleted"),
        ("bp_gone", "XN", delete("branch/breakpoints"), "any", "/branch/breakpoints deleted (/mesh remains)"),
        ("mesh_gone", "XN", delete("mesh"), "any", "/mesh deleted"),
        ("phi_str", "XN", replace("branch/phi_L", np.array([b"x"] * n)), "any", "/branch/phi_L strings"),
        ("phi_2d", "XN", replace("branch/phi_L", np.zeros((n, 2))), "any", "/branch/phi_L 2-D"),
        ("phi_scalar", "XN", replace("branch/phi_L", 1.0), "err", "/branch/phi_L a scalar"),
        ("phi_inf", "XN", setitem("branch/phi_L", 3, np.inf), "any", "one Phi = inf"),
        ("phi_nan_all", "XN", setitem("branch/phi_L", slice(None), np.nan), "any", "every Phi = nan"),
        ("phi_short", "XN", replace("branch/phi_L", np.zeros(5)), "any", "/branch/phi_L 5 long (the others n)"),
        ("stretch_complex", "XN", replace("branch/stretch", np.ones(n, complex)), "any", "complex stretch"),
        ("waves_float", "XN", replace("branch/helical_waves", np.full(n, 0.5)), "any", "helical_waves 0.5"),
        ("waves_gone", "XN", delete("branch/helical_waves"), "any", "helical_waves deleted"),
        ("empty", "XN", truncate_branch(0), "any", "every /branch dataset emptied (0 points)"),
        ("one_point", "XN", truncate_branch(1), "any", "one point"),
        ("folds_idx_big", "FN", replace("folds/index", np.array([999])), "err", "/folds/index out of range"),
        ("folds_idx_neg", "FN", replace("folds/index", np.array([-1])), "err", "/folds/index negative"),
        ("folds_idx_float", "FN", replace("folds/index", np.array([1.5])), "err", "/folds/index a float"),
        ("folds_waves_gone", "FN", delete("folds/waves_before"), "any", "/folds/waves_before deleted"),
        ("folds_phi_short", "FN", replace("folds/phi_L", np.zeros(0)), "any", "/folds/phi_L shorter than index"),
        ("folds_dataset", "FN", lambda h: (h.__delitem__("folds"), h.create_dataset("folds", data=np.zeros(2))),
         "err", "/folds a dataset"),
        ("folds_str", "FN", replace("folds/phi_L", np.array([b"x"])), "any", "/folds/phi_L a string"),
        ("bps_idx", "XN", replace("branch_points/index", np.array([0])), "any",
         "/branch_points/index = [0] (a regular point)"),
        ("bps_kind", "XN", lambda h: (replace("branch_points/index", np.array([5]))(h),
                                      replace("branch_points/phi_L", np.array([1.0]))(h),
                                      replace("branch_points/stretch", np.array([0.0]))(h),
                                      switch_kind(5, "branch_point")(h)), "any",
         "point 5 relabelled a branch point (it is not one)"),
        ("bp_nonmono", "XN", setitem("branch/breakpoints", (3, 5), 0.9), "err", "breakpoints not increasing"),
        ("coef_nan", "XN", setitem("branch/coefficients", (3, 100), np.nan), "err", "a NaN inside a coefficient row"),
        ("coef_zero", "XN", setitem("branch/coefficients", slice(None), 0.0), "any", "every coefficient 0"),
        ("coef_huge", "XN", setitem("branch/coefficients", slice(None), 1e308), "any", "every coefficient 1e308"),
        ("coef_1d", "XN", replace("branch/coefficients", np.zeros(n)), "err", "coefficients 1-D"),
        ("tangent_bad", "XN", replace("branch/tangent", np.ones((n, 7), "f4")), "any", "tangent of the wrong width"),
        ("tangent_nan", "XN", setitem("branch/tangent", slice(None), np.nan), "any", "tangent all NaN"),
        ("kind_int", "XN", replace("branch/kind", np.arange(n)), "err", "/branch/kind numbers"),
        ("branch_dataset", "XN", lambda h: (h.__delitem__("branch"), h.create_dataset("branch", data=np.zeros(3))),
         "err", "/branch a dataset"),
        ("ext_missing", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                         h["branch"].__setitem__("stretch", h5py.ExternalLink("missing.h5", "/x"))),
         "err", "/branch/stretch an external link to a missing file"),
        ("ext_devzero", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                         h["branch"].__setitem__("stretch", h5py.ExternalLink("/dev/zero", "/x"))),
         "err", "/branch/stretch an external link to /dev/zero"),
        ("ext_self", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                      h["branch"].__setitem__("stretch",
                                                              h5py.ExternalLink("edit_ext_self.h5", "/branch/l0"))),
         "any", "/branch/stretch an external link into the file itself"),
        ("soft_loop", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                       h["branch"].__setitem__("stretch", h5py.SoftLink("/branch/stretch"))),
         "err", "/branch/stretch a soft link to itself"),
        ("soft_dangling", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                           h["branch"].__setitem__("stretch", h5py.SoftLink("/nowhere"))),
         "err", "/branch/stretch a dangling soft link"),
        ("bomb", "XN", lambda h: (h.__delitem__("branch/stretch"),
                                  h["branch"].create_dataset("stretch", shape=(200_000_000,), dtype="f8",
                                                             chunks=(1_000_000,), compression="gzip", fillvalue=0.0)),
         "any", "/branch/stretch declared 200 million long (1.6 GB unwritten, compressed)"),
        ("diag_branch_col", "DN", delete("folds/branch"), "any", "diagram /folds/branch deleted"),
        ("diag_branch_big", "DN", replace("folds/branch", np.array([7])), "any", "diagram /folds/branch = 7"),
        ("diag_group_dataset", "DN", lambda h: (h.__delitem__("branches/0"),
                                                h["branches"].create_dataset("0", data=np.zeros(3))), "err",
         "diagram /branches/0 a dataset"),
        ("diag_no_folds", "DN", delete("folds"), "any", "diagram /folds deleted"),
    ]
    src_files = {"XN": "XN.h5", "FN": "FN.h5", "DN": "DN.h5"}
    for name, src, fn, exp, why in E:
        fname = f"edit_{name}.h5"
        path = os.path.join(fixdir, fname)
        shutil.copy(os.path.join(fixdir, src_files[src]), path)
        with h5py.File(path, "a") as h:
            fn(h)
        readers = _readers(fname, with_fold_curve=(src == "FN"))
        # folds, shape and trace --start read everything plot reads; plot only where the curve data is edited;
        # an edited root attribute matters where the rod is rebuilt (shape, trace, fold-curve), not in folds
        readers = [r for r in readers if r[1] != "plot" or name.startswith(("phi", "stretch", "empty", "one_"))]
        if name.split("_")[0] in ("gamma", "EI", "EA", "L", "w", "k", "N", "T", "wd", "param", "kind", "version",
                                  "stop", "settings", "guard") and src != "DN":
            readers = [r for r in readers if r[1] != "folds"] if name not in ("version_gone", "kind_diagram") \
                else readers
        if src == "DN":
            readers = [(["folds", fname], "folds"), (["plot", fname, "-o", "p.png"], "plot"),
                       (["shape", fname, "--branch", "0", "-o", "s.png"], "shape"),
                       (["trace", "--start", fname + ":0:-1", "--max-steps", "3", "--out", "o.h5", "--quiet"],
                        "trace")]
        if name == "bps_kind":
            readers.append((["trace", "--start", fname + ":BP1", "--switch", "--max-steps", "3", "--out", "o.h5",
                             "--quiet"], "trace --switch"))
        for args, cmd in readers:
            P.append(Probe("edited", args, exp, f"hand-edited copy (no rodcont header): {why}", files=(fname,)))
    # the same kind of edit on a file that still has rodcont's header: refused by the checksum
    path = os.path.join(fixdir, "edit_checksummed.h5")
    shutil.copy(os.path.join(fixdir, "X.h5"), path)
    with h5py.File(path, "a") as h:
        h.attrs["stop_reason"] = "edited by hand"
    P.append(Probe("edited", ["folds", "edit_checksummed.h5"], "err",
                   "a harmless h5py edit of a file with rodcont's header (checksum mismatch)",
                   files=("edit_checksummed.h5",)))
    return P


# --------------------------------------------------------------------------
# Fixtures
# --------------------------------------------------------------------------
def run_cli(args, cwd, env, timeout=300):
    return subprocess.run([sys.executable, CLI] + args, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def build_fixtures(fixdir: str, env: dict) -> None:
    steps = [
        (["trace", "--gamma", "1", "--stretch-max", "0.1", "--out", "X.h5", "--quiet"], "X.h5"),
        (["trace", "--gamma", "1", "--stretch-max", "0.2", "--out", "F.h5", "--quiet"], "F.h5"),
        (["diagram", "--gamma", "1", "--phi-max", "15", "--stretch-max", "0.2", "--out", "D.h5", "--quiet"], "D.h5"),
        (["fold-curve", "F.h5:0", "--range", "0.9", "1.1", "--max-steps", "3", "--out", "C.h5", "--quiet"], "C.h5"),
        (["plot", "X.h5", "-o", "pic.png"], "pic.png"),
        (["trace", "--start", "X.h5:3", "--param", "EI", "--range", "0.5", "2", "--max-steps", "6", "--out", "E.h5",
          "--quiet"], "E.h5"),
        (["trace", "--start", "X.h5:3", "--param", "gamma", "--range", "0.5", "2", "--max-steps", "6", "--out",
          "G.h5", "--quiet"], "G.h5"),
    ]
    for args, out in steps:
        r = run_cli(args, fixdir, env)
        if r.returncode != 0 or not os.path.exists(os.path.join(fixdir, out)):
            sys.exit(f"fuzz_cli: cannot build the fixture {out}: {_shell(args)} -> {r.returncode}\n{r.stderr}")
    for src in ("X", "F", "D"):   # header-less copies: the magic spoiled, HDF5 still finds its superblock at 512
        d = bytearray(open(os.path.join(fixdir, f"{src}.h5"), "rb").read())
        d[0] ^= 0xFF
        with open(os.path.join(fixdir, f"{src}N.h5"), "wb") as fh:
            fh.write(d)
        r = run_cli(["folds", f"{src}N.h5"], fixdir, env)
        if r.returncode != 0:
            sys.exit(f"fuzz_cli: the header-less copy {src}N.h5 does not read back: {r.stderr}")
    for name, data in (("text.txt", b"phi_L stretch\n1 2\n"), ("empty.h5", b"")):
        with open(os.path.join(fixdir, name), "wb") as fh:
            fh.write(data)
    build_safety_fixtures(fixdir, env)
    with open(os.path.join(fixdir, "X.h5"), "rb") as fh:
        n = fh.read()
    assert n.startswith(b"RODCONT-BRANCH-FILE"), "the branch file format changed: update MAGIC_LEN"


# --------------------------------------------------------------------------
# Running and judging
# --------------------------------------------------------------------------
def snapshot(root: str) -> dict:
    """relative path -> what it is (content hash for regular files, target for links)."""
    out = {}

    def walk(d, rel):
        try:
            entries = list(os.scandir(d))
        except OSError as exc:
            out[rel or "."] = ("unreadable", str(exc))
            return
        for e in entries:
            r = os.path.join(rel, e.name) if rel else e.name
            try:
                st = os.lstat(e.path)
            except OSError:
                continue
            if stat.S_ISLNK(st.st_mode):
                out[r] = ("link", os.readlink(e.path))
            elif stat.S_ISDIR(st.st_mode):
                out[r] = ("dir", stat.S_IMODE(st.st_mode))
                walk(e.path, r)
            elif stat.S_ISREG(st.st_mode):
                if st.st_size > (64 << 20):
                    out[r] = ("file", st.st_size, st.st_mtime_ns)
                else:
                    h = hashlib.blake2b(digest_size=16)
                    with open(e.path, "rb") as fh:
                        for chunk in iter(lambda: fh.read(1 << 20), b""):
                            h.update(chunk)
                    out[r] = ("file", st.st_size, h.hexdigest())
            else:
                out[r] = ("special", stat.S_IFMT(st.st_mode))
    walk(root, "")
    return out


@dataclass
class Result:
    probe: Probe
    rc: int | None
    stdout: str
    stderr: str
    elapsed: float
    problems: list = field(default_factory=list)
    cwd: str = ""
    notes: list = field(default_factory=list)
    skipped: str = ""


def _check_complete(path: str, env: dict, cwd: str) -> str | None:
    """A branch file left behind must read back whole (rodcont folds)."""
    if os.path.isdir(path):
        return None
    r = subprocess.run([sys.executable, CLI, "folds", path], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=60, stdin=subprocess.DEVNULL)
    if r.returncode != 0:
        return f"left {os.path.basename(path)} that does not read back: {r.stderr.strip()[:200]}"
    return None


def run_probe(p: Probe, workdir: str, env: dict, mem_limit: int, keep: bool) -> Result:
    d = os.path.join(workdir, "p", f"{p.id:05d}")
    os.makedirs(d)
    os.chmod(d, 0o755)
    fixdir = os.path.join(workdir, "fixtures")
    for f in p.files:
        shutil.copy2(os.path.join(fixdir, f), os.path.join(d, f))
    if p.setup is not None:
        try:
            p.setup(d)
        except OSError as exc:       # e.g. mknod without CAP_MKNOD: the probe cannot be set up here
            res = Result(p, None, "", "", 0.0, [], d)
            res.skipped = f"setup failed: {exc}"
            _rmtree(d)
            return res
    if p.user == "nocap" and p.ro_cwd:
        os.chmod(d, 0o555)           # root-owned, 555: without CAP_DAC_OVERRIDE nothing can be created here
    before = snapshot(d)
    limits = [f"ulimit -S -v {mem_limit // 1024}"]
    if p.fsize is not None:
        limits.append(f"ulimit -S -f {max(1, p.fsize // 1024)}")
    if p.stdout_path == "CLOSED":
        limits.append("exec 1>&-")
    target = [sys.executable, "-c", _api_code(p.python)] if p.python else [sys.executable, CLI] + list(p.args)
    cmd = ["bash", "-c", "; ".join(limits) + '; exec "$@"', "bash"] + target
    kw = dict(cwd=d, env=env, stdin=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    stdout_f = None
    if p.stdout_path == "BROKENPIPE":      # a pipe whose reader has already gone (`rodcont ... | true`)
        r_fd, w_fd = os.pipe()
        os.close(r_fd)
        stdout_f = os.fdopen(w_fd, "wb")
        kw["stdout"] = stdout_f
    elif p.stdout_path == "CLOSED":
        kw["stdout"] = subprocess.DEVNULL
    elif p.stdout_path:
        stdout_f = open(p.stdout_path, "wb")
        kw["stdout"] = stdout_f
    else:
        kw["stdout"] = subprocess.PIPE
    if p.user == "nocap":
        cmd = NOCAP + cmd
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, **kw)
    problems = []
    out = err = b""
    rc = None
    try:
        if p.signal_after:
            sig, delay = p.signal_after
            try:
                out, err = proc.communicate(timeout=delay)
            except subprocess.TimeoutExpired:
                try:
                    if sig == signal.SIGINT:
                        os.killpg(proc.pid, sig)      # a terminal's Ctrl-C goes to the foreground group
                    else:
                        proc.send_signal(sig)
                except ProcessLookupError:
                    pass
                out, err = proc.communicate(timeout=p.timeout)
        else:
            out, err = proc.communicate(timeout=p.timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
        problems.append(f"HANG: no exit within {p.timeout:g} s (killed)")
    finally:
        if stdout_f is not None:
            stdout_f.close()
    elapsed = time.monotonic() - t0
    stdout = (out or b"").decode("utf-8", "replace")
    stderr = (err or b"").decode("utf-8", "replace")
    if p.user == "nocap":
        os.chmod(d, 0o755)
    res = Result(p, rc, stdout, stderr, elapsed, problems, d)
    if rc is not None:
        judge(res, before, snapshot(d), env)
    if not keep and not res.problems:
        _rmtree(d)
    return res


SYSTEM_DEVICES = {"/dev/null": (1, 3), "/dev/full": (1, 7), "/dev/zero": (1, 5)}


def devices_intact() -> list[str]:
    """System device nodes that are no longer the character devices they should be."""
    bad = []
    for path, (major, minor) in SYSTEM_DEVICES.items():
        try:
            st = os.lstat(path)
        except OSError:
            bad.append(path)
            continue
        if not stat.S_ISCHR(st.st_mode) or os.major(st.st_rdev) != major or os.minor(st.st_rdev) != minor:
            bad.append(path)
    return bad


def restore_devices(bad: list[str]) -> list[str]:
    """Put back a system device node replaced by a probe (root only); returns what could not be restored."""
    left = []
    for path in bad:
        major, minor = SYSTEM_DEVICES[path]
        try:
            if os.path.lexists(path):
                os.unlink(path)
            os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(major, minor))
            os.chmod(path, 0o666)
        except OSError:
            left.append(path)
    return left


def _rmtree(d):
    for root, dirs, files in os.walk(d):
        for x in dirs:
            try:
                os.chmod(os.path.join(root, x), 0o755)
            except OSError:
                pass
    shutil.rmtree(d, ignore_errors=True)


def judge(res: Result, before: dict, after: dict, env: dict) -> None:
    p, rc, problems = res.probe, res.rc, res.problems
    if "Traceback" in res.stderr or "Traceback" in res.stdout:
        problems.append("TRACEBACK printed")
    if p.expect == "sig" and res.stderr.lstrip().startswith("Fatal Python error: init_import_site"):
        # the signal came while the interpreter itself imported its site module, before a line of rodcont ran
        # (a startup probe timed for a fast machine): the interpreter's own message, out of rodcont's reach
        res.notes.append("signalled during the interpreter's own start-up (its site import)")
        return
    if rc < 0 and p.expect == "sig" and -rc == p.signal_after[0]:
        # died of the signal itself before Python could run rodcont's handler: a shell reports 128 + signum too
        res.notes.append(f"killed by {signal.Signals(-rc).name} before any handler ran (no message)")
    elif rc < 0:
        problems.append(f"CRASH: killed by signal {-rc} ({signal.Signals(-rc).name})")
    expected = {"err": (2,), "ok": (0,), "any": (0, 2), "env": (1, 2), "env0": (0, 1, 2)}.get(p.expect)
    if p.expect == "sig":
        sig = p.signal_after[0]
        expected = (0, 130 if sig == signal.SIGINT else 143)
    if expected is None:  # a probe whose expectation this harness does not know: its own bug, reported
        problems.append(f"HARNESS: unknown expectation {p.expect!r}")
        expected = (0, 2)
    if rc >= 0 and rc not in expected:
        problems.append(f"EXIT {rc}, expected {' or '.join(map(str, expected))}")
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    if rc != 0 and p.expect != "sig":
        if len(lines) != 1:
            problems.append(f"STDERR has {len(lines)} non-empty lines, expected exactly 1")
        if not lines or not lines[0].startswith(PREFIX):
            problems.append(f"STDERR does not start with {PREFIX!r}")
        elif not lines[0][len(PREFIX):].strip() or re.search(r"(Error|Exception):\s*$", lines[0]):
            problems.append("STDERR message is empty")
        elif re.search(r"unexpected failure \(", lines[0]):
            problems.append("the CLI itself calls it an 'unexpected failure' (a bug)")
    if p.expect == "sig" and rc not in (0,) and any("Traceback" in ln for ln in lines):
        pass  # already reported
    if p.must_say and p.must_say not in res.stdout + res.stderr:
        problems.append(f"DID NOT SAY {p.must_say!r}")
    if p.must_not_say and p.must_not_say in res.stdout + res.stderr:
        problems.append(f"SAID {p.must_not_say!r}")
    if p.check is not None and rc is not None and rc >= 0:
        try:
            wrong = p.check(res)
        except Exception as exc:  # noqa: BLE001 - a check that cannot read the answer reports it
            wrong = f"the check could not read the answer ({type(exc).__name__}: {exc})"
        if wrong:
            problems.append(f"WRONG ANSWER: {wrong}")
    # files
    new = sorted(set(after) - set(before))
    gone = sorted(set(before) - set(after))
    changed = sorted(k for k in set(before) & set(after) if before[k] != after[k])
    junk = [k for k in new if re.search(r"(^|/)\..*\.(lock|tmp)$", k)]
    if junk:
        problems.append(f"LEFT temporary/lock file(s): {', '.join(junk)}")
    if gone:
        problems.append(f"REMOVED: {', '.join(gone)}")
    failed = rc != 0
    if failed:
        leftovers = [k for k in new if k not in junk and k not in p.partial_ok]
        if leftovers:
            problems.append(f"LEFT new file(s) after a failure: {', '.join(leftovers[:5])}")
        for k in new:
            if k in p.partial_ok and after[k][0] == "file":
                msg = _check_complete(os.path.join(res.cwd, k), env, res.cwd) if k.endswith(".h5") else None
                if msg:
                    problems.append(f"HALF-WRITTEN output: {msg}")
        bad = [k for k in changed if k not in p.partial_ok]
        if bad:
            problems.append(f"CHANGED after a failure: {', '.join(bad)}")
    else:
        bad = [k for k in changed if k not in p.changes_ok]
        if bad:
            problems.append(f"INPUT CHANGED: {', '.join(bad)}")
    if p.expect == "sig" and rc in (130, 143):
        for k in p.partial_ok:
            path = os.path.join(res.cwd, k)
            if k.endswith(".h5") and os.path.isfile(path):
                msg = _check_complete(path, env, res.cwd)
                if msg:
                    problems.append(f"INTERRUPTED run: {msg}")
                else:
                    try:
                        import h5py
                        with h5py.File(path, "r") as f:
                            why = str(f.attrs.get("stop_reason", ""))
                        if "interrupt" not in why and k == "o.h5" and p.probe_cmd() in ("trace", "fold-curve"):
                            problems.append(f"INTERRUPTED run: stop_reason of {k} is {why!r}, not 'interrupted'")
                    except Exception as exc:  # noqa: BLE001
                        problems.append(f"INTERRUPTED run: {k} unreadable by h5py ({exc})")


def cause_key(r: Result) -> str:
    """A coarse signature to group failures by cause."""
    kinds = sorted({re.sub(r"\d+", "N", re.split(r"[:,(]", x)[0]).strip() for x in r.problems})
    first = next((ln for ln in r.stderr.splitlines() if ln.strip()), "")
    m = re.search(r"unexpected failure \((\w+)", first) or re.search(r"error: (\w+Error)", first)
    exc = m.group(1) if m else ""
    return f"{r.probe.probe_cmd()} | {' + '.join(kinds)} | {exc or 'rc=' + str(r.rc)}"


# --------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------
def all_probes(fixdir: str, rng: random.Random, is_root: bool, n_flips: int, env: dict) -> list[Probe]:
    P = []
    P += numeric_probes()
    import h5py
    with h5py.File(os.path.join(fixdir, "X.h5"), "r") as f:
        n = int(f["branch/phi_L"].shape[0])
    P += spec_probes(n)
    P += contradiction_probes(is_root)
    P += heavy_probes()
    P += signal_probes()
    P += make_damaged(fixdir, rng, n_flips, 40)
    P += make_foreign(fixdir, rng, 16)
    P += make_edits(fixdir, n)
    P += text_option_probes()
    P += safety_probes()
    P += issue22_probes()
    P += discovered_probes(discover_options(env, fixdir))
    # base lines must work: otherwise every 'any' probe tells nothing
    for cmd, a in BASE.items():
        P.append(Probe("baseline", a, "ok", "the unmodified base command", files=BASE_FILES.get(cmd, ())))
    for i, p in enumerate(P):
        p.id = i
    return P


def quick_subset(P: list[Probe], n: int, rng: random.Random) -> list[Probe]:
    groups = defaultdict(list)
    for p in P:
        if not p.heavy:
            groups[p.group].append(p)
    total = sum(len(g) for g in groups.values())
    out = []
    for name, g in sorted(groups.items()):
        k = max(1, round(n * len(g) / total))
        if name in ("baseline",):
            k = len(g)
        if name == "signal":
            k = 2
        out += rng.sample(g, min(k, len(g)))
    return sorted(out, key=lambda p: p.id)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a stratified ~150-probe subset (< 3 minutes)")
    ap.add_argument("--jobs", type=int, default=2, help="parallel probes (at most 2)")
    ap.add_argument("--seed", type=int, default=20261123)
    ap.add_argument("--flips", type=int, default=100, help="byte-flip variants of the header-less file")
    ap.add_argument("--filter", default=None, help="only probes whose group or command line matches this regex")
    ap.add_argument("--timeout", type=float, default=None, help="override every probe's timeout (s)")
    ap.add_argument("--mem-limit", type=float, default=8.0, help="address-space limit per probe, GB")
    ap.add_argument("--keep", action="store_true", help="keep the work directory (failures are kept anyway)")
    ap.add_argument("--workdir", default=None, help="where to work (default: a new temporary directory)")
    ap.add_argument("--json", default=None, help="also write the results as JSON to this file")
    ap.add_argument("--list", action="store_true", help="list the probes and exit")
    ap.add_argument("--no-heavy", action="store_true", help="skip the probes that ask for big meshes")
    a = ap.parse_args(argv)
    jobs = max(1, min(2, a.jobs))
    try:
        sys.stdout.reconfigure(errors="backslashreplace")   # probe names hold non-UTF-8 bytes
    except AttributeError:
        pass
    rng = random.Random(a.seed)
    is_root = hasattr(os, "geteuid") and os.geteuid() == 0
    if is_root:   # can we drop the permission bypass? (needs setpriv and CAP_SETPCAP)
        ro = tempfile.mkdtemp(prefix="rodcont-fuzz-ro-")
        os.chmod(ro, 0o555)
        try:
            t = subprocess.run(NOCAP + [sys.executable, "-c", "import os,sys; sys.exit(os.access(sys.argv[1], os.W_OK))",
                                        ro], capture_output=True, timeout=30)
            is_root = t.returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            is_root = False
        finally:
            os.rmdir(ro)
        if not is_root:
            print("fuzz_cli: setpriv cannot drop CAP_DAC_OVERRIDE here: permission probes skipped")

    workdir = a.workdir or tempfile.mkdtemp(prefix="rodcont-fuzz-")
    os.makedirs(workdir, exist_ok=True)
    os.chmod(workdir, 0o755)
    fixdir = os.path.join(workdir, "fixtures")
    os.makedirs(fixdir, exist_ok=True)
    mpl = os.path.join(workdir, "mplconfig")
    os.makedirs(mpl, exist_ok=True)
    os.chmod(mpl, 0o777)
    env = dict(os.environ)
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", MPLBACKEND="Agg",
               MPLCONFIGDIR=mpl, PYTHONDONTWRITEBYTECODE="1", LC_ALL="C.UTF-8", PYTHONWARNINGS="")
    env.pop("PYTHONPATH", None)

    t0 = time.monotonic()
    print(f"fuzz_cli: work directory {workdir}", flush=True)
    build_fixtures(fixdir, env)
    for root, dirs, files in os.walk(fixdir):
        os.chmod(root, 0o755)
        for f in files:
            os.chmod(os.path.join(root, f), 0o644)
    P = all_probes(fixdir, rng, is_root, a.flips, env)
    for root, dirs, files in os.walk(fixdir):
        for f in files:
            os.chmod(os.path.join(root, f), 0o644)
    if a.no_heavy:
        P = [p for p in P if not p.heavy]
    if a.quick:
        P = quick_subset(P, 150, random.Random(a.seed))
    if a.filter:
        rx = re.compile(a.filter)
        P = [p for p in P if rx.search(p.group) or rx.search(_shell(p.args))]
    if a.timeout:
        for p in P:
            p.timeout = a.timeout
    print(f"fuzz_cli: fixtures built in {time.monotonic() - t0:.1f} s; {len(P)} probes, {jobs} at a time",
          flush=True)
    if a.list:
        for p in P:
            print(f"{p.id:5d} {p.group:26s} {p.expect:4s} {_shell(p.args)[:160]}  # {p.why[:80]}")
        return 0

    # long probes first: better packing on two workers
    order = sorted(P, key=lambda p: (-(p.timeout if (p.heavy or p.signal_after) else 0), p.id))
    results = []
    lock = threading.Lock()
    done = [0]
    mem = int(a.mem_limit * (1 << 30))

    if devices_intact():
        sys.exit(f"fuzz_cli: system device nodes are already damaged before any probe: {devices_intact()}")

    def task(p):
        r = run_probe(p, workdir, env, mem, a.keep)
        with lock:
            bad = devices_intact()
            if bad:     # a probe (or anything else on the machine meanwhile) replaced /dev/null, /dev/full...
                left = restore_devices(bad)
                r.problems.append(f"SYSTEM DEVICE REPLACED while this probe ran: {', '.join(bad)} "
                                  f"({'restored' if not left else 'NOT restored: ' + ', '.join(left)})")
                print(f"fuzz_cli: WARNING: {', '.join(bad)} replaced during probe #{p.id}; "
                      f"{'restored' if not left else 'could not restore'}", flush=True)
            done[0] += 1
            if r.problems:
                print(f"  FAIL #{p.id} [{p.group}] {_shell(p.args)[:140]}", flush=True)
            if done[0] % 100 == 0:
                print(f"fuzz_cli: {done[0]}/{len(P)} probes, {time.monotonic() - t0:.0f} s", flush=True)
        return r

    with ThreadPoolExecutor(max_workers=jobs) as ex:
        futs = [ex.submit(task, p) for p in order]
        for f in as_completed(futs):
            results.append(f.result())
    results.sort(key=lambda r: r.probe.id)
    skipped = [r for r in results if r.skipped]
    results = [r for r in results if not r.skipped]
    failed = [r for r in results if r.problems]
    elapsed = time.monotonic() - t0

    print()
    print("=" * 100)
    print(f"probes tried {len(results)}   passed {len(results) - len(failed)}   failed {len(failed)}   "
          f"({elapsed:.0f} s, {jobs} workers)" + (f"   skipped {len(skipped)} (could not be set up)" if skipped else ""))
    hangs = [r for r in results if any(x.startswith("HANG") for x in r.problems)]
    if hangs:
        print(f"hangs: {len(hangs)}")
    print("=" * 100)
    by = OrderedDict()
    for r in failed:
        by.setdefault(cause_key(r), []).append(r)
    for key, rs in sorted(by.items(), key=lambda kv: -len(kv[1])):
        print(f"\n### {len(rs)} x  {key}")
        for r in rs:
            p = r.probe
            print(f"- #{p.id} [{p.group}] expect {p.expect}: {p.why}")
            if p.setup_desc or p.user or p.fsize or p.stdout_path or p.files:
                extra = []
                if p.files:
                    extra.append("inputs: " + ", ".join(p.files))
                if p.setup_desc:
                    extra.append("setup: " + p.setup_desc)
                if p.fsize:
                    extra.append(f"ulimit -f {p.fsize // 1024}")
                if p.stdout_path:
                    extra.append(f"> {p.stdout_path}")
                print(f"    ({'; '.join(extra)})")
            print(f"    $ {_shell(p.args)[:300]}")
            print(f"    exit {r.rc}; {'; '.join(r.problems)}")
            errl = r.stderr.splitlines()
            for ln in errl[:3]:
                print(f"    stderr| {ln[:300]}")
            if len(errl) > 3:
                print(f"    stderr| ... ({len(errl) - 3} more lines)")
            print(f"    dir: {r.cwd}")
    noted = [r for r in results if r.notes and not r.problems]
    if noted:
        print("\nnotes (passed, but worth knowing):")
        for r in noted:
            print(f"- #{r.probe.id} {_shell(r.probe.args)[:150]}: exit {r.rc}; {'; '.join(r.notes)}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump([dict(id=r.probe.id, group=r.probe.group, args=r.probe.args, expect=r.probe.expect,
                            why=r.probe.why, files=list(r.probe.files), setup=r.probe.setup_desc, rc=r.rc,
                            problems=r.problems, notes=r.notes, stderr=r.stderr[-4000:], stdout=r.stdout[-2000:],
                            elapsed=r.elapsed, cause=cause_key(r) if r.problems else None, dir=r.cwd)
                       for r in results], fh, indent=1)
    print()
    print(f"probes tried {len(results)}   passed {len(results) - len(failed)}   failed {len(failed)}")
    if not a.keep and not failed and not a.workdir:
        _rmtree(workdir)
    elif failed:
        print(f"failing probe directories kept under {os.path.join(workdir, 'p')}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
