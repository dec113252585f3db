"""The README's "Your own problem" table: three problems with rodcont, scipy's solve_bvp and a plain Newton tracker.

    python benchmarks/bvp_compare.py            # the table (markdown), the date and the machine's load
    python benchmarks/bvp_compare.py --uniform  # also: the uniform meshes Troesch's problem needs (slow)

Each tool gets the code a user would write (between the ``# user code`` markers below: its lines,
blank lines and comments not counted, are the table's "lines"), against the closed forms of
``tests/bvp_reference.py``:

* Bratu ``u'' + lam e^u = 0``, ``u(0) = u(1) = 0``: the fold ``lam* = 3.513830719125162``;
* Troesch ``u'' = lam sinh(lam u)``, ``u(0) = 0``, ``u(1) = 1``: ``u'(0)`` at ``lam = 10``;
* the pinned elastica with ``int cos(theta) = 1 - delta`` and the load ``P`` free: ``P`` at ``delta = 1``.

scipy and the plain tracker continue naturally (the parameter stepped, the last solution the next
guess, the step halved where the solve fails, down to 1e-8): they cannot pass a fold, only bracket it
(the table gives the last value that converged). rodcont runs the examples' calls (pseudo-arclength,
the fold located, the mesh adapting under ``max_error``). Times are wall-clock seconds of one run,
imports excluded, on a machine shared with other work (the load is printed).
"""

from __future__ import annotations

import inspect
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, os.path.join(ROOT, "tests"))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.integrate import solve_bvp

import bvp_reference as ref
import rodcont


# user code begin: rodcont bratu
def rodcont_bratu():
    bratu = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                              bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"])
    start = rodcont.bvp.solve(bratu, {"lam": 0.0}, N=4, max_error=1e-10,
                              outputs={"u_mid": lambda sol: sol.evaluate(0.5, 0)})
    stop = rodcont.Event("u(1/2) = 4", lambda pt: 4.0 - pt.data["u_mid"], stop=True)
    res = rodcont.continue_bvp(bratu, "lam", start, (0.0, 4.0), ds=0.1, ds_max=0.5, max_error=1e-10,
                               fold_error=1e-11, events=[stop])
    return res.folds["lam"][0], bool(res.folds["located"][0])
# user code end


# user code begin: rodcont troesch
def rodcont_troesch(result=False):
    troesch = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] - p[0] * np.sinh(p[0] * z[0]),
                                bc=lambda za, zb, p: np.stack([za[0], zb[0] - 1.0]), interval=(0.0, 1.0),
                                params=["lam"])
    outputs = {"slope_at_0": lambda sol: sol.evaluate(0.0, "u", 1)}
    start = rodcont.bvp.solve(troesch, {"lam": 0.0}, guess=lambda x: x, N=4, max_error=1e-8, outputs=outputs,
                              scales={"slope_at_0": 1e-6})
    res = rodcont.continue_bvp(troesch, "lam", start, (0.0, 10.0), ds=0.1, ds_max=1.0, max_error=1e-8)
    return res if result else res.table["slope_at_0"][-1]
# user code end


# user code begin: rodcont elastica
def rodcont_elastica():
    elastica = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.sin(z[0]),
                                 bc=lambda za, zb, p: np.stack([za[1], zb[1]]),
                                 integrals=lambda S, z, p: (np.cos(z[0]) - (1.0 - p[1]))[None, :],
                                 interval=(0.0, 1.0), params=["P", "delta"], free=[0])
    start = rodcont.bvp.solve(elastica, {"P": np.pi**2, "delta": 0.01}, guess=lambda s: 0.2 * np.cos(np.pi * s),
                              max_error=1e-10)
    res = rodcont.continue_bvp(elastica, "delta", start, (0.01, 1.0), ds=0.1, ds_max=0.5, max_error=1e-10)
    return res.table["P"][-1]
# user code end


# user code begin: scipy bratu
def scipy_bratu(tol=1e-8):
    x, y, lam, step = np.linspace(0, 1, 11), np.zeros((2, 11)), 0.0, 0.1
    while step > 1e-8:
        trial = lam + step
        s = solve_bvp(lambda x, y: np.vstack([y[1], -trial * np.exp(y[0])]), lambda a, b: np.array([a[0], b[0]]),  # noqa: B023 (called in this iteration)
                      x, y, tol=tol, max_nodes=100000)
        if s.success:
            x, y, lam = s.x, s.y, trial
        else:
            step /= 2
    return lam, False  # the last lam that converged: the fold bracketed, not located
