"""The bordered solve on a user's finite-difference Bratu problem (issue 21 item 6); prints targets, not a test.

    python benchmarks/bordered_fd.py                 # n = 2000 .. 20000, both forms, plain loop + Tracker
    python benchmarks/bordered_fd.py --quick         # n = 2000 and 20000, unscaled form
    python benchmarks/bordered_fd.py --full-lu       # also the LU of the whole bordered matrix at n = 2000
    python benchmarks/bordered_fd.py --rod           # also the rod's located fold (a near-singular J)

The problem: ``u_{i-1} - 2 u_i + u_{i+1} + h^2 lam e^{u_i} = 0``, ``u_0 = u_{n+1} = 0`` (``--form unscaled``), or
the same divided by ``h^2`` (``scaled``), continued in ``lam`` from the lower solution at ``lam = 0.5`` through
its fold (``lam* = 3.51383...``) until ``lam`` is back at 0.5 on the upper branch. Each run is a child process
(its peak resident memory is its own). Two loops:

* ``plain``: Keller's pseudo-arclength loop written out (tangent predictor, Newton on the bordered system,
  one factorisation per iteration, the fold located by a secant on ``dlam/ds``), with the solver under test;
* ``tracker``: ``rodcont.continuation.Tracker`` with the problem's ``bordered_solver`` hook; where the Tracker
  does not call the hook (a tree without the hook) the line says so.

Figures: CPU and wall time of the continuation (imports excluded), peak memory of the process, the largest
factorisation's ``L + U`` nonzeros over the bordered matrix's own, the fold. Targets: n = 20000 in under
10 s CPU and 500 MB, time linear in n (CPU per unknown at 20000 within 1.5 times that at 2000), factors
at most 5 times the matrix.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(os.path.dirname(HERE), "src")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # BLAS threads on a loaded machine: 5 times slower
sys.path.insert(0, SRC)

import numpy as np
import scipy.sparse as sp

from rodcont.linalg import LU, BorderedSolver, bordered


class FDBratu:
    """Finite-difference Bratu, ``n`` interior points; ``linearise(u, lam) -> (F, J, F_lam)``."""

    def __init__(self, n: int, scaled: bool, solver):
        self.n, self.h2 = n, (1.0 / (n + 1)) ** 2
        self.scale = 1.0 / self.h2 if scaled else 1.0
        self.lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc")
        self.solver, self.worst_fill, self.factorisations = solver, 0.0, 0

    def residual(self, u, lam):
        return self.scale * (self.lap @ u + self.h2 * lam * np.exp(u))

    def linearise(self, u, lam):
        e = self.h2 * np.exp(u)
        J = (self.scale * (self.lap + sp.diags(lam * e))).tocsc()
        return self.scale * (self.lap @ u + lam * e), J, self.scale * e

    def bordered_solver(self, J, b, c, d):
        s = self.solver(J, b, c, d)
        self.factorisations += 1
        self.worst_fill = max(self.worst_fill, factor_nonzeros(s) / (J.nnz + 2 * J.shape[0] + 1))
        return s


def factor_nonzeros(s) -> int:
    if isinstance(s, BorderedSolver):
        return s.factor_nonzeros()
    return s._lu.L.nnz + s._lu.U.nnz


def full_lu(J, b, c, d):
    return LU(bordered(J, b, c, d))


def plain_loop(pb: FDBratu, lam0: float = 0.5, ds: float = 0.1, ds_max: float = 0.5, theta: float = 0.5):
    """Keller's pseudo-arclength continuation from the lower solution at ``lam0`` through the fold until ``lam``
    is back below ``lam0``; returns the located fold's ``lam`` and ``|dlam/ds|`` there."""
    n = pb.n
    wx, wp = theta / n, 1.0 - theta
    u = np.zeros(n)
    for _ in range(20):  # Newton at fixed lam0 (J alone: regular away from the fold)
        F, J, _ = pb.linearise(u, lam0)
        du = LU(J).solve(-F)
        u += du
        if np.max(np.abs(du)) < 1e-12:
            break
    e = np.zeros(n + 1)
    e[-1] = 1.0

    def tangent(y, ref):
        _, J, Fp = pb.linearise(y[:-1], y[-1])
        t = pb.bordered_solver(J, Fp, wx * ref[:-1], wp * ref[-1]).solve(e)
        return t / math.sqrt(wx * t[:-1] @ t[:-1] + wp * t[-1] ** 2)

    def correct(y0, t, ds, guess=None):
        """Newton on F = 0 and the arclength condition from ``guess`` (default the tangent predictor);
        None if it does not converge in 10 iterations."""
        y = y0 + ds * t if guess is None else guess
        for _ in range(10):
            F, J, Fp = pb.linearise(y[:-1], y[-1])
            g = wx * t[:-1] @ (y[:-1] - y0[:-1]) + wp * t[-1] * (y[-1] - y0[-1]) - ds
            dy = pb.bordered_solver(J, Fp, wx * t[:-1], wp * t[-1]).solve(-np.append(F, g))
            y = y + dy
            if np.max(np.abs(dy)) < 1e-10 * (1 + np.max(np.abs(y))):
                return y
        return None

    y = np.append(u, lam0)
    t = tangent(y, e)
    fold = None
    while True:
        y1 = correct(y, t, ds)
        if y1 is None:
            ds *= 0.5
            if ds < 1e-6:
                raise RuntimeError(f"the step fell below 1e-6 at lam = {y[-1]}")
            continue
        ds_step, ds = ds, min(1.5 * ds, ds_max)
        t1 = tangent(y1, t)
        if fold is None and t[-1] > 0 >= t1[-1]:  # the fold, dlam/ds = 0: Illinois on the arclength
            a, b, ta, tb, ya, yb, side = 0.0, ds_step, t[-1], t1[-1], y, y1, 0
            for _ in range(40):
                if abs(b - a) <= 1e-14 * abs(b):  # the bracket at rounding: |dlam/ds| cannot fall further
                    break
                s = b - tb * (b - a) / (tb - ta)
                ys = correct(y, t, s, ya + (s - a) / (b - a) * (yb - ya))  # the chord of the bracket
                ts = tangent(ys, t)[-1]
                if abs(ts) < 1e-10:
                    break
                if ts * tb < 0:
                    a, ta, ya, side = b, tb, yb, 0
                else:
                    ta, side = (ta / 2 if side == 1 else ta), 1
                b, tb, yb = s, ts, ys
            fold = (float(ys[-1]), abs(ts))
        y, t = y1, t1
        if fold is not None and y[-1] < lam0:
            return fold


