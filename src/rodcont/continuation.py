"""Keller pseudo-arclength continuation of ``F(x, p) = 0`` (knows nothing of rods).

Protocol. A problem is any object with

* ``residual(x, p) -> F`` (``n``-vector), and
* ``tangent(x, p) -> (J, F_p)``: the Jacobian ``dF/dx`` (sparse or dense
  ``n x n``) and ``dF/dp`` (``n``-vector);

optionally ``linearise(x, p) -> (F, J, F_p)`` doing both at once. The
tracker follows the curve ``(x(s), p(s))`` with the arclength of the
weighted inner product (BifurcationKit's normalisation, so a step means the
same on any mesh)::

    <(x, p), (y, q)> = theta / n * x.y + (1 - theta) * p q

Each step: tangent predictor ``(x, p) + ds (tx, tp)``, then Newton on the
augmented (Keller) system

    F(x, p) = 0,    <(tx, tp), (x - x0, p - p0)> = ds

with the bordered Jacobian ``[[J, F_p], [theta/n tx, (1-theta) tp]]``
factorised by a sparse LU. The tangent at a converged point solves the same
bordered system with right-hand side ``(0, 1)`` and is oriented so that the
branch never turns back (``<t_new, t_old> > 0``).

Special points, each *located*, not just bracketed, by a secant (Illinois)
iteration on a test function along the arc from the last regular point:

* fold: ``tp`` changes sign; located to ``|tp| < fold_tol``;
* branch point: the sign of ``det`` of the bordered Jacobian changes (read
  off the sparse LU); located on ``det`` scaled by its value at the start;
* forced points ``p = p_k`` and the parameter bounds;
* user events ``g(point) = 0`` (e.g. a validity guard), optionally stopping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterator, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .collocation import newton_solve, NewtonResult


# --------------------------------------------------------------------------
# Settings and points
# --------------------------------------------------------------------------
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
    fast_iterations: int = 3    # grow the step when the corrector needs at most this
    grow: float = 1.5
    shrink: float = 0.5
    max_angle: float = 0.35     # radians between successive tangents
    max_correction: float = 0.5  # first corrector step / ds (a larger one means the predictor was poor)
    max_contraction: float = 0.5  # second corrector step / first (Newton must contract at once)
    detect_folds: bool = True
    detect_branch_points: bool = True
    fold_tol: float = 1e-10     # |tp| at a located fold
    locate_tol: float = 1e-11   # |g| / |g(start)| for events and branch points
    locate_max_iter: int = 40
    forced: Sequence[float] = ()  # parameter values that get a point of their own

    def validate(self) -> None:
        checks = [
            (self.ds > 0, "ds must be positive"),
            (0 < self.ds_min <= self.ds <= self.ds_max, "need 0 < ds_min <= ds <= ds_max"),
            (self.direction in (1, -1), "direction must be +1 or -1"),
            (self.max_steps >= 1, "max_steps must be >= 1"),
            (self.p_min < self.p_max, "p_min must be below p_max"),
            (0 < self.theta < 1, "theta must be in (0, 1)"),
            (self.grow >= 1 and 0 < self.shrink < 1, "need grow >= 1 and 0 < shrink < 1"),
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
    kind: str = "regular"          # regular | fold | branch_point | forced | bound | event:<name> | start
    iterations: int = 0
    ds: float = 0.0
    det_sign: int = 0
    det_log: float = 0.0
    data: dict = field(default_factory=dict)


@dataclass
class Event:
    """A scalar test function ``g(point)``; a sign change is located; ``stop`` ends the trace there."""

    name: str
    function: Callable[[Point], float]
    stop: bool = False
    tol: float = 1e-11  # located where |g| <= tol * |g at the last point before it|


# --------------------------------------------------------------------------
# Sparse bordered systems
# --------------------------------------------------------------------------
def bordered(J, b: np.ndarray, c: np.ndarray, d: float) -> sp.csc_matrix:
    """``[[J, b], [c^T, d]]`` as CSC, built directly from ``J``'s CSC arrays."""
    J = J.tocsc() if sp.issparse(J) else sp.csc_matrix(np.asarray(J))
    n = J.shape[0]
    if not J.has_sorted_indices:
        J.sort_indices()
    ends = J.indptr[1:]
    data = np.insert(J.data, ends, c)
    indices = np.insert(J.indices, ends, n)
    indptr = J.indptr + np.arange(n + 1)
    data = np.concatenate([data, b, [d]])
    indices = np.concatenate([indices, np.arange(n + 1)])
    indptr = np.concatenate([indptr, [indptr[-1] + n + 1]])
    return sp.csc_matrix((data, indices, indptr), shape=(n + 1, n + 1))


