"""Spline collocation at Gauss points for mixed-order boundary value problems.

The problem (knows nothing of rods) is a system of ``n`` ODEs for ``n``
unknown fields ``u_i(S)``, field ``i`` of order ``m_i``::

    G(S, z(S), p) = 0,      S in [a, b]             (n equations)
    g(z(a), z(b), p) = 0                             (sum m_i + n_free conditions)

with the local jet ``z = (u_0, u_0', ..., u_0^(m_0), u_1, ..., u_{n-1}^(m_{n-1}))``.
Following Ascher, Christiansen & Russell (1979), field ``i`` is sought in
``P_{k+m_i} ∩ C^{m_i-1}`` on a partition of ``N`` subintervals
(:mod:`rodcont.bspline`), dimension ``N k + m_i``. The ``n k N`` collocation
equations at the ``k`` Gauss-Legendre points of each subinterval plus the
boundary conditions close the system for the B-spline coefficients (and the
free scalar parameters, if any).

Jacobian (the tangent operator). At a collocation point ``G`` depends only on
the local jet, so with ``B_j`` the matrices evaluating the ``j``-th
derivative of each basis function at the collocation points::

    dG/dc = sum_j D_j B_j,    D_j = blockdiag_q(dG/dz_j at S_q)

The pointwise derivatives ``dG/dz`` are obtained by the complex step
``Im G(z + i h e_j) / h`` with ``h = 1e-30`` (exact to rounding for analytic
``G``), all jet components and all points in one vectorised call; its real
part is ``G`` itself (a problem may supply its own exact ``jacobian`` instead,
see :class:`BVProblem`). Which jet components and parameters the residual uses
is *declared* by the problem (default: all of them), never guessed from
samples: a sampled probe misses a term that vanishes where it looked (a
switching term, a contact force). The boundary conditions are differentiated
with respect to every jet component at both ends. The sparsity pattern and
the map from the pointwise blocks to CSC storage are computed once per
discretisation.

Block pattern (rows: the conditions ordered along the span; columns: the
coefficients of all fields interleaved by the position of their support, then
free parameters)::

    [xxxx.........]   boundary conditions at a
    [xxxxxx.......]   point 0      (n rows each)
    [.xxxxxx......]   point 1
    ...
    [.........xxxx]   boundary conditions at b

Joins (optional). A problem may declare interior points ``S_J`` (``joins``)
where field ``i`` is only ``C^(c_i)`` (``join_continuity``, ``c_i <= m_i - 1``)
and interface conditions ``h(z(S_J-), z(S_J+), p, S_J) = 0`` hold, ``z(S_J-)``,
``z(S_J+)`` the one-sided jets. Each join is a breakpoint of every mesh; its
knots are repeated ``k + m_i - 1 - c_i`` times, so it adds
``sum(m_i - 1 - c_i)`` coefficients, as many as the interface conditions.
Their rows read the basis functions nonzero on the two subintervals that meet
there (and the free parameters): declared, not sampled. The derivatives come
from one complex-step call over all joins and both one-sided jets. A point
evaluated exactly at a join belongs to its right subinterval (as everywhere).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .bspline import SplineSpace, gauss_points, locate
from .linalg import NewtonResult, canonical_csc, csc_with_data, newton_solve

COMPLEX_STEP = 1e-30
POINT_BLOCK = 1024  # collocation points per complex-step call


def uniform_mesh(a: float, b: float, N: int) -> np.ndarray:
    return np.linspace(a, b, int(N) + 1)


# --------------------------------------------------------------------------
# Problem protocol
# --------------------------------------------------------------------------
@dataclass
class BVProblem:
    """A mixed-order BVP in the form the collocation core solves.

    ``residual(S, z, p) -> (n, npts)``: the ODEs at points ``S`` given the jets
    ``z`` (``(sum(m_i + 1), npts)``, see module docstring) and parameters ``p``.
    ``bc(za, zb, p) -> (sum(m_i) + len(free),)``: the boundary conditions, with
    ``za, zb`` the jets at the two ends; it must broadcast over a trailing
    batch axis of ``za, zb``. Both must be written with analytic operations
    only (``sqrt(v.v)``, never ``abs``) so the complex step is exact.
    ``free``: indices into ``p`` that are unknowns (solved for) rather than data.
    ``params``: names of the entries of ``p``.
    ``jet_dependence``: the jet components the residual depends on (default:
    all); ``residual_params``: the parameters it depends on (default: all).
    Declaring fewer saves work; a wrong declaration gives a wrong Jacobian,
    which ``tests`` check against the complex step of everything.
    ``joins``, ``join_continuity``, ``interface`` (optional, see the module
    docstring): interior points ``S_J``, the continuity ``c_i`` of each field
    there, and ``interface(zl, zr, p, S) -> (sum(m_i - 1 - c_i), nb)`` with
    ``zl, zr`` one-sided jets ``(jet_size, nb)`` and ``S`` ``(nb,)`` their
    joins (it must broadcast over that batch axis, analytic operations only).
    ``jacobian`` (optional): ``jacobian(S, z, p) -> (G, dG)``, the residual and
    its exact derivatives with respect to the declared jet components
    (``(n, na, npts)``, components in increasing order), for a problem that
    can compute them more cheaply than the complex step of ``residual``
    (which is used when it is absent). It must agree with that complex step
    to rounding (the problem's own tests check it).
    ``affine_bc``: the boundary conditions are affine in the end jets and the
    parameters, so their derivatives are constant: computed once per
    discretisation instead of at every linearisation (a wrong declaration
    gives a wrong Jacobian).
    ``integrals`` (optional): ``integrals(S, z, p) -> (n_int, npts)``, the
    integrands of the conditions ``int_a^b q_j(S, z(S), p) dS = 0`` (module
    docstring); analytic operations only. With them ``bc`` returns
    ``sum(m_i) + len(free) - n_int`` conditions. ``integral_dependence``: the
    jet components the integrands depend on (default: all).
    """

    orders: Sequence[int]
    residual: Callable
    bc: Callable
    interval: tuple[float, float]
    params: Sequence[str] = ()
    free: Sequence[int] = ()
    names: Sequence[str] | None = None
    jet_dependence: Sequence[int] | None = None
    residual_params: Sequence[int] | None = None
    jacobian: Callable | None = None
    affine_bc: bool = False
    joins: Sequence[float] = ()
    join_continuity: Sequence[int] | None = None
    interface: Callable | None = None
    integrals: Callable | None = None
    integral_dependence: Sequence[int] | None = None

    @property
    def n_fields(self) -> int:
        return len(self.orders)

    @property
    def jet_size(self) -> int:
        return int(sum(m + 1 for m in self.orders))

    def param_index(self, name: str | int) -> int:
        if isinstance(name, (int, np.integer)):
            return int(name)
        try:
            return list(self.params).index(name)
        except ValueError:
            raise KeyError(f"unknown parameter {name!r}; known: {', '.join(self.params)}") from None


# --------------------------------------------------------------------------
# Discretisation
# --------------------------------------------------------------------------
class Collocation:
    """Gauss collocation of a :class:`BVProblem` on B-spline spaces.

    Unknown vector ``x``: the B-spline coefficients of all fields, interleaved
    by the position of their support along ``[a, b]`` (so that the Jacobian is
    banded and a natural-order sparse LU makes little fill), then the free
    parameters. ``coefficients(x, i)`` returns field ``i``'s coefficients.
    The residual vector lists the conditions in the same along-the-span order.
    """

    def __init__(self, problem: BVProblem, breakpoints: np.ndarray | int, k: int = 5):
        if isinstance(breakpoints, (int, np.integer)) and not isinstance(breakpoints, bool):
            if breakpoints < 1:
                raise ValueError(f"N (number of subintervals) must be >= 1, got {breakpoints}")
            breakpoints = uniform_mesh(*problem.interval, breakpoints)
        b = np.asarray(breakpoints, dtype=float)
        if b.ndim != 1 or b.size < 2 or not np.all(np.isfinite(b)) or np.any(np.diff(b) <= 0):
            raise ValueError("breakpoints must be a strictly increasing sequence of at least 2 finite values")
        if isinstance(k, bool) or not (isinstance(k, (int, np.integer)) and 1 <= k <= 7):
            raise ValueError(f"k (Gauss points per subinterval) must be an integer in 1..7, got {k!r}")
        self.problem = pb = problem
        self.breakpoints = b
        self.k = k = int(k)
        self.N = N = b.size - 1
        self._setup_joins(b)
        # one space per (order, extra multiplicity at the joins): fields that share it share its bases
        keys = [(m, int(e)) for m, e in zip(pb.orders, self.join_extra)]
        spaces = {}
        for m, e in sorted(set(keys)):
            extra = np.zeros(N - 1, int)
            extra[self.join_at - 1] = e
            spaces[(m, e)] = SplineSpace(b, k, m, extra)
        self.spaces = [spaces[key] for key in keys]
        self.n_free = len(pb.free)
        n_coef = int(sum(s.dim for s in self.spaces))
        self.size = n_coef + self.n_free
        self.S, self.weights = gauss_points(b, k)
        self.npts = npts = self.S.size
        n, nz = pb.n_fields, pb.jet_size
        self.jet_rows = np.concatenate([[0], np.cumsum([m + 1 for m in pb.orders])])
        self.n_int = self._count_integrals()
        self.n_bc = self.size - n * npts - self.n_interface - self.n_int
        if self.n_bc < 0:
            if self.n_int:
                raise ValueError(f"{self.n_int} integral conditions, but the orders and the free parameters "
                                 f"allow {self.n_bc + self.n_int} conditions in all (boundary + integral = "
                                 f"sum of orders + free parameters): free one parameter per extra condition")
            raise ValueError("more collocation equations than unknowns")
        self.active = np.arange(nz) if pb.jet_dependence is None else np.unique(np.asarray(pb.jet_dependence, int))
        self.int_active = (np.arange(nz) if pb.integral_dependence is None
                           else np.unique(np.asarray(pb.integral_dependence, int)))
        npar = max(len(pb.params), 1)
        self.param_in_residual = np.ones(npar, bool)
        if pb.residual_params is not None:
            self.param_in_residual[:] = False
            self.param_in_residual[list(pb.residual_params)] = True

        # Interleave the coefficients of all fields by the centre of their support.
        centre = np.concatenate([0.5 * (s.knots[:s.dim] + s.knots[s.order:]) for s in self.spaces])
        field_of = np.concatenate([np.full(s.dim, i) for i, s in enumerate(self.spaces)])
        order = np.lexsort((field_of, centre))
        position = np.empty(n_coef, int)
        position[order] = np.arange(n_coef)
        starts = np.concatenate([[0], np.cumsum([s.dim for s in self.spaces])])
        self.index = [position[starts[i]:starts[i + 1]] for i in range(n)]
        self.free_index = np.arange(n_coef, self.size)

        # Local bases at the collocation points: values of the k + m_i basis functions
        # nonzero at each point, for every derivative up to the field's order.
        interval = np.repeat(np.arange(N), k)
        local = {key: spaces[key].local(self.S, key[0], interval) for key in spaces}
        widths = [k + m for m in pb.orders]
        wstart = np.concatenate([[0], np.cumsum(widths)])
        cols = np.empty((npts, wstart[-1]), int)
        for i, m in enumerate(pb.orders):
            cols[:, wstart[i]:wstart[i + 1]] = self.index[i][local[keys[i]][1][:, None] + np.arange(k + m)[None, :]]
        self._local_cols_all = cols
        self._local_active = self._local_bases(local, keys, wstart, self.active)
        # the integral rows: Gauss weight times the bases of the integrands' components
        self._local_integral = (self._local_bases(local, keys, wstart, self.int_active) * self.weights[:, None, None]
                                if self.n_int else None)
        # Jets at the collocation points: z = E @ x (row j * npts + q), field by field (a dense block of all
        # the fields' bases held mostly zeros: 56 MB and a second at N = 2000)
        rows, ecols, vals = [], [], []
        for i, m in enumerate(pb.orders):
            v = local[keys[i]][0]
            nonzero = v != 0
            jet_row = (self.jet_rows[i] + np.arange(m + 1))[:, None, None] * npts + np.arange(npts)[None, :, None]
            rows.append(np.broadcast_to(jet_row, v.shape)[nonzero])
            ecols.append(np.broadcast_to(cols[None, :, wstart[i]:wstart[i + 1]], v.shape)[nonzero])
            vals.append(v[nonzero])
        self.E = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(ecols))),
                               shape=(nz * npts, self.size))
        # Jets at the two ends: small dense blocks on the columns of the basis functions nonzero there.
        self.end_cols, self.end_E = [], []
        at_ends = {key: spaces[key].local(b[[0, -1]], key[0], np.array([0, N - 1])) for key in spaces}
        for side in (0, 1):
            ecols, blocks = [], []
            for i, m in enumerate(pb.orders):
                vals, first = at_ends[keys[i]]
                ecols.append(self.index[i][first[side] + np.arange(k + m)])
                blk = np.zeros((nz, k + m))
                blk[self.jet_rows[i]:self.jet_rows[i + 1]] = vals[:, side, :]
                blocks.append(blk)
            self.end_cols.append(np.concatenate(ecols))
            self.end_E.append(np.concatenate(blocks, axis=1))  # (nz, ncols_end)
        self._interface_bases()
        self._check_bc_count()
        self._build_pattern()

    def _local_bases(self, local: dict, keys: list, wstart: np.ndarray, components: np.ndarray) -> np.ndarray:
        """``(npts, len(components), width)``: at each collocation point, the jet components' values on the
        ``k + m_i`` basis functions of their field (zero on the other fields' columns)."""
        out = np.zeros((self.npts, components.size, wstart[-1]))
        for i, m in enumerate(self.problem.orders):
            lo, hi = self.jet_rows[i], self.jet_rows[i + 1]
            at = np.flatnonzero((components >= lo) & (components < hi))
            if at.size:
                out[:, at, wstart[i]:wstart[i + 1]] = local[keys[i]][0][components[at] - lo].transpose(1, 0, 2)
        return out

    # ---- joins -------------------------------------------------------------
    def _setup_joins(self, b: np.ndarray) -> None:
        """``join_at``: the breakpoint index of each join; ``join_extra``: the knots each field gains there."""
        pb = self.problem
        S = np.unique(np.asarray(pb.joins, float))
        self.joins = S
        self.join_extra = np.zeros(pb.n_fields, int)
        self.join_at = np.zeros(0, int)
        self.n_interface = 0
        if S.size == 0:
            return
        if pb.interface is None or pb.join_continuity is None or len(pb.join_continuity) != pb.n_fields:
            raise ValueError("joins need an interface function and a join_continuity for every field")
        c = np.asarray(pb.join_continuity, int)
        m = np.asarray(pb.orders, int)
        if np.any(c < 0) or np.any(c > m - 1):
            raise ValueError(f"join_continuity must lie in 0 .. order - 1 for each field, got {list(c)}")
        tol = 1e-12 * (b[-1] - b[0])
        at = np.clip(np.searchsorted(b, S), 1, b.size - 2)
        at = np.where((at > 1) & (np.abs(b[at - 1] - S) < np.abs(b[at] - S)), at - 1, at)
        if np.any(S <= b[0] + tol) or np.any(S >= b[-1] - tol) or np.any(np.abs(b[at] - S) > tol):
            missing = [f"{v:.10g}" for v in S[np.abs(b[at] - S) > tol]]
            raise ValueError(f"every join must be an interior breakpoint of the mesh: missing "
                             f"{', '.join(missing[:4]) or 'an end'}{', ...' if len(missing) > 4 else ''}")
        self.join_at = at = np.unique(at)  # two joins within rounding of one breakpoint are one join
        self.joins = b[at]  # the breakpoint itself, not a value within rounding of it
        self.join_extra = m - 1 - c
        self.n_interface = int(self.join_extra.sum()) * at.size

    def _interface_bases(self) -> None:
        """One-sided jets at the joins: ``z(S_J-) = EL[J] @ x[IC[J]]``, ``z(S_J+) = ER[J] @ x[IC[J]]``,
        ``IC[J]`` the columns of the basis functions nonzero on either subinterval at the join."""
        nj, nz, k = self.join_at.size, self.problem.jet_size, self.k
        if nj == 0:
            return
        cols, EL, ER = [], [], []
        for i, (m, sp_i) in enumerate(zip(self.problem.orders, self.spaces)):
            w = 2 * k + m + int(self.join_extra[i])  # left functions, then the right ones (overlap c_i + 1)
            vl, fl = sp_i.local(self.joins, m, self.join_at - 1)
            vr, fr = sp_i.local(self.joins, m, self.join_at)
            assert np.all(fr - fl == w - k - m), "the right subinterval's functions start k + e further"
            cols.append(self.index[i][fl[:, None] + np.arange(w)[None, :]])
            rows = slice(self.jet_rows[i], self.jet_rows[i + 1])
            for vals, off, out in ((vl, 0, EL), (vr, w - k - m, ER)):
                blk = np.zeros((nj, nz, w))
                blk[:, rows, off:off + k + m] = vals.transpose(1, 0, 2)
                out.append(blk)
        self.iface_cols = np.concatenate(cols, axis=1)      # (nj, width)
        self.iface_EL = np.concatenate(EL, axis=2)          # (nj, nz, width)
        self.iface_ER = np.concatenate(ER, axis=2)

    def interface_jets(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The one-sided jets ``(jet_size, n_joins)`` left and right of the joins."""
        c = x[self.iface_cols]
        return np.einsum("jzc,jc->zj", self.iface_EL, c), np.einsum("jzc,jc->zj", self.iface_ER, c)

    def _interface_residual(self, x: np.ndarray, pf: np.ndarray) -> np.ndarray:
        """Interface conditions, join after join (natural order)."""
        if not self.n_interface:
            return np.zeros(0)
        zl, zr = self.interface_jets(x)
        h = np.asarray(self.problem.interface(zl, zr, pf, self.joins))
        per = self.n_interface // self.joins.size
        if h.shape != (per, self.joins.size):
            raise ValueError(f"interface must return {per} conditions per join (the continuity given up), "
                             f"got shape {h.shape}")
        return h.T.ravel()

    def _interface_dp(self, x: np.ndarray, pc: np.ndarray) -> np.ndarray:
        """Imaginary part of the interface conditions at the complex-stepped parameters ``pc``, over the step."""
        if not self.n_interface:
            return np.zeros(0)
        zl, zr = self.interface_jets(x)
        h = np.asarray(self.problem.interface(zl.astype(complex), zr.astype(complex), pc, self.joins))
        return h.T.ravel().imag / COMPLEX_STEP

    def _interface_jacobian(self, x: np.ndarray, pf: np.ndarray):
        """``h`` (natural order) and ``dh/dx`` as ``(n_joins, per, width)`` on the columns ``iface_cols``.

        One complex-step call: every join, unperturbed and with each of the ``2 jet_size`` one-sided
        jet components stepped (``h`` depends on nothing else of ``x``)."""
        zl, zr = self.interface_jets(x)
        nz, nj = zl.shape
        nb = 2 * nz + 1
        Z = np.repeat(np.concatenate([zl, zr]).astype(complex)[:, :, None], nb, axis=2)  # (2nz, nj, nb)
        Z[np.arange(2 * nz), :, np.arange(1, nb)] += 1j * COMPLEX_STEP
        Z = Z.reshape(2 * nz, nj * nb)
        h = np.asarray(self.problem.interface(Z[:nz], Z[nz:], pf, np.repeat(self.joins, nb)))
        per = self.n_interface // nj
        if h.shape != (per, nj * nb):
            raise ValueError(f"interface must return {per} conditions per join (the continuity given up), "
                             f"got shape {h.shape[:1]}")
        h = h.reshape(per, nj, nb)
        dh = h[:, :, 1:].imag / COMPLEX_STEP                  # (per, nj, 2 nz)
        dl, dr = dh[:, :, :nz].transpose(1, 0, 2), dh[:, :, nz:].transpose(1, 0, 2)
        dx = np.matmul(dl, self.iface_EL) + np.matmul(dr, self.iface_ER)  # (nj, per, width)
        return h[:, :, 0].real.T.ravel(), dx

    # ---- integral conditions ---------------------------------------------------
    def _count_integrals(self) -> int:
        """``n_int``: the integrands' count, from one evaluation at unit jets (it is structural)."""
        pb = self.problem
        if pb.integrals is None:
            return 0
        with np.errstate(all="ignore"):
            q = np.asarray(pb.integrals(self.S, np.ones((pb.jet_size, self.npts)), np.ones(max(len(pb.params), 1))))
        if q.ndim != 2 or q.shape[1] != self.npts or q.shape[0] < 1:
            raise ValueError(f"integrals must return an array (number of integral conditions, number of points), "
                             f"got shape {q.shape} at {self.npts} points")
        return int(q.shape[0])

    def _integrands(self, S, z, p) -> np.ndarray:
        q = np.asarray(self.problem.integrals(S, z, p))
        if q.shape != (self.n_int, S.size):
            raise ValueError(f"integrals must return {self.n_int} integrands at each of the {S.size} points, "
                             f"got shape {q.shape}")
        return q

    def _integral_residual(self, x: np.ndarray, pf: np.ndarray) -> np.ndarray:
        """``I_j = sum_q w_q q_j(S_q, z_q, p)`` (natural order)."""
        if not self.n_int:
            return np.zeros(0)
        return self._integrands(self.S, self.jets(x), pf) @ self.weights

    def _integral_dp(self, z: np.ndarray, pc: np.ndarray) -> np.ndarray:
        """``dI/dp_j`` from the integrands at the complex-stepped parameters ``pc``."""
        if not self.n_int:
            return np.zeros(0)
        return (self._integrands(self.S, z.astype(complex), pc).imag / COMPLEX_STEP) @ self.weights

    def _integral_jacobian(self, z: np.ndarray, pf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``I`` and ``dI/dc`` as dense ``(n_int, size)`` rows (the free-parameter columns left zero):
        one complex-step call over all points and the declared components."""
        q, dq = self._complex_step(self._integrands, self.S, z, pf, self.int_active, self.n_int)
        contrib = np.einsum("jaq,qac->jqc", dq, self._local_integral)  # (n_int, npts, width)
        flat = (np.arange(self.n_int)[:, None, None] * self.size + self._local_cols_all[None]).ravel()
        rows = np.bincount(flat, weights=contrib.ravel(), minlength=self.n_int * self.size)
        return q @ self.weights, rows.reshape(self.n_int, self.size)

    def _bc_count_message(self) -> str:
        what = "sum of orders + free parameters"
        if self.n_int:
            what += f" - {self.n_int} integral condition{'s' if self.n_int > 1 else ''}"
        return f"bc must return {self.n_bc} conditions ({what})"

    def _check_bc_count(self) -> None:
        """The number of boundary conditions is structural: check it once, at unit jets.

        The same evaluation (and one at other jets) gives a first guess of which
        end each condition reads; :meth:`linearise` computes every condition's
        derivative with respect to both ends anyway and widens the pattern if a
        condition turns out to read more (so the Jacobian is never missing an
        entry, and the conditions sit next to their end in the banded order).
        """
        self._bc_cols = np.unique(np.concatenate(self.end_cols + [self.free_index]))
        self._bc_cols_pos = [np.searchsorted(self._bc_cols, c) for c in self.end_cols]
        mask = np.zeros((self.n_bc, self._bc_cols.size), bool)
        mask[:, np.searchsorted(self._bc_cols, self.free_index)] = True
        reads = self._bc_probes()
        if reads is None:  # a bc undefined at the probes: assume it reads both ends
            mask[:] = True
        for side_reads in reads or ():
            for side in (0, 1):
                mask[np.ix_(side_reads[side], self._bc_cols_pos[side])] = True
        mask[~mask.any(axis=1)] = True  # a condition that seems to read nothing: give it everything
        self._bc_mask = mask

    def _bc_probes(self):
        """Which end each condition reads at the two probes (``[(reads_a, reads_b)]``; None: a bc undefined
        there), the affine declaration checked against them. It depends on the problem's ``bc`` only, not on the
        mesh: kept on the problem for its next discretisation (a remesh; the error estimate's richer twin)."""
        pb = self.problem
        nz, npar = pb.jet_size, max(len(pb.params), 1)
        key = (pb.bc, pb.affine_bc, nz, npar, self.n_bc)
        cached = pb.__dict__.get("_bc_probe_cache")
        if cached is not None and cached[0] == key:
            return cached[1]
        slopes, found = [], []  # derivatives at the two probes, w.r.t. the end jets and the parameters
        for za, p in ((np.ones(nz), np.ones(npar)), (np.linspace(0.3, 0.7, nz), np.linspace(0.6, 0.9, npar))):
            try:
                with np.errstate(all="ignore"):
                    g, dg = self._bc_jacobian(za, za[::-1].copy(), p)
                    if pb.affine_bc:
                        slopes.append(np.hstack([dg, self._bc_param_slopes(za, za[::-1].copy(), p)]))
            except ValueError:
                raise
            except Exception:  # noqa: BLE001 - a bc undefined at these jets: assume it reads both ends
                found, slopes = None, []
                break
            found.append(tuple(np.any(dg[:, side * nz:(side + 1) * nz] != 0, axis=1)
                               | ~np.all(np.isfinite(dg[:, side * nz:(side + 1) * nz]), axis=1) for side in (0, 1)))
        # a declaration the probes contradict would give a wrong Jacobian: say so (a problem copied with
        # dataclasses.replace and another bc keeps the flag)
        if slopes and not np.allclose(slopes[0], slopes[1], rtol=1e-12, atol=1e-300):
            raise ValueError("the boundary conditions are declared affine (affine_bc) but their derivatives "
                             "differ between two points: declare affine_bc=False")
        pb.__dict__["_bc_probe_cache"] = (key, found)
        return found

    def _bc_param_slopes(self, za, zb, p) -> np.ndarray:
        """``dg/dp`` (``(n_bc, len(p))``) by the complex step, one parameter at a time."""
        out = np.empty((self.n_bc, p.size))
        for j in range(p.size):
            pc = p.astype(complex)
            pc[j] += 1j * COMPLEX_STEP
            out[:, j] = np.atleast_1d(self.problem.bc(za.astype(complex), zb.astype(complex), pc)).imag / COMPLEX_STEP
        return out

    def _build_pattern(self) -> None:
        pb = self.problem
        n, npts = pb.n_fields, self.npts
        width = self._local_cols_all.shape[1]
        r = np.arange(npts)[:, None, None] * n + np.arange(n)[None, :, None]  # (npts, n, 1)
        rows = [np.broadcast_to(r, (npts, n, width)).ravel()]
        cols = [np.broadcast_to(self._local_cols_all[:, None, :], (npts, n, width)).ravel()]
        for j in self.free_index:  # dense free-parameter columns of the collocation rows
            rows.append(np.arange(n * npts))
            cols.append(np.full(n * npts, j))
        bc_r, bc_c = np.nonzero(self._bc_mask)
        rows.append(n * npts + bc_r)
        cols.append(self._bc_cols[bc_c])
        if self.n_interface:  # each interface row reads both subintervals at its join, and the free parameters
            nj, width = self.iface_cols.shape
            per = self.n_interface // nj
            r = n * npts + self.n_bc + np.arange(self.n_interface).reshape(nj, per, 1)
            rows.append(np.broadcast_to(r, (nj, per, width)).ravel())
            cols.append(np.broadcast_to(self.iface_cols[:, None, :], (nj, per, width)).ravel())
            for j in self.free_index:
                rows.append(n * npts + self.n_bc + np.arange(self.n_interface))
                cols.append(np.full(self.n_interface, j))
        first_integral = self.size - self.n_int
        if self.n_int:  # dense rows over every column
            rows.append(np.repeat(np.arange(first_integral, self.size), self.size))
            cols.append(np.tile(np.arange(self.size), self.n_int))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        # Order the conditions along the span: each row by the mean of its columns; the integral rows last
        counts = np.maximum(np.bincount(rows, minlength=self.size), 1)
        centre = np.bincount(rows, weights=cols, minlength=self.size) / counts
        centre[first_integral:] = self.size + np.arange(self.n_int)
        self.row_order = np.argsort(centre, kind="stable")  # F = F_natural[row_order]
        rank = np.empty_like(self.row_order)
        rank[self.row_order] = np.arange(self.size)
        rows = rank[rows]
        # the CSC order (by column, then row) of the raw entries: the entry numbers carried through scipy's COO ->
        # CSC conversion (a counting sort, then a sort within each column; exact as floats below 2^53), where
        # an argsort of the keys col * size + row took a second at 60 000 unknowns
        ids = sp.coo_matrix((np.arange(rows.size, dtype=float), (rows, cols)), shape=(self.size, self.size)).tocsc()
        if ids.nnz != rows.size:
            raise AssertionError("duplicate entries in the collocation pattern")
        perm = ids.data.astype(np.intp)
        self._perm = perm  # CSC data position i holds raw entry _perm[i]
        self._csc_indices = rows[perm].astype(np.int32)
        self._csc_indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=self.size))]).astype(np.int32)
        self.nnz = perm.size
        self._J_template = canonical_csc(np.zeros(self.nnz), self._csc_indices, self._csc_indptr, self.size)
        self._bc_block = None  # the boundary rows' Jacobian entries, kept when the conditions are affine

    # ---- pointwise derivatives --------------------------------------------------
    def _pointwise_jacobian(self, S, z, p, active):
        """``G`` and ``dG/dz_j`` for ``j`` in ``active``: one complex call over all points (or the
        problem's own ``jacobian``, for the declared components).

        Copy 0 of the batch is unperturbed: a nonzero imaginary part there means
        the residual left its real domain (log or sqrt of a negative number),
        where the complex step would silently return finite values; ``G`` is
        then NaN, as the real residual is.
        """
        npts, na = z.shape[1], len(active)
        if self.problem.jacobian is not None and active is self.active:
            G, dG = self.problem.jacobian(S, z, p)
            n = self.problem.n_fields
            if np.shape(G) != (n, npts) or np.shape(dG) != (n, na, npts):
                raise ValueError(f"the jacobian must return G of shape {(n, npts)} and dG of shape {(n, na, npts)}, "
                                 f"got {np.shape(G)} and {np.shape(dG)}")
            return G, dG
        return self._complex_step(self.problem.residual, S, z, p, active, self.problem.n_fields)

    def _complex_step(self, fun, S, z, p, active, n):
        """``fun(S, z, p) -> (n, npts)`` and its derivatives ``(n, len(active), npts)`` with respect to the
        jet components ``active``: one call on ``len(active) + 1`` copies of the points (copy 0 unperturbed)."""
        nz, npts, na = z.shape[0], z.shape[1], len(active)
        nb = na + 1
        if npts > POINT_BLOCK:
            # long rods: blocks of points keep the complex batch (and the residual's temporaries) in cache;
            # one call for everything allocated hundreds of MB and spent a third of the time in the kernel
            parts = [self._complex_step(fun, S[i:i + POINT_BLOCK], z[:, i:i + POINT_BLOCK], p, active, n)
                     for i in range(0, npts, POINT_BLOCK)]
            return np.concatenate([a for a, _ in parts], axis=1), np.concatenate([b for _, b in parts], axis=2)
        Zc = np.tile(z.astype(complex), (1, nb))
        Zc.reshape(nz, nb, npts)[active, np.arange(1, nb), :] += 1j * COMPLEX_STEP
        Gc = np.asarray(fun(np.tile(S, nb), Zc, p))
        if Gc.size != n * npts * nb:
            raise ValueError(f"the residual must return {n} equations (one per field) at each point, "
                             f"got an array of shape {Gc.shape}")
        Gc = Gc.reshape(n, nb, npts)
        G = Gc[:, 0, :].real.copy()
        G[Gc[:, 0, :].imag != 0] = np.nan
        return G, Gc[:, 1:, :].imag / COMPLEX_STEP

    def _bc_jacobian(self, za, zb, p) -> tuple[np.ndarray, np.ndarray]:
        """``g`` and ``dg/d(za, zb)`` (``(n_bc, 2 jet_size)``); ``bc`` broadcasts over a trailing batch axis."""
        nz = self.problem.jet_size
        Zab = np.concatenate([za, zb]).astype(complex)[:, None] + 1j * COMPLEX_STEP * np.eye(2 * nz)
        Zab = np.concatenate([np.concatenate([za, zb]).astype(complex)[:, None], Zab], axis=1)
        g = np.asarray(self.problem.bc(Zab[:nz], Zab[nz:], p))
        if g.shape != (self.n_bc, 2 * nz + 1):
            raise ValueError(f"{self._bc_count_message()}, got {g.shape[0] if g.ndim else 1}")
        return g[:, 0].real, g[:, 1:].imag / COMPLEX_STEP

    # ---- evaluation --------------------------------------------------------
    def jets(self, x: np.ndarray) -> np.ndarray:
        """Local jets at the collocation points, ``(jet_size, npts)``."""
        return (self.E @ x).reshape(self.problem.jet_size, self.npts)

    def end_jets(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.end_E[0] @ x[self.end_cols[0]], self.end_E[1] @ x[self.end_cols[1]]

    def full_params(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        p = np.array(p, dtype=float)
        if self.n_free:
            p[list(self.problem.free)] = x[self.free_index]
        return p

    def residual(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        """All conditions (collocation and boundary), in along-the-span order."""
        pf = self.full_params(x, p)
        G = np.asarray(self.problem.residual(self.S, self.jets(x), pf))
        if G.size != self.problem.n_fields * self.npts:
            raise ValueError(f"the residual must return {self.problem.n_fields} equations (one per field) "
                             f"at each point, got an array of shape {G.shape}")
        G = G.reshape(-1, self.npts)
        za, zb = self.end_jets(x)
        return np.concatenate([G.T.ravel(), self._bc_values(za, zb, pf), self._interface_residual(x, pf),
                               self._integral_residual(x, pf)])[self.row_order]

    def _bc_values(self, za, zb, p) -> np.ndarray:
        g = np.atleast_1d(self.problem.bc(za, zb, p))
        if g.shape != (self.n_bc,):
            raise ValueError(f"{self._bc_count_message()}, got {g.shape[0] if g.ndim else 1}")
        return g

    def linearise(self, x: np.ndarray, p: np.ndarray, dparams: Sequence[int] = ()):
        """Residual ``F``, sparse Jacobian ``dF/dx`` (CSC), and ``[dF/dp_j for j in dparams]``."""
        pb = self.problem
        pf = self.full_params(x, p)
        z = self.jets(x)
        G, dGa = self._pointwise_jacobian(self.S, z, pf, self.active)
        n, npts, nz = G.shape[0], self.npts, pb.jet_size
        # the entries in raw order (collocation blocks first, written in place), then gathered into CSC order
        raw = np.empty(self.nnz)
        blocks = npts * n * self._local_active.shape[2]
        np.matmul(dGa.transpose(2, 0, 1), self._local_active, out=raw[:blocks].reshape(npts, n, -1))
        data = []
        za, zb = self.end_jets(x)
        affine = pb.affine_bc and self._bc_block is not None
        if affine:  # constant derivatives, kept from the first linearisation
            g = self._bc_values(za, zb, pf)
        else:
            g, dg = self._bc_jacobian(za, zb, pf)
        free = [int(j) for j in pb.free]
        want = free + [int(j) for j in dparams]
        dFp = []
        for j in want:  # parameter derivatives, natural row order
            pc = pf.astype(complex)
            pc[j] += 1j * COMPLEX_STEP
            if self.param_in_residual[j]:
                dGj = np.asarray(pb.residual(self.S, z.astype(complex), pc)).reshape(-1, npts).imag / COMPLEX_STEP
            else:
                dGj = np.zeros((n, npts))
            dgj = self._bc_dp.get(j) if affine else None
            if dgj is None:
                dgj = np.atleast_1d(pb.bc(za.astype(complex), zb.astype(complex), pc)).imag / COMPLEX_STEP
                if affine:
                    self._bc_dp[j] = dgj
            dFp.append(np.concatenate([dGj.T.ravel(), dgj, self._interface_dp(x, pc), self._integral_dp(z, pc)]))
        for j in range(len(free)):
            data.append(dFp[j][: n * npts])
        if affine:
            data.append(self._bc_block)
        else:
            Jb = np.zeros((self.n_bc, self._bc_cols.size))
            Jb[:, self._bc_cols_pos[0]] += dg[:, :nz] @ self.end_E[0]
            Jb[:, self._bc_cols_pos[1]] += dg[:, nz:] @ self.end_E[1]
            for j in range(len(free)):
                Jb[:, np.searchsorted(self._bc_cols, self.free_index[j])] += dFp[j][n * npts:n * npts + self.n_bc]
            outside = Jb[~self._bc_mask]
            if outside.size and np.any(outside != 0):
                # a condition reads an end the pattern did not have: widen it (the row order may change)
                self._bc_mask |= Jb != 0
                self._build_pattern()
                return self.linearise(x, p, dparams)
            data.append(Jb[self._bc_mask])
            if pb.affine_bc:
                self._bc_block = data[-1]
                self._bc_dp = dict(zip(want, (v[n * npts:n * npts + self.n_bc] for v in dFp)))
        h = q = np.zeros(0)
        first_integral = self.size - self.n_int
        if self.n_interface:
            h, dh = self._interface_jacobian(x, pf)
            data.append(dh.ravel())
            data += [dFp[j][n * npts + self.n_bc:first_integral] for j in range(len(free))]
        if self.n_int:
            q, dq = self._integral_jacobian(z, pf)
            for j in range(len(free)):
                dq[:, self.free_index[j]] += dFp[j][first_integral:]
            data.append(dq.ravel())
        if data:
            raw[blocks:] = np.concatenate(data)
        J = csc_with_data(self._J_template, raw[self._perm])
        F = np.concatenate([G.T.ravel(), g, h, q])[self.row_order]
        return F, J, [v[self.row_order] for v in dFp[len(free):]]

    def jacobian(self, x: np.ndarray, p: np.ndarray) -> sp.csc_matrix:
        return self.linearise(x, p)[1]

    # ---- solving -----------------------------------------------------------
    def newton(self, x0: np.ndarray, p: np.ndarray, tol: float = 1e-10, max_iter: int = 30,
               min_damping: float = 1.0 / 64) -> NewtonResult:
        """Damped Newton on ``F(x) = 0`` at fixed parameters (see :func:`rodcont.linalg.newton_solve`)."""
        return newton_solve(lambda x: self.linearise(x, p)[:2], lambda x: self.residual(x, p),
                            x0, tol=tol, max_iter=max_iter, min_damping=min_damping)

    # ---- solution access ---------------------------------------------------
    def coefficients(self, x: np.ndarray, i: int) -> np.ndarray:
        return x[self.index[i]]

    def evaluate(self, x: np.ndarray, S: np.ndarray | float, i: int, nu: int = 0) -> np.ndarray:
        """``nu``-th derivative of field ``i`` at ``S``."""
        return self.spaces[i].evaluate(self.coefficients(x, i), np.asarray(S, float), nu)

    def evaluation_matrix(self, S: np.ndarray, i: int, nu: int = 0) -> sp.csr_matrix:
        """Sparse ``(len(S), size)`` matrix mapping ``x`` to ``d^nu u_i / dS^nu`` at ``S``."""
        S = np.atleast_1d(np.asarray(S, float))
        sp_i = self.spaces[i]
        vals, first = sp_i.local(S, nu)
        cols = self.index[i][first[:, None] + np.arange(sp_i.order)[None, :]]
        rows = np.repeat(np.arange(S.size), sp_i.order)
        return sp.csr_matrix((vals[nu].ravel(), (rows, cols.ravel())), shape=(S.size, self.size))

    def jet_matrix(self, S: np.ndarray, interval: np.ndarray | None = None) -> sp.csr_matrix:
        """Sparse matrix mapping ``x`` to the jets at ``S`` (row ``j * len(S) + q``, as :meth:`jets`)."""
        S = np.atleast_1d(np.asarray(S, float))
        pb = self.problem
        data, indices, widths = [], [], []
        done = {}
        for i, m in enumerate(pb.orders):
            if id(self.spaces[i]) not in done:  # fields that share a space share its bases
                done[id(self.spaces[i])] = self.spaces[i].local(S, m, interval)
            vals, first = done[id(self.spaces[i])]
            cols = self.index[i][first[:, None] + np.arange(self.k + m)[None, :]].ravel()
            for nu in range(m + 1):  # row j * len(S) + q: the k + m basis functions of field i at S[q]
                data.append(vals[nu].ravel())
                indices.append(cols)
                widths.append(self.k + m)
        # CSR arrays written directly (one matrix per jet row and a vstack cost ten times more)
        indptr = np.concatenate([[0], np.cumsum(np.repeat(widths, S.size))])
        return sp.csr_matrix((np.concatenate(data), np.concatenate(indices), indptr),
                             shape=(len(widths) * S.size, self.size))

    def project(self, funcs: Sequence[Callable], free_values: Sequence[float] = ()) -> np.ndarray:
        """Unknown vector whose fields approximate the callables ``funcs`` (least squares, 3 points per coefficient)."""
        x = np.zeros(self.size)
        for i, f in enumerate(funcs):
            x[self.index[i]] = self.spaces[i].interpolant_coefficients(f)
        if self.n_free:
            x[self.free_index] = free_values
        return x

    def transfer(self, x: np.ndarray, source: Collocation) -> np.ndarray:
        """Unknown vector on this mesh closest to ``source``'s solution ``x``, jets included.

        Least squares on the values and derivatives up to each field's order
        (derivative ``j`` weighted by ``h_min^j``) at the Gauss points of both
        meshes: the residual involves the highest derivatives, so matching
        values alone is not enough on a graded mesh. Exact when ``x`` lies in
        this mesh's spaces. The matrices are built once per source (a remesh
        carries a solution and its tangent over).
        """
        # keyed by the source's mesh, not the object: a remeshed trace must not keep old meshes alive
        key = (source.breakpoints.tobytes(), source.k, tuple(source.problem.orders),
               tuple(source.join_extra), source.joins.tobytes())
        cached = getattr(self, "_transfer_from", None)
        if cached is None or cached[0] != key:
            cached = self._transfer_from = (key, self._transfer_parts(source))
        out = np.zeros(self.size)
        for i, (m, At, lu, svals, scols, w) in enumerate(cached[1]):
            c = x[source.index[i]]
            rhs = (np.einsum("nqa,qa->nq", svals, c[scols]) * w[:, None]).ravel()
            out[self.index[i]] = lu.solve(At @ rhs)
        if self.n_free:
            out[self.free_index] = x[source.free_index]
        return out

    def _transfer_parts(self, source: Collocation) -> list:
        b = self.breakpoints
        S = np.union1d(np.union1d(gauss_points(b, min(self.k + 3, 10))[0], b),
                       gauss_points(source.breakpoints, min(source.k + 3, 10))[0])
        hmin = float(np.min(np.diff(b)))
        npts = S.size
        per_order, parts = {}, []
        for i, m in enumerate(self.problem.orders):
            key = (id(self.spaces[i]), id(source.spaces[i]))  # fields that share both spaces share the matrices
            if key not in per_order:
                vals, first = self.spaces[i].local(S, m)
                svals, sfirst = source.spaces[i].local(S, m)
                order = self.spaces[i].order
                w = hmin ** np.arange(m + 1)
                # rows: (nu, point); columns: this field's coefficients
                rows = np.repeat(np.arange((m + 1) * npts), order)
                cols = np.tile((first[:, None] + np.arange(order)[None, :]).ravel(), m + 1)
                data = (vals[:m + 1] * w[:, None, None]).ravel()
                A = sp.csr_matrix((data, (rows, cols)), shape=((m + 1) * npts, self.spaces[i].dim))
                scols = sfirst[:, None] + np.arange(source.spaces[i].order)[None, :]
                At = A.T.tocsr()
                # factorised once per order (a remesh carries a solution and a tangent, six fields each)
                per_order[key] = (m, At, spla.splu((At @ A).tocsc()), svals[:m + 1], scols, w)
            parts.append(per_order[key])
        return parts

    def integrate(self, values: np.ndarray) -> float:
        """Gauss rule of the mesh applied to values at the collocation points."""
        return float(np.dot(self.weights, values))

    def integrate_between(self, values: np.ndarray, edges) -> np.ndarray:
        """``integral of f dS`` between successive ``edges`` (increasing, clipped to the span), ``f`` given by its
        ``values`` at the collocation points: on each mesh interval the polynomial through its ``k`` values,
        integrated exactly over each piece. Over whole intervals it is :meth:`integrate` (the Gauss rule, the
        load the discrete balance equations carry)."""
        b, k = self.breakpoints, self.k
        f = np.asarray(values, float).reshape(b.size - 1, k)
        edges = np.asarray(edges, float)
        cuts = np.union1d(b, np.clip(edges, b[0], b[-1]))
        mid = 0.5 * (cuts[1:] + cuts[:-1])
        parent = np.clip(np.searchsorted(b, mid, side="right") - 1, 0, b.size - 2)
        h = np.diff(b)[parent]
        g, wg = np.polynomial.legendre.leggauss(k)
        nodes = 0.5 * (g + 1.0)                      # the collocation points on [0, 1]
        ta, te = (cuts[:-1] - b[parent]) / h, (cuts[1:] - b[parent]) / h
        t = 0.5 * (ta + te)[:, None] + 0.5 * (te - ta)[:, None] * g[None, :]   # k Gauss points of each piece
        diff = t[:, :, None] - nodes[None, None, :]   # Lagrange basis of the nodes at t: exact for degree k - 1
        basis = np.ones(t.shape + (k,))
        for j in range(k):
            others = [i for i in range(k) if i != j]
            basis[:, :, j] = np.prod(diff[:, :, others], axis=2) / np.prod(nodes[j] - nodes[others])
        piece = 0.5 * (te - ta) * h * np.einsum("q,pqj,pj->p", wg, basis, f[parent])
        inside = (mid > edges[0]) & (mid < edges[-1])   # the pieces between the first and the last edge
        which = np.searchsorted(edges, mid[inside], side="right") - 1
        return np.bincount(which, weights=piece[inside], minlength=edges.size - 1)

    def interval_of(self, S: np.ndarray) -> np.ndarray:
        return locate(self.breakpoints, np.asarray(S, float))