# user code end


# user code begin: scipy troesch
def scipy_troesch(tol=1e-8):
    x, y, lam, step = np.linspace(0, 1, 11), np.vstack([np.linspace(0, 1, 11), np.ones(11)]), 0.0, 0.5
    while lam < 10.0 and step > 1e-8:
        trial = min(lam + step, 10.0)
        s = solve_bvp(lambda x, y: np.vstack([y[1], trial * np.sinh(trial * y[0])]),  # noqa: B023 (called in this iteration)
                      lambda a, b: np.array([a[0], b[0] - 1.0]), x, y, tol=tol, max_nodes=1000000)
        if s.success:
            x, y, lam = s.x, s.y, trial
        else:
            step /= 2
    return y[1, 0] if lam == 10.0 else math.nan
# user code end


# user code begin: scipy elastica
def scipy_elastica(tol=1e-8):
    x = np.linspace(0, 1, 11)
    y = np.vstack([0.2 * np.cos(np.pi * x), -0.2 * np.pi * np.sin(np.pi * x), x])  # theta, theta', int cos
    P, delta, step = np.array([np.pi**2]), 0.01, 0.05
    while delta < 1.0 and step > 1e-8:
        trial = min(delta + step, 1.0)
        s = solve_bvp(lambda x, y, p: np.vstack([y[1], -p[0] * np.sin(y[0]), np.cos(y[0])]),
                      lambda a, b, p: np.array([a[1], b[1], a[2], b[2] - (1.0 - trial)]), x, y, p=P, tol=tol,  # noqa: B023 (called in this iteration)
                      max_nodes=100000)
        if s.success:
            x, y, P, delta = s.x, s.y, s.p, trial
        else:
            step /= 2
    return P[0] if delta == 1.0 else math.nan
# user code end


# user code begin: newton bratu
def newton_bratu(n=2000):
    h = 1.0 / (n + 1)
    D2 = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc") / h**2
    u, lam, step = np.zeros(n), 0.0, 0.1
    while step > 1e-8:
        trial, v = lam + step, u.copy()
        for _ in range(20):
            du = spla.spsolve(D2 + sp.diags(trial * np.exp(v)), -(D2 @ v + trial * np.exp(v)))
            v += du
            if np.max(np.abs(du)) < 1e-12:
                break
        if np.max(np.abs(du)) < 1e-12 and np.all(np.isfinite(v)):
            u, lam = v, trial
        else:
            step /= 2
    return lam, False
# user code end


# user code begin: newton troesch
def newton_troesch(n=20000):
    h = 1.0 / (n + 1)
    D2 = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc") / h**2
    b = np.zeros(n)
    b[-1] = 1.0 / h**2  # u(1) = 1
    x = np.linspace(h, 1 - h, n)
    u, lam, step = x.copy(), 0.0, 0.5
    while lam < 10.0 and step > 1e-8:
        trial, v = min(lam + step, 10.0), u.copy()
        for _ in range(30):
            F = D2 @ v + b - trial * np.sinh(trial * v)
            du = spla.spsolve(D2 - sp.diags(trial**2 * np.cosh(trial * v)), -F)
            v += du
            if np.max(np.abs(du)) < 1e-12:
                break
        if np.max(np.abs(du)) < 1e-12 and np.all(np.isfinite(v)):
            u, lam = v, trial
        else:
            step /= 2
    return (-3 * 0.0 + 4 * u[0] - u[1]) / (2 * h)  # u'(0), second order
# user code end


