"""Spline collocation at Gauss points for mixed-order boundary value problems.

The problem (knows nothing of rods) is a system of ``n`` ODEs for ``n``
unknown fields ``u_i(S)``, field ``i`` of order ``m_i``::

    G(S, z(S), p) = 0,      S in [a, b]             (n equations)
    g(z(a), z(b), p) = 0                             (sum m_i + n_free conditions)

with the local jet ``z = (u_0, u_0', ..., u_0^(m_0), u_1, ..., u_{n-1}^(m_{n-1}))``.
Following Ascher, Christiansen & Russell (1979), field ``i`` is sought in
``P_{k+m_i} ∩ C^{m_i-1}`` on a partition of ``N`` subintervals: B-splines of
order ``k + m_i`` (degree ``k + m_i - 1``) whose interior knots have
multiplicity ``k``, dimension ``N k + m_i``. The ``n k N`` collocation
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
part is ``G`` itself. The sparsity pattern and the map from the pointwise
blocks to CSC storage are computed once per discretisation.

Block pattern (rows: point-major collocation equations, then boundary
conditions; columns: the coefficients of each field, then free parameters)::

    field 0      field 1      ...   free
    [xxx.......] [xxxx......]       [x]   point 0      (n rows each)
    [.xxx......] [.xxxx.....]       [x]   point 1
    ...
    [xxx....xxx] [xxxx...xxx]       [x]   boundary conditions
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.interpolate import BSpline

COMPLEX_STEP = 1e-30


# --------------------------------------------------------------------------
# B-spline spaces
# --------------------------------------------------------------------------
class SplineSpace:
    """``P_{k+m} ∩ C^{m-1}`` on the partition ``breakpoints`` (order ``k+m`` B-splines)."""

    def __init__(self, breakpoints: np.ndarray, k: int, m: int):
        self.breakpoints = np.asarray(breakpoints, dtype=float)
        self.k, self.m = int(k), int(m)
        self.order = self.k + self.m
        self.degree = self.order - 1
        b = self.breakpoints
        self.knots = np.concatenate(
            [np.full(self.order, b[0]), np.repeat(b[1:-1], self.k), np.full(self.order, b[-1])]
        )
        self.dim = (len(b) - 1) * self.k + self.m

    def basis(self, x: np.ndarray, nu: int = 0) -> np.ndarray:
        """Dense ``(len(x), dim)`` matrix of the ``nu``-th derivatives of all basis functions."""
        return self.basis_sparse(x, nu).toarray()

    def basis_sparse(self, x: np.ndarray, nu: int = 0) -> sp.csr_matrix:
        """Sparse ``(len(x), dim)`` matrix of the ``nu``-th derivatives of all basis functions.

        ``x`` is clipped to the interval. Derivatives through the B-spline
        derivative recurrence: the coefficients of ``d/dx sum c_j B_j`` in the
        basis of degree ``d - 1`` on ``t[1:-1]`` are
        ``d (c_{j+1} - c_j) / (t_{j+d+1} - t_{j+1})`` (de Boor), so
        ``D_nu = design_matrix(x, degree - nu) @ M_nu ... M_1``: ``O(len(x) k)`` work.
        """
        x = np.clip(np.atleast_1d(np.asarray(x, dtype=float)), self.breakpoints[0], self.breakpoints[-1])
        if nu > self.degree:
            return sp.csr_matrix((x.size, self.dim))
        t, d = self.knots, self.degree
        D = sp.identity(self.dim, format="csr")
        for _ in range(nu):
            ncur = len(t) - d - 1
            denom = t[d + 1:d + ncur] - t[1:ncur]
            scale = np.divide(d, denom, out=np.zeros_like(denom), where=denom > 0)
            j = np.arange(ncur - 1)
            M = sp.csr_matrix((np.concatenate([-scale, scale]), (np.concatenate([j, j]), np.concatenate([j, j + 1]))),
                              shape=(ncur - 1, ncur))
            D = M @ D
            t, d = t[1:-1], d - 1
        B = sp.csr_matrix(BSpline.design_matrix(x, t, d))
        return (B @ D).tocsr()

    def spline(self, coefficients: np.ndarray) -> BSpline:
        return BSpline(self.knots, np.asarray(coefficients), self.degree, extrapolate=False)

    def interpolant_coefficients(self, f: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Coefficients of the least-squares fit of ``f`` on 3 points per basis function (sparse normal equations)."""
        x = np.union1d(np.linspace(self.breakpoints[0], self.breakpoints[-1], 3 * self.dim), self.breakpoints)
        A = self.basis_sparse(x).tocsc()
        y = np.broadcast_to(np.asarray(f(x), dtype=float), x.shape)
        return spla.spsolve((A.T @ A).tocsc(), A.T @ y)


