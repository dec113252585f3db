"""Trace one branch of the rod: in ``phi_L`` (the end rotation) or in any rod parameter.

The driver runs the generic tracker in *segments*: a segment is one mesh. It
watches the estimated error of every point (:class:`Accuracy`); when the error
grows past ``max_error / 100`` the mesh is rebuilt for the solution
(:func:`rodcont.mesh.adapted_mesh`: more or fewer subintervals, placed where
the residual concentrates), the last point and its tangent are carried over,
and a new segment starts there. A point whose error exceeds ``max_error`` is
never stored: the mesh is refined and the step retried, or, when the mesh
may not grow (``adapt=False`` or ``N_max`` reached), the trace stops there
(the accuracy guard). The validity guard (``min d3.K3 = min_alignment``: the
rod about to fold back over the reference curve), ``stretch_max`` and the
parameter bounds are located exactly by the tracker.

Every guard and bound is also checked at the first point: a start already
outside them is refused (``ValueError``), one on a bound and heading out of
it stops at once.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
import warnings
from dataclasses import asdict, dataclass, fields
from typing import Callable, Sequence

import numpy as np

from ..branch import Branch
from ..continuation import (ContinuationSettings, Detector, Event, Finding, Kind, Point, Stop, StopContinuation,
                            StopReason, Tracker)
from ..linalg import HeapTrimmer, scaled_smallest_singular_value
from ..mesh import ErrorEstimator, adapted_mesh, halved
from ..rod import RodParameters
from ..system import SYSTEM_PARAMS, RodSystem, check_number
from .solve import check_tension


class TraceError(ValueError):
    """A trace that cannot start (the message says why, in one line)."""


@dataclass
class TraceOptions:
    """Every knob of a trace, named once, with its default; checked when made.

    ``max_error``: the accuracy guard, on the estimated error of the stored
    outputs and centreline (relative; :class:`rodcont.mesh.ErrorEstimator`).
    ``adapt``: rebuild the mesh when the error passes ``max_error / 100``
    (up to ``N_max`` subintervals); ``False`` keeps the first mesh.
    ``p_range``: bounds of the continued parameter when it is not ``phi_L``.
    ``fold_error``: a fold whose estimated error is larger is located again on
    a mesh refined for it (with ``adapt``).
    """

    phi_max: float = 40.0
    phi_min: float = -1.0
    stretch_max: float | None = None
    min_alignment: float = 0.05
    max_error: float = 1e-6
    max_steps: int = 2000
    ds: float = 0.1
    ds_max: float = 0.5
    ds_min: float = 1e-6
    forced: Sequence[float] = ()
    adapt: bool = True
    N_max: int = 400
    p_range: tuple | None = None
    direction: int = 1
    fold_error: float = 1e-9

    def __post_init__(self):
        for name in ("phi_max", "phi_min", "ds", "ds_max", "ds_min", "max_error", "min_alignment", "fold_error"):
            setattr(self, name, check_number(name, getattr(self, name)))
        self.max_steps = check_number("max_steps", self.max_steps, integer=True)
        self.N_max = check_number("N_max", self.N_max, integer=True)
        self.direction = check_number("direction", self.direction, integer=True)
        if self.stretch_max is not None:
            self.stretch_max = check_number("stretch_max", self.stretch_max)
        if not isinstance(self.adapt, (bool, np.bool_)):
            raise TypeError(f"adapt must be True or False, got {self.adapt!r}")
        if not isinstance(self.forced, (list, tuple, np.ndarray)):
            raise TypeError(f"forced must be a sequence of numbers, got {self.forced!r}")
        self.forced = tuple(check_number("forced", v) for v in self.forced)
        if self.p_range is not None:
            if not isinstance(self.p_range, (list, tuple)) or len(self.p_range) != 2:
                raise TypeError(f"p_range must be a pair (lo, hi), got {self.p_range!r}")
            lo, hi = (check_number("range", v) for v in self.p_range)
            if not lo < hi:
                raise ValueError(f"the range must be given as A B with A < B, got {lo:g} {hi:g}")
            self.p_range = (lo, hi)
        checks = [
            (self.phi_min < self.phi_max, "phi_min must be below phi_max"),
            (0 <= self.min_alignment < 1, "min_alignment must be in [0, 1)"),
            (self.max_error > 0, "max_error must be positive"),
            (self.fold_error > 0, "fold_error must be positive"),
            (self.max_steps >= 1, "max_steps must be >= 1"),
            (self.N_max >= 1, "N_max must be >= 1"),
            (self.direction in (1, -1), "direction must be +1 or -1"),
            (0 < self.ds_min <= self.ds <= self.ds_max,
             f"need 0 < ds_min <= ds <= ds_max, got {self.ds_min:g}, {self.ds:g}, {self.ds_max:g}"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(msg)

    def as_dict(self) -> dict:
        return asdict(self)


OPTION_NAMES = tuple(f.name for f in fields(TraceOptions))
# branch-table columns of a trace inside a conduit (rodcont.contact): the narrowest gap c - |Delta|,
# the integral of the wall force, the number of contact zones
CONTACT_COLUMNS = ("min_gap", "side_force", "contact_zones")


# --------------------------------------------------------------------------
# Accuracy: estimated error of each point, measured where it matters
# --------------------------------------------------------------------------
class Accuracy:
    """The estimated error of each point, cheap where it is small.

    The full estimate (one Newton step in the richer space) costs a few
    steps; between two of them the error is taken proportional to the defect
    (the residual between collocation points, computed at every point
    anyway), with the ratio of the last measurement. Before the first
    measurement on a mesh the ratio is a pessimistic prior, ``PRIOR = 1e-2``
    (measured along the paper's branches it is 1e-6 to 1e-4): a mesh that
    obviously resolves the solution is not measured at all. It is measured at
    every fold, branch point and event, whenever the defect has changed
    sixteenfold since (or doubled, once the guess is within a fiftieth of the
    adaptation threshold), every ``every`` points, and whenever the guess
    comes within half of the threshold.
    """

    PRIOR = 1e-2

    def __init__(self, max_error: float, every: int = 25):
        self.max_error = max_error
        self.trigger = max_error / 10.0
        self.every = every
        self.estimators: dict = {}
        self.ratio = None
        self.defect = None
        self.since = 0
        self.measurements = 0

    def reset(self) -> None:
        self.ratio = self.defect = None

    def estimator(self, system: RodSystem) -> ErrorEstimator:
        key = id(system)
        if key not in self.estimators:
            if len(self.estimators) > 4:
                self.estimators.clear()
            self.estimators[key] = (system, ErrorEstimator(system))
        return self.estimators[key][1]

    def measure(self, system: RodSystem, pt: Point) -> float:
        e = self.estimator(system).estimate(pt.x, pt.p, (pt.tx, pt.tp))
        d = max(float(pt.data.get("defect", 0.0)), 1e-300)
        self.ratio, self.defect, self.since = e / d, d, 0
        self.measurements += 1
        pt.data["error"] = e
        return e

    def __call__(self, system: RodSystem, pt: Point) -> float:
        d = max(float(pt.data.get("defect", 0.0)), 1e-300)
        self.since += 1
        special = pt.kind not in (Kind.REGULAR, Kind.START)
        if self.ratio is None:  # nothing measured on this mesh yet: the pessimistic prior
            e = self.PRIOR * d
            if special or e > self.trigger / 2:
                return self.measure(system, pt)
            pt.data["error"] = e
            return e
        e = self.ratio * d
        drift = d > 16 * self.defect or d < self.defect / 16
        if (special or drift or self.since >= self.every or e > self.trigger / 2
                or (d > 2 * self.defect and e > self.trigger / 50)):
            return self.measure(system, pt)
        pt.data["error"] = e
        return e


#: Seconds between returns of the C heap's free pages to the system in a trace (None: never); see
#: :class:`rodcont.linalg.HeapTrimmer`.
TRIM_INTERVAL: float | None = 0.25


class StabilityCount:
    """The number of unstable modes of each stored point (:func:`rodcont.stability.unstable_modes`).

    The count of divergent modes changes only where the Jacobian at fixed
    ``phi_L`` is singular: at folds and branch points. It is computed (an
    eigenproblem, a few ms) at the first point, at every special point, at the
    first regular point after one, and every ``every`` points as a check;
    other points carry the last count. In a trace of another parameter at
    fixed ``phi_L`` the controls are the same (``Phi`` and ``T`` imposed), so it
    is counted there too. ``-1`` where it is not defined (a curved reference
    curve).

    A check that finds another count with no special point since means that
    eigenvalues crossed zero unseen: the branch-point detector watches the
    sign of a determinant, which an even number of crossings in one step
    (a symmetric and an antisymmetric mode at nearly the same load: lateral
    buckling in a pipe) leaves unchanged. That is reported in ``missed``
    (and warned): ``(parameter before, parameter after, count before, count after)``.
    """

    def __init__(self, every: int = 50):
        self.every = every
        self.last = None
        self.fresh = True
        self.since = 0
        self.ref = None       # (count, parameter) at the last counted non-singular point
        self.crossings = 0    # folds and branch points located since then
        self.missed: list = []
        self.k = 8            # eigenvalues asked of ARPACK: the last count's (it grows along a branch)

    def __call__(self, system: RodSystem, pt: Point) -> int:
        if not system.straight:
            pt.data["unstable_modes"] = -1
            return -1
        self.since += 1
        special = pt.kind not in (Kind.REGULAR,)
        if self.last is None or self.fresh or special or self.since >= self.every:
            from ..stability import spectrum
            if system.param == "phi_L":
                at, phi = system, pt.p
            else:  # the point's parameters as the base of a Phi-system (same controls)
                at = RodSystem.__new__(RodSystem)
                at.__dict__.update(system.__dict__)
                at.base, at.param, at.index, at.scale = system.params(pt.p), "phi_L", 0, 1.0
                phi = float(at.base[0])
            try:
                sp = spectrum(at, pt.x, phi, k=self.k)
                n = int(sp.unstable)
                self.k = max(sp.k, 8)
            except Exception as exc:  # noqa: BLE001 - an eigensolver failure is a missing count, said so
                raise RuntimeError(f"stability count failed at {system.param} = {pt.p:.10g}: {exc}") from exc
            if pt.kind in (Kind.FOLD, Kind.BRANCH_POINT):
                self.crossings += 1  # singular here: its count is not a reference
            elif pt.kind == Kind.START and self.ref is None:
                pass  # a trace may start at a fold or a branch point (a restart, a switch): not a reference
            else:
                if self.ref is not None and abs(n - self.ref[0]) > self.crossings:
                    self.missed.append((self.ref[1], float(pt.p), self.ref[0], n))
                    import warnings
                    warnings.warn(f"the number of unstable modes changed from {self.ref[0]} to {n} between "
                                  f"{system.param} = {self.ref[1]:.10g} and {pt.p:.10g} across "
                                  f"{self.crossings} located fold(s) or branch point(s): more eigenvalues "
                                  f"crossed zero than were seen (the branch-point test watches a determinant's "
                                  f"sign, which two crossings in one step leave unchanged); "
                                  + ("here the rod is symmetric about its axis and its eigenvalues cross in "
                                     "pairs: a weight across the axis, however small, separates them"
                                     if _symmetric_about_axis(system) else
                                     "trace that interval with a smaller --ds-max to separate them"
                                     + "; or the trace went on along another branch close to its own (seen "
                                       "in T on a rod pressed on a wall, past a branch point): a second trace "
                                       "with other steps shows which"),
                                  RuntimeWarning, stacklevel=2)
                self.ref, self.crossings = (n, float(pt.p)), 0
            self.last, self.since = n, 0
            self.fresh = special and (pt.kind != Kind.START or self.ref is None)
        pt.data["unstable_modes"] = self.last
        return self.last


# --------------------------------------------------------------------------
# Starts
# --------------------------------------------------------------------------
def straight_seed(rod: RodParameters, T: float, phi_L: float, N: int = 15, k: int = 5,
                  breakpoints=None) -> tuple[RodSystem, np.ndarray]:
    """A solution of the heavy rod near the straight twisted state at ``phi_L`` (and tension ``T``).

    The weightless straight state is exact for every ``phi_L``; it is continued
    in ``w`` from 0 to the rod's weight at fixed ``phi_L`` and ``T``
    (pseudo-arclength, so a fold in ``w`` is passed; the homotopy must reach
    the rod's weight without leaving the Eulerian domain). Raises
    :class:`TraceError` when it cannot.
    """
    sysw = RodSystem(rod, T=T, N=N, k=k, param="w", phi_L=phi_L, breakpoints=breakpoints)
    x0 = sysw.straight_state(phi_L)
    if rod.w == 0:
        return sysw, x0
    s = ContinuationSettings(ds=0.2 * rod.w, ds_min=1e-9 * rod.w, ds_max=rod.w, p_min=-0.5 * rod.w, p_max=rod.w,
                             max_steps=400, detect_branch_points=False, detect_fold_pairs=False)
    guard = Event("left the Eulerian domain", lambda q: q.data["min_alignment"] - 0.05, stop=True)
    tr = Tracker(sysw, x0, 0.0, s, monitor=sysw.outputs, events=[guard])
    last = None
    try:
        for pt in tr:
            last = pt
    except StopContinuation as exc:
        raise TraceError(f"no start near the straight state at phi_L = {phi_L:g}: {exc}") from None
    if last is None or last.kind != Kind.BOUND or abs(last.p - rod.w) > 1e-9 * rod.w:
        why = tr.stop_reason or "it did not reach the rod's weight"
        raise TraceError(f"no start near the straight state at phi_L = {phi_L:g}: the weight homotopy "
                         f"stopped at w = {last.p if last else 0.0:.6g} ({why})")
    return sysw, last.x


def switch_direction(sysm: RodSystem, x: np.ndarray, value: float, direction: tuple, theta: float = 0.5):
    """Direction of the other branch at a branch point of ``sysm`` (incoming direction given)."""
    from ..bifurcation import bifurcating_direction
    _, J, Fp = sysm.linearise(x, value)
    n = x.size
    sx, sp = sysm.arclength_scale()
    tx, tp = bifurcating_direction(J, Fp, np.asarray(direction[0], float), float(direction[1]),
                                   theta / n / sx**2, (1.0 - theta) / sp**2)
    return tx, tp


# --------------------------------------------------------------------------
# Recording
# --------------------------------------------------------------------------
class Recorder:
    """Adds points to a :class:`Branch` and, if any, to a branch-file group; publishes
    the file on every special point and at least every second."""

    def __init__(self, branch: Branch, writer=None, group=None, contact: "_ContactRows | None" = None,
                 thin: int = 1):
        """``thin = M > 1``: the branch in memory keeps what a file written with ``store_every = M`` keeps
        (the solution of every M-th point, of the special points and of the last; tangents at the special
        points and the last), so a long trace's memory does not grow with every point's unknowns."""
        self.branch, self.writer, self.group, self.contact = branch, writer, group, contact
        self.thin = int(thin)

    def add(self, pt: Point, breakpoints: np.ndarray) -> int:
        if self.thin > 1 and len(self.branch):
            # the previous point is no longer the last (its contact rows are computed: fill ran at its add)
            self.branch.thin(len(self.branch) - 1, self.thin)
        i = self.branch.add(pt, breakpoints)
        if self.writer is not None:
            row = dict(pt.data)
            row["arclength"] = pt.arclength
            row["dphi_ds"] = self.branch.table["dphi_ds"][-1]
            row.setdefault("error", np.nan)
            self.writer.add_point(self.group, row, str(pt.kind), pt.located, pt.x,
                                  np.append(pt.tx, pt.tp), breakpoints)
            if self.contact is not None:
                self.contact.fill(self.branch)
            if pt.kind not in (Kind.REGULAR,) or self.writer.due():
                self.sync()
                self.writer.flush()
        return i

    def sync(self) -> None:
        if self.writer is not None:
            bps = [dict(index=i, phi_L=self.branch.table["phi_L"][i], stretch=self.branch.table["stretch"][i])
                   for i in self.branch.branch_points]
            self.group.set_special(self.branch.folds, bps)


# --------------------------------------------------------------------------
# The driver
# --------------------------------------------------------------------------
@dataclass
class _Segment:
    system: RodSystem
    x: np.ndarray
    p: float
    tangent: tuple | None
    exact: bool = False
    # the start is a point not yet stored (a step's end, re-converged on the new mesh): store it, at this
    # arclength; otherwise the start is the last stored point, converged again
    record_at: float | None = None


def run(system: RodSystem, x0: np.ndarray, p0: float, options: TraceOptions, tangent0=None, exact: bool = False,
        branch: Branch | None = None, recorder: Recorder | None = None,
        callback: Callable[[Point], None] | None = None, settings: ContinuationSettings | None = None) -> Branch:
    """Trace from ``(x0, p0)`` on ``system`` (its parameter continued) with ``options``; fills ``branch``.

    ``tangent0``: the direction to leave by (``(tx, tp)``), else ``options.direction``
    in the parameter. ``exact``: ``(x0, p0)`` is a solution used as is (branch switching).
    """
    o = options
    rod = system.rod
    if branch is None:
        branch = Branch(gamma=system.gamma if rod.w > 0 else math.nan, rod=rod, N=system.disc.N, k=system.disc.k,
                        param=system.param)
    recorder = recorder or Recorder(branch)
    if system.param == "phi_L":
        p_min, p_max = o.phi_min, o.phi_max
    elif o.p_range is not None:
        p_min, p_max = o.p_range
    else:
        raise TraceError(f"a trace in {system.param} needs its range (p_range / --range A B)")
    if settings is None:
        settings = ContinuationSettings(ds=o.ds, ds_min=o.ds_min, ds_max=o.ds_max, p_min=p_min, p_max=p_max,
                                        max_steps=o.max_steps, direction=o.direction, forced=tuple(o.forced))
    events = [Event(f"validity guard: min d3.K3 reached min_alignment = {o.min_alignment:g} (the rod is about "
                    f"to fold back over the reference curve: the Eulerian description ends)",
                    lambda q: q.data["min_alignment"] - o.min_alignment, stop=True, tol=1e-6),
              Event("the stretch factor reached 0 (compressed through zero length: not physical)",
                    lambda q: q.data["alpha_min"], stop=True, tol=1e-6)]
    # inside a conduit: contact onset, lift-off, merges and splits (ZoneChangeDetector, per segment)
    if o.stretch_max is not None:
        events.append(Event(f"stretch_max = {o.stretch_max:g} reached",
                            lambda q: o.stretch_max - q.data["stretch"], stop=True))
    accuracy = Accuracy(o.max_error)
    stability = StabilityCount()
    stability.missed = branch.missed_crossings
    trim_heap = HeapTrimmer(TRIM_INTERVAL)
    t_start = time.perf_counter()
    seg = _Segment(system, np.asarray(x0, float), float(p0), tangent0, exact)
    segments = 0
    start_attempts = 0
    remeshes_here = 0  # remeshes since the last stored point: more than a few means no progress
    failed_remeshes = 0
    last_recorded: tuple | None = None  # (point, system) of the last stored point
    reason = StopReason(Stop.START_FAILED, "not started")
    steps = iterations = 0
    step_in_use = None  # the step size reached before a remesh: a new segment goes on with it
    try:
        while True:
            sysm = seg.system
            tracker = Tracker(sysm, seg.x, seg.p, settings, monitor=sysm.outputs, events=events,
                              tangent0=seg.tangent, exact_start=seg.exact)
            tracker.unlocated = branch.unlocated
            if sysm.wall is not None:
                tracker.detectors.append(ZoneChangeDetector(sysm))
            if step_in_use is not None:
                # not the initial ds: where a stiff stretch forced small steps, a fresh segment that
                # starts with ds = 0.1 leaps past it, onto another branch (seen at a contact onset)
                tracker.ds = step_in_use
            try:
                first = tracker.start()
            except StopContinuation as exc:
                if last_recorded is None:
                    # a contact on a mesh too coarse for it is the usual cause in a conduit (the 1 km well
                    # at the default N = 15, 61 with its stations: elements of 16 m in a 5 cm clearance;
                    # N = 200 starts)
                    advice = f" (N = {sysm.disc.N} may be too coarse for the contact: raise --N)" \
                        if sysm.wall is not None else ""
                    raise TraceError(str(exc) + advice) from None
                # the adapted mesh did not converge: from the last stored point, halve every
                # subinterval of its mesh instead (a nested space: the point carries over exactly)
                failed_remeshes += 1
                pt, old = last_recorded
                if failed_remeshes > 3 or old.disc.N * 2 > o.N_max:
                    reason = StopReason(Stop.NO_CONVERGENCE, f"accuracy guard: no converged solution on a refined mesh "
                                                    f"at p = {pt.p:.10g} ({exc})")
                    break
                new = old.with_mesh(old.conform(halved(old.disc.breakpoints)))
                seg = _Segment(new, new.disc.transfer(pt.x, old.disc), pt.p,
                               (new.disc.transfer(pt.tx, old.disc), pt.tp))
                accuracy.reset()
                continue
            steps += tracker.steps
            if tracker.start_on_fold and last_recorded is None:
                warnings.warn(f"the start is a fold in {sysm.param} (d{sysm.param}/ds = 0 there): {sysm.param} moves "
                              f"the same way on both sides, so the direction asked for cannot choose; the trace "
                              f"follows one side (its other side: the same command with the other --direction)",
                              RuntimeWarning, stacklevel=2)
            err = accuracy(sysm, first)
            if err > accuracy.trigger and o.adapt and start_attempts < 6 and sysm.disc.N < o.N_max:
                start_attempts += 1
                seg = dataclasses.replace(_remesh(sysm, first, err, accuracy, o), record_at=seg.record_at)
                continue
            if err > o.max_error:
                if last_recorded is None:
                    raise TraceError(f"accuracy guard already violated at the start: estimated error "
                                     f"{err:.2g} > max_error = {o.max_error:g} with N = {sysm.disc.N}"
                                     + ("" if o.adapt else " (the mesh is fixed: raise N or let it adapt)")
                                     + ("" if sysm.disc.N < o.N_max else f" (N_max = {o.N_max} reached)"))
                why = (f"N_max = {o.N_max} reached" if sysm.disc.N >= o.N_max or not o.adapt
                       else f"{start_attempts} refinements did not bring it down")
                reason = StopReason(Stop.EVENT, f"accuracy guard: estimated error {err:.2g} > max_error = "
                                                f"{o.max_error:g} at p = {first.p:.10g} (N = {sysm.disc.N}; {why})")
                break
            start_attempts = 0
            if last_recorded is None:
                first.arclength = 0.0
                why = tracker._check_start(first)
                if why is not None:
                    raise TraceError(f"cannot start there: {why.message}")
                stability(sysm, first)
                recorder.add(first, sysm.disc.breakpoints)
                last_recorded = (first, sysm)
                if callback is not None:
                    callback(first)
            elif seg.record_at is not None:
                first.arclength, first.kind = seg.record_at, Kind.REGULAR
                stability(sysm, first)
                recorder.add(first, sysm.disc.breakpoints)
                last_recorded = (first, sysm)
                if callback is not None:
                    callback(first)
            else:
                first.arclength = last_recorded[0].arclength
            next_seg = None
            tracker.current = first
            arc0 = first.arclength
            for pt in tracker:
                pt.arclength += arc0
                err = accuracy(sysm, pt)
                if (pt.kind == Kind.FOLD and err > o.fold_error and o.adapt and sysm.disc.N < o.N_max
                        and remeshes_here < 3):
                    # locate this fold again on a mesh refined for it
                    remeshes_here += 1
                    base = last_recorded[0]
                    next_seg = _remesh(last_recorded[1], base, accuracy.measure(last_recorded[1], base),
                                       accuracy, o, at_least=err, target=o.fold_error / 10, ahead=(sysm, pt))
                    break
                if err > o.max_error:
                    if o.adapt and sysm.disc.N < o.N_max and remeshes_here < 4:
                        remeshes_here += 1
                        base = last_recorded[0]
                        if base.kind == Kind.BRANCH_POINT and pt.kind == Kind.REGULAR:
                            # not from the branch point: there the bordered matrix is singular, and a segment
                            # started on it went on along the other branch (a compressed rod on a wall, in T).
                            # From this step's end instead, on the branch, stored once converged on the mesh
                            next_seg = dataclasses.replace(
                                _remesh(sysm, pt, err, accuracy, o, at_least=err), record_at=pt.arclength)
                            break
                        next_seg = _remesh(last_recorded[1], base, accuracy.measure(last_recorded[1], base),
                                           accuracy, o, at_least=err, ahead=(sysm, pt))
                        break
                    reason = StopReason(Stop.EVENT, f"accuracy guard: estimated error {err:.2g} > max_error = "
                                                    f"{o.max_error:g} at p = {pt.p:.10g}"
                                                    + ("" if o.adapt else " (the mesh is fixed: raise N or let it adapt)")
                                                    + ("" if sysm.disc.N < o.N_max else
                                                       f" (N_max = {o.N_max} reached)")
                                                    + (" (refining the mesh did not help)" if remeshes_here >= 4 else ""))
                    break
                stability(sysm, pt)
                recorder.add(pt, sysm.disc.breakpoints)
                trim_heap()
                last_recorded = (pt, sysm)
                remeshes_here = 0
                if callback is not None:
                    callback(pt)
                # not at a point where the trace stops (a guard, a bound: the tracker's stop is set when it
                # hands that point over): a new segment from there would start past the guard and never see it
                # cross again (seen: the validity guard passed on a deep sag, L = 10). Nor at a special point
                # whose location failed: it is near a singular point, where a new segment's first steps
                # diverge at every size (seen: a helix in a pipe, N = 60, at its branch point Phi = 16.46);
                # the step's end follows at once and is refined from instead. Nor at a branch point, where the
                # bordered matrix of the new segment's start and first step is singular: its first step went
                # on along the other branch (a compressed rod on a wall, in T, eps = 1e-4: the trace ended
                # with one contact zone instead of two)
                if (err > accuracy.trigger and o.adapt and sysm.disc.N < o.N_max and tracker.stop is None
                        and pt.located and pt.kind != Kind.BRANCH_POINT):
                    next_seg = _remesh(sysm, pt, err, accuracy, o)
                    break
            steps += tracker.steps
            iterations += tracker.newton_iterations
            segments += 1
            step_in_use = tracker.ds
            if next_seg is not None:
                seg = next_seg
                branch.remeshes += 1
                continue
            if tracker.stop is not None:
                reason = tracker.stop
            break
    except StopContinuation as exc:
        reason = StopReason(Stop.START_FAILED, str(exc))
    except KeyboardInterrupt:
        reason = StopReason(Stop.EVENT, "interrupted")
        raise
    finally:
        hint = ""
        if reason.status in (Stop.STEP_TOO_SMALL, Stop.NO_CONVERGENCE):
            hint = _symmetry_hint(system) or (_singular_hint(*last_recorded) if last_recorded else "")
        branch.stop_reason = reason.message + hint
        branch.steps += steps
        branch.newton_iterations += iterations
        branch.elapsed += time.perf_counter() - t_start
        recorder.sync()
    return branch


class ZoneChangeDetector(Detector):
    """Contact zones that appear (onset), vanish (lift-off), merge or split within a step, located like folds.

    The zones are the runs where the wall pressure is at least the contact level (on the contact grid of
    the mesh, 16 samples per subinterval). A step whose zone count changes is searched for the first
    stretch of the grid that changed sides; the change is located where the pressure there crosses the
    level: its largest value over the stretch for a zone that appears or lifts off, its smallest for the
    gap of a merge or the dip of a split (both continuous along the branch). A second change within the
    same step is not located (the trace warns), nor one that leaves the count unchanged (a zone that
    appears as another lifts off).
    """

    name = "contact onset, lift-off, merge or split of zones"

    def __init__(self, system: RodSystem, tol: float = 1e-9):
        self.system, self.tol = system, tol
        self.level = system.wall.contact_level * system.model.contact_scale

    def _pressure(self, pt: Point) -> np.ndarray:
        sysm = self.system
        c = sysm.model.contact(sysm.disc, pt.x, sysm.params(pt.p))
        self.S = c["S"]
        return c["pressure"]

    def _mirrors(self, a, b) -> bool:
        """Whether two runs of the grid are mirror images about mid-span (a symmetric rod's pair, which
        changes at one parameter: one located point stands for both)."""
        S = self.S
        h = float(np.max(np.diff(S)))
        return abs(S[a[0]] + S[a[1]] + S[b[0]] + S[b[1]] - 2 * (S[0] + S[-1])) <= 4 * h

    def check(self, tracker, base, new, ds):
        n0, n1 = base.data.get("contact_zones"), new.data.get("contact_zones")
        if n0 is None or n1 is None or n0 == n1:
            return []
        q0, q1 = self._pressure(base) - self.level, self._pressure(new) - self.level
        on0, on1 = q0 >= 0, q1 >= 0
        topological = []  # (first, last, peak): the runs of samples whose change alters the zones
        for flipped in (on1 & ~on0, on0 & ~on1):
            idx = np.flatnonzero(flipped)
            for run in (np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1) if idx.size else []):
                a, b = run[0] - 1, run[-1] + 1
                # its neighbours where the run is a gap: in the base point for a gained run, in the new one
                # for a lost run
                side = on0 if on1[run[0]] else on1
                left = bool(side[a]) if a >= 0 else False
                right = bool(side[b]) if b < side.size else False
                if left == right:  # both in contact: a gap closes or a dip opens; both free: a zone comes or goes
                    topological.append((run[0], run[-1], not left))
        if not topological:
            import warnings
            warnings.warn(f"the contact zones changed from {n0} to {n1} between {self.system.param} = "
                          f"{base.p:.10g} and {new.p:.10g} where no stretch of the contact grid changed sides "
                          f"(a narrow peak between its samples): not located", RuntimeWarning, stacklevel=2)
            return []
        lo, hi, peak = topological[0]
        others = [r for r in topological[1:] if not self._mirrors(topological[0], r)]
        window = slice(max(lo - 2, 0), min(hi + 3, q0.size))

        def g(pt):
            q = self._pressure(pt)[window] - self.level
            return float(q.max() if peak else q.min())

        g0, g1 = g(base), g(new)
        f = None
        if g0 * g1 < 0:
            # (g jumps where the pressure's sample changes: a bracket shrunk to rounding is the location)
            f = tracker.locate(base, ds, g, g0, g1, self.tol * max(abs(g0), abs(g1), 1e-300), f"event:{self.name}",
                               continuous=False)
        if f is None or others:
            import warnings
            warnings.warn(f"the contact zones changed from {n0} to {n1} between {self.system.param} = "
                          f"{base.p:.10g} and {new.p:.10g}" + (" (more than one change in the step)"
                                                                if others else "")
                          + ": not all located; a smaller --ds-max separates them", RuntimeWarning, stacklevel=2)
        return [] if f is None else [Finding(f.ds, f, None)]


def _symmetric_about_axis(system: RodSystem) -> bool:
    """Whether the rod can be turned about a straight axis as a whole: its weight does not point across
    (weightless, or weighing along the axis) and the reference is straight (a conduit around it, of any
    clearance profile, turns with it). Turned with its material frame turned back about its tangent, an
    isotropic rod keeps its energy and its clamps: equilibria off the axis come in circles (a singular
    Jacobian on them) and eigenvalues in pairs (a double crossing at each bifurcation from the axis)."""
    model = system.model
    if not model.constant_frame or system.param == "w":  # a trace in w changes the weight along the way
        return False
    gK = np.asarray(model.gK, float)  # the weight's direction on the frame (K1, K2 across, K3 along)
    return system.rod.w == 0 or float(np.hypot(gK[0], gK[1]) / np.linalg.norm(gK)) <= 1e-12


def _symmetry_hint(system: RodSystem) -> str:
    if not _symmetric_about_axis(system):
        return ""
    return (" (a rod whose weight does not point across a straight reference has equilibria off its axis "
            "in circles, turned about the axis, with a singular Jacobian: give it a weight across the axis, "
            "however small, to pick the plane)")


def _singular_hint(pt: Point, sysm: RodSystem) -> str:
    """Where the corrector failed at every step size: whether the Jacobian at the last stored point is
    singular to rounding (the stop is then a singular point, of the rod or of this discrete problem, that
    no step size passes: seen in a pipe with eps = 1e-5 on a graded mesh of N = 241). Not near a fold in
    the parameter (``|dp/ds| < 1e-3``), where the Jacobian is singular by nature. The Jacobian itself, not
    the tracker's bordered matrix: a natural-order LU of that (a dense tangent row) filled 24 GB at
    N = 3000, where J's took 0.1 s."""
    if abs(pt.tp) < 1e-3:
        return ""
    _, J, _ = sysm.linearise(pt.x, pt.p)
    sigma = scaled_smallest_singular_value(J)
    # the scaled collocation matrix of a regular point has sigma ~ h^3 (the paper's rod at Phi = 5: 5.9e-8
    # at N = 54, 1.5e-10 at 400, 2.8e-12 at 1500, so about 7e-14 at 5000): rounding is the level below
    if sigma > 2e-15:
        return ""
    return (f" (the Jacobian is singular to rounding at the last stored point, p = {pt.p:.10g}: smallest "
            f"singular value {sigma:.1g} with rows and columns scaled; a singular point of this discrete "
            f"problem or of the rod, which no step size passes"
            + ("; a different mesh (--N-max, --N) or a larger eps may pass it" if sysm.wall is not None
               else "; a different mesh (--N-max, --N) may pass it") + ")")


def _remesh(sysm: RodSystem, pt: Point, err: float, accuracy: Accuracy, o: TraceOptions,
            at_least: float = 0.0, target: float | None = None, ahead: tuple | None = None) -> _Segment:
    """A new segment from ``pt`` on a mesh adapted to it (aiming at a tenth of the trigger, or ``target``).

    ``ahead = (system, point)``: the point of a step rejected for its error. The
    mesh is adapted to it (from its own mesh, which may already be a
    refinement), and on one mesh to ``pt`` as well: a feature that appears
    within the step, such as a new contact, is not in ``pt``'s indicator, and a
    mesh adapted to ``pt`` alone fails the same step again, however often it is
    refined; one that vanishes within it is in ``pt``'s only.
    """
    p = pt.p
    src, x_src, p_src = (sysm, pt.x, p) if ahead is None else (ahead[0], ahead[1].x, ahead[1].p)
    indicator = src.interval_defect(x_src, p_src)
    if ahead is not None and np.array_equal(src.disc.breakpoints, sysm.disc.breakpoints):
        # on one mesh: the features of both ends of the step (one that lifts off within it is in pt's only)
        indicator = np.maximum(indicator, sysm.interval_defect(pt.x, p))
    b = adapted_mesh(src.disc.breakpoints, indicator, src.disc.k, max(err, at_least),
                     target if target is not None else accuracy.trigger / 10,
                     N_max=o.N_max)
    new = sysm.with_mesh(sysm.conform(b))
    x = new.disc.transfer(pt.x, sysm.disc)
    tx = new.disc.transfer(pt.tx, sysm.disc)
    accuracy.reset()
    return _Segment(new, x, p, (tx, pt.tp))


def trace(gamma: float | None = None, rod: RodParameters | None = None, N: int = 15, k: int = 5, *,
          T: float | None = None, param: str = "phi_L", phi_L: float = 0.0,
          start: tuple | None = None, switch: bool = False, from_straight: float | None = None,
          breakpoints=None, out: str | None = None, overwrite: bool = False, meta: dict | None = None,
          store_every: int = 1, curve=None, wall=None, callback: Callable[[Point], None] | None = None,
          settings: ContinuationSettings | None = None, **options) -> Branch:
    """Trace a branch of the twisted heavy rod; returns a :class:`Branch` (and writes ``out`` as it goes).

    In ``phi_L`` (default) from the planar sag at ``phi_L = 0``; from a stored
    point ``start = (x, value, direction)`` (``direction = (dx, dvalue)`` or
    None; ``breakpoints`` its mesh); or from the near-straight state at
    ``from_straight = PHI`` (:func:`straight_seed`). ``param`` other than
    ``phi_L`` continues that rod parameter at fixed ``phi_L`` over
    ``p_range = (lo, hi)``. ``switch``: the start is a branch point, leave it
    along the other branch. ``curve``: the reference curve
    (:mod:`rodcont.curves`; default the straight span ``L e1``); ``wall``: a conduit
    wall around it (:class:`rodcont.contact.Wall`; default none). ``store_every``: keep the solution (coefficients,
    tangent) of every ``store_every``-th point only, and of every special point
    and the last one, in the file and in the returned branch (smaller files, and the memory of a long
    trace; the table keeps every point, ``coefficients[i]`` is empty where the solution was not kept).
    ``options``: the fields of :class:`TraceOptions` (a misspelt name is a ``TypeError``).
    """
    try:
        opts = TraceOptions(**options)
    except TypeError as exc:
        raise TypeError(str(exc).replace("TraceOptions.__init__()", "trace()")) from None
    if rod is None:
        rod = RodParameters()
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    N = check_number("N", N, integer=True)
    k = check_number("k", k, integer=True)
    if not 1 <= N <= 100000:
        raise ValueError(f"N (number of subintervals) must be an integer >= 1, got {N}")
    if not 1 <= k <= 7:
        raise ValueError(f"k (Gauss points per subinterval) must be an integer in 1..7, got {k}")
    if param not in SYSTEM_PARAMS:
        raise ValueError(f"param must be one of {', '.join(SYSTEM_PARAMS)}, got {param!r}")
    if T is None:
        if gamma is None:
            raise ValueError("give gamma (T = gamma w L) or T")
        gamma = check_number("gamma", gamma)
        if rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: give T")
        T = rod.tension(gamma)
    T = check_number("T", T)
    if not math.isfinite(T) or abs(T) > 1e12 * max(rod.EA, rod.EI / rod.L**2):
        raise ValueError(f"the tension T = {T:.6g} is not a usable number")
    if start is None:  # from the sag or the straight state, unique only above the Euler load; a stored point is
        check_tension(rod, T)  # an equilibrium wherever it was reached
    phi_L = check_number("phi_L", phi_L)
    if start is not None and from_straight is not None:
        raise ValueError("give start or from_straight, not both")
    if switch and start is None:
        raise ValueError("switch needs a start point (a branch point) with its incoming direction")
    tangent0, exact = None, False
    if curve is not None and not isinstance(curve, str):
        from ..curves import ReferenceCurve
        if not isinstance(curve, ReferenceCurve):
            raise TypeError(f"curve must be a rodcont.curves.ReferenceCurve, got {curve!r}")
    if isinstance(curve, str):
        from ..curves import parse_reference
        curve = parse_reference(curve, rod.L)
    if wall is not None:
        from ..contact import Wall
        if not isinstance(wall, Wall):
            raise TypeError(f"wall must be a rodcont.contact.Wall, got {wall!r}")
        if from_straight is not None:
            raise ValueError("--from-straight is not available inside a conduit (trace from the sag instead)")
    if from_straight is not None:
        phi0 = check_number("from_straight", from_straight)
        if curve is not None and not getattr(curve, "constant_frame", False):
            raise ValueError("--from-straight needs the straight reference (the straight rod state lives there)")
        sysw, x0 = straight_seed(rod, T, phi0, N, k, breakpoints)
        system = RodSystem(rod, T=T, N=N, k=k, param=param, phi_L=phi0, breakpoints=sysw.disc.breakpoints)
        p0 = phi0 if param == "phi_L" else system.value()
    elif start is not None:
        x0, p0, t0 = start
        system = RodSystem(rod, T=T, N=N, k=k, param=param, phi_L=phi_L if param != "phi_L" else 0.0,
                           breakpoints=breakpoints, curve=curve, wall=wall)
        x0 = np.asarray(x0, float)
        if x0.size != system.disc.size:
            raise ValueError("the start point does not fit this mesh (N, k)")
        p0 = check_number("start value", p0)
        if t0 is not None:
            tangent0 = (np.asarray(t0[0], float), float(t0[1]))
            if tangent0[0].size != x0.size:
                tangent0 = (np.zeros(x0.size), tangent0[1] if tangent0[1] != 0 else 1.0)
        if switch:
            if tangent0 is None:
                raise ValueError("switch needs the incoming direction at the branch point")
            tangent0 = switch_direction(system, x0, p0, tangent0)
            exact = True
    else:
        if param != "phi_L":
            raise ValueError(f"a trace in {param} starts from a stored point or from the straight state")
        system = RodSystem(rod, T=T, N=N, k=k, param="phi_L", breakpoints=breakpoints, curve=curve, wall=wall)
        x0 = system.model.initial_guess(system.disc, system.base[1])
        p0 = 0.0
        if wall is not None:
            from .solve import ConvergenceError, settle_in_conduit
            try:
                with np.errstate(all="ignore"):
                    x0 = settle_in_conduit(system, x0, system.params(p0))
            except ConvergenceError as exc:
                raise TraceError(str(exc)) from None
    branch = Branch(gamma=rod.gamma(T) if rod.w > 0 else math.nan, rod=rod, N=N, k=k, param=param)
    writer = group = None
    store_every = check_number("store_every", store_every, integer=True)
    if store_every < 1:
        raise ValueError(f"store_every must be >= 1, got {store_every}")
    if out is not None:
        from ..branchfile import BranchWriter, check_output
        check_output(out, overwrite=overwrite)
        writer = BranchWriter(out, file_meta(rod, T, N, k, param, opts, system, meta), store_every=store_every)
        group = writer.group("/", extra_columns=((param,) if param != "phi_L" else ())
                             + (CONTACT_COLUMNS if wall is not None else ()))
        _mesh_group(writer, system)
    contact = _ContactRows(system) if writer is not None and wall is not None else None
    recorder = Recorder(branch, writer, group, contact, thin=store_every)
    try:
        with np.errstate(all="ignore"):
            run(system, x0, p0, opts, tangent0=tangent0, exact=exact, branch=branch, recorder=recorder,
                callback=callback, settings=settings)
    except KeyboardInterrupt:
        branch.stop_reason = "interrupted"
        raise
    finally:
        if writer is not None:
            try:
                if branch.missed_crossings:
                    writer.f.attrs["missed_crossings"] = json.dumps(branch.missed_crossings)
                if branch.unlocated:
                    writer.f.attrs["unlocated"] = json.dumps(branch.unlocated)
                if contact is not None and len(branch):
                    # the rows are computed as the points are recorded: here at most the last point's
                    # (when a second Ctrl-C came during its computation), so an interrupt does not wait
                    contact.fill(branch)
                    contact.write(writer)
            finally:
                writer.close(branch.stop_reason or "interrupted")
    return branch


class _ContactRows:
    """``/contact`` of a trace in a conduit, point by point as the trace records them: the contact zones
    of each point and, on ``samples`` points of the span, the wall pressure, the gap, the axial force and
    the torque (the branch table's min_gap, side_force, contact_zones go with each point).

    Computed when each point is recorded (about 10 ms a point on the paper's mesh), written when the
    run ends: computing them all at the end delayed the exit of an interrupted long trace by as much
    (seconds to minutes), and a second Ctrl-C there lost the group."""

    def __init__(self, system: RodSystem, samples: int = 201):
        self.system = system
        self.S = np.linspace(*system.model.interval, samples)
        self.profiles: list[dict] = []
        self.zones: list[tuple] = []
        self._mesh = (None, None)  # (breakpoints bytes, RodSystem on that mesh): meshes change seldom

    def fill(self, branch: Branch) -> None:
        """Compute the rows of the points of ``branch`` not yet computed."""
        system, model = self.system, self.system.model
        while len(self.profiles) < len(branch):
            i = len(self.profiles)
            b = branch.meshes[i]
            key = b.tobytes()
            if self._mesh[0] != key:
                self._mesh = (key, system.with_mesh(b))
            sysm = self._mesh[1]
            value = branch.table[system.param][i] if system.param != "phi_L" else branch.table["phi_L"][i]
            p = sysm.params(float(value))
            x = branch.coefficients[i]
            fine = model.contact(sysm.disc, x, p)
            at = model.contact(sysm.disc, x, p, S=self.S)
            row = {name: np.asarray(at[name], np.float32) for name in ("pressure", "gap", "axial_force", "torque")}
            # zones and profile together (a Ctrl-C between them would record the zones twice)
            self.zones.extend((i, a, e, f) for a, e, f in fine["zones"])
            self.profiles.append(row)

    def write(self, writer) -> None:
        """``/contact`` for the rows computed (every point of the branch after :meth:`fill`)."""
        wall, model = self.system.wall, self.system.model
        n, samples = len(self.profiles), self.S.size
        prof = {name: np.array([r[name] for r in self.profiles], np.float32).reshape(n, samples)
                for name in ("pressure", "gap", "axial_force", "torque")}
        g = writer.f.require_group("contact")
        for name in list(g):
            del g[name]
        g.attrs.update(clearance=np.asarray(wall.clearance) if wall.varying else wall.clearance, eps=wall.eps,
                       force_scale=model.contact_scale, contact_level=wall.contact_level,
                       law="p (g + p/k) = mu, g = (c^2 - |Delta|^2)/(2c), k = P/(eps c), mu = eps c P")
        g.create_dataset("S", data=self.S)
        for name, data in prof.items():
            g.create_dataset(name, data=data, compression="gzip", chunks=(max(min(n, 64), 1), samples))
        g.create_dataset("zones", data=np.asarray(self.zones, float).reshape(-1, 4), compression="gzip")
        g["zones"].attrs["columns"] = "point,S_start,S_end,force"


def file_meta(rod: RodParameters, T: float, N: int, k: int, param: str, opts: TraceOptions, system: RodSystem,
              extra: dict | None = None) -> dict:
    """Root attributes of a branch file: the rod, the loads, the mesh and every run setting."""
    from .. import __version__
    meta = dict(kind="branch", gamma=rod.gamma(T) if rod.w > 0 else math.nan, T=float(T), w=rod.w, EI=rod.EI,
                GJ=rod.GJ, EA=rod.EA, L=rod.L, N=int(N), k=int(k), param=param,
                weight_direction=np.asarray(rod.weight_direction), min_alignment_guard=opts.min_alignment,
                max_error=opts.max_error, phi_L_fixed=float(system.base[0]) if param != "phi_L" else math.nan,
                reference=str(getattr(system.curve, "spec", "straight") or "straight"),
                # the force scale as resolved (a default follows w or EI, which a trace may change)
                conduit=(dataclasses.replace(system.wall, force_scale=system.model.contact_scale).spec
                         if system.wall is not None else ""),
                settings=json.dumps(dict(opts.as_dict(), rodcont_version=__version__), default=float))
    if rod.w == 0:
        meta["gamma"] = math.nan
    meta.update(extra or {})
    return meta


def _mesh_group(writer, system: RodSystem) -> None:
    from ..rod import FIELDS, ORDERS
    mesh = writer.f.require_group("mesh")
    if "breakpoints" not in mesh:
        mesh.create_dataset("breakpoints", data=np.asarray(system.disc.breakpoints, float))
        mesh.attrs["orders"] = np.asarray(ORDERS)
        mesh.attrs["fields"] = ",".join(FIELDS)
        mesh.attrs["layout"] = "rodcont.collocation.Collocation interleaved coefficients"
