"""The rod on the generic solvers: the discretised rod as a one- or two-parameter problem.

:class:`RodSystem` is ``F(x, q) = 0`` for the tracker, with ``q`` any one of
``phi_L, T, w, EI, GJ, EA`` or ``gamma`` (``T = gamma w L``); the other
parameters are held at ``base``. :class:`RodSystem2` is ``F(x, phi_L, q) = 0``
for fold curves. Both are meshed problems (the protocol of :mod:`rodcont.adaptive`):
they know their mesh, ``with_mesh`` moves them to another, ``transfer`` carries a
solution over, and they name what the error estimate compares.
"""

from __future__ import annotations

import math

import numpy as np

from .collocation import Collocation
from .rod import PARAMS, EulerianRod, RodParameters

SYSTEM_PARAMS = PARAMS + ("gamma",)
OUTPUTS = ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "defect")


def check_number(name: str, value, *, positive: bool = False, nonnegative: bool = False,
                 integer: bool = False, allow_inf: bool = False) -> float:
    """One validation for the API and the command line: a ``TypeError`` or ``ValueError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be {'an integer' if integer else 'a number'}, got {value!r}")
    if integer and not (isinstance(value, (int, np.integer)) or float(value).is_integer()):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if positive and not v > 0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    if nonnegative and not v >= 0:
        raise ValueError(f"{name} must be non-negative, got {value!r}")
    return int(v) if integer else v


class RodSystem:
    """The discretised rod as a one-parameter problem ``F(x, q) = 0`` for the tracker.

    ``param`` names the continuation parameter (default ``phi_L``); every other
    entry of ``(phi_L, T, w, EI, GJ, EA)`` is held at ``base``. With
    ``param = "gamma"`` the tension follows ``T = gamma w L``.
    """

    def __init__(self, rod: RodParameters, gamma: float | None = None, N: int = 15, k: int = 5,
                 param: str = "phi_L", phi_L: float = 0.0, breakpoints=None, T: float | None = None,
                 curve=None, wall=None):
        if param not in SYSTEM_PARAMS:
            raise ValueError(f"param must be one of {', '.join(SYSTEM_PARAMS)}, got {param!r}")
        if T is None:
            if gamma is None:
                raise ValueError("give gamma or T")
            T = rod.tension(gamma)
        if param == "gamma" and rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: continue in T")
        self.rod = rod
        self.model = EulerianRod(rod, curve, wall)
        self.wall = wall
        self.curve = self.model.curve
        self.disc: Collocation = self.model.discretise(N, k, breakpoints=breakpoints)
        self.base = self.model.params(phi_L, T=T)
        self.param = param
        self.index = PARAMS.index("T" if param == "gamma" else param)
        self.scale = rod.w * rod.L if param == "gamma" else 1.0  # d(entry)/dq

    @property
    def gamma(self) -> float:
        return self.rod.gamma(self.base[1])

    @property
    def _transverse(self) -> np.ndarray:
        return np.concatenate([self.disc.index[0], self.disc.index[1]])

    def with_mesh(self, breakpoints, k: int | None = None) -> "RodSystem":
        """The same rod and parameters on another partition (and, optionally, another ``k``)."""
        new = RodSystem.__new__(RodSystem)
        new.__dict__.update(self.__dict__)
        new.disc = self.model.discretise(k=self.disc.k if k is None else k, breakpoints=np.asarray(breakpoints, float))
        new.model.output_evaluator(new.disc)
        new.base = self.base.copy()
        return new

    # ---- the meshed-problem protocol (rodcont.adaptive) ------------------------------
    @property
    def breakpoints(self) -> np.ndarray:
        return self.disc.breakpoints

    @property
    def k(self) -> int:
        return self.disc.k

    def transfer(self, x, source: "RodSystem") -> np.ndarray:
        """``x`` (a solution or a tangent of ``source``, on its mesh) on this system's mesh."""
        return self.disc.transfer(x, source.disc)

    @property
    def fixed_parameters(self) -> np.ndarray:
        """The parameters held fixed (``base``), for the error estimate's richer twin."""
        return self.base.copy()

    @fixed_parameters.setter
    def fixed_parameters(self, base) -> None:
        self.base = np.array(base, float)

    def error_quantities(self, x, value):
        """What the error estimate compares, with its scales: the stretch, ``l0`` (scale ``L``) and
        the torque (scale ``max(|torque|, EI/L)``)."""
        p = self.params(value)
        o = self.model.outputs(self.disc, x, p)
        L = self.rod.L
        return ((o["stretch"], o["l0"], o["torque"]),
                (1.0, L, max(abs(o["torque"]), float(p[3]) / L)))

    def error_fields(self):
        """The fields the error estimate compares point by point: the deflections, on the scale ``L``."""
        return ((0, self.rod.L), (1, self.rod.L))

    def watched_quantities(self, x, value) -> dict:
        """Inside a conduit, the side force (scale ``max(|side force|, P L)``), kept apart from the
        estimate: the contact law turns a deflection error d into a pressure error of about
        d P / (eps c), and held to max_error it would refine far below the law's own error."""
        if self.wall is None:
            return {}
        sf = self.model.contact(self.disc, x, self.params(value))["side_force"]
        return {"side_force": (sf, max(abs(sf), self.model.contact_scale * self.rod.L))}

    def value(self) -> float:
        """``q`` at the base parameters."""
        return float(self.base[self.index] / self.scale)

    def params(self, value: float) -> np.ndarray:
        p = self.base.copy()
        p[self.index] = value * self.scale
        return p

    def set_value(self, value: float) -> None:
        self.base = self.params(value)

    def residual(self, x, value):
        return self.disc.residual(x, self.params(value))

    def linearise(self, x, value):
        F, J, Fp = self.disc.linearise(x, self.params(value), [self.index])
        return F, J, Fp[0] * self.scale

    def tangent(self, x, value):
        return self.linearise(x, value)[1:]

    def outputs(self, x, value) -> dict:
        p = self.params(value)
        o = self.model.outputs(self.disc, x, p)
        out = dict(phi_L=float(p[0]), stretch=o["stretch"], torque=o["torque"], l0=o["l0"],
                   helical_waves=o["helical_waves"], min_alignment=o["min_alignment"],
                   defect=o["defect"], torque_spread=o["torque_spread"], alpha_min=o["alpha_min"])
        if self.param != "phi_L":
            out[self.param] = float(value)
        if self.wall is not None:
            c = self.model.contact(self.disc, x, p)
            out.update(min_gap=c["min_gap"], side_force=c["side_force"], contact_zones=len(c["zones"]),
                       max_pressure=float(c["pressure"].max()))
        return out

    def arclength_scale(self):
        """Scales of the unknowns and of the parameter in the tracker's arclength, so that a step means
        the same in any units: the deflections by ``L``, the twist by one radian, the forces by
        ``max(|T|, w L, EI / L^2)``; the parameter by its own size (one radian for ``phi_L``)."""
        rod = self.rod
        T = float(self.base[1])
        fs = max(abs(T), rod.w * rod.L, rod.EI / rod.L**2)
        sx = np.empty(self.disc.size)
        for i, s in enumerate((rod.L, rod.L, 1.0, fs, fs, fs)):
            sx[self.disc.index[i]] = s
        sp = {"phi_L": 1.0, "T": fs, "gamma": max(abs(self.value()), 1.0), "w": max(rod.w, rod.EI / rod.L**3),
              "EI": rod.EI, "GJ": rod.GJ, "EA": rod.EA}[self.param]
        return sx, sp

    def relative_change(self, x0, x1) -> float:
        """Change of the transverse deflection ``(Delta1, Delta2)`` relative to its size
        (:meth:`relative_correction` with the predictor at the step's start). A deflection that doubles
        reads 0.5; one that flips sign reads 2. Only for traces in ``phi_L`` (where a nearly
        symmetric rod passes close to other branches); other parameters, such as the weight
        homotopy that grows a deflection from zero, read 0."""
        if self.param != "phi_L":
            return 0.0
        return self.relative_correction(x0, x0, x1)

    def relative_correction(self, x0, x_pred, x1) -> float:
        """How far the corrector moved the predictor's transverse deflection, relative to the deflection's
        size at the step's two ends: ``|Delta1 - Delta_pred| / max(|Delta0|, |Delta1|)`` (B-spline coefficients,
        max norm; sizes below 1e-12 L count as 1e-12 L). Small on any resolved step, whatever the
        parameter (the weight homotopy's deflection that grows from zero is predicted by its tangent);
        about 1 where the corrector lands on another branch with or without the deflection (the
        straight rod)."""
        idx = self._transverse
        a, q, b = x0[idx], x_pred[idx], x1[idx]
        size = max(float(np.max(np.abs(a))), float(np.max(np.abs(b))), 1e-12 * self.rod.L)
        return float(np.max(np.abs(b - q))) / size

    def interval_defect(self, x, value) -> np.ndarray:
        return self.model.output_evaluator(self.disc).interval_defect(x, self.params(value))

    @property
    def straight(self) -> bool:
        """Is the reference curve the straight span (the only one with a straight rod state)?"""
        return bool(getattr(self.curve, "constant_frame", False))

    def conform(self, breakpoints) -> np.ndarray:
        """A mesh with breakpoints at the stations of the reference curve and of the clearance, if any."""
        from .curves import conform_to
        return np.asarray(conform_to(np.asarray(breakpoints, float), self.model.stations), float)

    def straight_state(self, phi_L: float) -> np.ndarray:
        """The exact straight state ``Delta = 0``, ``phi = phi_L S / L``, ``F = T K3`` (exact for ``w = 0``)."""
        if not self.straight:
            raise ValueError("the straight rod state exists only on the straight reference (--reference straight)")
        L, T = self.rod.L, float(self.base[1])
        zero = lambda S: 0.0 * S  # noqa: E731
        return self.disc.project([zero, zero, lambda S: phi_L * S / L, zero, zero, lambda S: 0.0 * S + T])

    def key(self) -> tuple:
        """What makes two systems the same discrete problem (for caches)."""
        return (tuple(self.base), self.param, self.disc.k, self.disc.breakpoints.tobytes(),
                tuple(sorted(self.rod.as_dict().items())), getattr(self.curve, "spec", ""),
                self.wall.spec if self.wall is not None else "")


