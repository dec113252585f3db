"""Codimension-two continuation and branch switching (knows nothing of rods).

Fold curves: the minimally augmented system (Govaerts 2000; BifurcationKit's
``MinAugFold``). For a two-parameter problem ``F(x, p1, p2) = 0`` the fold of
the ``p1``-branches is continued in ``p2`` with unknowns ``X = (x, p1)``::

    F(x, p1, p2) = 0
    g(x, p1, p2) = 0,   [[J, b], [c^T, 0]] [v; g] = [0; 1]

``g`` vanishes exactly where ``J = F_x`` is singular; ``b, c`` approximate
the left and right null vectors and are refreshed at every accepted point.
Its derivatives use the adjoint solve ``[[J^T, c], [b^T, 0]] [w; g] = [0; 1]``
(same LU, transposed): ``g_z = -w^T (J_z v)``, the second-derivative terms
``J_z v`` by central differences of the Jacobian along ``v`` (and of ``J v``
in the parameters). ``g`` itself is exact, so converged points are exact; the
differences only affect the Newton rate.

Two-parameter protocol: ``residual(x, p1, p2)``, ``tangent(x, p1, p2) ->
(J, F_p1, F_p2)``. A two-parameter problem on a mesh (``breakpoints``, ``k``,
``with_mesh(breakpoints, k)``, ``transfer(x, source)``, ``conform(breakpoints)``,
``interval_defect(x, p1, p2)``, ``outputs(x, p1, p2)`` and ``slice(p2)``, the
one-parameter meshed problem in ``p1`` at ``p2``, for the error estimate) makes the
fold problem a meshed problem of :mod:`rodcont.adaptive`: its mesh adapts as a
branch's does, carrying ``x``, ``p1`` and the null vector over.

Branch switching: at a simple branch point the kernel of ``[J, F_p]`` is
two-dimensional; the direction orthogonal to the incoming tangent (found by
inverse iteration on the bordered matrix) starts the new branch, as AUTO's
``ISW = -1`` does.
"""

from __future__ import annotations

import math

import numpy as np

from .linalg import LU, bordered


