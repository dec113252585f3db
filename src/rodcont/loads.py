"""Distributed loads on the rod: each one object, written once for the straight and the curved reference.

The balance laws of the Eulerian rod (:mod:`rodcont.rod`), in the components of
the reference frame ``K(S)``, with every distributed load per unit reference
length ``S``::

    F' + sum f = 0                                        (force balance, 3 rows)
    (EI u_perp' + m d3' + m' d3 + r' x F + sum l) . K_a = 0  (moment balance, a = 1, 2)
    (m' + sum l . d3) / GJ = 0                            (torque, 1 row)

A load contributes a force ``f`` (:meth:`DistributedLoad.force`) and/or a
moment ``l`` (:meth:`DistributedLoad.moment`), both ``(3, npts)`` on ``K1, K2, K3``.
The residual computes the kinematics once and hands them to every load as a
:class:`Kinematics`; the same load code serves the straight reference (constant
frame, ``g_K`` constant) and a moving frame (``g_K(S)`` varies).

Adding a load (e.g. Coulomb friction on the wall: an axial force ``-mu p`` along
the motion and a moment ``mu p r`` about ``d3``) is one subclass: its
``force``/``moment`` from the kinematics (the wall pressure through
:meth:`WallContact.pressure`, cached per evaluation), ``reads_deflection`` if it
reads ``Delta`` itself, ``params`` for the entries of the parameter vector it reads
(declared: the collocation differentiates only those), and pass it in
``EulerianRod(..., loads=[Weight(), WallContact(wall), Friction(...)])``. Loads
must be analytic in the jets (the complex step differentiates them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Kinematics:
    """What a load may read at the points ``S``: frame components throughout.

    ``z`` the jets (rows :class:`rodcont.rod.Jet`), ``p`` the parameter vector
    (names ``model.param_names``), ``n = |r'|``, ``alpha = 1 + F.d3/EA`` (so the
    unstressed arclength is ``s' = n/alpha``), ``d3`` the tangent director, ``gK``
    the weight's direction in the local frame (``(3, 1)`` on the straight
    reference, ``(3, npts)`` on a moving frame), ``deflection`` the rows
    ``(Delta1, Delta2)`` of the jets, ``cache`` shared by the loads of one
    evaluation (the wall pressure, for a friction law), ``w`` the weight per
    unstressed length at the points where it varies (a rod of
    :class:`rodcont.rod.Sections`; None: the parameter ``w``).
    """

    S: np.ndarray
    z: np.ndarray
    p: np.ndarray
    n: np.ndarray
    alpha: np.ndarray
    d3: np.ndarray
    gK: np.ndarray
    deflection: tuple
    cache: dict = field(default_factory=dict)
    w: object = None


@dataclass
class Tangents:
    """Tangents of the :class:`Kinematics` along seeds (axis 0, the model's choice of jet directions):
    ``n``, ``alpha`` ``(seeds, npts)``, ``d3`` ``(seeds, 3, npts)``, ``deflection`` the tangents of
    ``(Delta1, Delta2)``, each ``(seeds, npts)`` (or broadcasting to it)."""

    n: np.ndarray
    alpha: np.ndarray
    d3: np.ndarray
    deflection: tuple


class DistributedLoad:
    """A load per unit reference length ``S`` (module docstring). Subclasses override what they contribute."""

    #: reads ``Delta1, Delta2`` themselves (not only through ``r'``): they enter the jet dependence
    reads_deflection = False
    #: names of the parameters it reads (entries of ``model.param_names``)
    params: tuple = ()
    #: :meth:`force_tangent` and :meth:`moment_tangent` are exact, for loads that read only ``S, p, n, alpha,
    #: d3, deflection`` (and ``w``, ``cache``) of the kinematics: the model's analytic Jacobian uses them;
    #: a rod with any load without them takes the complex step (a subclass that changes ``force`` or ``moment``
    #: must change their tangents too, or set this False)
    tangents = False

    def force_tangent(self, k: Kinematics, t: Tangents):
        """Tangent of :meth:`force` along the seeds of ``t``, ``(seeds, 3, npts)``, or None where it is None."""
        return None

    def moment_tangent(self, k: Kinematics, t: Tangents):
        """Tangent of :meth:`moment` along the seeds of ``t``, ``(seeds, 3, npts)``, or None where it is None."""
        return None

    def force(self, k: Kinematics):
        """Force per unit ``S`` on ``K1, K2, K3`` (``(3, npts)``, or three rows; a row may be a scalar), or None."""
        return None

    def moment(self, k: Kinematics):
        """Moment per unit ``S`` on ``K1, K2, K3`` (``(3, npts)``), or None."""
        return None

    def stations(self, a: float, b: float) -> list:
        """Points of ``(a, b)`` where the load's data have a kink (mesh breakpoints)."""
        return []

    def bind(self, model) -> None:
        """Called once by the model that carries the load (resolve what depends on the rod)."""


class Weight(DistributedLoad):
    """The rod's own weight ``w`` per unit unstressed length along ``g``: ``f = (w n / alpha) g_K(S)``
    (``w`` the parameter ``w``, so a trace in ``w`` moves it; ``g`` is ``RodParameters.weight_direction``)."""

    params = ("w",)
    tangents = True

    def force(self, k: Kinematics):
        return ((k.p[2] if k.w is None else k.w) * k.n / k.alpha) * k.gK

    def force_tangent(self, k: Kinematics, t: Tangents):
        w = k.p[2] if k.w is None else k.w
        return ((w / k.alpha) * (t.n - (k.n / k.alpha) * t.alpha))[:, None] * k.gK

    def __repr__(self):
        return "Weight()"


class WallContact(DistributedLoad):
    """The conduit wall's normal force (:class:`rodcont.contact.Wall`, smoothed complementarity) with the
    force scale ``P`` fixed when the model is built (``scale``; default the wall's own,
    :meth:`rodcont.contact.Wall.scale`): a trace in ``w`` or ``EI`` keeps one contact law."""

    reads_deflection = True
    tangents = True

    def __init__(self, wall, scale: float | None = None):
        from .contact import Wall
        if not isinstance(wall, Wall):
            raise TypeError(f"wall must be a rodcont.contact.Wall, got {wall!r}")
        self.wall = wall
        self.scale = None if scale is None else float(scale)

    def bind(self, model) -> None:
        if self.scale is None:
            r = model.rod
            self.scale = self.wall.scale(r.w, r.EI, r.L)

    def pressure(self, k: Kinematics):
        """``p >= 0`` at the points (cached on ``k``: a friction law reads the same values)."""
        got = k.cache.get(id(self))
        if got is None:
            D1, D2 = k.deflection
            got = k.cache[id(self)] = self.wall.pressure(D1, D2, self.scale, k.S)
        return got

    def force(self, k: Kinematics):
        D1, D2 = k.deflection
        return self.wall.force(D1, D2, self.scale, k.S, pressure=self.pressure(k))

    def pressure_tangent(self, k: Kinematics, t: Tangents):
        """Tangent of :meth:`pressure` along the seeds of ``t``, ``(seeds, npts)`` (cached on ``k`` as it is)."""
        key = (id(self), "tangent")
        got = k.cache.get(key)
        if got is None:
            D1, D2 = k.deflection
            s1, s2 = self.wall.pressure_slopes(D1, D2, self.scale, k.S, pressure=self.pressure(k))
            got = k.cache[key] = s1 * t.deflection[0] + s2 * t.deflection[1]
        return got

    def force_tangent(self, k: Kinematics, t: Tangents):
        """Of ``q = -p Delta / c`` across and ``p c' |Delta|^2 / c^2`` along (:meth:`rodcont.contact.Wall.force`)."""
        D1, D2 = k.deflection
        dD1, dD2 = t.deflection
        p, dp = self.pressure(k), self.pressure_tangent(k, t)
        c = self.wall._c(k.S)
        out = np.zeros((dp.shape[0], 3, dp.shape[-1]))
        out[:, 0] = -(dp * D1 + p * dD1) / c
        out[:, 1] = -(dp * D2 + p * dD2) / c
        if self.wall.varying:
            r2 = D1 * D1 + D2 * D2
            out[:, 2] = (self.wall.slope_at(k.S) / (c * c)) * (dp * r2 + 2.0 * p * (D1 * dD1 + D2 * dD2))
        return out

    def stations(self, a: float, b: float) -> list:
        if not self.wall.varying:
            return []
        return [S for S, _ in self.wall.clearance if a < S < b]

    def __repr__(self):
        return f"WallContact({self.wall.spec!r}, scale={self.scale!r})"


# --------------------------------------------------------------------------
# Friction on the wall, set by the rig's operation
# --------------------------------------------------------------------------
#: the speed below which the motion is smoothed (m/s): the friction's direction ``v / sqrt(|v|^2 + v_s^2)``
#: is analytic through ``v = 0`` and vanishes there, as the contact law is analytic through ``p = 0``
SMOOTH_SPEED = 1e-6

#: the rig operations: trip speed ``V`` (m/s, > 0 out of the hole) and rotation rate (rpm); only the ratio
#: ``V : Omega r`` enters the friction (the velocity-vector method)
OPERATIONS = {"pick-up": (1.0, 0.0), "slack-off": (-1.0, 0.0), "rotate": (0.0, 60.0), "drill": (0.0, 60.0),
              "static": (0.0, 0.0)}


_MEANS = {"pick-up": "trips out (trip speed > 0)", "slack-off": "trips in (trip speed < 0)",
          "rotate": "turns the string (rpm != 0)", "drill": "has the bit on bottom (trip speed <= 0)",
          "static": "is the string at rest (no trip speed, no rpm)"}


def motion_name(trip_speed: float | None, rpm: float | None, on_bottom: bool = False) -> str:
    """The operation a motion names: drill on bottom; off bottom tripping out or in by the trip speed's sign
    (turning or not), else rotate where it turns, else static."""
    if on_bottom:
        return "drill"
    if trip_speed:
        return "pick-up" if trip_speed > 0 else "slack-off"
    return "rotate" if rpm else "static"


@dataclass(frozen=True)
class Operation:
    """The string's motion in the hole, the same at every point (a rigid trip and turn): trip speed ``V``
    (m/s, positive out of the hole: pick-up; negative: slack-off) and rotation rate ``rpm`` (positive
    clockwise seen from above, i.e. about the down-hole tangent ``d3``). At the contact the string's surface
    slides with ``(V, Omega r)`` (axial, circumferential; ``Omega = 2 pi rpm / 60``, ``r`` its outer radius) and
    the friction ``mu p`` is split along them::

        s_a = V / sqrt(V^2 + (Omega r)^2 + v_s^2),   s_r = Omega r / sqrt(V^2 + (Omega r)^2 + v_s^2)

    (``v_s`` = :data:`SMOOTH_SPEED`: both vanish when the string is at rest, ``static``).
    ``drill`` is ``rotate`` with the bit on bottom (its WOB and bit torque are end conditions)."""

    name: str = "static"
    trip_speed: float = 0.0
    rpm: float = 0.0

    @classmethod
    def named(cls, name: str | None, trip_speed: float | None = None, rpm: float | None = None) -> Operation:
        """An operation of :data:`OPERATIONS` by name (None: the one the motion names, :func:`motion_name`);
        ``trip_speed``/``rpm`` replace its motion (combined), and may not contradict the name: pick-up trips out
        (``V > 0``), slack-off in (``V < 0``), rotate turns (``rpm != 0``), drill has the bit on bottom (``V <= 0``),
        static is at rest (``--operation pick-up --trip-speed -0.5`` solved a slack-off and printed pick-up:
        test_the_printed_operation_is_the_motion_solved)."""
        for what, v in (("trip_speed", trip_speed), ("rpm", rpm)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)):
                raise ValueError(f"{what} must be a finite number, got {v!r}")
        name = motion_name(trip_speed, rpm) if name is None else name
        if name not in OPERATIONS:
            raise ValueError(f"unknown operation {name!r}: one of {', '.join(OPERATIONS)}")
        V, rpm0 = OPERATIONS[name]
        op = cls(name, float(V if trip_speed is None else trip_speed), float(rpm0 if rpm is None else rpm))
        wrong = {"pick-up": op.trip_speed <= 0, "slack-off": op.trip_speed >= 0, "rotate": op.rpm == 0,
                 "drill": op.trip_speed > 0, "static": op.trip_speed != 0 or op.rpm != 0}[name]
        if wrong:
            raise ValueError(f"operation {name} {_MEANS[name]}: trip speed {op.trip_speed:g} m/s and {op.rpm:g} rpm "
                             f"contradict it (give the operation the motion names, or no operation)")
        return op

    @property
    def omega(self) -> float:
        return 2.0 * np.pi * self.rpm / 60.0

    def split(self, r):
        """``(s_a, s_r)`` at the outer radius ``r`` (number or array)."""
        vr = self.omega * np.asarray(r, float)
        speed = np.sqrt(self.trip_speed**2 + vr * vr + SMOOTH_SPEED**2)
        return self.trip_speed / speed, vr / speed

    @property
    def rotating(self) -> bool:
        return self.rpm != 0.0


