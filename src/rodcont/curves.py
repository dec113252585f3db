"""Reference curves of the Eulerian rod: position, a moving frame and its curvatures.

A reference curve is unit-speed, ``R(S)``, ``S in [0, length]``, with an
orthonormal frame ``{K1, K2, K3 = R'}`` that moves with ``S``::

    K3' = k1 K1 + k2 K2,     K1' = k3 K2 - k1 K3,     K2' = -k3 K1 - k2 K3

(Darboux vector ``omega = -k2 K1 + k1 K2 + k3 K3``, so ``v' = [v]' + omega x v``
for a vector ``v`` with frame components ``[v]``). The built-in curves carry a
rotation-minimising (Bishop) frame, ``k3 = 0``: unlike a frame tied to ``e3``
it has no singularity where the curve is vertical, and unlike Frenet's it
exists where the curvature vanishes. The rod model needs ``k1, k2, k3`` and
their first two S-derivatives (``r'''`` reads ``K''``), the frame itself (the
weight direction in frame components, outputs) and the position (outputs).

The start frame is, unless given, the minimal rotation of ``{e2, e3, e1}``
taking ``e1`` onto ``K3(0)``: a curve leaving along ``e1`` starts with the
straight reference's frame ``K1 = e2, K2 = e3``.

Curves: :class:`Straight` (constant frame), :class:`CircularArc`,
:class:`Helix` (Bishop or Frenet frame), :class:`GraphCurve` (``x e1 + f(x)``,
reparametrised numerically by arclength; :class:`Bump` and :class:`Wiggle`
are two of them), :class:`MinimumCurvatureWell` (survey stations, piecewise
circular, ``breakpoints`` at the stations) and :class:`UserCurve` (any
unit-speed curve through callables). :func:`parse_reference` builds the
command-line kinds.

Numbers that are computed, not written in closed form (the arclength of a
graph, the Bishop frame of a general curve), are integrated by composite
Gauss-Legendre quadrature (20 points per cell, cumulative over the cells) and
inverted by Newton's method: exact to rounding (about 1e-15), with smooth
derivatives up to the order the model needs.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np

__all__ = ["CurveJet", "ReferenceCurve", "Straight", "StraightReference", "CircularArc", "Helix", "GraphCurve",
           "Bump", "Wiggle", "MinimumCurvatureWell", "UserCurve", "parse_reference", "frame_jets",
           "minimal_rotation", "REFERENCE_KINDS"]

_E1, _E2, _E3 = np.eye(3)
_GAUSS = np.polynomial.legendre.leggauss(20)


# --------------------------------------------------------------------------
# Vector helpers on (3, npts) arrays (np.cross is slow on small arrays)
# --------------------------------------------------------------------------
def _dot(a, b):
    return (a * b).sum(axis=0)


def _cross(a, b):
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.result_type(a, b))
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    np.multiply(a[0], b[1], out=out[2])
    out[2] -= a[1] * b[0]
    return out


def _col(v):
    return np.asarray(v, float).reshape(3, 1)


def minimal_rotation(p, d, v):
    """The rotation about ``p x d`` taking the unit vector ``p`` onto the unit vector ``d``, applied to ``v``.

    Rodrigues' formula ``c v + k x v + k (k.v) / (1 + c)``, ``k = p x d``,
    ``c = p.d``; arrays ``(3, ...)`` broadcast. Singular only for ``d = -p``.
    """
    p, d, v = (np.asarray(a) for a in (p, d, v))
    if p.ndim == d.ndim == v.ndim == 1:
        return minimal_rotation(p[:, None], d[:, None], v[:, None])[:, 0]
    c = _dot(p, d)
    kx = _cross(np.broadcast_to(p, np.broadcast_shapes(p.shape, d.shape)),
                np.broadcast_to(d, np.broadcast_shapes(p.shape, d.shape)))
    v = np.broadcast_to(v, kx.shape)
    return c * v + _cross(kx, v) + kx * (_dot(kx, v) / (1.0 + c))


def _unit(v, name: str) -> np.ndarray:
    v = np.asarray(v, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a finite 3-vector, got {v!r}")
    n = float(np.sqrt(v @ v))
    if n == 0:
        raise ValueError(f"{name} must be non-zero")
    return v / n


def start_frame(t0, K1=None) -> tuple[np.ndarray, np.ndarray]:
    """``K1(0), K2(0)`` for a curve leaving along the unit ``t0``.

    ``K1`` given: its part normal to ``t0``, normalised. Otherwise the minimal
    rotation of ``e2, e3`` taking ``e1`` onto ``t0`` (``e2, t0 x e2`` for ``t0 = -e1``).
    """
    t0 = _unit(t0, "the start tangent")
    if K1 is not None:
        K1 = np.asarray(K1, float)
        K1 = K1 - (K1 @ t0) * t0
        n = float(np.sqrt(K1 @ K1))
        if not n > 1e-8:
            raise ValueError("K1 must not be parallel to the start tangent")
        K1 = K1 / n
        return K1, np.cross(t0, K1)
    if 1.0 + t0[0] < 1e-12:
        return _E2.copy(), np.cross(t0, _E2)
    K1 = minimal_rotation(_E1, t0, _E2)
    K1 = K1 / np.sqrt(K1 @ K1)
    return K1, np.cross(t0, K1)


def frame_jets(k, D1, D2, twist: bool = True):
    """``r', r'', r'''`` of ``r = R + D1 K1 + D2 K2`` in frame components ``(v.K1, v.K2, v.K3)``.

    ``k``: ``(3, 3, npts)``, ``k[a, j]`` the ``j``-th derivative of ``k_{a+1}``;
    ``D1, D2``: ``(4, npts)`` jets (value and three derivatives). With
    ``Delta = (D1, D2, 0)`` and ``omega = (-k2, k1, k3)``, ``r' = K3 + Delta'`` and
    each S-derivative of a vector is ``[v]' + omega x v``::

        A0 = e3 + [Delta]' + omega x Delta                     (= r')
        A1 = [Delta]'' + omega' x Delta + omega x [Delta]'      (= [r']')
        A2 = [Delta]''' + omega'' x Delta + 2 omega' x [Delta]' + omega x [Delta]''
        r'' = A1 + omega x A0
        r''' = A2 + omega' x A0 + 2 omega x A1 + omega x (omega x A0)

    Pure arithmetic: complex jets (the complex step) pass through. Written out
    in components (``Delta`` has no third component; ``twist=False`` drops
    the ``k3`` terms, zero for a Bishop frame).
    """
    k1, k2 = k[0], k[1]
    a0, a1, a2, a3 = D1
    b0, b1, b2, b3 = D2
    # omega^(j) x Delta^(i) = (-k3^(j) D2^(i), k3^(j) D1^(i), -(k1^(j) D1^(i) + k2^(j) D2^(i)))
    A0 = np.stack([a1, b1, 1.0 - (k1[0] * a0 + k2[0] * b0)])
    A1 = np.stack([a2, b2, -(k1[1] * a0 + k2[1] * b0) - (k1[0] * a1 + k2[0] * b1)])
    A2 = np.stack([a3, b3, -(k1[2] * a0 + k2[2] * b0) - 2.0 * (k1[1] * a1 + k2[1] * b1) - (k1[0] * a2 + k2[0] * b2)])
    if twist:
        k3 = k[2]
        A0[0] -= k3[0] * b0
        A0[1] += k3[0] * a0
        A1[0] -= k3[1] * b0 + k3[0] * b1
        A1[1] += k3[1] * a0 + k3[0] * a1
        A2[0] -= k3[2] * b0 + 2.0 * k3[1] * b1 + k3[0] * b2
        A2[1] += k3[2] * a0 + 2.0 * k3[1] * a1 + k3[0] * a2
    w0 = np.stack([-k2[0], k1[0], k[2, 0]])
    w1 = np.stack([-k2[1], k1[1], k[2, 1]])
    wA0 = _cross(w0, A0)
    r2 = A1 + wA0
    r3 = A2 + _cross(w1, A0) + _cross(w0, 2.0 * A1 + wA0)
    return A0, r2, r3


class CurveJet:
    """A reference curve at points ``S``.

    ``R``: position ``(3, n)``; ``K``: frame ``(3, 3, n)``, ``K[a]`` the global
    components of ``K_{a+1}``; ``k``: curvatures ``(3, 3, n)``, ``k[a, j]`` the
    ``j``-th S-derivative of ``k_{a+1}`` (``k3 = 0`` for a Bishop frame).
    """

    __slots__ = ("R", "K", "k")

    def __init__(self, R, K, k):
        self.R, self.K, self.k = R, K, k

    def to_global(self, v):
        """Global components of a vector given by its frame components ``(3, n)``."""
        return self.K[0] * v[0] + self.K[1] * v[1] + self.K[2] * v[2]


class _Cumulative:
    """``x -> integral from edges[0] to x of f``, by 20-point Gauss-Legendre on each cell (cumulative)."""

    def __init__(self, f: Callable, edges: np.ndarray):
        self.f = f
        self.edges = e = np.asarray(edges, float)
        xi, wi = _GAUSS
        h = np.diff(e)
        nodes = e[:-1, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)
        vals = np.asarray(f(nodes.ravel())).reshape(nodes.shape)
        self.cum = np.concatenate([[0.0], np.cumsum(0.5 * h * (vals @ wi))])

    def __call__(self, x):
        x = np.asarray(x, float)
        xi, wi = _GAUSS
        j = np.clip(np.searchsorted(self.edges, x, side="right") - 1, 0, self.edges.size - 2)
        a = self.edges[j]
        h = x - a
        nodes = a[:, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)
        vals = np.asarray(self.f(nodes.ravel())).reshape(nodes.shape)
        return self.cum[j] + 0.5 * h * (vals @ wi)


def _bishop_curvatures(K, dK3):
    """``k[a, j]`` of a Bishop frame from its vectors ``K`` and ``K3', K3'', K3'''`` (``dK3``, ``(3, 3, n)``).

    ``k_a = K3'.K_a``, ``k_a' = K3''.K_a``, ``k_a'' = K3'''.K_a + k_a |K3'|^2`` (``K_a' = -k_a K3``).
    """
    n = K.shape[-1]
    k = np.zeros((3, 3, n))
    kap2 = _dot(dK3[0], dK3[0])
    for a in range(2):
        k[a, 0] = _dot(dK3[0], K[a])
        k[a, 1] = _dot(dK3[1], K[a])
        k[a, 2] = _dot(dK3[2], K[a]) + k[a, 0] * kap2
    return k


def _rotate_pair(F1, F2, psi):
    c, s = np.cos(psi), np.sin(psi)
    return c * F1 + s * F2, -s * F1 + c * F2


# --------------------------------------------------------------------------
# The interface
# --------------------------------------------------------------------------
class ReferenceCurve:
    """A unit-speed reference curve ``R(S)``, ``S in [0, length]``, with a moving frame.

    Subclasses implement :meth:`jet`. Attributes: ``length`` (the curve's own
    length: the Eulerian domain), ``span`` (what ``stretch = (l - span)/span``
    and ``Gamma = T/(w span)`` are measured on: the chord for curves between
    two points, the axial length for a helix), ``breakpoints`` (``0``, the
    points where the curvature is not smooth, ``length``: a mesh must contain
    them), ``constant_frame`` (True only for :class:`Straight`), ``spec``
    (the command-line form, if any).
    """

    length: float
    span: float
    constant_frame: bool = False
    spec: str = ""

    @property
    def breakpoints(self) -> np.ndarray:
        return np.array([0.0, self.length])

    def jet(self, S) -> CurveJet:  # pragma: no cover - interface
        raise NotImplementedError

    # ---- derived --------------------------------------------------------------
    def frame(self, S):
        """``K1, K2, K3`` at ``S``, each ``(3, len(S))``."""
        K = self.jet(np.atleast_1d(np.asarray(S, float))).K
        return K[0], K[1], K[2]

    def position(self, S) -> np.ndarray:
        return self.jet(np.atleast_1d(np.asarray(S, float))).R

    def centreline_jets(self, S, D1, D2):
        """``r, r', r'', r'''`` (global components, each ``(3, npts)``) of ``r = R + D1 K1 + D2 K2``."""
        j = self.jet(np.atleast_1d(np.asarray(S, float)))
        r1, r2, r3 = frame_jets(j.k, D1, D2)
        r = j.R + j.K[0] * D1[0] + j.K[1] * D2[0]
        return r, j.to_global(r1), j.to_global(r2), j.to_global(r3)

    @property
    def end_twist(self) -> float:
        """The turn ``beta`` of the curve's frame about the end tangent, relative to the start frame carried
        to the end by the minimal rotation taking ``K3(0)`` onto ``K3(length)``.

        ``K1(end) = cos(beta) E1 + sin(beta) E2``, ``E_a`` that carried frame.
        Zero for a planar curve with a Bishop frame; for curves whose ends
        are parallel (``K3(end) = K3(0)``) ``E_a = K_a(0)``: the holonomy of
        the frame. Followed continuously along the curve (defined while
        ``K3(S) != -K3(0)``). The rod model imposes ``phi(end) = Phi - beta``
        so that ``Phi`` is the physical turn of the end clamp relative to the
        start clamp (carried to the end the same way).
        """
        if getattr(self, "_end_twist", None) is None:
            self._end_twist = self._compute_end_twist()
        return self._end_twist

    def _compute_end_twist(self) -> float:
        j0 = self.jet(np.array([0.0]))
        K10, K20, K30 = (j0.K[a][:, 0] for a in range(3))
        b = self.breakpoints
        per = 200
        for _ in range(8):
            S = np.unique(np.concatenate([np.linspace(b[i], b[i + 1], per + 1) for i in range(b.size - 1)]))
            K = self.jet(S).K
            if np.min(1.0 + _dot(_col(K30), K[2])) < 1e-10:
                raise ValueError("the curve's tangent turns to the opposite of its start tangent: "
                                 "the end twist is undefined")
            E1 = minimal_rotation(_col(K30), K[2], _col(K10))
            E2 = minimal_rotation(_col(K30), K[2], _col(K20))
            ang = np.unwrap(np.arctan2(_dot(K[0], E2), _dot(K[0], E1)))
            if np.max(np.abs(np.diff(ang))) < 0.2:
                return float(ang[-1])
            per *= 2
        return float(ang[-1])

    def max_curvature(self, per_piece: int = 400) -> float:
        """Largest curvature ``sqrt(k1^2 + k2^2)`` on a fine grid of each piece between breakpoints."""
        b = self.breakpoints
        S = np.unique(np.concatenate([np.linspace(b[i], b[i + 1], per_piece + 1) for i in range(b.size - 1)]))
        k = self.jet(S).k
        return float(np.max(np.hypot(k[0, 0], k[1, 0])))

    @property
    def curvature_jumps(self) -> np.ndarray:
        """Interior breakpoints where the curvature vector ``(k1, k2)`` jumps (a well's stations).

        There the Eulerian fields are not smooth: the rod's own curvature is
        continuous (no point moment) while the reference's jumps, so ``Delta''``
        jumps by about ``-(jump of k)``; and the sections turn at a rate that
        jumps, so ``s'(S)``, ``Delta'`` (by ``h = 1 - k.Delta``) and ``phi'`` jump
        wherever ``Delta != 0``. The rod model makes them joins of the
        collocation: ``Delta`` and ``phi`` only C^0 there, with the continuity of
        the physical rod as interface conditions (:meth:`rodcont.rod.EulerianRod.interface`).
        """
        b = self.breakpoints[1:-1]
        if b.size == 0:
            return b
        eps = 1e-9 * self.length
        left, right = self.jet(b - eps).k, self.jet(b + eps).k
        scale = np.max(np.abs(np.concatenate([left[:2, 0], right[:2, 0]], axis=1)), initial=0.0) + 1.0 / self.length
        jump = np.max(np.abs(left[:2, 0] - right[:2, 0]), axis=0)
        return b[jump > 1e-6 * scale]

    def one_sided_jet(self, S, side: int) -> CurveJet:
        """The curve just left (``side = -1``) or right (``+1``) of the points ``S``: where the curvature
        jumps, its one-sided limits. Default: :meth:`jet` at ``S -+ 1e-12 length`` (an error of
        ``1e-12 length |k'|``); a piecewise curve overrides it with its pieces' exact limits."""
        S = np.atleast_1d(np.asarray(S, float))
        return self.jet(np.clip(S + side * 1e-12 * self.length, 0.0, self.length))

    def mesh(self, N: int) -> np.ndarray:
        """``N`` subintervals containing every breakpoint (:func:`mesh_through`)."""
        return mesh_through(self.breakpoints, N, "pieces of the reference curve (its breakpoints)")

    def conform(self, mesh: np.ndarray, min_fraction: float = 0.25) -> np.ndarray:
        """``mesh`` with every breakpoint of the curve inserted (:func:`conform_to`)."""
        return conform_to(mesh, self.breakpoints, min_fraction)


def mesh_through(b: np.ndarray, N: int, what: str = "pieces") -> np.ndarray:
    """``N`` subintervals containing every station of ``b`` (its ends included): each piece gets a share
    proportional to its length (at least one), uniform within the piece."""
    b = np.asarray(b, float)
    pieces = b.size - 1
    N = int(N)
    if N < pieces:
        raise ValueError(f"N = {N} subintervals cannot hold the {pieces} {what}: use N >= {pieces}")
    h = np.diff(b)
    share = h / h.sum() * N
    n = np.maximum(np.floor(share).astype(int), 1)
    while n.sum() < N:  # largest remainders first
        n[np.argmax(share - n)] += 1
    while n.sum() > N:
        i = np.argmax(np.where(n > 1, n - share, -np.inf))
        n[i] -= 1
    return np.concatenate([np.linspace(b[i], b[i + 1], n[i] + 1)[:-1] for i in range(pieces)] + [b[-1:]])


def conform_to(mesh: np.ndarray, b: np.ndarray, min_fraction: float = 0.25) -> np.ndarray:
    """``mesh`` with every interior station of ``b`` inserted (mesh points closer to one than
    ``min_fraction`` of the local spacing are dropped): for adapted meshes."""
    m = np.asarray(mesh, float)
    inner = np.asarray(b, float)[1:-1]
    if inner.size == 0:
        return m
    keep = np.ones(m.size, bool)
    h = np.diff(m)
    for s in inner:
        i = int(np.clip(np.searchsorted(m, s) - 1, 0, h.size - 1))
        close = np.abs(m - s) < min_fraction * h[i]
        close[[0, -1]] = False
        keep &= ~close
    return np.union1d(m[keep], inner)


# --------------------------------------------------------------------------
# Straight line
# --------------------------------------------------------------------------
class Straight(ReferenceCurve):
    """``R(S) = origin + S K3`` with constant frame (default ``K1 = e2, K2 = e3, K3 = e1``)."""

    constant_frame = True
    spec = "straight"

    def __init__(self, length: float = 1.0, K1=(0.0, 1.0, 0.0), K2=(0.0, 0.0, 1.0), origin=(0.0, 0.0, 0.0)):
        if isinstance(length, bool) or not isinstance(length, (int, float, np.integer, np.floating)):
            raise TypeError(f"reference length L must be a number, got {length!r}")
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"reference length L must be positive, got {length}")
        self.length = float(length)
        self.span = self.length
        self.K1, self.K2, self.origin = (_vector(name, v) for name, v in (("K1", K1), ("K2", K2), ("origin", origin)))
        self.K3 = np.cross(self.K1, self.K2)
        if not np.allclose([self.K1 @ self.K1, self.K2 @ self.K2, self.K1 @ self.K2], [1, 1, 0], atol=1e-14):
            raise ValueError("K1, K2 must be orthonormal")
        self._end_twist = 0.0

    def jet(self, S) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        n = S.size
        K = np.repeat(np.stack([self.K1, self.K2, self.K3])[:, :, None], n, axis=2)
        return CurveJet(self.origin[:, None] + self.K3[:, None] * S, K, np.zeros((3, 3, n)))

    def centreline_jets(self, S, D1, D2):
        K1, K2, K3 = self.K1[:, None], self.K2[:, None], self.K3[:, None]
        r = self.origin[:, None] + K3 * S + K1 * D1[0] + K2 * D2[0]
        r1 = K3 + K1 * D1[1] + K2 * D2[1]
        r2 = K1 * D1[2] + K2 * D2[2]
        r3 = K1 * D1[3] + K2 * D2[3]
        return r, r1, r2, r3

    def frame(self, S):
        n = np.size(S)
        return tuple(np.repeat(K[:, None], n, axis=1) for K in (self.K1, self.K2, self.K3))


StraightReference = Straight


def _vector(name: str, value) -> np.ndarray:
    """``value`` as a 3-vector of finite floats; a ``TypeError``/``ValueError`` naming ``name`` otherwise."""
    try:
        v = None if isinstance(value, (str, bytes, dict)) else np.asarray(value, float)
    except (TypeError, ValueError):
        v = None
    if v is None:
        raise TypeError(f"{name} must be a 3-vector of numbers, got {value!r}")
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a 3-vector of finite numbers, got {value!r}")
    return v


# --------------------------------------------------------------------------
# Circular arc
# --------------------------------------------------------------------------
class CircularArc(ReferenceCurve):
    """A circular arc of signed ``curvature`` and ``length`` leaving ``origin`` along ``tangent``,
    bending toward ``normal`` (toward ``-normal`` for a negative curvature); Bishop frame.

    Planar, so the Bishop frame is ``K_a = c_a N(S) + b_a B`` with constant
    ``c_a, b_a`` (``N`` the in-plane normal, ``B`` the constant binormal) and
    constant curvatures ``k_a = curvature c_a``.
    """

    def __init__(self, curvature: float, length: float, origin=(0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
                 normal=(0.0, 0.0, 1.0), K1=None, span: float | None = None):
        if not (math.isfinite(curvature) and math.isfinite(length) and length > 0):
            raise ValueError(f"arc: need a finite curvature and a positive length, got {curvature}, {length}")
        self.kappa = float(curvature)
        self.length = float(length)
        self.origin = np.asarray(origin, float)
        self.t = _unit(tangent, "tangent")
        n = np.asarray(normal, float) - (np.asarray(normal, float) @ self.t) * self.t
        self.n = _unit(n, "normal (its part normal to the tangent)")
        self.b = np.cross(self.t, self.n)
        K1_0, K2_0 = start_frame(self.t, K1)
        self.c = np.array([K1_0 @ self.n, K2_0 @ self.n])
        self.bb = np.array([K1_0 @ self.b, K2_0 @ self.b])
        chord = float(np.linalg.norm(self.jet(np.array([self.length])).R[:, 0] - self.origin))
        self.span = chord if span is None else float(span)

    @classmethod
    def spanning(cls, span: float, angle: float, theta: float = math.pi / 2) -> CircularArc:
        """The arc from ``0`` to ``span e1`` whose tangent turns by ``angle`` (radians, ``0 < |angle| < 2 pi``),
        bulging toward ``cos(theta) e2 + sin(theta) e3`` (away from it for a negative angle)."""
        if not (math.isfinite(angle) and 0 < abs(angle) < 2 * math.pi):
            raise ValueError(f"arc: the turning angle must be in (0, 2 pi) in magnitude, got {angle}")
        m = np.array([0.0, math.cos(theta), math.sin(theta)])
        h = 0.5 * angle
        t0 = math.cos(h) * _E1 + math.sin(h) * m
        n0 = math.sin(h) * _E1 - math.cos(h) * m
        kappa = 2.0 * math.sin(h) / span
        return cls(kappa, angle / kappa, tangent=t0, normal=n0, span=float(span))

    def jet(self, S) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        kap = self.kappa
        x = kap * S
        if kap == 0.0:
            sx, cx = S, np.zeros_like(S)
        else:
            sx, cx = np.sin(x) / kap, 2.0 * np.sin(0.5 * x) ** 2 / kap
        t, n, b = _col(self.t), _col(self.n), _col(self.b)
        R = _col(self.origin) + t * sx + n * cx
        K3 = t * np.cos(x) + n * np.sin(x)
        N = -t * np.sin(x) + n * np.cos(x)
        K1 = self.c[0] * N + self.bb[0] * b
        K2 = self.c[1] * N + self.bb[1] * b
        k = np.zeros((3, 3, S.size))
        k[0, 0], k[1, 0] = kap * self.c[0], kap * self.c[1]
        return CurveJet(R, np.stack([K1, K2, K3]), k)


# --------------------------------------------------------------------------
# Helix
# --------------------------------------------------------------------------
class Helix(ReferenceCurve):
    """A circular helix of ``radius`` about an axis along ``axis`` through ``origin - radius * radial``,
    ``turns`` turns (signed: positive right-handed) over the axial length ``span``, starting at ``origin``.

    ``R(t) = origin + c t a + radius ((cos t - 1) u + chi sin t v)``, ``t = S / sqrt(radius^2 + c^2)``,
    ``c = span / (2 pi |turns|)``, ``a = axis``, ``u = radial``, ``v = a x u``, ``chi = sign(turns)``.
    Curvature ``kappa = radius / s^2``, torsion ``tau = chi c / s^2`` (``s^2 = radius^2 + c^2``).
    ``frame="bishop"`` (default): ``K1 = cos(psi) N + sin(psi) B``, ``psi = psi0 - tau S``,
    ``k1 + i k2 = kappa exp(-i psi)``, the start frame by the default rule;
    ``frame="frenet"``: ``K1 = N``, ``K2 = B``, constant ``k = (kappa, 0, tau)``.
    ``span`` is the axial length (the chord for whole turns).
    """

    def __init__(self, radius: float, span: float, turns: float, frame: str = "bishop", origin=(0.0, 0.0, 0.0),
                 axis=(1.0, 0.0, 0.0), radial=(0.0, 1.0, 0.0), K1=None):
        if not (math.isfinite(radius) and radius > 0):
            raise ValueError(f"helix: the radius must be positive, got {radius}")
        if not (math.isfinite(span) and span > 0):
            raise ValueError(f"helix: the axial length must be positive, got {span}")
        if not (math.isfinite(turns) and turns != 0):
            raise ValueError(f"helix: the number of turns must be non-zero, got {turns}")
        if max(radius, span / (2 * math.pi * abs(turns))) > 1e150:  # its squares (curvature, torsion) overflow
            raise ValueError(f"helix: radius {radius:g} with {turns:g} turns over {span:g} is too large to "
                             f"represent (radius and axial length per radian must be below 1e150)")
        if frame not in ("bishop", "frenet"):
            raise ValueError(f"helix: frame must be 'bishop' or 'frenet', got {frame!r}")
        self.radius, self.span, self.turns, self.kind = float(radius), float(span), float(turns), frame
        self.a = _unit(axis, "axis")
        u = np.asarray(radial, float) - (np.asarray(radial, float) @ self.a) * self.a
        self.u = _unit(u, "radial (its part normal to the axis)")
        self.v = np.cross(self.a, self.u)
        self.origin = np.asarray(origin, float)
        self.chi = 1.0 if turns > 0 else -1.0
        self.c = self.span / (2 * math.pi * abs(self.turns))
        self.s = math.hypot(self.radius, self.c)
        self.length = 2 * math.pi * abs(self.turns) * self.s
        self.kappa = self.radius / self.s**2
        self.tau = self.chi * self.c / self.s**2
        self.constant_frame = False
        self.psi0 = 0.0
        if frame == "bishop":
            T0, N0, B0 = self._frenet(np.array([0.0]))
            K10, _ = start_frame(T0[:, 0], K1)
            self.psi0 = math.atan2(K10 @ B0[:, 0], K10 @ N0[:, 0])

    def _frenet(self, S):
        t = S / self.s
        a, u, v = _col(self.a), _col(self.u), _col(self.v)
        ct, st = np.cos(t), np.sin(t)
        chi, c, rho, s = self.chi, self.c, self.radius, self.s
        T = (c * a - rho * st * u + chi * rho * ct * v) / s
        N = -(ct * u + chi * st * v)
        B = (chi * rho * a + chi * c * st * u - c * ct * v) / s
        return T, N, B

    def jet(self, S) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        t = S / self.s
        R = (_col(self.origin) + self.c * t * _col(self.a)
             + self.radius * ((np.cos(t) - 1.0) * _col(self.u) + self.chi * np.sin(t) * _col(self.v)))
        T, N, B = self._frenet(S)
        k = np.zeros((3, 3, S.size))
        kap, tau = self.kappa, self.tau
        if self.kind == "frenet":
            k[0, 0] = kap
            k[2, 0] = tau
            return CurveJet(R, np.stack([N, B, T]), k)
        psi = self.psi0 - tau * S
        K1, K2 = _rotate_pair(N, B, psi)
        c, s = np.cos(psi), np.sin(psi)
        k[0] = kap * np.stack([c, tau * s, -tau**2 * c])
        k[1] = kap * np.stack([-s, tau * c, tau**2 * s])
        return CurveJet(R, np.stack([K1, K2, T]), k)


# --------------------------------------------------------------------------
# Graphs over the span, reparametrised by arclength
# --------------------------------------------------------------------------
class GraphCurve(ReferenceCurve):
    """``X(x) = origin + x e1 + f2(x) e2 + f3(x) e3``, ``x in [0, span]``, reparametrised by its own arclength.

    ``offset(x, nu)`` returns the ``nu``-th x-derivative (``nu = 0..4``) of
    ``(f2, f3)`` as a ``(2, len(x))`` array. The arclength ``sigma(x)`` is
    integrated by composite Gauss-Legendre quadrature and inverted by Newton
    (``x(S)`` exact to rounding); the S-derivatives of ``R`` follow by the
    chain rule (Faa di Bruno) from ``x' = 1/g``, ``g = |X_x|``. Bishop frame:
    the minimal rotation ``F_a`` of ``e2, e3`` taking ``e1`` onto ``K3`` (never
    singular: ``K3.e1 = 1/g > 0``), turned by ``psi`` with
    ``psi' = e1.(K3 x K3') / (1 + e1.K3)`` (``psi(0) = 0``), integrated the same way.
    ``span`` is the chord.
    """

    def __init__(self, span: float, offset: Callable, cells: int = 64, origin=(0.0, 0.0, 0.0)):
        if not (math.isfinite(span) and span > 0):
            raise ValueError(f"the span must be positive, got {span}")
        self.L = float(span)
        self.offset = offset
        self.origin = np.asarray(origin, float)
        edges = np.linspace(0.0, self.L, int(cells) + 1)
        self._sigma = _Cumulative(lambda x: self._g(x), edges)
        self._psi = _Cumulative(lambda x: self._psi_x(x), edges)
        self.length = float(self._sigma(np.array([self.L]))[0])
        X0 = self._X(np.array([0.0]))[0][:, 0]
        XL = self._X(np.array([self.L]))[0][:, 0]
        self.span = float(np.linalg.norm(XL - X0))

    def _X(self, x, order: int = 0):
        """``X`` and its x-derivatives up to ``order``, each ``(3, n)``."""
        out = []
        for nu in range(order + 1):
            f = np.asarray(self.offset(x, nu), float).reshape(2, -1)
            if nu == 0:
                first = x
            elif nu == 1:
                first = np.ones_like(x)
            else:
                first = np.zeros_like(x)
            v = np.stack([first, f[0], f[1]])
            if nu == 0:
                v = v + _col(self.origin)
            out.append(v)
        return out

    def _g(self, x):
        f1 = np.asarray(self.offset(x, 1), float).reshape(2, -1)
        return np.sqrt(1.0 + _dot(f1, f1))

    def _derivs(self, x):
        """``R, R', R'', R''', R''''`` (S-derivatives) at parameters ``x``."""
        X = self._X(x, 4)
        fp, fpp, fppp, fpppp = (v[1:] for v in X[1:])
        P1 = _dot(fp, fpp)
        P2 = _dot(fpp, fpp) + _dot(fp, fppp)
        P3 = 3.0 * _dot(fpp, fppp) + _dot(fp, fpppp)
        g = np.sqrt(1.0 + _dot(fp, fp))
        gx = P1 / g
        gxx = (P2 - gx**2) / g
        gxxx = (P3 - 3.0 * gx * gxx) / g
        x1 = 1.0 / g
        x2 = -gx / g**3
        x3 = -gxx / g**4 + 3.0 * gx**2 / g**5
        x4 = -gxxx / g**5 + 10.0 * gx * gxx / g**6 - 15.0 * gx**3 / g**7
        R1 = X[1] * x1
        R2 = X[2] * x1**2 + X[1] * x2
        R3 = X[3] * x1**3 + 3.0 * X[2] * (x1 * x2) + X[1] * x3
        R4 = X[4] * x1**4 + 6.0 * X[3] * (x1**2 * x2) + X[2] * (3.0 * x2**2 + 4.0 * x1 * x3) + X[1] * x4
        return X[0], R1, R2, R3, R4, g

    def _psi_x(self, x):
        """``d psi / dx = g e1.(K3 x K3') / (1 + e1.K3)``."""
        _, K3, dK3, _, _, g = self._derivs(x)
        return g * (K3[1] * dK3[2] - K3[2] * dK3[1]) / (1.0 + K3[0])

    def x_of_S(self, S) -> np.ndarray:
        """The graph parameter of the point at arclength ``S`` (Newton on ``sigma(x) = S``)."""
        S = np.atleast_1d(np.asarray(S, float))
        e = self._sigma.edges
        x = np.interp(S, self._sigma.cum, e) + 0.0
        for _ in range(12):
            dx = (self._sigma(x) - S) / self._g(x)
            x = x - dx
            if np.max(np.abs(dx), initial=0.0) < 4e-16 * self.L:
                break
        return x

    def jet(self, S) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        x = self.x_of_S(S)
        R, K3, d1, d2, d3, _ = self._derivs(x)
        F1 = minimal_rotation(_col(_E1), K3, _col(_E2))
        F2 = minimal_rotation(_col(_E1), K3, _col(_E3))
        K1, K2 = _rotate_pair(F1, F2, self._psi(x))
        K = np.stack([K1, K2, K3])
        return CurveJet(R, K, _bishop_curvatures(K, np.stack([d1, d2, d3])))


def _sin2(x, nu, a):
    """``nu``-th derivative of ``sin^2(a x) = (1 - cos(2 a x)) / 2``."""
    if nu == 0:
        return np.sin(a * x) ** 2
    return -0.5 * (2 * a) ** nu * np.cos(2 * a * x + 0.5 * nu * math.pi)


class Bump(GraphCurve):
    """The span from ``0`` to ``span e1`` displaced by ``H sin^2(pi x / span)`` along ``cos(theta) e2 + sin(theta) e3``.

    Same end points and end tangents as the straight span, so a rod clamped
    at both ends is the same physical problem; planar, so its end twist is 0.
    """

    def __init__(self, span: float, H: float, theta: float = 0.0, cells: int = 64):
        if not (math.isfinite(H) and math.isfinite(theta)):
            raise ValueError(f"bump: H and THETA must be finite, got {H}, {theta}")
        self.H, self.theta = float(H), float(theta)
        m = np.array([math.cos(theta), math.sin(theta)])
        a = math.pi / span
        super().__init__(span, lambda x, nu: np.outer(m, self.H * _sin2(x, nu, a)), cells=cells)


class Wiggle(GraphCurve):
    """Out of the plane: offset ``H2 sin^2(pi x/span) e2 + H3 (sin(2 pi x/span) - sin(4 pi x/span)/2) e3``.

    Same end points and end tangents as the straight span (both offsets and
    their slopes vanish at the ends). Not planar: its tangent indicatrix
    encloses a solid angle, so its Bishop frame turns between the ends
    (``end_twist`` about ``-2 pi^3 H2 H3 / span^2``, the signed area of the
    slope loop, for small offsets).
    """

    def __init__(self, span: float, H2: float, H3: float, cells: int = 64):
        if not (math.isfinite(H2) and math.isfinite(H3)):
            raise ValueError(f"wiggle: H2 and H3 must be finite, got {H2}, {H3}")
        self.H2, self.H3 = float(H2), float(H3)
        a = math.pi / span
        super().__init__(span, lambda x, nu: np.stack([self.H2 * _sin2(x, nu, a),
                                                       self.H3 * (_sin(x, nu, 2 * a) - 0.5 * _sin(x, nu, 4 * a))]),
                         cells=cells)


def _sin(x, nu, b):
    """``nu``-th derivative of ``sin(b x)``."""
    return b**nu * np.sin(b * x + 0.5 * nu * math.pi)


# --------------------------------------------------------------------------
# Well path: minimum curvature between survey stations
# --------------------------------------------------------------------------
def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


class MinimumCurvatureWell(ReferenceCurve):
    """A well path through survey stations ``(measured depth, inclination, azimuth)`` by minimum curvature.

    Axes: ``e1`` east, ``e2`` north, ``e3`` up (so the default weight ``-e3``
    points down the hole); inclination from the downward vertical, azimuth
    clockwise from north: ``t = (sin I sin A, sin I cos A, -cos I)``. Between
    two stations the path is the circular arc tangent to both station
    directions (dogleg ``beta = 2 asin(|t2 - t1| / 2)``, curvature
    ``beta / dMD``); it passes through the classical minimum-curvature
    positions (ratio factor ``tan(beta/2) / (beta/2)``). ``S = MD - MD_0``.
    The curvature is constant on each arc and jumps at the stations: they are
    the ``breakpoints``. Bishop frame carried exactly across the arcs
    (``K_a = c_a N + b_a B`` on each). ``span``: the chord from the first to
    the last station.
    """

    def __init__(self, stations, origin=(0.0, 0.0, 0.0), degrees: bool = True, K1=None):
        st = np.asarray(stations, float)
        if st.ndim != 2 or st.shape[1] != 3 or st.shape[0] < 2:
            raise ValueError("a well needs at least two survey stations (measured depth, inclination, azimuth)")
        if not np.all(np.isfinite(st)):
            raise ValueError("survey stations must be finite numbers")
        md = st[:, 0]
        if np.any(np.diff(md) <= 0):
            raise ValueError("the measured depths of the survey stations must increase strictly")
        inc, azi = (np.radians(st[:, 1]), np.radians(st[:, 2])) if degrees else (st[:, 1], st[:, 2])
        if np.any(inc < 0) or np.any(inc > math.pi + 1e-12):
            raise ValueError("inclinations must lie between 0 and 180 degrees")
        self.stations = st
        self.md = md
        t = np.stack([np.sin(inc) * np.sin(azi), np.sin(inc) * np.cos(azi), -np.cos(inc)], axis=1)
        t /= np.linalg.norm(t, axis=1)[:, None]
        nseg = st.shape[0] - 1
        self._S0 = md[:-1] - md[0]
        self.length = float(md[-1] - md[0])
        self._t = t[:-1]
        self._n = np.zeros((nseg, 3))
        self._b = np.zeros((nseg, 3))
        self._kappa = np.zeros(nseg)
        self._R0 = np.zeros((nseg, 3))
        self._c = np.zeros((nseg, 2))
        self._bc = np.zeros((nseg, 2))
        self._K0 = np.zeros((nseg, 2, 3))
        R = np.asarray(origin, float).copy()
        Ka = np.stack(start_frame(t[0], K1))
        for i in range(nseg):
            t1, t2, dmd = t[i], t[i + 1], md[i + 1] - md[i]
            chord = float(np.linalg.norm(t2 - t1))
            if chord > 2.0 - 1e-12:
                raise ValueError(f"stations {i} and {i + 1} point in opposite directions: no minimum-curvature arc")
            beta = 2.0 * math.asin(0.5 * chord)
            self._R0[i] = R
            self._K0[i] = Ka
            if beta > 1e-14:
                n = (t2 - math.cos(beta) * t1) / math.sin(beta)
                n /= np.linalg.norm(n)
                kap = beta / dmd
                b = np.cross(t1, n)
                self._n[i], self._b[i], self._kappa[i] = n, b, kap
                self._c[i] = Ka @ n
                self._bc[i] = Ka @ b
                R = R + math.sin(beta) / kap * t1 + 2.0 * math.sin(0.5 * beta) ** 2 / kap * n
                N = math.cos(beta) * n - math.sin(beta) * t1
                Ka = self._c[i][:, None] * N[None, :] + self._bc[i][:, None] * b[None, :]
                Ka[0] /= np.linalg.norm(Ka[0])
                Ka[1] = np.cross(t2, Ka[0])
            else:
                R = R + dmd * t1
        self._end = R
        self.span = float(np.linalg.norm(R - np.asarray(origin, float)))
        if not self.span > 0:
            raise ValueError("the well's first and last stations coincide: no span")

    @classmethod
    def from_file(cls, path: str, **kw) -> MinimumCurvatureWell:
        """Stations from a text file: three columns MD, inclination, azimuth (degrees), separated by
        blanks or commas; ``#`` starts a comment; a first line none of whose fields is a number is a header
        (``0,0,O`` with a letter O is a station with a typo, not a header: taken for one, the survey began at the
        next station, 400 m deeper, silently; test_a_typo_in_the_first_survey_station_is_not_taken_for_a_header)."""
        from .safeio import InputFileError, read_input
        rows = []
        try:  # a regular file of survey size only: a device, a FIFO or a huge file is refused before reading
            text = read_input(path, "survey").decode("utf-8")
        except InputFileError as exc:
            if exc.strerror is not None:
                raise ValueError(f"cannot read the survey file {path!r}: {exc.strerror}") from None
            raise ValueError(f"the survey file {exc}") from None
        except UnicodeDecodeError as exc:
            raise ValueError(f"the survey file {path}: not text (byte {exc.start} is not UTF-8)") from None
        lines = text.splitlines()
        first = True
        for i, line in enumerate(lines):
            line = line.split("#", 1)[0].replace(",", " ").strip()
            if not line:
                continue
            header, first = first and not any(_is_number(v) for v in line.split()), False
            if header:
                continue
            try:
                vals = [float(v) for v in line.split()]
            except ValueError:
                raise ValueError(f"{path}, line {i + 1}: not three numbers: {line!r}") from None
            if len(vals) != 3:
                raise ValueError(f"{path}, line {i + 1}: expected MD, inclination, azimuth, got {len(vals)} values")
            rows.append(vals)
        well = cls(np.array(rows), **kw)
        well.source = os.path.abspath(path)  # an input of every command that uses it (rodcont.safeio)
        return well

    @property
    def breakpoints(self) -> np.ndarray:
        return self.md - self.md[0]

    def jet(self, S) -> CurveJet:
        return self._jet(S, "right")

    def one_sided_jet(self, S, side: int) -> CurveJet:
        """Exact one-sided limits: a station belongs to the arc before it (``side = -1``) or after it."""
        return self._jet(S, "left" if side < 0 else "right")

    def _jet(self, S, station_side: str) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        i = np.clip(np.searchsorted(self._S0, S, side=station_side) - 1, 0, self._S0.size - 1)
        sig = S - self._S0[i]
        kap = self._kappa[i]
        t, n, b = self._t[i].T, self._n[i].T, self._b[i].T
        curved = kap > 0
        safe = np.where(curved, kap, 1.0)
        x = kap * sig
        sx = np.where(curved, np.sin(x) / safe, sig)
        cx = np.where(curved, 2.0 * np.sin(0.5 * x) ** 2 / safe, 0.0)
        R = self._R0[i].T + t * sx + n * cx
        K3 = t * np.cos(x) + n * np.sin(x)
        N = -t * np.sin(x) + n * np.cos(x)
        K = np.empty((3, 3, S.size))
        K[2] = K3
        k = np.zeros((3, 3, S.size))
        for a in range(2):
            bent = self._c[i, a] * N + self._bc[i, a] * b
            K[a] = np.where(curved, bent, self._K0[i, a].T)
            k[a, 0] = kap * self._c[i, a]
        return CurveJet(R, K, k)


# --------------------------------------------------------------------------
# A user curve
# --------------------------------------------------------------------------
class UserCurve(ReferenceCurve):
    """Any unit-speed curve given by callables.

    ``position(S)`` returns ``R, R', R'', R''', R''''`` as an array
    ``(5, 3, len(S))`` (``S`` the arclength: ``|R'| = 1``, checked).
    ``frame(S)`` (optional) returns ``K1, K1', K1'', K1'''`` as ``(4, 3, len(S))``
    (``K1`` unit and normal to ``R'``; ``K2 = K3 x K1``; any twist ``k3`` is
    allowed). Without it the Bishop frame is built from ``K1_start`` (default:
    the minimal rotation of ``e2`` from ``e1`` onto ``R'(0)``) by integrating
    its turn relative to the minimal rotation from ``K3(0)`` (singular if the
    tangent turns to ``-K3(0)``). ``breakpoints``: interior points where the
    curve is not smooth (a mesh must contain them); ``span`` defaults to the chord.
    """

    def __init__(self, length: float, position: Callable, frame: Callable | None = None, span: float | None = None,
                 breakpoints=(), K1_start=None, cells_per_piece: int = 32):
        if not (math.isfinite(length) and length > 0):
            raise ValueError(f"the curve length must be positive, got {length}")
        self.length = float(length)
        self._position = position
        self._frame = frame
        inner = np.asarray(breakpoints, float).ravel()
        if inner.size and (np.any(inner <= 0) or np.any(inner >= self.length) or np.any(np.diff(inner) <= 0)):
            raise ValueError("breakpoints must increase strictly inside (0, length)")
        self._breaks = np.concatenate([[0.0], inner, [self.length]])
        Sc = np.unique(np.concatenate([np.linspace(self._breaks[i], self._breaks[i + 1], 9)
                                       for i in range(self._breaks.size - 1)]))
        P = self._derivs(Sc)
        speed = np.sqrt(_dot(P[1], P[1]))
        if np.max(np.abs(speed - 1.0)) > 1e-8:
            raise ValueError(f"the curve must be parametrised by arclength: |R'| - 1 reaches "
                             f"{np.max(np.abs(speed - 1.0)):.2e}")
        if frame is not None:
            Kf = self._frames(Sc)
            if np.max(np.abs(_dot(Kf[0], Kf[0]) - 1.0)) > 1e-8 or np.max(np.abs(_dot(Kf[0], P[1]))) > 1e-8:
                raise ValueError("frame: K1 must be a unit vector normal to the tangent R'")
        else:
            K3_0 = P[1][:, 0]
            self._pole = K3_0
            self._E = start_frame(K3_0, K1_start)
            edges = np.unique(np.concatenate([np.linspace(self._breaks[i], self._breaks[i + 1], cells_per_piece + 1)
                                              for i in range(self._breaks.size - 1)]))
            self._psi = _Cumulative(self._psi_S, edges)
        R0, RL = self._derivs(np.array([0.0, self.length]))[0].T
        self.span = float(np.linalg.norm(RL - R0)) if span is None else float(span)
        if not self.span > 0:
            raise ValueError("the span must be positive")

    @property
    def breakpoints(self) -> np.ndarray:
        return self._breaks

    def _derivs(self, S):
        P = np.asarray(self._position(S), float)
        if P.shape != (5, 3, S.size):
            raise ValueError(f"position(S) must return an array (5, 3, len(S)) (R and 4 derivatives), got {P.shape}")
        return P

    def _frames(self, S):
        Kf = np.asarray(self._frame(S), float)
        if Kf.shape != (4, 3, S.size):
            raise ValueError(f"frame(S) must return an array (4, 3, len(S)) (K1 and 3 derivatives), got {Kf.shape}")
        return Kf

    def _psi_S(self, S):
        P = self._derivs(S)
        K3, dK3 = P[1], P[2]
        p = _col(self._pole)
        den = 1.0 + _dot(p, K3)
        if np.min(den) < 1e-10:
            raise ValueError("the tangent turns to the opposite of its start: give a frame")
        return _dot(p, _cross(K3, dK3)) / den

    def jet(self, S) -> CurveJet:
        S = np.atleast_1d(np.asarray(S, float))
        P = self._derivs(S)
        R, K3 = P[0], P[1]
        if self._frame is None:
            p = _col(self._pole)
            F1 = minimal_rotation(p, K3, _col(self._E[0]))
            F2 = minimal_rotation(p, K3, _col(self._E[1]))
            K1, K2 = _rotate_pair(F1, F2, self._psi(S))
            K = np.stack([K1, K2, K3])
            return CurveJet(R, K, _bishop_curvatures(K, P[2:5]))
        Kf = self._frames(S)
        T = P[1:5]  # K3 and three derivatives
        A = Kf      # K1 and three derivatives
        B = [_cross(T[0], A[0]),
             _cross(T[1], A[0]) + _cross(T[0], A[1]),
             _cross(T[2], A[0]) + 2.0 * _cross(T[1], A[1]) + _cross(T[0], A[2]),
             _cross(T[3], A[0]) + 3.0 * _cross(T[2], A[1]) + 3.0 * _cross(T[1], A[2]) + _cross(T[0], A[3])]
        k = np.empty((3, 3, S.size))
        for a, V in enumerate((A, B)):  # k_a = K3'.K_a and derivatives (Leibniz)
            k[a, 0] = _dot(T[1], V[0])
            k[a, 1] = _dot(T[2], V[0]) + _dot(T[1], V[1])
            k[a, 2] = _dot(T[3], V[0]) + 2.0 * _dot(T[2], V[1]) + _dot(T[1], V[2])
        k[2, 0] = _dot(A[1], B[0])  # k3 = K1'.K2
        k[2, 1] = _dot(A[2], B[0]) + _dot(A[1], B[1])
        k[2, 2] = _dot(A[3], B[0]) + 2.0 * _dot(A[2], B[1]) + _dot(A[1], B[2])
        return CurveJet(R, np.stack([A[0], B[0], K3]), k)


# --------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------
REFERENCE_KINDS = """\
straight            the span 0 .. L e1 (default)
bump:H,THETA        the span displaced by H sin^2(pi x/L) along cos(THETA) e2 + sin(THETA) e3
                    (same ends and end tangents: the same clamped problem)
wiggle:H2,H3        H2 sin^2(pi x/L) e2 + H3 (sin(2 pi x/L) - sin(4 pi x/L)/2) e3 (same ends and
                    end tangents, not planar: its frame turns between the ends)
arc:ANGLE,THETA     circular arc from 0 to L e1 turning its tangent by ANGLE (radians),
                    bulging toward cos(THETA) e2 + sin(THETA) e3 (THETA default pi/2)
helix:RADIUS,TURNS  helix about e1 from 0, TURNS turns (negative: left-handed) over the axial length L
well:FILE           minimum-curvature well path through the survey stations of FILE (MD, INC, AZI in
                    degrees; e1 east, e2 north, e3 up); its span is the chord between the end stations"""


def _numbers(kind: str, args: str, names: tuple, defaults: tuple = ()) -> list[float]:
    parts = [a.strip() for a in args.split(",")] if args.strip() else []
    need = len(names) - len(defaults)
    if not need <= len(parts) <= len(names):
        want = ",".join(names)
        raise ValueError(f"--reference {kind}: expected {kind}:{want}, got {len(parts)} value(s)")
    vals = []
    for name, text in zip(names, parts):
        try:
            v = float(text)
        except ValueError:
            raise ValueError(f"--reference {kind}: {name} must be a number, got {text!r}") from None
        if not math.isfinite(v):
            raise ValueError(f"--reference {kind}: {name} must be finite, got {text!r}")
        vals.append(v)
    return vals + list(defaults[len(parts) - need:])


def parse_reference(spec: str, L: float) -> ReferenceCurve:
    """The reference curve of a ``--reference KIND[:ARGS]`` specification, for the span ``L``.

    Kinds: see :data:`REFERENCE_KINDS`. Raises ``ValueError`` with a one-line
    message for a bad specification. Every kind but ``well`` has span ``L``;
    a well's span is its chord (the rod's ``L`` must then be set to it).
    """
    if not isinstance(spec, str):
        raise ValueError(f"--reference must be a string, got {spec!r}")
    if not (isinstance(L, (int, float, np.integer, np.floating)) and math.isfinite(L) and L > 0):
        raise ValueError(f"the span L must be a positive number, got {L!r}")
    L = float(L)
    kind, _, args = spec.strip().partition(":")
    kind = kind.strip().lower()
    try:
        if kind == "straight":
            if args.strip():
                raise ValueError("--reference straight takes no arguments")
            curve = Straight(L)
        elif kind == "bump":
            H, theta = _numbers(kind, args, ("H", "THETA"))
            curve = Straight(L) if H == 0 else Bump(L, H, theta)
        elif kind == "wiggle":
            H2, H3 = _numbers(kind, args, ("H2", "H3"))
            curve = Straight(L) if H2 == 0 and H3 == 0 else Wiggle(L, H2, H3)
        elif kind == "arc":
            angle, theta = _numbers(kind, args, ("ANGLE", "THETA"), (math.pi / 2,))
            curve = Straight(L) if angle == 0 else CircularArc.spanning(L, angle, theta)
        elif kind == "helix":
            radius, turns = _numbers(kind, args, ("RADIUS", "TURNS"))
            curve = Helix(radius, L, turns)
        elif kind == "well":
            if not args.strip():
                raise ValueError("--reference well: expected well:FILE")
            curve = MinimumCurvatureWell.from_file(args.strip())
        else:
            raise ValueError(f"--reference: unknown kind {kind!r}; known: straight, bump, wiggle, arc, helix, well")
    except ValueError as exc:
        msg = str(exc).splitlines()[0] if str(exc) else "bad specification"
        if not msg.startswith("--reference"):
            msg = f"--reference {spec}: {msg}"
        raise ValueError(msg) from None
    curve.spec = spec.strip()
    return curve
