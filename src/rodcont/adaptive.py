"""Continuation on a mesh that adapts, under an accuracy guard (knows nothing of rods).

The engine (:class:`AdaptiveContinuation`, or :func:`adaptive_continuation`) runs the
tracker (:class:`rodcont.continuation.Tracker`) in *segments*, one mesh each. It estimates
the error of every point (:class:`Accuracy`) and

* rebuilds the mesh from a stored point whose error passes ``trigger * max_error``
  (:func:`rodcont.mesh.adapted_mesh`: as many subintervals as the estimate says are needed to
  reach ``target`` of that threshold, placed where the problem's refinement indicator
  concentrates), carrying the point and its tangent over; a new segment starts there;
* never stores a point whose error exceeds ``max_error``: the mesh is refined for the step
  (from the last stored point, or from the step's end when that point is a branch point, where
  the bordered matrix is singular) and the step retried, up to ``error_remeshes`` times; when
  the mesh may not grow (``adapt`` off or ``N_max`` reached) the run stops there: the
  accuracy guard (:attr:`rodcont.result.Status.ACCURACY_GUARD`);
* locates a fold again on a mesh refined for it when its error exceeds ``fold_error``
  (``fold_remeshes`` times at most); a fold's error is the larger of the estimate and how
  far the fold itself moves, in the parameter's own unit (its arclength scale);
* refines the start up to ``start_refinements`` times; a segment whose start does not
  converge on its adapted mesh is replaced by the last stored point's mesh halved, up to
  ``halvings`` times (then :attr:`Status.NO_CONVERGENCE`).

Every limit is a field of :class:`AdaptiveSettings`, named once.

Meshed problem protocol. Besides the tracker's protocol (``residual(x, p)``,
``tangent(x, p) -> (J, F_p)`` or ``linearise(x, p) -> (F, J, F_p)``; optionally
``arclength_scale()``, ``relative_change(x0, x1)``, ``relative_correction(x0, x_pred, x1)``,
``accept(x, p)``), a problem on a mesh has

* ``outputs(x, p) -> dict``: named scalars of a solution (the result's columns; events read them);
* ``breakpoints`` (the mesh, an increasing array) and ``k`` (its degree; collocation points per
  subinterval);
* ``with_mesh(breakpoints, k=None)``: the same problem on another mesh;
* ``transfer(x, source)``: a solution (or a tangent) of ``source`` carried onto this mesh;
* ``interval_defect(x, p)``: a refinement indicator per subinterval (``~ h^k`` there);
* ``conform(breakpoints)``: the mesh with the stations the problem needs kept (joins of its
  data, say);
* for the error estimate (:class:`rodcont.mesh.ErrorEstimator`): ``disc`` (its collocation),
  ``error_quantities(x, p) -> (values, scales)``, ``error_fields() -> [(field, scale)]``;
  or instead ``error_estimator()`` returning an object with ``estimate(x, p, tangent)``.

The run's other parts plug in: ``events`` (:class:`rodcont.continuation.Event`: a guard declares
the status it stops with), ``detectors(problem)`` (extra detectors for each segment's mesh),
``observers`` (``observer(problem, point, recorder)``, run before a point is stored: they may add
to its ``data``), a ``recorder`` (``add(point, problem)``, ``sync()``, ``result``: a
:class:`ResultRecorder` fills a :class:`rodcont.result.ContinuationResult`; a driver's also writes a
file), a ``callback(point)`` after each stored point, and ``hints`` (:class:`Hints`: what to add
to a message where the run fails).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from .blas import with_one_blas_thread
from .continuation import ContinuationSettings, Kind, Point, StopContinuation, StopReason, Tracker
from .linalg import HeapTrimmer
from .mesh import ErrorEstimator, adapted_mesh, halved
from .result import ContinuationResult, Status


class StartError(ValueError):
    """A run that cannot start (the message says why, in one line; ``status`` is the
    :class:`rodcont.result.Status` it would end with: START_FAILED, AT_START or ACCURACY_GUARD)."""

    def __init__(self, message: str, status: Status = Status.START_FAILED):
        super().__init__(message)
        self.status = status


@dataclass
class AdaptiveSettings:
    """Every limit of the adaptive loop, named once, with its default; checked when made.

    ``max_error``: the accuracy guard on the estimated error of each stored point;
    ``fold_error``: a located fold whose estimate is larger is located again on a finer mesh;
    ``adapt``: rebuild the mesh (``False``: keep the first one); ``N_max``: most subintervals;
    ``trigger``: rebuild once the error passes ``trigger * max_error``; ``target``: an adapted
    mesh aims at ``target`` of that threshold; ``fold_target``: a fold's mesh aims at
    ``fold_target * fold_error``; ``start_refinements``: refinements of a start;
    ``error_remeshes`` / ``fold_remeshes``: refinements for one step above ``max_error`` / for one
    fold above ``fold_error`` before giving up; ``halvings``: meshes halved when an adapted one
    does not converge; ``measure_every``: the full error estimate at least every this many points
    (1: at every point; between, the estimate follows the defect, :class:`Accuracy`).
    """

    max_error: float = 1e-6
    fold_error: float = 1e-9
    adapt: bool = True
    N_max: int = 400
    trigger: float = 0.1
    target: float = 0.1
    fold_target: float = 0.1
    start_refinements: int = 6
    error_remeshes: int = 4
    fold_remeshes: int = 3
    halvings: int = 3
    measure_every: int = 25

    def __post_init__(self):
        for name in ("max_error", "fold_error", "trigger", "target", "fold_target"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not v > 0 \
                    or not math.isfinite(v):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        for name in ("N_max", "start_refinements", "error_remeshes", "fold_remeshes", "halvings", "measure_every"):
            v = getattr(self, name)
            least = 1 if name in ("N_max", "measure_every") else 0
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < least:
                raise ValueError(f"{name} must be a non-negative integer (N_max, measure_every >= 1), got {v!r}")
        if not isinstance(self.adapt, (bool, np.bool_)):
            raise TypeError(f"adapt must be True or False, got {self.adapt!r}")
        if not self.trigger <= 1:
            raise ValueError("trigger must be at most 1 (a fraction of max_error)")


# --------------------------------------------------------------------------
# Accuracy: estimated error of each point, measured where it matters
# --------------------------------------------------------------------------
class Accuracy:
    """The estimated error of each point, cheap where it is small.

    The full estimate (one Newton step in the richer space) costs a few
    steps; between two of them the error is taken proportional to the defect
    (the ``defect`` output, the residual between collocation points, computed at every point
    anyway), with the ratio of the last measurement. Before the first
    measurement on a mesh the ratio is a pessimistic prior, ``PRIOR = 1e-2``
    (measured along the paper's branches it is 1e-6 to 1e-4): a mesh that
    obviously resolves the solution is not measured at all. It is measured at
    every fold, branch point and event, whenever the defect has changed
    sixteenfold since (or doubled, once the guess is within a fiftieth of the
    adaptation threshold), every ``every`` points (``every = 1``: at every point,
    the defect unused), and whenever the guess comes within half of the threshold.
    """

    PRIOR = 1e-2

    def __init__(self, max_error: float, every: int = 25, trigger: float = 0.1):
        self.max_error = max_error
        self.trigger = max_error * trigger
        self.every = every
        self.estimators: dict = {}
        self.ratio = None
        self.defect = None
        self.since = 0
        self.measurements = 0

    def reset(self) -> None:
        self.ratio = self.defect = None

    def estimator(self, problem):
        key = id(problem)
        if key not in self.estimators:
            if len(self.estimators) > 4:
                self.estimators.clear()
            factory = getattr(problem, "error_estimator", None)
            self.estimators[key] = (problem, factory() if factory is not None else ErrorEstimator(problem))
        return self.estimators[key][1]

    def measure(self, problem, pt: Point) -> float:
        estimator = self.estimator(problem)
        e = estimator.estimate(pt.x, pt.p, (pt.tx, pt.tp))
        d = max(float(pt.data.get("defect", 0.0)), 1e-300)
        self.ratio, self.defect, self.since = e / d, d, 0
        self.measurements += 1
        if pt.kind == Kind.FOLD:
            e = max(e, self.fold_error(problem, estimator))
        pt.data["error"] = e
        return e

    @staticmethod
    def fold_error(problem, estimator) -> float:
        """At a fold its location is the answer: how far it moves, in the parameter's own unit (the problem's
        arclength scale of it), not relative to the parameter's size as at a regular point (seen: a fold at
        Phi = 29.24 off by 3.6e-9 whose relative estimate read 3.8e-10, under fold_error = 1e-9). Doubled:
        the move is measured against the richer space, whose own error adds to it; taken as at most the
        coarse one's, the coarse error is at most twice the move (on the Gamma = 1 fold: moved 4.11e-10,
        off by 4.15e-10 from the independent value)."""
        dp = getattr(estimator, "parameter_change", math.nan)
        if not math.isfinite(dp):
            return 0.0 if math.isnan(dp) else math.inf
        scale = getattr(problem, "arclength_scale", None)
        return 2.0 * abs(dp) / (float(scale()[1]) if scale is not None else 1.0)

    def __call__(self, problem, pt: Point) -> float:
        if self.every <= 1:
            return self.measure(problem, pt)
        d = max(float(pt.data.get("defect", 0.0)), 1e-300)
        self.since += 1
        special = pt.kind not in (Kind.REGULAR, Kind.START)
        if self.ratio is None:  # nothing measured on this mesh yet: the pessimistic prior
            e = self.PRIOR * d
            if special or e > self.trigger / 2:
                return self.measure(problem, pt)
            pt.data["error"] = e
            return e
        e = self.ratio * d
        drift = d > 16 * self.defect or d < self.defect / 16
        if (special or drift or self.since >= self.every or e > self.trigger / 2
                or (d > 2 * self.defect and e > self.trigger / 50)):
            return self.measure(problem, pt)
        pt.data["error"] = e
        return e


# --------------------------------------------------------------------------
# Recording and hints
# --------------------------------------------------------------------------
class ResultRecorder:
    """Adds each stored point to a :class:`ContinuationResult` (its mesh with it); a driver's recorder
    extends it (a file, thinning). ``correct(name, i, value)`` changes a stored value (an observer
    that finds a column wrong between its checks)."""

    def __init__(self, result: ContinuationResult):
        self.result = result

    def add(self, pt: Point, problem) -> int:
        return self.result.add(pt, getattr(problem, "breakpoints", None))

    def correct(self, name: str, i: int, value) -> None:
        self.result.table[name][i] = value

    def sync(self) -> None:
        pass


class Hints:
    """What a run adds to its messages where it fails (a driver knows its problem's likely causes)."""

    def start_failed(self, problem) -> str:
        """Appended to the message of a first point that does not converge."""
        return ""

    def stopped(self, status: Status, problem, last: tuple | None) -> str:
        """Appended to a stop for a step too small or no convergence; ``last = (point, problem)``."""
        return ""


# --------------------------------------------------------------------------
# The engine
# --------------------------------------------------------------------------
@dataclass
class _Segment:
    problem: object
    x: np.ndarray
    p: float
    tangent: tuple | None
    exact: bool = False
    # the start is a point not yet stored (a step's end, re-converged on the new mesh): store it, at this
    # arclength; otherwise the start is the last stored point, converged again
    record_at: float | None = None


_STOP = object()  # a rejected point that ends the run (the accuracy guard)


def _N(problem) -> int:
    return len(problem.breakpoints) - 1


class AdaptiveContinuation:
    """One run of the adaptive loop (see the module docstring); :meth:`run` returns the result.

    ``settings``: the tracker's (:class:`ContinuationSettings`: steps, bounds, detection);
    ``adaptive``: the loop's limits (:class:`AdaptiveSettings`). ``tangent0``: the direction to
    leave ``(x0, p0)`` by, else ``settings.direction`` in the parameter; ``exact_start``:
    ``(x0, p0)`` is a solution left along ``tangent0`` as is (branch switching). ``result``: the
    result to fill (default a new :class:`ContinuationResult` in ``param``); ``recorder`` fills it
    (default :class:`ResultRecorder`). A first point that cannot be made raises
    :class:`StartError`; every other end is the result's status.
    """

    def __init__(self, problem, x0, p0: float, settings: ContinuationSettings | None = None,
                 adaptive: AdaptiveSettings | None = None, *, tangent0=None, exact_start: bool = False,
                 events: Sequence = (), detectors: Callable | None = None, observers: Sequence[Callable] = (),
                 recorder=None, result: ContinuationResult | None = None, callback: Callable | None = None,
                 hints: Hints | None = None, param: str = "p", heap_trim_interval: float | None = 0.25):
        self.settings = settings or ContinuationSettings()
        self.adaptive = adaptive or AdaptiveSettings()
        if recorder is None:
            recorder = ResultRecorder(result if result is not None else ContinuationResult(param))
        self.recorder, self.result = recorder, recorder.result
        self.result.settings.setdefault("continuation", asdict(self.settings))
        self.result.settings.setdefault("adaptive", asdict(self.adaptive))
        self.events, self.detectors, self.observers = list(events), detectors, list(observers)
        self.callback, self.hints = callback, hints or Hints()
        a = self.adaptive
        self.accuracy = Accuracy(a.max_error, a.measure_every, a.trigger)
        self.trim_heap = HeapTrimmer(heap_trim_interval)
        self.first = _Segment(problem, np.asarray(x0, float), float(p0), tangent0, exact_start)
        self.start_attempts = self.remeshes_here = self.failed_remeshes = 0
        self.last: tuple | None = None  # (point, problem) of the last stored point
        self.stop = StopReason(Status.START_FAILED, "not started")
        self.steps = self.iterations = 0
        self.step_in_use = None  # the step size reached before a remesh: a new segment goes on with it

    # ---- the loop -------------------------------------------------------------------
    @with_one_blas_thread
    def run(self) -> ContinuationResult:
        t0 = time.perf_counter()
        seg = self.first
        try:
            while seg is not None:
                seg = self._segment(seg)
        except StopContinuation as exc:
            self.stop = StopReason(Status.START_FAILED, str(exc))
        except KeyboardInterrupt:
            self.stop = StopReason(Status.INTERRUPTED, "interrupted")
            raise
        finally:
            self._finish(t0)
        return self.result

    def _segment(self, seg: _Segment) -> _Segment | None:
        """One tracker on one mesh; returns the next segment, or None when the run ends."""
        tracker = self._tracker(seg)
        first = self._first_point(tracker, seg)
        if not isinstance(first, Point):
            return first
        nxt = self._follow(tracker, seg.problem, first)
        self.steps += tracker.steps
        self.iterations += tracker.newton_iterations
        self.step_in_use = tracker.ds
        if isinstance(nxt, _Segment):
            self.result.remeshes += 1
            return nxt
        if tracker.stop is not None:
            self.stop = tracker.stop
        return None

    def _tracker(self, seg: _Segment) -> Tracker:
        tracker = Tracker(seg.problem, seg.x, seg.p, self.settings, monitor=seg.problem.outputs,
                          events=self.events, tangent0=seg.tangent, exact_start=seg.exact)
        tracker.unlocated = self.result.unlocated
        if self.detectors is not None:
            tracker.detectors += list(self.detectors(seg.problem))
        if self.step_in_use is not None:
            # not the initial ds: where a stiff stretch forced small steps, a fresh segment that
            # starts with the initial ds leaps past it, onto another branch (seen at a contact onset)
            tracker.ds = self.step_in_use
        return tracker

    def _first_point(self, tracker: Tracker, seg: _Segment):
        """The segment's start, checked and stored as needed: a Point to go on from, or the segment to
        try instead, or None (the run ends)."""
        problem, a = seg.problem, self.adaptive
        try:
            first = tracker.start()
        except StopContinuation as exc:
            if self.last is None:
                raise StartError(str(exc) + self.hints.start_failed(problem)) from None
            return self._halved(exc)
        self.steps += tracker.steps
        if tracker.start_on_fold and self.last is None:
            q = self.result.param
            warnings.warn(f"the start is a fold in {q} (d{q}/ds = 0 there): {q} moves the same way on both "
                          f"sides, so the direction asked for cannot choose; the trace follows one side (its "
                          f"other side: the same command with the other --direction)", RuntimeWarning, stacklevel=4)
        err = self.accuracy(problem, first)
        if err > self.accuracy.trigger and a.adapt and self.start_attempts < a.start_refinements \
                and _N(problem) < a.N_max:
            self.start_attempts += 1
            return dataclasses.replace(self._remesh(problem, first, err), record_at=seg.record_at)
        if err > a.max_error:
            return self._start_above_guard(problem, first, err)
        self.start_attempts = 0
        if self.last is None:
            first.arclength = 0.0
            why = tracker.check_start(first)
            if why is not None:
                raise StartError(f"cannot start there: {why.message}", why.status)
            self._store(problem, first)
        elif seg.record_at is not None:
            first.arclength, first.kind = seg.record_at, Kind.REGULAR
            self._store(problem, first)
        else:
            first.arclength = self.last[0].arclength
        tracker.resume(first)
        return first

    def _start_above_guard(self, problem, first: Point, err: float) -> None:
        a, N = self.adaptive, _N(problem)
        if self.last is None:
            raise StartError(f"accuracy guard already violated at the start: estimated error {err:.2g} > "
                             f"max_error = {a.max_error:g} with N = {N}"
                             + ("" if a.adapt else " (the mesh is fixed: raise N or let it adapt)")
                             + ("" if N < a.N_max else f" (N_max = {a.N_max} reached)"), Status.ACCURACY_GUARD)
        why = (f"N_max = {a.N_max} reached" if N >= a.N_max or not a.adapt
               else f"{self.start_attempts} refinements did not bring it down")
        self.stop = StopReason(Status.ACCURACY_GUARD, f"accuracy guard: estimated error {err:.2g} > max_error = "
                                                      f"{a.max_error:g} at p = {first.p:.10g} (N = {N}; {why})")
        return None

    def _follow(self, tracker: Tracker, problem, first: Point):
        """Iterate the tracker from ``first``; returns the next segment, or None (the tracker or the
        accuracy guard ended the run)."""
        a = self.adaptive
        # the tracker's arclength goes on from ``first``'s, which the segment's start was given (adding it
        # again doubled it at every segment: 553 in one step on the Gamma = 1 trace)
        for pt in tracker:
            err = self.accuracy(problem, pt)
            rejected = self._rejected(problem, pt, err)
            if rejected is _STOP:
                return None
            if rejected is not None:
                return rejected
            self._store(problem, pt)
            self.trim_heap()
            self.remeshes_here = 0
            # not at a point where the run stops (a guard, a bound: the tracker's stop is set when it hands
            # that point over): a new segment from there would start past the guard and never see it cross
            # again. Nor at a special point whose location failed: near a singular point a new segment's
            # first steps diverge at every size; the step's end follows at once and is refined from
            # instead. Nor at a branch point, where the bordered matrix of the new start is singular (its
            # first step went on along the other branch)
            if (err > self.accuracy.trigger and a.adapt and _N(problem) < a.N_max and tracker.stop is None
                    and pt.located and pt.kind != Kind.BRANCH_POINT):
                return self._remesh(problem, pt, err)
        return None

    def _rejected(self, problem, pt: Point, err: float):
        """A point not to store: the segment to retry its step on, or ``_STOP``; None to store it."""
        a = self.adaptive
        grow = a.adapt and _N(problem) < a.N_max
        if pt.kind == Kind.FOLD and err > a.fold_error and grow and self.remeshes_here < a.fold_remeshes:
            self.remeshes_here += 1  # locate this fold again on a mesh refined for it
            base, bproblem = self.last
            return self._remesh(bproblem, base, self.accuracy.measure(bproblem, base), at_least=err,
                                target=a.fold_error * a.fold_target, ahead=(problem, pt))
        if pt.kind == Kind.FOLD and err > a.fold_error:
            # stored above its promise (the mesh may not grow, or refining did not bring it down): said, not silent
            why = ("the mesh is fixed" if not a.adapt else f"N_max = {a.N_max} reached" if not grow else
                   f"{a.fold_remeshes} refinements did not bring it down")
            pt.data["fold_error_exceeded"] = True
            warnings.warn(f"the fold at p = {pt.p:.10g} has an estimated error {err:.2g} above fold_error = "
                          f"{a.fold_error:g} ({why})", RuntimeWarning, stacklevel=4)
        if err <= a.max_error:
            return None
        if grow and self.remeshes_here < a.error_remeshes:
            self.remeshes_here += 1
            base, bproblem = self.last
            if base.kind == Kind.BRANCH_POINT and pt.kind == Kind.REGULAR:
                # not from the branch point, where the bordered matrix is singular: from this step's end,
                # on the branch, stored once converged on the new mesh
                return dataclasses.replace(self._remesh(problem, pt, err, at_least=err), record_at=pt.arclength)
            return self._remesh(bproblem, base, self.accuracy.measure(bproblem, base), at_least=err,
                                ahead=(problem, pt))
        N = _N(problem)
        self.stop = StopReason(Status.ACCURACY_GUARD,
                               f"accuracy guard: estimated error {err:.2g} > max_error = {a.max_error:g} at "
                               f"p = {pt.p:.10g}" + ("" if a.adapt else " (the mesh is fixed: raise N or let it adapt)")
                               + ("" if N < a.N_max else f" (N_max = {a.N_max} reached)")
                               + (" (refining the mesh did not help)" if self.remeshes_here >= a.error_remeshes
                                  else ""))
        return _STOP

    def _store(self, problem, pt: Point) -> None:
        for observe in self.observers:
            observe(problem, pt, self.recorder)
        self.recorder.add(pt, problem)
        self.last = (pt, problem)
        if self.callback is not None:
            self.callback(pt)

    # ---- meshes -------------------------------------------------------------------------
    def _remesh(self, problem, pt: Point, err: float, at_least: float = 0.0, target: float | None = None,
                ahead: tuple | None = None) -> _Segment:
        """A new segment from ``pt`` on a mesh adapted to it (aiming at ``target`` of the trigger, or at
        ``target`` itself when given).

        ``ahead = (problem, point)``: the point of a step rejected for its error. The mesh is adapted to
        it (from its own mesh, which may already be a refinement), and on one mesh to ``pt`` as well: a
        feature that appears within the step (a new contact, say) is not in ``pt``'s indicator, and a
        mesh adapted to ``pt`` alone fails the same step again, however often it is refined; one that
        vanishes within it is in ``pt``'s only.
        """
        a = self.adaptive
        src, x_src, p_src = (problem, pt.x, pt.p) if ahead is None else (ahead[0], ahead[1].x, ahead[1].p)
        indicator = src.interval_defect(x_src, p_src)
        if ahead is not None and np.array_equal(src.breakpoints, problem.breakpoints):
            indicator = np.maximum(indicator, problem.interval_defect(pt.x, pt.p))
        b = adapted_mesh(src.breakpoints, indicator, src.k, max(err, at_least),
                         target if target is not None else self.accuracy.trigger * a.target, N_max=a.N_max)
        new = problem.with_mesh(problem.conform(b))
        self.accuracy.reset()
        return _Segment(new, new.transfer(pt.x, problem), pt.p, (new.transfer(pt.tx, problem), pt.tp))

    def _halved(self, exc) -> _Segment | None:
        """The adapted mesh did not converge: from the last stored point, every subinterval of its mesh
        halved instead (a nested space: the point carries over exactly)."""
        self.failed_remeshes += 1
        pt, old = self.last
        if self.failed_remeshes > self.adaptive.halvings or 2 * _N(old) > self.adaptive.N_max:
            self.stop = StopReason(Status.NO_CONVERGENCE, f"accuracy guard: no converged solution on a refined "
                                                          f"mesh at p = {pt.p:.10g} ({exc})")
            return None
        new = old.with_mesh(old.conform(halved(old.breakpoints)))
        self.accuracy.reset()
        return _Segment(new, new.transfer(pt.x, old), pt.p, (new.transfer(pt.tx, old), pt.tp))

    def _finish(self, t0: float) -> None:
        stop = self.stop
        hint = ""
        if stop.status in (Status.STEP_TOO_SMALL, Status.NO_CONVERGENCE):
            hint = self.hints.stopped(stop.status, self.first.problem, self.last)
        r = self.result
        if stop.status != Status.INTERRUPTED and self.last is not None:
            for observer in self.observers:  # what an observer carried to the last point, checked there
                getattr(observer, "finish", lambda recorder: None)(self.recorder)
        r.set_status(stop.status, stop.message + hint)
        r.steps += self.steps
        r.newton_iterations += self.iterations
        r.elapsed += time.perf_counter() - t0
        self.recorder.sync()


def adaptive_continuation(problem, x0, p0: float, settings: ContinuationSettings | None = None,
                          adaptive: AdaptiveSettings | None = None, **options) -> ContinuationResult:
    """Continue a meshed problem from ``(x0, p0)`` with its mesh adapting under the accuracy guard;
    returns the :class:`rodcont.result.ContinuationResult`. ``options``: those of
    :class:`AdaptiveContinuation` (events, detectors, observers, recorder, callback, hints, tangent0, ...)."""
    return AdaptiveContinuation(problem, x0, p0, settings, adaptive, **options).run()
