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
from .linalg import full_bordered_lu, powers_of_two
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


def check_callable(name: str, function, what: str = "a function") -> None:
    """``None`` or a callable; otherwise a ``TypeError`` naming ``name``."""
    if function is not None and not callable(function):
        raise TypeError(f"{name} must be {what}, got {function!r}")


def check_numbers(name: str, values) -> tuple:
    """A sequence of numbers as a tuple of floats; a single number or a string is a ``TypeError`` naming ``name``."""
    if isinstance(values, (str, bytes, dict)) or not hasattr(values, "__iter__"):
        raise TypeError(f"{name} must be a sequence of numbers, got {values!r}")
    return tuple(check_number(name, v) for v in values)


def check_mapping(name: str, value) -> None:
    """``None`` or a mapping (a dict); otherwise a ``TypeError`` naming ``name``."""
    from collections.abc import Mapping
    if value is not None and not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a dict, got {value!r}")


class RodSystem:
    """The discretised rod as a one-parameter problem ``F(x, q) = 0`` for the tracker.

    ``param`` names the continuation parameter (default ``phi_L``); every other
    entry of the model's parameters (``phi_L, T, w, EI, GJ, EA`` and those the end
    conditions add: ``torque``, ``l0``) is held at ``base``. With ``param = "gamma"``
    the tension follows ``T = gamma w L``.

    ``ends`` (:class:`rodcont.ends.RodEnds`, default the canonical clamps with ``Phi`` and ``T``
    imposed): under :class:`rodcont.ends.Torque` ``phi_L`` is an unknown (the last entries of ``x``,
    ``disc.full_params`` reads it), under :class:`rodcont.ends.UnstressedLength` ``T`` is; neither can
    then be the continued parameter. ``T`` under length control is only the first guess (default the
    straight rod's, ``EA (L/l0 - 1)``). A solution is stored without those entries (:meth:`stored`: the
    fields' coefficients, the same layout under every control) and read back by :meth:`expanded`.

    ``loads`` and ``sections``: the model's (:class:`rodcont.rod.EulerianRod`; default its weight, and the
    wall's force with ``wall``; one section).
    """

    def bordered_solver(self, J, b, c, d):
        """The LU of the whole bordered matrix, its rows in the rod's own units (:meth:`equation_scale`): the
        rod's border does not fill it, and block elimination costs ~25 % per step at N = 1500
        (benchmarks/bench.py section_bordered)."""
        r = self.equation_scale()
        # all ones (the paper's units): R A is A, so none is formed (0.2 ms a step at N = 50)
        return full_bordered_lu(J, b, c, d, row_scale=None if self.__dict__["_equation_scale"][2] else r)

    def equation_scale(self) -> np.ndarray:
        """Powers of two nearest the inverse units of the collocation rows (:func:`rodcont.linalg.powers_of_two`),
        so that the LU pivots as on the dimensionless problem: each row by its equation's unit from ``L`` and
        ``EI`` alone (force balance ``EI/L^3``, moment ``EI/L^2``, torque ``1/L^2``: all 1 for the paper's rod,
        whose LU is then the raw matrix's bit for bit). Unscaled, forces x 1e6 left the torque rows 1e-6 of
        the others, partial pivoting spoiled them, and a fold's torque was 1.2e-8 off (tests/test_units.py).
        The few boundary, interface and integral rows are left at 1: scaled by their terms in the unknowns'
        units, the paper's pivots changed and a trace in a pipe stopped elsewhere near its singular point
        (test_contact.py::test_a_trace_stopped_by_a_singular_point_says_so...). Once per discretisation."""
        disc = self.disc
        cached = self.__dict__.get("_equation_scale")
        if cached is None or cached[0] is not disc:
            force = self.rod.EI / self.rod.L**2
            m = disc.problem.n_fields * disc.npts
            units = np.ones(disc.size)
            units[:m] = np.tile([force / self.rod.L] * 3 + [force] * 2 + [self.rod.L**-2], disc.npts)
            r = powers_of_two(units[disc.row_order])
            cached = self._equation_scale = (disc, r, bool(np.all(r == 1.0)))
        return cached[1]

    def __init__(self, rod: RodParameters, gamma: float | None = None, N: int = 15, k: int = 5,
                 param: str = "phi_L", phi_L: float = 0.0, breakpoints=None, T: float | None = None,
                 curve=None, wall=None, ends=None, loads=None, sections=None):
        from .ends import RodEnds, UnstressedLength
        if not isinstance(rod, RodParameters):
            raise TypeError(f"rod must be a RodParameters, got {rod!r}")
        for name, v in (("gamma", gamma), ("phi_L", phi_L), ("T", T)):
            if v is not None and (isinstance(v, bool) or not np.isrealobj(v) or np.ndim(v) != 0
                                  or not isinstance(v, (int, float, np.number, np.ndarray))):
                raise TypeError(f"{name} must be a number, got {v!r}")
        ends = RodEnds() if ends is None else ends
        if not isinstance(ends, RodEnds):
            raise TypeError(f"ends must be a rodcont.ends.RodEnds, got {ends!r}")
        allowed = tuple(q for q in SYSTEM_PARAMS + tuple(name for name, _ in ends.params)
                        if q not in ends.frees and not (q == "gamma" and "T" in ends.frees))
        if param not in allowed:
            freed = [q for q in ends.frees if q == param or (param == "gamma" and q == "T")]
            raise ValueError(f"{param} is solved for under these end conditions: it cannot be continued" if freed
                             else f"param must be one of {', '.join(allowed)}, got {param!r}")
        if T is None:
            length = ends.find(UnstressedLength)
            if gamma is None and length is None:
                raise ValueError("give gamma or T")
            T = rod.tension(gamma) if gamma is not None else rod.EA * (rod.L / length.l0 - 1.0)
        if param == "gamma" and rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: continue in T")
        self.rod = rod
        self.model = EulerianRod(rod, curve, wall, ends=ends, loads=loads, sections=sections)
        self.ends = ends
        self.wall = wall
        self.curve = self.model.curve
        self.disc: Collocation = self.model.discretise(N, k, breakpoints=breakpoints)
        from .loads import Friction
        # a drill string (friction on the wall): its outputs gain the hook load and the surface torque
        self.drilling = any(isinstance(q, Friction) for q in (loads or ()))
        # friction that turns the string: its twist winds up tens of radians (rodcont.drilling)
        self.friction_torque = any(isinstance(q, Friction) and q.operation.rotating for q in loads or ())
        self.base = self.model.params(phi_L, T=T)
        self.param = param
        self.index = self.model.param_names.index("T" if param == "gamma" else param)
        self.scale = rod.w * rod.L if param == "gamma" else 1.0  # d(entry)/dq

    # ---- the controls: parameters solved for, and a solution's stored layout ---------------
    @property
    def freed(self) -> tuple:
        """The parameters the end conditions make unknowns (``phi_L`` under a torque, ``T`` under ``l0``)."""
        return tuple(self.ends.frees)

    def free_position(self, name: str) -> int:
        """Where the freed parameter ``name`` sits in ``x``."""
        return int(self.disc.free_index[self.freed.index(name)])

    def stored(self, x) -> np.ndarray:
        """``x`` (a solution or a tangent) without the freed parameters: the fields' coefficients, the layout a
        branch stores under every control (the freed values are columns of the table)."""
        x = np.asarray(x, float)
        return x[:self.disc.size - self.disc.n_free] if x.size == self.disc.size else x

    def expanded(self, x, tangent: bool = False) -> np.ndarray:
        """A stored solution (or, ``tangent``, a tangent) with the freed parameters appended, read from the
        fields at ``S = L``: ``phi_L = phi(L) + beta`` (the frame's turn), ``T = F . K3(L)``."""
        x = np.asarray(x, float)
        if x.size == self.disc.size or not self.disc.n_free:
            return x
        from .rod import Jet
        full = np.append(x, np.zeros(self.disc.n_free))
        zb = self.disc.end_jets(full)[1]
        # (a phase condition's freed weight is 0 on every equilibrium of the symmetric rod)
        read = {"phi_L": zb[Jet.PHI[0]] + (0.0 if tangent else self.model.twist_offset), "T": zb[Jet.F[2]], "w": 0.0}
        full[self.disc.free_index] = [read[name] for name in self.freed]
        return full

    def without_phase(self) -> RodSystem:
        """The same rod, mesh and parameters without a phase condition (:class:`rodcont.ends.Phase`): the physical
        controls, whose Jacobian is singular on the circles of buckled states (the stability count reads it:
        the rotation's null eigenvalue is not counted). ``self`` when there is none; cached per mesh."""
        from .ends import Phase, RodEnds
        if self.ends.find(Phase) is None:
            return self
        key = (self.disc.k, self.disc.breakpoints.tobytes(), tuple(self.base))
        cached = self.__dict__.get("_unphased")
        if cached is not None and cached[0] == key:
            return cached[1]
        ends = RodEnds(start=self.ends.start, end=tuple(c for c in self.ends.end if not isinstance(c, Phase)))
        other = RodSystem(self.rod, T=float(self.base[1]), k=self.disc.k, breakpoints=self.disc.breakpoints,
                          param=self.param, curve=self.curve, wall=self.wall, ends=ends)
        other.base = self.base.copy()
        self._unphased = (key, other)
        return other

    def full_params(self, x, value) -> np.ndarray:
        """Every parameter at ``(x, value)``, the freed ones read from ``x``."""
        return self.disc.full_params(self.expanded(x), self.params(value))

    @property
    def gamma(self) -> float:
        return self.rod.gamma(self.base[1])

    @property
    def _transverse(self) -> np.ndarray:
        return np.concatenate([self.disc.index[0], self.disc.index[1]])

    def with_mesh(self, breakpoints, k: int | None = None) -> RodSystem:
        """The same rod and parameters on another partition (and, optionally, another ``k``)."""
        new = RodSystem.__new__(RodSystem)
        new.__dict__.update(self.__dict__)
        new.disc = self.model.discretise(k=self.disc.k if k is None else k, breakpoints=np.asarray(breakpoints, float))
        new.base = self.base.copy()
        return new

    # ---- the meshed-problem protocol (rodcont.adaptive) ------------------------------
    @property
    def breakpoints(self) -> np.ndarray:
        return self.disc.breakpoints

    @property
    def k(self) -> int:
        return self.disc.k

    def transfer(self, x, source: RodSystem) -> np.ndarray:
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
        """What the error estimate compares, with its scales: the stretch, ``l0`` (scale ``L``), the torque
        (scale ``max(|torque|, EI/L)``) and the parameters solved for (``phi_L`` by one radian, or by its own size
        past one under friction that turns the string, ``T`` by the arclength's force scale)."""
        p = self.params(value)
        stretch, l0, torque = self.model.integral_outputs(self.disc, x, p)
        L = self.rod.L
        pf = self.disc.full_params(x, p)
        freed = [(v, self._free_unit(q, v)) for q in self.freed for v in [float(pf[self.model.param_names.index(q)])]]
        return ((stretch, l0, torque, *(v for v, _ in freed)),
                (1.0, L, max(abs(torque), float(p[3]) / L), *(u for _, u in freed)))

    def error_fields(self):
        """The fields the error estimate compares point by point: the deflections, on the scale ``L``."""
        return ((0, self.rod.L), (1, self.rod.L))

    def watched_quantities(self, x, value) -> dict:
        """Inside a conduit, the side force (scale ``max(|side force|, P L)``), kept apart from the
        estimate: the contact law turns a deflection error d into a pressure error of about
        d P / (eps c), and held to max_error it would refine far below the law's own error."""
        if self.wall is None:
            return {}
        sf = self.disc.integrate(self.model.pressure_at_points(self.disc, x))  # contact()'s, without its grid
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
        p = self.disc.full_params(x, self.params(value))
        o = self.model.outputs(self.disc, x, p)
        out = dict(phi_L=float(p[0]), stretch=o["stretch"], torque=o["torque"], l0=o["l0"],
                   helical_waves=o["helical_waves"], min_alignment=o["min_alignment"],
                   defect=o["defect"], torque_spread=o["torque_spread"], alpha_min=o["alpha_min"])
        if "T" in self.freed:
            out["T"] = float(p[1])
        if self.param != "phi_L":
            out[self.param] = float(value)
        if self.wall is not None:
            c = self.model.contact(self.disc, x, p)
            out.update(min_gap=c["min_gap"], side_force=c["side_force"], contact_zones=len(c["zones"]),
                       max_pressure=float(c["pressure"].max()),
                       penetration=float(np.max(-c["gap"] / self.wall.clearance_at(c["S"]))))
        if getattr(self, "drilling", False):
            from .ends import axial_force_and_torque
            F, M = axial_force_and_torque(self.model, self.disc, x, p, [self.model.interval[0]])
            out.update(hook_load=float(F[0]), surface_torque=float(M[0]))
        return out

    def arclength_scale(self):
        """Scales of the unknowns and of the parameter in the tracker's arclength, so that a step means
        the same in any units: the deflections by ``L``, the twist by one radian, the forces by
        ``max(|T|, w L, EI / L^2)``; the parameter by its own size (one radian for ``phi_L``)."""
        rod = self.rod
        fs = self._force_scale()
        sx = np.empty(self.disc.size)
        for i, s in enumerate((rod.L, rod.L, 1.0, fs, fs, fs)):
            sx[self.disc.index[i]] = s
        for name, j in zip(self.freed, self.disc.free_index):
            sx[j] = self._free_unit(name)
        sp = {"phi_L": 1.0, "T": fs, "gamma": max(abs(self.value()), 1.0), "w": max(rod.w, rod.EI / rod.L**3),
              "EI": rod.EI, "GJ": rod.GJ, "EA": rod.EA, "torque": rod.EI / rod.L, "l0": rod.L}[self.param]
        return sx, sp

    def unit_scale(self):
        """The rod's own units of the unknowns and of the parameter, from its span ``L`` and bending stiffness
        ``EI`` alone: deflections ``L``, the twist a radian, forces ``EI/L^2`` (a freed ``T`` too, a phase
        condition's weight ``EI/L^3``); the parameter likewise (``phi_L`` 1, ``T`` and ``EA`` ``EI/L^2``, ``w``
        ``EI/L^3``, ``EI`` and ``GJ`` ``EI``, ``torque`` ``EI/L``, ``l0`` ``L``, ``gamma`` 1). What the corrector's
        and Newton's convergence tests and the error estimate's hyperplane measure in: the same in any consistent
        units, and exactly 1 for the paper's rod (``L = EI = 1``), whose results are then those of the raw
        unknowns bit for bit (the arclength's own scales, :meth:`arclength_scale`, are not 1 there)."""
        rod = self.rod
        L, EI = rod.L, rod.EI
        force = EI / L**2
        sx = np.empty(self.disc.size)
        for i, u in enumerate((L, L, 1.0, force, force, force)):
            sx[self.disc.index[i]] = u
        for name, j in zip(self.freed, self.disc.free_index):
            sx[j] = {"phi_L": 1.0, "T": force, "w": force / L}[name]
        sp = {"phi_L": 1.0, "T": force, "gamma": 1.0, "w": force / L, "EI": EI, "GJ": EI, "EA": force,
              "torque": EI / L, "l0": L}[self.param]
        return sx, sp

    def _free_unit(self, name: str, value: float = 0.0) -> float:
        """The scale of a freed parameter: ``phi_L`` a radian (under friction that turns the string, the larger of
        a radian and its own size), ``T`` the forces', a phase condition's weight theirs per length."""
        if name == "phi_L" and self.friction_torque:
            return max(1.0, abs(value))
        return {"phi_L": 1.0, "T": self._force_scale(), "w": self._force_scale() / self.rod.L}[name]

    def _force_scale(self) -> float:
        """``max(|T|, w L, EI / L^2)``: the forces' scale (``T`` of the base: the start's under length control)."""
        rod = self.rod
        return max(abs(float(self.base[1])), rod.w * rod.L, rod.EI / rod.L**2)

    def relative_change(self, x0, x1) -> float:
        """Change of the transverse deflection ``(Delta1, Delta2)`` relative to its size
        (:meth:`relative_correction` with the predictor at the step's start). A deflection that doubles
        reads 0.5; one that flips sign reads 2. Only for traces in ``phi_L`` (where a nearly
        symmetric rod passes close to other branches); other parameters, such as the weight
        homotopy that grows a deflection from zero, read 0; so does a step from the straight rod (a switch at a
        critical twist), whose deflection grows from zero too."""
        if self.param != "phi_L":
            return 0.0
        idx = self._transverse
        if float(np.max(np.abs(x0[idx]))) <= 1e-12 * self.rod.L:
            return 0.0  # from the straight rod (a switch at a critical twist): the deflection grows from zero
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

    def straight_state(self, phi_L: float | None = None) -> np.ndarray:
        """The exact straight state ``Delta = 0``, ``phi = phi_L S / L``, ``F = T K3`` (exact for ``w = 0``).

        The controls in force decide what is given: ``T`` (or, under length control, ``T = EA (L/l0 - 1)``:
        ``alpha = L / l0``) and ``phi_L`` (or, under torque control, ``phi_L = M L / (GJ alpha)``: the torque
        ``GJ alpha phi_L / L``)."""
        if not self.straight:
            raise ValueError("the straight rod state exists only on the straight reference (--reference straight)")
        rod, L = self.rod, self.rod.L
        p = self.base
        names = self.model.param_names
        T = rod.EA * (L / float(p[names.index("l0")]) - 1.0) if "T" in self.freed else float(p[1])
        if "phi_L" in self.freed:
            phi_L = float(p[names.index("torque")]) * L / (rod.GJ * (1.0 + T / rod.EA))
        elif phi_L is None:
            phi_L = float(p[0])
        zero = lambda S: 0.0 * S  # noqa: E731
        free = {"phi_L": phi_L, "T": T, "w": 0.0}
        return self.disc.project([zero, zero, lambda S: phi_L * S / L, zero, zero, lambda S: 0.0 * S + T],
                                 [free[name] for name in self.freed])

    def key(self) -> tuple:
        """What makes two systems the same discrete problem (for caches)."""
        return (tuple(self.base), self.param, self.disc.k, self.disc.breakpoints.tobytes(),
                tuple(sorted(self.rod.as_dict().items())), getattr(self.curve, "spec", ""),
                self.wall.spec if self.wall is not None else "", self.ends)


