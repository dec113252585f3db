"""One equilibrium by natural loading, on a mesh that adapts until its own error estimate meets the guard.

The end rotation ``phi_L`` (or, under torque control, the end torque) is raised
from 0 in steps, Newton at each; the tension is prescribed (``gamma`` or ``T``) or
follows from a fixed unstressed length ``l0``. Natural continuation cannot pass
a fold: beyond the first one it reports non-convergence
(:class:`ConvergenceError`) and says where it stopped.

Then the answer is checked as a trace checks its points
(:class:`rodcont.mesh.ErrorEstimator`: a re-solve in a richer space) and the mesh
adapted (:func:`rodcont.mesh.adapted_mesh`) until the estimate is below
``max_error`` (and, in a conduit, the side force's own estimate below
``max_side_force_error``); a result still far above the guard is refused
(:class:`AccuracyError`). In a conduit the contact law's force scale comes from
the problem (:func:`rodcont.contact.default_force_scale`) and is stiffened by a
homotopy when the rod sits deeper than :data:`rodcont.contact.MAX_PENETRATION` of
the clearance inside the wall.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..blas import with_one_blas_thread
from ..linalg import NewtonResult, chord_solve
from ..rod import RodParameters
from ..system import RodSystem, check_number

#: how far above its guard an estimate may be and still be printed (with a warning): beyond, refused
FAR_ABOVE = 10.0
#: the first mesh resolves these lengths (bending under tension, sag onto a wall) with this many subintervals
PER_LENGTH = 2


class ConvergenceError(RuntimeError):
    pass


class AccuracyError(ConvergenceError):
    """The solution's own error estimate is far above the guard on the finest mesh allowed."""


def euler_tension(rod: RodParameters) -> float:
    """Tension at which the untwisted clamped rod buckles (Euler, extensible, self-feeding):
    ``tau = T L^2 / (EI (1 + T/EA)) = -4 pi^2``."""
    c = 4 * math.pi**2 * rod.EI / rod.L**2
    return -c / (1.0 + c / rod.EA)


def check_tension(rod: RodParameters, T: float, what: str = "the tension") -> None:
    """Refuse a tension at or below the Euler load (the untwisted start is not unique there)."""
    TE = euler_tension(rod)
    if not T > TE:
        lim = f" (Gamma = {TE / (rod.w * rod.L):.6g})" if rod.w > 0 else ""
        raise ValueError(f"{what} T = {T:.6g} is at or below the Euler buckling load of the clamped rod, "
                         f"T = {TE:.6g}{lim}: the untwisted start is not unique")


def check_physical(outputs: dict, where: str) -> None:
    """A solution with a non-positive stretch factor or unstressed length is not a rod."""
    if not (outputs.get("l0", 1.0) > 0 and outputs.get("alpha_min", 1.0) > 0):
        raise ConvergenceError(f"{where}: the solution has a non-positive unstressed length or stretch "
                               f"factor (the rod would be compressed through zero length): not physical")


@dataclass
class Equilibrium:
    """One solved equilibrium: its outputs, the unknown vector and how Newton ended.

    ``outputs`` holds every control and response (``T``, ``gamma``, ``phi_L``,
    ``torque``, ``l0``, ``stretch``, ...); ``error`` the estimate of :class:`rodcont.mesh.ErrorEstimator` on
    the final mesh, ``side_force_error`` the side force's: the mesh's part (the same estimator) plus, when the
    penetration guard stiffened the law, the contact law's, ``law_side_force_error`` (:func:`law_side_force_error`;
    NaN for the law posed, which is the problem, not an error);
    ``warnings`` what was said about the result (also issued as ``RuntimeWarning``), ``notes`` what was
    done to reach it (a stiffened contact law).
    """

    outputs: dict
    x: np.ndarray
    system: RodSystem
    newton: NewtonResult
    error: float = math.nan
    side_force_error: float = math.nan
    warnings: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    law_side_force_error: float = math.nan

    @property
    def converged(self) -> bool:
        return self.newton.converged

    @property
    def params(self) -> np.ndarray:
        """The full parameter vector (``model.param_names``), freed parameters read from the solution."""
        return self.system.disc.full_params(self.x, self.system.base)

    def contact(self) -> dict:
        """Contact with the conduit wall (:meth:`rodcont.rod.EulerianRod.contact`)."""
        sysm = self.system
        return sysm.model.contact(sysm.disc, self.x, self.params)

    def centreline(self, S=None):
        S = np.linspace(*self.system.model.interval, 201) if S is None else S
        return self.system.model.centreline(self.system.disc, self.x, S)


#: the contact homotopy's coarsest rung is every COARSEN-th breakpoint of a mesh (fewer where that leaves under
#: COARSE_MIN subintervals; _ladder): 4 of 41 LUs on the 3500 m drill string's own 2936 subintervals, 12 on every
#: second breakpoint, 24 on every 8th, the same equilibrium (bench.py --only drilling)
COARSEN, COARSE_MIN = 8, 128