class RodSystem2:
    """The rod as a two-parameter problem ``F(x, phi_L, q) = 0`` for fold curves.

    ``q`` is ``gamma`` (``T = gamma w L``, the others fixed) or one of ``T, w,
    EI, GJ, EA`` (the others, including ``T``, fixed).
    """

    def __init__(self, one: RodSystem, param: str):
        if param not in ("gamma", "T", "w", "EI", "GJ", "EA"):
            raise ValueError(f"param must be one of gamma, T, w, EI, GJ, EA, got {param!r}")
        if param == "gamma" and one.rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: continue in T")
        self.one = one
        self.param = param
        self.index = PARAMS.index("T" if param == "gamma" else param)
        self.scale = one.rod.w * one.rod.L if param == "gamma" else 1.0

    def value(self) -> float:
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

    def outputs(self, x, phi_L, q) -> dict:
        p = self.params(phi_L, q)
        o = self.one.model.outputs(self.one.disc, x, p)
        return dict(phi_L=float(phi_L), stretch=o["stretch"], torque=o["torque"], l0=o["l0"],
                    helical_waves=o["helical_waves"], min_alignment=o["min_alignment"], defect=o["defect"],
                    **{self.param: float(q)})

    # ---- the meshed two-parameter protocol (rodcont.bifurcation.FoldProblem) -----------------
    @property
    def breakpoints(self) -> np.ndarray:
        return self.one.disc.breakpoints

    @property
    def k(self) -> int:
        return self.one.disc.k

    def with_mesh(self, breakpoints, k: int | None = None) -> "RodSystem2":
        return RodSystem2(self.one.with_mesh(breakpoints, k), self.param)

    def transfer(self, x, source: "RodSystem2") -> np.ndarray:
        return self.one.disc.transfer(x, source.one.disc)

    def conform(self, breakpoints) -> np.ndarray:
        return self.one.conform(breakpoints)

    def interval_defect(self, x, phi_L, q) -> np.ndarray:
        return self.one.model.output_evaluator(self.one.disc).interval_defect(x, self.params(phi_L, q))

    def slice(self, q) -> RodSystem:
        """The one-parameter problem in ``phi_L`` at ``q`` (this system's own, re-based: no new mesh)."""
        self.one.base = self.params(float(self.one.base[0]), q)
        return self.one


