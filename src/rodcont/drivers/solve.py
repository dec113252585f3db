"""One equilibrium by natural loading: ``phi_L`` raised from 0 in steps, Newton at each.

Natural continuation cannot pass a fold in ``phi_L``: beyond the first fold it
reports non-convergence (:class:`ConvergenceError`) and says where it stopped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..linalg import NewtonResult
from ..rod import RodParameters
from ..system import RodSystem, check_number


class ConvergenceError(RuntimeError):
    pass


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
    """One solved equilibrium: its outputs, the unknown vector and how Newton ended."""

    outputs: dict
    x: np.ndarray
    system: RodSystem
    newton: NewtonResult

    @property
    def converged(self) -> bool:
        return self.newton.converged

    def contact(self) -> dict:
        """Contact with the conduit wall (:meth:`rodcont.rod.EulerianRod.contact`)."""
        sysm = self.system
        return sysm.model.contact(sysm.disc, self.x, sysm.params(self.outputs["phi_L"]))

    def centreline(self, S=None):
        S = np.linspace(*self.system.model.interval, 201) if S is None else S
        return self.system.model.centreline(self.system.disc, self.x, S)


def settle_in_conduit(sysm: RodSystem, x: np.ndarray, p: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """An equilibrium inside the conduit from a guess that may cross its wall: homotopy in the smoothing.

    The contact law ``p (g + p/k) = mu`` (:mod:`rodcont.contact`) is solved
    first with a soft wall (``eps = 0.1``), then with ``eps`` divided by 100 at
    each stage down to the wall's own, each stage from the previous solution
    (a stiff wall seen from a far-off guess stalls Newton's line search).
    Returns the last stage's solution (the caller confirms it with Newton).
    """
    import dataclasses
    model, wall = sysm.model, sysm.model.wall
    stages = [0.1]
    while stages[-1] / 100 > wall.eps:
        stages.append(stages[-1] / 100)
    stages.append(wall.eps)
    try:
        for eps in stages:
            model.wall = dataclasses.replace(wall, eps=eps)
            r = sysm.disc.newton(x, p, tol=tol, max_iter=60)
            if not r.converged:
                raise ConvergenceError(f"no equilibrium found inside the conduit (contact smoothing eps = "
                                       f"{eps:g}): {r.message}")
            x = r.x
    finally:
        model.wall = wall
    return x


def solve_equilibrium(gamma: float | None, phi_L: float, rod: RodParameters | None = None, N: int = 15, k: int = 5,
                      load_step: float = 0.5, tol: float = 1e-10, T: float | None = None, curve=None,
                      wall=None) -> Equilibrium:
    """Equilibrium at ``(gamma, phi_L)`` (or tension ``T``) reached by loading ``phi_L`` up from 0 in steps.

    A step that fails is halved (down to ``load_step / 1024``).
    """
    if rod is None:
        rod = RodParameters()
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    if T is None:
        gamma = check_number("gamma", gamma)
        if rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: give T")
        T = rod.tension(gamma)
    else:
        T = check_number("T", T)
        gamma = rod.gamma(T) if rod.w > 0 else math.nan
    phi_L = check_number("phi_L", phi_L)
    load_step = check_number("load_step", load_step, positive=True)
    N = check_number("N", N, integer=True)
    k = check_number("k", k, integer=True)
    tol = check_number("tol", tol, positive=True)
    if abs(phi_L) / load_step > 1e5:
        raise ValueError(f"load_step = {load_step:g} would take more than 1e5 steps to reach phi_L = {phi_L:g}")
    if not math.isfinite(T):
        raise ValueError(f"gamma = {gamma:g} gives a tension that is not finite")
    check_tension(rod, T)
    sysm = RodSystem(rod, T=T, N=N, k=k, curve=curve, wall=wall)
    with np.errstate(all="ignore"):
        x = sysm.model.initial_guess(sysm.disc, sysm.base[1])
        if wall is not None:
            x = settle_in_conduit(sysm, x, sysm.params(0.0), tol)
        r = sysm.disc.newton(x, sysm.params(0.0), tol=tol)
        if not r.converged:
            raise ConvergenceError(f"no equilibrium found at phi_L = 0 (T = {T:g}): {r.message}")
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
        out = sysm.outputs(x, phi_L)
    out["alpha_min"] = sysm.model.stretch_factor_min(sysm.disc, x, sysm.params(phi_L))
    check_physical(out, f"T = {T:g}, phi_L = {phi_L:g}")
    return Equilibrium(out, x, sysm, r)


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
    x = solve_equilibrium(None, 0.0, rod, N=N, T=stable[0], wall=wall).x
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
