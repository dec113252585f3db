"""The Eulerian extensible rod (Huynen, Detournay & Denoël) as a collocation problem.

The rod is described as a perturbation of a reference curve ``R(S)`` with
frame ``{K1, K2, K3 = R'}``: centreline ``r = R + Delta1 K1 + Delta2 K2``,
section turned by ``phi(S)`` about ``d3`` relative to the minimal-rotation
image ``{a1, a2}`` of ``{K1, K2}`` (pole ``p = K3``). Unknown fields and
orders: ``Delta1, Delta2`` (3), ``phi`` (2), the components of the internal
force ``F`` on the frame ``K1, K2, K3`` (1 each). With ``n = |r'|``, ``d3 = r'/n``,
``alpha = 1 + F.d3/EA``, ``s' = n/alpha`` the equations (FORMULATION.md §2)::

    F' + f s' = 0                                   (3, f = w g per unstressed length)
    (EI u_perp' + m d3' + m' d3 + r' x F) . K_a = 0 (2, a = 1, 2)
    m' / GJ = 0                                     (1, isotropic: constant torque)

with ``u_perp = alpha (r' x r'')/n^3``, ``m = GJ J1 (phi' + tau_q)``,
``J1 = alpha/n`` and the twist rate of the minimal-rotation frame
``tau_q = -p.(d3 x d3')/(1 + p.d3)``. Everything is an explicit, analytic
function of the local jet, so the complex step gives the exact Jacobian.

Moving frame (any smooth reference curve, :mod:`rodcont.curves`). The frame
turns with ``S``: ``K3' = k1 K1 + k2 K2``, ``K1' = k3 K2 - k1 K3``,
``K2' = -k3 K1 - k2 K3`` (``k3 = 0`` for the Bishop frames of the built-in
curves), i.e. ``v' = [v]' + omega x v`` in frame components with
``omega = (-k2, k1, k3)``. Still in the components of the local frame, what
changes is (the rest is the same expression of ``r', r'', r'''``)::

    r'   = (Delta1' - k3 Delta2, Delta2' + k3 Delta1, 1 - k1 Delta1 - k2 Delta2)
    r''  = [r']' + omega x r',   r''' = [r'']' + omega x r''       (K' and K'' terms)
    F'   = [F]' + omega x F      (in the force balance and in alpha')
    f    = w g_K(S)              (the weight is global: its frame components vary)
    tau_q  = k3 + [d3.(p x p') - p.(d3 x d3')] / (1 + p.d3),  p = K3, p' = K3'
    tau_q' = k3' + N'/D - N D'/D^2   (N, D numerator and denominator of the fraction)

For a straight reference (``k = 0``) every added term vanishes; that case
keeps its own, cheaper residual.

Loads and ends. The distributed loads (the weight ``f = w g``, the wall's
force, any other) are objects (:mod:`rodcont.loads`), each added once to both
residuals from the kinematics they are handed; hand-derived Jacobians cover
the straight rod under its weight alone (:meth:`EulerianRod.jacobian`) and a
moving frame under loads with exact tangents (weight, wall, friction:
:meth:`EulerianRod._jacobian_curved`); every other case takes the complex
step. The boundary conditions are assembled from end-condition objects
(:mod:`rodcont.ends`: clamp, rotation or torque, tension or unstressed length). The end twist condition becomes
``phi(end) = phi_L - beta`` with ``beta`` the turn of the curve's frame
between the ends (:attr:`rodcont.curves.ReferenceCurve.end_twist`).

Joins. Where the reference's curvature jumps (a well's stations,
:attr:`rodcont.curves.ReferenceCurve.curvature_jumps`) the physical rod is
smooth but ``Delta'``, ``Delta''``, ``phi'`` jump: there ``Delta1, Delta2, phi``
are only C^0 and the interface conditions (:meth:`EulerianRod.interface`)
are the continuity of ``d3``, of ``u_perp`` (on ``K1, K2``) and of ``m / GJ``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from types import SimpleNamespace

import numpy as np

from .bspline import gauss_legendre
from .collocation import BVProblem, Collocation
from .curves import ReferenceCurve, Straight, StraightReference, _cross, _dot, frame_jets, minimal_rotation  # noqa: F401
from .loads import Kinematics, Tangents

PARAMS = ("phi_L", "T", "w", "EI", "GJ", "EA")
FIELDS = ("Delta1", "Delta2", "phi", "F.K1", "F.K2", "F.K3")
ORDERS = (3, 3, 2, 1, 1, 1)
# a join (a station where the reference's curvature jumps) leaves every field only C^0: the coefficients
# it adds, one per interface condition (Delta1, Delta2: 2 each; phi: 1)
UNKNOWNS_PER_JOIN = sum(m - 1 for m in ORDERS)


#: points per call of the curved Jacobian's kernel: its temporaries peak at about 4.3 kB a point (smaller blocks
#: cost more calls: 1024 took 35 ms at 10 000 points where 4096 took 31 and one call 28)
JACOBIAN_BLOCK = 4096


_JET_START = {f: int(sum(m + 1 for m in ORDERS[:i])) for i, f in enumerate(FIELDS)}


class Jet:
    """Named rows of the local jet ``z`` (each field and its S-derivatives up to its order).

    ``Jet.D1[j]``, ``Jet.D2[j]``: ``Delta1^(j)``, ``Delta2^(j)`` (j = 0..3);
    ``Jet.PHI[j]``: ``phi^(j)`` (j = 0..2); ``Jet.F``, ``Jet.FP``: the force
    components on ``K1, K2, K3`` and their first derivatives.
    """

    D1 = tuple(range(_JET_START["Delta1"], _JET_START["Delta1"] + 4))
    D2 = tuple(range(_JET_START["Delta2"], _JET_START["Delta2"] + 4))
    PHI = tuple(range(_JET_START["phi"], _JET_START["phi"] + 3))
    F = [_JET_START["F.K1"], _JET_START["F.K2"], _JET_START["F.K3"]]
    FP = [_JET_START["F.K1"] + 1, _JET_START["F.K2"] + 1, _JET_START["F.K3"] + 1]
    SIZE = int(sum(m + 1 for m in ORDERS))


# --------------------------------------------------------------------------
# Vector helpers on (3, npts) arrays (np.cross is slow on small arrays)
# --------------------------------------------------------------------------
# _dot and _cross: the vectorised helpers of rodcont.curves (imported above)


def _director_jets(r1, r2, r3):
    """``|r'|^2, |r'|, |r'|^3, r'.r''`` and ``d3 = r'/|r'|`` with its first two S-derivatives."""
    n2 = _dot(r1, r1)
    n = np.sqrt(n2)
    d3 = r1 / n
    c = _dot(r1, r2)
    d3r2 = _dot(d3, r2)
    e = r2 - d3 * d3r2
    d3p = e / n
    n3 = n2 * n
    d3pp = (r3 - d3p * d3r2 - d3 * (_dot(d3p, r2) + _dot(d3, r3))) / n - e * (c / n3)
    return n2, n, n3, c, d3, d3p, d3pp


def _cross2(a, b):
    """First two components of ``a x b``."""
    out = np.empty((2,) + np.broadcast_shapes(a.shape[1:], b.shape[1:]), dtype=np.result_type(a, b))
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    return out


def _cross_axial(r1, v):
    """``r' x v`` for a straight reference in frame components, ``r' = (a, b, 1)`` and ``v = (v0, v1, 0)``
    (as ``r''`` and ``r'''`` are): three operations where the general product takes nine, and the same
    values (the dropped terms are products with 0 and 1)."""
    out = np.empty(np.broadcast_shapes(r1.shape, v.shape), dtype=np.result_type(r1, v))
    np.negative(v[1], out=out[0])
    out[1] = v[0]
    np.multiply(r1[0], v[1], out=out[2])
    out[2] -= r1[1] * v[0]
    return out


def _deflection(z):
    """``(Delta1, Delta2)``: their rows of the jets."""
    return z[Jet.D1[0]], z[Jet.D2[0]]


def _equations(EF, EM, torque):
    """The six equations ``(6, npts)``: force balance (3), moment on ``K1, K2`` (2), torque (1).
    (Filled in place: ``np.stack`` of six rows costs more than the rows on a short rod.)"""
    G = np.empty((6,) + EF.shape[1:], dtype=np.result_type(EF, EM, torque))
    G[:3] = EF
    G[3:5] = EM
    G[5] = torque
    return G


# Tangent helpers for :meth:`EulerianRod.jacobian`: ``dA`` is ``(seeds, 3, npts)`` (or broadcasts to it),
# ``B`` a ``(3, npts)`` vector; the result carries the seed axis first.
def _tdot(dA, B):
    # one einsum instead of five operations (the same sum, in the same order)
    return np.einsum("sin,in->sn", dA, B)


def _tcross(dA, B):
    """``dA x B`` along the seeds: ``dA`` ``(seeds, 3, npts)``, ``B`` ``(3, npts)``."""
    return _cross(dA.transpose(1, 0, 2), B[:, None]).transpose(1, 0, 2)


def _frame_jet_tangents(k):
    """Tangents of ``r', r'', r'''`` (:func:`rodcont.curves.frame_jets`: affine in the jets) along
    the seeds ``Delta1^(j)``, then ``Delta2^(j)`` (``j = 0..3``), each ``(8, 3, npts)``, written out: ``A_m`` (the
    derivative of the components of ``r'``, ``m`` times) is ``[Delta]^(m+1) + sum_i C(m, i) omega^(i) x Delta^(m-i)``,
    with ``omega^(i) x e1 = (0, k3^(i), -k1^(i))`` and ``omega^(i) x e2 = (-k3^(i), 0, -k2^(i))``."""
    k1, k2, k3 = k[0], k[1], k[2]
    A = np.zeros((3, 8, 3, k.shape[-1]))
    for s, unit, wx in ((0, 0, lambda i: ((1, k3[i]), (2, -k1[i]))), (4, 1, lambda i: ((0, -k3[i]), (2, -k2[i])))):
        for m in range(3):
            A[m, s + m + 1, unit] = 1.0
            for i in range(m + 1):
                coef = 2.0 if (m, i) == (2, 1) else 1.0
                for comp, v in wx(i):
                    A[m, s + m - i, comp] += coef * v
    omega, omega1 = np.stack([-k2[0], k1[0], k3[0]]), np.stack([-k2[1], k1[1], k3[1]])
    wA0 = -_tcross(A[0], omega)
    return A[0], A[1] + wA0, A[2] - _tcross(A[0], omega1) - _tcross(2.0 * A[1] + wA0, omega)


def _seeded_dot(*pairs):
    """``sum_j dr^(j) . X_j`` along the six seeds for pairs ``(j, X_j)`` (``dr^(j)`` is a unit vector on
    two seeds of its own: no products needed)."""
    out = np.zeros((6,) + pairs[0][1].shape[1:])
    for j, X in pairs:
        out[j - 1] = X[0]
        out[j + 2] = X[1]
    return out


def _seeded_cross(*pairs):
    """``sum_j dr^(j) x X_j`` along the six seeds (``e1 x X = (0, -X2, X1)``, ``e2 x X = (X2, 0, -X0)``)."""
    X0 = pairs[0][1]
    out = np.zeros((6,) + X0.shape)
    for j, X in pairs:
        out[j - 1, 1] = -X[2]
        out[j - 1, 2] = X[1]
        out[j + 2, 0] = X[2]
        out[j + 2, 2] = -X[0]
    return out


def _evenly(cols):
    """Evenly spaced increasing indices as a slice."""
    cols = [int(c) for c in cols]
    step = cols[1] - cols[0]
    if step <= 0 or any(b - a != step for a, b in zip(cols, cols[1:])):
        raise ValueError(f"columns {cols} are not evenly spaced")
    return slice(cols[0], cols[-1] + 1, step)


# The geometric seeds of the straight-reference Jacobian (increasing jet order): the first three
# derivatives of Delta1, then of Delta2; _SEED_R[j - 1] is the tangent of the j-th derivative of r
# (frame components) along each seed, (6, 3, 1): seed j - 1 moves its first component, seed j + 2 its second.
_SEED_JETS = (Jet.D1[1], Jet.D1[2], Jet.D1[3], Jet.D2[1], Jet.D2[2], Jet.D2[3])
_SEED_R = np.zeros((3, 6, 3, 1))
for _s, (_order, _comp) in enumerate(((1, 0), (2, 0), (3, 0), (1, 1), (2, 1), (3, 1))):
    _SEED_R[_order - 1, _s, _comp, 0] = 1.0
del _s, _order, _comp


# --------------------------------------------------------------------------
# Rod parameters
# --------------------------------------------------------------------------
@dataclass
class RodParameters:
    """Stiffnesses, weight and span of a rod (paper values by default).

    ``EI`` bending, ``GJ`` torsional, ``EA`` axial stiffness; ``w`` weight per
    unit unstressed length (may be 0), acting along ``weight_direction``
    (default ``-e3``: normal to the straight reference along ``e1``);
    ``L`` the span (length of the reference curve).
    """

    EI: float = 1.0
    GJ: float = 0.75
    EA: float = 255.0
    w: float = 10.0
    L: float = 1.0
    weight_direction: tuple = (0.0, 0.0, -1.0)

    def __post_init__(self):
        for name in ("EI", "GJ", "EA", "L", "w"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise TypeError(f"{name} must be a number, got {v!r}")
            if not math.isfinite(v) or v < 0 or (v == 0 and name != "w"):
                raise ValueError(f"{name} must be a {'non-negative' if name == 'w' else 'positive'} number, got {v!r}")
            # products of a few of them must stay finite: keep each within 1e-100 .. 1e100
            if v != 0 and not 1e-100 <= v <= 1e100:
                raise ValueError(f"{name} = {v!r} is outside the range rodcont computes with (1e-100 .. 1e100): "
                                 f"change units")
            setattr(self, name, float(v))
        g = _vector3("weight_direction", self.weight_direction)
        if g.shape != (3,) or not np.isfinite(g).all() or not np.any(g != 0):
            raise ValueError("weight_direction must be a non-zero 3-vector of finite numbers")
        g = g / np.max(np.abs(g))  # scaled first: a huge vector has a finite norm
        self.weight_direction = tuple(g / np.linalg.norm(g))

    def tension(self, gamma: float) -> float:
        """``T = Gamma w L``."""
        return float(gamma) * self.w * self.L

    def gamma(self, T: float) -> float:
        return float(T) / (self.w * self.L) if self.w > 0 else float("nan")

    def as_dict(self) -> dict:
        return asdict(self)


class Sections:
    """A rod made of sections (a drill string: collars, heavy-weight pipe, drill pipe): piecewise-constant
    weight and stiffnesses, each the parameter's value times a section's factor.

    ``boundaries``: the ``n - 1`` interior points ``S`` (increasing) where one section ends and the next begins;
    ``factors``: ``(n, 4)`` factors of ``w, EI, GJ, EA``, one row per section from ``S = 0`` on. The local
    values are ``w(S) = w f_w(S)``, ``EI(S) = EI f_EI(S)``, ... (``w, EI, GJ, EA`` the parameters: a trace in
    ``EI`` scales every section). Each boundary is a join of the rod (as a well's stations are): the fields are
    C^0 there, and the interface conditions are the continuity of ``d3``, of the moment ``EI u`` and of the
    torque ``m`` (the physical rod has no point load there).
    """

    def __init__(self, boundaries, factors):
        b = np.asarray(boundaries, float).reshape(-1)
        f = np.asarray(factors, float)
        if f.ndim != 2 or f.shape != (b.size + 1, 4):
            raise ValueError(f"sections: factors must be (len(boundaries) + 1, 4) (w, EI, GJ, EA), got {f.shape}")
        if not (np.all(np.isfinite(b)) and np.all(np.diff(b) > 0)):
            raise ValueError("sections: the boundaries must be finite and strictly increasing")
        if not (np.all(np.isfinite(f)) and np.all(f[:, 1:] > 0) and np.all(f[:, 0] >= 0)):
            raise ValueError("sections: the stiffness factors must be positive, the weight's non-negative")
        self.boundaries, self.table = b, f

    def factors(self, S, side: int = 0) -> np.ndarray:
        """``(4, npts)`` factors of ``w, EI, GJ, EA`` at ``S`` (``side`` -1 / +1: just left / right of ``S``)."""
        S = np.real(np.asarray(S))
        i = np.searchsorted(self.boundaries, S, side="left" if side < 0 else "right")
        return self.table[i].T

    def __eq__(self, other):
        return isinstance(other, Sections) and np.array_equal(self.boundaries, other.boundaries) \
            and np.array_equal(self.table, other.table)

    __hash__ = None

    def __repr__(self):
        return f"Sections({self.boundaries.tolist()!r}, {self.table.tolist()!r})"


# --------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------
class EulerianRod:
    """The rod as a :class:`BVProblem`: by default the canonical problem, clamped at both ends,
    ``phi(0) = 0``, ``phi(L) = phi_L``, axial force ``F . K3 = T`` at ``S = L``, under its weight.

    Parameters vector ``p = (phi_L, T, w, EI, GJ, EA)`` (:data:`PARAMS`), followed by
    the parameters the end conditions add (``torque``, ``l0``): :attr:`param_names`.

    ``curve`` (default: the straight span ``0 .. L e1``) is any
    :class:`rodcont.curves.ReferenceCurve` whose ``span`` is ``rod.L``. The
    domain is ``S in [0, curve.length]``; ``stretch = (l - L)/L`` and
    ``Gamma = T/(w L)`` stay measured on the span ``L``. A curve with a
    constant frame (:class:`rodcont.curves.Straight`) runs the frame-component
    residual of the straight rod unchanged; any other curve runs the
    moving-frame residual (:meth:`_residual_curved`). With a curve whose frame
    turns by ``beta = curve.end_twist`` between the ends, the end condition is
    ``phi(end) = phi_L - beta``, so that ``phi_L`` stays the physical turn of
    the end clamp relative to the start clamp (see
    :attr:`rodcont.curves.ReferenceCurve.end_twist`).

    ``loads``: the distributed loads (:mod:`rodcont.loads`; default ``[Weight()]``,
    and ``WallContact(wall)`` with a ``wall``), each added once to both residuals.
    ``ends``: the end conditions (:class:`rodcont.ends.RodEnds`; default the
    canonical ones); a :class:`rodcont.ends.Torque` frees ``phi_L``, an
    :class:`rodcont.ends.UnstressedLength` frees ``T`` (unknowns of the
    discretisation, ``disc.full_params(x, p)`` reads them).
    """

    def __init__(self, rod: RodParameters | None = None, curve: ReferenceCurve | None = None, wall=None,
                 loads=None, ends=None, sections: Sections | None = None):
        from .ends import RodEnds
        self.rod = rod or RodParameters()
        if not isinstance(self.rod, RodParameters):
            raise TypeError(f"rod must be a RodParameters, got {self.rod!r}")
        if sections is not None and not isinstance(sections, Sections):
            raise TypeError(f"sections must be a rodcont.rod.Sections, got {sections!r}")
        self.sections = sections
        self.curve = curve or StraightReference(self.rod.L)
        if not isinstance(self.curve, ReferenceCurve):
            raise TypeError(f"curve must be a rodcont.curves.ReferenceCurve, got {self.curve!r}")
        self._set_loads(loads, wall)
        self.ends = RodEnds() if ends is None else ends
        if not isinstance(self.ends, RodEnds):
            raise TypeError(f"ends must be a rodcont.ends.RodEnds, got {self.ends!r}")
        self._check_phase()
        extra = self.ends.params
        self.param_names = PARAMS + tuple(name for name, _ in extra)
        self._extra_values = dict(extra)
        self.constant_frame = bool(self.curve.constant_frame)
        self.g = np.asarray(self.rod.weight_direction, float)
        unused = self._set_frame()
        if sections is not None:  # a section boundary is a join: the stiffness jumps there
            a, b = self.interval
            inner = [S for S in sections.boundaries if a < S < b]
            self.joins = np.unique(np.concatenate([self.joins, inner])) if inner else self.joins
            self._join_curve_cache = getattr(self, "_join_curve_cache", {})
        if any(load.reads_deflection for load in self.loads):  # the contact force reads the deflection itself
            unused = (Jet.PHI[0],)
        # mesh breakpoints: a well's stations (its curvature jumps) and a clearance table's (its slope jumps)
        stations = [self.interval[0], self.interval[1]]
        if not self.constant_frame:
            stations += list(self.curve.breakpoints)
        for load in self.loads:
            stations += list(load.stations(*self.interval))
        stations += list(self.joins)
        self.stations = np.unique(np.asarray(stations, float))
        self._set_problem([j for j in range(Jet.SIZE) if j not in unused])

    def _check_phase(self) -> None:
        """A phase condition (:class:`rodcont.ends.Phase`) is for the weightless rod on the straight reference, its
        freed weight across the axis."""
        from .ends import Phase
        if self.ends.find(Phase) is None:
            return
        g = np.asarray(self.rod.weight_direction, float)
        if not getattr(self.curve, "constant_frame", False) or self.rod.w != 0 or \
                np.linalg.norm(g - (g @ self.curve.K3) * self.curve.K3) < 1e-6:
            raise ValueError("a phase condition is for a weightless rod (w = 0) on the straight reference, with a "
                             "weight direction across its axis (the freed weight's): there its buckled states "
                             "come in circles")

    def _set_loads(self, loads, wall) -> None:
        """``self.loads`` (default ``[Weight()]``, a ``WallContact`` added for ``wall``), each bound to the rod."""
        from .loads import DistributedLoad, WallContact, Weight
        if wall is not None:
            from .contact import Wall
            if not isinstance(wall, Wall):
                raise TypeError(f"wall must be a rodcont.contact.Wall, got {wall!r}")
        if isinstance(loads, DistributedLoad) or not (loads is None or hasattr(loads, "__iter__")):
            raise TypeError(f"loads must be a list of rodcont.loads.DistributedLoad, got {loads!r}")
        loads = [Weight()] if loads is None else list(loads)
        for load in loads:
            if not isinstance(load, DistributedLoad):
                raise TypeError(f"a load must be a rodcont.loads.DistributedLoad, got {load!r}")
        walls = [load for load in loads if isinstance(load, WallContact)]
        if wall is not None and not walls:
            walls = [WallContact(wall)]
            loads.append(walls[0])
        if len(walls) > 1 or (wall is not None and walls[0].wall is not wall):
            raise ValueError("one conduit wall per rod (give it as wall= or as a WallContact load, not both)")
        self.loads = loads
        self._wall_load = walls[0] if walls else None
        if self.wall is not None:
            kmax = self.curve.max_curvature() if not self.curve.constant_frame else 0.0
            c_span = self.wall.max_on(0.0, float(self.curve.length))
            if c_span * kmax >= 1.0:
                raise ValueError(f"the conduit overlaps itself: clearance {c_span:g} times the largest "
                                 f"curvature of its axis ({kmax:g}) must be below 1")
        for load in loads:  # fixed here, not read from the parameters: a trace in w or EI keeps one contact law
            load.bind(self)

    def _set_frame(self) -> tuple:
        """The reference frame's data and the interval; returns the jet components the residual does not read."""
        if self.constant_frame:
            if abs(self.curve.length - self.rod.L) > 1e-14 * self.rod.L:
                raise ValueError("the reference curve length must equal L")
            self.pole = self.curve.K3
            self.K1, self.K2 = self.curve.K1, self.curve.K2
            self.frame = np.stack([self.K1, self.K2, self.pole])  # rows: K1, K2, K3 (global components)
            self.gK = self.frame @ self.g  # weight direction in frame components
            self.twist_offset = 0.0
            self.joins = np.zeros(0)  # a constant frame: no curvature to jump
            self.interval = (0.0, self.rod.L)
            # The residual reads the jets through r' and its derivatives: with a constant frame the
            # values Delta1, Delta2 and phi do not enter; of the parameters only w, EI, GJ, EA do.
            return (Jet.D1[0], Jet.D2[0], Jet.PHI[0])
        if abs(self.curve.span - self.rod.L) > 1e-12 * self.rod.L:
            raise ValueError(f"the span of the reference curve ({self.curve.span:.15g}) must equal the rod's "
                             f"L ({self.rod.L:.15g}): stretch and Gamma are measured on the span "
                             f"(use RodParameters(L=curve.span))")
        self._curve_cache: dict = {}  # grid bytes -> data, least recently used first
        self._curve_cache_size = 0  # bytes of data and keys held
        self.twist_offset = float(self.curve.end_twist)
        # where the reference's curvature jumps the exact Delta', Delta'', phi' jump: joins (see interface)
        self.joins = np.asarray(self.curve.curvature_jumps, float)
        self._join_curve_cache: dict = {}
        self.interval = (0.0, float(self.curve.length))
        # with a turning frame Delta1, Delta2 enter through omega x Delta; phi still does not
        return (Jet.PHI[0],)

    def _set_problem(self, dependence: list) -> None:
        """The :class:`BVProblem` (``dependence``: the jet components the residual reads) and what the
        boundary conditions and the hand-derived Jacobian precompute."""
        from .loads import Weight
        used = {"EI", "GJ", "EA"}.union(*(load.params for load in self.loads))
        # the hand-derived derivatives cover the straight rod under its weight alone and the moving frame under
        # loads with exact tangents; every other case takes the complex step of its residual
        self.weight_only = self.constant_frame and [type(load) for load in self.loads] == [Weight] \
            and self.sections is None
        # a moving frame whose loads all have exact tangents: the hand-derived curved Jacobian
        curved = not self.constant_frame and all(load.tangents for load in self.loads)
        jacobian = self.jacobian if self.weight_only else self._jacobian_curved if curved else None
        integrals = {}
        if self.ends.has_integrals:
            extra = [Jet.D1[0], Jet.D2[0]] if any(getattr(c, "integral_jets", "") == "deflection"
                                                 for _, c in self.ends.conditions) else []
            integrals = dict(integrals=self.integrals, integral_dependence=sorted(set(dependence) | set(extra)))
        self.problem = BVProblem(orders=ORDERS, residual=self.residual, bc=self.bc,
                                 interval=self.interval, params=self.param_names, names=FIELDS,
                                 free=[self.param_names.index(q) for q in self.ends.frees],
                                 jet_dependence=dependence,
                                 residual_params=[i for i, q in enumerate(self.param_names) if q in used],
                                 jacobian=jacobian,
                                 affine_bc=self.ends.affine,
                                 joins=self.joins, join_continuity=(0,) * len(FIELDS) if self.joins.size else None,
                                 interface=self.interface if self.joins.size else None, **integrals)
        self._bc_conditions = self.ends.conditions
        self._bc_affine = None
        if self.ends.affine:  # the rows as data: jet index (start, then end jet), parameter, offset
            terms = [(j + end * Jet.SIZE, q, off) for end, c in self._bc_conditions for j, q, off in c.terms(self, end)]
            self._bc_affine = (np.array([t[0] for t in terms]), np.array([t[1] or 0 for t in terms]),
                               np.array([float(t[1] is not None) for t in terms]),
                               np.array([t[2] for t in terms], float))
        self._active = np.unique(np.asarray(self.problem.jet_dependence, int))
        self._jet_pos = np.full(Jet.SIZE, -1)
        self._jet_pos[self._active] = np.arange(self._active.size)
        if self.problem.jacobian is not None:
            # columns of dG that jacobian fills by blocks, as slices (writes through views, no fancy indexing)
            pos = self._jet_pos
            seeds = _SEED_JETS if self.weight_only else Jet.D1 + Jet.D2
            self._dG_cols = (_evenly(pos[list(seeds)]), _evenly(pos[Jet.F]), _evenly(pos[Jet.FP]))

    # ---- sections: piecewise-constant stiffness and weight ----------------------------
    def _stiffness(self, S, p):
        """``w, EI, GJ, EA`` at the points ``S``: the parameters, times the sections' factors (:class:`Sections`)."""
        phi_L, T, w, EI, GJ, EA = p[:6]
        if self.sections is None:
            return w, EI, GJ, EA
        f = self.sections.factors(S)
        return w * f[0], EI * f[1], GJ * f[2], EA * f[3]

    def _local_weight(self, w) -> dict:
        """The weight per length the loads read (:class:`rodcont.loads.Kinematics` ``w``), where it varies."""
        return {} if self.sections is None else {"w": w}

    # ---- the wall, one of the loads ------------------------------------------------
    @property
    def wall(self):
        """The conduit wall (:class:`rodcont.contact.Wall`) of the rod's :class:`rodcont.loads.WallContact`, or None."""
        return self._wall_load.wall if self._wall_load is not None else None

    @wall.setter
    def wall(self, wall):  # a homotopy in the law's smoothing swaps the wall (settle_in_conduit)
        if self._wall_load is None:
            raise ValueError("this rod has no conduit wall to replace")
        self._wall_load.wall = wall

    @property
    def contact_scale(self) -> float:
        """``P``, the force scale of the contact law, fixed when the model was built."""
        if self._wall_load is None:
            raise AttributeError("this rod has no conduit wall")
        return self._wall_load.scale

    @contact_scale.setter
    def contact_scale(self, P: float):  # a homotopy to a stiffer law (solve's penetration guard)
        self._wall_load.scale = float(P)

    def params(self, phi_L: float = 0.0, T: float = 0.0, **changes) -> np.ndarray:
        """The parameter vector (:attr:`param_names`): ``phi_L``, ``T``, the rod's ``w, EI, GJ, EA``, the end
        conditions' own (``torque``, ``l0``); ``changes`` replace any of them by name."""
        r = self.rod
        d = dict(phi_L=phi_L, T=T, w=r.w, EI=r.EI, GJ=r.GJ, EA=r.EA, **self._extra_values)
        unknown = set(changes) - set(d)
        if unknown:
            raise TypeError(f"unknown parameter(s) {', '.join(sorted(unknown))}; this rod's: "
                           f"{', '.join(self.param_names)}")
        d.update(changes)
        return np.array([d[n] for n in self.param_names], float)

    # ---- kinematics shared by residual and outputs ----------------------------
    # With a constant frame every vector is written in frame components
    # (v.K1, v.K2, v.K3): r' = (Delta1', Delta2', 1), the pole p = K3 = (0, 0, 1),
    # and projections on K1, K2 are plain components (fewer operations per point).
    def _frame_jets(self, z):
        """First three S-derivatives of ``r`` in frame components, each ``(3, npts)``."""
        D1, D2 = Jet.D1, Jet.D2
        r = np.zeros((3, 3) + z.shape[1:], dtype=z.dtype)  # r[j - 1] = r^(j)
        r[:, 0] = z[D1[1]:D1[3] + 1]
        r[:, 1] = z[D2[1]:D2[3] + 1]
        r[0, 2] = 1.0
        return r[0], r[1], r[2]

    def _straight_jets(self, z):
        """``r', r'', r'''`` (frame components), ``F``, ``[F]'``, ``phi'``, ``phi''`` of the local jets."""
        r1, r2, r3 = self._frame_jets(z)
        return r1, r2, r3, z[Jet.F], z[Jet.FP], z[Jet.PHI[1]], z[Jet.PHI[2]]

    def residual(self, S, z, p):
        """Pointwise residual ``(6, npts)`` of the Eulerian equations (frame components)."""
        if not self.constant_frame:
            return self._residual_curved(S, z, p)
        w, EI, GJ, EA = self._stiffness(S, p)
        r1, r2, r3, F, Fp, phi1, phi2 = self._straight_jets(z)
        n2, n, n3, c, d3, d3p, d3pp = _director_jets(r1, r2, r3)
        alpha = 1.0 + _dot(F, d3) / EA
        alphap = (_dot(Fp, d3) + _dot(F, d3p)) / EA
        bend = _cross_axial(r1, r2)
        uperp_p = ((alphap * bend + alpha * _cross_axial(r1, r3)) - (3.0 * alpha * c / n2) * bend) / n3
        J1 = alpha / n
        J1p = alphap / n - alpha * c / n3
        # pole p = K3: p.v = v[2], p.(a x b) = a0 b1 - a1 b0
        pd = 1.0 + d3[2]
        pxd = d3[0] * d3p[1] - d3[1] * d3p[0]
        tau = -pxd / pd
        taup = -(d3[0] * d3pp[1] - d3[1] * d3pp[0]) / pd + pxd * d3p[2] / pd**2
        twist = phi1 + tau
        m = GJ * J1 * twist
        mp = GJ * (J1p * twist + J1 * (phi2 + taup))
        EM = EI * uperp_p[:2] + m * d3p[:2] + mp * d3[:2] + _cross2(r1, F)
        k = Kinematics(S, z, p, n, alpha, d3, self.gK[:, None], _deflection(z), **self._local_weight(w))
        EF, EM, torque = self._add_loads(k, Fp, EM, mp)
        return _equations(EF, EM, torque / GJ)

    def _add_loads(self, k, EF, EM, torque):
        """The distributed loads (:mod:`rodcont.loads`) added to the force balance ``EF``, the moment
        balance ``EM`` (on ``K1, K2``) and the torque ``m'``: ``EF + sum f``, ``EM + sum l``, ``m' + sum l.d3``."""
        owned = False  # EF may still be the caller's array: copied before the first write in place
        for load in self.loads:
            f = load.force(k)
            if isinstance(f, tuple):  # three rows, added in place (a stacked copy cost 8 % of a wall's step)
                if not owned:
                    EF, owned = EF.astype(np.result_type(EF, *f)), True
                for i in range(3):
                    EF[i] += f[i]
            elif f is not None:
                EF, owned = EF + f, True
            moment = load.moment(k)
            if moment is not None:
                EM = EM + moment[:2]
                torque = torque + _dot(moment, k.d3)
        return EF, EM, torque

    def jacobian(self, S, z, p):
        """The residual and its exact derivatives w.r.t. the jet (constant frame only), by hand.

        Returns ``(G, dG)``: ``G`` as :meth:`residual`, ``dG`` ``(6, na, npts)`` the derivatives
        w.r.t. the jet components of ``problem.jet_dependence`` (sorted). Forward-mode chain rule:
        the geometric quantities (``n, d3, d3', d3''``, ...) carry tangents along the six seeds
        ``Delta1', Delta1'', Delta1''', Delta2', Delta2'', Delta2'''`` (axis 0); the force and twist
        enter linearly (or bilinearly) and are differentiated in closed form. Checked against the
        complex step of :meth:`residual` in ``tests/test_rod.py``.
        """
        phi_L, T, w, EI, GJ, EA = p[:6]
        r1, r2, r3, F, Fp, phi1, phi2 = self._straight_jets(z)
        n2, n, n3, c, d3, d3p, d3pp = _director_jets(r1, r2, r3)
        dr1, dr2, dr3 = _SEED_R
        # tangents along the geometric seeds: (6, npts) scalars, (6, 3, npts) vectors
        dn = _seeded_dot((1, d3))
        dn2 = 2.0 * n * dn
        dd3 = (dr1 - d3 * dn[:, None]) / n
        dc = _seeded_dot((1, r2), (2, r1))
        d3r2 = c / n
        dd3r2 = _tdot(dd3, r2) + _seeded_dot((2, d3))
        e = r2 - d3 * d3r2
        de = dr2 - dd3 * d3r2 - d3 * dd3r2[:, None]
        dd3p = (de - d3p * dn[:, None]) / n
        dn3 = 3.0 * n2 * dn
        t1 = _dot(d3p, r2) + _dot(d3, r3)
        dt1 = _tdot(dd3p, r2) + _tdot(dd3, r3) + _seeded_dot((2, d3p), (3, d3))
        q = r3 - d3p * d3r2 - d3 * t1
        dq = dr3 - dd3p * d3r2 - d3p * dd3r2[:, None] - dd3 * t1 - d3 * dt1[:, None]
        ec = e * (c / n3)
        dd3pp = (dq - (q / n) * dn[:, None]) / n - (de * c + e * dc[:, None] - ec * dn3[:, None]) / n3
        bend = _cross_axial(r1, r2)
        dbend = _seeded_cross((1, r2), (2, -r1))
        r13 = _cross_axial(r1, r3)
        dr13 = _seeded_cross((1, r3), (3, -r1))
        # force-dependent scalars and their derivatives (geometric tangents; d/dF_i, d/dFp_i)
        alpha = 1.0 + _dot(F, d3) / EA
        dalpha = _tdot(dd3, F) / EA
        alphap = (_dot(Fp, d3) + _dot(F, d3p)) / EA
        dalphap = (_tdot(dd3, Fp) + _tdot(dd3p, F)) / EA
        K = c / n2
        dK = dc / n2 - (c / n2**2) * dn2
        W = r13 - 3.0 * K * bend
        dW = dr13 - 3.0 * (dK[:, None] * bend + K * dbend)
        uperp_p = (alphap * bend + alpha * W) / n3
        duperp = (dalphap[:, None] * bend + alphap * dbend + dalpha[:, None] * W + alpha * dW
                  - uperp_p * dn3[:, None]) / n3
        J1 = alpha / n
        dJ1 = dalpha / n - (alpha / n2) * dn
        J1p = alphap / n - alpha * c / n3
        dJ1p = (dalphap / n - (alphap / n2) * dn - (dalpha * c + alpha * dc) / n3
                + (alpha * c / n3**2) * dn3)
        pd = 1.0 + d3[2]
        dpd = dd3[:, 2]
        pxd = d3[0] * d3p[1] - d3[1] * d3p[0]
        dpxd = dd3[:, 0] * d3p[1] + d3[0] * dd3p[:, 1] - dd3[:, 1] * d3p[0] - d3[1] * dd3p[:, 0]
        tau = -pxd / pd
        dtau = -dpxd / pd + (pxd / pd**2) * dpd
        X = d3[0] * d3pp[1] - d3[1] * d3pp[0]
        dX = dd3[:, 0] * d3pp[1] + d3[0] * dd3pp[:, 1] - dd3[:, 1] * d3pp[0] - d3[1] * dd3pp[:, 0]
        taup = -X / pd + pxd * d3p[2] / pd**2
        dtaup = (-dX / pd + (X / pd**2) * dpd + (dpxd * d3p[2] + pxd * dd3p[:, 2]) / pd**2
                 - (2.0 * pxd * d3p[2] / pd**3) * dpd)
        twist = phi1 + tau
        ptw = phi2 + taup
        m = GJ * J1 * twist
        dm = GJ * (dJ1 * twist + J1 * dtau)
        mp = GJ * (J1p * twist + J1 * ptw)
        dmp = GJ * (dJ1p * twist + J1p * dtau + dJ1 * ptw + J1 * dtaup)
        gK = self.gK[:, None]
        EF = Fp + (w * n / alpha) * gK
        EM = EI * uperp_p[:2] + m * d3p[:2] + mp * d3[:2] + _cross2(r1, F)
        G = _equations(EF, EM, mp / GJ)

        npts = n.shape[-1]
        pos = self._jet_pos  # jet component -> column of dG
        seeds, jF, jFp = self._dG_cols
        out = np.zeros((6, self._active.size, npts))
        geo = out[:, seeds]  # (equation, seed, point): a view
        geo[:3] = (w / alpha)[None, None] * (dn - (n / alpha) * dalpha)[None] * gK[:, None]
        geo[3:5] = (EI * duperp[:, :2] + dm[:, None] * d3p[:2] + m * dd3p[:, :2] + dmp[:, None] * d3[:2]
                    + mp * dd3[:, :2]).transpose(1, 0, 2)
        # and r' x F along its seeds Delta1' (e1 x F) and Delta2' (e2 x F), first two components
        geo[4, 0] -= F[2]
        geo[3, 3] += F[2]
        geo[5] = dmp / GJ
        # twist rate and its derivative: m = GJ J1 (phi' + tau), mp = GJ (J1p (phi' + tau) + J1 (phi'' + tau'))
        out[3:5, pos[Jet.PHI[1]]] = GJ * (J1 * d3p[:2] + J1p * d3[:2])
        out[5, pos[Jet.PHI[1]]] = J1p
        out[3:5, pos[Jet.PHI[2]]] = GJ * J1 * d3[:2]
        out[5, pos[Jet.PHI[2]]] = J1
        # force components (index i first): alpha_F = d3 / EA, alphap_F = d3' / EA, alphap_Fp = d3 / EA
        aF, apF = d3 / EA, d3p / EA
        J1F = aF / n
        J1pF = apF / n - aF * (c / n3)
        mF = GJ * J1F * twist
        mpF = GJ * (J1pF * twist + J1F * ptw)
        mpFp = GJ * J1F * twist
        out[:3, jF] = gK[:, None] * (-(w * n / alpha**2) * aF)[None]  # d(w n / alpha)/dF_i
        out[[0, 1, 2], pos[Jet.FP]] = 1.0
        out[3:5, jF] = (EI * (apF[:, None] * bend[:2] + aF[:, None] * W[:2]) / n3
                        + mF[:, None] * d3p[:2] + mpF[:, None] * d3[:2]).transpose(1, 0, 2)
        out[5, jF] = mpF / GJ
        out[3:5, jFp] = (EI * aF[:, None] * bend[:2] / n3 + mpFp[:, None] * d3[:2]).transpose(1, 0, 2)
        out[5, jFp] = mpFp / GJ
        # r' x F: first two components (r'[1] F2 - r'[2] F1, r'[2] F0 - r'[0] F2)
        jF = pos[Jet.F]
        out[3, jF[1]] -= r1[2]
        out[3, jF[2]] += r1[1]
        out[4, jF[0]] += r1[2]
        out[4, jF[2]] -= r1[0]
        return G, out

    def bc(self, za, zb, p):
        """The end conditions (:class:`rodcont.ends.RodEnds`), rows grouped by kind: by default clamps
        (``Delta = Delta' = 0`` at both ends), twist ``phi(0) = 0, phi(end) = phi_L`` (``phi_L - beta`` when the
        frame turns by ``beta`` between the ends), tension ``F . K3(end) = T``: affine in the jets and the
        parameters (declared to the collocation, which then differentiates them once)."""
        if self._bc_affine is not None:  # every row z[j] - (p[q] + offset): one gather for all
            jet, param, has_param, offset = self._bc_affine
            zz = np.concatenate([za, zb])
            shift = np.asarray(p)[param] * has_param + offset
            return zz[jet] - shift.reshape(shift.shape + (1,) * (zz.ndim - 1))
        z = (za, zb)
        rows = []
        for end, condition in self._bc_conditions:
            rows += condition.rows(self, z[end], p, end)
        # np.array, not np.stack: the same array (the rows have one shape) for a tenth of the cost on scalars
        return np.array(rows)

    def integrals(self, S, z, p):
        """The integrands of the end conditions' integral conditions (``int q dS = 0``), ``(n_int, npts)``."""
        return np.array([q for _, c in self._bc_conditions if (q := c.integrand(self, S, z, p)) is not None])

    def end_torque(self, z, p, end: int):
        """``m = GJ J1 (phi' + tau_q)`` from an end's jet ``z`` (``(jet_size,)`` or with a trailing batch axis)."""
        zz = z.reshape(z.shape[0], -1)
        S = np.full(zz.shape[1], self.interval[end])
        return self._axial_quantities(S, zz, p)[0].reshape(z.shape[1:])

    # ---- the moving frame ------------------------------------------------------
    #: Bound on the bytes of curve data kept by :meth:`_curve_data` (least recently used out first).
    #: One Newton iteration on ``N`` subintervals reads about ``(k + 1) N`` distinct points (the
    #: collocation points, once whole and once in blocks of ``POINT_BLOCK``), a continuation step
    #: ``(3 k + 9) N`` more (outputs, check points): 96 bytes a point, so 256 MiB keep every grid of a
    #: trace up to some 10^5 subintervals. A count of entries is no bound here: the number of
    #: grids in use grows with the mesh (one per block of points).
    curve_cache_bytes = 256 * 2**20

    def _curve_data(self, S):
        """Curvatures ``k`` ``(3, 3, n)``, the weight direction in frame components ``(3, n)`` at ``S``, and
        whether the frame twists (``k3 != 0``) there.

        Cached by the content of ``S``: the residual is evaluated again and again
        at the same points (collocation points, their complex-step copies, check points).
        The complex step calls the residual at ``np.tile(S_block, m)``: such a grid is
        recognised, its block cached once and tiled on return (``m`` copies of the
        curve data would take ``m`` times the memory). Least recently used entries go
        when the data kept would exceed :attr:`curve_cache_bytes`.
        """
        S = np.asarray(S, float)
        base, reps = _untile(S)
        key = base.tobytes()
        cache = self._curve_cache
        hit = cache.pop(key, None)
        if hit is None:
            u, inv = np.unique(base, return_inverse=True)
            j = self.curve.jet(u)
            gK = np.einsum("ain,i->an", j.K, self.g)
            hit = (np.ascontiguousarray(j.k[:, :, inv]), np.ascontiguousarray(gK[:, inv]), bool(np.any(j.k[2])))
            size = hit[0].nbytes + hit[1].nbytes + len(key)
            if size > self.curve_cache_bytes:  # larger than the whole budget: not kept, nothing evicted for it
                return _tiled(hit, reps)
            self._curve_cache_size += size
            while cache and self._curve_cache_size > self.curve_cache_bytes:
                old_key = next(iter(cache))  # the least recently used
                old = cache.pop(old_key)
                self._curve_cache_size -= old[0].nbytes + old[1].nbytes + len(old_key)
        cache[key] = hit  # (re)inserted last: the most recently used
        return _tiled(hit, reps)

    def _curved_jets(self, S, z):
        """``r', r'', r'''`` (frame components), the curvatures and the weight direction at ``S``."""
        k, gK, twist = self._curve_data(S)
        return frame_jets(k, z[list(Jet.D1)], z[list(Jet.D2)], twist), k, gK

    def _residual_curved(self, S, z, p):
        """The residual with a moving frame, every vector in the components of the local frame ``K(S)``.

        What differs from the straight residual (``omega = (-k2, k1, k3)``, the
        frame's Darboux vector, so ``v' = [v]' + omega x v``):

        * ``r', r'', r'''`` carry the frame's rotation (:func:`rodcont.curves.frame_jets`);
        * the force's derivative is ``F' = [F]' + omega x F`` (``[F]'`` the derivative of
          its components, the unknowns), in the force balance
          ``F' + (w |r'| / alpha) g_K(S) = 0`` (``g_K`` the weight direction in the local
          frame) and in ``alpha' = (F'.d3 + F.d3') / EA``;
        * the pole ``p = K3`` turns: ``p' = (k1, k2, 0)``,
          ``p'' = (k1' - k3 k2, k2' + k3 k1, -(k1^2 + k2^2))``, and the twist rate of
          the untwisted frame gains the pole's terms::

              tau_q  = k3 + N / D,  N = d3.(p x p') - p.(d3 x d3'),  D = 1 + p.d3
              tau_q' = k3' + N'/D - N D'/D^2,
              N' = d3'.(p x p') + d3.(p x p'') - p'.(d3 x d3') - p.(d3 x d3''),  D' = p'.d3 + p.d3'

        The moment equations are still projected on ``K1, K2`` (the first two
        local components).
        """
        q = self._curved_state(S, z, p)
        EF, EM, torque = self._add_loads(self._curved_kinematics(q), q.Ft, q.EM, q.mp)
        return _equations(EF, EM, torque / q.GJ)

    def _curved_state(self, S, z, p) -> SimpleNamespace:
        """Every quantity of :meth:`_residual_curved` before the loads, by name (its Jacobian reads them too)."""
        w, EI, GJ, EA = self._stiffness(S, p)
        k, gK, turning = self._curve_data(S)
        r1, r2, r3 = frame_jets(k, z[list(Jet.D1)], z[list(Jet.D2)], turning)
        F = z[Jet.F]
        Fp = z[Jet.FP]
        phi1, phi2 = z[Jet.PHI[1]], z[Jet.PHI[2]]
        n2, n, n3, c, d3, d3p, d3pp = _director_jets(r1, r2, r3)
        k1, k2, k3 = k[0, 0], k[1, 0], k[2, 0]
        # the true derivative of the force: F' = [F]' + omega x F
        Ft = np.stack([Fp[0] + k1 * F[2] - k3 * F[1], Fp[1] + k2 * F[2] + k3 * F[0], Fp[2] - k1 * F[0] - k2 * F[1]])
        alpha = 1.0 + _dot(F, d3) / EA
        alphap = (_dot(Ft, d3) + _dot(F, d3p)) / EA
        bend = _cross(r1, r2)
        r13 = _cross(r1, r3)
        uperp_p = ((alphap * bend + alpha * r13) - (3.0 * alpha * c / n2) * bend) / n3
        J1 = alpha / n
        J1p = alphap / n - alpha * c / n3
        # the moving pole p = K3 = (0, 0, 1) in its own frame; p x v = (-v1, v0, 0)
        pd = 1.0 + d3[2]
        dxd = _cross(d3, d3p)
        N = k1 * d3[1] - k2 * d3[0] - dxd[2]
        P20 = k[0, 1] - k3 * k2
        P21 = k[1, 1] + k3 * k1
        Np = ((k1 * d3p[1] - k2 * d3p[0]) + (P20 * d3[1] - P21 * d3[0])
              - (k1 * dxd[0] + k2 * dxd[1]) - (d3[0] * d3pp[1] - d3[1] * d3pp[0]))
        pdp = k1 * d3[0] + k2 * d3[1] + d3p[2]
        tau = k3 + N / pd
        taup = k[2, 1] + Np / pd - N * pdp / pd**2
        twist = phi1 + tau
        m = GJ * J1 * twist
        mp = GJ * (J1p * twist + J1 * (phi2 + taup))
        EM = EI * uperp_p[:2] + m * d3p[:2] + mp * d3[:2] + _cross2(r1, F)
        return SimpleNamespace(**locals())  # every name above (the Jacobian's chain rule reads most of them)

    def _curved_kinematics(self, q) -> Kinematics:
        return Kinematics(q.S, q.z, q.p, q.n, q.alpha, q.d3, q.gK, _deflection(q.z), **self._local_weight(q.w))

    def _jacobian_curved(self, S, z, p):
        """The moving-frame residual and its exact derivatives w.r.t. the jet (:meth:`jacobian`'s contract), by
        hand: the geometry carries tangents along the eight seeds ``Delta1^(j), Delta2^(j)`` (``j = 0..3``,
        :meth:`_curved_geometry_tangents`), the force and the twist enter linearly (or bilinearly) and are
        differentiated in closed form (:meth:`_curved_linear_columns`), the loads by their own tangents along
        the geometric seeds and ``F`` (:meth:`_curved_load_tangents`). Checked against the complex step of
        :meth:`residual` in ``tests/test_rod_curved_jacobian.py``."""
        if S.size > JACOBIAN_BLOCK:  # bounds the tangents' memory
            parts = [self._jacobian_curved(S[i:i + JACOBIAN_BLOCK], z[:, i:i + JACOBIAN_BLOCK], p)
                     for i in range(0, S.size, JACOBIAN_BLOCK)]
            return np.concatenate([g for g, _ in parts], axis=1), np.concatenate([d for _, d in parts], axis=2)
        q = self._curved_state(S, z, p)
        kin = self._curved_kinematics(q)
        EF, EM, torque = self._add_loads(kin, q.Ft, q.EM, q.mp)
        G = _equations(EF, EM, torque / q.GJ)
        t = self._curved_geometry_tangents(q)
        geo_cols, jF, jFp = self._dG_cols
        out = np.zeros((6, self._active.size, q.n.shape[-1]))
        geo = out[:, geo_cols]  # (equation, seed, point): a view
        geo[3:5] = (q.EI * t.duperp[:, :2] + t.dm[:, None] * q.d3p[:2] + q.m * t.dd3p[:, :2]
                    + t.dmp[:, None] * q.d3[:2] + q.mp * t.dd3[:, :2] + _tcross(t.dr1, q.F)[:, :2]).transpose(1, 0, 2)
        geo[5] = t.dmp
        self._curved_linear_columns(q, out)
        dEF, dEM, dtq = self._curved_load_tangents(q, kin, t)
        if dEF is not None:
            geo[:3] += dEF[:8].transpose(1, 0, 2)
            out[:3, jF] += dEF[8:].transpose(1, 0, 2)
        if dEM is not None:
            geo[3:5] += dEM[:8, :2].transpose(1, 0, 2)
            out[3:5, jF] += dEM[8:, :2].transpose(1, 0, 2)
            geo[5] += dtq[:8]
            out[5, jF] += dtq[8:]
        out[5] /= q.GJ
        return G, out

    @staticmethod
    def _curved_geometry_tangents(q) -> SimpleNamespace:
        """Tangents of the geometric quantities of :meth:`_curved_state` along the seeds ``Delta1^(j)``
        (``j = 0..3``), then ``Delta2^(j)``: ``(8, npts)`` scalars, ``(8, 3, npts)`` vectors (``r^(j)`` is
        affine in the seeds: its tangents are :func:`_frame_jet_tangents`)."""
        dr1, dr2, dr3 = _frame_jet_tangents(q.k)
        n, n2, n3, c, d3, d3p = q.n, q.n2, q.n3, q.c, q.d3, q.d3p
        r1, r2, r3, F, EA = q.r1, q.r2, q.r3, q.F, q.EA
        dn = _tdot(dr1, d3)
        dd3 = (dr1 - d3 * dn[:, None]) / n
        dc = _tdot(dr1, r2) + _tdot(dr2, r1)
        d3r2 = _dot(d3, r2)
        dd3r2 = _tdot(dd3, r2) + _tdot(dr2, d3)
        e = r2 - d3 * d3r2
        de = dr2 - dd3 * d3r2 - d3 * dd3r2[:, None]
        dd3p = (de - d3p * dn[:, None]) / n
        dn3 = 3.0 * n2 * dn
        t1 = _dot(d3p, r2) + _dot(d3, r3)
        dt1 = _tdot(dd3p, r2) + _tdot(dr2, d3p) + _tdot(dd3, r3) + _tdot(dr3, d3)
        qv = r3 - d3p * d3r2 - d3 * t1
        dq = dr3 - dd3p * d3r2 - d3p * dd3r2[:, None] - dd3 * t1 - d3 * dt1[:, None]
        dd3pp = (dq - (qv / n) * dn[:, None]) / n - (de * c + e * dc[:, None] - (e * (c / n3)) * dn3[:, None]) / n3
        dbend = _tcross(dr1, r2) - _tcross(dr2, r1)
        dr13 = _tcross(dr1, r3) - _tcross(dr3, r1)
        dalpha = _tdot(dd3, F) / EA
        dalphap = (_tdot(dd3, q.Ft) + _tdot(dd3p, F)) / EA
        K = c / n2
        dK = dc / n2 - (c / n2**2) * (2.0 * n * dn)
        W = q.r13 - 3.0 * K * q.bend
        dW = dr13 - 3.0 * (dK[:, None] * q.bend + K * dbend)
        duperp = (dalphap[:, None] * q.bend + q.alphap * dbend + dalpha[:, None] * W + q.alpha * dW
                  - q.uperp_p * dn3[:, None]) / n3
        dJ1 = dalpha / n - (q.alpha / n2) * dn
        dJ1p = (dalphap / n - (q.alphap / n2) * dn - (dalpha * c + q.alpha * dc) / n3
                + (q.alpha * c / n3**2) * dn3)
        dtau, dtaup = EulerianRod._pole_tangents(q, dd3, dd3p, dd3pp)
        ptw = q.phi2 + q.taup
        dm = q.GJ * (dJ1 * q.twist + q.J1 * dtau)
        dmp = q.GJ * (dJ1p * q.twist + q.J1p * dtau + dJ1 * ptw + q.J1 * dtaup)
        return SimpleNamespace(dr1=dr1, dn=dn, dd3=dd3, dd3p=dd3p, dalpha=dalpha, duperp=duperp, dm=dm, dmp=dmp,
                               W=W)

    @staticmethod
    def _pole_tangents(q, dd3, dd3p, dd3pp):
        """Tangents of ``tau_q`` and ``tau_q'`` (the moving pole's terms) from those of ``d3, d3', d3''``."""
        k1, k2, d3, d3p, d3pp, pd, N = q.k1, q.k2, q.d3, q.d3p, q.d3pp, q.pd, q.N
        dpd = dd3[:, 2]
        ddxd = _tcross(dd3, d3p) - _tcross(dd3p, d3)
        dN = k1 * dd3[:, 1] - k2 * dd3[:, 0] - ddxd[:, 2]
        dNp = ((k1 * dd3p[:, 1] - k2 * dd3p[:, 0]) + (q.P20 * dd3[:, 1] - q.P21 * dd3[:, 0])
               - (k1 * ddxd[:, 0] + k2 * ddxd[:, 1])
               - (dd3[:, 0] * d3pp[1] + d3[0] * dd3pp[:, 1] - dd3[:, 1] * d3pp[0] - d3[1] * dd3pp[:, 0]))
        dpdp = k1 * dd3[:, 0] + k2 * dd3[:, 1] + dd3p[:, 2]
        dtau = dN / pd - (N / pd**2) * dpd
        dtaup = (dNp / pd - (q.Np / pd**2) * dpd - (dN * q.pdp + N * dpdp) / pd**2
                 + (2.0 * N * q.pdp / pd**3) * dpd)
        return dtau, dtaup

    def _curved_linear_columns(self, q, out) -> None:
        """The columns of ``phi', phi''``, ``F`` and ``[F]'`` of :meth:`_jacobian_curved` (torque row times GJ)."""
        pos = self._jet_pos
        _, jF, jFp = self._dG_cols
        GJ, EA, EI, n, n3, c, d3, d3p = q.GJ, q.EA, q.EI, q.n, q.n3, q.c, q.d3, q.d3p
        ptw = q.phi2 + q.taup
        out[3:5, pos[Jet.PHI[1]]] = GJ * (q.J1 * d3p[:2] + q.J1p * d3[:2])
        out[5, pos[Jet.PHI[1]]] = GJ * q.J1p
        out[3:5, pos[Jet.PHI[2]]] = GJ * q.J1 * d3[:2]
        out[5, pos[Jet.PHI[2]]] = GJ * q.J1
        # F enters alpha (d3 / EA) and alpha' ((d3' + d3 x omega) / EA: F' = [F]' + omega x F)
        omega = np.stack([-q.k2, q.k1, q.k3])
        aF = d3 / EA
        apF = (d3p + _cross(d3, omega)) / EA
        W = q.r13 - 3.0 * (c / q.n2) * q.bend
        J1F = aF / n
        J1pF = apF / n - aF * (c / n3)
        mF = GJ * J1F * q.twist
        mpF = GJ * (J1pF * q.twist + J1F * ptw)
        out[3:5, jF] = (EI * (apF[:, None] * q.bend[:2] + aF[:, None] * W[:2]) / n3
                        + mF[:, None] * d3p[:2] + mpF[:, None] * d3[:2]).transpose(1, 0, 2)
        out[5, jF] = mpF
        mpFp = GJ * J1F * q.twist
        out[3:5, jFp] = (EI * aF[:, None] * q.bend[:2] / n3 + mpFp[:, None] * d3[:2]).transpose(1, 0, 2)
        out[5, jFp] = mpFp
        # the force balance: F' = [F]' + omega x F; the moment: r' x F (first two components)
        jF, r1 = pos[Jet.F], q.r1
        out[[0, 1, 2], pos[Jet.FP]] = 1.0
        out[0, jF[1]], out[0, jF[2]] = -q.k3, q.k1
        out[1, jF[0]], out[1, jF[2]] = q.k3, q.k2
        out[2, jF[0]], out[2, jF[1]] = -q.k1, -q.k2
        out[3, jF[1]] -= r1[2]
        out[3, jF[2]] += r1[1]
        out[4, jF[0]] += r1[2]
        out[4, jF[2]] -= r1[0]

    def _curved_load_tangents(self, q, kin, t):
        """The loads' tangents along the eight geometric seeds, then ``F.K1, F.K2, F.K3``: force ``(11, 3, npts)``,
        moment on ``K1, K2`` and its ``d3`` part (``(11, 3, npts)``, ``(11, npts)``); None where no load has one."""
        npts = q.n.shape[-1]
        zero = np.zeros((3, npts))
        seeds = np.zeros((11, 1))
        dD1, dD2 = seeds.copy(), seeds.copy()
        dD1[0], dD2[4] = 1.0, 1.0
        lt = Tangents(n=np.concatenate([t.dn, zero]), alpha=np.concatenate([t.dalpha, q.d3 / q.EA]),
                      d3=np.concatenate([t.dd3, np.zeros((3, 3, npts))]), deflection=(dD1, dD2))
        dEF = dEM = dtq = None
        for load in self.loads:
            df = load.force_tangent(kin, lt)
            if df is not None:
                dEF = df if dEF is None else dEF + df
            dl = load.moment_tangent(kin, lt)
            if dl is not None:
                dq = _tdot(dl, q.d3) + _tdot(lt.d3, load.moment(kin))
                dEM, dtq = (dl, dq) if dEM is None else (dEM + dl, dtq + dq)
        return dEF, dEM, dtq

    def _axial_curved(self, S, z, p):
        """:meth:`_axial_quantities` with a moving frame."""
        w, EI, GJ, EA = self._stiffness(S, p)
        (r1, r2, _), k, _ = self._curved_jets(S, z)
        n = np.sqrt(_dot(r1, r1))
        d3 = r1 / n
        F = z[Jet.F]
        d3p = (r2 - d3 * _dot(d3, r2)) / n
        alpha = 1.0 + _dot(F, d3) / EA
        N = k[0, 0] * d3[1] - k[1, 0] * d3[0] - (d3[0] * d3p[1] - d3[1] * d3p[0])
        tau = k[2, 0] + N / (1.0 + d3[2])
        m = GJ * alpha / n * (z[Jet.PHI[1]] + tau)
        return m, alpha, n, d3

    # ---- joins: the stations where the reference's curvature jumps ---------------
    def interface(self, zl, zr, p, S):
        """The 5 interface conditions at the joins ``S`` (one-sided jets ``zl``, ``zr``): the physical rod is
        continuous there (no point force or moment), left minus right of :meth:`_joint_quantities`.

        The frame ``K`` and the fields are continuous (C^0), so are the centreline and the force; what the
        C^0 joins leave free is fixed by the continuity of ``d3`` (its ``K1, K2`` components), of the bending
        curvature ``alpha (r' x r'')/|r'|^3`` (the moment over ``EI``, on ``K1, K2``) and of the twist rate
        ``m / GJ`` (the torque). Each side reads the reference's curvature on its own side.
        """
        kl, kr = self._join_curvatures(S)
        if self.sections is not None:  # the moment EI u and the torque m are continuous where EI, GJ jump
            fl, fr = self.sections.factors(S, -1), self.sections.factors(S, 1)
            return self._joint_quantities(kl, zl, p, fl) - self._joint_quantities(kr, zr, p, fr)
        return self._joint_quantities(kl, zl, p) - self._joint_quantities(kr, zr, p)

    def _join_curvatures(self, S):
        """Curvatures ``(3, 3, len(S))`` just left and just right of the joins ``S`` (cached by grid)."""
        S = np.asarray(S, float)
        key = S.tobytes()
        hit = self._join_curve_cache.get(key)
        if hit is None:
            u, inv = np.unique(S, return_inverse=True)
            hit = tuple(np.ascontiguousarray(self.curve.one_sided_jet(u, side).k[:, :, inv]) for side in (-1, 1))
            if len(self._join_curve_cache) > 8:  # a few grids: the joins, and their complex-step copies
                self._join_curve_cache.clear()
            self._join_curve_cache[key] = hit
        return hit

    @staticmethod
    def _joint_quantities(k, z, p, factors=None):
        """``(d3.K1, d3.K2, u.K1, u.K2, m/GJ)`` from jets ``z`` with the curvatures ``k``: ``u = alpha (r' x r'')/n^3``
        (``= d3 x d3_s``), ``m/GJ = alpha/n (phi' + tau_q)`` as in :meth:`_residual_curved`. With a side's section
        ``factors`` (:meth:`Sections.factors`: of ``w, EI, GJ, EA``) ``u`` and ``m/GJ`` are scaled by that side's
        ``EI`` and ``GJ`` factors (the moment and the torque over the reference stiffnesses)."""
        phi_L, T, w, EI, GJ, EA = p[:6]
        if factors is not None:
            EA = EA * factors[3]
        r1, r2, r3 = frame_jets(k, z[list(Jet.D1)], z[list(Jet.D2)])
        n2, n, n3, c, d3, d3p, d3pp = _director_jets(r1, r2, r3)
        alpha = 1.0 + _dot(z[Jet.F], d3) / EA
        u = (alpha / n3) * _cross2(r1, r2)
        k1, k2, k3 = k[0, 0], k[1, 0], k[2, 0]
        tau = k3 + (k1 * d3[1] - k2 * d3[0] - (d3[0] * d3p[1] - d3[1] * d3p[0])) / (1.0 + d3[2])
        twist = alpha / n * (z[Jet.PHI[1]] + tau)
        if factors is not None:
            u, twist = u * factors[1], twist * factors[2]
        return np.stack([d3[0], d3[1], u[0], u[1], twist])

    def discretise(self, N: int = 15, k: int = 5, breakpoints=None) -> Collocation:
        """Collocation on ``N`` uniform subintervals of ``[0, curve.length]`` (or on ``breakpoints``).

        A curve with interior breakpoints (a well's stations) gets ``N``
        subintervals that contain them (:meth:`rodcont.curves.ReferenceCurve.mesh`);
        given ``breakpoints`` must contain them too.
        """
        if breakpoints is None:
            if not (isinstance(N, (int, np.integer)) and N >= 1):
                raise ValueError(f"N (number of subintervals) must be an integer >= 1, got {N!r}")
            check_mesh_size(int(N), k)
            breakpoints = int(N)
            if self.stations.size > 2:
                from .curves import mesh_through
                breakpoints = mesh_through(self.stations, int(N), "pieces between the stations of the reference "
                                                                 "curve and the conduit's clearance")
        else:
            self._check_mesh(breakpoints, k)
        return Collocation(self.problem, breakpoints, k)

    def _check_mesh(self, breakpoints, k) -> None:
        """A given mesh spans the domain ``[0, curve.length]`` and holds every station (a well's, a clearance
        table's): on another span it would solve another rod without a word (breakpoints ``0 .. 0.9`` of a span
        of 1 put the Gamma = 1 fold at 12.824 instead of 13.09999)."""
        if isinstance(breakpoints, (str, bytes, dict)):
            raise TypeError(f"breakpoints must be a sequence of numbers (the mesh's), got {breakpoints!r}")
        try:
            b = np.asarray(breakpoints, float)
        except (TypeError, ValueError):
            raise TypeError(f"breakpoints must be a sequence of numbers (the mesh's), got {breakpoints!r}") from None
        if b.ndim != 1 or b.size < 2 or not np.all(np.isfinite(b)):
            raise ValueError("breakpoints must be a strictly increasing sequence of at least 2 finite values")
        check_mesh_size(b.size - 1, k)
        a, e = self.interval
        tol = 1e-10 * (e - a)
        if abs(b[0] - a) > tol or abs(b[-1] - e) > tol:
            raise ValueError(f"the mesh must span the rod's domain [{a:.12g}, {e:.12g}] (the reference curve); its "
                             f"breakpoints run from {b[0]:.12g} to {b[-1]:.12g}")
        inner = self.stations[1:-1]
        if inner.size:
            gap = np.min(np.abs(inner[:, None] - b[None, :]), axis=1)
            if np.any(gap > tol):
                missing = inner[gap > tol]
                raise ValueError(f"the mesh must have a breakpoint at every station of the reference curve and the "
                                 f"conduit's clearance: {missing.size} missing, the first at S = {missing[0]:.12g}")

    def initial_guess(self, disc: Collocation, T: float) -> np.ndarray:
        """Straight untwisted rod; ``F`` carries ``T`` along the axis and the weight of a rod of length ``L``.

        ``F' = -w g`` split into its transverse part (shared equally by the two
        clamps) and its axial part (``F . K3 = T`` at ``S = L``); frame components.
        With a moving frame: the rod on the reference curve, the same split with
        the end tangent ``K3(end)`` as the axis and the curve's length for ``L``.
        """
        if not self.constant_frame:
            return self._initial_guess_curved(disc, T)
        L, w, gK = self.rod.L, self.rod.w, self.gK
        axis = np.array([0.0, 0.0, 1.0])
        ga = float(gK[2])
        gt = gK - ga * axis
        comps = [lambda S: 0 * S] * 3
        comps += [lambda S, a=a: T * axis[a] - w * gt[a] * (S - 0.5 * L) - w * ga * axis[a] * (S - L)
                  for a in range(3)]
        return disc.project(comps, self._free_guess(T))

    def _free_guess(self, T: float) -> list:
        """First values of the freed parameters: ``phi_L = 0`` (the untwisted start), ``T`` as given."""
        return [float(T) if name == "T" else 0.0 for name in self.ends.frees]

    def _initial_guess_curved(self, disc: Collocation, T: float) -> np.ndarray:
        L, w, g = self.curve.length, self.rod.w, self.g
        tL = self.curve.frame(np.array([L]))[2][:, 0]
        ga = float(g @ tL)
        gt = g - ga * tL

        def component(a):
            def f(S):
                S = np.atleast_1d(np.asarray(S, float))
                Fg = T * tL[:, None] - w * gt[:, None] * (S - 0.5 * L) - w * ga * tL[:, None] * (S - L)
                return _dot(Fg, self.curve.frame(S)[a])
            return f

        zero = lambda S: 0 * S  # noqa: E731
        return disc.project([zero, zero, zero, component(0), component(1), component(2)], self._free_guess(T))

    def force(self, disc: Collocation, x: np.ndarray, S) -> np.ndarray:
        """Internal force ``F(S)`` in global components, ``(3, len(S))``."""
        S = np.atleast_1d(np.asarray(S, float))
        FK = np.stack([disc.evaluate(x, S, i) for i in (3, 4, 5)])
        if not self.constant_frame:
            K = self.curve.jet(S).K
            return K[0] * FK[0] + K[1] * FK[1] + K[2] * FK[2]
        return self.frame.T @ FK

    # ---- derived outputs -------------------------------------------------
    def outputs(self, disc: Collocation, x: np.ndarray, p: np.ndarray, samples: int = 8) -> dict:
        """``stretch``, ``torque``, ``l``, ``l0``, ``min_alignment``, ``helical_waves``, ``defect`` of a solution.

        ``torque`` is the mean over the mesh points (superconvergent), ``torque_spread``
        its range there; ``l, l0`` use the Gauss rule of the mesh (error O(h^2k)).
        """
        return self.output_evaluator(disc, samples)(x, p)

    def output_evaluator(self, disc: Collocation, samples: int = 8) -> _Outputs:
        """The evaluation matrices behind :meth:`outputs`, built once per discretisation."""
        out = getattr(disc, "_rod_outputs", None)
        if out is None or out.model is not self or out.samples != samples:
            out = disc._rod_outputs = _Outputs(self, disc, samples)
        return out

    def integral_outputs(self, disc: Collocation, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        """``(stretch, l0, torque)`` of a solution, the values :meth:`outputs` gives, without its sample and check
        grids (what the error estimate's richer twin reads: building those grids cost it 2.7 ms a mesh)."""
        out = getattr(disc, "_rod_integrals", None)
        if out is None or out.model is not self:
            out = disc._rod_integrals = _Integrals(self, disc)
        return out(x, p)

    def contact(self, disc: Collocation, x: np.ndarray, p: np.ndarray, per_interval: int = 16,
                S: np.ndarray | None = None) -> dict:
        """Contact with the conduit wall on a grid of ``per_interval`` points per subinterval (or at ``S``).

        Returns ``S``, ``gap = c - |Delta|``, ``pressure`` (the wall's force per
        unit ``S``, :meth:`rodcont.contact.Wall.pressure`), the axial force
        ``F.d3`` and the torque ``m`` there; ``zones`` (``(S_start, S_end, force)``,
        :func:`rodcont.contact.contact_zones`), ``min_gap`` and ``side_force``
        (the integral of the pressure over the span). The forces (``side_force``, each zone's) are the
        collocation rule's, whatever ``S``: the pressure at the collocation points, where alone the equations
        load the rod, integrated as :meth:`rodcont.collocation.Collocation.integrate_between` does.
        """
        from .contact import contact_zones
        if self.wall is None:
            raise ValueError("this rod has no conduit wall")
        key = None
        if S is None:
            # a trace asks for the same point's contact twice (its table's columns, then its /contact rows)
            key = (disc.k, disc.breakpoints.tobytes(), np.asarray(x).tobytes(), np.asarray(p).tobytes(),
                   per_interval)
            cached = getattr(self, "_last_contact", None)
            if cached is not None and cached[0] == key:
                return cached[1]
            b = disc.breakpoints
            t = np.linspace(0.0, 1.0, per_interval + 1)[:-1]
            S = np.concatenate([(b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), [b[-1]]])
        S = np.asarray(S, float)
        p = disc.full_params(x, p)
        z = (disc.jet_matrix(S) @ x).reshape(self.problem.jet_size, S.size)
        D1, D2 = z[Jet.D1[0]], z[Jet.D2[0]]
        gap = self.wall.clearance_at(S) - np.hypot(D1, D2)
        pressure = self.wall.pressure(D1, D2, self.contact_scale, S)
        m, alpha, n, d3 = self._axial_quantities(S, z, p)
        axial = _dot(z[Jet.F], d3)
        at_points = self.pressure_at_points(disc, x)
        zones = contact_zones(S, pressure, self.wall.contact_level * self.contact_scale,
                              lambda edges: disc.integrate_between(at_points, edges))
        out = dict(S=S, gap=gap, pressure=pressure, axial_force=axial, torque=m, zones=zones,
                   min_gap=float(gap.min()), side_force=disc.integrate(at_points))
        if key is not None:
            self._last_contact = (key, out)
        return out

    def pressure_at(self, disc: Collocation, x: np.ndarray, S) -> np.ndarray:
        """The wall's force per length at points ``S`` on the solution's spline (:meth:`contact`'s ``pressure``,
        without the rest of its grid quantities)."""
        S = np.asarray(S, float)
        z = (disc.jet_matrix(S) @ x).reshape(self.problem.jet_size, S.size)
        return self.wall.pressure(z[Jet.D1[0]], z[Jet.D2[0]], self.contact_scale, S)

    def pressure_at_points(self, disc: Collocation, x: np.ndarray) -> np.ndarray:
        """The wall's force per length at the collocation points, where alone the equations load the rod (a point
        contact narrower than an interval is misread by a sampling; test_the_total_side_force_...); its Gauss
        rule is :meth:`contact`'s ``side_force``."""
        z = disc.jets(x)
        return self.wall.pressure(z[Jet.D1[0]], z[Jet.D2[0]], self.contact_scale, disc.S)

    def stretch_factor_min(self, disc: Collocation, x: np.ndarray, p: np.ndarray) -> float:
        """Smallest stretch factor ``alpha = 1 + F.d3/EA`` at the collocation points."""
        return float(np.min(self._axial_quantities(disc.S, disc.jets(x), disc.full_params(x, p))[1]))

    def torque_profile(self, disc: Collocation, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        """``m = GJ J1 (phi' + tau_q)`` at the collocation points."""
        return self._axial_quantities(disc.S, disc.jets(x), disc.full_params(x, p))[0]

    def _axial_quantities(self, S, z, p):
        """Torque ``m``, stretch ``alpha``, ``n = |r'|`` and ``d3`` (frame components) at points ``S``."""
        if not self.constant_frame:
            return self._axial_curved(S, z, p)
        w, EI, GJ, EA = self._stiffness(S, p)
        r1, r2, _ = self._frame_jets(z)
        n = np.sqrt(_dot(r1, r1))
        d3 = r1 / n
        F = z[Jet.F]
        d3p = (r2 - d3 * _dot(d3, r2)) / n
        alpha = 1.0 + _dot(F, d3) / EA
        tau = -(d3[0] * d3p[1] - d3[1] * d3p[0]) / (1.0 + d3[2])
        m = GJ * alpha / n * (z[Jet.PHI[1]] + tau)
        return m, alpha, n, d3

    def centreline(self, disc: Collocation, x: np.ndarray, S: np.ndarray) -> np.ndarray:
        """``r(S)``, ``(3, len(S))``."""
        S = np.atleast_1d(np.asarray(S, float))
        D1 = np.stack([disc.evaluate(x, S, 0, nu) for nu in range(4)])
        D2 = np.stack([disc.evaluate(x, S, 1, nu) for nu in range(4)])
        return self.curve.centreline_jets(S, D1, D2)[0]

    def directors(self, disc: Collocation, x: np.ndarray, S: np.ndarray) -> np.ndarray:
        """``d1, d2, d3`` at ``S``: array ``(3, 3, len(S))`` (director index first)."""
        S = np.atleast_1d(np.asarray(S, float))
        D1 = np.stack([disc.evaluate(x, S, 0, nu) for nu in range(4)])
        D2 = np.stack([disc.evaluate(x, S, 1, nu) for nu in range(4)])
        phi = disc.evaluate(x, S, 2, 0)
        _, r1, *_ = self.curve.centreline_jets(S, D1, D2)
        d3 = r1 / np.sqrt(_dot(r1, r1))
        if not self.constant_frame:  # minimal rotation taking the moving pole K3(S) onto d3
            K = self.curve.jet(S).K
            a1, a2 = minimal_rotation(K[2], d3, K[0]), minimal_rotation(K[2], d3, K[1])
            c, s = np.cos(phi), np.sin(phi)
            return np.stack([c * a1 + s * a2, -s * a1 + c * a2, d3])
        P = self.pole[:, None]
        kx = _cross(np.broadcast_to(P, d3.shape), d3)  # sin(theta) * axis
        cth = _dot(np.broadcast_to(P, d3.shape), d3)

        def rotate(v):  # minimal rotation taking the pole onto d3 (Rodrigues)
            v = np.broadcast_to(v[:, None], d3.shape)
            return cth * v + _cross(kx, v) + kx * (_dot(kx, v) / (1.0 + cth))

        a1, a2 = rotate(self.K1), rotate(self.K2)
        c, s = np.cos(phi), np.sin(phi)
        return np.stack([c * a1 + s * a2, -s * a1 + c * a2, d3])


class _Outputs:
    """Evaluation matrices for the derived outputs of one discretisation (built once).

    One sparse product gives everything the outputs read: ``Delta1, Delta2`` and
    their slopes on a grid of ``samples`` points per subinterval, the jets at the
    mesh points (where Gauss collocation is superconvergent, O(h^2k): the torque
    is read there) and the jets at the check points between the collocation
    points (where the residual is not forced to zero: its size there, the
    defect, indicates the discretisation error).
    """

    def __init__(self, model: EulerianRod, disc: Collocation, samples: int):
        self.model, self.disc, self.samples = model, disc, samples
        b = disc.breakpoints
        t = np.linspace(0.0, 1.0, samples + 1)[:-1]
        S = np.concatenate([(b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), [b[-1]]])
        self.S = S
        nodes = np.concatenate([[-1.0], gauss_legendre(disc.k)[0], [1.0]])
        mids = 0.5 * (nodes[1:] + nodes[:-1])
        self.S_check = (b[:-1, None] + 0.5 * np.diff(b)[:, None] * (mids[None, :] + 1.0)).ravel()
        nz = disc.problem.jet_size
        self.n_samples, self.n_mesh, self.n_check = S.size, b.size, self.S_check.size
        # one jet matrix for all points, then the rows each output reads
        pts = np.concatenate([S, b, self.S_check])
        npts = pts.size
        Z = disc.jet_matrix(pts)
        rows = [Jet.D1[0] * npts + np.arange(S.size), Jet.D2[0] * npts + np.arange(S.size),
                Jet.D1[1] * npts + np.arange(S.size), Jet.D2[1] * npts + np.arange(S.size)]
        for lo, n in ((S.size, b.size), (S.size + b.size, self.S_check.size)):
            rows.append((np.arange(nz)[:, None] * npts + lo + np.arange(n)[None, :]).ravel())
        self.E = Z[np.concatenate(rows)]
        self.nz = nz
        self.S_axial = np.concatenate([disc.S, b])  # collocation and mesh points: one call for both

    def _split(self, x):
        v = self.E @ x
        ns, nm = self.n_samples, self.n_mesh
        D1, D2, D1p, D2p = v[:ns], v[ns:2 * ns], v[2 * ns:3 * ns], v[3 * ns:4 * ns]
        o = 4 * ns
        zm = v[o:o + self.nz * nm].reshape(self.nz, nm)
        zc = v[o + self.nz * nm:].reshape(self.nz, self.n_check)
        return D1, D2, D1p, D2p, zm, zc

    def __call__(self, x, p):
        model, disc = self.model, self.disc
        p = disc.full_params(x, p)  # the freed parameters (phi_L under a torque, T under l0) from x
        z = disc.jets(x)
        D1, D2, d1p, d2p, zm, zc = self._split(x)
        m, alpha, n, _ = model._axial_quantities(self.S_axial, np.concatenate([z, zm], axis=1), p)
        npts = disc.npts
        alpha, n, m_mesh = alpha[:npts], n[:npts], m[npts:]
        L = model.rod.L
        l = disc.integrate(n)
        l0 = disc.integrate(n / alpha)
        if model.constant_frame:
            # alignment d3 . K3 on the sample grid (straight reference: K3 constant)
            align = 1.0 / np.sqrt(1.0 + d1p**2 + d2p**2)
        else:
            # r' = (D1' - k3 D2, D2' + k3 D1, 1 - k1 D1 - k2 D2) in the local frame: d3 . K3 = r'_3 / |r'|;
            # the slope relative to the reference curve (for the helical waves) is (r'_1, r'_2) / r'_3
            k = model._curve_data(self.S)[0]
            t1, t2 = d1p - k[2, 0] * D2, d2p + k[2, 0] * D1
            t3 = 1.0 - k[0, 0] * D1 - k[1, 0] * D2
            align = t3 / np.sqrt(t1**2 + t2**2 + t3**2)
            d1p, d2p = t1 / t3, t2 / t3
        G = np.abs(model.residual(self.S_check, zc, p)).max(axis=1)
        return dict(stretch=(l - L) / L, torque=float(np.mean(m_mesh)), l=l, l0=l0,
                    alpha_min=float(np.min(alpha)),
                    defect=float(np.max(G / self._scales(p, z))),
                    min_alignment=float(np.min(align)),
                    helical_waves=helical_waves(self.S, D1, D2, d1p, d2p),
                    torque_spread=float(np.ptp(m_mesh)))

    def interval_defect(self, x, p) -> np.ndarray:
        """The relative defect of :meth:`defect`, its maximum on each subinterval."""
        p = self.disc.full_params(x, p)
        z = self.disc.jets(x)
        zc = self._split(x)[5]
        G = np.abs(self.model.residual(self.S_check, zc, p)) / self._scales(p, z)[:, None]
        return G.max(axis=0).reshape(self.disc.N, -1).max(axis=1)

    def _scales(self, p, z):
        """Scales: force equations ``max(w, |F|/L, EI/L^3)``, moment equations
        ``max(|F|, EI/L^2)``, torque equation ``max(|phi_L|, 1)/L^2``."""
        L, w, EI = self.model.rod.L, p[2], p[3]
        Fmax = float(np.sqrt((z[Jet.F] ** 2).sum(axis=0)).max())
        return np.array([max(w, Fmax / L, EI / L**3)] * 3 + [max(Fmax, EI / L**2)] * 2
                        + [max(abs(p[0]), 1.0) / L**2])


class _Integrals:
    """The jets at the mesh points of one discretisation, for :meth:`EulerianRod.integral_outputs`: the rows of
    :class:`_Outputs`'s matrix that its lengths and torque read, so the values are the same to the bit."""

    def __init__(self, model: EulerianRod, disc: Collocation):
        self.model, self.disc = model, disc
        b = disc.breakpoints
        self.E = disc.jet_matrix(b)
        self.nz, self.n_mesh = disc.problem.jet_size, b.size
        self.S_axial = np.concatenate([disc.S, b])

    def __call__(self, x, p) -> tuple[float, float, float]:
        model, disc = self.model, self.disc
        p = disc.full_params(x, p)
        zm = (self.E @ x).reshape(self.nz, self.n_mesh)
        m, alpha, n, _ = model._axial_quantities(self.S_axial, np.concatenate([disc.jets(x), zm], axis=1), p)
        npts, L = disc.npts, model.rod.L
        alpha, n = alpha[:npts], n[:npts]
        return (disc.integrate(n) - L) / L, disc.integrate(n / alpha), float(np.mean(m[npts:]))


#: bytes a discretisation takes per unknown at k = 5 (the Jacobian, its LU and the evaluation matrices; measured
#: 1.5 GB at N = 8000, 240 011 unknowns), scaled by (k + 3) / 8 for other k
BYTES_PER_UNKNOWN = 6500.0


def _vector3(name: str, value) -> np.ndarray:
    """``value`` as a float array; a ``TypeError`` naming ``name`` when it is not a vector of numbers."""
    if isinstance(value, (str, bytes, dict)):
        raise TypeError(f"{name} must be a 3-vector of numbers (X, Y, Z), got {value!r}")
    try:
        return np.asarray(value, float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a 3-vector of numbers (X, Y, Z), got {value!r}") from None


def check_mesh_size(N: int, k: int) -> None:
    """Refuse a mesh the machine cannot hold (``ValueError``, one line): ``N`` subintervals of ``k`` Gauss points
    need about ``BYTES_PER_UNKNOWN (k + 3)/8`` bytes for each of their ``6 N k + 11`` unknowns (``N = 10^9`` would
    take petabytes; ``critical_twists(N_fine=10^7)`` ran to 10 GB before it was stopped)."""
    if isinstance(k, bool) or not (isinstance(k, (int, np.integer)) and 1 <= k <= 7):
        raise ValueError(f"k (Gauss points per subinterval) must be an integer in 1..7, got {k!r}")
    need = BYTES_PER_UNKNOWN * (int(k) + 3) / 8.0 * (6.0 * int(N) * int(k) + 11.0)
    have = _physical_memory()
    if need > have:
        raise ValueError(f"a mesh of N = {int(N)} subintervals (k = {int(k)}) needs about {need / 2**30:.3g} GiB, "
                         f"more than this machine's {have / 2**30:.3g} GiB")


def _physical_memory() -> float:
    import os
    try:
        return float(os.sysconf("SC_PAGE_SIZE")) * float(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 16.0 * 2**30


def _untile(S):
    """``(block, m)`` with ``S == np.tile(block, m)`` for the shortest such block that starts a new
    copy where ``S[0]`` recurs (the complex step's batches); ``(S, 1)`` for any other grid."""
    if S.ndim != 1 or S.size < 2:
        return S, 1
    again = np.flatnonzero(S[1:] == S[0])
    if again.size == 0:
        return S, 1
    m = int(again[0]) + 1
    if S.size % m or not np.array_equal(S.reshape(-1, m), np.broadcast_to(S[:m], (S.size // m, m))):
        return S, 1
    return S[:m], S.size // m


def _tiled(data, reps):
    """Curve data of a block for ``reps`` copies of it."""
    if reps == 1:
        return data
    k, gK, twist = data
    return np.tile(k, (1, 1, reps)), np.tile(gK, (1, reps)), twist


def helical_waves(S, D1, D2, D1p, D2p) -> int:
    """Number of helical waves: complete turns of the transverse slope ``(Delta1', Delta2')``.

    A helix about any axis parallel to the reference turns its transverse slope
    vector once per wave, whatever its offset (a sag). Counted as
    ``floor(turns + 1/4)``, ``turns = |total unwrapped angle of (Delta1', Delta2')| / 2 pi``
    over the part of the span where the slope is not negligible (the clamps force
    it to zero at the ends, where its direction is undefined): a wave counts
    once the slope has made three quarters of its turn. The planar sag turns
    it by half a turn only (down, then up) and counts 0; a helix whose slope is
    smaller than that of the sag it rides on does not circle and is not counted.
    """
    mag = np.hypot(D1p, D2p)
    keep = mag > 1e-3 * max(float(mag.max()), 1e-300)
    if keep.sum() < 2 or mag.max() < 1e-12:
        return 0
    u, v = D1p[keep], D2p[keep]
    cross = u[:-1] * v[1:] - v[:-1] * u[1:]
    dot = u[:-1] * u[1:] + v[:-1] * v[1:]
    # a slope through zero along a line turns it by +-pi as rounding decides: no turn
    # (test_helical_waves_of_a_planar_shape_in_any_plane_do_not_follow_rounding)
    through_zero = (dot < 0) & (np.abs(cross) <= 1e-8 * np.hypot(u[:-1], v[:-1]) * np.hypot(u[1:], v[1:]))
    turned = np.sum(np.where(through_zero, 0.0, np.arctan2(cross, dot)))
    return int(np.floor(abs(turned) / (2 * np.pi) + 0.25))