def tracker_loop(pb: FDBratu, lam0: float = 0.5):
    from rodcont.continuation import ContinuationSettings, Tracker
    s = ContinuationSettings(ds=0.1, ds_max=0.5, p_min=lam0, p_max=4.0, max_steps=500)
    tr = Tracker(pb, np.zeros(pb.n), lam0, s)
    folds = [(q.p, abs(q.tp)) for q in tr if str(q.kind) == "fold"]
    return folds[0] if folds else (float("nan"), float("nan"))


def one(n: int, form: str, loop: str, solver: str) -> dict:
    pb = FDBratu(n, form == "scaled", BorderedSolver if solver == "block" else full_lu)
    t, c = time.perf_counter(), time.process_time()
    fold, fold_tp = plain_loop(pb) if loop == "plain" else tracker_loop(pb)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    return {"n": n, "form": form, "loop": loop, "solver": solver, "wall": wall, "cpu": cpu, "fold": fold, "fold_tp": fold_tp,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "fill": pb.worst_fill,
            "factorisations": pb.factorisations}


def run_child(n, form, loop, solver, repeats=1) -> dict | None:
    best = None
    for _ in range(repeats):
        out = subprocess.run([sys.executable, __file__, "--one", str(n), form, loop, solver],
                             capture_output=True, text=True, timeout=1800, check=False)
        if out.returncode != 0:
            print(f"  n = {n} {form} {loop} {solver}: failed ({out.stderr.strip().splitlines()[-1:]})")
            return None
        r = json.loads(out.stdout.strip().splitlines()[-1])
        best = r if best is None or r["cpu"] < best["cpu"] else best
    return best


def report(r: dict) -> None:
    if r["factorisations"] == 0:
        print(f"  n = {r['n']:6d} {r['form']:8s} {r['loop']:7s}: the Tracker does not call problem.bordered_solver "
              f"(hook not in this tree): skipped")
        return
    print(f"  n = {r['n']:6d} {r['form']:8s} {r['loop']:7s} {r['solver']:5s} {r['cpu']:7.2f} s CPU "
          f"({r['wall']:.2f} s wall)  "
          f"peak {r['peak_mb']:6.0f} MB  factors/matrix {r['fill']:6.2f}  "
          f"{r['factorisations']:4d} factorisations  fold lam {r['fold']:.13f} (|dlam/ds| {r['fold_tp']:.0e})")