def rod_at(rod: RodParameters, p: np.ndarray) -> RodParameters:
    """The rod whose stiffnesses and weight are those of the parameter vector ``p``."""
    return RodParameters(EI=float(p[3]), GJ=float(p[4]), EA=float(p[5]), w=float(p[2]), L=rod.L,
                         weight_direction=rod.weight_direction)


_POINT_SYSTEMS: dict = {}


def point_system(data, i) -> RodSystem:
    """The :class:`RodSystem` a stored point ``i`` of a loaded branch lives on (its own mesh).

    Cached by content (rod, tension, mesh, k), never by file name: a file
    rewritten with another rod gets another system.
    """
    pt = data.point(i)
    b = np.asarray(pt["breakpoints"], float)
    rod, T = data.rod, data.tension
    param = data.param
    if param in ("EI", "GJ", "EA", "w") and param in pt:  # a trace in a rod parameter: the point's own value
        rod = RodParameters(**dict(rod.as_dict(), **{param: float(pt[param])}))
    elif param == "T" and "T" in pt:
        T = float(pt["T"])
    elif param == "gamma" and "gamma" in pt:
        T = float(pt["gamma"]) * rod.w * rod.L
    spec = str(data.attrs.get("reference", "straight"))
    key = (tuple(sorted(rod.as_dict().items())), float(T), b.tobytes(), int(data.attrs["k"]), spec,
           str(data.attrs.get("conduit", "")))
    if key not in _POINT_SYSTEMS:
        if len(_POINT_SYSTEMS) > 32:
            _POINT_SYSTEMS.clear()
        _POINT_SYSTEMS[key] = RodSystem(rod, T=T, N=b.size - 1, k=int(data.attrs["k"]), breakpoints=b,
                                        curve=data.curve, wall=data.wall)
    system = _POINT_SYSTEMS[key]
    if data.param == "phi_L" or "phi_L_fixed" not in data.attrs:
        return system
    out = RodSystem.__new__(RodSystem)  # a trace at fixed phi_L: that phi_L in the base
    out.__dict__.update(system.__dict__)
    out.base = system.base.copy()
    out.base[0] = float(pt["phi_L"])
    return out
