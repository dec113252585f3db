"""B-spline spaces for collocation: ``P_{k+m} ∩ C^{m-1}`` on a partition, and Gauss points.

Field ``i`` of order ``m`` lives in the span of the B-splines of order
``k + m`` (degree ``k + m - 1``) on the knot sequence with ``order`` copies of
each end and every interior breakpoint repeated ``k`` times (Ascher,
Christiansen & Russell 1979); the space has dimension ``N k + m``. On
subinterval ``j`` exactly ``k + m`` of them are nonzero, those numbered
``j k ... j k + k + m - 1``.

A *join* lowers the continuity at chosen interior breakpoints: ``extra[i]``
more copies of breakpoint ``i + 1`` (``k + e`` in all) leave the space
``C^(m-1-e)`` there and add ``e`` functions; subinterval ``j`` then starts at
function ``j k + E_j``, ``E_j`` the extra copies at breakpoints ``1 .. j``.

Values and derivatives are computed by the Cox-de Boor recurrence with the
derivative algorithm A2.3 of Piegl & Tiller (*The NURBS Book*), vectorised
over the evaluation points (the loops run over the degree only). No
``scipy.interpolate``: it costs a tenth of a second to import.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp


@functools.cache
def gauss_legendre(k: int) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.polynomial.legendre.leggauss(k)``, computed once per ``k`` (an eigenproblem: a tenth of a
    millisecond, and every discretisation and error estimate asks again); read-only arrays."""
    xi, wi = np.polynomial.legendre.leggauss(k)
    xi.flags.writeable = wi.flags.writeable = False
    return xi, wi