def _stations(value, what: str):
    """A number, or stations ``((S_from, value), ...)`` (piecewise constant, each from its ``S`` on) as arrays
    ``(S, values)``; the first station's value also holds before it."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return np.zeros(1), np.array([float(value)])
    try:
        rows = np.array([[float(a), float(b)] for a, b in value])
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number or stations [(S, value), ...], got {value!r}") from None
    if rows.shape[0] < 1 or not np.all(np.isfinite(rows)) or np.any(np.diff(rows[:, 0]) <= 0):
        raise ValueError(f"the stations of {what} must be finite with S strictly increasing")
    return rows[:, 0], rows[:, 1]


class Friction(DistributedLoad):
    """Coulomb friction of factor ``mu`` on the wall's normal force ``p`` (per unit ``S``, read from the rod's
    :class:`WallContact`), opposing the string's sliding on the wall (:class:`Operation`)::

        f = mu p s_a d3              (axial: the force balance, F' + ... + f = 0)
        l = -mu p r s_r d3           (about the axis: m' = mu p r s_r, so the torque is a field)

    ``r`` the string's outer radius (where it touches the wall). Sign conventions: ``F . d3 > 0`` is tension,
    ``d3`` points down-hole; pick-up (``s_a > 0``) drags the string down-hole, so the axial force grows towards
    the rig; the rig turns the string about ``d3`` and the internal torque ``m`` is negative: the surface torque
    is ``M = -m(0)``, with ``dM/dS = -mu p r s_r`` (the soft-string ``dM/ds = -s_r mu |N| r``). Not modelled: the
    circumferential friction force on the axis (it makes a turning string climb the wall) and the moment of
    the axial friction about the section (``r mu p``, across the axis).

    ``mu`` and ``radius``: numbers or stations ``((S, value), ...)``, piecewise constant (cased and open hole;
    a string's sections): their stations are mesh breakpoints.
    """

    reads_deflection = True
    tangents = True

    def __init__(self, mu, radius, operation: Operation | str = "static"):
        self.mu_table = _stations(mu, "the friction factor")
        self.r_table = _stations(radius, "the string's outer radius")
        if np.any(self.mu_table[1] < 0) or np.any(self.r_table[1] <= 0):
            raise ValueError("the friction factor must be non-negative and the outer radius positive")
        self.operation = Operation.named(operation) if isinstance(operation, str) else operation
        if not isinstance(self.operation, Operation):
            raise TypeError(f"operation must be a rodcont.loads.Operation or a name, got {operation!r}")
        self._wall = None

    def bind(self, model) -> None:
        wall = getattr(model, "_wall_load", None)
        if wall is None:
            raise ValueError("friction acts on a wall's force: the rod needs a conduit (wall=)")
        self._wall = wall

    @staticmethod
    def _at(table, S):
        at, values = table
        i = np.clip(np.searchsorted(at, np.real(np.asarray(S)), side="right") - 1, 0, values.size - 1)
        return values[i]

    def mu(self, S):
        """The friction factor at ``S``."""
        return self._at(self.mu_table, S)

    def radius(self, S):
        """The outer radius at ``S``."""
        return self._at(self.r_table, S)

    def shares(self, S):
        """``(mu s_a, mu s_r r)`` at ``S``: the axial friction and the friction moment per unit wall force."""
        r = self.radius(S)
        s_a, s_r = self.operation.split(r)
        mu = self.mu(S)
        return mu * s_a, mu * s_r * r

    def force(self, k: Kinematics):
        axial, _ = self.shares(k.S)
        if not np.any(axial):
            return None
        return (axial * self._wall.pressure(k)) * k.d3

    def moment(self, k: Kinematics):
        _, turn = self.shares(k.S)
        if not np.any(turn):
            return None
        return -(turn * self._wall.pressure(k)) * k.d3

    def _along_d3_tangent(self, share, k: Kinematics, t: Tangents):
        """Tangent of ``share p d3``."""
        dp = self._wall.pressure_tangent(k, t)
        return share * (dp[:, None] * k.d3 + self._wall.pressure(k) * t.d3)

    def force_tangent(self, k: Kinematics, t: Tangents):
        axial, _ = self.shares(k.S)
        return self._along_d3_tangent(axial, k, t) if np.any(axial) else None

    def moment_tangent(self, k: Kinematics, t: Tangents):
        _, turn = self.shares(k.S)
        return self._along_d3_tangent(-turn, k, t) if np.any(turn) else None

    def stations(self, a: float, b: float) -> list:
        return [float(S) for S in np.concatenate([self.mu_table[0], self.r_table[0]]) if a < S < b]

    def __repr__(self):
        return (f"Friction(mu={list(zip(*self.mu_table))!r}, radius={list(zip(*self.r_table))!r}, "
                f"operation={self.operation!r})")
