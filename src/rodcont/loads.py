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
    evaluation (the wall pressure, for a friction law).
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


class DistributedLoad:
    """A load per unit reference length ``S`` (module docstring). Subclasses override what they contribute."""

    #: reads ``Delta1, Delta2`` themselves (not only through ``r'``): they enter the jet dependence
    reads_deflection = False
    #: names of the parameters it reads (entries of ``model.param_names``)
    params: tuple = ()

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

    def force(self, k: Kinematics):
        return (k.p[2] * k.n / k.alpha) * k.gK

    def __repr__(self):
        return "Weight()"


class WallContact(DistributedLoad):
    """The conduit wall's normal force (:class:`rodcont.contact.Wall`, smoothed complementarity) with the
    force scale ``P`` fixed when the model is built (``scale``; default the wall's own,
    :meth:`rodcont.contact.Wall.scale`): a trace in ``w`` or ``EI`` keeps one contact law."""

    reads_deflection = True

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

    def stations(self, a: float, b: float) -> list:
        if not self.wall.varying:
            return []
        return [S for S, _ in self.wall.clearance if a < S < b]

    def __repr__(self):
        return f"WallContact({self.wall.spec!r}, scale={self.scale!r})"
