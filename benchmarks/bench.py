"""rodcont benchmark for issue 24: each figure, its target, met or NOT met (a benchmark, not a test).

    python benchmarks/bench.py                 # every section
    python benchmarks/bench.py --quick         # fewer repetitions, no N = 5000 step
    python benchmarks/bench.py --only trace floor

CPU time (process_time of the measured call, or user + system of a whole child process), best of N, with
the code of the issue (commit 0ee0293, ``--old``: a checkout of it, default /work/old, else ``git archive``
of it into a temporary directory) run in the same session, old and new repetitions alternating. Both are
byte-compiled first (``PYTHONPYCACHEPREFIX``, as an installed package is; with PYTHONDONTWRITEBYTECODE set
every start recompiled them). The load average is printed beside the figures.

Sections:
  trace    first rodcont.trace(gamma) of a process, Gamma = 1 and 2, to the validity guard, defaults:
           ratio to 0ee0293 (target 0.5), the folds of both
  floor    whole process `rodcont trace --gamma 1 --out F.h5` against `import numpy, scipy.sparse.linalg`
           (target 2.5x)
  diagram  whole process `rodcont diagram --gamma 1 --out F.h5`: wall time (target 5 s), CPU printed
  long     a continuation step at N = 5000 (target 250 ms); one equilibrium of the 1 km well, N = 2000
           (examples/conduit_well.toml, target 4 s CPU), its peak memory
  fill     fill of every factorisation at the Gamma = 1 fold (steps, error estimate, stability count): nonzeros
           of L + U over the matrix's own (target 5)
  broomstick  `rodcont broomstick` of the benchmark well, 3 operations x 100 depths (--quick: 10, extrapolated;
           target 3 minutes wall)
  breakdown  the first Gamma = 1 trace's CPU by kind of work (instrumented): what compiled pointwise kernels, and
           a free linear algebra, would leave at most (issue 24: measured, not added)
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
OLD_COMMIT = "0ee0293"
TMP = tempfile.mkdtemp(prefix="rodcont-bench-")


def env_for(src: str, tag: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(PYTHONPATH=src, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               PYTHONPYCACHEPREFIX=os.path.join(TMP, f"pyc-{tag}"))
    return env


def verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def load() -> str:
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def old_source(path: str | None) -> str | None:
    if path and os.path.isdir(os.path.join(path, "src", "rodcont")):
        return os.path.join(path, "src")
    d = os.path.join(TMP, "old")
    os.makedirs(d, exist_ok=True)
    r = subprocess.run(f"git -C {ROOT} archive {OLD_COMMIT} src | tar -x -C {d}", shell=True, capture_output=True)
    return os.path.join(d, "src") if r.returncode == 0 else None


def child(cmd, env, cwd=None) -> tuple[float, float, str]:
    """(CPU seconds, wall seconds, stdout) of one whole child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {r.stderr.strip()[-600:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall, r.stdout


FIRST_TRACE = """
import json, sys, time
import numpy, scipy.sparse.linalg
import rodcont
t = time.process_time()
br = rodcont.trace(float(sys.argv[1]))
t = time.process_time() - t
print(json.dumps(dict(cpu=t, steps=int(br.steps), folds=[float(f["phi_L"]) for f in br.folds])))
"""


def section_trace(a, old):
    print(f"\n## first rodcont.trace(gamma) of a process, to the validity guard, defaults (CPU s, best of {a.reps}, "
          f"old and new alternating)   {load()}")
    if old is None:
        print("(the code at 0ee0293 is not available: no ratio)")
    for gamma in (1.0, 2.0):
        runs = {"new": [], "old": []}
        for _ in range(a.reps + 1):  # the first pair writes the byte-code caches
            for tag, src in (("new", SRC), ("old", old)):
                if src is not None:
                    out = child([sys.executable, "-c", FIRST_TRACE, str(gamma)], env_for(src, tag))[2]
                    runs[tag].append(json.loads(out.splitlines()[-1]))
        new = min(runs["new"][1:], key=lambda r: r["cpu"])
        line = f"Gamma = {gamma:g}: now {new['cpu']:.3f} s ({new['steps']} steps)"
        if runs["old"]:
            o = min(runs["old"][1:], key=lambda r: r["cpu"])
            ratio = new["cpu"] / o["cpu"]
            if gamma == 1.0:
                a.old_gamma1 = o["cpu"]
            moved = max((abs(p - q) for p, q in zip(new["folds"], o["folds"])), default=0.0)
            line += (f", 0ee0293 {o['cpu']:.3f} s ({o['steps']} steps): ratio {ratio:.2f}  target 0.50  "
                     f"{verdict(ratio <= 0.5)};  folds {', '.join(f'{p:.12f}' for p in new['folds'])} "
                     f"(largest change {moved:.1e}, same count {len(new['folds']) == len(o['folds'])})")
        print(line)


def section_floor(a, old):
    print(f"\n## whole process: `rodcont trace --gamma 1 --out F.h5` against the import floor (CPU s, best of {a.reps})"
          f"   {load()}")
    py = [sys.executable, "-c"]
    rc = py + ["from rodcont._entry import main; main()"]
    out = os.path.join(TMP, "F.h5")
    best = {}
    for tag, src in (("new", SRC), ("old", old)):
        if src is None:
            continue
        env = env_for(src, tag)
        child(rc + ["--version"], env)  # the byte-code caches
        best[tag] = [float("inf"), float("inf")]
        for _ in range(a.reps):
            best[tag][0] = min(best[tag][0], child(py + ["import numpy, scipy.sparse.linalg"], env)[0])
            best[tag][1] = min(best[tag][1], child(rc + ["trace", "--gamma", "1", "--out", out, "--overwrite",
                                                         "--quiet"], env)[0])
    floor, tr = best["new"]
    print(f"floor python -c 'import numpy, scipy.sparse.linalg'  {floor:.3f} s")
    print(f"rodcont trace --gamma 1 --out F.h5                  {tr:.3f} s  ratio {tr / floor:.2f}  target 2.50  "
          f"{verdict(tr / floor <= 2.5)}")
    if "old" in best:
        print(f"  (0ee0293: {best['old'][1]:.3f} s, ratio {best['old'][1] / best['old'][0]:.2f} to its floor)")


DIAGRAM_API = """
import sys, time
import rodcont
t = time.perf_counter()
dg = rodcont.diagram(1.0, out=sys.argv[1], overwrite=True, jobs=int(sys.argv[2]))
print(len(dg.branches), len(dg.folds), time.perf_counter() - t)
"""


def section_diagram(a, old):
    print(f"\n## whole process: the Gamma = 1 diagram, `rodcont diagram --gamma 1 --out F.h5` and "
          f"rodcont.diagram(1.0, jobs=...)   {load()}")
    rc = [sys.executable, "-c", "from rodcont._entry import main; main()"]
    out = os.path.join(TMP, "D.h5")
    cpu, wall, text = child(rc + ["diagram", "--gamma", "1", "--out", out, "--overwrite", "--quiet"],
                            env_for(SRC, "new"))
    for line in text.splitlines():
        if line.strip()[:2].rstrip(":").isdigit() and "points" in line:
            print("   " + line.strip())
    print(f"command line (its default: the branches on a pool of the usable cores): wall {wall:.2f} s  target 5 s  "
          f"{verdict(wall <= 5.0)}   (CPU {cpu:.2f} s, all processes; {os.cpu_count()} cores)")
    for jobs in (1, os.cpu_count() or 1):
        cpu, wall, text = child([sys.executable, "-c", DIAGRAM_API, out, str(jobs)], env_for(SRC, "new"))
        nb, nf, _ = text.split()
        print(f"rodcont.diagram(1.0, jobs={jobs}) ({nb} branches, {nf} folds): wall {wall:.2f} s  target 5 s  "
              f"{verdict(wall <= 5.0)}   (CPU {cpu:.2f} s, all processes)")


STEP = """
import json, sys, time
import rodcont
N = int(sys.argv[1])
stamps = []
rodcont.trace(1.0, N=N, adapt=False, max_error=1.0, max_steps=6, phi_max=12.0,
              callback=lambda pt: stamps.append((time.process_time(), str(pt.kind))))
reg = [t for t, kind in stamps if kind == "regular"]
hwm = [float(l.split()[1]) / 1024 for l in open("/proc/self/status") if l.startswith("VmHWM")][0]
print(json.dumps(dict(step=(reg[-1] - reg[0]) / max(len(reg) - 1, 1), peak=hwm)))
"""


def section_long(a, old):
    print(f"\n## long strings (CPU, best of {min(a.reps, 3)})   {load()}")
    for tag, src in (("new", SRC), ("old", old)):
        if src is None or (a.quick and tag == "old"):
            continue
        runs = [json.loads(child([sys.executable, "-c", STEP, "5000"], env_for(src, tag))[2].splitlines()[-1])
                for _ in range(1 if a.quick else min(a.reps, 3))]
        r = min(runs, key=lambda q: q["step"])
        what = "now" if tag == "new" else "0ee0293"
        tail = f"  target 250 ms  {verdict(r['step'] <= 0.25)}" if tag == "new" else ""
        print(f"a continuation step at N = 5000 (150 011 unknowns), {what}: {1e3 * r['step']:.0f} ms, peak "
              f"{r['peak']:.0f} MB{tail}")
    conduit = os.path.join(ROOT, "examples", "conduit_well.toml")
    cmd = [sys.executable, "-c", "from rodcont._entry import main; main()", "solve", "--T", "1e5", "--phi", "0",
           "--conduit", conduit, "--L", "973.077121578337", "--EI", "1.25e6", "--GJ", "9.6e5", "--EA", "7.15e8",
           "--w", "235", "--N", "2000"]
    probe = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], capture_output=True, check=True); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    for tag, src in (("new", SRC), ("old", old)):
        if src is None or (a.quick and tag == "old"):
            continue
        best = min(child(cmd, env_for(src, tag))[0] for _ in range(1 if a.quick else 2))
        peak = int(child([sys.executable, "-c", probe] + cmd, env_for(src, tag))[2]) / 1024
        what = "now" if tag == "new" else "0ee0293"
        tail = f"  target 4 s  {verdict(best <= 4.0)}" if tag == "new" else ""
        print(f"one equilibrium of the 1 km well, N = 2000, whole process, {what}: {best:.2f} s, peak {peak:.0f} MB"
              f"{tail}")