def rod_fold_figures() -> None:
    """The rod's near-singular point: the located first fold of ``rodcont.trace(1.0)`` (J singular there but
    for |dp/ds| < 1e-10), the Tracker's bordered matrix with the fold's tangent row: factors, accuracy of
    the tangent solve and of a random one against extended-precision refinement, determinant signs."""
    import scipy.sparse.linalg as spla

    import rodcont
    from rodcont.linalg import scaled_smallest_singular_value
    found = []
    br = rodcont.trace(1.0, callback=lambda q: found.append(q.solver) if str(q.kind) == "fold" else None)
    s = found[0] if found else None
    if not isinstance(s, BorderedSolver):
        print("  rod fold: the Tracker's solver is not a BorderedSolver (hook not in this tree): skipped")
        return
    M = bordered(s.J, s.b, s.c, s.d)
    whole = spla.splu(M, permc_spec="NATURAL")
    lu = LU(M)
    Ml = M.tocsr().astype(np.longdouble)
    rng = np.random.default_rng(0)
    errs = []
    for f in (np.eye(1, M.shape[0], M.shape[0] - 1).ravel(), rng.standard_normal(M.shape[0])):
        ref = lu.solve(f).astype(np.longdouble)
        for _ in range(6):
            ref = ref + lu.solve((f - Ml @ ref).astype(float)).astype(np.longdouble)
        ref = ref.astype(float)
        errs.append([float(np.max(np.abs(z - ref)) / np.max(np.abs(ref))) for z in (s.solve(f), lu.solve(f))])
    print(f"  rod fold phi_L = {br.folds[0]['phi_L']:.13f}, {M.shape[0]} unknowns, J's scaled smallest singular "
          f"value {scaled_smallest_singular_value(s.J):.1e}; factors/matrix: block elimination "
          f"{s.factor_nonzeros() / M.nnz:.2f}, LU of the whole matrix {(whole.L.nnz + whole.U.nnz) / M.nnz:.2f}; "
          f"relative error (block, whole LU): tangent solve {errs[0][0]:.1e}, {errs[0][1]:.1e}; random "
          f"{errs[1][0]:.1e}, {errs[1][1]:.1e}; det sign {s.det()[0]:+d}, {lu.det()[0]:+d}; "
          f"fallbacks {s.fallbacks}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--full-lu", action="store_true", help="also the LU of the whole bordered matrix at n = 2000")
    ap.add_argument("--rod", action="store_true", help="also the rod's located fold (block against whole LU)")
    ap.add_argument("--one", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        n, form, loop, solver = args.one
        print(json.dumps(one(int(n), form, loop, solver)))
        return
    sizes = (2000, 20000) if args.quick else (2000, 5000, 10000, 20000)
    forms = ("unscaled",) if args.quick else ("unscaled", "scaled")
    repeats = 1 if args.quick else 3
    print("## Bordered solve on finite-difference Bratu through its fold (CPU time of the run, best of "
          f"{repeats}, one child process per run, load average {os.getloadavg()[0]:.2f})")
    results = {}
    for form in forms:
        for loop in ("plain", "tracker"):
            for n in sizes:
                r = run_child(n, form, loop, "block", repeats)
                if r is not None:
                    report(r)
                    results[(form, loop, n)] = r
    if args.full_lu:
        for form in forms:
            r = run_child(2000, form, "plain", "lu")
            if r is not None:
                report(r)
    if args.rod:
        rod_fold_figures()
    for (form, loop, n), r in results.items():
        if n != sizes[-1] or r["factorisations"] == 0:
            continue
        small = results.get((form, loop, sizes[0]))
        per = (r["cpu"] / n) / (small["cpu"] / sizes[0]) if small else math.nan
        ok = r["cpu"] < 10 and r["peak_mb"] < 500
        worst = max(q["fill"] for (f, lp, _), q in results.items() if (f, lp) == (form, loop))
        print(f"{form} {loop}: n = {n} in {r['cpu']:.2f} s CPU, {r['peak_mb']:.0f} MB  target < 10 s and < 500 MB  "
              f"{'met' if ok else 'NOT met'};  time per unknown {per:.2f} x that at n = {sizes[0]}  "
              f"target <= 1.5  {'met' if per <= 1.5 else 'NOT met'};  worst factors/matrix {worst:.2f}  "
              f"target <= 5  {'met' if worst <= 5 else 'NOT met'}")


if __name__ == "__main__":
    main()