def gauss_points(breakpoints: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` Gauss-Legendre points and weights of each subinterval, in order."""
    xi, wi = np.polynomial.legendre.leggauss(k)
    b = np.asarray(breakpoints, dtype=float)
    h = np.diff(b)
    S = (b[:-1, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)).ravel()
    W = (0.5 * h[:, None] * wi[None, :]).ravel()
    return S, W


def uniform_mesh(a: float, b: float, N: int) -> np.ndarray:
    return np.linspace(a, b, int(N) + 1)


def equidistribute(breakpoints: np.ndarray, indicator: np.ndarray, order: int, floor: float = 0.02,
                   ratio: float = 2.0, relax: float = 0.5) -> np.ndarray:
    """A mesh with the same number of subintervals on which ``indicator`` would be equal.

    ``indicator[i]`` is an error estimate on subinterval ``i`` behaving like
    ``C_i h_i^order``; the new sizes follow the density ``C^(1/order)``
    (floored at ``floor`` of its maximum, neighbours within ``ratio``), and the
    new mesh is ``relax`` of the way from the old one to the equidistributed one.
    """
    b = np.asarray(breakpoints, float)
    h = np.diff(b)
    d = np.maximum(np.asarray(indicator, float), 1e-300)
    rho = (d / h**order) ** (1.0 / order)
    rho = np.maximum(rho, floor * rho.max())
    for _ in range(len(rho)):  # limit the ratio of neighbouring densities
        before = rho.copy()
        rho[1:] = np.maximum(rho[1:], rho[:-1] / ratio)
        rho[:-1] = np.maximum(rho[:-1], rho[1:] / ratio)
        if np.array_equal(before, rho):
            break
    cum = np.concatenate([[0.0], np.cumsum(rho * h)])
    target = np.interp(np.linspace(0.0, cum[-1], b.size), cum, b)
    new = (1 - relax) * b + relax * target
    new[0], new[-1] = b[0], b[-1]
    return new


# --------------------------------------------------------------------------
# Problem protocol
# --------------------------------------------------------------------------
@dataclass
class BVProblem:
    """A mixed-order BVP in the form the collocation core solves.

    ``residual(S, z, p) -> (n, npts)``: the ODEs at points ``S`` given the jets
    ``z`` (``(sum(m_i + 1), npts)``, see module docstring) and parameters ``p``.
    ``bc(za, zb, p) -> (sum(m_i) + len(free),)``: the boundary conditions, with
    ``za, zb`` the jets at the two ends. Both must be written with analytic
    operations only (``sqrt(v.v)``, never ``abs``) so the complex step is exact.
    ``free``: indices into ``p`` that are unknowns (solved for) rather than data.
    ``params``: names of the entries of ``p``.
    """

    orders: Sequence[int]
    residual: Callable
    bc: Callable
    interval: tuple[float, float]
    params: Sequence[str] = ()
    free: Sequence[int] = ()
    names: Sequence[str] | None = None

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


@dataclass
class NewtonResult:
    """Outcome of a Newton solve. ``converged`` False is a result, not an error."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual_norm: float
    step_norm: float
    message: str
    lu: object = field(default=None, repr=False)
    corrections: list = field(default_factory=list, repr=False)  # the first two Newton steps


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
        if isinstance(breakpoints, (int, np.integer)):
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
        self.spaces = [SplineSpace(b, k, m) for m in pb.orders]
        self.n_free = len(pb.free)
        n_coef = int(sum(s.dim for s in self.spaces))
        self.size = n_coef + self.n_free
        self.S, self.weights = gauss_points(b, k)
        self.npts = npts = self.S.size
        n, nz = pb.n_fields, pb.jet_size
        self.jet_rows = np.concatenate([[0], np.cumsum([m + 1 for m in pb.orders])])

        # Interleave the coefficients of all fields by the centre of their support.
        centre = np.concatenate([0.5 * (s.knots[:s.dim] + s.knots[s.order:]) for s in self.spaces])
        field_of = np.concatenate([np.full(s.dim, i) for i, s in enumerate(self.spaces)])
        order = np.lexsort((field_of, centre))
        position = np.empty(n_coef, int)
        position[order] = np.arange(n_coef)
        starts = np.concatenate([[0], np.cumsum([s.dim for s in self.spaces])])
        self.index = [position[starts[i]:starts[i + 1]] for i in range(n)]
        self.free_index = np.arange(n_coef, self.size)

        # Jets at the collocation points: z = E @ x (row j * npts + q), and the
        # values of the k + m_i basis functions nonzero at each point.
        interval = np.repeat(np.arange(N), k)
        rows, cols, vals_E = [], [], []
        self._local = []
        self._local_cols = []
        for i, sp_i in enumerate(self.spaces):
            m = pb.orders[i]
            c = interval[:, None] * k + np.arange(k + m)[None, :]  # (npts, k+m) local -> field index
            vals = np.stack([_take_local(sp_i.basis_sparse(self.S, nu), c) for nu in range(m + 1)])
            self._local.append(vals)  # (m+1, npts, k+m)
            self._local_cols.append(self.index[i][c])
            for nu in range(m + 1):
                rows.append(np.repeat((self.jet_rows[i] + nu) * npts + np.arange(npts), k + m))
                cols.append(self.index[i][c].ravel())
                vals_E.append(vals[nu].ravel())
        self.E = sp.csr_matrix((np.concatenate(vals_E), (np.concatenate(rows), np.concatenate(cols))),
                               shape=(nz * npts, self.size))
        # Jets at the two ends, dense (2, nz, size).
        self.E_ends = np.zeros((2, nz, self.size))
        ends = np.array([b[0], b[-1]])
        for i, sp_i in enumerate(self.spaces):
            for nu in range(pb.orders[i] + 1):
                self.E_ends[:, self.jet_rows[i] + nu, self.index[i]] = sp_i.basis(ends, nu)
        self.n_bc = self.size - n * npts
        self._probe_dependence()
        # All fields' local bases side by side, one row per active jet component, so that the
        # collocation blocks of the Jacobian are one batched matrix product per linearisation:
        # block_q = dG/dz_active(q) @ local[q]   ((n, na) @ (na, sum(k + m_i)) at each point q).
        widths = [self.k + m for m in pb.orders]
        starts = np.concatenate([[0], np.cumsum(widths)])
        local = np.zeros((npts, nz, starts[-1]))
        for i, m in enumerate(pb.orders):
            local[:, self.jet_rows[i]:self.jet_rows[i + 1], starts[i]:starts[i + 1]] = self._local[i].transpose(1, 0, 2)
        self._local_active = np.ascontiguousarray(local[:, self.active, :])
        self._local_cols_all = np.concatenate(self._local_cols, axis=1)  # (npts, sum(k + m_i))
        self._build_pattern()

    # ---- structure (computed once) -------------------------------------------
    def _probe_dependence(self) -> None:
        """Which jet components the residual and the bc depend on, probed with
        the complex step at random data (a dependence that vanishes there is
        improbable); unused components are skipped in every linearisation."""
        pb, nz = self.problem, self.problem.jet_size
        rng = np.random.default_rng(20261122)
        used = np.zeros(nz, bool)
        bc_pattern = np.zeros((self.n_bc, self.size), bool)
        for _ in range(2):
            pr = rng.uniform(0.5, 2.0, max(len(pb.params), 1))
            z = rng.uniform(-0.3, 0.3, (nz, 3))
            S = rng.uniform(*self.breakpoints[[0, -1]], 3)
            dG = self._pointwise_jacobian(S, z, pr, np.arange(nz))[1]
            used |= np.any(dG != 0, axis=(0, 2))
            za, zb = rng.uniform(-0.3, 0.3, nz), rng.uniform(-0.3, 0.3, nz)
            dg = self._bc_jet_jacobian(za, zb, pr)
            bc_pattern |= (np.abs(dg[:, :nz]) @ np.abs(self.E_ends[0]) + np.abs(dg[:, nz:]) @ np.abs(self.E_ends[1])) != 0
        bc_pattern[:, self.free_index] = True
        self.active = np.flatnonzero(used)
        # parameters the pointwise residual depends on (others enter only the bc)
        npar = max(len(pb.params), 1)
        self.param_in_residual = np.zeros(npar, bool)
        for j in range(npar):
            pc = pr.astype(complex)
            pc[j] += 1j * COMPLEX_STEP
            G = np.asarray(pb.residual(S, z.astype(complex), pc))
            self.param_in_residual[j] = np.any(G.imag != 0)
        self._bc_pattern = np.nonzero(bc_pattern)

    def _build_pattern(self) -> None:
        pb = self.problem
        n, npts = pb.n_fields, self.npts
        rows, cols = [], []
        q = np.arange(npts)
        width = self._local_cols_all.shape[1]
        r = q[:, None, None] * n + np.arange(n)[None, :, None]  # (npts, n, 1)
        rows.append(np.broadcast_to(r, (npts, n, width)).ravel())
        cols.append(np.broadcast_to(self._local_cols_all[:, None, :], (npts, n, width)).ravel())
        for j in self.free_index:  # dense free-parameter columns of the collocation rows
            rows.append(np.arange(n * npts))
            cols.append(np.full(n * npts, j))
        rows.append(n * npts + self._bc_pattern[0])
        cols.append(self._bc_pattern[1])
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        # Order the conditions along the span: each row by the mean of its columns.
        centre = np.bincount(rows, weights=cols, minlength=self.size) / np.bincount(rows, minlength=self.size)
        self.row_order = np.argsort(centre, kind="stable")  # F = F_natural[row_order]
        rank = np.empty_like(self.row_order)
        rank[self.row_order] = np.arange(self.size)
        rows = rank[rows]
        nnz = rows.size
        M = sp.csc_matrix((np.arange(1, nnz + 1, dtype=float), (rows, cols)), shape=(self.size, self.size))
        M.sum_duplicates()
        M.sort_indices()
        slot = np.searchsorted(_csc_keys(M), _key(rows, cols, self.size))
        self._scatter = sp.csr_matrix((np.ones(nnz), (slot, np.arange(nnz))), shape=(M.nnz, nnz))
        self._csc_indices, self._csc_indptr = M.indices.copy(), M.indptr.copy()
        self.nnz = M.nnz

    def _pointwise_jacobian(self, S, z, p, active):
        """``G`` and ``dG/dz_j`` for ``j`` in ``active``: one complex call over all points.

        Copy 0 of the batch is unperturbed: a nonzero imaginary part there means
        the residual left its real domain (log or sqrt of a negative number),
        where the complex step would silently return finite values; ``G`` is
        then NaN, as the real residual is.
        """
        nz, npts, na = z.shape[0], z.shape[1], len(active)
        nb = na + 1
        Zc = np.tile(z.astype(complex), (1, nb))
        Zc.reshape(nz, nb, npts)[active, np.arange(1, nb), :] += 1j * COMPLEX_STEP
        Gc = np.asarray(self.problem.residual(np.tile(S, nb), Zc, p))
        n = self.problem.n_fields
        if Gc.size != n * npts * nb:
            raise ValueError(f"the residual must return {n} equations (one per field) at each point, "
                             f"got an array of shape {Gc.shape}")
        Gc = Gc.reshape(n, nb, npts)
        G = Gc[:, 0, :].real.copy()
        G[Gc[:, 0, :].imag != 0] = np.nan
        return G, Gc[:, 1:, :].imag / COMPLEX_STEP

    def _bc_jet_jacobian(self, za, zb, p) -> np.ndarray:
        """``dg/d(za, zb)``, ``(n_bc, 2 jet_size)``; ``bc`` broadcasts over a trailing batch axis."""
        nz = self.problem.jet_size
        Zab = np.concatenate([za, zb]).astype(complex)[:, None] + 1j * COMPLEX_STEP * np.eye(2 * nz)
        g = np.asarray(self.problem.bc(Zab[:nz], Zab[nz:], p))
        if g.shape != (self.n_bc, 2 * nz):
            raise ValueError(f"bc must return {self.n_bc} conditions (sum of orders + free parameters), "
                             f"got {g.shape[0] if g.ndim else 1}")
        return g.imag / COMPLEX_STEP

    # ---- evaluation --------------------------------------------------------
    def jets(self, x: np.ndarray) -> np.ndarray:
        """Local jets at the collocation points, ``(jet_size, npts)``."""
        return (self.E @ x).reshape(self.problem.jet_size, self.npts)

    def end_jets(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.E_ends[0] @ x, self.E_ends[1] @ x

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
        return np.concatenate([G.T.ravel(), np.atleast_1d(self.problem.bc(za, zb, pf))])[self.row_order]

    def linearise(self, x: np.ndarray, p: np.ndarray, dparams: Sequence[int] = ()):
        """Residual ``F``, sparse Jacobian ``dF/dx`` (CSC), and ``[dF/dp_j for j in dparams]``."""
        pb = self.problem
        pf = self.full_params(x, p)
        z = self.jets(x)
        G, dGa = self._pointwise_jacobian(self.S, z, pf, self.active)
        n, npts, nz = G.shape[0], self.npts, pb.jet_size
        data = [np.matmul(dGa.transpose(2, 0, 1), self._local_active).ravel()]
        za, zb = self.end_jets(x)
        g = np.atleast_1d(pb.bc(za, zb, pf))
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
            dgj = np.atleast_1d(pb.bc(za.astype(complex), zb.astype(complex), pc)).imag / COMPLEX_STEP
            dFp.append(np.concatenate([dGj.T.ravel(), dgj]))
        for j in range(len(free)):
            data.append(dFp[j][: n * npts])
        dg = self._bc_jet_jacobian(za, zb, pf)
        Jb = dg[:, :nz] @ self.E_ends[0] + dg[:, nz:] @ self.E_ends[1]  # (n_bc, size)
        for j in range(len(free)):
            Jb[:, self.free_index[j]] += dFp[j][n * npts:]
        data.append(Jb[self._bc_pattern])
        J = sp.csc_matrix((self._scatter @ np.concatenate(data), self._csc_indices, self._csc_indptr),
                          shape=(self.size, self.size))
        F = np.concatenate([G.T.ravel(), g])[self.row_order]
        return F, J, [v[self.row_order] for v in dFp[len(free):]]

    def jacobian(self, x: np.ndarray, p: np.ndarray) -> sp.csc_matrix:
        return self.linearise(x, p)[1]

    # ---- solving -----------------------------------------------------------
    def newton(self, x0: np.ndarray, p: np.ndarray, tol: float = 1e-10, max_iter: int = 30,
               min_damping: float = 1.0 / 64) -> NewtonResult:
        """Damped Newton on ``F(x) = 0`` at fixed parameters (see :func:`newton_solve`)."""
        return newton_solve(lambda x: self.linearise(x, p)[:2], lambda x: self.residual(x, p),
                            x0, tol=tol, max_iter=max_iter, min_damping=min_damping)

    # ---- solution access ---------------------------------------------------
    def coefficients(self, x: np.ndarray, i: int) -> np.ndarray:
        return x[self.index[i]]

    def evaluate(self, x: np.ndarray, S: np.ndarray | float, i: int, nu: int = 0) -> np.ndarray:
        """``nu``-th derivative of field ``i`` at ``S``."""
        return self.spaces[i].spline(self.coefficients(x, i))(np.asarray(S, float), nu)

    def evaluation_matrix(self, S: np.ndarray, i: int, nu: int = 0) -> sp.csr_matrix:
        """Sparse ``(len(S), size)`` matrix mapping ``x`` to ``d^nu u_i / dS^nu`` at ``S``."""
        B = self.spaces[i].basis_sparse(np.atleast_1d(S), nu).tocoo()
        out = sp.csr_matrix((B.data, (B.row, self.index[i][B.col])), shape=(B.shape[0], self.size))
        out.eliminate_zeros()
        return out

    def project(self, funcs: Sequence[Callable], free_values: Sequence[float] = ()) -> np.ndarray:
        """Unknown vector whose fields approximate the callables ``funcs``."""
        x = np.zeros(self.size)
        for i, f in enumerate(funcs):
            x[self.index[i]] = self.spaces[i].interpolant_coefficients(f)
        if self.n_free:
            x[self.free_index] = free_values
        return x

    def transfer(self, x: np.ndarray, source: "Collocation") -> np.ndarray:
        """Unknown vector on this mesh closest to ``source``'s solution ``x``, jets included.

        Least squares on the values and derivatives up to each field's order
        (derivative ``j`` weighted by ``h_min^j``) at the Gauss points of both
        meshes: the residual involves the highest derivatives, so matching
        values alone is not enough on a graded mesh.
        """
        b = self.breakpoints
        S = np.union1d(np.union1d(gauss_points(b, min(self.k + 3, 10))[0], b),
                       gauss_points(source.breakpoints, min(source.k + 3, 10))[0])
        hmin = float(np.min(np.diff(b)))
        out = np.zeros(self.size)
        for i, m in enumerate(self.problem.orders):
            rows = [hmin**j * self.spaces[i].basis_sparse(S, j) for j in range(m + 1)]
            rhs = [hmin**j * source.evaluate(x, S, i, j) for j in range(m + 1)]
            A = sp.vstack(rows).tocsc()
            out[self.index[i]] = spla.spsolve((A.T @ A).tocsc(), A.T @ np.concatenate(rhs))
        if self.n_free:
            out[self.free_index] = x[source.free_index]
        return out

    def integrate(self, values: np.ndarray) -> float:
        """Gauss rule of the mesh applied to values at the collocation points."""
        return float(np.dot(self.weights, values))


def _take_local(B: sp.csr_matrix, cols: np.ndarray) -> np.ndarray:
    """Dense ``B[q, cols[q, :]]`` for each row ``q`` (the basis functions nonzero at point ``q``)."""
    B = B.tocsr()
    out = np.zeros(cols.shape)
    for a in range(cols.shape[1]):
        out[:, a] = np.asarray(B[np.arange(cols.shape[0]), cols[:, a]]).ravel()
    return out


def _key(rows, cols, n):
    return cols.astype(np.int64) * n + rows


def _csc_keys(M: sp.csc_matrix) -> np.ndarray:
    cols = np.repeat(np.arange(M.shape[1]), np.diff(M.indptr))
    return _key(M.indices, cols, M.shape[0])


def _norm(v: np.ndarray) -> float:
    return float(np.max(np.abs(v))) if v.size else 0.0


def newton_solve(linearise: Callable, residual: Callable, x0: np.ndarray, tol: float = 1e-10,
                 max_iter: int = 30, min_damping: float = 1.0 / 64) -> NewtonResult:
    """Damped Newton for ``F(x) = 0`` given ``linearise(x) -> (F, J)`` (``J`` sparse).

    One assembly and one sparse LU per iteration. A full step is tried first;
    while the max-norm residual does not decrease the step is halved, down to
    ``min_damping``. Converged when a full step is below ``tol * (1 + |x|)``,
    or when quadratic convergence predicts the next one is
    (``|dx_k|^2 / |dx_{k-1}| <= tol * (1 + |x|)`` with ``|dx_k| < |dx_{k-1}| / 4``),
    which saves the last, confirming, iteration. ``lu`` in the result is the
    factorisation of the last Jacobian used (one step before ``x``).
    """
    x = np.array(x0, dtype=float)
    F, J = linearise(x)
    fnorm, step, prev = _norm(F), np.inf, np.inf
    # residual changes below this are rounding: the size of the terms, not of their sum
    floor = 1e-13 * (1.0 + (fnorm if np.isfinite(fnorm) else 0.0))
    corrections: list = []
    for it in range(1, max_iter + 1):
        if not np.all(np.isfinite(F)):
            return NewtonResult(x, False, it - 1, fnorm, step, "residual is not finite")
        try:
            lu = spla.splu(J, permc_spec="NATURAL")
        except RuntimeError as exc:  # exactly singular factor
            return NewtonResult(x, False, it - 1, fnorm, step, f"singular Jacobian ({exc})")
        dx = lu.solve(-F)
        if len(corrections) < 2:
            corrections.append(dx)
        prev, step = step, _norm(dx)
        xnorm = _norm(x)
        scale = tol * (1 + xnorm)
        if not np.isfinite(step):
            return NewtonResult(x, False, it, fnorm, step, "Newton step is not finite (singular Jacobian)")
        done = step <= scale or (np.isfinite(prev) and step < 0.25 * prev and step * step <= scale * prev)
        if done:
            fdone = _norm(residual(x + dx))
            if np.isfinite(fdone) and fdone <= 10.0 * fnorm + floor:  # a tiny step only moves rounding
                return NewtonResult(x + dx, True, it, fdone, step, "converged", lu, corrections)
        Ft, Jt = linearise(x + dx)
        ft, lam = _norm(Ft), 1.0
        while not (np.isfinite(ft) and ft <= fnorm * (1 + 1e-6) + floor):
            lam *= 0.5
            if lam < min_damping:
                return NewtonResult(x, False, it, fnorm, step, "line search failed: the residual does not decrease")
            Ft = residual(x + lam * dx)
            ft, Jt = _norm(Ft), None
        x = x + lam * dx
        if Jt is None:
            Ft, Jt = linearise(x)
        F, J, fnorm = Ft, Jt, _norm(Ft)
        if lam < 1.0:
            step = np.inf  # a damped step says nothing about the rate
    return NewtonResult(x, False, max_iter, fnorm, step, f"no convergence in {max_iter} iterations")