def settle_in_conduit(sysm: RodSystem, x: np.ndarray, p: np.ndarray, tol: float = 1e-10,
                      factor: float = 100.0, confirm: bool = True, coarsen: int | None = None,
                      softest_is_verdict: bool = False) -> np.ndarray:
    """An equilibrium inside the conduit from a guess that may cross its wall: homotopy in the smoothing.

    The contact law ``p (g + p/k) = mu`` (:mod:`rodcont.contact`) is solved
    first with a soft wall (``eps = 0.1``), then with ``eps`` divided by ``factor`` at
    each stage down to the wall's own (a slack drill string needs 10: rodcont.drilling.settle),
    each stage from the previous solution (a stiff wall seen from a far-off guess stalls Newton's line search).
    Each stage is solved by the chord (:func:`rodcont.linalg.chord_solve`: the Jacobian frozen while the steps
    contract, Newton's line search where they do not; 4-6 LUs a stage on the 1 km well against 8-9 Newton
    iterations), Newton's where the chord fails (a stage fails only where Newton fails), and the last stage's
    solution is confirmed by Newton (``confirm``; off for a caller that confirms it itself). Returns the last
    stage's solution.

    The stages run on a ladder of meshes (:func:`_ladder`): all but the last on every ``coarsen``-th breakpoint
    (default :data:`COARSEN`, fewer where the coarse mesh would have under :data:`COARSE_MIN` subintervals; 1:
    none), the last two on every second one, the last on ``sysm``'s own mesh, each rung from the one before carried
    over; where a rung fails, the whole homotopy runs on ``sysm``'s mesh as without it (the ladder only chooses the
    start of the last stage's Newton). ``softest_is_verdict``: where the coarsest rung fails at the softest stage,
    the ``ConvergenceError`` at once, for a caller with another path to try first (the same soft law from the same
    guess on a finer mesh: the 3250 m slack-off's homotopy on its own mesh failed there too, after 3.3 s).
    """
    wall = sysm.model.wall
    stages = [0.1]
    while stages[-1] / factor > wall.eps:
        stages.append(stages[-1] / factor)
    stages.append(wall.eps)
    rungs = _ladder(sysm, coarsen, stages)
    if len(rungs) > 1:
        try:
            return climb(rungs, x, sysm, p, tol, confirm)
        except ConvergenceError as exc:  # a coarser mesh is no verdict: the homotopy on the mesh itself is
            if softest_is_verdict and getattr(exc, "at", None) == (rungs[0][0], stages[0]):
                raise
    return _homotopy(sysm, x, p, tol, stages, confirm)


def climb(rungs: list, x: np.ndarray, source: RodSystem, p: np.ndarray, tol: float, confirm: bool) -> np.ndarray:
    """The stages of each rung of ``rungs`` (:func:`_ladder`) from ``x`` on ``source``'s mesh, each rung from the
    one before carried over; the last rung's solution (confirmed by Newton where ``confirm``)."""
    for rung, its_stages in rungs:
        x = _homotopy(rung, rung.disc.transfer(x, source.disc), p, tol, its_stages, confirm and rung is rungs[-1][0])
        source = rung
    return x


def _ladder(sysm: RodSystem, coarsen: int | None, stages: list, coarsest: RodSystem | None = None) -> list:
    """``[(system, stages)]`` from the coarsest mesh to ``sysm``'s own: the stages but the last on every c-th
    breakpoint, the last two on every second (where c > 2), the last on ``sysm``. A coarse solution of the stiff
    law misplaces the contacts the mesh itself resolves: carried straight to the mesh of examples/well_s3d.toml's
    3250 m pick-up its last stage failed and the solve took 161 LUs in all, 49 with the middle rung, 4 of them on
    the mesh itself (test_homotopy.py). ``coarsest``: ``_coarse_system(sysm, coarsen)`` where the caller has it."""
    c = _coarsening(sysm.disc.N, coarsen)
    if c < 2 or len(stages) < 2:
        return [(sysm, stages)]
    rungs = [(_coarse_system(sysm, c) if coarsest is None else coarsest, stages[:-1])]
    if c > 2:
        rungs.append((_coarse_system(sysm, 2), stages[-2:]))
    return rungs + [(sysm, stages[-1:] if c > 2 else stages[-2:])]


