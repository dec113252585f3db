"""Helical buckling of a heavy rod in a horizontal pipe against Chen and Cheatham (evidence, not a test).

    python benchmarks/chen_cheatham.py --L 4 [--eps 1e-5] [--H 0.001] [--N 120] [--ds-max 0.5] [--out DIR]

A heavy rod (EI = 1, GJ = 0.75, w = 10, EA = 1e6: nearly inextensible) clamped at both ends on the axis of a
horizontal straight pipe of radial clearance c = 0.005 (``Wall(c, eps)``) is compressed: ``T`` (the axial
force at the far end, tension positive) is traced down from T = 10 to about -3.5 F_DP, where
F_DP = 2 sqrt(EI w / c) is Dawson and Paslay's lateral (sinusoidal) buckling load. The infinite-pipe theory
predicts the rod to lie on the bottom up to F_DP, to snake on the wall beyond it, and to wrap the wall in a
helix at F_hel = 2 sqrt(2) sqrt(EI w / c) = sqrt(2) F_DP = 1.414 F_DP (Chen, Lin and Cheatham 1990; Wu and
Juan 1995 give 2 (2 sqrt 2 - 1) sqrt(EI w / c) = (2 sqrt 2 - 1) F_DP = 1.828 F_DP on loading). The
coefficients 2.828 and 3.657 of these formulas multiply sqrt(EI w / c), not F_DP = 2 sqrt(EI w / c).

The left-right symmetry of the pipe is broken by a slight lateral bend of its axis, ``bump:H,0`` (the axis
displaced horizontally by ``H sin^2(pi x / L)``); on a perfect pipe the lateral buckling is a pitchfork. (A
weight tilted sideways does not break it: the round pipe turns the whole problem with the weight. On the
curved axis rodcont does not count unstable modes, so the stability of the traced states is not measured.)

Measured at every stored point of the trace, from the centreline's displacement ``Delta(S)`` off the pipe's
axis (on 16 samples per mesh subinterval):

* contact: the samples where the gap ``c - |Delta|`` is below ``gap_tol c`` (default 1e-2: the rod on the
  wall to 1 % of the clearance; the smoothed law keeps it within ``~eps c`` where the wall pushes with its
  force scale); a contact zone is a run of such samples;
* ``theta(S)``: the angle of ``Delta`` about the axis measured from the low side (the weight's direction
  across the axis), unwrapped along each contact zone only, the branch of the unwrap chosen so that the
  zone's sample nearest the low side has ``|theta| <= pi``;
* ``reach``: the largest ``|theta|`` over the contact zones (the rod in contact at the top of the pipe:
  ``reach = pi``); ``wrap``: the largest ``max - min`` of ``theta`` over one zone (``2 pi``: a full turn).

Located along the branch (first stored point past the criterion, then bisection in T with Newton solves at
fixed T between it and the previous point, to 1e-4 F_DP): ``T_top``, where ``reach`` first reaches pi, and
``T_turn``, where ``wrap`` first reaches 2 pi. The lateral onset is the compression at which the rod lying on
the bottom of the perfect (straight) pipe first has an unstable mode (``rodcont.stability.unstable_modes``,
bisection to 1e-4 F_DP). Prints these as multiples of F_DP, ``reach / pi`` at 1, 1.414, 1.828, 2, 2.828 F_DP
and at the end, the folds of the trace in T, its stop reason, the mesh sizes and the wall-clock time; writes
``points.csv`` (one row per stored point), ``summary.json`` and the branch file ``trace.h5`` to the output
directory.

Measured (c = 0.005, H = 0.001, eps = 1e-5 unless said): onset 1.0267 (L = 4) and 1.0064 (L = 8) F_DP. At
L = 4 the traced branch stays sinusoidal to 3.5 F_DP, with no fold and no branch point: reach / pi = 0.253,
0.370, 0.412, 0.592, 0.722 at 1.414, 1.828, 2, 2.828, 3.5 F_DP; the rod never reaches the top, T_top and
T_turn are not reached on this branch. The same within 0.003 pi for H = 0.0005 and for eps = 1e-4 (to
2 F_DP). At L = 8 the trace stopped at 1.206 F_DP (corrector diverged), reach 0.174 pi there (L = 4: 0.175).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
import warnings

import numpy as np

from rodcont.contact import Wall
from rodcont.curves import parse_reference
from rodcont.drivers.solve import first_unstable_tension, solve_equilibrium
from rodcont.drivers.trace import trace
from rodcont.rod import Jet, RodParameters
from rodcont.system import RodSystem

C = 0.005            # radial clearance
EI, W, EA = 1.0, 10.0, 1e6
CHEN_CHEATHAM = math.sqrt(2)                   # helical buckling / F_DP: 2 sqrt(2 EI w / c), infinite pipe
WU_JUAN = 2 * math.sqrt(2) - 1                  # on loading / F_DP (Wu and Juan 1995): 2 (2 sqrt 2 - 1) sqrt(EI w / c)


class Shapes:
    """The contact-angle measures of a solution (module docstring), with a system per mesh cached."""

    def __init__(self, rod, wall, curve, gap_tol, per_interval=16):
        self.rod, self.wall, self.curve = rod, wall, curve
        self.gap_tol, self.per_interval = gap_tol, per_interval
        self._systems = {}

    def system(self, breakpoints, T):
        key = np.asarray(breakpoints, float).tobytes()
        if key not in self._systems:
            if len(self._systems) > 8:
                self._systems.clear()
            self._systems[key] = RodSystem(self.rod, T=T, breakpoints=np.asarray(breakpoints, float),
                                           wall=self.wall, curve=self.curve)
        s = self._systems[key]
        s.set_value(0.0)      # phi_L = 0: the continued parameter of this system
        s.base[1] = T
        return s

    def grid(self, b):
        t = np.linspace(0.0, 1.0, self.per_interval + 1)[:-1]
        return np.concatenate([(b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), [b[-1]]])

    def measure(self, breakpoints, x, T) -> dict:
        s = self.system(breakpoints, T)
        S = self.grid(s.disc.breakpoints)
        z = (s.disc.jet_matrix(S) @ x).reshape(s.model.problem.jet_size, S.size)
        D1, D2 = z[Jet.D1[0]], z[Jet.D2[0]]
        K = s.curve.jet(S).K                                   # (K1, K2, K3) x global components x S
        g = np.asarray(self.rod.weight_direction, float)
        g1, g2 = np.einsum("an,a->n", K[0], g), np.einsum("an,a->n", K[1], g)   # low side on K1, K2
        # angle of Delta from the low side: atan2(u x Delta, u . Delta) with u = (g1, g2)
        theta = np.arctan2(g1 * D2 - g2 * D1, g1 * D1 + g2 * D2)
        gap = C - np.hypot(D1, D2)
        on = gap <= self.gap_tol * C
        reach = wrap = 0.0
        zones = []
        if on.any():
            edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
            for a, e in zip(edges[::2], edges[1::2]):
                th = np.unwrap(theta[a:e])
                low = int(np.argmin(np.abs(theta[a:e])))      # the sample nearest the low side
                th = th - 2 * math.pi * round((th[low] - theta[a + low]) / (2 * math.pi))
                zones.append((float(S[a]), float(S[e - 1]), float(np.max(np.abs(th))), float(np.ptp(th))))
                reach = max(reach, zones[-1][2])
                wrap = max(wrap, zones[-1][3])
        p = s.params(0.0)
        lib_zones = len(s.model.contact(s.disc, x, p)["zones"])
        return dict(reach=reach, wrap=wrap, zones=len(zones), lib_zones=lib_zones, min_gap=float(gap.min()),
                    zone_list=zones, N=int(s.disc.N))


def lateral_onset(rod, wall, N):
    """Compression / F_DP at which the rod on the bottom of the straight pipe first has an unstable mode."""
    F = f_dp()
    T, n = first_unstable_tension(rod, (10.0, -0.5 * F, -0.9 * F), -1.2 * F, N=N, wall=wall, tol=1e-4 * F)
    return -T / F if n else math.nan


def f_dp():
    return 2 * math.sqrt(EI * W / C)


def locate(branch, shapes, rows, key, target, tol):
    """First crossing of ``rows[i][key] >= target`` along the branch, bisected in T between the stored points.

    Returns a dict: ``T`` (nan when never reached), ``index`` of the first stored point past it, ``how``
    (``bisected``, ``interpolated`` or ``at a point``) and the unknowns there."""
    Ts = np.asarray(branch.table["T"], float)
    past = [i for i, r in enumerate(rows) if r[key] >= target]
    if not past:
        return dict(T=math.nan, index=-1, how="not reached")
    i = past[0]
    if i == 0:
        return dict(T=float(Ts[0]), index=0, how="at the start")
    a, b = i - 1, i
    va, vb = rows[a][key], rows[b][key]
    T_lin = Ts[a] + (target - va) / (vb - va) * (Ts[b] - Ts[a])
    mesh = branch.meshes[b]
    s = shapes.system(mesh, Ts[b])
    xa = s.disc.transfer(branch.coefficients[a], shapes.system(branch.meshes[a], Ts[a]).disc) \
        if branch.meshes[a].shape != mesh.shape or np.any(branch.meshes[a] != mesh) else branch.coefficients[a]
    xb = branch.coefficients[b]
    lo, hi = (float(Ts[a]), xa, va), (float(Ts[b]), xb, vb)
    chord = float(np.linalg.norm(xb - xa))
    if not (Ts[b] < Ts[a]):  # T does not decrease across the interval (a fold in it): no bisection in T
        return dict(T=float(T_lin), index=i, how="interpolated (T not monotone here)")
    for _ in range(60):
        if abs(hi[0] - lo[0]) <= tol:
            break
        T = 0.5 * (lo[0] + hi[0])
        guess = lo[1] + (T - lo[0]) / (hi[0] - lo[0]) * (hi[1] - lo[1])
        s = shapes.system(mesh, T)
        r = s.disc.newton(guess, s.params(0.0))
        if not r.converged or np.linalg.norm(r.x - guess) > chord:
            return dict(T=float(T_lin), index=i, how=f"interpolated (no Newton solution near the chord at "
                                                       f"T = {T:.6g})")
        v = shapes.measure(mesh, r.x, T)[key]
        if v >= target:
            hi = (T, r.x, v)
        else:
            lo = (T, r.x, v)
    how = "bisected"
    if hi[2] - lo[2] > 0.1 * target:
        how += f" (a jump: {lo[2]:.3f} -> {hi[2]:.3f} within {abs(hi[0] - lo[0]):.1e} in T)"
    return dict(T=0.5 * (lo[0] + hi[0]), index=i, how=how)


def reach_at(rows, load):
    """``reach / pi`` at compression ``load`` (in F_DP), interpolated between the first two stored points
    around it."""
    for r0, r1 in zip(rows, rows[1:]):
        if (r0["load"] - load) * (r1["load"] - load) <= 0 and r1["load"] != r0["load"]:
            t = (load - r0["load"]) / (r1["load"] - r0["load"])
            return (1 - t) * r0["reach_pi"] + t * r1["reach_pi"]
    return math.nan


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--L", type=float, default=4.0, help="span (default 4)")
    ap.add_argument("--eps", type=float, default=1e-5, help="smoothing of the contact law (default 1e-5)")
    ap.add_argument("--N", type=int, default=None, help="initial subintervals (default 30 L); the mesh adapts")
    ap.add_argument("--N-max", type=int, default=2000, help="largest mesh of the trace (default 2000)")
    ap.add_argument("--H", type=float, default=1e-3, help="lateral bend of the pipe axis (default 0.001)")
    ap.add_argument("--ratio", type=float, default=3.5, help="trace down to T = -ratio F_DP (default 3.5)")
    ap.add_argument("--gap-tol", type=float, default=1e-2, help="contact: gap below gap_tol c (default 1e-2)")
    ap.add_argument("--ds-max", type=float, default=0.5, help="largest continuation step (default 0.5)")
    ap.add_argument("--no-onset", action="store_true", help="skip the eigenvalue count of the lateral onset")
    ap.add_argument("--out", default=None, help="output directory (default cc_L<L>_eps<eps>_H<H>)")
    a = ap.parse_args(argv)
    N = a.N or int(round(30 * a.L))
    imperfection = f"H {a.H:g}"
    out = a.out or f"cc_L{a.L:g}_eps{a.eps:g}_H{a.H:g}"
    os.makedirs(out, exist_ok=True)
    F = f_dp()
    rod = RodParameters(EI=EI, GJ=0.75, EA=EA, w=W, L=a.L)
    wall = Wall(C, eps=a.eps)
    curve = parse_reference(f"bump:{a.H!r},0", a.L)
    print(f"L = {a.L:g}, eps = {a.eps:g}, {imperfection}, c = {C:g}, F_DP = {F:.4f}, N = {N}", flush=True)
    t0 = time.perf_counter()
    onset = math.nan
    if not a.no_onset:
        onset = lateral_onset(rod, wall, N)
        print(f"lateral onset (eigen count, straight pipe): {onset:.4f} F_DP  [{time.perf_counter() - t0:.0f} s]",
              flush=True)
    t1 = time.perf_counter()
    caught = []
    with warnings.catch_warnings(record=True) as wlist:
        warnings.simplefilter("always")
        e = solve_equilibrium(None, 0.0, rod, T=10.0, wall=wall, N=N, curve=curve)
        branch = trace(rod=rod, T=10.0, wall=wall, curve=curve, param="T", start=(e.x, 10.0, None),
                       breakpoints=e.system.disc.breakpoints, phi_L=0.0, p_range=(-a.ratio * F, 20.0),
                       direction=-1, out=os.path.join(out, "trace.h5"), overwrite=True, N_max=a.N_max,
                       ds_max=a.ds_max)
        caught = [str(w.message) for w in wlist]
    t_trace = time.perf_counter() - t1
    for m in caught:
        print(f"warning: {m}", flush=True)
    Ts = np.asarray(branch.table["T"], float)
    print(f"trace: {len(branch)} points, {branch.steps} steps, {branch.remeshes} remeshes, {t_trace:.0f} s; "
          f"stopped: {branch.stop_reason}; last T = {Ts[-1]:.4f} = {-Ts[-1] / F:.4f} F_DP", flush=True)

    shapes = Shapes(rod, wall, curve, a.gap_tol)
    rows = []
    for i in range(len(branch)):
        m = shapes.measure(branch.meshes[i], branch.coefficients[i], Ts[i])
        rows.append(dict(i=i, T=Ts[i], load=-Ts[i] / F, kind=branch.table["kind"][i], N=m["N"],
                         error=branch.table["error"][i], unstable=branch.table["unstable_modes"][i],
                         zones=m["zones"], lib_zones=m["lib_zones"],
                         min_gap=m["min_gap"], reach=m["reach"], wrap=m["wrap"],
                         reach_pi=m["reach"] / math.pi, wrap_2pi=m["wrap"] / (2 * math.pi)))
    with open(os.path.join(out, "points.csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    for r in rows[:: max(1, len(rows) // 60)] + [rows[-1]]:
        print(f"  T/F_DP {r['load']:7.4f}  N {r['N']:4d}  zones {r['zones']:3d} ({r['lib_zones']:3d} by "
              f"pressure)  reach {r['reach_pi']:.3f} pi  wrap {r['wrap_2pi']:.3f} turns  unstable {r['unstable']}"
              f"  {r['kind']}", flush=True)

    tol = 1e-4 * F
    top = locate(branch, shapes, rows, "reach", math.pi, tol)
    turn = locate(branch, shapes, rows, "wrap", 2 * math.pi, tol)
    folds = [float(-Ts[i] / F) for i, k in enumerate(branch.table["kind"]) if k == "fold"]
    bps = [float(-Ts[i] / F) for i, k in enumerate(branch.table["kind"]) if k == "branch_point"]
    Ns = [r["N"] for r in rows]
    elapsed = time.perf_counter() - t0

    def at(loc):
        return -loc["T"] / F

    unstable = [r["load"] for r in rows if r["unstable"] > 0]
    print(f"\nL = {a.L:g}, eps = {a.eps:g}, {imperfection} (F_DP = {F:.4f})")
    print(f"  lateral onset          {onset:.4f} F_DP   (Dawson-Paslay 1)")
    print(f"  T_top  (reach = pi)    {at(top):.4f} F_DP   [{top['how']}]   (Chen-Cheatham {CHEN_CHEATHAM:.3f}, "
          f"Wu-Juan {WU_JUAN:.3f})")
    print(f"  T_turn (wrap = 2 pi)   {at(turn):.4f} F_DP   [{turn['how']}]")
    print(f"  folds in T at          {', '.join(f'{v:.4f}' for v in folds) or 'none'} F_DP;"
          f" branch points {', '.join(f'{v:.4f}' for v in bps) or 'none'}")
    loads = [v for v in (1.0 + 1e-9, CHEN_CHEATHAM, WU_JUAN, 2.0, 2 * CHEN_CHEATHAM, a.ratio) if v <= -Ts[-1] / F]
    at_loads = {f"{v:.3f}": reach_at(rows, v) for v in loads}
    print("  reach / pi at load / F_DP:  " + ",  ".join(f"{k}: {v:.3f}" for k, v in at_loads.items()))
    print(f"  mesh N: start {Ns[0]}, at T_top {Ns[top['index']] if top['index'] >= 0 else '-'}, max {max(Ns)}, "
          f"end {Ns[-1]}; largest estimated error {np.nanmax(branch.table['error']):.2g}")
    print(f"  unstable modes: first > 0 at {unstable[0]:.4f} F_DP" if unstable else
          "  unstable modes: not counted (rodcont counts them on a straight reference only)")
    if branch.missed_crossings:
        print(f"  missed eigenvalue crossings (T before, T after, count before, after): {branch.missed_crossings}")
    print(f"  trace stop: {branch.stop_reason} at {-Ts[-1] / F:.4f} F_DP; warnings {len(caught)}")
    print(f"  wall clock {elapsed:.0f} s (trace {t_trace:.0f} s)", flush=True)
    summary = dict(L=a.L, eps=a.eps, H=a.H,
                   first_unstable=unstable[0] if unstable else None, missed=branch.missed_crossings,
                   reach_at=at_loads, c=C, F_DP=F, N0=N, onset=onset, T_top=at(top), T_top_how=top["how"],
                   T_turn=at(turn), T_turn_how=turn["how"], folds=folds, branch_points=bps, N_start=Ns[0],
                   N_max_used=max(Ns), N_end=Ns[-1], stop_reason=branch.stop_reason, last=-Ts[-1] / F,
                   points=len(branch), warnings=caught, time=elapsed, trace_time=t_trace, gap_tol=a.gap_tol,
                   max_error=float(np.nanmax(branch.table["error"])))
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
