"""Unilateral contact with the wall of a conduit: a rod inside a tube around its reference curve.

The conduit is the reference curve ``R(S)`` plus a clearance ``c`` (radius of
the conduit minus radius of the rod), constant or given at stations ``S_i`` and
varying linearly between them. In the Eulerian description
the wall constraint is local in ``S``: the rod's centreline
``r = R + Delta1 K1 + Delta2 K2`` must keep ``|Delta(S)| <= c``. The wall
pushes with a normal force per unit reference length ``p(S) >= 0`` along
``-Delta/|Delta|``, with ``p g = 0`` (no force across a gap). For a tube of
constant radius the wall's normal at ``R(S) + c n`` is ``n`` itself, in the
normal plane of ``S``, so the force acts in that plane and (frictionless,
through the axis of the section) adds no moment.

Complementarity, smoothed (the exact problem is the limit ``eps -> 0``).
With the smooth gap ``g = (c^2 - |Delta|^2) / (2 c)`` (``= c - |Delta|`` at the
wall, to second order) and a force scale ``P``::

    p (g + p / k) = mu,     k = P / (eps c),   mu = eps c P,

i.e. ``p = P (sqrt(gamma^2 + 4) - gamma) / 2`` with ``gamma = g / (eps c)``: a
wall of compliance ``eps c / P`` seen through a barrier of strength
``eps c P``. ``p`` is positive and smooth (analytic) for every ``Delta``;
where ``p = P`` the rod sits exactly on the wall, a smaller force leaves a
standoff ``~ eps c P / p``, a larger one a penetration ``~ eps c p / P``. Every
deviation from the exact complementarity is of order ``eps``; the tests drive
``eps`` down and check the limit against an independent solution of the
exact contact problem (free spans glued to a contact zone, shooting). The
force on the rod per unit ``S`` is ``q = -p Delta / c`` (``= -p Delta/|Delta|``
at the wall; the smooth form has no singularity at ``Delta = 0``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Wall:
    """A conduit wall at clearance ``c`` around the reference curve.

    ``eps``: the relative smoothing of the contact law (module docstring);
    deviations from exact contact are ``O(eps c)`` in the gap.
    ``force_scale``: ``P``, the force per unit length at which the rod sits
    exactly on the wall. Without one a model takes :meth:`scale` (the weight per
    unit length ``w``, or ``EI c / L^4`` for a weightless rod: what files written
    without a stored scale were solved with), and ``solve`` the problem's own,
    :func:`default_force_scale`. Any positive ``P`` gives the same limit; one near
    the actual contact forces gives the smallest error.
    ``contact_level``: a point is in contact where the wall pushes with at least
    ``contact_level * P`` (reporting only: the equations do not use it). For
    the default 1/2 that is where the gap is below ``1.5 eps c``: tied to the
    law, so the zones converge with it. A rod leaves a wall with a cubic gap
    (the shear force jumps at the edge of a contact), so a zone's ends
    converge like ``eps^(1/3)``; the force on it converges like ``eps``.
    """

    clearance: float | tuple
    eps: float = 1e-5
    force_scale: float | None = None
    contact_level: float = 0.5

    def __post_init__(self):
        if not isinstance(self.clearance, (int, float, np.integer, np.floating)) or isinstance(self.clearance, bool):
            object.__setattr__(self, "clearance", _clearance_table(self.clearance))
        for name in ("eps", "contact_level") + (() if self.varying else ("clearance",)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(v) or not v > 0:
                raise ValueError(f"conduit {name} must be a positive number, got {v!r}")
        if not self.eps <= 0.1:
            raise ValueError(f"conduit eps must be at most 0.1 (a relative smoothing), got {self.eps!r}")
        if not self.eps >= 1e-12:
            raise ValueError(f"conduit eps must be at least 1e-12 (a smaller one makes the wall stiffer than "
                             f"double precision resolves), got {self.eps!r}")
        for name, v in (("clearance", self.c_max), ("clearance", self.c_min), ("force_scale", self.force_scale)):
            if v is not None and not 1e-100 <= v <= 1e100:
                raise ValueError(f"conduit {name} = {v!r} is outside the range rodcont computes with "
                                 f"(1e-100 .. 1e100): change units")
        P = self.force_scale
        if P is not None and (isinstance(P, bool) or not isinstance(P, (int, float, np.integer, np.floating))
                              or not math.isfinite(P) or not P > 0):
            raise ValueError(f"conduit force_scale must be a positive number, got {P!r}")

    @property
    def varying(self) -> bool:
        """Whether the clearance varies along the conduit (a table of ``(S, c)``)."""
        return isinstance(self.clearance, tuple)

    @property
    def c_max(self) -> float:
        return max(c for _, c in self.clearance) if self.varying else float(self.clearance)

    def max_on(self, a: float, b: float) -> float:
        """The largest clearance over ``[a, b]`` (at the ends or at a station between them)."""
        if not self.varying:
            return float(self.clearance)
        at = [a, b] + [S for S, _ in self.clearance if a < S < b]
        return float(np.max(self.clearance_at(np.asarray(at, float))))

    @property
    def c_min(self) -> float:
        return min(c for _, c in self.clearance) if self.varying else float(self.clearance)

    def clearance_at(self, S):
        """``c(S)``: the constant clearance, or the table interpolated linearly in ``S`` (constant beyond its
        ends)."""
        if not self.varying:
            return float(self.clearance)
        t = np.asarray(self.clearance, float)
        return np.interp(np.real(np.asarray(S, float)), t[:, 0], t[:, 1])

    def scale(self, w: float, EI: float, L: float) -> float:
        """``P``: the given force scale, else ``w``, else ``EI c / L^4`` (the largest ``c`` over the span
        ``[0, L]``: stations of a table beyond the rod do not set its law)."""
        if self.force_scale is not None:
            return float(self.force_scale)
        return float(w) if w > 0 else float(EI) * self.max_on(0.0, float(L)) / float(L) ** 4

    def pressure(self, D1, D2, P: float, S=None):
        """Contact force per unit ``S``, ``p >= 0``, at deflections ``(D1, D2)`` (analytic: complex-step safe);
        ``S``: where, for a varying clearance."""
        c = self._c(S)
        gamma = (c * c - (D1 * D1 + D2 * D2)) / (2.0 * c * self.eps * c)
        root = np.sqrt(gamma * gamma + 4.0)
        # the two forms of the same root of p^2/k + g p - mu = 0, each free of cancellation on its side
        return np.where(np.real(gamma) > 0, (2.0 * P) / (root + gamma), 0.5 * P * (root - gamma))

    def pressure_slopes(self, D1, D2, P: float, S=None, pressure=None):
        """``(dp/dD1, dp/dD2)`` of :meth:`pressure` (exact): ``dp/dgamma = -p / sqrt(gamma^2 + 4)`` on both of
        its forms, ``dgamma/dD_a = -D_a / (eps c^2)`` (a subclass that changes :meth:`pressure` changes this too).
        ``pressure``: :meth:`pressure` at these points, when known."""
        c = self._c(S)
        p = self.pressure(D1, D2, P, S) if pressure is None else pressure
        gamma = (c * c - (D1 * D1 + D2 * D2)) / (2.0 * c * self.eps * c)
        s = p / (np.sqrt(gamma * gamma + 4.0) * (c * self.eps * c))
        return s * D1, s * D2

    def force(self, D1, D2, P: float, S=None, pressure=None):
        """The wall's force per unit ``S`` on the rod, components on ``K1, K2, K3``: ``q = -p Delta / c``
        across, and, where the clearance varies, ``p c'(S) |Delta|^2 / c^2`` along the axis (the wall of a
        widening conduit is a cone: its normal leans by ``c'``, so a frictionless wall pushes the rod toward
        the wide end; exact for a straight axis, to ``O(c kappa)`` on a curved one). The force acts through
        the centreline: the moment ``a p c'`` of a rod of radius ``a`` on a leaning wall is left out.
        ``pressure``: :meth:`pressure` at these points, when already computed."""
        c = self._c(S)
        p = self.pressure(D1, D2, P, S) if pressure is None else pressure
        f = -p / c
        if not self.varying:
            return f * D1, f * D2, 0.0
        return f * D1, f * D2, p * self.slope_at(S) * (D1 * D1 + D2 * D2) / (c * c)

    def slope_at(self, S):
        """``c'(S)`` of a varying clearance (piecewise constant; 0 beyond the table's ends)."""
        t = np.asarray(self.clearance, float)
        S = np.real(np.asarray(S, float))
        slopes = np.append(np.diff(t[:, 1]) / np.diff(t[:, 0]), 0.0)
        i = np.searchsorted(t[:, 0], S, side="right") - 1
        return np.where(i < 0, 0.0, slopes[np.clip(i, 0, slopes.size - 1)])

    def _c(self, S):
        if not self.varying:
            return float(self.clearance)
        if S is None:
            raise ValueError("a varying clearance needs the points S")
        return self.clearance_at(S)

    @property
    def spec(self) -> str:
        """A one-line description stored in branch files and compared on restart."""
        if self.varying:
            table = ";".join(f"{a!r}:{c!r}" for a, c in self.clearance)
            s = f"clearance={table},eps={float(self.eps)!r}"
        else:
            s = f"clearance={float(self.clearance)!r},eps={float(self.eps)!r}"
        if self.force_scale is not None:
            s += f",force_scale={float(self.force_scale)!r}"
        if self.contact_level != 0.5:
            s += f",contact_level={float(self.contact_level)!r}"
        return s

    @classmethod
    def from_spec(cls, spec: str) -> Wall:
        fields = {}
        for part in str(spec).split(","):
            key, _, val = part.partition("=")
            if key.strip() == "clearance" and ":" in val:
                fields["clearance"] = tuple(tuple(float(u) for u in row.split(":")) for row in val.split(";"))
            else:
                fields[key.strip()] = float(val)
        if fields.pop("steps", 0.0):  # a piecewise-constant clearance (rodcont.drilling.SteppedWall)
            from .drilling import SteppedWall
            return SteppedWall(**fields)
        return cls(**fields)


def _clearance_table(table) -> tuple:
    """``((S0, c0), (S1, c1), ...)`` from a sequence of pairs: at least two, ``S`` strictly increasing,
    every ``c`` positive and finite (a conduit whose clearance varies linearly between the stations)."""
    def number(v):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise TypeError
        return float(v)
    try:
        rows = tuple((number(a), number(c)) for a, c in table)
    except (TypeError, ValueError):
        raise ValueError(f"conduit clearance must be a positive number or a table of (S, c) pairs of numbers, "
                         f"got {table!r}") from None
    if len(rows) < 2:
        raise ValueError(f"a conduit clearance table needs at least two (S, c) rows, got {len(rows)}")
    S = np.array([a for a, _ in rows])
    c = np.array([v for _, v in rows])
    if not (np.all(np.isfinite(S)) and np.all(np.diff(S) > 0)):
        raise ValueError("the S of a conduit clearance table must be finite and strictly increasing")
    if np.any(np.diff(S) < 1e-9 * max(1.0, float(np.max(np.abs(S))))):
        raise ValueError("the stations of a conduit clearance table are too close (closer than 1e-9 of the "
                         "span): a step in the clearance needs a taper the mesh can resolve")
    if not (np.all(np.isfinite(c)) and np.all(c > 0)):
        raise ValueError("every clearance of a conduit clearance table must be a positive number")
    with np.errstate(all="ignore"):
        if not np.all(np.isfinite(np.diff(c) / np.diff(S))):
            raise ValueError("the stations of a conduit clearance table are too close for its slope to be finite")
    return rows


def contact_zones(S: np.ndarray, pressure: np.ndarray, level: float,
                  integral=None) -> list[tuple[float, float, float]]:
    """Contact zones ``(S_start, S_end, force)`` on a fine grid ``S``: runs where ``pressure >= level``.

    ``force`` is the wall's resultant on the zone: the integral of ``p`` from
    half-way to the previous zone (or the start) to half-way to the next one
    (or the end); ``integral(edges)`` gives the integrals between successive edges (default: the trapezoid
    rule on ``S``). The smoothed law turns the point forces of the exact problem
    (an isolated contact, the edge of a contact arc) into narrow peaks whose
    flanks lie just outside the contact run; the force in the gaps between
    zones is ``O(eps)``. A zone of a single grid point is a point contact
    (``S_start == S_end``).
    """
    on = pressure >= level
    if not on.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]])))
    runs = list(zip(edges[::2], edges[1::2] - 1))  # first and last grid index of each run
    bounds = [0] + [(runs[i][1] + runs[i + 1][0]) // 2 for i in range(len(runs) - 1)] + [S.size - 1]
    if integral is None:
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (pressure[1:] + pressure[:-1]) * np.diff(S))])
        force = np.diff(cum[bounds])
    else:
        force = integral(S[bounds])
    return [(float(S[a]), float(S[b]), float(force[i])) for i, (a, b) in enumerate(runs)]



# --------------------------------------------------------------------------
# The force scale a problem needs, and the penetration it leaves
# --------------------------------------------------------------------------
#: The penetration guard: a solved rod may sit at most this fraction of the local clearance inside the wall
#: (the smoothed law leaves ``~ eps c p / P``; solve stiffens the law to a tenth of it when it is passed).
MAX_PENETRATION = 1e-3


def default_force_scale(rod, T: float, curve=None, wall: Wall | None = None) -> float:
    """``P`` for a problem whose wall gives none: the largest of the wall forces per unit length the rod must
    carry, ``w`` (its weight), ``|T| kappa`` (pulled or pushed round the axis' curvature ``kappa``, its largest),
    ``EI kappa / L^2`` (bent with the axis) and ``EI c / L^4`` (a weightless rod deflected across the
    clearance): the law's penetration ``~ eps c p / P`` stays ``O(eps c)`` where the rod carries them.
    (The old default, ``w`` or ``EI c / L^4``, is :meth:`Wall.scale`: files without a stored scale keep it.)"""
    kappa = 0.0 if curve is None or getattr(curve, "constant_frame", True) else float(curve.max_curvature())
    L = float(rod.L)
    c = wall.max_on(0.0, L) if wall is not None else 0.0
    return float(max(rod.w, abs(float(T)) * kappa, rod.EI * kappa / L**2, rod.EI * c / L**4))


def penetration(model, disc, x, p) -> float:
    """The deepest penetration of the rod into the wall, as a fraction of the local clearance:
    ``max_S (|Delta| - c(S)) / c(S)`` on the contact grid (negative: nowhere in the wall)."""
    con = model.contact(disc, x, p)
    return float(np.max(-con["gap"] / model.wall.clearance_at(con["S"])))


# --------------------------------------------------------------------------
# Conduit files
# --------------------------------------------------------------------------
CONDUIT_KEYS = ("clearance", "eps", "force_scale", "contact_level", "reference")


class ConduitError(ValueError):
    """A conduit file that cannot be used; the message is one line and starts with the file's path."""


def load_conduit(path, L: float, reference: str | None = None):
    """``(curve, wall)`` of a conduit file (TOML, section ``[conduit]``): the wall
    (:class:`Wall`: ``clearance`` required, ``eps``, ``force_scale``, ``contact_level``) and the conduit's
    axis from its ``reference`` key (``KIND[:ARGS]`` as :func:`rodcont.curves.parse_reference`; a
    ``well:FILE`` read relative to the conduit file), its span checked against ``L``; ``curve`` is None when
    the file gives no axis (the caller's own reference curve applies).

    ``reference``: the caller's reference curve specification, if any other than ``straight``: a file that
    names a different one is refused (the axis is given twice). Every failure is a :class:`ConduitError`
    whose message starts with ``path``.
    """
    import json
    import os
    import tomllib

    from .safeio import InputFileError, read_input
    try:  # opened without blocking, checked by fstat: a device, a FIFO or a huge file is refused unread
        doc = tomllib.loads(read_input(path, "toml", what="conduit file").decode("utf-8"))
    except InputFileError as exc:
        raise ConduitError(str(exc)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConduitError(f"{path}: not a TOML file ({' '.join(str(exc).split())})") from None
    sec = doc.get("conduit")
    if not isinstance(sec, dict):
        raise ConduitError(f"{path}: needs a [conduit] section with clearance = C")
    unknown = sorted(set(sec) - set(CONDUIT_KEYS))
    if unknown:
        raise ConduitError(f"{path}: unknown key(s) {', '.join(unknown)} in [conduit] (known: "
                           f"{', '.join(CONDUIT_KEYS)})")
    if "clearance" not in sec:
        raise ConduitError(f"{path}: [conduit] needs clearance = C (conduit radius minus rod radius) "
                           f"or clearance = [[S0, C0], [S1, C1], ...] (varying linearly between stations S)")
    try:
        wall = Wall(**{key: sec[key] for key in CONDUIT_KEYS[:-1] if key in sec})
    except (TypeError, ValueError) as exc:
        raise ConduitError(f"{path}: {exc}") from None
    spec = sec.get("reference")
    if spec is None:
        return None, wall
    if not isinstance(spec, str):
        raise ConduitError(f"{path}: reference must be a string KIND[:ARGS], got {spec!r}")
    if reference is not None and reference.strip() not in ("straight", spec.strip()):
        raise ConduitError(f"{path} gives the reference curve ({spec}): drop --reference {reference}")
    source = f"{path}: reference = {json.dumps(spec, ensure_ascii=False)}"  # as written in the file
    kind, _, args = spec.strip().partition(":")
    if kind == "well" and args and not os.path.isabs(args):
        spec = f"well:{os.path.join(os.path.dirname(os.path.abspath(path)), args)}"
    return _conduit_axis(spec, L, source), wall


def unworded_reference_error(msg: str, spec: str) -> str:
    """``msg`` of :func:`rodcont.curves.parse_reference` without its ``--reference ...:`` prefix, for a file that
    gives the specification under another name."""
    kind = spec.strip().partition(":")[0].strip()
    for prefix in (f"--reference {spec}: ", f"--reference {kind}: ", "--reference: ", "--reference "):
        if msg.startswith(prefix):
            return msg[len(prefix):]
    return msg


def _conduit_axis(spec: str, L: float, source: str):
    """The reference curve of a conduit file's ``reference`` key (None for ``straight``), errors worded for
    the file's key (:func:`rodcont.curves.parse_reference` words them for ``--reference``)."""
    from .curves import parse_reference
    if not spec.strip():
        raise ConduitError(f"{source}: needs KIND[:ARGS] (straight, bump:H,THETA, ...)")
    if spec.strip() == "straight":
        return None
    try:
        with np.errstate(all="ignore"):
            curve = parse_reference(spec, L)
    except (ValueError, ArithmeticError) as exc:
        raise ConduitError(f"{source}: {unworded_reference_error(str(exc), spec)}") from None
    if abs(curve.span - L) > 1e-9 * L:
        raise ConduitError(f"{source}: its span {curve.span:.15g} differs from --L {L:.15g}; "
                           f"give --L {curve.span:.15g}")
    return curve