class FoldProblem:
    """The fold of ``problem2``'s ``p1``-branches as a one-parameter problem in ``p2``.

    Unknown vector ``X = (x, p1)``; ``residual(X, p2)`` and ``linearise(X, p2)``
    follow the tracker's protocol. ``v0``: a right null vector of ``J`` at the
    starting fold (the ``x`` part of the branch tangent there).
    """

    def __init__(self, problem2, x0: np.ndarray, p1: float, p2: float, v0: np.ndarray, eps: float = 1e-6):
        self.pb = problem2
        self.n = x0.size
        self.eps = eps
        v0 = np.asarray(v0, float)
        self.c = v0 / np.linalg.norm(v0)
        self.b = self._left_null_vector(problem2.tangent(x0, p1, p2)[0])

    def _left_null_vector(self, J) -> np.ndarray:
        """``J^T w = 0`` from the transposed bordered system with the right null vector as a trial border."""
        lu = LU(bordered(J, self.c, self.c, 0.0))
        e = np.zeros(self.n + 1)
        e[-1] = 1.0
        w = lu.solve(e, trans=True)[:-1]
        return w / np.linalg.norm(w)

    # ---- on a mesh (the meshed-problem protocol of rodcont.adaptive) --------------------
    @property
    def breakpoints(self):
        return self.pb.breakpoints

    @property
    def k(self) -> int:
        return self.pb.k

    def with_mesh(self, breakpoints, k: int | None = None) -> FoldProblem:
        """The same fold problem on another mesh: the right null vector carried over; the left one is
        made again at the first point evaluated there (the start of the next segment)."""
        new = FoldProblem.__new__(FoldProblem)
        new.pb, new.eps = self.pb.with_mesh(breakpoints, k), self.eps
        c = new.pb.transfer(self.c, self.pb)
        new.n, new.c, new.b = c.size, c / np.linalg.norm(c), None
        return new

    def transfer(self, X, source: FoldProblem) -> np.ndarray:
        """``X = (x, p1)`` (or a tangent of it) of ``source`` on this mesh: ``x`` carried over, ``p1`` kept."""
        X = np.asarray(X, float)
        return np.append(self.pb.transfer(X[:-1], source.pb), X[-1])

    def conform(self, breakpoints):
        return self.pb.conform(breakpoints)

    def interval_defect(self, X, p2):
        return self.pb.interval_defect(X[:-1], float(X[-1]), p2)

    def outputs(self, X, p2) -> dict:
        return self.pb.outputs(X[:-1], float(X[-1]), p2)

    def error_estimator(self):
        """The error of a fold point is that of the ``p1``-branch's point there, with the null vector as
        its tangent: the fold state re-solved in the richer space (:class:`rodcont.mesh.ErrorEstimator`)."""
        return _FoldError(self)

    def _ensure_left(self, J) -> None:
        if self.b is None:
            self.b = self._left_null_vector(J)

    # ---- the test function and its null vectors -------------------------------
    def _null_vectors(self, J):
        lu = LU(bordered(J, self.b, self.c, 0.0))
        e = np.zeros(self.n + 1)
        e[-1] = 1.0
        vg = lu.solve(e)
        wg = lu.solve(e, trans=True)
        return vg[:-1], wg[:-1], vg[-1]

    def test_function(self, x, p1, p2) -> float:
        J, _, _ = self.pb.tangent(x, p1, p2)
        self._ensure_left(J)
        return float(self._null_vectors(J)[2])

    def residual(self, X, p2):
        x, p1 = X[:-1], X[-1]
        F = self.pb.residual(x, p1, p2)
        return np.append(F, self.test_function(x, p1, p2))

    def linearise(self, X, p2):
        x, p1 = X[:-1], X[-1]
        F = self.pb.residual(x, p1, p2)
        J, F1, F2 = self.pb.tangent(x, p1, p2)
        self._ensure_left(J)
        v, w, g = self._null_vectors(J)
        # second-derivative terms by central differences along v (x) and in p1, p2
        hx = self.eps * (1.0 + np.max(np.abs(x))) / max(np.max(np.abs(v)), 1e-300)
        Jp = self.pb.tangent(x + hx * v, p1, p2)[0]
        Jm = self.pb.tangent(x - hx * v, p1, p2)[0]
        gx = -((Jp.T @ w) - (Jm.T @ w)) / (2 * hx)  # d/dx (w^T J v) = w^T J_x[v, .]
        g1 = -self._dJv(x, p1, p2, v, w, which=1)
        g2 = -self._dJv(x, p1, p2, v, w, which=2)
        Jbig = bordered(J, np.asarray(F1, float), gx, g1)
        Fp = np.append(np.asarray(F2, float), g2)
        return np.append(F, g), Jbig, Fp

    def tangent(self, X, p2):
        return self.linearise(X, p2)[1:]

    def _dJv(self, x, p1, p2, v, w, which):
        h = self.eps * (1.0 + abs(p1 if which == 1 else p2))
        if which == 1:
            Jp, Jm = self.pb.tangent(x, p1 + h, p2)[0], self.pb.tangent(x, p1 - h, p2)[0]
        else:
            Jp, Jm = self.pb.tangent(x, p1, p2 + h)[0], self.pb.tangent(x, p1, p2 - h)[0]
        return float(w @ ((Jp @ v) - (Jm @ v))) / (2 * h)

    def accept(self, X, p2) -> None:
        """Refresh the bordering vectors with the null vectors at an accepted point."""
        x, p1 = X[:-1], X[-1]
        J, _, _ = self.pb.tangent(x, p1, p2)
        self._ensure_left(J)
        v, w, _ = self._null_vectors(J)
        if np.all(np.isfinite(v)) and np.all(np.isfinite(w)) and np.linalg.norm(v) > 0 and np.linalg.norm(w) > 0:
            self.c = v / np.linalg.norm(v)
            self.b = w / np.linalg.norm(w)


class _FoldError:
    """The estimated error of the fold points of a :class:`FoldProblem` (see its ``error_estimator``)."""

    def __init__(self, fp: FoldProblem):
        self.fp, self.estimator = fp, None

    def estimate(self, X, p2, tangent=None) -> float:
        one = self.fp.pb.slice(p2)
        if self.estimator is None:
            from .mesh import ErrorEstimator
            self.estimator = ErrorEstimator(one)
        return self.estimator.estimate(np.asarray(X[:-1]), float(X[-1]), (self.fp.c, 0.0))


def bifurcating_direction(J, Fp, tx, tp, wx: float, wp: float, iterations: int = 4):
    """Direction of the second branch at a simple branch point.

    ``[J, F_p]`` has a two-dimensional kernel there, spanned by the incoming
    tangent ``t0 = (tx, tp)`` and a second vector ``t1``; ``t1`` is the null
    vector of the (nearly singular) matrix ``[[J, F_p], [t0^T]]`` found by
    inverse iteration, orthogonalised against ``t0`` in the arclength inner
    product ``wx x.y + wp p q`` and normalised in it.
    """
    A = bordered(J, np.asarray(Fp, float), np.asarray(wx, float) * np.asarray(tx), wp * float(tp))
    lu = LU(A)
    n = tx.size
    rng = np.random.default_rng(7)
    y = rng.standard_normal(n + 1)
    for _ in range(iterations):
        y = lu.solve(y)
        y /= np.linalg.norm(y)
    t0 = np.append(tx, tp)
    W = np.append(np.broadcast_to(np.asarray(wx, float), (n,)), wp)
    y = y - (W * y @ t0) / (W * t0 @ t0) * t0
    y /= math.sqrt(W * y @ y)
    return y[:-1], float(y[-1])