def gauss_points(breakpoints: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` Gauss-Legendre points and weights of each subinterval, in order."""
    xi, wi = gauss_legendre(int(k))
    b = np.asarray(breakpoints, dtype=float)
    h = np.diff(b)
    S = (b[:-1, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)).ravel()
    W = (0.5 * h[:, None] * wi[None, :]).ravel()
    return S, W


def locate(breakpoints: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Subinterval of each ``x`` (clipped to the interval; the right end belongs to the last one)."""
    b = np.asarray(breakpoints, float)
    j = np.searchsorted(b, x, side="right") - 1
    return np.clip(j, 0, b.size - 2)


@functools.cache
def _derivative_indices(p: int, kk: int) -> tuple[np.ndarray, np.ndarray]:
    """Piegl & Tiller A2.3's index ``rk + j = r - kk + j`` (``r = 0..p``, ``j = 0..kk``), as ``(valid, clipped)``:
    ``valid[r, j, None]`` where it lies in ``0..p - kk``; computed once per degree and order (read-only)."""
    idx = np.arange(p + 1)[:, None] - kk + np.arange(kk + 1)[None, :]
    valid = ((idx >= 0) & (idx <= p - kk))[:, :, None]
    idc = np.clip(idx, 0, p - kk)
    valid.flags.writeable = idc.flags.writeable = False
    return valid, idc


class SplineSpace:
    """``P_{k+m} ∩ C^{m-1}`` on the partition ``breakpoints`` (order ``k+m`` B-splines).

    ``extra`` (optional, one integer ``0 <= e <= m - 1`` per interior breakpoint):
    only ``C^(m-1-e)`` at that breakpoint (a join), ``dim = N k + m + sum(extra)``.
    """

    def __init__(self, breakpoints: np.ndarray, k: int, m: int, extra: np.ndarray | None = None):
        self.breakpoints = b = np.asarray(breakpoints, dtype=float)
        self.k, self.m = int(k), int(m)
        self.order = self.k + self.m
        self.degree = self.order - 1
        self.N = b.size - 1
        e = np.zeros(self.N - 1, int) if extra is None else np.asarray(extra, int)
        if e.shape != (self.N - 1,) or np.any(e < 0) or np.any(e > self.m - 1):
            raise ValueError(f"extra multiplicities: one integer in 0..{self.m - 1} per interior breakpoint")
        self.extra = e
        self.shift = np.concatenate([[0], np.cumsum(e)])  # E_j: extra knots before subinterval j
        self.knots = np.concatenate(
            [np.full(self.order, b[0]), np.repeat(b[1:-1], self.k + e), np.full(self.order, b[-1])])
        self.dim = self.N * self.k + self.m + int(e.sum())

    def local(self, x: np.ndarray, nu_max: int = 0, interval: np.ndarray | None = None):
        """The ``order`` basis functions nonzero at each ``x`` and their derivatives.

        Returns ``(values, first)``: ``values[nu, q, a]`` is the ``nu``-th
        derivative (``nu <= nu_max``) of basis function ``first[q] + a`` at ``x[q]``.
        ``interval`` (optional) says which subinterval each ``x`` belongs to
        (so a breakpoint can be evaluated from either side).
        """
        x = np.clip(np.atleast_1d(np.asarray(x, dtype=float)), self.breakpoints[0], self.breakpoints[-1])
        j = locate(self.breakpoints, x) if interval is None else np.asarray(interval)
        p, t = self.degree, self.knots
        span = p + j * self.k + self.shift[j]
        npts = x.size
        nd = min(nu_max, p)
        # ndu[a, b]: upper triangle (a <= b) the basis values of degree b, lower triangle
        # (a > b) the knot differences; each degree in one vectorised sweep over r
        ndu = np.zeros((p + 1, p + 1, npts))
        ndu[0, 0] = 1.0
        # left[r] = x - t[span + 1 - r], right[r] = t[span + r] - x for r = 1 .. p, each in one gather
        offsets = np.arange(p + 1)[:, None]
        left = x - t[span + 1 - offsets]
        right = t[span + offsets] - x
        for jj in range(1, p + 1):  # (reversed slices of left: left[jj - r] for r = 0 .. jj - 1)
            ndu[jj, :jj] = right[1:jj + 1] + left[jj:0:-1]
            temp = ndu[:jj, jj - 1] / ndu[jj, :jj]
            ndu[:jj, jj] = right[1:jj + 1] * temp
            ndu[1:jj, jj] += left[jj:1:-1] * temp[:-1]
            ndu[jj, jj] = left[1] * temp[jj - 1]
        out = np.zeros((nu_max + 1, npts, p + 1))
        out[0] = ndu[:, p].T
        # derivatives (Piegl & Tiller A2.3), all r at once: a[r, j] over j = 0..kk
        a = np.zeros((p + 1, nd + 2, npts))
        a[:, 0] = 1.0
        for kk in range(1, nd + 1):
            pk = p - kk
            valid, idc = _derivative_indices(p, kk)
            diff = a[:, :kk + 1].copy()
            diff[:, 1:] -= a[:, :kk]
            new = np.where(valid, diff / ndu[pk + 1][idc], 0.0)
            out[kk] = (new * ndu[idc, pk]).sum(axis=1).T
            a[:, :kk + 1] = new
        factor = p
        for kk in range(1, nd + 1):
            out[kk] *= factor
            factor *= p - kk
        return out, span - p

    def basis(self, x: np.ndarray, nu: int = 0) -> np.ndarray:
        """Dense ``(len(x), dim)`` matrix of the ``nu``-th derivatives of all basis functions."""
        vals, first = self.local(x, nu)
        x = np.atleast_1d(x)
        out = np.zeros((x.size, self.dim))
        cols = first[:, None] + np.arange(self.order)[None, :]
        np.put_along_axis(out, cols, vals[nu], axis=1)
        return out

    def evaluate(self, coefficients: np.ndarray, x: np.ndarray, nu: int = 0) -> np.ndarray:
        """``nu``-th derivative of ``sum c_j B_j`` at ``x``."""
        shape = np.shape(x)
        vals, first = self.local(np.ravel(x), nu)
        c = np.asarray(coefficients)
        cols = first[:, None] + np.arange(self.order)[None, :]
        return np.einsum("qa,qa->q", vals[nu], c[cols]).reshape(shape)

    def matrix(self, x: np.ndarray, nu: int = 0) -> sp.csc_matrix:
        """Sparse ``(len(x), dim)`` matrix of the ``nu``-th derivatives of all basis functions."""
        x = np.atleast_1d(np.asarray(x, float))
        vals, first = self.local(x, nu)
        cols = first[:, None] + np.arange(self.order)[None, :]
        rows = np.repeat(np.arange(x.size), self.order)
        return sp.csr_matrix((vals[nu].ravel(), (rows, cols.ravel())), shape=(x.size, self.dim)).tocsc()

    def interpolant_coefficients(self, f) -> np.ndarray:
        """Coefficients of the least-squares fit of ``f`` (sparse normal equations) on 3 points per basis
        function spread evenly, and ``order`` more inside every subinterval: a short subinterval (stations
        close together) would otherwise hold too few points and make the normal equations singular."""
        key = self.knots.tobytes()  # a copied space moved along S (rodcont.drilling.carried_guess) has new knots
        fit = getattr(self, "_fit", None)
        if fit is None or fit[0] != key:  # the points, the matrix, its normal equations' LU: once per space
            b = self.breakpoints
            inner = (b[:-1, None] + np.diff(b)[:, None] * np.linspace(0.0, 1.0, self.order + 2)[None, 1:-1]).ravel()
            x = np.union1d(np.union1d(np.linspace(b[0], b[-1], 3 * self.dim), b), inner)
            A = self.matrix(x)
            from .linalg import superlu  # SuperLU's failures read as the solvers' are (out of memory: its size)
            fit = self._fit = (key, x, A.T.tocsr(), superlu((A.T @ A).tocsc(), "COLAMD"))
        _, x, At, lu = fit
        y = np.broadcast_to(np.asarray(f(x), dtype=float), x.shape)
        return lu.solve(At @ y) if np.any(y) else np.zeros(self.dim)  # zero data: the fit is exactly zero