# user code begin: newton elastica
def newton_elastica(n=2000):
    h = 1.0 / n  # nodes 0..n; theta'(0) = theta'(1) = 0 by ghost points; unknowns theta and P
    main = -2 * np.ones(n + 1)
    D2 = sp.diags([np.r_[np.ones(n - 1), 2.0], main, np.r_[2.0, np.ones(n - 1)]], [-1, 0, 1], format="csc") / h**2
    w = np.full(n + 1, h)
    w[[0, -1]] = h / 2  # trapezoid rule
    s = np.linspace(0, 1, n + 1)
    th, P, delta, step = 0.2 * np.cos(np.pi * s), np.pi**2, 0.01, 0.05
    while delta < 1.0 and step > 1e-8:
        trial, v, Q = min(delta + step, 1.0), th.copy(), P
        for _ in range(30):
            F = np.r_[D2 @ v + Q * np.sin(v), w @ np.cos(v) - (1 - trial)]
            J = sp.bmat([[D2 + sp.diags(Q * np.cos(v)), np.sin(v)[:, None]], [(-w * np.sin(v))[None, :], None]],
                        format="csc")
            d = spla.spsolve(J, -F)
            v, Q = v + d[:-1], Q + d[-1]
            if np.max(np.abs(d)) < 1e-12:
                break
        if np.max(np.abs(d)) < 1e-12 and np.all(np.isfinite(v)):
            th, P, delta = v, Q, trial
        else:
            step /= 2
    return P if delta == 1.0 else math.nan
# user code end


def user_lines() -> dict:
    """Lines of each ``# user code`` block: neither blank nor comments."""
    out, name, count = {}, None, 0
    for line in inspect.getsource(sys.modules[__name__]).splitlines():
        s = line.strip()
        if s.startswith("# user code begin:"):
            name, count = s.split(":", 1)[1].strip(), 0
        elif s == "# user code end":
            out[name], name = count, None
        elif name and s and not s.startswith("#"):
            count += 1
    return out


def timed(f):
    t = time.perf_counter()
    v = f()
    return v, time.perf_counter() - t


def table() -> list[str]:
    lines = user_lines()
    lam, slope, load = ref.bratu_fold()["lam"], ref.troesch_slope(10.0), ref.elastica_load(1.0)
    rows = []
    for tool in ("rodcont", "scipy", "newton"):
        (fold, located), t1 = timed(globals()[f"{tool}_bratu"])
        s, t2 = timed(globals()[f"{tool}_troesch"])
        P, t3 = timed(globals()[f"{tool}_elastica"])
        rows.append(dict(tool=tool, bratu=(lines[f"{tool} bratu"], "located" if located else "bracketed",
                                           abs(fold - lam), t1),
                         troesch=(lines[f"{tool} troesch"], abs(s / slope - 1), t2),
                         elastica=(lines[f"{tool} elastica"], abs(P / load - 1), t3)))
    names = {"rodcont": "rodcont (`continue_bvp`)", "scipy": "scipy `solve_bvp`, natural continuation",
             "newton": "plain Newton tracker (finite differences, natural continuation)"}
    out = ["| tool | Bratu: lines, fold, error of λ*, time | Troesch: lines, relative error of u'(0), time "
           "| elastica: lines, relative error of P(δ = 1), time |", "| --- | --- | --- | --- |"]
    for r in rows:
        b, tr, e = r["bratu"], r["troesch"], r["elastica"]
        out.append(f"| {names[r['tool']]} | {b[0]}, {b[1]}, {b[2]:.1e}, {b[3]:.2f} s | {tr[0]}, {tr[1]:.1e}, "
                   f"{tr[2]:.2f} s | {e[0]}, {e[1]:.1e}, {e[2]:.2f} s |")
    return out


def troesch_uniform(rtol: float = 1e-8, k: int = 5) -> tuple[int, int]:
    """Subintervals a uniform mesh (``k`` Gauss points) needs for ``u'(0)`` at ``lam = 10`` to ``rtol``, and
    the adaptive run's at the end (as the example's)."""
    adaptive = rodcont_troesch(result=True).solution(-1)
    slope = ref.troesch_slope(10.0)

    def error(N):
        sol = rodcont.bvp.solve(adaptive.problem, {"lam": 10.0}, guess=adaptive, mesh=np.linspace(0, 1, N + 1), k=k,
                                max_error=1e30)
        return abs(sol.evaluate(0.0, "u", 1) / slope - 1)

    lo, hi = 10, 2000  # error(lo) > rtol >= error(hi): bisection on N
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if error(mid) > rtol else (lo, mid)
    return hi, adaptive.N


def main() -> None:
    print(f"# {time.strftime('%Y-%m-%d %H:%M')}, load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores, "
          f"rodcont {rodcont.__version__}")
    for line in table():
        print(line)
    if "--uniform" in sys.argv:
        N, Na = troesch_uniform()
        print(f"troesch_uniform_N {N}")
        print(f"troesch_adaptive_N {Na}")


if __name__ == "__main__":
    main()
