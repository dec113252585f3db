"""rodcont benchmark: prints measured figures and ratios (not a test; machines are noisy).

    python benchmarks/bench.py            # all sections
    python benchmarks/bench.py --quick    # fewer repeats

Sections
1. One Newton iteration (residual + tangent + sparse LU + solve) for N = 15, 30, 60, 120 (k = 5).
2. One continuation step (predictor, corrector, tangent, outputs) for the same meshes.
3. The Gamma = 1 branch (paper values, N = 15, k = 5) from Phi = 0 through the first fold to the
   stop guard: time, steps, Newton iterations per step, time per step.
4. The same branch segment (Phi = 0 up to 13, just below the first fold) by a plain scipy
   solve_bvp Lagrangian natural continuation (benchmarks/lagrangian_bvp.py), what a user
   would otherwise write; the ratio of times.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np
import scipy.sparse.linalg as spla

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

import rodcont  # noqa: E402
from rodcont.branch import solve_equilibrium, trace  # noqa: E402


def best_of(fn, repeats: int, inner: int) -> float:
    """Best mean time per call over ``repeats`` batches of ``inner`` calls (seconds)."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(inner):
            fn()
        best = min(best, (time.perf_counter() - t) / inner)
    return best


def newton_iteration_table(quick: bool):
    print("\n## 1. One Newton iteration (residual + tangent + sparse LU + solve), k = 5, Gamma = 1, Phi = 10")
    print(f"{'N':>5} {'unknowns':>9} {'nnz':>7} {'linearise [ms]':>15} {'LU+solve [ms]':>14} {'total [ms]':>11} {'ratio to N=15':>14}")
    base = None
    rows = []
    for N in (15, 30, 60, 120):
        eq = solve_equilibrium(1.0, 10.0, N=N, k=5)
        sysm = eq.system
        d, x, p = sysm.disc, eq.x, sysm.params(10.0)
        F, J, _ = d.linearise(x, p)
        inner = 20 if quick else 50
        t_lin = best_of(lambda: d.linearise(x, p), 3 if quick else 7, inner)
        t_lu = best_of(lambda: spla.splu(J, permc_spec="NATURAL").solve(F), 3 if quick else 7, inner)
        tot = t_lin + t_lu
        base = base or tot
        rows.append((N, tot))
        print(f"{N:5d} {d.size:9d} {d.nnz:7d} {1e3 * t_lin:15.3f} {1e3 * t_lu:14.3f} {1e3 * tot:11.3f} {tot / base:14.2f}")
    return rows


def continuation_step_table(quick: bool):
    print("\n## 2. Continuation steps (predictor, corrector, tangent, outputs), Gamma = 1, Phi = 0 to 12, k = 5")
    print(f"{'N':>5} {'steps':>6} {'Newton it/step':>15} {'time/step [ms]':>15} {'ratio to N=15':>14}")
    base = None
    for N in (15, 30, 60, 120):
        stamps = []
        br = trace(1.0, N=N, k=5, max_steps=40, phi_max=12.0,
                   callback=lambda pt: stamps.append((time.perf_counter(), pt.kind)))
        regular = [t for t, kind in stamps if kind == "regular"]
        per = (regular[-1] - regular[0]) / (len(regular) - 1)  # steps only: no start, no set-up
        base = base or per
        print(f"{N:5d} {br.steps:6d} {br.newton_iterations / max(br.steps, 1):15.2f} {1e3 * per:15.3f} {per / base:14.2f}")


def gamma1_branch():
    print("\n## 3. Gamma = 1 branch, paper values, N = 15, k = 5: Phi = 0 through the first fold to the stop guard")
    trace(1.0, max_steps=5)  # warm caches (imports and first-call overheads excluded)
    times = []
    for _ in range(3):
        br = trace(1.0)
        times.append(br.elapsed)
    f = br.folds[0]
    print(f"time {min(times):.3f} s (best of 3; {', '.join(f'{t:.3f}' for t in times)})   target 0.3 s   "
          f"ratio to target {min(times) / 0.3:.2f}")
    print(f"points {len(br)}, steps {br.steps}, Newton iterations {br.newton_iterations} "
          f"({br.newton_iterations / br.steps:.2f} per step), time per step {1e3 * min(times) / br.steps:.2f} ms")
    print(f"first fold Phi = {f['phi_L']:.10f}, stretch = {f['stretch']:.10f}; stop: {br.stop_reason}")
    return br, min(times)


def lagrangian_segment():
    print("\n## 4. Phi = 0 .. 13 (just below the Gamma = 1 fold): rodcont against plain scipy solve_bvp")
    sys.path.insert(0, HERE)
    from lagrangian_bvp import natural_continuation
    trace(1.0, max_steps=3)
    br = min((trace(1.0, phi_max=13.0) for _ in range(3)), key=lambda b: b.elapsed)
    s_rc = br.table["stretch"][-1]
    print(f"rodcont (Eulerian, pseudo-arclength, N = 15, k = 5): {br.steps} steps: {br.elapsed:.3f} s; "
          f"stretch at Phi = 13: {s_rc:.12f}")
    phis = np.arange(0.0, 13.0 + 1e-9, 0.5)
    for tol in (1e-6, 1e-8):
        times = []
        for _ in range(2):
            t = time.perf_counter()
            out = natural_continuation(1.0, phis, tol=tol)
            times.append(time.perf_counter() - t)
        t_lag = min(times)
        print(f"solve_bvp (Lagrangian, natural continuation, tol {tol:g}, FD Jacobians): {len(phis)} load steps, "
              f"{out['n_solve_bvp']} calls, up to {out['max_nodes_used']} nodes: {t_lag:.3f} s; "
              f"stretch at Phi = 13: {out['stretch'][-1]:.12f} (differs from rodcont by "
              f"{abs(out['stretch'][-1] - s_rc):.1e}); ratio solve_bvp / rodcont: {t_lag / br.elapsed:.1f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print(f"# rodcont {rodcont.__version__} benchmark, {time.strftime('%Y-%m-%d')}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}")
    print(f"# OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    newton_iteration_table(args.quick)
    continuation_step_table(args.quick)
    gamma1_branch()
    lagrangian_segment()


if __name__ == "__main__":
    main()
