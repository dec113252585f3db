"""Where the helical branch of a heavy rod in a horizontal pipe ends on unloading (evidence, not a test).

    python benchmarks/helical_unloading.py --L 4 [--ratio 2] [--turns N] [--eps 1e-5] [--H 0] [--ds-max 10]
                                           [--N-max 150L] [--mem-gb 8] [--out DIR]

The rod and pipe of ``benchmarks/chen_cheatham.py`` (EI = 1, GJ = 0.75, w = 10, EA = 1e6, clamped at both
ends on the axis of a horizontal straight pipe of clearance c = 0.005, ``Wall(c, eps)``; F_DP = 2 sqrt(EI w / c)
= 89.44). The branch traced there from the sag only snakes on the wall; the helical states lie on another
branch. This script reaches that branch directly and follows it to its end:

1. a helix at Phi = 0 (clamped ends, no end rotation) and T = -ratio F_DP: a guess ``Delta = r f(S) (cos kS,
   sin kS)`` with ``r = c`` (on the wall), ``f`` ramping from 0 to 1 over ``ell`` at each clamp
   (``1 - exp(-(S/ell)^2)``), ``k = 2 pi n / L`` with ``n`` whole turns (default the nearest to Lubinski's
   pitch ``2 pi sqrt(2 EI / F)``), no twist, the axial force T and the weight shared by the clamps; solved by
   Newton with its step in ``Delta`` capped at ``cap c`` (the library's Newton with its line search on the
   max-norm residual stalls from this guess: the stiff contact law), then confirmed by the library's Newton;
2. stages: a trace in T at fixed Phi = 0 toward less compression (``rodcont.drivers.trace.run``, the mesh
   adapting, the unstable modes counted: the straight pipe, ``--H 0``, is the default for that), measured at
   every stored point with the contact-angle measures of ``chen_cheatham.Shapes`` -- ``wrap`` (turns of the
   largest contact zone about the axis) and the number of zones -- and ``winding``, the turns of the
   centreline about the axis where ``|Delta| >= c/2`` (contact or not); a stage ends at its first fold or
   branch point (the stable states end there), at the range's end or where the trace stops;
3. from a stage's last point the capped Newton at fixed T a little beyond it (``--beyond``, in F_DP): a state
   the rod may fall to (not a dynamic computation); a helix found there (wrap >= 1 turn) starts the next
   stage, anything else ends the run.

Prints the trace (every stored point), its folds and branch points in T / F_DP with the unstable-mode count on
each side, the first point with an unstable mode, the last helical point, the stop, the fallen state, and the
wall-clock times; writes ``points.csv`` and ``summary.json`` to the output directory.

Measured (c = 0.005, eps = 1e-5, straight pipe, ``--ds-max 10``; F_DP multiples of the compression):

* L = 4 from 2 F_DP (guess 6 turns, ``--N-max 600``, 2 min): a stable helix (0 unstable modes) of 5.17 turns
  in one contact zone (S = 0.247 .. 3.753). Unloaded it stays one zone to 1.3966; at 1.3946 a piece of 0.36
  turn at each end comes off (contact zones 0.26-0.54, 0.59-3.41, 3.46-3.74); branch point at 1.39046
  (unstable modes 0 before it). 0.005 F_DP beyond, Newton finds another stable helix (4.15 turns in one
  zone, winding 4.22): it stays one zone to 1.3077, sheds its end pieces at 1.3036 (0.50 turn each, 2.88
  in the middle), loses contact over the top of every turn at 1.2996 (5 zones of at most 0.93 turn; the
  centreline still winds 4.18 turns about the axis) and ends at a branch point at 1.28213 (unstable modes
  0 -> 1). 0.005 F_DP beyond, Newton falls to the snake: one zone on the bottom, reach 0.199 pi, winding 0,
  stable.
* L = 8 from 1.45 F_DP (guess 10 turns, ``--N-max 1200``, 77 s): a stable helix of 9.18 turns in one zone;
  one zone to 1.3076, end pieces (0.53 turn) off at 1.3062, 10 zones of at most 0.92 turn at 1.2987, still
  winding 9.18 turns and stable at 1.28210, where the trace stopped (a MemoryError in the error estimate of
  a new segment, the address space limited to 8 GB); 0.005 F_DP beyond, the snake (reach 0.196 pi, stable).
* L = 8 from 2 F_DP (guess 12 turns): a stable helix of 10.31 turns in two zones (S = 0.255 .. 7.488 and a
  short one, 7.664 .. 7.744: not symmetric), but its trace crawls (1.3e-4 F_DP a stored point, N = 591: 0.017
  F_DP in 150 s, with ``--ds-max`` 2 or 10); not followed to the end.
* L = 4 on the bent axis of ``chen_cheatham.py`` (``--H 0.001``, from 1.45 F_DP, 89 s; unstable modes not
  counted there): a helix of 4.17 turns; one zone to 1.3091, the piece at one end off at 1.3076, the trace
  piling up points at 1.28230 (still winding 4.18 turns: the end, a fold here) and stopping there with the
  same MemoryError; 0.005 F_DP beyond, the snake (reach 0.227 pi).
* So the helical branch at Phi = 0 ends at 1.282 F_DP for both lengths (the top of the turns lifting off
  from 1.30 F_DP), below Chen-Cheatham's sqrt(2) = 1.414 and far below Wu-Juan's 1.828 (a loading value);
  the clamped ends only shed a part-turn at each end (at 1.39 F_DP for the 5-turn helix of L = 4, at 1.30
  for the others) and do not move the end. On loading the snake does not wrap up to 3.5 F_DP
  (``chen_cheatham.py``): the two coexist, stable, from 1.28 F_DP to at least 2 F_DP.
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from chen_cheatham import CHEN_CHEATHAM, EA, EI, WU_JUAN, C, Shapes, W, f_dp  # noqa: E402

from rodcont.branch import Branch  # noqa: E402
from rodcont.contact import Wall  # noqa: E402
from rodcont.continuation import StopContinuation  # noqa: E402
from rodcont.curves import parse_reference  # noqa: E402
from rodcont.drivers.trace import TraceOptions, run  # noqa: E402
from rodcont.linalg import LU, max_norm  # noqa: E402
from rodcont.rod import Jet, RodParameters  # noqa: E402
from rodcont.stability import unstable_modes  # noqa: E402
from rodcont.system import RodSystem  # noqa: E402


def helix_guess(s: RodSystem, L: float, T: float, turns: int, ell: float, r: float = C) -> np.ndarray:
    """Unknowns of a helix of ``turns`` whole turns on the wall, ramped to the axis at the clamps."""
    k = 2 * math.pi * turns / L
    w = s.rod.w
    gK = s.model.gK if s.model.constant_frame else np.array([0.0, -1.0, 0.0])

    def f(S):
        return (1 - np.exp(-(S / ell) ** 2)) * (1 - np.exp(-((L - S) / ell) ** 2))

    return s.disc.project([lambda S: r * f(S) * np.cos(k * S), lambda S: r * f(S) * np.sin(k * S),
                           lambda S: 0 * S, lambda S: -w * gK[0] * (S - 0.5 * L),
                           lambda S: -w * gK[1] * (S - 0.5 * L), lambda S: T + 0 * S])


def capped_newton(s: RodSystem, x: np.ndarray, p: np.ndarray, cap: float, iters: int = 400,
                  tol: float = 1e-10) -> tuple[np.ndarray, bool, int]:
    """Newton with the step in (Delta1, Delta2) scaled down to at most ``cap`` (max norm); no line search."""
    idx = np.concatenate([s.disc.index[0], s.disc.index[1]])
    for it in range(1, iters + 1):
        F, J = s.disc.linearise(x, p)[:2]
        dx = LU(J).solve(-F)
        d = max_norm(dx[idx])
        lam = min(1.0, cap / d) if d > 0 else 1.0
        x = x + lam * dx
        if not np.all(np.isfinite(x)):
            return x, False, it
        if lam == 1.0 and max_norm(dx) <= tol * (1 + max_norm(x)):
            return x, True, it
    return x, False, iters


def winding(shapes: Shapes, breakpoints, x, T) -> float:
    """Turns of the centreline about the axis: the angle of ``Delta`` unwrapped along the longest run of samples
    with ``|Delta| >= c / 2`` (contact or not: a rod that passes over the top off the wall still winds)."""
    s = shapes.system(breakpoints, T)
    S = shapes.grid(s.disc.breakpoints)
    z = (s.disc.jet_matrix(S) @ x).reshape(s.model.problem.jet_size, S.size)
    D1, D2 = z[Jet.D1[0]], z[Jet.D2[0]]
    far = np.hypot(D1, D2) >= 0.5 * C
    best = 0.0
    if far.any():
        edges = np.flatnonzero(np.diff(np.concatenate([[0], far.astype(np.int8), [0]])))
        for a0, e0 in zip(edges[::2], edges[1::2]):
            th = np.unwrap(np.arctan2(D2[a0:e0], D1[a0:e0]))
            best = max(best, abs(th[-1] - th[0]) / (2 * math.pi))
    return float(best)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--L", type=float, default=4.0, help="span (default 4)")
    ap.add_argument("--ratio", type=float, default=2.0, help="start at T = -ratio F_DP (default 2)")
    ap.add_argument("--turns", type=int, default=None, help="turns of the guess (default: Lubinski's pitch)")
    ap.add_argument("--ell", type=float, default=0.3, help="ramp length of the guess at the clamps (0.3)")
    ap.add_argument("--cap", type=float, default=0.2, help="Newton step cap in Delta, times c (0.2)")
    ap.add_argument("--eps", type=float, default=1e-5, help="smoothing of the contact law (default 1e-5)")
    ap.add_argument("--H", type=float, default=0.0, help="lateral bend of the pipe axis (default 0: straight)")
    ap.add_argument("--N", type=int, default=None, help="subintervals of the start (default 40 L)")
    ap.add_argument("--N-max", type=int, default=None, help="largest mesh of the trace (default 150 L)")
    ap.add_argument("--ds-max", type=float, default=10.0, help="largest continuation step (default 10; with 2 the "
                                                               "L = 8 trace crawls, 1e-4 F_DP a point)")
    ap.add_argument("--until", type=float, default=0.3, help="trace up to T = -until F_DP (default 0.3)")
    ap.add_argument("--beyond", type=float, default=0.005, help="the fallen state: this much (F_DP) past the "
                                                                 "trace's last point (default 0.005)")
    ap.add_argument("--mem-gb", type=float, default=8.0, help="address-space limit of this process, GB (default 8: "
                                                               "an error estimate near a singular point has taken "
                                                               "23 GB at N = 2000)")
    ap.add_argument("--stages", type=int, default=8, help="at most this many stages (default 8)")
    ap.add_argument("--out", default=None, help="output directory (default helix_L<L>_r<ratio>_H<H>)")
    a = ap.parse_args(argv)
    if a.mem_gb > 0:
        import resource
        lim = int(a.mem_gb * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
    F = f_dp()
    T0 = -a.ratio * F
    N = a.N or int(round(40 * a.L))
    a.N_max = a.N_max or int(round(150 * a.L))
    turns = a.turns or max(1, round(a.L * math.sqrt(-T0 / (2 * EI)) / (2 * math.pi)))
    out = a.out or f"helix_L{a.L:g}_r{a.ratio:g}_H{a.H:g}"
    os.makedirs(out, exist_ok=True)
    rod = RodParameters(EI=EI, GJ=0.75, EA=EA, w=W, L=a.L)
    wall = Wall(C, eps=a.eps)
    curve = parse_reference(f"bump:{a.H!r},0", a.L) if a.H else None
    shapes = Shapes(rod, wall, curve, 1e-2)
    print(f"L = {a.L:g}, eps = {a.eps:g}, H = {a.H:g}, c = {C:g}, F_DP = {F:.4f}; start T = {T0:.4f} "
          f"({a.ratio:g} F_DP), guess {turns} turns, N = {N}", flush=True)
    t0 = time.perf_counter()

    # 1. the helix at Phi = 0
    s = RodSystem(rod, T=T0, N=N, wall=wall, curve=curve, param="T", phi_L=0.0)
    with np.errstate(all="ignore"):
        x, ok, its = capped_newton(s, helix_guess(s, a.L, T0, turns, a.ell), s.params(T0), a.cap * C)
        r = s.disc.newton(x, s.params(T0)) if ok else None
    if not ok or not r.converged:
        print(f"no helix found from the guess ({its} capped Newton iterations"
              + (f"; confirmation: {r.message}" if r is not None else "") + ")", flush=True)
        return 1
    x = r.x
    m0 = shapes.measure(s.disc.breakpoints, x, T0)
    n0 = unstable_modes(RodSystem(rod, T=T0, breakpoints=s.disc.breakpoints, wall=wall), x, 0.0) \
        if curve is None else -1
    t_helix = time.perf_counter() - t0
    print(f"helix at Phi = 0, T = {a.ratio:g} F_DP: {its} capped Newton iterations, wrap "
          f"{m0['wrap'] / (2 * math.pi):.3f} turns, {m0['zones']} zone(s) {[(round(z[0], 3), round(z[1], 3)) for z in m0['zone_list']]}, "
          f"unstable modes {n0}, torque {s.outputs(x, T0)['torque']:.4g}  [{t_helix:.0f} s]", flush=True)

    # 2.-3. stages: trace in T toward less compression until the first fold or branch point (or the end of
    # the range, or a stop), then the capped Newton a little beyond; a helix found there starts the next stage
    rows, stages, caught = [], [], []
    s_cur, x_cur, T_cur = s, x, T0
    t1 = time.perf_counter()
    for stage in range(a.stages):
        branch = Branch(gamma=rod.gamma(T_cur), rod=rod, N=s_cur.disc.N, k=s_cur.disc.k, param="T")
        first_row = len(rows)

        def callback(pt, branch=branch, stage=stage):
            m = shapes.measure(branch.meshes[-1], pt.x, pt.p)
            kind = str(pt.kind)
            rows.append(dict(stage=stage, T=float(pt.p), load=-float(pt.p) / F, wrap_turns=m["wrap"] / (2 * math.pi),
                             winding=winding(shapes, branch.meshes[-1], pt.x, pt.p),
                             zones=m["zones"], lib_zones=m["lib_zones"], N=m["N"],
                             unstable=int(pt.data.get("unstable_modes", -1)), kind=kind,
                             error=float(pt.data.get("error", math.nan)), torque=float(pt.data["torque"]),
                             min_gap=m["min_gap"], zone_list=m["zone_list"]))
            rw = rows[-1]
            print(f"  [{stage}] T/F_DP {rw['load']:8.5f}  wrap {rw['wrap_turns']:6.3f} turns  winding "
                  f"{rw['winding']:6.3f}  zones {rw['zones']:3d} "
                  f"({rw['lib_zones']:3d} by pressure)  N {rw['N']:5d}  unstable {rw['unstable']:2d}  {kind}"
                  f"  [{time.perf_counter() - t1:.0f} s]", flush=True)
            if kind in ("fold", "branch_point"):
                raise StopContinuation(f"{kind} at T = {pt.p:.10g}: the end of this stage")

        opts = TraceOptions(p_range=(-4.0 * F - 1.0, -a.until * F), direction=1, N_max=a.N_max, ds_max=a.ds_max)
        ts = time.perf_counter()
        with warnings.catch_warnings(record=True) as wl, np.errstate(all="ignore"):  # as trace() does
            warnings.simplefilter("always")
            try:
                run(s_cur, x_cur, T_cur, opts, branch=branch, callback=callback)
            except MemoryError:  # seen: the bordered LU of the error estimate near a singular point
                branch.stop_reason = (f"MemoryError (the error estimate's bordered LU at a new segment's start; "
                                      f"address space limited to {a.mem_gb:g} GB)")
            caught += [f"stage {stage}: {w.message}" for w in wl]
        Ts = np.asarray(branch.table["T"], float)
        srows = rows[first_row:]
        print(f"  [{stage}] trace: {len(branch)} points, {branch.remeshes} remeshes, {time.perf_counter() - ts:.0f} s; "
              f"stopped: {branch.stop_reason}", flush=True)
        last = len(branch) - 1
        sl = RodSystem(rod, T=T0, breakpoints=branch.meshes[last], wall=wall, curve=curve, param="T", phi_L=0.0)
        T_b = Ts[last] + a.beyond * F
        with np.errstate(all="ignore"):
            xb, okb, itb = capped_newton(sl, branch.coefficients[last], sl.params(T_b), a.cap * C)
            rb = sl.disc.newton(xb, sl.params(T_b)) if okb else None
        fallen = None
        if rb is not None and rb.converged:
            mb = shapes.measure(sl.disc.breakpoints, rb.x, T_b)
            nb = unstable_modes(RodSystem(rod, T=T_b, breakpoints=sl.disc.breakpoints, wall=wall), rb.x, 0.0) \
                if curve is None else -1
            fallen = dict(load=-T_b / F, wrap_turns=mb["wrap"] / (2 * math.pi), zones=mb["zones"], unstable=nb,
                          winding=winding(shapes, sl.disc.breakpoints, rb.x, T_b),
                          zone_list=mb["zone_list"], reach_pi=mb["reach"] / math.pi)
        one_zone = [r for r in srows if r["zones"] == 1 and r["wrap_turns"] >= 1]
        stages.append(dict(stage=stage, start=srows[0]["load"], start_wrap=srows[0]["wrap_turns"],
                           start_winding=srows[0]["winding"], end_winding=srows[-1]["winding"],
                           last_winding=max((r["load"], r["winding"]) for r in srows if r["winding"] < 1.0)
                           if any(r["winding"] < 1.0 for r in srows) else None,
                           start_zones=srows[0]["zones"], start_unstable=srows[0]["unstable"],
                           end=srows[-1]["load"], end_kind=srows[-1]["kind"], end_wrap=srows[-1]["wrap_turns"],
                           end_zones=srows[-1]["zones"], end_unstable=srows[-1]["unstable"],
                           before_end_unstable=srows[-2]["unstable"] if len(srows) > 1 else None,
                           first_unstable=next((r["load"] for r in srows if r["unstable"] > 0), math.nan),
                           last_one_zone=(one_zone[-1]["load"], one_zone[-1]["wrap_turns"]) if one_zone else None,
                           split=None, stop=branch.stop_reason, fallen=fallen, newton_iterations=itb,
                           time=time.perf_counter() - ts, max_error=float(np.nanmax(branch.table["error"])),
                           N_max_used=max(r["N"] for r in srows)))
        if one_zone and srows.index(one_zone[-1]) + 1 < len(srows):
            nxt = srows[srows.index(one_zone[-1]) + 1]
            stages[-1]["split"] = (nxt["load"], [(round(z[0], 3), round(z[1], 3), round(z[3] / (2 * math.pi), 3))
                                                 for z in nxt["zone_list"]])
        if fallen is None or fallen["wrap_turns"] < 1.0 or -T_b / F <= a.until:
            break
        s_cur, x_cur, T_cur = sl, rb.x, T_b
    t_trace = time.perf_counter() - t1

    # summary
    elapsed = time.perf_counter() - t0
    print(f"\nL = {a.L:g}, eps = {a.eps:g}, H = {a.H:g} (F_DP = {F:.4f}); Chen-Cheatham {CHEN_CHEATHAM:.4f}, "
          f"Wu-Juan {WU_JUAN:.4f} F_DP")
    print(f"  helix at Phi = 0, {a.ratio:g} F_DP: {m0['wrap'] / (2 * math.pi):.3f} turns in {m0['zones']} zone(s), "
          f"unstable modes {n0}")
    for g in stages:
        print(f"  stage {g['stage']}: from {g['start']:.5f} F_DP ({g['start_wrap']:.3f} turns, {g['start_zones']} zone(s), "
              f"unstable {g['start_unstable']}) to {g['end']:.5f} F_DP [{g['end_kind']}; unstable "
              f"{g['before_end_unstable']} before it; {g['end_wrap']:.3f} turns, {g['end_zones']} zone(s)]; "
              f"first unstable {g['first_unstable']:.5f}; {g['time']:.0f} s, N <= {g['N_max_used']}, "
              f"error <= {g['max_error']:.1g}")
        if g["last_one_zone"]:
            print(f"      last one-zone helix {g['last_one_zone'][0]:.5f} F_DP ({g['last_one_zone'][1]:.3f} turns)"
                  + (f"; then at {g['split'][0]:.5f}: zones (S from, S to, turns) {g['split'][1]}" if g["split"] else ""))
        print(f"      winding (centreline turns about the axis) {g['start_winding']:.3f} at the start, "
              f"{g['end_winding']:.3f} at the end"
              + (f"; first below 1 turn at {g['last_winding'][0]:.5f} F_DP" if g["last_winding"] else ""))
        if g["end_kind"] not in ("fold", "branch_point"):
            print(f"      stop: {g['stop']}")
        fb = g["fallen"]
        if fb:
            print(f"      capped Newton at {fb['load']:.5f} F_DP: {fb['wrap_turns']:.3f} turns in {fb['zones']} zone(s), "
                  f"winding {fb['winding']:.3f}, "
                  f"reach {fb['reach_pi']:.3f} pi, unstable {fb['unstable']}")
        else:
            print(f"      capped Newton {a.beyond:g} F_DP beyond: no solution ({g['newton_iterations']} iterations)")
    print(f"  warnings {len(caught)}" + "".join(f"\n    {m}" for m in caught))
    print(f"  wall clock {elapsed:.0f} s (helix {t_helix:.0f} s, stages {t_trace:.0f} s)", flush=True)
    with open(os.path.join(out, "points.csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=[k for k in rows[0] if k != "zone_list"])
        wr.writeheader()
        wr.writerows([{k: v for k, v in r.items() if k != "zone_list"} for r in rows])
    summary = dict(L=a.L, eps=a.eps, H=a.H, ratio=a.ratio, turns_guess=turns, F_DP=F,
                   start_wrap=m0["wrap"] / (2 * math.pi), start_zones=m0["zones"], start_unstable=n0,
                   stages=stages, warnings=caught, time=elapsed)
    with open(os.path.join(out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1, default=str)
    return 0


if __name__ == "__main__":
    sys.exit(main())
