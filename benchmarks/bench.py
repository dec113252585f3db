"""rodcont benchmark: prints each target, the measured figure, and whether it is met (not a test).

    python benchmarks/bench.py            # all sections
    python benchmarks/bench.py --quick    # fewer repeats, no dask or long-rod tail

Machines are shared and noisy: every figure is the best of a few runs, CPU
time of the measured process where a whole process is timed. Sections:

1. Process floor: ``python -c "import numpy, scipy.sparse.linalg"`` against
   ``rodcont --version`` (target 1.15x) and ``rodcont trace --gamma 1 --out F.h5``
   (target 1.5x).
2. Per branch in one process: ``rodcont.trace(1.0, stretch_max=0.5)`` with the
   default settings against the code before this work (commit 85b9e70, checked
   out into a temporary directory and run in a subprocess): target a third of
   its time. Time per continuation step at N = 15, k = 5 (target 2 ms).
3. Accuracy per unknown: the cheapest fixed uniform mesh (k = 5) that gives the
   Gamma = 1 and Gamma = 2 first folds to 1e-9 in Phi (against the independent
   Lagrangian reference, tests/data/lagrangian_folds.json), and its time.
4. Long rods: one Newton iteration and one continuation step at N = 15, 150,
   1500, 5000 (linear in N), peak memory.
5. The whole Gamma = 1 diagram up to Phi = 40, whole process (target 10 s),
   per-branch times.
7. A 1 km drill pipe in a survey-defined well with 2000 subintervals: one
   equilibrium, whole process (target 10 s).
6. Many branches: a 6-Gamma sweep on a dask LocalCluster of 1 and 2 worker
   processes (speed-up).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SRC = os.path.join(ROOT, "src")
sys.path.insert(0, SRC)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import rodcont  # noqa: E402

BEFORE = "85b9e70"  # the code as it stood when the speed issue was filed
ENV = dict(os.environ, PYTHONPATH=SRC, OPENBLAS_NUM_THREADS="1")


def verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def child_cpu(cmd, env=ENV, repeats=3, cwd=None) -> float:
    """Best user+system CPU seconds of a whole child process."""
    best = np.inf
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        r = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if r.returncode != 0:
            raise RuntimeError(f"{cmd}: {r.stderr}")
        best = min(best, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime))
    return best


def cpu(fn, repeats=3):
    best, out = np.inf, None
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def section_floor(quick):
    print("\n## 1. Process floor (CPU seconds of the whole process, best of 3)")
    floor = child_cpu([sys.executable, "-c", "import numpy, scipy.sparse.linalg"])
    rc = [sys.executable, "-c", "from rodcont._entry import main; main()"]
    # rodcont's modules byte-compiled, as numpy's and scipy's are (pip compiles on install; an editable
    # install writes them on first import unless PYTHONDONTWRITEBYTECODE is set, as on the machine this
    # was written on, where every start recompiled them: about 0.08 s)
    compiled = subprocess.run([sys.executable, "-m", "compileall", "-q", os.path.join(SRC, "rodcont")],
                              env={k: v for k, v in ENV.items() if k != "PYTHONDONTWRITEBYTECODE"},
                              capture_output=True).returncode == 0
    version = child_cpu(rc + ["--version"])
    with tempfile.TemporaryDirectory() as d:
        tr = child_cpu(rc + ["trace", "--gamma", "1", "--out", os.path.join(d, "F.h5"), "--overwrite", "--quiet"])
    print(f"(rodcont byte-compiled first: {'yes' if compiled else 'NO, compileall failed'})")
    print(f"floor  python -c 'import numpy, scipy.sparse.linalg'   {floor:.3f} s")
    print(f"rodcont --version                                     {version:.3f} s  ratio {version / floor:.2f}  "
          f"target 1.15  {verdict(version / floor <= 1.15)}")
    print(f"rodcont trace --gamma 1 --out F.h5 (defaults)         {tr:.3f} s  ratio {tr / floor:.2f}  "
          f"target 1.5  {verdict(tr / floor <= 1.5)}")


OLD_SNIPPET = """
import sys, time
sys.path.insert(0, sys.argv[1])
from rodcont.branch import trace
trace(1.0, stretch_max=0.5)
best = 1e9
for _ in range(3):
    t = time.process_time(); br = trace(1.0, stretch_max=0.5); best = min(best, time.process_time() - t)