class RodSystem2:
    """The rod as a two-parameter problem ``F(x, phi_L, q) = 0`` for fold curves.

    ``q`` is ``gamma`` (``T = gamma w L``, the others fixed) or one of ``T, w,
    EI, GJ, EA`` (the others, including ``T``, fixed).
    """

    def bordered_solver(self, J, b, c, d):
        """The one-parameter system's (:meth:`RodSystem.bordered_solver`: the same rows)."""
        return self.one.bordered_solver(J, b, c, d)

    def __init__(self, one: RodSystem, param: str):
        if not one.ends.is_default:
            raise ValueError("fold curves are continued with Phi and T imposed (the canonical end conditions)")
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

    def with_mesh(self, breakpoints, k: int | None = None) -> RodSystem2:
        return RodSystem2(self.one.with_mesh(breakpoints, k), self.param)

    def transfer(self, x, source: RodSystem2) -> np.ndarray:
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


def controls_spec(ends) -> dict:
    """The end conditions of a rod as a file stores them (``controls`` attribute, JSON): ``twist`` (``rotation``
    or ``torque``), ``axial`` (``tension`` or ``l0``) and the prescribed ``torque`` / ``l0`` values."""
    from .ends import Phase, Torque, UnstressedLength
    out = dict(twist="rotation", axial="tension")
    if ends.find(Phase) is not None:
        out["phase"] = True
    torque, length = ends.find(Torque), ends.find(UnstressedLength)
    if torque is not None:
        out.update(twist="torque", torque=float(torque.M))
    if length is not None:
        out.update(axial="l0", l0=float(length.l0))
    return out


