"""Trace one branch of the rod: in ``phi_L`` (the end rotation) or in any rod parameter.

A thin configuration of the generic adaptive engine (:mod:`rodcont.adaptive`): the rod's
system (:class:`rodcont.system.RodSystem`, a meshed problem), its guards as events (the
validity guard ``min d3.K3 = min_alignment``: the rod about to fold back over the reference
curve, status ``validity_guard``; the stretch factor reaching 0; ``stretch_max``), the
contact-zone detector of each mesh in a conduit (:class:`ZoneChangeDetector`), the count of
unstable modes of each stored point (:class:`StabilityCount`, an observer), and a recorder
that writes the branch file as it goes (:class:`Recorder`). :class:`TraceOptions` names every
knob once (:mod:`rodcont.settings`); the engine's settings are made from them.

Every guard and bound is also checked at the first point: a start already
outside them is refused (``ValueError``), one on a bound and heading out of
it stops at once.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields

import numpy as np

from ..adaptive import Accuracy, AdaptiveContinuation, Hints, ResultRecorder, StartError
from ..blas import with_one_blas_thread
from ..branch import CONTACT_COLUMNS, DRILLING_COLUMNS, Branch
from ..continuation import ContinuationSettings, Detector, Event, Finding, Kind, Point, StopContinuation, Tracker
from ..linalg import scaled_smallest_singular_value
from ..result import Status
from ..rod import RodParameters
from ..settings import TraceOptions
from ..system import SYSTEM_PARAMS, RodSystem, check_mapping, check_number, controls_spec
from .solve import check_tension

__all__ = ["Accuracy", "Recorder", "StabilityCount", "TraceError", "TraceOptions", "ZoneChangeDetector", "run",
           "straight_seed", "switch_direction", "trace"]


class TraceError(StartError):
    """A trace that cannot start (the message says why, in one line)."""


OPTION_NAMES = tuple(f.name for f in fields(TraceOptions))

#: Seconds between returns of the C heap's free pages to the system in a trace (None: never); see
#: :class:`rodcont.linalg.HeapTrimmer`.
TRIM_INTERVAL: float | None = 0.25


class StabilityCount:
    """The number of unstable modes of each stored point (:func:`rodcont.stability.unstable_modes`): an
    observer of the engine (:mod:`rodcont.adaptive`), called before each point is stored.

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
    buckling in a pipe) leaves unchanged. Where the count changed is then found
    by bisection over the stored points since the last count (counted at those
    with a solution; one without, in a thinned run, carries its neighbour's), and
    the column is corrected there, in memory and in the file. That is reported in
    ``missed`` (and warned): ``(parameter before, parameter after, count before,
    count after)``, the interval the bisection left around the change(s).
    """

    def __init__(self, every: int = 50):
        self.every = every
        self.last = None
        self.fresh = True
        self.since = 0
        self.ref = None       # (count, parameter, index) at the last counted non-singular point
        self.crossings = 0    # folds and branch points located since then
        self.missed: list = []
        self.k = 8            # eigenvalues asked of ARPACK: the last count's (it grows along a branch)

    def count(self, system: RodSystem, x, value: float) -> int:
        """Method 1 at one point of ``system``, under its own end conditions (a stored solution, without the
        freed parameters, is expanded first): with ``Phi`` imposed, or under a torque the rotation free."""
        from ..stability import spectrum
        x = system.expanded(x)
        p = system.params(value)
        physical = system.without_phase()  # a phase condition fixes the turn only: counted without it
        if physical is not system:
            x, system = physical.expanded(system.stored(x)), physical
        try:
            sp = spectrum(system, x, float(p[0]), k=self.k, params=p)
        except Exception as exc:  # noqa: BLE001 - an eigensolver failure is a missing count, said so
            raise RuntimeError(f"stability count failed at {system.param} = {value:.10g}: {exc}") from exc
        self.k = max(sp.k, 8)
        return int(sp.unstable)

    def __call__(self, system: RodSystem, pt: Point, recorder=None) -> int:
        if not system.straight:
            pt.data["unstable_modes"] = -1
            return -1
        self._system = system
        self.since += 1
        special = pt.kind not in (Kind.REGULAR,)
        if self.last is None or self.fresh or special or self.since >= self.every:
            index = len(recorder.result) if recorder is not None else None
            self._check(system, self.count(system, pt.x, pt.p), pt, index, recorder)
            self.fresh = special and (pt.kind != Kind.START or self.ref is None)
        pt.data["unstable_modes"] = self.last
        return self.last

    def _check(self, system, n: int, pt: Point, index, recorder) -> None:
        if pt.kind in (Kind.FOLD, Kind.BRANCH_POINT):
            self.crossings += 1  # singular here: its count is not a reference
        elif pt.kind == Kind.START and self.ref is None:
            pass  # a trace may start at a fold or a branch point (a restart, a switch): not a reference
        else:
            if self.ref is not None and abs(n - self.ref[0]) > self.crossings:
                self._missed(system, n, float(pt.p), index, recorder)
            self.ref, self.crossings = (n, float(pt.p), index), 0
        self.last, self.since = n, 0

    def finish(self, recorder) -> None:
        """The last stored point, if its count was carried: counted, and the column corrected if it changed."""
        result = recorder.result
        i = len(result) - 1
        if self._system is None or self.since == 0 or self.ref is None or i < 0 \
                or not np.size(result.coefficients[i]):
            return
        system = self._system_at(self._system, result, i)
        p = float(result.table[result.param][i])
        n = self.count(system, result.coefficients[i], p)
        if n != result.table["unstable_modes"][i]:
            if abs(n - self.ref[0]) > self.crossings:
                self._missed(system, n, p, i, recorder)
            recorder.correct("unstable_modes", i, n)

    def _missed(self, system, n: int, p: float, index, recorder) -> None:
        n0, p0 = self.ref[0], self.ref[1]
        bracket = (p0, p)
        if recorder is not None and index is not None and self.ref[2] is not None:
            result = recorder.result
            lo, hi = self._bisect(system, recorder, self.ref[2], index, n0, n)
            value = lambda j: float(result.table[result.param][j]) if j < len(result) else p  # noqa: E731
            bracket = (value(lo), value(hi))
        self.missed.append((bracket[0], bracket[1], n0, n))
        warnings.warn(f"the number of unstable modes changed from {n0} to {n} between {system.param} = "
                      f"{bracket[0]:.10g} and {bracket[1]:.10g} across {self.crossings} located fold(s) or branch "
                      f"point(s): more eigenvalues crossed zero than were seen (the branch-point test watches a "
                      f"determinant's sign, which two crossings in one step leave unchanged); "
                      + crossing_advice(system.model, system.param), RuntimeWarning, stacklevel=3)

    _system = None

    @staticmethod
    def _system_at(system, result, i):
        mesh = np.asarray(result.meshes[i], float)
        return system if np.array_equal(mesh, system.breakpoints) else system.with_mesh(mesh)

    def _bisect(self, system, recorder, i0: int, i1: int, n0: int, n1: int):
        """Counts at stored points between ``i0`` (count ``n0``) and ``i1`` (``n1``; the point about to be
        stored, or the last one) by bisection, the column corrected between; the bracket of the change(s)."""
        result = recorder.result
        kinds, values = result.table["kind"], result.table[result.param]
        probes = [j for j in range(i0 + 1, min(i1, len(result))) if kinds[j] in ("regular", "forced")
                  and np.size(result.coefficients[j])]
        known = {i0: n0, i1: n1}

        def split(a, b):
            inner = [j for j in probes if a < j < b]
            if known[a] == known[b] or not inner:
                return
            m = inner[len(inner) // 2]
            known[m] = self.count(self._system_at(system, result, m), result.coefficients[m], float(values[m]))
            split(a, m)
            split(m, b)

        split(i0, i1)
        value = n0
        for j in range(i0 + 1, min(i1, len(result))):
            if j in known:
                value = known[j]
            elif kinds[j] not in ("regular", "forced"):
                continue  # a special point keeps its own count
            if result.table["unstable_modes"][j] != value:
                recorder.correct("unstable_modes", j, value)
        order = sorted(known)
        first = next(j for j in order if known[j] != n0)
        last = next(j for j in reversed(order) if known[j] != n1)
        lo = order[order.index(first) - 1]
        hi = order[order.index(last) + 1]
        return lo, hi

# --------------------------------------------------------------------------
# Starts
# --------------------------------------------------------------------------
def straight_seed(rod: RodParameters, T: float, phi_L: float, N: int = 15, k: int = 5,
                  breakpoints=None, ends=None) -> tuple[RodSystem, np.ndarray]:
    """A solution of the heavy rod near the straight twisted state at ``phi_L`` (and tension ``T``).

    The weightless straight state is exact for every ``phi_L``; it is continued
    in ``w`` from 0 to the rod's weight at fixed ``phi_L`` and ``T``
    (pseudo-arclength, so a fold in ``w`` is passed; the homotopy must reach
    the rod's weight without leaving the Eulerian domain). Raises
    :class:`TraceError` when it cannot. ``ends``: other end conditions (:class:`rodcont.ends.RodEnds`),
    held during the homotopy (the unstressed length, or the torque, instead of ``T`` or ``phi_L``).
    """
    if rod.w == 0:  # the straight state itself (under a phase condition w is an unknown: no homotopy in it)
        sysw = RodSystem(rod, T=T, N=N, k=k, phi_L=phi_L, breakpoints=breakpoints, ends=ends,
                         param="torque" if "phi_L" in getattr(ends, "frees", ()) else "phi_L")
        return sysw, sysw.straight_state(phi_L)
    sysw = RodSystem(rod, T=T, N=N, k=k, param="w", phi_L=phi_L, breakpoints=breakpoints, ends=ends)
    x0 = sysw.straight_state(phi_L)
    # steps in units of the dimensionless weight W = w L^3 / EI (in units of w they were 1e10 times too long or
    # short in other units, tests/test_units.py; W = w for the paper's rod, L = EI = 1, as before)
    W = rod.w * rod.L**3 / rod.EI
    s = ContinuationSettings(ds=0.2 * W, ds_min=1e-9 * W, ds_max=W, p_min=-0.5 * rod.w, p_max=rod.w,
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
class Recorder(ResultRecorder):
    """Adds points to a :class:`Branch` and, if any, to a branch-file group; publishes
    the file on every special point and at least every second."""

    def __init__(self, branch: Branch, writer=None, group=None, contact: _ContactRows | None = None,
                 thin: int = 1):
        """``thin = M > 1``: the branch in memory keeps what a file written with ``store_every = M`` keeps
        (the solution of every M-th point, of the special points and of the last; tangents at the special
        points and the last), so a long trace's memory does not grow with every point's unknowns."""
        super().__init__(branch)
        self.branch, self.writer, self.group, self.contact = branch, writer, group, contact
        self.thin = int(thin)
        # True while points traced elsewhere are copied in one go: the file is published once they are all in
        # (a diagram's branch from its workers published at each special point took 0.4 s of the main process)
        self.deferred = False

    def add(self, pt: Point, problem) -> int:
        # without the freed parameters (a torque's phi_L, a length's T: columns of the row), as every control stores
        x, tx = (problem.stored(pt.x), problem.stored(pt.tx)) if hasattr(problem, "stored") else (pt.x, pt.tx)
        return self.add_row(self.branch.row(pt), x, np.append(tx, pt.tp), problem.breakpoints, pt.message)

    def add_row(self, row: dict, solution, tangent, breakpoints, message: str = "") -> int:
        """Append one point by its row of values (a tracker point's, or a stored one's)."""
        if self.thin > 1 and len(self.branch):
            # the previous point is no longer the last (its contact rows are computed: fill ran at its add)
            self.branch.thin(len(self.branch) - 1, self.thin)
        i = self.branch.add_row(row, solution, tangent, breakpoints, message)
        if self.writer is not None:
            self.writer.add_point(self.group, dict(row), row["kind"], row["located"], solution, tangent,
                                  breakpoints)
            if self.contact is not None:
                self.contact.fill(self.branch)
            if not self.deferred and (row["kind"] != Kind.REGULAR or self.writer.due()):
                self.sync()
                self.writer.flush()
        return i

    def copy(self, source: Branch, i: int, kind: str | None = None) -> int:
        """Append point ``i`` of another branch as it is stored there (its kind replaced by ``kind``)."""
        row = source.row_at(i)
        if kind is not None:
            row["kind"] = kind
        return self.add_row(row, source.coefficients[i], source.tangents[i], source.meshes[i],
                            source.messages.get(i, ""))

    def correct(self, name: str, i: int, value) -> None:
        self.branch.table[name][i] = value
        if self.writer is not None:
            self.group.correct(name, i, value)

    def sync(self) -> None:
        if self.writer is not None:
            self.group.set_special(self.branch.folds, list(self.branch.branch_points), self.branch.special)


class _RodHints(Hints):
    """Where a trace fails, the rod's likely causes."""

    def start_failed(self, problem) -> str:
        # a contact on a mesh too coarse for it is the usual cause in a conduit (the 1 km well at the default
        # N = 15, 61 with its stations: elements of 16 m in a 5 cm clearance; N = 200 starts)
        if problem.wall is None:
            return ""
        return f" (N = {problem.disc.N} may be too coarse for the contact: raise --N)"

    def stopped(self, status, problem, last) -> str:
        return _symmetry_hint(problem) or (_singular_hint(*last) if last else "")


def _zone_detectors(system: RodSystem) -> list:
    """Inside a conduit: contact onset, lift-off, merges and splits (one detector per mesh)."""
    return [ZoneChangeDetector(system)] if system.wall is not None else []


# --------------------------------------------------------------------------
# The driver
# --------------------------------------------------------------------------
def run(system: RodSystem, x0: np.ndarray, p0: float, options: TraceOptions, tangent0=None, exact: bool = False,
        branch: Branch | None = None, recorder: Recorder | None = None,
        callback: Callable[[Point], None] | None = None, settings: ContinuationSettings | None = None) -> Branch:
    """Trace from ``(x0, p0)`` on ``system`` (its parameter continued) with ``options``; fills ``branch``.

    ``tangent0``: the direction to leave by (``(tx, tp)``), else ``options.direction``
    in the parameter. ``exact``: ``(x0, p0)`` is a solution used as is (branch switching).
    The engine is :class:`rodcont.adaptive.AdaptiveContinuation`; a first point that cannot be
    made is a :class:`TraceError`.
    """
    o = options
    rod = system.rod
    if branch is None:
        branch = Branch(system.gamma if rod.w > 0 else math.nan, rod, system.disc.N, system.disc.k, system.param,
                        curve=system.curve, wall=system.wall)
    recorder = recorder or Recorder(branch)
    settings = settings or o.continuation_settings(system.param)
    stability = StabilityCount()
    stability.missed = branch.missed_crossings
    branch.settings["trace"] = o.as_dict()
    watch = PenetrationWatch()
    observers = [stability] + ([_phi_rate] if "phi_L" in system.freed else []) + \
        ([watch] if system.wall is not None else [])
    engine = AdaptiveContinuation(system, x0, p0, settings, o.adaptive_settings(), tangent0=tangent0,
                                  exact_start=exact, events=o.events() + _phi_bounds(system, o),
                                  detectors=_zone_detectors, observers=observers, recorder=recorder,
                                  callback=callback, hints=_RodHints(), heap_trim_interval=TRIM_INTERVAL)
    try:
        engine.run()
    except StartError as exc:
        raise TraceError(str(exc), exc.status) from None
    if watch.crossed is not None:
        branch.penetration_guard = list(watch.crossed)
        warnings.warn(watch.message(system), RuntimeWarning, stacklevel=2)
    return branch


def _phi_rate(system: RodSystem, pt: Point, recorder=None) -> None:
    """Under a prescribed torque ``phi_L`` is an unknown: ``dphi_ds`` is its component of the tangent."""
    pt.data["dphi_ds"] = float(pt.tx[system.free_position("phi_L")])


def _phi_bounds(system: RodSystem, o: TraceOptions) -> list[Event]:
    """Under a prescribed torque ``phi_L`` is solved for: ``phi_min``, ``phi_max`` bound it as events."""
    if "phi_L" not in system.freed:
        return []
    return [Event(f"phi_L reached phi_max = {o.phi_max:g}", lambda q: o.phi_max - q.data["phi_L"], stop=True,
                  label="phi_max", status=Status.BOUND),
            Event(f"phi_L reached phi_min = {o.phi_min:g}", lambda q: q.data["phi_L"] - o.phi_min, stop=True,
                  label="phi_min", status=Status.BOUND)]


def _options(options: dict, where: str) -> TraceOptions:
    try:
        return TraceOptions(**options)
    except TypeError as exc:
        raise TypeError(str(exc).replace("TraceOptions.__init__()", where)) from None


TRACE_PARAMS = SYSTEM_PARAMS + ("torque", "l0")


def trace_ends(l0=None, torque=None, param: str = "phi_L", phase: bool = False):
    """The end conditions of a trace (:class:`rodcont.ends.RodEnds`): the unstressed length ``l0`` prescribed
    (``T`` solved for), a torque prescribed (``torque``: ``phi_L`` solved for) or continued
    (``param = "torque"``, from ``torque`` or 0); otherwise ``Phi`` and ``T``; ``phase``: a phase condition
    (:class:`rodcont.ends.Phase`, for the weightless rod). ``ValueError`` for a combination that continues a
    parameter solved for."""
    from ..ends import Clamp, Phase, RodEnds, Rotation, Tension, Torque, UnstressedLength
    if not isinstance(phase, (bool, np.bool_)):
        raise TypeError(f"phase must be True or False, got {phase!r}")
    if phase and param == "w":
        raise ValueError("under a phase condition the weight is solved for (0 on every equilibrium): it cannot "
                         "be continued")
    if torque is not None:
        torque = check_number("torque", torque)
        if param == "phi_L":
            raise ValueError("under a prescribed torque phi_L is solved for: continue the torque itself "
                             "(param='torque', --param torque) or a rod parameter")
    if l0 is not None:
        l0 = check_number("l0", l0, positive=True)
        if param in ("T", "gamma"):
            raise ValueError("under a prescribed unstressed length l0 the tension is solved for: it cannot be "
                             "continued (continue l0 itself, param='l0', --param l0)")
    elif param == "l0":
        raise ValueError("param='l0' continues the unstressed length: give its start value (l0=, --l0)")
    twist = Torque(torque or 0.0) if (torque is not None or param == "torque") else Rotation()
    return RodEnds(end=(Clamp(), twist, UnstressedLength(l0) if l0 is not None else Tension())
                   + ((Phase(),) if phase else ()))


def _rod_and_tension(gamma, rod, N, k, T, param, start, l0=None):
    """The checked rod, mesh size and tension of a trace (``ValueError``/``TypeError`` naming the input); under
    length control (``l0``) the tension is the straight rod's, ``EA (L/l0 - 1)``, a first guess."""
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
    if param not in TRACE_PARAMS:
        raise ValueError(f"param must be one of {', '.join(TRACE_PARAMS)}, got {param!r}")
    if l0 is not None:
        if gamma is not None or T is not None:
            raise ValueError("give one of gamma, T and l0 (the tension, or the unstressed length that sets it)")
        l0 = check_number("l0", l0, positive=True)
        T = rod.EA * (rod.L / l0 - 1.0)
        if start is None:
            check_tension(rod, T, "the straight rod of this unstressed length has a tension that")
        return rod, N, k, T
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
    return rod, N, k, T


def _curve_and_wall(curve, wall, rod, from_straight):
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
    return curve, wall


@dataclass
class _Start:
    system: RodSystem
    x0: np.ndarray
    p0: float
    tangent0: tuple | None = None
    exact: bool = False
    ds_min: float | None = None  # a smallest step below the options' (a start at the vertex of a pitchfork)
    notes: list = dataclasses.field(default_factory=list)  # what was done to reach it (a stiffened contact law)


def _start_state(rod, T, N, k, param, phi_L, start, switch, from_straight, breakpoints, curve, wall,
                 ends=None, from_critical=None, stiffen=False) -> _Start:
    """Where a trace starts: the straight state, a stored point (with its direction), or the sag."""
    from ..ends import Torque
    ends = trace_ends(param=param) if ends is None else ends
    if from_critical is not None:
        return _critical_start(rod, T, N, k, param, from_critical, breakpoints, curve, wall, ends)
    if from_straight is not None:
        phi0 = check_number("from_straight", from_straight)
        if curve is not None and not getattr(curve, "constant_frame", False):
            raise ValueError("--from-straight needs the straight reference (the straight rod state lives there)")
        if "phi_L" in ends.frees and param != "torque":
            raise ValueError("--from-straight gives the end rotation, which a prescribed torque leaves free: "
                             "continue the torque from there (--param torque) or start from a stored point")
        if param == "torque":  # the straight rod's torque at phi0, GJ alpha phi0 / L (alpha at its T)
            ends = _with_twist(ends, Torque(rod.GJ * (1.0 + T / rod.EA) * phi0 / rod.L))
        sysw, x0 = straight_seed(rod, T, phi0, N, k, breakpoints, ends=ends)
        system = RodSystem(rod, T=T, N=N, k=k, param=param, phi_L=phi0, breakpoints=sysw.disc.breakpoints, ends=ends)
        return _Start(system, x0, phi0 if param == "phi_L" else system.value())
    if start is not None:
        return _stored_start(rod, T, N, k, param, phi_L, start, switch, breakpoints, curve, wall, ends)
    if param not in ("phi_L", "torque") or ends.find(Torque) is not None and ends.find(Torque).M != 0:
        raise ValueError(f"a trace in {param} starts from a stored point or from the straight state"
                         if param not in ("phi_L", "torque") else
                         "a trace in the torque from the sag starts at torque 0 (or from --start / --from-straight)")
    system = RodSystem(rod, T=T, N=N, k=k, param=param, breakpoints=breakpoints, curve=curve, wall=wall, ends=ends)
    x0 = system.model.initial_guess(system.disc, system.base[1])
    notes: list = []
    if wall is not None:
        from .solve import ConvergenceError, settle_in_conduit
        try:
            with np.errstate(all="ignore"):
                x0 = settle_in_conduit(system, x0, system.params(0.0))
                if stiffen:
                    x0 = _within_penetration_guard(system, x0, notes)
        except ConvergenceError as exc:
            raise TraceError(str(exc)) from None
    return _Start(system, x0, 0.0, notes=notes)


def _within_penetration_guard(system: RodSystem, x0: np.ndarray, notes: list, max_error: float = 1e-6) -> np.ndarray:
    """The start in a conduit at most :data:`rodcont.contact.MAX_PENETRATION` of the clearance inside the wall, as
    ``solve`` leaves it: a deeper one is reached again under a law stiffened by a homotopy in its force scale
    (:func:`rodcont.drivers.solve.stiffen_contact`) until within a tenth of the guard; ``notes`` says so. Only a
    law the trace chose (the wall gave no force_scale: a given one is the user's, kept), and only on a start its
    mesh resolves (its error estimate within ``max_error``). The branch then keeps
    its law; :class:`PenetrationWatch` says where it goes deeper."""
    from ..contact import MAX_PENETRATION, penetration
    from ..mesh import ErrorEstimator
    from .solve import stiffen_contact
    p = system.params(system.value())
    P0, depth0 = system.model.contact_scale, penetration(system.model, system.disc, x0, p)
    depth = depth0
    if depth0 > MAX_PENETRATION and not ErrorEstimator(system).estimate(x0, system.value()) <= max_error:
        # on a mesh that does not resolve the start its depth is the discretisation's (the 1 km drill pipe at the
        # default N: a law stiffened 2e6 times, then solved, put its side force at 9.9e6 for 1.36e5): left to
        # the engine's refinement, and the watch says where it stays deep
        return x0
    for _ in range(8):  # as solve's rounds: the depth is not linear in 1/P where the law stiffens a peak
        if not depth > MAX_PENETRATION:
            break
        x0 = stiffen_contact(system, x0, p, system.model.contact_scale * depth / (MAX_PENETRATION / 10))
        depth = penetration(system.model, system.disc, x0, p)
    if depth0 > MAX_PENETRATION:
        notes.append(f"the contact law was stiffened from force_scale {P0:.4g} to {system.model.contact_scale:.4g}: "
                     f"the rod sat {depth0:.2g} of the clearance inside the wall at the start (guard "
                     f"{MAX_PENETRATION:g}; now {depth:.2g})")
    return x0


class PenetrationWatch:
    """In a conduit: the first stored point where the rod sits deeper than :data:`rodcont.contact.MAX_PENETRATION`
    of the clearance inside the wall (the contact law too soft for the loads there), an observer of the engine:
    ``crossed = (value before, value after, depth)``, warned of by :func:`run` and stored in the file
    (``penetration_guard``). It neither stops the branch nor adds a point: a law stiffened on the way would be
    another problem, and a located point changed the steps of a trace in T on a wall enough to send it along
    another branch past a branch point (README Limits)."""

    def __init__(self):
        self.before = None  # (parameter, depth) of the last point
        self.crossed = None

    def __call__(self, system: RodSystem, pt: Point, recorder=None) -> None:
        from ..contact import MAX_PENETRATION
        depth = pt.data.get("penetration")
        if depth is None:
            return
        if self.crossed is None and depth > MAX_PENETRATION:
            self.crossed = (self.before[0] if self.before else float(pt.p), float(pt.p), float(depth))
        self.before = (float(pt.p), float(depth))

    def message(self, system: RodSystem) -> str:
        from ..contact import MAX_PENETRATION
        a, b, depth = self.crossed
        return (f"penetration guard: the rod sits deeper than {MAX_PENETRATION:g} of the clearance inside the wall "
                f"from {system.param} between {a:.10g} and {b:.10g} ({depth:.2g} there): the contact law is too "
                f"soft for these loads (give the conduit file a larger force_scale than "
                f"{system.model.contact_scale:.4g})")


def _critical_start(rod, T, N, k, param, n, breakpoints, curve, wall, ends) -> _Start:
    """At the ``n``-th critical twist of the straight weightless rod (under the trace's axial control), along the
    bifurcating helical branch, with a phase condition (:class:`rodcont.ends.Phase`) that fixes the turn of its
    circle of buckled states.

    The critical twist is refined on the trace's own mesh (its pencil, :func:`rodcont.drivers.diagram._pencil`);
    the Jacobian there has a two-dimensional null space (the circle's two modes, O(2)); the start leaves along
    the null vector that meets the phase condition (``int Delta . g dS = 0``), exactly (branch switching).
    """
    from ..ends import Phase, RodEnds, UnstressedLength
    from ..rod import Jet
    from .diagram import _pencil, _refine, critical_twists
    from .solve import first_mesh
    n = check_number("from_critical", n, integer=True)
    if n < 1:
        raise ValueError(f"from_critical counts the critical twists from 1, got {n}")
    if param != "phi_L" or "phi_L" in ends.frees:
        raise ValueError("from_critical starts a trace in phi_L (with the end rotation imposed)")
    if wall is not None or (curve is not None and not getattr(curve, "constant_frame", False)):
        raise ValueError("from_critical needs the straight reference without a conduit (the straight rod state)")
    if rod.w != 0:
        raise ValueError("from_critical is for the weightless rod (w = 0), whose buckled states come in circles; "
                         "with a weight, reach the buckled branches from the straight state (--from-straight)")
    length = ends.find(UnstressedLength)
    crit, window = [], 40.0
    while len(crit) < n and window <= 200.0:
        crit = critical_twists(rod, T, phi_max=window, k=k, l0=None if length is None else length.l0)
        window = 200.0 if window < 200.0 and 2 * window > 200.0 else 2 * window
    if len(crit) < n:
        raise ValueError(f"the straight rod has {len(crit)} critical twist(s) below 200 rad, not {n}")
    ends = RodEnds(start=ends.start, end=ends.end + (Phase(),))
    if breakpoints is None:
        N = max(N, first_mesh(rod, T, curve))
    system = RodSystem(rod, T=T, N=N, k=k, breakpoints=breakpoints, ends=ends)
    phys = system.without_phase()
    A, B = _pencil(rod, T, system.disc.N, k, phys.ends, breakpoints=system.disc.breakpoints)
    phi_c = _refine(A, B, float(crit[n - 1]))
    xs = phys.straight_state(phi_c)
    modes = _circle_modes(phys.disc.linearise(xs, phys.params(phi_c))[1], phys)
    g = np.asarray(phys.model.gK, float)

    def phase(v) -> float:  # int Delta . g dS of a mode
        z = phys.disc.jets(v)
        return phys.disc.integrate(z[Jet.D1[0]] * g[0] + z[Jet.D2[0]] * g[1])

    v = phase(modes[1]) * modes[0] - phase(modes[0]) * modes[1]
    v = v / np.max(np.abs(v / phys.arclength_scale()[0]))
    # the first step: at the vertex of the pitchfork, where Phi grows with the square of the mode's amplitude, the
    # branch may turn from the mode's direction to Phi's within a short arc (in the arclength's scales, deflections
    # by L: on the long rod of the localized helix, L = 37, within 1e-6, below the default ds_min); the first step
    # is the options' ds, halved as the angle test asks (a first step of 1e-7 everywhere left the rod under length
    # control at amplitudes where dPhi/ds is rounding, and its noise read as folds)
    return _Start(system, system.expanded(phys.stored(xs)), phi_c,
                  (system.expanded(phys.stored(v), tangent=True), 0.0), True, ds_min=CRITICAL_DS_MIN)


#: the smallest step of a trace from a critical twist (the options' ds_min is lowered to it)
CRITICAL_DS_MIN = 1e-10


def _circle_modes(J, system) -> list:
    """Two independent null vectors of ``J`` (singular to rounding, with a two-dimensional null space: a critical
    twist of the straight rod), by inverse iteration from two starts, in the problem's scales."""
    from scipy import sparse

    from ..linalg import LU, SingularMatrix
    sx = system.arclength_scale()[0]
    A = (J @ sparse.diags(sx)).tocsc()
    try:
        lu = LU(A)
    except SingularMatrix:
        lu = LU((A + 1e-14 * abs(A).max() * sparse.identity(A.shape[0], format="csc")).tocsc())
    rng = np.random.default_rng(7)
    out: list = []
    for _ in range(2):
        y = rng.standard_normal(A.shape[0])
        for _ in range(3):
            y = lu.solve(y)
            y /= np.linalg.norm(y)
        for q in out:  # orthogonal to the first (scaled units)
            y -= (q @ y) * q
        out.append(y / np.linalg.norm(y))
    return [sx * y for y in out]


def _with_twist(ends, twist):
    """``ends`` with the twist condition at ``S = L`` replaced by ``twist``."""
    from ..ends import RodEnds
    return RodEnds(start=ends.start, end=tuple(twist if c.kind == "twist" else c for c in ends.end))


def _stored_start(rod, T, N, k, param, phi_L, start, switch, breakpoints, curve, wall, ends=None) -> _Start:
    """A start at a stored point ``start = (x, value, direction)`` (its solution stored without freed parameters,
    or with them); under a continued torque the point's own torque is the start value given."""
    from ..ends import Torque
    x0, p0, t0 = start
    p0 = check_number("start value", p0)
    if param == "torque":
        ends = _with_twist(ends, Torque(p0))
    system = RodSystem(rod, T=T, N=N, k=k, param=param, phi_L=phi_L if param != "phi_L" else 0.0,
                       breakpoints=breakpoints, curve=curve, wall=wall, ends=ends)
    x0 = np.asarray(x0, float)
    if x0.size not in (system.disc.size, system.disc.size - system.disc.n_free):
        raise ValueError("the start point does not fit this mesh (N, k)")
    x0 = system.expanded(x0)
    tangent0 = None
    if t0 is not None:
        tangent0 = (np.asarray(t0[0], float), float(t0[1]))
        if tangent0[0].size == x0.size - system.disc.n_free:
            tangent0 = (system.expanded(tangent0[0], tangent=True), tangent0[1])
        if tangent0[0].size != x0.size:
            tangent0 = (np.zeros(x0.size), tangent0[1] if tangent0[1] != 0 else 1.0)
    if not switch:
        return _Start(system, x0, p0, tangent0)
    if tangent0 is None:
        raise ValueError("switch needs the incoming direction at the branch point")
    return _Start(system, x0, p0, switch_direction(system, x0, p0, tangent0), True)


@with_one_blas_thread
def trace(gamma: float | None = None, rod: RodParameters | None = None, N: int = 15, k: int = 5, *,
          T: float | None = None, param: str = "phi_L", phi_L: float = 0.0, l0: float | None = None,
          torque: float | None = None, phase: bool = False, start: tuple | None = None, switch: bool = False,
          from_straight: float | None = None, from_critical: int | None = None, breakpoints=None,
          out: str | None = None, overwrite: bool = False,
          meta: dict | None = None, store_every: int = 1, curve=None, wall=None,
          callback: Callable[[Point], None] | None = None, settings: ContinuationSettings | None = None,
          resume: Branch | None = None, **options) -> Branch:
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

    Other controls (:func:`trace_ends`): ``l0`` prescribes the unstressed length instead of the tension (``T``
    is solved for at each point, a column of the table); ``param = "torque"`` continues the end torque with
    the end rotation free (the distinguished diagram under torque control: its folds are torque extrema, the
    stability counted with the rotation free; ``phi_L`` a column, bounded by ``phi_min``, ``phi_max``);
    ``torque`` holds a torque fixed for a trace in a rod parameter from a stored point. ``from_critical = n``:
    the weightless rod from its ``n``-th critical twist along the bifurcating helical branch
    (:func:`_critical_start`), with a phase condition (:class:`rodcont.ends.Phase`) that fixes the turn of its
    circle of buckled states (stored in the file's controls: a restart keeps it); the stability is counted
    without it (the rotation's null eigenvalue is not an unstable mode).

    ``options``: the fields of :class:`TraceOptions` (a misspelt name is a ``TypeError``).
    ``resume``: the branch (read from ``out``) this trace continues from its last point: its points come
    first, the start takes the last one's place (:func:`rodcont.restart.resume`).
    The branch's ``status`` says why it ended (:class:`rodcont.result.Status`), ``stop_reason`` in words.
    """
    opts = _options(options, "trace()")
    if start is not None and not (isinstance(start, (tuple, list)) and len(start) == 3):
        raise TypeError(f"start must be a stored point (x, value, direction), got {type(start).__name__}: "
                        f"from a branch, rodcont.trace(**rodcont.restart.restart_from(branch, label))")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be a function of the point, got {callback!r}")
    _check_extras(meta, settings, resume)
    rod, N, k, T = _rod_and_tension(gamma, rod, N, k, T, param, start, l0)
    phi_L = check_number("phi_L", phi_L)
    if switch and start is None:
        raise ValueError("switch needs a start point (a branch point) with its incoming direction")
    ends = trace_ends(l0, torque, param, phase)
    curve, wall = _curve_and_wall(curve, wall, rod, from_straight)
    stiffen = wall is not None and wall.force_scale is None and start is None  # a given law is kept
    if stiffen:
        # the problem's own scale; a restart keeps its file's law (files store the resolved scale; those written
        # before it was stored were solved with Wall.scale's, w or EI c / L^4, which the model takes without one)
        from ..contact import default_force_scale
        wall = dataclasses.replace(wall, force_scale=default_force_scale(rod, T, curve, wall))
    if sum(v is not None for v in (start, from_straight, from_critical)) > 1:
        raise ValueError("give one of start, from_straight and from_critical")
    st = _start_state(rod, T, N, k, param, phi_L, start, switch, from_straight, breakpoints, curve, wall, ends,
                      from_critical, stiffen)
    store_every = check_number("store_every", store_every, integer=True)
    if store_every < 1:
        raise ValueError(f"store_every must be >= 1, got {store_every}")
    settings = settings or opts.continuation_settings(param)
    if st.ds_min is not None and st.ds_min < settings.ds_min:
        settings = dataclasses.replace(settings, ds_min=st.ds_min)
    if st.notes:
        meta = dict(meta or {}, notes=json.dumps(st.notes))
    attrs = file_meta(rod, T, N, k, param, opts, st.system, meta, settings)
    branch = Branch(rod.gamma(T) if rod.w > 0 else math.nan, rod, N, k, param, attrs=attrs, curve=st.system.curve,
                    wall=st.system.wall)
    writer, recorder = _open_output(out, overwrite, attrs, store_every, branch, st.system)
    try:
        if resume is not None:  # inside: the writer is closed (its lock released) whatever happens
            from ..restart import continuing
            recorder = continuing(recorder, resume)
        with np.errstate(all="ignore"):
            run(st.system, st.x0, st.p0, opts, tangent0=st.tangent0, exact=st.exact, branch=branch,
                recorder=recorder, callback=callback, settings=settings)
    finally:
        if writer is not None:
            _close_output(writer, branch, recorder.contact)
    return branch


def _check_extras(meta, settings, resume) -> None:
    """The types of trace's ``meta``, ``settings`` and ``resume`` (a ``TypeError`` naming the argument)."""
    check_mapping("meta", meta)
    if settings is not None and not isinstance(settings, ContinuationSettings):
        raise TypeError(f"settings must be a rodcont.ContinuationSettings, got {settings!r}")
    if resume is not None and not isinstance(resume, Branch):
        raise TypeError(f"resume must be a rodcont.Branch (the unfinished branch, rodcont.load_branch(out)), "
                        f"got {resume!r}")


def _open_output(out, overwrite, attrs, store_every, branch, system):
    """The branch file's writer (None without ``out``) and the recorder that fills branch and file."""
    writer = group = contact = None
    if out is not None:
        from ..branchfile import BranchWriter, check_output
        from ..safeio import curve_files
        out = check_output(out, curve_files(system.curve), overwrite=overwrite)  # never onto the survey it reads
        writer = BranchWriter(out, attrs, store_every=store_every)
        group = writer.group("/", extra_columns=((branch.param,) if branch.param != "phi_L" else ())
                             + (("T",) if "T" in system.freed else ())
                             + (CONTACT_COLUMNS if system.wall is not None else ())
                             + (DRILLING_COLUMNS if getattr(system, "drilling", False) else ()))
        _mesh_group(writer, system)
        contact = _ContactRows(system) if system.wall is not None else None
    return writer, Recorder(branch, writer, group, contact, thin=store_every)


def _close_output(writer, branch: Branch, contact) -> None:
    try:
        if branch.missed_crossings:
            writer.f.attrs["missed_crossings"] = json.dumps(branch.missed_crossings)
        if branch.unlocated:
            writer.f.attrs["unlocated"] = json.dumps(branch.unlocated)
        if getattr(branch, "penetration_guard", None):
            writer.f.attrs["penetration_guard"] = json.dumps(branch.penetration_guard)
        if contact is not None and len(branch):
            # the rows are computed as the points are recorded: here at most the last point's (when a second
            # Ctrl-C came during its computation), so an interrupt does not wait
            contact.fill(branch)
            contact.write(writer)
    finally:
        writer.close(branch.stop_reason or "interrupted", branch.status if branch.stop_reason else
                     Status.INTERRUPTED)


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
    kind = "event:contact"

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
            f = tracker.locate(base, ds, g, g0, g1, self.tol * max(abs(g0), abs(g1), 1e-300), self.kind,
                               continuous=False)
            if f is not None:
                f.message = self.name
        if f is None or others:
            import warnings
            warnings.warn(f"the contact zones changed from {n0} to {n1} between {self.system.param} = "
                          f"{base.p:.10g} and {new.p:.10g}" + (" (more than one change in the step)"
                                                                if others else "")
                          + ": not all located; a smaller --ds-max separates them", RuntimeWarning, stacklevel=2)
        return [] if f is None else [Finding(f.ds, f, None)]


def symmetric_about_axis(model, param: str) -> bool:
    """Whether the rod ``model`` (an :class:`rodcont.rod.EulerianRod`) traced in ``param`` can be turned about
    a straight axis as a whole: its weight does not point across (weightless, or weighing along the axis) and
    the reference is straight (a conduit around it, of any clearance profile, turns with it). Turned with its
    material frame turned back about its tangent, an isotropic rod keeps its energy and its clamps: equilibria
    off the axis come in circles (a singular Jacobian on them) and eigenvalues in pairs (a double crossing at
    each bifurcation from the axis)."""
    if not model.constant_frame or param == "w":  # a trace in w changes the weight along the way
        return False
    gK = np.asarray(model.gK, float)  # the weight's direction on the frame (K1, K2 across, K3 along)
    return model.rod.w == 0 or float(np.hypot(gK[0], gK[1]) / np.linalg.norm(gK)) <= 1e-12


def crossing_advice(model, param: str) -> str:
    """What separates eigenvalues that crossed zero unseen on the rod ``model`` traced in ``param``: a weight
    across the axis where the rod is symmetric about it (they cross in pairs), else a smaller step."""
    if symmetric_about_axis(model, param):
        return ("here the rod is symmetric about its axis and its eigenvalues cross in pairs: a weight across the "
                "axis, however small, separates them (or, weightless, trace its buckled branches from the critical "
                "twists: from_critical, --from-critical)")
    return ("trace that interval with a smaller --ds-max to separate them; or the trace went on along another "
            "branch close to its own (seen in T on a rod pressed on a wall, past a branch point): a second trace "
            "with other steps shows which")


def _symmetry_hint(system: RodSystem) -> str:
    if not symmetric_about_axis(system.model, system.param):
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
            x = sysm.expanded(branch.coefficients[i])
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
              extra: dict | None = None, settings: ContinuationSettings | None = None) -> dict:
    """Root attributes of a branch file: the rod, the loads, the mesh and every run setting (``settings``:
    the trace options; ``continuation_settings``, ``adaptive_settings``: the engine's, JSON)."""
    from .. import __version__
    meta = dict(kind="branch", gamma=rod.gamma(T) if rod.w > 0 else math.nan, T=float(T), w=rod.w, EI=rod.EI,
                GJ=rod.GJ, EA=rod.EA, L=rod.L, N=int(N), k=int(k), param=param,
                weight_direction=np.asarray(rod.weight_direction), min_alignment_guard=opts.min_alignment,
                max_error=opts.max_error,
                phi_L_fixed=float(system.base[0]) if param != "phi_L" and "phi_L" not in system.freed else math.nan,
                controls=json.dumps(controls_spec(system.ends)),
                reference=str(getattr(system.curve, "spec", "straight") or "straight"),
                # the force scale as resolved (a default follows w or EI, which a trace may change)
                conduit=(dataclasses.replace(system.wall, force_scale=system.model.contact_scale).spec
                         if system.wall is not None else ""),
                settings=json.dumps(dict(opts.as_dict(), rodcont_version=__version__), default=float),
                adaptive_settings=json.dumps(asdict(opts.adaptive_settings()), default=float))
    if settings is not None or param == "phi_L" or opts.p_range is not None:
        meta["continuation_settings"] = json.dumps(asdict(settings or opts.continuation_settings(param)),
                                                   default=float)
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