DRILL = """
import json, os, sys, time
from rodcont import drilling
ex = sys.argv[1]
well = drilling.Well.from_toml(os.path.join(ex, "well_s3d.toml"))
string = drilling.DrillString.from_toml(os.path.join(ex, "drill_string.toml"))
t = time.process_time()
soft = drilling.soft_string(well, string, 3500.0, "slack-off", mu=0.25)
t_soft = time.process_time() - t
t = time.process_time()
td = drilling.torque_and_drag(well, string, 3500.0, "slack-off", mu=0.25)
t_stiff = time.process_time() - t
print(json.dumps(dict(stiff=t_stiff, soft=t_soft, hook=td.hook_load, soft_hook=soft[0], N=td.N)))
"""


def section_drilling(a, old):
    """Issue 23's speed figure: one slack-off equilibrium with friction of the 3-section string at 3500 m on the
    benchmark well (target 10 s of CPU), the soft-string estimate's time beside it (0ee0293 has no drilling)."""
    print(f"\n## torque and drag (CPU, best of {min(a.reps, 2)})   {load()}")
    runs = [json.loads(child([sys.executable, "-c", DRILL, os.path.join(ROOT, "examples")],
                             env_for(SRC, "new"))[2].splitlines()[-1]) for _ in range(1 if a.quick else min(a.reps, 2))]
    r = min(runs, key=lambda q: q["stiff"])
    print(f"one slack-off equilibrium, mu 0.25, bit at 3500 m (well_s3d, 3 sections, N = {r['N']}): "
          f"{r['stiff']:.1f} s, hook load {r['hook'] / 1e3:.1f} kN  target 10 s  {verdict(r['stiff'] <= 10.0)}")
    print(f"the soft string on the same well: {1e3 * r['soft']:.0f} ms, hook load {r['soft_hook'] / 1e3:.1f} kN")