def ends_from_spec(spec):
    """The :class:`rodcont.ends.RodEnds` of a ``controls`` attribute (a dict or its JSON; empty: the canonical ends)."""
    import json

    from .ends import Clamp, Phase, RodEnds, Rotation, Tension, Torque, UnstressedLength
    if isinstance(spec, (str, bytes)):
        spec = json.loads(spec) if spec else {}
    spec = dict(spec or {})
    twist = Torque(float(spec.get("torque", 0.0))) if spec.get("twist") == "torque" else Rotation()
    axial = UnstressedLength(float(spec["l0"])) if spec.get("axial") == "l0" else Tension()
    return RodEnds(end=(Clamp(), twist, axial) + ((Phase(),) if spec.get("phase") else ()))


_POINT_SYSTEMS: dict = {}


def point_system(data, i) -> RodSystem:
    """The :class:`RodSystem` a stored point ``i`` of a loaded branch lives on (its own mesh), with ``Phi`` and
    ``T`` imposed at the point's values (a point stored under other controls is the same equilibrium: its
    coefficients are stored without the freed parameters, :meth:`RodSystem.stored`, and its ``T`` is a column).

    Cached by content (rod, tension, mesh, k), never by file name: a file
    rewritten with another rod gets another system.
    """
    pt = data.point(i)
    b = np.asarray(pt["breakpoints"], float)
    rod, T = data.rod, data.tension
    param = data.param
    if param in ("EI", "GJ", "EA", "w") and param in pt:  # a trace in a rod parameter: the point's own value
        rod = RodParameters(**dict(rod.as_dict(), **{param: float(pt[param])}))
    if "T" in pt:  # a trace in T, or one under length control (T solved for at each point)
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
    if data.param == "phi_L" or ("phi_L_fixed" not in data.attrs and data.param != "torque"):
        return system
    out = RodSystem.__new__(RodSystem)  # a trace at fixed phi_L: that phi_L in the base
    out.__dict__.update(system.__dict__)
    out.base = system.base.copy()
    out.base[0] = float(pt["phi_L"])
    return out