print(best, br.steps, br.folds[0]['phi_L'])
"""


def section_branch(quick):
    print("\n## 2. Per branch in one process: rodcont.trace(1.0, stretch_max=0.5), default settings (CPU, best of 3)")
    rodcont.trace(1.0, stretch_max=0.5)
    t_new, br = cpu(lambda: rodcont.trace(1.0, stretch_max=0.5))
    f = br.folds[0]
    print(f"now:    {t_new:.3f} s, {br.steps} steps, {br.remeshes} remeshes, fold Phi {f['phi_L']:.12f} "
          f"(estimated error {f['error']:.1e})")
    with tempfile.TemporaryDirectory() as d:
        r = subprocess.run(f"git -C {ROOT} archive {BEFORE} src | tar -x -C {d}", shell=True, capture_output=True)
        if r.returncode == 0:
            out = subprocess.run([sys.executable, "-c", OLD_SNIPPET, os.path.join(d, "src")], env=dict(
                os.environ, OPENBLAS_NUM_THREADS="1"), capture_output=True, text=True)
            t_old, steps_old, phi_old = out.stdout.split()
            t_old = float(t_old)
            print(f"before ({BEFORE}): {t_old:.3f} s, {steps_old} steps, fold Phi {float(phi_old):.12f}")
            print(f"ratio now / before {t_new / t_old:.2f}   target 0.33  {verdict(t_new / t_old <= 1 / 3)}")
        else:
            print(f"(the code before, {BEFORE}, is not in this checkout: no comparison)")
    # time per continuation step on a fixed mesh (no error estimates, no remeshing): the steps only
    stamps = []
    rodcont.trace(1.0, N=15, adapt=False, max_steps=5)
    best = np.inf
    for _ in range(3):
        stamps.clear()
        t0 = time.process_time()
        b = rodcont.trace(1.0, N=15, adapt=False, phi_max=12.0, max_error=1.0,
                          callback=lambda pt: stamps.append((time.process_time(), str(pt.kind))))
        reg = [t for t, kind in stamps if kind == "regular"]
        best = min(best, (reg[-1] - reg[0]) / (len(reg) - 1))
    print(f"one continuation step, N = 15, k = 5 (corrector, tangent, outputs): {1e3 * best:.2f} ms   target 2 ms  "
          f"{verdict(best <= 2e-3)}   ({b.newton_iterations / b.steps:.1f} corrector iterations per step, chord and "
          f"Newton)")


def section_accuracy(quick):
    print("\n## 3. Accuracy per unknown: the cheapest fixed mesh (k = 5) giving the first fold to 1e-9 in Phi")
    with open(os.path.join(ROOT, "tests", "data", "lagrangian_folds.json")) as fh:
        ref = {r["gamma"]: r for r in json.load(fh)["primary_folds"]}
    for gamma in (1.0, 2.0):
        r = ref[gamma]
        for N in range(4, 60):
            try:
                b = rodcont.trace(gamma, N=N, adapt=False, max_error=1.0, stretch_max=r["stretch"] + 0.05)
            except ValueError:
                continue
            if not b.folds:
                continue
            err = abs(b.folds[0]["phi_L"] - r["phi_L"])
            if err < 1e-9:
                t, _ = cpu(lambda: rodcont.trace(gamma, N=N, adapt=False, max_error=1.0,
                                                 stretch_max=r["stretch"] + 0.05))
                print(f"Gamma = {gamma:g}: N = {N} ({6 * N * 5 + 11} unknowns): fold Phi error {err:.1e}, "
                      f"{t:.3f} s for the branch to just past the fold")
                break
        t, b = cpu(lambda: rodcont.trace(gamma, stretch_max=r["stretch"] + 0.05))
        print(f"Gamma = {gamma:g}, the default adaptive mesh: fold Phi error {abs(b.folds[0]['phi_L'] - r['phi_L']):.1e}, "
              f"{t:.3f} s")


def section_long(quick):
    print("\n## 4. Long rods: one Newton iteration and one continuation step against N (k = 5)")
    from rodcont.linalg import LU, bordered
    from rodcont.system import RodSystem
    print(f"{'N':>6} {'unknowns':>9} {'Newton it [ms]':>15} {'per unknown [us]':>17} {'step [ms]':>10} "
          f"{'peak memory [MB]':>17}")
    rod = rodcont.RodParameters()
    for N in ((15, 150, 1500) if quick else (15, 150, 1500, 5000)):
        s = RodSystem(rod, 1.0, N=N)
        x = s.model.initial_guess(s.disc, s.base[1])
        x = s.disc.newton(x, s.params(0.0)).x
        reps = 20 if N <= 150 else 3

        def newton_iteration():
            F, J, Fp = s.linearise(x, 0.0)
            A = bordered(J, Fp, np.full(J.shape[0], 1.0 / J.shape[0]), 0.5)
            return LU(A).solve(np.append(F, 0.0))

        newton_iteration()
        t0 = time.process_time()
        for _ in range(reps):
            newton_iteration()
        t_it = (time.process_time() - t0) / reps
        stamps = []
        # regular steps only: a point where the trace ends (a bound) carries an error estimate and a
        # stability count, which at N = 1500 cost more than the steps
        b = rodcont.trace(1.0, N=N, adapt=False, max_error=1.0, max_steps=6 if N >= 1500 else 12, phi_max=12.0,
                          callback=lambda pt: stamps.append((time.process_time(), str(pt.kind))))
        reg = [t for t, kind in stamps if kind == "regular"]
        per = (reg[-1] - reg[0]) / max(len(reg) - 1, 1)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"{N:6d} {s.disc.size:9d} {1e3 * t_it:15.2f} {1e6 * t_it / s.disc.size:17.2f} {1e3 * per:10.1f} "
              f"{peak:17.0f}")
    if not quick:
        print("memory of a long trace (a helix in a pipe, N = 60 adapted to 159, 154 points; whole process, "
              "best of 2), with the heap trimmed every 0.25 s above 256 MB (the default) and never:")
        for interval in ("0.25", "None"):
            runs = [subprocess.run([sys.executable, "-c", MEMORY_SNIPPET, interval], env=ENV, capture_output=True,
                                   text=True).stdout.split() for _ in range(2)]
            peak, cpu_s, sys_s = min((float(a), float(b), float(c)) for a, b, c in runs)
            print(f"  TRIM_INTERVAL = {interval:5s}: peak {peak:5.0f} MB, {cpu_s:.2f} s CPU of which {sys_s:.2f} s "
                  f"system")


MEMORY_SNIPPET = """
import resource, sys, time
import rodcont, rodcont.drivers.trace as T
from rodcont.rod import RodParameters
from rodcont.contact import Wall
T.TRIM_INTERVAL = eval(sys.argv[1])
t = time.process_time()
rodcont.trace(rod=RodParameters(w=0.5), T=-20.0, wall=Wall(0.01, eps=1e-2, force_scale=50.0), phi_max=60.0, N=60)
# VmHWM, this process's own peak (ru_maxrss carries the parent's peak across fork and exec)
hwm = [float(l.split()[1]) / 1024 for l in open("/proc/self/status") if l.startswith("VmHWM")][0]
print(hwm, time.process_time() - t, resource.getrusage(resource.RUSAGE_SELF).ru_stime)
"""


def section_diagram(quick):
    print("\n## 5. rodcont diagram --gamma 1 --phi-max 40, whole process (CPU), per-branch times")
    rc = [sys.executable, "-c", "from rodcont._entry import main; main()"]
    with tempfile.TemporaryDirectory() as d:
        t0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        r = subprocess.run(rc + ["diagram", "--gamma", "1", "--phi-max", "40", "--out", os.path.join(d, "d.h5")],
                           env=ENV, capture_output=True, text=True)
        t1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = (t1.ru_utime - t0.ru_utime) + (t1.ru_stime - t0.ru_stime)
    for line in r.stdout.splitlines():
        if line.lstrip()[:2].rstrip(":").isdigit() and "points" in line:
            print("   " + line.strip())
    print(f"whole process {cpu_s:.2f} s CPU   target 10 s  {verdict(cpu_s <= 10.0)}")


def section_well(quick):
    print("\n## 7. A 1 km drill pipe in a survey-defined well (examples/conduit_well.toml), N = 2000: one "
          "equilibrium, whole process (CPU, peak memory)")
    rc = [sys.executable, "-c", "from rodcont._entry import main; main()"]
    conduit = os.path.join(ROOT, "examples", "conduit_well.toml")
    cmd = rc + ["solve", "--T", "1e5", "--phi", "0", "--conduit", conduit, "--L", "973.077121578337",
                "--EI", "1.25e6", "--GJ", "9.6e5", "--EA", "7.15e8", "--w", "235", "--N", "2000"]
    best = child_cpu(cmd, repeats=1 if quick else 3)
    # its own peak memory: measured by a fresh parent (this process's children include the long rods above)
    probe = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], capture_output=True, check=True); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    peak = int(subprocess.run([sys.executable, "-c", probe] + cmd, env=ENV, capture_output=True, text=True,
                              check=True).stdout) / 1024
    # unknowns: 6 N k + 11, and 5 at each of the well's 2 curvature jumps (joins: MD 300, 600)
    print(f"one equilibrium {best:.2f} s CPU ({6 * 5 * 2000 + 11 + 2 * 5} unknowns), peak memory {peak:.0f} MB   "
          f"target 10 s  {verdict(best <= 10.0)}")


def section_dask(quick):
    print("\n## 6. A 6-Gamma sweep on a dask LocalCluster of process workers")
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print("dask.distributed is not installed (pip install 'rodcont[dask]'): skipped")
        return
    from rodcont.drivers.sweep import sweep
    times = {}
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as c, \
                Client(c) as client, tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            sweep([0.0, 0.5, 1.0, 2.0, 5.0, 10.0], d, executor=client.get_executor(), stretch_max=0.5, plot=False)
            times[workers] = time.perf_counter() - t
        print(f"{workers} worker(s): {times[workers]:.2f} s wall")
    print(f"speed-up on 2 workers: {times[1] / times[2]:.2f} (2 cores, shared)")


def section_bordered(quick):
    print("\n## 8. Bordered solve: finite-difference Bratu through its fold, n = 2000 .. 20000, and the rod's fold")
    args = [sys.executable, os.path.join(HERE, "bordered_fd.py"), "--rod"] + (["--quick"] if quick else [])
    out = subprocess.run(args, env=ENV, capture_output=True, text=True)
    print(out.stdout.rstrip() if out.returncode == 0 else f"bordered_fd.py failed: {out.stderr.strip()[-400:]}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", nargs="*", help="sections to run: floor branch accuracy long diagram well dask")
    args = ap.parse_args()
    print(f"# rodcont {rodcont.__version__} benchmark, {time.strftime('%Y-%m-%d')}, {platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}, "
          f"load average {os.getloadavg()[0]:.2f}")
    sections = dict(floor=section_floor, branch=section_branch, accuracy=section_accuracy, long=section_long,
                    diagram=section_diagram, well=section_well, dask=section_dask, bordered=section_bordered)
    for name, fn in sections.items():
        if args.only and name not in args.only:
            continue
        if args.quick and name == "dask":
            continue
        fn(args.quick)


if __name__ == "__main__":
    main()