def section_broomstick(a, old):
    """Issue 23's broomstick figure: `rodcont broomstick` on the benchmark well with the 3-section string, mu 0.25,
    3 operations, whole process on the usable cores (target 3 minutes for 100 depths from 1000 to 3500 m). With
    --quick 10 depths over the same range, the 100 depths' time extrapolated from them (each depth a cold
    start: the time is the sum over depths, sampled evenly)."""
    points = 10 if a.quick else 100
    print(f"\n## torque and drag: a broomstick, 3 operations x {points} depths (wall, whole process)   {load()}")
    ex = os.path.join(ROOT, "examples")
    cmd = [sys.executable, "-c", "from rodcont._entry import main; main()", "broomstick",
           os.path.join(ex, "well_s3d.toml"), "--string", os.path.join(ex, "drill_string.toml"), "--friction",
           "0.25", "--depth", "1000", "3500", "--points", str(points), "-o", os.path.join(TMP, "broom.png"),
           "--overwrite"]
    cpu, wall, _ = child(cmd, env_for(SRC, "new"))
    full = wall * 100 / points
    how = "" if points == 100 else f", extrapolated to 100 depths: {full:.0f} s"
    print(f"broomstick of {3 * points} equilibria on {os.cpu_count()} cores: wall {wall:.1f} s (CPU {cpu:.1f} s, "
          f"{cpu / (3 * points):.2f} s an equilibrium){how}  target 180 s  {verdict(full <= 180.0)}"
          f"{'' if full <= 180 else f' ({full / 180:.1f}x over)'}")


FILL = """
import collections, json, sys
import scipy.sparse.linalg as spla
worst, orig = collections.defaultdict(float), spla.splu


def splu(A, *args, **kwargs):
    lu = orig(A, *args, **kwargs)
    f = sys._getframe(1)
    while any(s in f.f_code.co_filename for s in ("scipy", "linalg.py")):
        f = f.f_back
    where = f.f_code.co_filename.rsplit("/", 1)[-1] + ":" + f.f_code.co_name
    worst[where] = max(worst[where], (lu.L.nnz + lu.U.nnz) / A.nnz)
    return lu


spla.splu = splu
import rodcont
br = rodcont.trace(1.0, stretch_max=0.2)  # through the fold: its location, estimate and count
print(json.dumps(worst))
"""


