"""Equilibria and branches of the twisted heavy rod: the rod model on the generic core and tracker.

``solve_equilibrium`` loads ``phi_L`` up from 0 by natural continuation
(Newton at each load step). ``trace`` follows the branch in ``phi_L`` by
pseudo-arclength continuation through its folds, monitors the outputs of
PROBLEM.md at every point, locates folds, branch points and forced values,
and stops at the validity guard ``min d3.K3 = min_alignment``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .collocation import Collocation, NewtonResult, equidistribute
from .continuation import ContinuationSettings, Event, Point, Tracker, StopContinuation
from .rod import EulerianRod, RodParameters, PARAMS

OUTPUTS = ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "defect")


class RodSystem:
    """The discretised rod as a one-parameter problem ``F(x, p) = 0`` for the tracker.

    ``param`` names the continuation parameter (default ``phi_L``); every other
    entry of ``(phi_L, T, w, EI, GJ, EA)`` is held at ``base``.
    """

    def __init__(self, rod: RodParameters, gamma: float, N: int = 15, k: int = 5, param: str = "phi_L",
                 phi_L: float = 0.0, breakpoints=None):
        self.rod = rod
        self.model = EulerianRod(rod)
        self.disc: Collocation = self.model.discretise(N, k, breakpoints=breakpoints)
        self.model.output_evaluator(self.disc)  # set-up work outside the traces
        self.gamma = float(gamma)
        self.base = self.model.params(phi_L, T=rod.tension(gamma))
        self.index = PARAMS.index(param)
        self.param = param

    def with_mesh(self, breakpoints) -> "RodSystem":
        """The same rod and parameters on another partition (same N and k)."""
        new = RodSystem(self.rod, self.gamma, self.disc.N, self.disc.k, self.param, breakpoints=breakpoints)
        new.base = self.base.copy()
        return new

    def params(self, value: float) -> np.ndarray:
        p = self.base.copy()
        p[self.index] = value
        return p

    def residual(self, x, value):
        return self.disc.residual(x, self.params(value))

    def linearise(self, x, value):
        F, J, Fp = self.disc.linearise(x, self.params(value), [self.index])
        return F, J, Fp[0]

    def tangent(self, x, value):
        return self.linearise(x, value)[1:]

    def outputs(self, x, value) -> dict:
        p = self.params(value)
        o = self.model.outputs(self.disc, x, p)
        return dict(phi_L=float(p[0]), stretch=o["stretch"], torque=o["torque"], l0=o["l0"],
                    helical_waves=o["helical_waves"], min_alignment=o["min_alignment"],
                    defect=o["defect"], torque_spread=o["torque_spread"])


@dataclass
class Equilibrium:
    """One solved equilibrium: its outputs, the unknown vector and how Newton ended."""

    outputs: dict
    x: np.ndarray
    system: RodSystem
    newton: NewtonResult

    @property
    def converged(self) -> bool:
        return self.newton.converged

    def centreline(self, S=None):
        S = np.linspace(0, self.system.rod.L, 201) if S is None else S
        return self.system.model.centreline(self.system.disc, self.x, S)


class ConvergenceError(RuntimeError):
    pass


def solve_equilibrium(gamma: float, phi_L: float, rod: RodParameters | None = None, N: int = 15, k: int = 5,
                      load_step: float = 0.5, tol: float = 1e-10) -> Equilibrium:
    """Equilibrium at ``(gamma, phi_L)`` reached by loading ``phi_L`` up from 0 in steps.

    A step that fails is halved (down to ``load_step / 1024``). Natural
    continuation cannot pass a fold in ``phi_L``: beyond the first fold it
    reports non-convergence (``ConvergenceError``) and says where it stopped.
    """
    rod = rod or RodParameters()
    _check_finite(gamma=gamma, phi_L=phi_L, load_step=load_step)
    if load_step <= 0:
        raise ValueError("load_step must be positive")
    sysm = RodSystem(rod, gamma, N, k)
    x = sysm.model.initial_guess(sysm.disc, sysm.base[1])
    r = sysm.disc.newton(x, sysm.params(0.0), tol=tol)
    if not r.converged:
        raise ConvergenceError(f"no equilibrium found at phi_L = 0 (Gamma = {gamma:g}): {r.message}")
    x, done, step = r.x, 0.0, math.copysign(load_step, phi_L) if phi_L else load_step
    while done != phi_L:
        target = done + step
        if (target - phi_L) * math.copysign(1.0, step) > 0:
            target = phi_L
        r = sysm.disc.newton(x, sysm.params(target), tol=tol)
        if r.converged:
            x, done = r.x, target
        else:
            step *= 0.5
            if abs(step) < load_step / 1024:
                raise ConvergenceError(f"loading stopped at phi_L = {done:.10g} (a fold of the branch is "
                                       f"likely just beyond; use 'rodcont trace'): {r.message}")
    return Equilibrium(sysm.outputs(x, phi_L), x, sysm, r)


def _check_finite(**values):
    for name, v in values.items():
        if not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
            raise ValueError(f"{name} must be a finite number, got {v!r}")


# --------------------------------------------------------------------------
# Branches
# --------------------------------------------------------------------------
@dataclass
class Branch:
    """A traced branch: table of outputs per point, the special points, and the unknowns for restarts."""

    gamma: float
    rod: RodParameters
    N: int
    k: int
    table: dict = field(default_factory=lambda: {name: [] for name in OUTPUTS + ("arclength", "kind")})
    coefficients: list = field(default_factory=list)
    tangents: list = field(default_factory=list)
    meshes: list = field(default_factory=list)  # breakpoints of each point
    stop_reason: str = ""
    elapsed: float = 0.0
    steps: int = 0
    newton_iterations: int = 0

    def __len__(self) -> int:
        return len(self.coefficients)

    def add(self, pt: Point, breakpoints: np.ndarray | None = None) -> None:
        self.meshes.append(breakpoints)
        for name in OUTPUTS:
            self.table[name].append(pt.data[name])
        self.table["arclength"].append(pt.arclength)
        self.table["kind"].append(pt.kind)
        self.coefficients.append(pt.x)
        self.tangents.append(np.append(pt.tx, pt.tp))

    def column(self, name: str) -> np.ndarray:
        return np.asarray(self.table[name])

    @property
    def folds(self) -> list[dict]:
        """Fold table: outputs at each located fold, waves on either side, index along the branch."""
        kinds = self.table["kind"]
        waves = self.table["helical_waves"]
        out = []
        for i, kind in enumerate(kinds):
            if kind == "fold":
                before = next((waves[j] for j in range(i - 1, -1, -1) if kinds[j] != "fold"), waves[i])
                after = next((waves[j] for j in range(i + 1, len(kinds)) if kinds[j] != "fold"), waves[i])
                out.append(dict(index=i, phi_L=self.table["phi_L"][i], stretch=self.table["stretch"][i],
                                torque=self.table["torque"][i], l0=self.table["l0"][i],
                                waves_before=before, waves_after=after))
        return out

    @property
    def branch_points(self) -> list[int]:
        return [i for i, kd in enumerate(self.table["kind"]) if kd == "branch_point"]


def default_settings(**changes) -> ContinuationSettings:
    s = ContinuationSettings(ds=0.1, ds_min=1e-6, ds_max=0.5, p_min=-1.0, p_max=40.0, max_steps=2000,
                             newton_tol=1e-10, newton_max_iter=8, max_angle=0.3)
    for key, val in changes.items():
        setattr(s, key, val)
    return s


def trace(gamma: float, rod: RodParameters | None = None, N: int = 15, k: int = 5, phi_max: float = 40.0,
          phi_min: float = -1.0, stretch_max: float | None = None, min_alignment: float = 0.05,
          max_defect: float = 1e-2, max_steps: int = 2000, ds: float = 0.1, ds_max: float = 0.5,
          ds_min: float = 1e-6,
          forced: Sequence[float] = (), start: tuple | None = None, switch: bool = False, out: str | None = None,
          callback: Callable[[Point], None] | None = None, settings: ContinuationSettings | None = None,
          adapt: bool = False, breakpoints=None) -> Branch:
    """Trace the branch of the twisted heavy rod in ``phi_L`` from ``phi_L = 0`` (or ``start``).

    Stops at ``phi_max``/``phi_min``, at ``stretch_max``, where ``min d3.K3``
    falls to ``min_alignment`` (the validity guard of the Eulerian
    description), where the discretisation defect exceeds ``max_defect``
    (the mesh no longer resolves the shape: raise ``N``), after ``max_steps``,
    or when the step size collapses; each guard is located exactly and
    ``branch.stop_reason`` says which. ``start = (x, phi_L, direction or None)``
    restarts from a stored point, ``direction = (dx, dphi)`` the way to go on; with
    ``switch`` the start is a branch point and the trace leaves it along the other branch.
    ``out``: branch file written as the trace goes. ``breakpoints``: the partition to
    start on (default uniform, ``N`` subintervals).

    ``adapt``: when the defect reaches ``max_defect / 10`` the ``N`` breakpoints are
    moved to equidistribute it (:func:`rodcont.collocation.equidistribute`), the
    point and its tangent are transferred to the new mesh and the trace goes on
    there; each stored point keeps its own breakpoints. When moving the mesh no
    longer reduces the defect (by half), the trace goes on to the accuracy guard.
    """
    rod = rod or RodParameters()
    _check_finite(gamma=gamma, phi_max=phi_max, phi_min=phi_min, min_alignment=min_alignment, ds=ds,
                  ds_max=ds_max, max_defect=max_defect)
    if not 0 <= min_alignment < 1:
        raise ValueError("min_alignment must be in [0, 1)")
    if max_defect <= 0:
        raise ValueError("max_defect must be positive")
    if stretch_max is not None:
        _check_finite(stretch_max=stretch_max)
    sysm = RodSystem(rod, gamma, N, k, breakpoints=breakpoints)
    if settings is None:
        settings = default_settings(ds=ds, ds_max=ds_max, ds_min=ds_min, p_min=phi_min, p_max=phi_max,
                                    max_steps=max_steps, forced=tuple(forced))
    settings.validate()
    branch = Branch(gamma=float(gamma), rod=rod, N=N, k=k)
    # The guards are thresholds of judgement: located to 1e-6 of their value, not to rounding.
    events = [Event(f"validity guard: min d3.K3 reached min_alignment = {min_alignment:g}",
                    lambda q: q.data["min_alignment"] - min_alignment, stop=True, tol=1e-6),
              Event(f"accuracy guard: discretisation defect reached max_defect = {max_defect:g} "
                    f"(the mesh no longer resolves the shape: raise N, or --adapt)",
                    lambda q: 1.0 - q.data["defect"] / max_defect, stop=True, tol=1e-6)]
    if stretch_max is not None:
        events.append(Event(f"stretch_max = {stretch_max:g} reached", lambda q: stretch_max - q.data["stretch"],
                            stop=True))
    if start is None:
        x0 = sysm.model.initial_guess(sysm.disc, sysm.base[1])
        p0, t0 = 0.0, None
    else:
        x0, p0, t0 = start
        if np.asarray(x0).size != sysm.disc.size:
            raise ValueError("the start point does not fit this mesh (N, k)")
        if t0 is not None:
            t0 = (np.asarray(t0[0], float), float(t0[1]))
    writer = None
    if out is not None:
        from .branchfile import BranchWriter
        meta = dict(gamma=float(gamma), w=rod.w, EI=rod.EI, GJ=rod.GJ, EA=rod.EA, L=rod.L, N=int(N), k=int(k),
                    param="phi_L", weight_direction=np.asarray(rod.weight_direction),
                    min_alignment_guard=min_alignment, max_defect=max_defect)
        writer = BranchWriter(out, meta, sysm.disc.size, sysm.disc.breakpoints)
    recorder = _Recorder(branch, writer)
    if switch:
        if start is None or t0 is None:
            raise ValueError("switch needs a start point with its incoming direction")
        t0 = switch_direction(sysm, np.asarray(x0, float), float(p0), t0, settings)
    remesh_at = max_defect / 10 if adapt else None
    t_start = time.perf_counter()
    arc0 = 0.0
    segment = 0  # mesh segments: the first records its start point, later ones continue a stored point
    steps = iterations = 0
    tracker = last = previous = None  # last point, and the system it was on, across segments
    exact = switch
    try:
        while True:
            seg_events = list(events)
            if remesh_at is not None:
                seg_events.append(Event(REMESH, lambda q: 1.0 - q.data["defect"] / remesh_at, stop=True, tol=1e-3))
            tracker = Tracker(sysm, x0, p0, settings, monitor=sysm.outputs, events=seg_events, tangent0=t0,
                              exact_start=exact)
            try:
                first = tracker.start()
            except StopContinuation:
                if segment == 0:
                    raise
                first = None  # the moved mesh did not converge: fall back below
            moved_in_vain = segment > 0 and (first is None or first.data["defect"] > 0.5 * last.data["defect"])
            if moved_in_vain and remesh_at is not None:
                # moving the mesh no longer pays: go on where we were, to the accuracy guard
                sysm, remesh_at = previous, None
                tracker = Tracker(sysm, last.x, last.p, settings, monitor=sysm.outputs, events=events,
                                  tangent0=(last.tx, last.tp))
                first = tracker.start()
            if segment == 0:
                first.arclength = 0.0
                recorder.add(first, sysm.disc.breakpoints)
                if callback is not None:
                    callback(first)
            last = first
            for pt in tracker:
                pt.arclength += arc0
                recorder.add(pt, sysm.disc.breakpoints)
                if callback is not None:
                    callback(pt)
                last = pt
            steps += tracker.steps
            iterations += tracker.newton_iterations
            if tracker.stop_reason != REMESH:
                reason = tracker.stop_reason
                break
            # move the mesh, carry the point and its tangent over
            ev = sysm.model.output_evaluator(sysm.disc)
            d = ev.interval_defect(last.x, sysm.params(last.p))
            previous = sysm
            sysm = sysm.with_mesh(equidistribute(sysm.disc.breakpoints, d, order=sysm.disc.k + 1))
            x0, p0 = sysm.disc.transfer(last.x, previous.disc), last.p
            t0 = (sysm.disc.transfer(last.tx, previous.disc), last.tp)
            exact, arc0, segment = False, last.arclength, segment + 1
    except StopContinuation as exc:
        reason = str(exc)
    except KeyboardInterrupt:
        reason = "interrupted"
        raise
    except BaseException as exc:
        reason = f"failed: {type(exc).__name__}: {exc}"
        raise
    finally:
        branch.stop_reason = reason if "reason" in locals() else "interrupted"
        if tracker is not None and tracker.stop_reason == "":
            steps += tracker.steps
            iterations += tracker.newton_iterations
        branch.steps = steps
        branch.newton_iterations = iterations
        branch.elapsed = time.perf_counter() - t_start
        recorder.close(branch.stop_reason)
    return branch


REMESH = "remesh: the defect reached max_defect / 10"


class _Recorder:
    """Adds points to the Branch and, if any, the branch file; a fold's table row
    is completed (waves after it) when the next non-fold point arrives."""

    def __init__(self, branch: Branch, writer):
        self.branch, self.writer = branch, writer
        self.pending: list[int] = []

    def add(self, pt: Point, breakpoints: np.ndarray) -> None:
        b = self.branch
        b.add(pt, breakpoints)
        i = len(b) - 1
        if self.writer is not None:
            self.writer.add(pt.data | {"arclength": pt.arclength, "dphi_ds": pt.tp}, pt.kind, pt.x, breakpoints)
        if pt.kind == "fold":
            self.pending.append(i)
        else:
            self._flush_folds()
        if pt.kind == "branch_point" and self.writer is not None:
            self.writer.add_branch_point(i, pt.data)

    def _flush_folds(self) -> None:
        if self.writer is not None:
            by_index = {f["index"]: f for f in self.branch.folds}
            for i in self.pending:
                self.writer.add_fold(by_index[i])
        self.pending = []

    def close(self, reason: str) -> None:
        self._flush_folds()
        if self.writer is not None:
            self.writer.close(reason)


# --------------------------------------------------------------------------
# Two parameters: fold curves and branch switching
# --------------------------------------------------------------------------
CURVE_PARAMS = ("gamma", "T", "w", "EI", "GJ", "EA")


class RodSystem2:
    """The rod as a two-parameter problem ``F(x, phi_L, q) = 0`` for fold curves.

    ``q`` is ``gamma`` (``T = gamma w L``, the others fixed) or one of ``T, w,
    EI, GJ, EA`` (the others, including ``T``, fixed).
    """

    def __init__(self, rod: RodParameters, gamma: float, N: int, k: int, param: str):
        if param not in CURVE_PARAMS:
            raise ValueError(f"--param must be one of {', '.join(CURVE_PARAMS)}, got {param!r}")
        if param == "gamma" and rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: continue in T")
        self.one = RodSystem(rod, gamma, N, k)
        self.param = param
        self.index = PARAMS.index("T" if param == "gamma" else param)
        self.scale = rod.w * rod.L if param == "gamma" else 1.0  # d(entry)/dq

    def value(self) -> float:
        """``q`` at the base parameters."""
        return float(self.one.base[self.index] / self.scale)

    def params(self, phi_L, q):
        p = self.one.base.copy()
        p[0] = phi_L
        p[self.index] = q * self.scale
        return p

    def residual(self, x, phi_L, q):
        return self.one.disc.residual(x, self.params(phi_L, q))

    def tangent(self, x, phi_L, q):
        _, J, (F1, Fq) = self.one.disc.linearise(x, self.params(phi_L, q), [0, self.index])
        return J, F1, Fq * self.scale

    def outputs(self, X, q) -> dict:
        x, phi_L = X[:-1], X[-1]
        p = self.params(phi_L, q)
        o = self.one.model.outputs(self.one.disc, x, p)
        return dict(phi_L=float(phi_L), stretch=o["stretch"], torque=o["torque"], l0=o["l0"],
                    helical_waves=o["helical_waves"], min_alignment=o["min_alignment"], defect=o["defect"],
                    **{self.param: float(q)})


def fold_curve(data, fold: int, param: str, lo: float, hi: float, out: str | None = None,
               ds: float = 0.05, ds_max: float = 0.5, max_steps: int = 500, forced: Sequence[float] = (),
               callback: Callable[[Point], None] | None = None) -> dict:
    """Continue the ``fold``-th fold (from 0) of a loaded branch file in ``(phi_L, param)`` over ``[lo, hi]``.

    Minimally augmented system (:class:`rodcont.bifurcation.FoldProblem`) traced from
    the fold in both directions; ``lo`` and ``hi`` are located exactly. Returns
    ``{"points": [...], "stop_reasons": (down, up)}`` with the points ordered by the
    locus; ``out`` writes them as a branch file whose ``branch`` group also holds
    ``param``.
    """
    from .bifurcation import FoldProblem
    from .branchfile import BranchWriter

    folds = data.folds
    nf = len(folds.get("index", []))
    if not 0 <= fold < nf:
        raise ValueError(f"{data.path} has {nf} fold(s); fold {fold} (counted from 0) does not exist")
    _check_finite(lo=lo, hi=hi, ds=ds, ds_max=ds_max)
    if not lo < hi:
        raise ValueError("the range must be given as A B with A < B")
    N, k = int(data.attrs["N"]), int(data.attrs["k"])
    two = RodSystem2(data.rod, data.gamma, N, k, param)
    q0 = two.value()
    if not lo <= q0 <= hi:
        raise ValueError(f"the fold's {param} = {q0:g} is outside the range [{lo:g}, {hi:g}]")
    i = int(folds["index"][fold])
    x0, phi0 = data.branch["coefficients"][i], float(data.branch["phi_L"][i])
    # the branch tangent at the fold is (v, 0): v is the right null vector of J
    J, F1, _ = two.tangent(x0, phi0, q0)
    v0 = _fold_null_vector(J, np.asarray(F1, float), x0.size)
    fp = FoldProblem(two, x0, phi0, q0, v0)
    X0 = np.append(x0, phi0)
    parts = []
    reasons = []
    for direction in (-1, 1):
        s = ContinuationSettings(ds=ds, ds_min=min(1e-7, ds), ds_max=ds_max, direction=direction,
                                 p_min=lo if direction < 0 else -math.inf, p_max=hi if direction > 0 else math.inf,
                                 max_steps=max_steps, detect_folds=True, detect_branch_points=False,
                                 forced=tuple(forced), max_angle=0.3)
        tr = Tracker(fp, X0, q0, s, monitor=two.outputs)
        pts = []
        try:
            for pt in tr:
                pts.append(pt)
                if callback is not None:
                    callback(pt)
            reasons.append(tr.stop_reason)
        except StopContinuation as exc:
            reasons.append(str(exc))
        parts.append(pts)
    down, up = parts
    for pt in down:
        pt.arclength = -pt.arclength
    ordered = list(reversed(down[1:])) + up  # the start point once
    for pt in ordered:
        pt.data["arclength"] = pt.arclength
    if out is not None:
        meta = dict(gamma=float(data.gamma), w=data.rod.w, EI=data.rod.EI, GJ=data.rod.GJ, EA=data.rod.EA,
                    L=data.rod.L, N=N, k=k, param=param, weight_direction=np.asarray(data.rod.weight_direction),
                    source=f"{data.path}: fold {fold}")
        w = BranchWriter(out, meta, x0.size, two.one.disc.breakpoints, extra_columns=(param,) if param != "phi_L" else ())
        try:
            for pt in ordered:
                w.add(pt.data | {"dphi_ds": pt.tx[-1]}, pt.kind, pt.x[:-1])
        finally:
            w.close(f"down: {reasons[0]}; up: {reasons[1]}")
    return {"points": ordered, "stop_reasons": tuple(reasons), "param": param}


def _fold_null_vector(J, F1, n):
    """Right null vector of ``J`` at a fold: the tangent of ``[J, F_phi]`` there, x part."""
    from .continuation import bordered, factorise
    rng = np.random.default_rng(3)
    c = rng.standard_normal(n + 1)
    A = bordered(J, F1, c[:-1], c[-1])
    e = np.zeros(n + 1)
    e[-1] = 1.0
    t = factorise(A).solve(e)
    return t[:-1]


def switch_direction(sysm: RodSystem, x: np.ndarray, phi_L: float, direction: tuple, settings: ContinuationSettings):
    """Direction of the other branch at a branch point of ``sysm`` (incoming direction given)."""
    from .bifurcation import bifurcating_direction
    F, J, Fp = sysm.linearise(x, phi_L)
    tr = Tracker(sysm, x, phi_L, settings)
    tx, tp = bifurcating_direction(J, Fp, np.asarray(direction[0], float), float(direction[1]), tr.wx, tr.wp)
    return tx, tp


def point_system(data, i: int, _cache: dict = {}) -> RodSystem:
    """The :class:`RodSystem` a stored point ``i`` of a loaded branch file lives on (its own mesh)."""
    b = np.asarray(data.point(i)["breakpoints"], float)
    key = (data.path, float(data.gamma), b.tobytes(), int(data.attrs["k"]))
    if key not in _cache:
        if len(_cache) > 32:
            _cache.clear()
        _cache[key] = RodSystem(data.rod, data.gamma, N=b.size - 1, k=int(data.attrs["k"]), breakpoints=b)
    return _cache[key]