def factorise(A: sp.csc_matrix):
    """Sparse LU (natural column order: the problems here come banded)."""
    return spla.splu(A, permc_spec="NATURAL")


def det_sign_log(lu) -> tuple[int, float]:
    """Sign and log-magnitude of ``det`` from a SuperLU factorisation ``Pr A Pc = L U``."""
    u = lu.U.diagonal()
    sign = int(np.prod(np.sign(u))) * _perm_sign(lu.perm_r) * _perm_sign(lu.perm_c)
    with np.errstate(divide="ignore"):
        return sign, float(np.sum(np.log(np.abs(u))))


def _perm_sign(perm: np.ndarray) -> int:
    perm = np.asarray(perm)
    seen = np.zeros(perm.size, bool)
    parity = 0
    for start in np.flatnonzero(perm != np.arange(perm.size)):
        if seen[start]:
            continue
        j, length = start, 0
        while not seen[j]:
            seen[j] = True
            j = perm[j]
            length += 1
        parity += length - 1
    return -1 if parity % 2 else 1


# --------------------------------------------------------------------------
# The tracker
# --------------------------------------------------------------------------
class StopContinuation(Exception):
    pass


class Tracker:
    """Pseudo-arclength tracker; iterate it to get the points one by one.

    ``monitor(x, p) -> dict`` (optional) adds named scalars to each point's
    ``data``; ``events`` are located where they change sign. After the
    iteration ends, ``stop_reason`` says why.
    """

    def __init__(self, problem, x0: np.ndarray, p0: float, settings: ContinuationSettings | None = None,
                 monitor: Callable | None = None, events: Sequence[Event] = (), tangent0=None,
                 exact_start: bool = False):
        self.problem = problem
        self.settings = s = settings or ContinuationSettings()
        s.validate()
        self.monitor = monitor
        self.events = list(events)
        self.stop_reason = ""
        self.n = np.asarray(x0).size
        self.wx = s.theta / self.n
        self.wp = 1.0 - s.theta
        self._x0, self._p0, self._t0 = np.asarray(x0, float), float(p0), tangent0
        self.steps = 0
        self.newton_iterations = 0
        self.current: Point | None = None
        self.ds = s.ds
        self._last_newton: NewtonResult | None = None
        # exact_start: (x0, p0) is a solution and tangent0 the direction to leave it by,
        # used as is (branch switching: at a branch point no bordered system is regular)
        self.exact_start = exact_start
        if exact_start and tangent0 is None:
            raise ValueError("exact_start needs tangent0")

    def _wnorm(self, v) -> float:
        """Arclength norm of a vector ``(dx, dp)``."""
        return math.sqrt(self.wx * float(v[:-1] @ v[:-1]) + self.wp * float(v[-1]) ** 2)

    # ---- linear algebra on the problem -----------------------------------
    def _linearise(self, x, p):
        pb = self.problem
        if hasattr(pb, "linearise"):
            return pb.linearise(x, p)
        F = pb.residual(x, p)
        J, Fp = pb.tangent(x, p)
        return F, J, Fp

    def _tangent_at(self, x, p, tx_ref, tp_ref, lu=None):
        """Unit tangent at a solution, oriented along ``(tx_ref, tp_ref)``; with det info.

        ``lu``: a factorisation of the bordered matrix with that border at (or
        within a converged Newton step of) ``(x, p)``, reused instead of a new one.
        """
        if lu is None:
            _, J, Fp = self._linearise(x, p)
            lu = factorise(bordered(J, np.asarray(Fp, float), self.wx * tx_ref, self.wp * tp_ref))
        rhs = np.zeros(self.n + 1)
        rhs[-1] = 1.0
        t = lu.solve(rhs)
        tx, tp = t[:-1], t[-1]
        # c.t = 1 > 0 orients t along the reference; the same LU gives det: with a border
        # that has a positive product with the tangent its sign is that of the bordered
        # matrix built on the tangent itself (no singular matrix in between).
        norm = math.sqrt(self.wx * tx @ tx + self.wp * tp * tp)
        sign, log = det_sign_log(lu)
        return tx / norm, float(tp / norm), sign, log

    def _correct(self, base: Point, ds: float, max_iter: int | None = None):
        """Predictor from ``base`` with step ``ds``, Keller corrector. Returns (x, p, iterations, lu) or None."""
        s = self.settings
        x = base.x + ds * base.tx
        p = base.p + ds * base.tp
        c, d = self.wx * base.tx, self.wp * base.tp

        def lin(y):
            xx, pp = y[:-1], y[-1]
            F, J, Fp = self._linearise(xx, pp)
            g = c @ (xx - base.x) + d * (pp - base.p) - ds
            return np.append(F, g), bordered(J, np.asarray(Fp, float), c, d)

        def res(y):
            xx, pp = y[:-1], y[-1]
            return np.append(self.problem.residual(xx, pp), c @ (xx - base.x) + d * (pp - base.p) - ds)

        r = newton_solve(lin, res, np.append(x, p), tol=s.newton_tol, max_iter=max_iter or s.newton_max_iter,
                         min_damping=0.25)
        self._last_newton = r
        self.newton_iterations += r.iterations
        if not r.converged:
            return None
        # Step-length guards (Allgower & Georg): a first correction large against ds, or a
        # Newton iteration that does not contract at once, means the step may have
        # jumped across a fold or onto another branch.
        if ds > 0 and r.corrections:
            d1 = self._wnorm(r.corrections[0])
            if d1 > s.max_correction * ds:
                return None
            if len(r.corrections) > 1 and self._wnorm(r.corrections[1]) > s.max_contraction * d1 + 1e-12:
                return None
        return r.x[:-1], float(r.x[-1]), r.iterations, r.lu

    def _make_point(self, x, p, base: Point, ds: float, iterations: int, kind="regular", lu=None) -> Point | None:
        """The point with its tangent and monitor data; None if the tangent system is singular."""
        try:
            tx, tp, sign, log = self._tangent_at(x, p, base.tx, base.tp, lu)
        except RuntimeError:  # exactly singular bordered matrix
            return None
        if not (np.all(np.isfinite(tx)) and math.isfinite(tp)):
            return None
        pt = Point(x=x, p=p, tx=tx, tp=tp, arclength=base.arclength + ds, kind=kind,
                   iterations=iterations, ds=ds, det_sign=sign, det_log=log)
        if self.monitor is not None:
            pt.data = dict(self.monitor(x, p))
        return pt

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
            norm = math.sqrt(self.wx * tx @ tx + self.wp * tp * tp)
            pt = Point(x=self._x0.copy(), p=self._p0, tx=tx / norm, tp=tp / norm, kind="start")
            if self.monitor is not None:
                pt.data = dict(self.monitor(pt.x, pt.p))
            self.current = pt
            return pt
        if self._t0 is None:
            tx_ref, tp_ref = np.zeros(self.n), float(s.direction)
            r = newton_solve(lambda x: self._linearise(x, self._p0)[:2],
                             lambda x: self.problem.residual(x, self._p0), self._x0, tol=s.newton_tol, max_iter=30)
            x, p = r.x, self._p0
        else:
            tx_ref, tp_ref = np.asarray(self._t0[0], float), float(self._t0[1])
            norm = math.sqrt(self.wx * tx_ref @ tx_ref + self.wp * tp_ref * tp_ref)
            if not norm > 0:
                raise StopContinuation("the restart direction is zero")
            tx_ref, tp_ref = tx_ref / norm, tp_ref / norm
            base = Point(x=self._x0, p=self._p0, tx=tx_ref, tp=tp_ref)
            c = self._correct(base, 0.0, max_iter=30)
            r = self._last_newton
            x, p = (c[0], c[1]) if c is not None else (self._x0, self._p0)
        if not r.converged:
            raise StopContinuation(f"no convergence at the starting point ({r.message})")
        base = Point(x=x, p=p, tx=tx_ref, tp=tp_ref)
        pt = self._make_point(x, p, base, 0.0, r.iterations, kind="start")
        if pt is None:
            raise StopContinuation("the starting point is singular (no unique tangent): use branch switching")
        pt.arclength = 0.0
        self.current = pt
        return pt

    # ---- location of special points --------------------------------------------
    def _locate(self, base: Point, ds_hi: float, g: Callable[[Point], float], g0: float, g1: float,
                tol: float, kind: str) -> Point | None:
        """Secant (Illinois) on ``g`` along the arc from ``base``; ``g(0) = g0``, ``g(ds_hi) = g1``."""
        s = self.settings
        a, b, fa, fb = 0.0, ds_hi, g0, g1
        side = 0
        best = None
        for _ in range(s.locate_max_iter):
            m = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
            if not (min(a, b) < m < max(a, b)):
                m = 0.5 * (a + b)
            pt = None
            for nudge in (0.0, 1e-9, -1e-9):  # exactly on a branch point the bordered matrix is singular
                mm = m + nudge * ds_hi
                c = self._correct(base, mm)
                if c is not None:
                    # a fold's test function is the tangent itself: it needs the tangent at the
                    # converged point; the others read the corrector's last factorisation
                    pt = self._make_point(c[0], c[1], base, mm, c[2], kind=kind, lu=None if kind == "fold" else c[3])
                if pt is not None:
                    m = mm
                    break
            if pt is None:
                return best
            fm = g(pt)
            best = pt
            if abs(fm) <= tol:
                return pt
            if (fm > 0) == (fb > 0):
                b, fb = m, fm
                if side == -1:
                    fa *= 0.5
                side = -1
            else:
                a, fa = m, fm
                if side == 1:
                    fb *= 0.5
                side = 1
            if abs(b - a) <= 1e-15 * (1 + abs(ds_hi)):
                return pt
        return best

    def _accept(self, pt: Point) -> None:
        """Make ``pt`` the current point; problems with an ``accept(x, p)`` hook are told."""
        self.current = pt
        hook = getattr(self.problem, "accept", None)
        if hook is not None:
            hook(pt.x, pt.p)

    # ---- iteration -----------------------------------------------------------------
    def __iter__(self) -> Iterator[Point]:
        if self.current is None:
            yield self.start()
        s = self.settings
        forced = sorted(set(float(v) for v in s.forced) - {s.p_min, s.p_max})  # bounds are located anyway
        while True:
            if self.steps >= s.max_steps:
                self.stop_reason = f"maximum number of steps ({s.max_steps}) reached"
                return
            base = self.current
            ds = self.ds
            new = None
            while new is None:
                c = self._correct(base, ds)
                if c is not None:
                    # the corrector's last factorisation gives the tangent to O(last step)
                    cand = self._make_point(c[0], c[1], base, ds, c[2], lu=c[3])
                    cos = -1.0 if cand is None else self.wx * cand.tx @ base.tx + self.wp * cand.tp * base.tp
                    if cos >= math.cos(s.max_angle):
                        new = cand
                        break
                ds *= s.shrink
                if ds < s.ds_min:
                    why = "the corrector did not converge" if c is None else "the tangent turns too fast"
                    self.stop_reason = f"step size fell below ds_min = {s.ds_min:g} ({why}) at p = {base.p:.10g}"
                    return
            self.steps += 1
            iters = new.iterations
            found: list[tuple[float, Point, bool, str]] = []  # (arclength offset, point, stop, reason)

            # folds
            on_fold_start = base.kind == "start" and abs(base.tp) < 1e3 * s.fold_tol  # restarted at a fold
            if s.detect_folds and base.tp * new.tp < 0 and not on_fold_start:
                f = self._locate(base, ds, lambda q: q.tp, base.tp, new.tp, s.fold_tol, "fold")
                if f is not None:
                    found.append((f.ds, f, False, ""))
            # branch points
            if s.detect_branch_points and base.det_sign * new.det_sign < 0:
                g0 = 1.0
                g1 = -math.exp(min(new.det_log - base.det_log, 700.0))
                ref = base.det_log

                def gdet(q, ref=ref, s0=base.det_sign):
                    return q.det_sign * s0 * math.exp(min(q.det_log - ref, 700.0))

                f = self._locate(base, ds, gdet, g0, g1, s.locate_tol, "branch_point")
                if f is not None:
                    found.append((f.ds, f, False, ""))
            # forced values and bounds
            for v in forced:
                if (base.p - v) * (new.p - v) < 0:
                    f = self._locate(base, ds, lambda q, v=v: q.p - v, base.p - v, new.p - v,
                                     1e-13 * (1 + abs(v)), "forced")
                    if f is not None:
                        f.p = v if abs(f.p - v) < 1e-12 * (1 + abs(v)) else f.p
                        found.append((f.ds, f, False, ""))
            for v, name in ((s.p_max, "p_max"), (s.p_min, "p_min")):
                if math.isfinite(v) and (new.p - v) * (base.p - v) <= 0 and new.p != base.p and base.p != v:
                    f = self._locate(base, ds, lambda q, v=v: q.p - v, base.p - v, new.p - v,
                                     1e-13 * (1 + abs(v)), "bound")
                    if f is not None:
                        found.append((f.ds, f, True, f"parameter bound {name} = {v:g} reached"))
            # user events
            for ev in self.events:
                g0, g1 = ev.function(base), ev.function(new)
                if g0 * g1 < 0:
                    f = self._locate(base, ds, ev.function, g0, g1, ev.tol * max(abs(g0), 1e-300),
                                     f"event:{ev.name}")
                    if f is not None:
                        found.append((f.ds, f, ev.stop, f"{ev.name}"))
                    elif ev.stop:  # crossed but not located: stop before the crossing, say so
                        found.append((ds, None, True, f"{ev.name} (crossed between p = {base.p:.10g} and "
                                                      f"{new.p:.10g}; not located)"))
            found.sort(key=lambda item: item[0])
            for _, pt, stop, reason in found:
                if pt is not None:
                    self._accept(pt)
                    yield pt
                if stop:
                    self.stop_reason = reason
                    return
            self._accept(new)
            yield new
            # step control
            if iters <= s.fast_iterations:
                self.ds = min(ds * s.grow, s.ds_max)
            elif iters >= s.newton_max_iter - 1:
                self.ds = max(ds * s.shrink, s.ds_min)
            else:
                self.ds = ds


def continuation(problem, x0, p0, settings: ContinuationSettings | None = None, monitor=None,
                 events: Sequence[Event] = (), callback: Callable[[Point], None] | None = None,
                 tangent0=None, exact_start: bool = False):
    """Trace a branch; returns ``(points, stop_reason)``. ``callback`` sees each point as it comes."""
    tr = Tracker(problem, x0, p0, settings, monitor, events, tangent0, exact_start)
    points = []
    try:
        for pt in tr:
            points.append(pt)
            if callback is not None:
                callback(pt)
    except StopContinuation as exc:
        tr.stop_reason = str(exc)
    return points, tr.stop_reason