def section_fill(a, old):
    print(f"\n## fill of the factorisations at the Gamma = 1 fold (nonzeros of L + U / the matrix's)   {load()}")
    try:
        r = json.loads(child([sys.executable, "-c", FILL], env_for(SRC, "new"))[2].splitlines()[-1])
    except RuntimeError as exc:
        print(f"not measured: {exc}")
        return
    for name, ratio in r.items():
        print(f"{name:28s} {ratio:5.2f}  target 5  {verdict(ratio <= 5.0)}")


BREAKDOWN = """
import collections, json, sys, time
import numpy, scipy.sparse.linalg as spla
import rodcont, rodcont.collocation as col, rodcont.rod as rod
spent, stack = collections.Counter(), []


def timed(label, f):  # exclusive CPU time of f under label (what it calls under another label is not its own)
    def g(*a, **k):
        t = time.process_time()
        stack.append(0.0)
        try:
            return f(*a, **k)
        finally:
            dt, inner = time.process_time() - t, stack.pop()
            spent[label] += dt - inner
            if stack:
                stack[-1] += dt
    return g


class Factors:  # a SuperLU whose solves are timed
    def __init__(self, lu):
        self._lu = lu

    def __getattr__(self, name):
        return getattr(self._lu, name)


solve = timed("sparse LU solves", lambda lu, *a, **k: lu.solve(*a, **k))
Factors.solve = lambda self, *a, **k: solve(self._lu, *a, **k)
splu = spla.splu
spla.splu = timed("sparse LU factorisations", lambda *a, **k: Factors(splu(*a, **k)))
spla.eigs = timed("ARPACK (its solves apart)", spla.eigs)
for name in ("residual", "jacobian", "_axial_quantities"):
    setattr(rod.EulerianRod, name, timed("rod pointwise kernels (residual, jacobian, axial)",
                                         getattr(rod.EulerianRod, name)))
col.Collocation.__init__ = timed("discretisations built", col.Collocation.__init__)
t = time.process_time()
rodcont.trace(float(sys.argv[1]))
print(json.dumps(dict(total=time.process_time() - t, **spent)))
"""


def section_breakdown(a, old):
    print(f"\n## where the first Gamma = 1 trace spends its CPU, and what compiled code could gain at most   {load()}")
    runs = [json.loads(child([sys.executable, "-c", BREAKDOWN, "1"], env_for(SRC, "new"))[2].splitlines()[-1])
            for _ in range(a.reps)]
    r = min(runs, key=lambda q: q["total"])
    total = r.pop("total")
    rest = total - sum(r.values())
    rest_name = "the rest (Python and numpy of engine, collocation, estimates, counts)"
    for name, v in [*sorted(r.items(), key=lambda kv: -kv[1]), (rest_name, rest)]:
        print(f"{name:62s} {v:6.3f} s  {100 * v / total:4.1f} %")
    kernels = r.get("rod pointwise kernels (residual, jacobian, axial)", 0.0)
    linear = sum(v for k, v in r.items() if k.startswith(("sparse LU", "ARPACK")))
    print(f"total {total:.3f} s; with the pointwise kernels free (compiled, bound): {total - kernels:.3f} s; "
          f"with the linear algebra free as well: {total - kernels - linear:.3f} s")
    if getattr(a, "old_gamma1", None):
        o = a.old_gamma1
        print(f"against 0ee0293's {o:.3f} s: now {total / o:.2f}, kernels free {(total - kernels) / o:.2f}, "
              f"kernels and linear algebra free {(total - kernels - linear) / o:.2f}  (target 0.50; instrumented "
              f"run, a few % slower than the trace section's)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--reps", type=int, default=None, help="repetitions (best of; default 5, --quick 3)")
    ap.add_argument("--old", default="/work/old", help="a checkout of 0ee0293 (else git archive of it)")
    ap.add_argument("--only", nargs="*", help="sections: trace floor diagram long fill breakdown drilling broomstick")
    a = ap.parse_args()
    a.reps = a.reps or (3 if a.quick else 5)
    import numpy as np
    print(f"# rodcont benchmark (issue 24), {time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}, {load()}")
    old = old_source(a.old)
    sections = dict(trace=section_trace, floor=section_floor, diagram=section_diagram, long=section_long,
                    fill=section_fill, breakdown=section_breakdown, drilling=section_drilling,
                    broomstick=section_broomstick)
    for name, fn in sections.items():
        if not a.only or name in a.only:
            fn(a, old)


if __name__ == "__main__":
    main()