def _coarsening(N: int, coarsen: int | None) -> int:
    """Every how many breakpoints the coarsest mesh keeps (:data:`COARSEN`, fewer on a small mesh; < 2: none)."""
    return min(COARSEN, N // COARSE_MIN) if coarsen is None else int(coarsen)


def _coarse_system(sysm: RodSystem, coarsen: int | None) -> RodSystem | None:
    """``sysm`` on every ``coarsen``-th of its breakpoints (and its stations), or None for no coarser mesh."""
    c = _coarsening(sysm.disc.N, coarsen)
    if c < 2:
        return None
    b = sysm.disc.breakpoints
    return sysm.with_mesh(sysm.conform(np.union1d(b[::c], b[[0, -1]])))


def _homotopy(sysm: RodSystem, x: np.ndarray, p: np.ndarray, tol: float, stages: list, confirm: bool) -> np.ndarray:
    """The stages of :func:`settle_in_conduit` on ``sysm``'s own mesh (its model's wall restored after)."""
    model, wall = sysm.model, sysm.model.wall
    disc = sysm.disc
    try:
        for eps in stages:
            model.wall = dataclasses.replace(wall, eps=eps)
            r = _chord_then_newton(disc, x, p, tol, confirm and eps == stages[-1])
            if not r.converged:
                exc = ConvergenceError(f"no equilibrium found inside the conduit (contact smoothing eps = "
                                       f"{eps:g}): {r.message}")
                exc.at = (sysm, eps)  # where it failed (settle_in_conduit's softest_is_verdict)
                raise exc
            x = r.x
    finally:
        model.wall = wall
    return x


def stiffen_contact(sysm: RodSystem, x: np.ndarray, p: np.ndarray, P: float, tol: float = 1e-10) -> np.ndarray:
    """The equilibrium under the stiffer contact law of force scale ``P`` (``> model.contact_scale``; a softer
    one the same way down), reached by a homotopy in the scale (at most a factor 10 per stage, halved in the
    logarithm when Newton fails), as :func:`settle_in_conduit` reaches ``eps``. The system's wall and model
    carry ``P`` afterwards."""
    model = sysm.model
    P0 = model.contact_scale
    up = 1.0 if P >= P0 else -1.0  # the homotopy's direction
    target = up * math.log10(P / P0)
    done, step = 0.0, min(1.0, target)  # |log10| of the factor reached, of the next stage
    while done < target:
        nxt = min(done + step, target)
        model.contact_scale = P0 * 10.0**(up * nxt)
        r = _chord_then_newton(sysm.disc, x, p, tol, confirm=nxt >= target)
        if r.converged:
            x, done = r.x, nxt
            continue
        step *= 0.5
        if step < 1e-3:
            model.contact_scale = P0 * 10.0**(up * done)
            _set_force_scale(sysm, model.contact_scale)
            how = "stiffened" if up > 0 else "softened"
            raise ConvergenceError(f"the contact law could not be {how} past force scale "
                                   f"{model.contact_scale:.4g} (aiming at {P:.4g}): {r.message}")
    _set_force_scale(sysm, P)
    return x


def _chord_then_newton(disc, x: np.ndarray, p: np.ndarray, tol: float, confirm: bool) -> NewtonResult:
    """One stage of a homotopy: the chord (:func:`rodcont.linalg.chord_solve`), Newton from the stage's start where
    it fails (the chord's failure is no verdict), Newton from its solution where ``confirm``."""
    r = chord_solve(lambda y: disc.linearise(y, p)[:2], lambda y: disc.residual(y, p), x, tol=tol, max_iter=60)
    if not r.converged:
        return disc.newton(x, p, tol=tol, max_iter=60)
    return disc.newton(r.x, p, tol=tol, max_iter=60) if confirm else r


def _set_force_scale(sysm: RodSystem, P: float) -> None:
    wall = dataclasses.replace(sysm.wall, force_scale=float(P))
    sysm.wall = wall
    sysm.model.wall = wall
    sysm.model.contact_scale = float(P)


# --------------------------------------------------------------------------
# The controls: which parameters are given, which are solved for
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class _Controls:
    """The axial control (``T`` given, or ``l0`` with ``T`` a first guess) and the twist control
    (``phi_L`` or ``torque``)."""

    T: float
    l0: float | None
    phi_L: float | None
    torque: float | None

    def ends(self):
        from ..ends import Clamp, RodEnds, Rotation, Tension, Torque, UnstressedLength
        twist = Rotation() if self.torque is None else Torque(self.torque)
        axial = Tension() if self.l0 is None else UnstressedLength(self.l0)
        return RodEnds(end=(Clamp(), twist, axial))

    @property
    def load_name(self) -> str:
        return "phi_L" if self.torque is None else "torque"

    @property
    def target(self) -> float:
        return self.phi_L if self.torque is None else self.torque


def _controls(rod, gamma, T, l0, phi_L, torque) -> _Controls:
    given = [n for n, v in (("gamma", gamma), ("T", T), ("l0", l0)) if v is not None]
    if len(given) != 1:
        raise ValueError("give one of gamma, T and l0 (the tension, or the unstressed length that sets it)"
                         + (f", not {' and '.join(given)}" if given else ""))
    twist = [n for n, v in (("phi_L", phi_L), ("torque", torque)) if v is not None]
    if len(twist) != 1:
        raise ValueError("give one of phi_L and torque (the end rotation, or the end torque)"
                         + (f", not {' and '.join(twist)}" if twist else ""))
    if gamma is not None:
        gamma = check_number("gamma", gamma)
        if rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: give T")
        T = rod.tension(gamma)
        if not math.isfinite(T):
            raise ValueError(f"gamma = {gamma:g} gives a tension that is not finite")
    elif T is not None:
        T = check_number("T", T)
    if l0 is not None:
        l0 = check_number("l0", l0, positive=True)
        T = rod.EA * (rod.L / l0 - 1.0)  # the straight rod's: a first guess only
    else:
        check_tension(rod, T)
    return _Controls(T=float(T), l0=l0, phi_L=None if phi_L is None else check_number("phi_L", phi_L),
                     torque=None if torque is None else check_number("torque", torque))


def _reference(curve, rod: RodParameters):
    """``curve`` as a :class:`rodcont.curves.ReferenceCurve` (a ``KIND[:ARGS]`` string parsed for the span
    ``rod.L``, as ``trace`` takes it), or None for the straight span."""
    from ..curves import ReferenceCurve, parse_reference
    if isinstance(curve, str):
        return parse_reference(curve, rod.L)
    if curve is not None and not isinstance(curve, ReferenceCurve):
        raise TypeError(f"curve must be a rodcont.curves.ReferenceCurve or a KIND[:ARGS] string, got {curve!r}")
    return curve


def first_mesh(rod: RodParameters, T: float, curve=None, wall=None, N_max: int = 4000) -> int:
    """Subintervals of a first mesh that resolves the problem's own lengths: ``PER_LENGTH`` per bending
    length ``sqrt(EI/|T|)``, per sag length ``(EI/w)^(1/3)`` and, in a conduit, per length ``(EI c/w)^(1/4)``
    over which a heavy rod lifts off its wall (and 15 over the span at least)."""
    lengths = [rod.L / 15 * PER_LENGTH]
    if T != 0:
        lengths.append(math.sqrt(rod.EI / abs(T)))
    if rod.w > 0:
        lengths.append((rod.EI / rod.w) ** (1 / 3))
        if wall is not None:
            lengths.append((rod.EI * wall.c_min / rod.w) ** 0.25)
    length = float(curve.length) if curve is not None else rod.L
    return int(min(max(15, math.ceil(PER_LENGTH * length / min(lengths))), N_max))


def _system(rod, controls: _Controls, N: int, k: int, curve, wall, breakpoints=None) -> RodSystem:
    """The rod system with the controls' end conditions, in the loaded control (``phi_L`` or ``torque``)."""
    sysm = RodSystem(rod, T=controls.T, N=N, k=k, curve=curve, wall=wall, breakpoints=breakpoints,
                     ends=controls.ends(), param=controls.load_name)
    sysm.base = sysm.model.params(0.0, T=controls.T)
    return sysm


# --------------------------------------------------------------------------
# Loading and refinement
# --------------------------------------------------------------------------
def _load(sysm: RodSystem, controls: _Controls, load_step: float, tol: float):
    """Natural loading of the twist control from 0 to its target on ``sysm``'s mesh: ``(x, p, newton)``."""
    model, disc = sysm.model, sysm.disc
    idx = model.param_names.index(controls.load_name)
    unit = 1.0 if controls.torque is None else model.rod.GJ / model.rod.L  # a torque step: load_step rad of twist
    p = sysm.base.copy()
    p[idx] = 0.0
    x = model.initial_guess(disc, controls.T)
    if sysm.wall is not None:
        x = settle_in_conduit(sysm, x, p, tol, confirm=False)  # confirmed below
    r = disc.newton(x, p, tol=tol)
    if not r.converged:
        raise ConvergenceError(f"no equilibrium found at {controls.load_name} = 0 ({_axial_text(controls)}): "
                               f"{r.message}")
    target = controls.target
    x, done = r.x, 0.0
    step = math.copysign(load_step * unit, target) if target else load_step * unit
    while done != target:
        nxt = target if (done + step - target) * math.copysign(1.0, step) > 0 else done + step
        p[idx] = nxt
        r = disc.newton(x, p, tol=tol)
        if r.converged:
            x, done = r.x, nxt
        else:
            step *= 0.5
            if abs(step) < load_step * unit / 1024:
                raise ConvergenceError(f"loading stopped at {controls.load_name} = {done:.10g} (a fold of the "
                                       f"branch is likely just beyond; use 'rodcont trace'): {r.message}")
    return x, p, r


def _axial_text(controls: _Controls) -> str:
    return f"T = {controls.T:g}" if controls.l0 is None else f"l0 = {controls.l0:g}"


@dataclass
class _Check:
    """The estimates of one solution on its mesh, against the guards: ``side_force_error`` is the mesh's part
    (``mesh_side_force_error``) plus, for a law the guard stiffened, the contact law's (``law_side_force_error``,
    :func:`law_side_force_error`; NaN otherwise)."""

    error: float
    side_force_error: float
    penetration: float
    mesh_side_force_error: float = math.nan
    law_side_force_error: float = math.nan

    def ratio(self, max_error: float, max_side_force_error: float) -> float:
        """How far the worse of the two error estimates is above its guard (<= 1: within)."""
        sf = 0.0 if math.isnan(self.side_force_error) else self.side_force_error / max_side_force_error
        return max(self.error / max_error, sf)


def _check(sysm: RodSystem, x: np.ndarray) -> _Check:
    from ..mesh import ErrorEstimator
    wall = sysm.wall is not None
    try:
        est = ErrorEstimator(sysm, watch_side_force=wall)
    except TypeError:  # the estimator's newer spelling of the same watch
        est = ErrorEstimator(sysm, watch=wall)
    err = est.estimate(x, sysm.value())
    pen = sf = math.nan
    if wall:
        from ..contact import penetration
        pen = penetration(sysm.model, sysm.disc, x, sysm.base)
        sf = getattr(est, "side_force_error", None)
        sf = est.watched.get("side_force", math.nan) if sf is None else sf
    return _Check(err, sf, pen, sf)


#: the slowest rate at which a contact force of the smoothed law converges, ``eps^LAW_RATE`` (a point contact
#: in the straight pipe: ``F(eps)`` 1.3e-4 off the exact 2.3385483 for a change of 4e-5 at ``2 eps``, the
#: rate 1/3 of a zone's ends); the change at ``2 eps`` is ``(2^LAW_RATE - 1)`` of the error
LAW_RATE = 1.0 / 3.0


def law_side_force_error(sysm: RodSystem, x: np.ndarray, own_scale: float, tol: float = 1e-10) -> float:
    """The side force's error from the contact law's smoothing, relative to ``max(|F|, own_scale L)``
    (``own_scale``: the problem's own force scale, :func:`rodcont.contact.default_force_scale`, not one the
    penetration guard stiffened): ``|F(2 eps) - F(eps)|``, the law re-solved on the same mesh with ``eps``
    doubled (Newton from ``x``), divided by ``2^LAW_RATE - 1``: the error from exact contact of a force that
    converges like ``eps^LAW_RATE`` or faster. The softer law is the better resolved of the two, so the change
    reads little of the mesh's error.

    No mesh estimate sees this error, since every mesh agrees on it: the smoothed law pushes with about
    ``eps c P / g`` across every gap, and on a forced coarse mesh whose rod crossed the wall between its points
    the penetration guard stiffened the law a million times: the README's drill pipe on a uniform N = 20 read
    3.5 MN for 136 kN, its mesh estimate 6e-10, this one 1. ``inf`` when Newton fails at ``2 eps``."""
    model = sysm.model
    wall = model.wall
    F0 = model.contact(sysm.disc, x, sysm.disc.full_params(x, sysm.base))["side_force"]
    try:
        model.wall = dataclasses.replace(wall, eps=min(2.0 * wall.eps, 0.1))
        r = sysm.disc.newton(x, sysm.base, tol=tol, max_iter=60)
        F1 = model.contact(sysm.disc, r.x, sysm.disc.full_params(r.x, sysm.base))["side_force"] \
            if r.converged else math.nan
    finally:
        model.wall = wall
        model._last_contact = None  # its cache keys the point, not the law
    if not math.isfinite(F1):
        return math.inf
    return abs(F1 - F0) / (2.0**LAW_RATE - 1.0) / max(abs(F0), own_scale * sysm.rod.L)


def _with_law(sysm: RodSystem, x: np.ndarray, check: _Check, own_scale: float | None, tol: float) -> _Check:
    """``check`` with the contact law's part of the side force's error added (no wall: unchanged)."""
    if sysm.wall is None or own_scale is None:
        return check
    law = law_side_force_error(sysm, x, own_scale, tol)
    mesh = 0.0 if math.isnan(check.mesh_side_force_error) else check.mesh_side_force_error
    return dataclasses.replace(check, side_force_error=mesh + law, law_side_force_error=law)


def _refined(sysm: RodSystem, x: np.ndarray, check: _Check, settings: dict, controls, load_step, tol):
    """The solution on a mesh adapted to it (:func:`rodcont.mesh.adapted_mesh`): ``(system, x, newton)``."""
    from ..mesh import adapted_mesh
    ratio = check.ratio(settings["max_error"], settings["max_side_force_error"])
    indicator = sysm.interval_defect(x, sysm.value())
    b = adapted_mesh(sysm.disc.breakpoints, indicator, sysm.disc.k, ratio * settings["max_error"],
                     settings["max_error"] / 4, N_max=settings["N_max"])
    new = sysm.with_mesh(sysm.conform(b))
    r = new.disc.newton(new.disc.transfer(x, sysm.disc), new.base, tol=tol)
    if r.converged:
        return new, r.x, r
    x, p, r = _load(new, controls, load_step, tol)  # the carried solution did not converge: load anew
    return new, x, r


def _posed_law(sysm: RodSystem, x: np.ndarray, r, P: float, tol: float):
    """``(x, newton)`` under the law posed (force scale ``P``, softer than the one the guard stiffened on a
    coarser mesh), from ``x``: a refined mesh may not need the stiffening, whose barrier ``eps c P / g`` pushes
    along every free span. ``(x, r)`` under the stiffened law when Newton fails at ``P``."""
    P1 = sysm.model.contact_scale
    sysm.model._last_contact = None  # its cache keys the point, not the law
    try:
        y = stiffen_contact(sysm, x, sysm.base, P, tol)
    except ConvergenceError:
        _set_force_scale(sysm, P1)
        return x, r
    return y, sysm.disc.newton(y, sysm.base, tol=tol)


def _adapt(sysm, x, r, controls, settings, load_step, tol, notes: list):
    """Stiffen the contact law past the penetration guard, refine the mesh past the error guards: at most
    eight rounds of each. A law the guard stiffened has the law's part in the side force's estimate
    (:func:`law_side_force_error`) and is taken back to the one posed on each refined mesh (the guard decides
    there anew). Returns ``(system, x, newton, check)``; ``notes`` says what was stiffened."""
    from ..contact import MAX_PENETRATION
    law_before = math.inf
    posed, first_note = (sysm.model.contact_scale if sysm.wall is not None else None), len(notes)
    own_scale = None  # set once the guard stiffened the law: the law posed is the problem, not an error
    stiffenings = refinements = 0
    while stiffenings < 8 and refinements < 8:
        check = _check(sysm, x)
        if sysm.wall is not None and check.penetration > MAX_PENETRATION:
            P0 = sysm.model.contact_scale
            P = P0 * check.penetration / (MAX_PENETRATION / 10)
            x = stiffen_contact(sysm, x, sysm.base, P, tol)
            notes.append(f"the contact law was stiffened from force_scale {P0:.4g} to {P:.4g}: the rod sat "
                         f"{check.penetration:.2g} of the clearance inside the wall (guard {MAX_PENETRATION:g})")
            own_scale, stiffenings = settings.get("own_scale"), stiffenings + 1
            continue
        ratio = check.ratio(settings["max_error"], settings["max_side_force_error"])
        final = not settings["adapt"] or sysm.disc.N >= settings["N_max"]
        if ratio <= 1.0 or final:  # the mesh's estimates met (or the mesh final): the law's part added
            check = _with_law(sysm, x, check, own_scale, tol)
            law = check.law_side_force_error
            # a coarse mesh's re-solve reads some of the mesh's error too, which a finer mesh lowers; a part
            # that one refinement did not halve is the smoothing's own, which no mesh lowers
            if final or check.ratio(settings["max_error"], settings["max_side_force_error"]) <= 1.0 \
                    or not law < 0.5 * law_before:
                return sysm, x, r, check
            law_before = law
        sysm, x, r = _refined(sysm, x, check, settings, controls, load_step, tol)
        refinements += 1
        if check.law_side_force_error > settings["max_side_force_error"] and sysm.model.contact_scale > posed:
            x, r = _posed_law(sysm, x, r, posed, tol)
            if sysm.model.contact_scale == posed:  # the notes of the law left behind
                del notes[first_note:]
                own_scale = None
    return sysm, x, r, _with_law(sysm, x, _check(sysm, x), own_scale, tol)


def _judge(sysm: RodSystem, check: _Check, settings: dict) -> list:
    """Refuse a result far above its guards (:class:`AccuracyError`; with ``strict`` off, warn); the warnings
    for one just above."""
    from ..contact import MAX_PENETRATION
    N = sysm.disc.N
    where = (f"N = {N}" + (" (N_max reached: raise N_max)" if settings["adapt"] and N >= settings["N_max"]
                           else "" if settings["adapt"] else " (a uniform mesh: raise N or let it adapt)"))
    said = []
    if sysm.wall is not None and check.penetration > MAX_PENETRATION and settings["strict"]:
        raise AccuracyError(f"the rod sits {check.penetration:.2g} of the clearance inside the wall (guard "
                            f"{MAX_PENETRATION:g}) with the contact law's force scale "
                            f"{sysm.model.contact_scale:.4g}: give a larger force_scale in the conduit file")
    for name, value, guard in (("estimated error", check.error, settings["max_error"]),
                               ("side force's estimated error", check.side_force_error,
                                settings["max_side_force_error"])):
        part = ""  # the law's share, said when it is most of the side force's estimate
        if name.startswith("side") and check.law_side_force_error > 0.5 * value:
            part = (f" ({check.law_side_force_error:.2g} from the contact law: eps = {sysm.wall.eps:g}, "
                    f"force_scale {sysm.model.contact_scale:.4g})")
        if not value <= FAR_ABOVE * guard and not math.isnan(value) and settings["strict"]:
            raise AccuracyError(f"the {name} {value:.2g}{part} is far above its guard {guard:g} on {where}: "
                                f"the result is not printed")
        if not value <= guard and not math.isnan(value):
            said.append(f"the {name} {value:.2g}{part} exceeds its guard {guard:g} on {where}")
    return said


def _outputs(sysm: RodSystem, x: np.ndarray, controls: _Controls) -> dict:
    """Every control and response: ``T``, ``gamma``, ``phi_L``, ``torque``, ``l0`` and the model's outputs."""
    p = sysm.disc.full_params(x, sysm.base)
    o = sysm.model.outputs(sysm.disc, x, p)
    rod = sysm.rod
    out = dict(T=float(p[1]), gamma=rod.gamma(float(p[1])) if rod.w > 0 else math.nan, phi_L=float(p[0]),
               **{key: o[key] for key in ("stretch", "torque", "l0", "helical_waves", "min_alignment", "defect",
                                          "torque_spread", "alpha_min")})
    out["alpha_min"] = sysm.model.stretch_factor_min(sysm.disc, x, p)
    out["N"] = sysm.disc.N
    if sysm.wall is not None:
        c = sysm.model.contact(sysm.disc, x, p)
        out.update(min_gap=c["min_gap"], side_force=c["side_force"], contact_zones=len(c["zones"]),
                   max_pressure=float(c["pressure"].max()), force_scale=sysm.model.contact_scale)
    return out


_ACCEPTED = ("gamma", "phi_L", "rod", "N", "k", "load_step", "tol", "T", "curve", "wall", "torque", "l0", "adapt",
             "max_error", "max_side_force_error", "N_max", "strict")


@with_one_blas_thread
def solve_equilibrium(gamma: float | None = None, phi_L: float | None = None, rod: RodParameters | None = None,
                      N: int | None = None, k: int = 5, load_step: float = 0.5, tol: float = 1e-10,
                      T: float | None = None, curve=None, wall=None, *, torque: float | None = None,
                      l0: float | None = None, adapt: bool = True, max_error: float = 1e-6,
                      max_side_force_error: float = 1e-3, N_max: int = 4000, strict: bool | None = None,
                      **unknown) -> Equilibrium:
    """The equilibrium for one axial control (``gamma``, ``T = gamma w L``, or the unstressed length ``l0``,
    which makes ``T`` an unknown) and one twist control (the end rotation ``phi_L``, or the end torque
    ``torque``, which makes ``phi_L`` an unknown), reached by loading the twist control up from 0 in steps
    (``load_step`` radians of rotation, or ``load_step GJ / L`` of torque; a step that fails is halved, down
    to 1/1024 of it).

    ``N``: the first mesh (default: :func:`first_mesh`, from the problem's lengths); with ``adapt`` the
    mesh is refined (up to ``N_max``) until the estimated error is below ``max_error`` and, in a conduit
    (``wall``), the side force's below ``max_side_force_error``. A result more than ``FAR_ABOVE`` times
    above either is refused (:class:`AccuracyError`; ``strict``, default ``adapt``: on a mesh kept fixed
    on purpose, ``adapt=False``, such a result is returned with a warning), one just above is returned with
    a warning. In a
    conduit whose wall gives no ``force_scale`` it is chosen from the problem
    (:func:`rodcont.contact.default_force_scale`), and stiffened when the rod sits deeper than
    :data:`rodcont.contact.MAX_PENETRATION` of the clearance in the wall.
    """
    if unknown:
        hint = " (the end rotation is phi_L)" if "phi" in unknown else ""
        raise TypeError(f"rodcont.solve() got unexpected keyword argument(s) {', '.join(map(repr, unknown))}"
                        f"{hint}; it accepts {', '.join(_ACCEPTED)}")
    rod = RodParameters() if rod is None else rod
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    controls = _controls(rod, gamma, T, l0, phi_L, torque)
    curve = _reference(curve, rod)
    load_step = check_number("load_step", load_step, positive=True)
    if abs(controls.target) / (load_step * (1.0 if torque is None else rod.GJ / rod.L)) > 1e5:
        raise ValueError(f"load_step = {load_step:g} would take more than 1e5 steps to reach "
                         f"{controls.load_name} = {controls.target:g}")
    for name, flag in (("adapt", adapt), ("strict", strict)):
        if not (isinstance(flag, (bool, np.bool_)) or (name == "strict" and flag is None)):
            raise TypeError(f"{name} must be True or False, got {flag!r}")
    if not (isinstance(N_max, (int, np.integer)) and not isinstance(N_max, bool) and N_max >= 1):
        raise ValueError(f"N_max must be an integer >= 1, got {N_max!r}")
    settings = dict(adapt=bool(adapt), max_error=check_number("max_error", max_error, positive=True),
                    max_side_force_error=check_number("max_side_force_error", max_side_force_error, positive=True),
                    N_max=check_number("N_max", N_max, integer=True),
                    strict=bool(adapt if strict is None else strict))
    k = check_number("k", k, integer=True)
    tol = check_number("tol", tol, positive=True)
    P_goal = None
    if wall is not None:
        from ..contact import Wall, default_force_scale
        if not isinstance(wall, Wall):
            raise TypeError(f"wall must be a rodcont.contact.Wall, got {wall!r}")
        P = default_force_scale(rod, controls.T, curve, wall)
        if wall.force_scale is not None and wall.force_scale > P:
            # a law stiffer than the problem's own scale: reached from that one by a homotopy (seen from the
            # straight guess it stalls Newton, as a small eps does)
            P_goal = float(wall.force_scale)
        if wall.force_scale is None or P_goal is not None:
            wall = dataclasses.replace(wall, force_scale=P)
        settings["own_scale"] = P  # the side force's floor in its law estimate (not a stiffened scale)
    N = first_mesh(rod, controls.T, curve, wall, settings["N_max"]) if N is None else check_number("N", N, integer=True)
    if not 1 <= N <= settings["N_max"]:
        raise ValueError(f"N = {N} must lie in 1 .. N_max = {settings['N_max']} (raise N_max for a larger mesh)")
    with np.errstate(all="ignore"):
        sysm = _system(rod, controls, N, k, curve, wall)
        x, sysm.base, r = _load(sysm, controls, load_step, tol)
        if P_goal is not None:
            x = stiffen_contact(sysm, x, sysm.base, P_goal, tol)
        notes: list = []
        sysm, x, r, check = _adapt(sysm, x, r, controls, settings, load_step, tol, notes)
        said = _judge(sysm, check, settings)
        out = _outputs(sysm, x, controls)
    where = ", ".join(f"{n} = {out[n]:g}" for n in ("T", "phi_L"))
    check_physical(out, where)
    for s in said:
        warnings.warn(s, RuntimeWarning, stacklevel=3)  # the caller's line, past with_one_blas_thread
    return Equilibrium(out, x, sysm, r, check.error, check.side_force_error, said, notes, check.law_side_force_error)


def first_unstable_tension(rod: RodParameters, stable, unstable: float, N: int = 15, wall=None,
                           tol: float = 1e-4) -> tuple[float, int]:
    """The axial force at which the untwisted rod (Phi = 0) first has an unstable mode, by bisection on
    the count of :func:`rodcont.stability.unstable_modes` (straight reference, e.g. lateral buckling of a
    rod lying in a pipe: ``wall``).

    ``stable``: forces walked through in order, the equilibrium solved at the first and carried to
    each next by Newton; every one must have no unstable mode (else ``ValueError``). ``unstable``: a
    force beyond the last of them. The bracket ``[stable[-1], unstable]`` is halved until shorter than
    ``tol``; returns ``(T, n)``: its end on the unstable side and the count at ``unstable``, or
    ``(nan, 0)`` when ``unstable`` has no unstable mode. ``ConvergenceError`` when Newton fails.
    """
    from ..stability import unstable_modes
    stable = [float(T) for T in stable]
    with np.errstate(all="ignore"):  # the start on this very mesh and law: carried to each force by Newton
        x = _load(_system(rod, _controls(rod, None, stable[0], None, 0.0, None), N, 5, None, wall),
                  _controls(rod, None, stable[0], None, 0.0, None), 0.5, 1e-10)[0]
    at: dict = {}

    def count(T: float, start: np.ndarray) -> int:
        s = RodSystem(rod, T=T, N=N, wall=wall)
        r = s.disc.newton(start, s.params(0.0))
        if not r.converged:
            raise ConvergenceError(f"no equilibrium of the untwisted rod at T = {T:.6g} ({r.message})")
        at[T] = r.x
        return unstable_modes(s, r.x, 0.0)

    for T in stable:
        if count(T, x):
            raise ValueError(f"the rod already has an unstable mode at T = {T:.6g}, given as stable")
        x = at[T]
    lo, hi = stable[-1], float(unstable)
    n = count(hi, at[lo])
    if n == 0:
        return math.nan, 0
    while abs(hi - lo) > tol:
        mid = 0.5 * (lo + hi)
        if count(mid, at[lo]) > 0:
            hi = mid
        else:
            lo = mid
    return hi, n


def write_equilibrium(eq: Equilibrium, out: str, overwrite: bool = False, meta: dict | None = None,
                      max_error: float = 1e-6) -> None:
    """``eq`` as a one-point branch file (``solve --out``): the point as a trace stores it (its coefficients without
    the parameters the controls freed, ``phi_L`` and ``T`` in its columns, the error estimate and, on the straight
    reference, the unstable modes under the controls in force), its mesh, the rod, the conduit as solved (its
    force scale) and the controls (``controls``: what was prescribed; a restart keeps them), and the unit tangent
    of the branch in ``phi_L`` at ``T`` through it (a restart's direction). ``export``, ``shape`` and
    ``trace --start F.h5:0`` read it as any branch file; ``max_error`` the guard it was solved to (a restart's
    default)."""
    import json

    from ..branch import CONTACT_COLUMNS, Branch
    from ..branchfile import BranchWriter, check_output
    from ..continuation import Kind, Point
    from ..result import Status
    from ..system import controls_spec
    from .trace import Recorder, StabilityCount, TraceOptions, _ContactRows, _mesh_group, file_meta
    sysm, o = eq.system, eq.outputs
    T, phi = float(o["T"]), float(o["phi_L"])
    canon = RodSystem(sysm.rod, T=T, k=sysm.disc.k, breakpoints=sysm.disc.breakpoints, curve=sysm.curve,
                      wall=sysm.wall, phi_L=phi)
    x = sysm.stored(eq.x)
    opts = TraceOptions(max_error=max_error)  # the guard it met (a restart's, unless given)
    attrs = file_meta(sysm.rod, T, canon.disc.N, canon.disc.k, "phi_L", opts, canon,
                      dict(meta or {}, solved="one equilibrium (rodcont solve)",
                           controls=json.dumps(controls_spec(sysm.ends))))
    out = check_output(out, overwrite=overwrite)
    data = dict(canon.outputs(x, phi), error=eq.error)
    pt = Point(x=x, p=phi, tx=np.zeros(x.size), tp=0.0, kind=Kind.START, data=data)
    pt.tx, pt.tp = _tangent_in_phi(canon, x, phi)
    # under the controls in force (a torque leaves the rotation free); -1 off the straight reference
    pt.data["unstable_modes"] = StabilityCount().count(sysm, eq.x, sysm.value()) if canon.straight else -1
    branch = Branch(sysm.rod.gamma(T) if sysm.rod.w > 0 else math.nan, sysm.rod, canon.disc.N, canon.disc.k,
                    attrs=attrs, curve=canon.curve, wall=canon.wall)
    writer = BranchWriter(out, attrs)
    group = writer.group("/", extra_columns=CONTACT_COLUMNS if canon.wall is not None else ())
    _mesh_group(writer, canon)
    contact = _ContactRows(canon) if canon.wall is not None else None
    try:
        Recorder(branch, writer, group, contact).add(pt, canon)
        if contact is not None:
            contact.fill(branch)
            contact.write(writer)
    finally:
        writer.close("one equilibrium (rodcont solve)", Status.COMPLETE)


def _tangent_in_phi(system: RodSystem, x: np.ndarray, phi: float) -> tuple[np.ndarray, float]:
    """The unit tangent (the tracker's arclength) of the branch in ``phi_L`` through ``(x, phi)``; zero where the
    Jacobian at fixed ``phi_L`` is singular (a fold: a restart then starts along ``phi_L``)."""
    from ..linalg import LU, SingularMatrix
    _, J, Fp = system.linearise(x, phi)
    try:
        dx = LU(J).solve(-np.asarray(Fp, float))
    except SingularMatrix:
        return np.zeros(x.size), 0.0
    sx, sp = system.arclength_scale()
    norm = math.sqrt(0.5 / x.size * float(np.sum((dx / sx) ** 2)) + 0.5 / sp**2)
    if not (math.isfinite(norm) and norm > 0):
        return np.zeros(x.size), 0.0
    return dx / norm, 1.0 / norm
