"""Keller pseudo-arclength continuation of ``F(x, p) = 0`` (knows nothing of rods).

Protocol. A problem is any object with

* ``residual(x, p) -> F`` (``n``-vector), and
* ``tangent(x, p) -> (J, F_p)``: the Jacobian ``dF/dx`` (sparse or dense
  ``n x n``) and ``dF/dp`` (``n``-vector);

optionally ``linearise(x, p) -> (F, J, F_p)`` doing both at once,
``accept(x, p)``, told of every accepted point, and ``relative_change(x0, x1)``,
a problem's own measure of how much a step changed the solution (a step
above ``max_change`` is retried shorter: a feature the arclength norm hardly
sees, such as a small deflection that doubles, is resolved), and
``relative_correction(x0, x_pred, x1)``, the same measure of how far the corrector
moved the predictor: a corrector that removes (or creates) a feature the predictor
carried has converged on another branch, where the arclength norm, dominated by
the parameter, may see almost nothing (a step above ``max_change`` is retried
shorter). The tracker follows the curve
``(x(s), p(s))`` with the arclength of the weighted inner product
(BifurcationKit's normalisation, so a step means the same on any mesh)::

    <(x, p), (y, q)> = theta / n * x.y + (1 - theta) * p q

Each step: tangent predictor ``(x, p) + ds (tx, tp)``, then a chord
(simplified Newton) corrector on the augmented (Keller) system

    F(x, p) = 0,    <(tx, tp), (x - x0, p - p0)> = ds

with the bordered Jacobian ``[[J, F_p], [theta/n tx, (1-theta) tp]]`` of the
*base* point, whose LU was made for the base tangent anyway (its last row is
changed by a rank-one update, :class:`rodcont.linalg.RowUpdatedLU`). A chord
iteration costs one residual and one solve; the one new factorisation per
step is made at the converged point, where it gives the tangent (the
solution of the bordered system with right-hand side ``(0, 1)``, oriented so
that the branch never turns back), the sign of the determinant, and the
corrector matrix of the next step. A corrector that contracts slowly falls
back to full Newton.

Steps are accepted only if they stay on the branch (Allgower & Georg): the
corrector contracts at once, the corrected point lies within
``max_distance * ds`` of the predictor, and the tangent turns by less than
``max_angle`` per step (also between the base tangent and the secant). The
next step grows or shrinks with the measured contraction, distance and
angle, within ``[shrink, grow]``.

Special points are found by :class:`Detector` objects, each *located*, not
just bracketed, by a secant (Illinois) iteration on its test function along
the arc from the last regular point; a point whose location does not reach
its tolerance is kept and marked ``located = False`` (bracketed):

* fold: ``tp`` changes sign (to ``|tp| < fold_tol``); a pair of folds inside
  one step is caught by the cubic Hermite model of ``p(s)`` on the step,
  whose derivative then changes sign twice: the step is halved;
* branch point: the sign of ``det`` of the bordered Jacobian changes;
* parameter values (forced points, bounds);
* user events ``g(point) = 0``: recorded, stopping the trace (with the status the event
  declares), or ending a segment (the caller changes the discretisation and starts a new
  tracker); the point's kind is ``event:<label>``, its ``message`` the event's sentence.

:func:`continuation` runs one tracker and returns a :class:`rodcont.result.ContinuationResult`;
:mod:`rodcont.adaptive` runs trackers on a mesh that adapts.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, fields
from enum import Enum

import numpy as np
from scipy import sparse

from .linalg import SingularMatrix, at_rounding, bordered_solver, max_norm, newton_solve
from .result import ContinuationResult, Status


# --------------------------------------------------------------------------
# Kinds, stop reasons, settings and points
# --------------------------------------------------------------------------
class Kind(str, Enum):
    """What a point is. Stored in branch files as the value (events as ``event:<label>``)."""

    START = "start"
    REGULAR = "regular"
    FOLD = "fold"
    BRANCH_POINT = "branch_point"
    FORCED = "forced"
    BOUND = "bound"
    EVENT = "event"

    def __str__(self) -> str:
        return self.value


#: Why a tracker ended: the result's :class:`rodcont.result.Status` (``Stop.BOUND is Status.BOUND``).
Stop = Status


@dataclass
class StopReason:
    """A status with its message (and the label of the event that stopped, if one did)."""

    status: Status
    message: str
    label: str | None = None

    def __str__(self) -> str:
        return self.message


def _at_rounding(F, J, Fp, x, p, factor: float = 1e3) -> bool:
    """:func:`rodcont.linalg.at_rounding` with the parameter's terms ``|F_p| |p|``.

    A corrector whose residual stalls while its steps stop shrinking has either reached rounding or
    stagnated on a nearly singular matrix: a trace in a pipe (L = 8, eps = 1e-5) stored a point whose
    residual was 2e9 times its noise (0.11 in rows whose terms are 5e5), its neighbours 1.3 times."""
    return at_rounding(F, J, x, np.abs(np.asarray(Fp, float)) * abs(p), factor)


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


#: The corrector's chord stops, and the Newton step that gives a regular point's tangent is taken,
#: once the correction is below NEAR sqrt(tol) (1e-6 relative for tol = 1e-10); a last correction
#: with that factorisation then checks the point to tol. A regular point's tangent is accurate to a
#: few NEAR sqrt(tol) (2.2e-6 on Bratu's branch, tests/test_continuation.py; located points to tol).
#: NEAR = 1e-3 gave tangents to 1.6e-8 for about one more residual per step.
NEAR = 0.1


@dataclass
class ContinuationSettings:
    """Every knob of the tracker, named once, with its default."""

    ds: float = 0.05            # first step (weighted arclength)
    ds_min: float = 1e-7        # below this the tracker stops
    ds_max: float = 0.5
    direction: int = 1          # initial direction of p
    max_steps: int = 2000
    p_min: float = -math.inf
    p_max: float = math.inf
    theta: float = 0.5          # weight of x against p in the arclength
    newton_tol: float = 1e-10   # corrector: step below tol * (1 + |x|)
    newton_max_iter: int = 8
    chord_max_iter: int = 8     # chord iterations before falling back to Newton
    grow: float = 2.0           # largest step growth per step
    shrink: float = 0.5         # step reduction after a rejected step
    max_angle: float = 0.3      # radians between successive tangents (and base tangent to secant)
    max_distance: float = 0.3   # corrector distance from the predictor / ds
    max_contraction: float = 0.5  # chord: each correction at most this fraction of the previous one
    max_change: float = 0.5     # relative change per step of what the problem's relative_change measures
    target_angle: float = 0.15  # step control aims at this turn per step
    detect_folds: bool = True
    detect_fold_pairs: bool = True
    detect_branch_points: bool = True
    fold_tol: float = 1e-10     # |tp| at a located fold
    locate_tol: float = 1e-11   # |g| / |g(start)| for events and branch points
    locate_max_iter: int = 40
    forced: Sequence[float] = ()  # parameter values that get a point of their own

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        """Types, finiteness and ranges of every field; one ``ValueError``/``TypeError`` naming it."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("detect_folds", "detect_fold_pairs", "detect_branch_points"):
                if not isinstance(v, (bool, np.bool_)):
                    raise TypeError(f"{f.name} must be True or False, got {v!r}")
            elif f.name in ("direction", "max_steps", "newton_max_iter", "chord_max_iter", "locate_max_iter"):
                if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool)):
                    raise TypeError(f"{f.name} must be an integer, got {v!r}")
            elif f.name == "forced":
                vals = list(v) if isinstance(v, (list, tuple, np.ndarray)) else None
                if vals is None or not all(_is_number(u) and math.isfinite(u) for u in vals):
                    raise ValueError(f"forced must be a sequence of finite numbers, got {v!r}")
                self.forced = tuple(float(u) for u in vals)
            else:
                if not _is_number(v) or math.isnan(v):
                    raise TypeError(f"{f.name} must be a number, got {v!r}")
                if f.name not in ("p_min", "p_max") and not math.isfinite(v):
                    raise ValueError(f"{f.name} must be finite, got {v!r}")
        checks = [
            (self.ds > 0, "ds must be positive"),
            (0 < self.ds_min <= self.ds <= self.ds_max, "need 0 < ds_min <= ds <= ds_max"),
            (self.direction in (1, -1), "direction must be +1 or -1"),
            (self.max_steps >= 1, "max_steps must be >= 1"),
            (self.p_min < self.p_max, "p_min must be below p_max"),
            (0 < self.theta < 1, "theta must be in (0, 1)"),
            (self.newton_tol > 0 and self.fold_tol > 0 and self.locate_tol > 0, "newton_tol, fold_tol and locate_tol must be positive"),
            (self.newton_max_iter >= 1 and self.chord_max_iter >= 1 and self.locate_max_iter >= 1,
             "newton_max_iter, chord_max_iter and locate_max_iter must be >= 1"),
            (self.grow >= 1 and 0 < self.shrink < 1, "need grow >= 1 and 0 < shrink < 1"),
            (0 < self.max_angle < math.pi / 2 and 0 < self.target_angle <= self.max_angle,
             "need 0 < target_angle <= max_angle < pi/2"),
            (self.max_distance > 0, "max_distance must be positive"),
            (self.max_change > 0, "max_change must be positive"),
            (0 < self.max_contraction < 1, "need 0 < max_contraction < 1"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(msg)


@dataclass
class Point:
    """One point of a branch: the solution, its tangent and what was found there."""

    x: np.ndarray
    p: float
    tx: np.ndarray
    tp: float
    arclength: float = 0.0
    kind: str = Kind.REGULAR       # a Kind, or "event:<label>"
    iterations: int = 0
    ds: float = 0.0
    det_sign: int = 0
    det_log: float = 0.0
    located: bool = True           # False: a special point bracketed but not located to its tolerance
    data: dict = field(default_factory=dict)
    message: str = ""              # what a special point is (an event's sentence, why a bound stopped)
    solver: object = field(default=None, repr=False)  # corrector matrix for steps from this point


class Action(str, Enum):
    """What a located event does (a string enum: ``"stop"`` and ``Action.STOP`` are the same)."""

    RECORD = "record"    # a point is kept there
    STOP = "stop"        # the trace ends there (a guard)
    SEGMENT = "segment"  # the tracker ends there with Status.SEGMENT, for the caller to go on differently

    def __str__(self) -> str:
        return self.value


@dataclass
class Event:
    """A scalar test function ``g(point)``; a sign change is located.

    ``name``: the event's sentence (a stop's message); ``label``: a short name, the point's kind
    ``event:<label>`` (default: ``name``). ``action``: ``"record"`` (a point is kept there),
    ``"stop"`` (the trace ends there: a guard), or ``"segment"`` (the tracker ends there with
    :attr:`Status.SEGMENT`, for the caller to go on with another discretisation). ``stop=True`` is
    the same as ``action="stop"``. ``status``: the :class:`rodcont.result.Status` a stopping event
    ends the run with (default :attr:`Status.EVENT`; a model's domain guard says
    :attr:`Status.VALIDITY_GUARD`). A stopping event whose ``g`` is already negative at the first
    point stops the trace at once (:attr:`Status.AT_START`).
    """

    name: str
    function: Callable[[Point], float]
    stop: bool = False
    # located where |g| <= tol * max |g| at the two points around the crossing: relative to the step's change
    # of g, not to g at the point before it, which may be already tiny (a restart just short of the event)
    tol: float = 1e-11
    action: Action | str = ""
    label: str = ""
    status: Status | str | None = None

    def __post_init__(self):
        if not self.action:
            self.action = Action.STOP if self.stop else Action.RECORD
        try:
            self.action = Action(self.action)
        except ValueError:
            raise ValueError(f"event action must be record, stop or segment, got {self.action!r}") from None
        self.stop = self.action == Action.STOP
        self.label = str(self.label or self.name)
        if self.status is None:
            self.status = {Action.STOP: Status.EVENT, Action.SEGMENT: Status.SEGMENT}.get(self.action)
        elif self.status is not None:
            self.status = Status(self.status)

    @property
    def kind(self) -> str:
        """The kind of the point where it is located."""
        return f"event:{self.label}"


@dataclass
class Finding:
    """A special point found in a step: where (arclength offset), the point, and what it does."""

    offset: float
    point: Point | None
    stop: StopReason | None = None


# --------------------------------------------------------------------------
# Detectors
# --------------------------------------------------------------------------
class Detector:
    """Looks at each accepted step ``base -> new`` and returns the special points in it."""

    def check(self, tracker: Tracker, base: Point, new: Point, ds: float) -> list[Finding]:
        raise NotImplementedError


class FoldDetector(Detector):
    """Turning points of ``p``: ``tp`` changes sign."""

    def check(self, tracker, base, new, ds):
        s = tracker.settings
        on_fold_start = base.kind == Kind.START and (abs(base.tp) < 1e3 * s.fold_tol or tracker.start_on_fold)
        if base.tp * new.tp < 0 and not on_fold_start:
            f = tracker.locate(base, ds, lambda q: q.tp, base.tp, new.tp, s.fold_tol, Kind.FOLD)
            if f is not None:
                return [Finding(f.ds, f)]
            tracker.not_located(Kind.FOLD, base, new)
        return []

    @staticmethod
    def hidden_pair(base: Point, new: Point, ds: float, tol: float) -> bool:
        """Does the cubic Hermite model of ``p(s)`` on the step turn twice (two folds inside)?

        Its derivative is the quadratic ``q(u) = tp0 (1 - u) + tp1 u + c u (1 - u)``
        with ``c = 6 (dp/ds - (tp0 + tp1)/2)`` (so that ``q`` integrates to ``dp``).
        """
        if ds == 0 or base.tp * new.tp <= 0:
            return False
        c = 6.0 * ((new.p - base.p) / ds - 0.5 * (base.tp + new.tp))
        if c == 0:
            return False
        # q(u) = tp0 + (tp1 - tp0 + c) u - c u^2: vertex at u* = (tp1 - tp0 + c) / (2c)
        u = (new.tp - base.tp + c) / (2.0 * c)
        if not 0 < u < 1:
            return False
        qmin = base.tp + (new.tp - base.tp + c) * u - c * u * u
        return qmin * base.tp < 0 and abs(qmin) > tol


class BranchPointDetector(Detector):
    """Sign changes of ``det`` of the bordered Jacobian (located on ``det`` scaled at the base)."""

    def check(self, tracker, base, new, ds):
        s = tracker.settings
        if base.det_sign * new.det_sign >= 0:
            return []
        ref, s0 = base.det_log, base.det_sign

        def gdet(q):
            return q.det_sign * s0 * math.exp(min(q.det_log - ref, 700.0))

        g1 = -math.exp(min(new.det_log - ref, 700.0))
        f = tracker.locate(base, ds, gdet, 1.0, g1, s.locate_tol, Kind.BRANCH_POINT)
        if f is None:
            tracker.not_located(Kind.BRANCH_POINT, base, new)
            return []
        return [Finding(f.ds, f)]


class ValueDetector(Detector):
    """Crossings of ``p = v``: forced points, or a bound that stops the trace."""

    def __init__(self, values: Sequence[float], kind: str, stop: bool = False, name: str = ""):
        self.values, self.kind, self.stop, self.name = [float(v) for v in values], kind, stop, name

    def check(self, tracker, base, new, ds):
        out = []
        for v in self.values:
            crossed = (base.p - v) * (new.p - v) < 0 or (self.stop and new.p == v and base.p != v)
            if not crossed:
                continue
            # the point at p = v directly: Newton at fixed p from the chord between base and new (two or
            # three iterations where the branch is regular in p); the secant along the arc otherwise
            f = tracker.solve_at_value(base, new, ds, v, self.kind)
            if f is None:
                f = tracker.locate(base, ds, lambda q, v=v: q.p - v, base.p - v, new.p - v, 1e-13 * (1 + abs(v)),
                                   self.kind)
            if f is None:
                continue
            if abs(f.p - v) < 1e-12 * (1 + abs(v)):
                f.p = v
            why = StopReason(Status.BOUND, f"parameter bound {self.name} = {v:g} reached") if self.stop else None
            out.append(Finding(f.ds, f, why))
        return out


class EventDetector(Detector):
    def __init__(self, event: Event):
        self.event = event

    def check(self, tracker, base, new, ds):
        ev = self.event
        g0, g1 = ev.function(base), ev.function(new)
        if tracker.entering.get(id(ev)) is base and g0 < 0 < g1:
            return []  # the first step from a start on the event, heading in (check_start)
        if not g0 * g1 < 0:
            return []
        f = tracker.locate(base, ds, ev.function, g0, g1, ev.tol * max(abs(g0), abs(g1), 1e-300), ev.kind)
        status = ev.status if ev.action in (Action.STOP, Action.SEGMENT) else None
        if f is not None:
            f.message = ev.name
            return [Finding(f.ds, f, StopReason(status, ev.name, ev.label) if status else None)]
        if status is not None:  # crossed but not located: stop before the crossing, say so
            return [Finding(ds, None, StopReason(status, f"{ev.name} (crossed between p = {base.p:.10g} and "
                                                         f"{new.p:.10g}; not located)", ev.label))]
        return []


class StopContinuation(Exception):
    pass


# --------------------------------------------------------------------------
# The tracker
# --------------------------------------------------------------------------
class Tracker:
    """Pseudo-arclength tracker; iterate it to get the points one by one.

    ``monitor(x, p) -> dict`` (optional) adds named scalars to each point's
    ``data``; ``events`` are located where they change sign. After the
    iteration ends, ``stop`` (a :class:`StopReason`) says why, and
    ``stop_reason`` is its message.
    """

    def __init__(self, problem, x0: np.ndarray, p0: float, settings: ContinuationSettings | None = None,
                 monitor: Callable | None = None, events: Sequence[Event] = (), tangent0=None,
                 exact_start: bool = False, detectors: Sequence[Detector] | None = None):
        self.problem = problem
        self.settings = s = settings or ContinuationSettings()
        s.validate()
        self.monitor = monitor
        self.events = list(events)
        self.stop: StopReason | None = None
        self.start_on_fold = False  # the start is a fold in p (found by start(); no fold is reported there)
        self.entering: dict = {}  # id of a stopping event -> the start that lies on it, heading in (check_start)
        # (kind, p before, p after): a fold or branch point detected in a step whose location failed
        # (no point of the bracket converged); the step's end is kept as a regular point
        self.unlocated: list[tuple[str, float, float]] = []
        self.n = np.asarray(x0).size
        # The arclength weights: theta / n on the unknowns, 1 - theta on the parameter, each divided
        # by the square of the problem's own scale of it (``arclength_scale() -> (sx, sp)``, optional),
        # so that a step means the same in any units.
        scale = getattr(problem, "arclength_scale", None)
        sx, sp = scale() if scale is not None else (1.0, 1.0)
        self.wx = s.theta / self.n / np.asarray(sx, float) ** 2
        if np.ndim(self.wx) == 0:
            self.wx = float(self.wx)
        self.wp = (1.0 - s.theta) / float(sp) ** 2
        # the corrector's and Newton's convergence tests in the problem's own units (max norm of (x/ux, p/up):
        # ``unit_scale()``, else the arclength's): on the raw unknowns a change of units moved the fold torque by
        # 9e-8 (tests/test_units.py)
        units = getattr(problem, "unit_scale", None)
        ux, up = units() if units is not None else (sx, sp)
        self._sx = np.broadcast_to(np.asarray(ux, float), (self.n,)).copy()
        self._sy = np.append(self._sx, float(up))
        self._x0, self._p0, self._t0 = np.asarray(x0, float), float(p0), tangent0
        self.steps = 0
        self.newton_iterations = 0
        self.factorisations = 0
        self.current: Point | None = None
        self._previous: Point | None = None  # the point before current, for the second-order predictor
        self.ds = s.ds
        # exact_start: (x0, p0) is a solution and tangent0 the direction to leave it by,
        # used as is (branch switching: at a branch point no bordered system is regular)
        self.exact_start = exact_start
        if exact_start and tangent0 is None:
            raise ValueError("exact_start needs tangent0")
        if detectors is None:
            detectors = []
            if s.detect_folds:
                detectors.append(FoldDetector())
            if s.detect_branch_points:
                detectors.append(BranchPointDetector())
            forced = sorted(set(float(v) for v in s.forced) - {s.p_min, s.p_max})  # bounds are located anyway
            if forced:
                detectors.append(ValueDetector(forced, Kind.FORCED))
            for v, name in ((s.p_max, "p_max"), (s.p_min, "p_min")):
                if math.isfinite(v):
                    detectors.append(ValueDetector([v], Kind.BOUND, stop=True, name=name))
            detectors += [EventDetector(ev) for ev in self.events]
        self.detectors = list(detectors)

    @property
    def stop_reason(self) -> str:
        return self.stop.message if self.stop is not None else ""

    def _wnorm(self, v) -> float:
        """Arclength norm of a vector ``(dx, dp)``."""
        return math.sqrt(float((self.wx * v[:-1]) @ v[:-1]) + self.wp * float(v[-1]) ** 2)

    def _wdot(self, a: Point, b: Point) -> float:
        return float((self.wx * a.tx) @ b.tx) + self.wp * a.tp * b.tp

    def _ymax(self, v) -> float:
        """Max norm of ``(x, p)`` (or of a correction) in the problem's own scales."""
        return max_norm(np.asarray(v, float) / self._sy)

    def _newton(self, x0, p: float, max_iter: int):
        """Newton at fixed ``p`` (:func:`rodcont.linalg.newton_solve`) on the unknowns in their own scales,
        ``x / sx``: its convergence test then means the same in any units."""
        sx = self._sx
        if np.all(sx == 1.0):
            return newton_solve(lambda x: self._linearise(x, p)[:2], lambda x: self.problem.residual(x, p), x0,
                                tol=self.settings.newton_tol, max_iter=max_iter)
        D = sparse.diags(sx)

        def linearise(y):
            F, J = self._linearise(sx * y, p)[:2]
            return F, (J @ D).tocsc() if sparse.issparse(J) else np.asarray(J) * sx

        r = newton_solve(linearise, lambda y: self.problem.residual(sx * y, p), np.asarray(x0, float) / sx,
                         tol=self.settings.newton_tol, max_iter=max_iter)
        r.x = sx * r.x
        return r

    # ---- linear algebra on the problem -----------------------------------
    def _linearise(self, x, p):
        pb = self.problem
        if hasattr(pb, "linearise"):
            return pb.linearise(x, p)
        F = pb.residual(x, p)
        J, Fp = pb.tangent(x, p)
        return F, J, Fp

    def _factorise(self, J, Fp, row):
        """The solver of ``[[J, F_p], [row]]``: the problem's ``bordered_solver(J, b, c, d)`` if it has one
        (the rod keeps the LU of the whole matrix, its border does not fill), else block elimination on the
        LU of ``J`` (:class:`~rodcont.linalg.BorderedSolver`: memory linear in n on FD Bratu,
        benchmarks/bordered_fd.py)."""
        make = getattr(self.problem, "bordered_solver", None) or bordered_solver
        return make(J, np.asarray(Fp, float), row[:-1], row[-1])

    def _border(self, tx, tp) -> np.ndarray:
        return np.append(self.wx * np.asarray(tx, float), self.wp * float(tp))

    def _tangent_at(self, x, p, tx_ref, tp_ref, linearisation=None, arc_residual=None):
        """Unit tangent at a solution, oriented along ``(tx_ref, tp_ref)``; with det and the LU.

        The bordered matrix ``[[J, F_p], [w t_ref]]`` is factorised once: its solve with
        ``(0, 1)`` is the tangent (``c.t = 1 > 0`` orients it along the reference),
        its determinant sign is that of the matrix bordered by the tangent itself
        (no singular matrix in between), and, with its last row changed to the new
        tangent, it is the corrector matrix of the next step. With ``arc_residual``
        (the residual ``g`` of the arclength condition whose border is ``t_ref``) it
        also gives a last Newton correction of ``(x, p)``, returned as ``dy``.
        """
        if linearisation is None:
            linearisation = self._linearise(x, p)
        F, J, Fp = linearisation
        row = self._border(tx_ref, tp_ref)
        lu = self._factorise(J, Fp, row)
        self.factorisations += 1
        rhs = np.zeros(self.n + 1)
        rhs[-1] = 1.0
        t = lu.solve(rhs)
        dy = None if arc_residual is None else lu.solve(-np.append(F, arc_residual))
        tx, tp = t[:-1], float(t[-1])
        norm = math.sqrt(float((self.wx * tx) @ tx) + self.wp * tp * tp)
        sign, log = lu.det()
        tx, tp = tx / norm, tp / norm
        solver = lu.with_last_row(row, self._border(tx, tp), t)
        return tx, tp, sign, log, solver, dy

    def _make_point(self, x, p, base: Point, ds: float, iterations: int, kind=Kind.REGULAR,
                    linearisation=None) -> Point | None:
        """The point at a converged ``(x, p)`` with its tangent, det and corrector matrix;
        None if the tangent system is singular."""
        try:
            tx, tp, sign, log, solver, _ = self._tangent_at(x, p, base.tx, base.tp, linearisation)
        except SingularMatrix:
            return None
        if not (np.all(np.isfinite(tx)) and math.isfinite(tp)):
            return None
        return self._point(x, p, tx, tp, base, ds, iterations, kind, sign, log, solver)

    def _point(self, x, p, tx, tp, base, ds, iterations, kind, sign, log, solver) -> Point:
        pt = Point(x=x, p=p, tx=tx, tp=tp, arclength=base.arclength + ds, kind=kind,
                   iterations=iterations, ds=ds, det_sign=sign, det_log=log, solver=solver)
        if self.monitor is not None:
            pt.data = dict(self.monitor(x, p))
        return pt

    # ---- the corrector -----------------------------------------------------------
    def _augmented_residual(self, y, base: Point, ds: float):
        x, p = y[:-1], y[-1]
        F = self.problem.residual(x, p)
        g = float((self.wx * base.tx) @ (x - base.x)) + self.wp * base.tp * (p - base.p) - ds
        return np.append(F, g)

    def _correct(self, base: Point, ds: float, kind=Kind.REGULAR, max_iter: int | None = None,
                 near: tuple[float, Point] | None = None):
        """Predictor from ``base`` with step ``ds``, then the corrector; returns ``(point, info)``
        or ``(None, why)``.

        Chord iterations with the base matrix first (one residual and one solve
        each); then Newton iterations whose factorisation also gives the tangent:
        the first one that moves the point by less than the tolerance ends the
        corrector, so after a converged chord it costs the one factorisation the
        tangent needs anyway. ``info``: the first chord contraction and the distance
        from the predictor (weighted norm / ds), for step control and the
        branch-jump guards.

        ``near = (ds0, q)``: a point ``q`` already corrected from this ``base`` at ``ds0`` (a
        location's previous iterate). The predictor then starts from ``q`` along its tangent and
        the chord uses ``q``'s factorisation, which is that of this very system (same border row)
        at a nearby point: a location converges with one factorisation per iterate.
        """
        y_pred, chord = self._predict(base, ds, kind, near)
        tol = self.settings.newton_tol
        # The Newton step whose factorisation gives the tangent is applied to the point: after it
        # the error is of the order of the square of that step. So the chord stops, and that step is
        # taken, at NEAR sqrt(tol) (1e-6 for tol = 1e-10); one more correction with the new
        # factorisation then measures what is left, and the point is accepted only if that is below
        # tol. Located points (folds, events) need the tangent itself to the tolerance: the tangent
        # is taken before the last step, so there the step must be below the tolerance.
        accept = max(tol, NEAR * math.sqrt(tol)) if kind == Kind.REGULAR else tol
        info = dict(contraction=0.0, distance=0.0, newton=0, predictor=y_pred[:-1])
        y, iterations = y_pred.copy(), 0
        if chord is not None:
            y, iterations, why = self._chord(y, base, ds, chord, accept, info)
            if why:
                return None, why
        return self._newton_corrector(y, y_pred, base, ds, kind, accept, info, iterations, max_iter)

    def _predict(self, base: Point, ds: float, kind, near) -> tuple:
        """``(y_pred, chord)``: the predicted point (secant-free: along ``base``'s tangent, with the
        tangent's change over the last step as a second-order term on a regular step, or along a
        nearby iterate's tangent, :meth:`_correct`'s ``near``) and the factorisation the chord uses."""
        y_pred = np.append(base.x + ds * base.tx, base.p + ds * base.tp)
        chord = base.solver
        prev = self._previous
        if near is not None and getattr(near[1].solver, "lu", None) is not None:  # a row update of q's solver
            ds0, q = near
            along = self._wdot(q, base)
            if along > 0.5:  # q's tangent crosses the hyperplanes <t_base, y - y_base> = const
                y_pred = np.append(q.x + (ds - ds0) / along * q.tx, q.p + (ds - ds0) / along * q.tp)
                chord = near[1].solver.lu
        elif prev is not None and prev.x.size == base.x.size and base.ds != 0 and kind == Kind.REGULAR:
            # second-order predictor: the tangent's change per unit arclength over the last step
            kx = (base.tx - prev.tx) / base.ds
            kp = (base.tp - prev.tp) / base.ds
            y_pred[:-1] += 0.5 * ds * ds * kx
            y_pred[-1] += 0.5 * ds * ds * kp
        return y_pred, chord

    def _chord(self, y, base: Point, ds: float, chord, accept: float, info: dict) -> tuple:
        """``(y, iterations, why)``: chord iterations on the augmented system with the factorisation
        ``chord`` from ``y``, stopped where they no longer contract by 0.9 (or by ``max_contraction``
        at the first ratio, which ``info["contraction"]`` keeps) or where the predicted error left is
        below ``accept``; ``why`` is the failure (a residual or step not finite), else empty."""
        s = self.settings
        sizes: list[float] = []
        iterations = 0
        for _ in range(s.chord_max_iter):
            r = self._augmented_residual(y, base, ds)
            if not np.all(np.isfinite(r)):
                return y, iterations, "the residual is not finite"
            dy = chord.solve(-r)
            iterations += 1
            size = self._ymax(dy)
            if not math.isfinite(size):
                return y, iterations, "the corrector diverged"
            y_next = y + dy
            scale = accept * (1 + self._ymax(y_next))
            if not sizes:
                y = y_next
                sizes.append(size)
                if size <= 0.1 * scale:
                    break
                continue
            rate = size / sizes[-1] if sizes[-1] > 0 else 0.0
            if len(sizes) == 1:
                # the first ratio: how far the step took the Jacobian from the base's
                info["contraction"] = rate
                if rate > s.max_contraction:
                    break  # too far for the chord: Newton from the first correction
            if rate > 0.9:
                break
            y = y_next
            sizes.append(size)
            if size * rate / max(1 - rate, 1e-3) <= scale:
                break
        return y, iterations, ""

    def _newton_corrector(self, y, y_pred, base: Point, ds: float, kind, accept: float, info: dict,
                          iterations: int, max_iter: int | None):
        """Newton on the augmented system from ``y``, each factorisation also giving the tangent: ``(point,
        info)`` once a step is below ``accept`` (or Newton is at rounding) and what it leaves below the
        tolerance, ``(None, why)`` where it diverges, is singular or runs out of iterations."""
        s = self.settings
        tol = s.newton_tol
        row = self._border(base.tx, base.tp)
        e = np.zeros(self.n + 1)
        e[-1] = 1.0
        prev = math.inf
        prev_res = math.inf
        for _ in range(max_iter or s.newton_max_iter):
            x, p = y[:-1], float(y[-1])
            F, J, Fp = self._linearise(x, p)
            g = float(row[:-1] @ (x - base.x)) + row[-1] * (p - base.p) - ds
            r = np.append(F, g)
            if not np.all(np.isfinite(r)):
                return None, "the residual is not finite"
            res = max_norm(r)
            # converged to rounding: the residual no longer falls and the steps are tiny
            stalled = res >= 0.5 * prev_res and prev <= math.sqrt(tol) * (1 + self._ymax(y))
            prev_res = res
            try:
                lu = self._factorise(J, Fp, row)
            except SingularMatrix:
                return None, "singular Jacobian"
            self.factorisations += 1
            info["newton"] += 1
            iterations += 1
            dy = lu.solve(-r)
            size = self._ymax(dy)
            rounding = size <= math.sqrt(tol) * (1 + self._ymax(y))
            # On a regular step, Newton that does not contract (theta = |dy_k| / |dy_k-1| >= 1) has left
            # its basin: a shorter step is cheaper than the iterations it would waste finding that out,
            # and resolves what the long one jumps (with 2x here, a trace in T missed the split of a
            # contact zone: tests/test_contact.py). A located point may sit on a singular point, where
            # Newton is only linear (theta near 1/2) and rounding makes theta jitter: there only a
            # doubling step counts as divergence.
            if not math.isfinite(size) or (size >= (prev if kind == Kind.REGULAR else 2 * prev) and not rounding):
                self.newton_iterations += iterations
                return None, "the corrector diverged"
            # a residual that stops falling while the steps still contract is a slow (stiff) start of
            # Newton's quadratic phase, not rounding: a stiff contact law showed 3.8e-4 then 6.4e-5 with
            # the residual at 0.1, and the point was off by 1e-6 of the span
            if size <= accept * (1 + self._ymax(y)) or (stalled and rounding and size > 0.25 * prev
                                                       and _at_rounding(F, J, Fp, x, p)):
                tangent = self._unit_tangent(lu, e)
                if tangent is None:
                    return None, "the tangent system is singular"
                tx, tp, t = tangent
                sign, log = lu.det()
                solver = lu.with_last_row(row, self._border(tx, tp), t)
                y = y + dy
                if size > tol * (1 + self._ymax(y)):
                    y, _, done = self._polish(y, lu, base, ds, J, Fp)
                    iterations += 1
                    if not done:
                        prev = size
                        continue
                self.newton_iterations += iterations
                if ds != 0:
                    info["distance"] = self._wnorm(y - y_pred) / abs(ds)
                pt = self._point(y[:-1], float(y[-1]), tx, tp, base, ds, iterations, kind, sign, log, solver)
                return pt, info
            y = y + dy
            prev = size
        self.newton_iterations += iterations
        return None, "the corrector did not converge"

    def _unit_tangent(self, lu, e) -> tuple | None:
        """``(tx, tp, t)``: ``t`` the solution of the bordered system for ``e`` (the last unit vector),
        ``(tx, tp)`` it at unit weighted norm; None where that norm is not finite or zero."""
        t = lu.solve(e)
        tx, tp = t[:-1], float(t[-1])
        norm = math.sqrt(float((self.wx * tx) @ tx) + self.wp * tp * tp)
        if not (math.isfinite(norm) and norm > 0):
            return None
        return tx / norm, tp / norm, t

    def _polish(self, y, lu, base: Point, ds: float, J, Fp) -> tuple:
        """``(y, step, done)``: what the accepted Newton step left, one correction with its factorisation
        (contraction ~ |dy|); ``done`` where that correction is below the tolerance (or at rounding)."""
        tol = self.settings.newton_tol
        r = self._augmented_residual(y, base, ds)
        dy = lu.solve(-r)
        y = y + dy
        step = self._ymax(dy)
        done = step <= tol * (1 + self._ymax(y)) or _at_rounding(r[:-1], J, Fp, y[:-1] - dy[:-1],
                                                                 float(y[-1] - dy[-1]))
        return y, step, done

    # ---- start -------------------------------------------------------------------
    def start(self) -> Point:
        """Converge the first point and its tangent.

        Without a reference direction: Newton at fixed ``p0``, tangent oriented
        along ``direction``. With one (``tangent0``, e.g. the secant to the
        previous point of a stored branch): Newton on ``F = 0`` and
        ``<t_ref, (x - x0, p - p0)> = 0``, which stays regular at a fold.
        """
        s = self.settings
        if self.exact_start:
            tx, tp = np.asarray(self._t0[0], float), float(self._t0[1])
            norm = math.sqrt(float((self.wx * tx) @ tx) + self.wp * tp * tp)
            pt = Point(x=self._x0.copy(), p=self._p0, tx=tx / norm, tp=tp / norm, kind=Kind.START)
            if self.monitor is not None:
                pt.data = dict(self.monitor(pt.x, pt.p))
            self.current = pt
            return pt
        if self._t0 is None:
            tx_ref, tp_ref = np.zeros(self.n), float(s.direction)
            r = self._newton(self._x0, self._p0, 30)
            self.newton_iterations += r.iterations
            x, p = r.x, self._p0
            ok, message = r.converged, r.message
        else:
            tx_ref, tp_ref = np.asarray(self._t0[0], float), float(self._t0[1])
            norm = math.sqrt(float((self.wx * tx_ref) @ tx_ref) + self.wp * tp_ref * tp_ref)
            if not norm > 0 or not math.isfinite(norm):
                raise StopContinuation("the restart direction is zero")
            tx_ref, tp_ref = tx_ref / norm, tp_ref / norm
            base = Point(x=self._x0, p=self._p0, tx=tx_ref, tp=tp_ref)
            pt, why = self._correct(base, 0.0, kind=Kind.START, max_iter=30)
            if pt is None:
                raise StopContinuation(f"no convergence at the starting point ({why})")
            pt.arclength = 0.0
            self.current = pt
            return pt
        pt = None
        if ok:
            base = Point(x=x, p=p, tx=tx_ref, tp=tp_ref)
            pt = self._make_point(x, p, base, 0.0, 0, kind=Kind.START)
        if pt is None:
            # at a fold in p (e.g. a stored fold in another parameter) J is singular: neither Newton at
            # fixed p nor the tangent bordered by (0, 1) is regular; [J, F_p] still has a one-dimensional
            # null space, and a start along it is the regular restart above
            try:
                self._t0 = self._null_direction(self._x0, self._p0, s.direction)
            except SingularMatrix:
                self._t0 = None
            if self._t0 is None:
                if not ok:
                    raise StopContinuation(f"no convergence at the starting point ({message})")
                raise StopContinuation("the starting point is singular (no unique tangent): use branch switching")
            pt = self.start()
            # a fold in p: p moves the same way on both sides, so the requested direction cannot choose
            self.start_on_fold = abs(pt.tp) < 1e-6
            return pt
        pt.arclength = 0.0
        self.current = pt
        return pt

    def _null_direction(self, x, p, direction: float):
        """A null vector ``(tx, tp)`` of ``[J, F_p]`` at ``(x, p)``, with ``tp`` along ``direction``
        (at a fold in p, where ``tp`` is rounding, either side); None where ``[J, F_p]`` is not of full
        rank (a branch point). The border is a fixed random row: regular wherever the rank is full."""
        # (x need not solve F = 0: a stored fold moved to a finer mesh is near its fold, not on it; the
        # start along this direction corrects it on the hyperplane through x, or fails and says so)
        F, J, Fp = self._linearise(x, p)
        row = np.random.default_rng(20261123).standard_normal(self.n + 1)
        lu = self._factorise(J, Fp, row)
        e = np.zeros(self.n + 1)
        e[-1] = 1.0
        t = lu.solve(e)
        if not np.all(np.isfinite(t)):
            return None
        # a null vector: [J, F_p] t vanishes relative to the size of t (rank deficiency leaves it large)
        defect = max_norm(J @ t[:-1] + np.asarray(Fp, float) * t[-1])
        scale = max_norm(t) * max(abs(J).max(), max_norm(np.asarray(Fp, float)), 1.0)
        if not defect <= 1e-8 * scale:
            return None
        if t[-1] * direction < 0:
            t = -t
        return t[:-1], float(t[-1])

    def check_start(self, pt: Point) -> StopReason | None:
        """Why the run may not go on from its first point ``pt``: a bound or a stopping event already
        violated there (:attr:`Status.AT_START`), or a bound it heads out of (:attr:`Status.BOUND`);
        None when it may."""
        s = self.settings
        if not s.p_min <= pt.p <= s.p_max:
            return StopReason(Status.AT_START, f"the start p = {pt.p:.10g} is outside the bounds "
                                             f"[{s.p_min:g}, {s.p_max:g}]")
        if (pt.p >= s.p_max and pt.tp > 0) or (pt.p <= s.p_min and pt.tp < 0):
            return StopReason(Status.BOUND, f"parameter bound {'p_max' if pt.tp > 0 else 'p_min'} = "
                                          f"{s.p_max if pt.tp > 0 else s.p_min:g} reached at the start")
        for ev in self.events:
            if ev.action not in (Action.STOP, Action.SEGMENT):
                continue
            g = ev.function(pt)
            if (g < 0 and not self._enters(ev, pt)) or (g >= 0 and self._leaves(ev, pt, g)):
                return StopReason(Status.AT_START if ev.action == Action.STOP else Status.SEGMENT,
                                  f"{ev.name} (already at the start)", ev.label)
        return None

    def _leaves(self, ev: Event, pt: Point, g0: float) -> bool:
        """Is ``pt`` on the event, heading out: ``g`` crosses zero within a thousandth of one smallest step along its
        tangent? (A guard's located point read a hair inside on one machine and a hair outside on another: the
        restart on past it was refused on one only, test_the_last_point_of_a_finished_branch_restarts_back_along_it;
        an event a hundredth of that step ahead is located, test_an_event_just_ahead_of_the_start_is_located_...)"""
        q, _ = self._correct(pt, self.settings.ds_min)
        if q is None:
            return False
        g1 = ev.function(q)
        return g1 < 0 <= g0 <= 1e-3 * (g0 - g1)

    def _enters(self, ev: Event, pt: Point) -> bool:
        """Is ``pt`` on the event, heading in: inside (``g > 0``) one smallest step along its tangent? (The
        last point of a run that a guard stopped, restarted back along the branch, is located to the guard's
        tolerance, often a hair outside: it was refused, test_a_finished_branch_restarts_back_from_its_guard.)
        The event then ignores its crossing back in during the first step."""
        q, _ = self._correct(pt, self.settings.ds_min)
        if q is None or not ev.function(q) > 0:
            return False
        self.entering[id(ev)] = pt
        return True

    def resume(self, pt: Point) -> None:
        """Go on from ``pt`` (a point of this problem with its tangent, e.g. the start re-converged by
        :meth:`start`): the iteration's first step leaves from it, without the start's checks."""
        self.current = pt
        self._previous = None

    # ---- location of special points --------------------------------------------
    def locate(self, base: Point, ds_hi: float, g: Callable[[Point], float], g0: float, g1: float,
               tol: float, kind: str, continuous: bool = True) -> Point | None:
        """Secant (Illinois) on ``g`` along the arc from ``base``; ``g(0) = g0``, ``g(ds_hi) = g1``.

        Returns the located point (``located`` True when ``|g| <= tol``), the
        best bracketed one otherwise, or None if no point in the bracket converged.
        A bracket that shrinks to rounding with ``|g|`` still above ``tol``: where ``g``
        may jump (``continuous`` False: a quantity sampled on a grid) that is the
        location; where it is continuous (the tangent's ``dp/ds``, a determinant) it is
        the location to rounding if the points on the bracket's two sides are the same
        solution, but if they differ (by more than 1e-9 in the arclength norm) the two
        sides lie on different branches (seen at a crossing of two branches, 5e-5 from
        it, the point on the other branch) and the point is kept as bracketed.
        """
        s = self.settings
        a, b, fa, fb = 0.0, ds_hi, g0, g1
        side = 0
        best = last = None
        ends = [base, None]  # the converged points at a and b (None: the step's end, not at hand)
        for _ in range(s.locate_max_iter):
            m = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
            if not (min(a, b) < m < max(a, b)):
                m = 0.5 * (a + b)
            pt = None
            for nudge in (0.0, 1e-9, -1e-9):  # exactly on a branch point the bordered matrix is singular
                mm = m + nudge * ds_hi
                pt, _ = self._correct(base, mm, kind=kind, near=last)
                if pt is None and last is not None:  # from the base itself, as the first iterate
                    pt, _ = self._correct(base, mm, kind=kind)
                if pt is not None:
                    m = mm
                    break
            if pt is None:
                break
            last = (m, pt)
            fm = g(pt)
            best = pt
            if abs(fm) <= tol:
                return pt
            if (fm > 0) == (fb > 0):
                b, fb = m, fm
                ends[1] = pt
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                a, fa = m, fm
                ends[0] = pt
                if side == 1:
                    fb *= 0.5
                side = 1
            if abs(b - a) <= 1e-15 * (1 + abs(ds_hi)):
                qa, qb = ends
                if continuous and qb is not None:
                    pt.located = self._wnorm(np.append(qa.x - qb.x, qa.p - qb.p)) <= 1e-9 * (1 + abs(ds_hi))
                return pt
        if best is not None:
            best.located = False
        return best

    def solve_at_value(self, base: Point, new: Point, ds: float, v: float, kind) -> Point | None:
        """The branch point with parameter exactly ``v`` between ``base`` and ``new`` (Newton at fixed ``p``),
        or None if Newton there does not converge (near a fold)."""
        theta = (v - base.p) / (new.p - base.p) if new.p != base.p else 0.5
        x0 = base.x + theta * (new.x - base.x)
        r = self._newton(x0, v, 6)
        self.newton_iterations += r.iterations
        if not r.converged:
            return None
        step = self._wnorm(np.append(new.x - base.x, new.p - base.p))
        if self._wnorm(np.append(r.x - x0, 0.0)) > 0.5 * step:
            return None  # Newton went elsewhere: not the point between these two
        pt = self._make_point(r.x, v, base, theta * ds, r.iterations, kind=kind)
        if pt is None or self._wdot(pt, base) <= 0:
            return None
        return pt

    def _guards_at_found(self, base: Point, found: list[Finding]) -> list[Finding]:
        """A stopping event can be crossed between the base and a located point even when it is not
        crossed between the base and the step's end (a guard that dips at a fold): then it is
        located on that shorter arc, and the trace stops there."""
        for ev in self.events:
            if ev.action != Action.STOP:
                continue
            g0 = ev.function(base)
            if self.entering.get(id(ev)) is base:  # a start on the event, heading in (check_start)
                continue
            for j, f in enumerate(found):
                if f.point is None or f.stop is not None or g0 * ev.function(f.point) >= 0:
                    continue
                g1 = ev.function(f.point)
                e = self.locate(base, f.offset, ev.function, g0, g1, ev.tol * max(abs(g0), abs(g1), 1e-300),
                                ev.kind)
                stop = StopReason(ev.status, ev.name, ev.label)
                if e is None:
                    return found[:j] + [Finding(f.offset, None, stop)]
                e.message = ev.name
                return found[:j] + [Finding(e.ds, e, stop)]
        return found

    def not_located(self, kind, base: Point, new: Point) -> None:
        """A detected special point whose location failed: recorded and warned, never dropped silently."""
        self.unlocated.append((str(kind), float(base.p), float(new.p)))
        warnings.warn(f"a {str(kind).replace('_', ' ')} between p = {base.p:.10g} and {new.p:.10g} was detected "
                      f"but could not be located (no point between them converged)", RuntimeWarning, stacklevel=3)

    def _accept(self, pt: Point) -> None:
        """Make ``pt`` the current point; problems with an ``accept(x, p)`` hook are told."""
        self._previous = self.current
        self.current = pt
        hook = getattr(self.problem, "accept", None)
        if hook is not None:
            hook(pt.x, pt.p)

    # ---- one step ------------------------------------------------------------------
    def _try_step(self, base: Point, ds: float):
        """Corrector and acceptance tests for one step; returns ``(point, info)`` or ``(None, why)``."""
        s = self.settings
        new, info = self._correct(base, ds)
        if new is None:
            return None, info
        x_pred = info.pop("predictor")
        if info["distance"] > s.max_distance:
            return None, "the corrector moved too far from the predictor (another branch?)"
        cos_t = self._wdot(new, base)
        sec = np.append(new.x - base.x, new.p - base.p)
        sec_norm = self._wnorm(sec)
        cos_s = (float((self.wx * base.tx) @ sec[:-1]) + self.wp * base.tp * sec[-1]) / sec_norm if sec_norm > 0 else 1.0
        if min(cos_t, cos_s) < math.cos(s.max_angle):
            return None, "the tangent turns too fast"
        if s.detect_folds and s.detect_fold_pairs and FoldDetector.hidden_pair(base, new, ds, s.fold_tol):
            return None, "two folds in one step"
        change = getattr(self.problem, "relative_change", None)
        if change is not None:
            # a change of the solution's shape that the arclength norm hardly sees (a small
            # deflection doubling, or flipping onto a nearby branch): resolve it with shorter steps
            info["change"] = float(change(base.x, new.x))
            if info["change"] > s.max_change:
                return None, "the solution changes too much in one step (another branch?)"
        correction = getattr(self.problem, "relative_correction", None)
        if correction is not None and base.x.size == new.x.size:
            # seen: a trace in T of a rod pressed on a wall, with ds_max = 2, converged from the bent rod's
            # predictor onto the straight rod (the deflection removed: 1.0; the arclength distance 0.03)
            info["correction"] = float(correction(base.x, x_pred, new.x))
            if info["correction"] > s.max_change:
                return None, "the corrector changed the solution's shape more than the step predicted (another branch?)"
        info["angle"] = math.acos(min(1.0, cos_t))
        return new, info

    def _next_ds(self, ds: float, info: dict) -> float:
        """Step control on the measured contraction, distance and angle (Allgower & Georg)."""
        s = self.settings
        factors = [s.grow]
        if info.get("angle", 0) > 0:
            factors.append(s.target_angle / info["angle"])
        if info.get("newton", 0) > 1:  # the chord did not converge: a step this long is enough
            factors.append(1.0)
        if info.get("change", 0) > 0:
            factors.append(0.5 * s.max_change / info["change"])
        if info.get("distance", 0) > 0:
            factors.append(math.sqrt(0.5 * s.max_distance / info["distance"]))
        f = max(s.shrink, min(factors))
        return min(max(abs(ds) * f, s.ds_min), s.ds_max)

    # ---- iteration -----------------------------------------------------------------
    def __iter__(self) -> Iterator[Point]:
        if self.current is None:
            first = self.start()
            yield first
            why = self.check_start(first)
            if why is not None:
                self.stop = why
                return
        s = self.settings
        while True:
            if self.steps >= s.max_steps:
                self.stop = StopReason(Status.MAX_STEPS, f"maximum number of steps ({s.max_steps}) reached")
                return
            base = self.current
            # factorise at the base once (a point without a corrector matrix); not at an exact start, a branch point
            # where the bordered matrix is singular by construction: its LU (regular by rounding) sent the chord
            # off and the corrector diverged at every step size (a switch from a critical twist of the straight rod)
            if base.solver is None and not (self.exact_start and base.kind == Kind.START):
                lin = self._linearise(base.x, base.p)
                try:
                    base.solver = self._tangent_at(base.x, base.p, base.tx, base.tp, lin)[4]
                except SingularMatrix:
                    base.solver = None
            ds = self.ds
            while True:
                new, info = self._try_step(base, ds)
                if new is not None:
                    break
                ds *= s.shrink
                if ds < s.ds_min:
                    self.stop = StopReason(Status.STEP_TOO_SMALL, f"step size fell below ds_min = {s.ds_min:g} "
                                                                f"({info}) at p = {base.p:.10g}")
                    return
            self.steps += 1
            found: list[Finding] = []
            for det in self.detectors:
                found += det.check(self, base, new, ds)
            found.sort(key=lambda f: f.offset)
            found = self._guards_at_found(base, found)
            for f in found:
                # the stop is set before its point is handed over: a consumer deciding what to do with
                # the point (e.g. refine the mesh and go on from it) sees that the tracker ends there
                if f.stop is not None:
                    self.stop = f.stop
                    if f.point is not None and not f.point.message:
                        f.point.message = f.stop.message
                if f.point is not None:
                    self._accept(f.point)
                    yield f.point
                if f.stop is not None:
                    return
            self._accept(new)
            yield new
            self.ds = self._next_ds(ds, info)


def continuation(problem, x0, p0, settings: ContinuationSettings | None = None, monitor=None,
                 events: Sequence[Event] = (), callback: Callable[[Point], None] | None = None,
                 tangent0=None, exact_start: bool = False, param: str = "p") -> ContinuationResult:
    """Trace a branch on a fixed discretisation; returns a :class:`rodcont.result.ContinuationResult`.

    Its table has the columns ``param`` (the parameter's name), ``arclength``, ``kind``,
    ``located`` and the scalars ``monitor(x, p)`` returns; ``status``/``message`` say why it ended
    (:attr:`Status.START_FAILED` when no first point converged). ``callback`` sees each point as it
    comes. For a problem on a mesh that should adapt, see :func:`rodcont.adaptive.adaptive_continuation`.
    """
    from dataclasses import asdict
    s = settings or ContinuationSettings()
    result = ContinuationResult(param, settings={"continuation": asdict(s)})
    tr = Tracker(problem, x0, p0, s, monitor, events, tangent0, exact_start)
    tr.unlocated = result.unlocated
    try:
        for pt in tr:
            result.add(pt)
            if callback is not None:
                callback(pt)
    except StopContinuation as exc:
        tr.stop = StopReason(Status.START_FAILED, str(exc))
    result.set_status(tr.stop.status if tr.stop is not None else Status.MAX_STEPS, tr.stop_reason)
    result.steps, result.newton_iterations = tr.steps, tr.newton_iterations
    return result


class _CallableModule(type(math)):
    """This module, callable as its function :func:`continuation`: the package re-exports the function under
    the module's own name, so ``rodcont.continuation`` is one object whatever was imported first (the module,
    ``import rodcont.continuation as m``, and the function, ``rodcont.continuation(problem, x0, p0)``)."""

    def __call__(self, *args, **kwargs) -> ContinuationResult:
        return continuation(*args, **kwargs)


__import__("sys").modules[__name__].__class__ = _CallableModule
