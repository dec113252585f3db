"""The bordered solver (block elimination on the LU of J, rodcont.linalg.BorderedSolver) against independent
solutions: dense LAPACK on small matrices, and, at the exact fold of a finite-difference Bratu problem (J
singular to rounding), a reference refined with residuals in extended precision; its fill against the
LU of the whole bordered matrix, which pulls the dense border row into its factors."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

from rodcont import linalg
from rodcont.linalg import (
    LU,
    BorderedSolver,
    SingularMatrix,
    bordered,
    bordered_solver,
    full_bordered_lu,
)


def reference(M, f, steps=6):
    """``M^-1 f`` by iterative refinement with residuals in extended precision (``longdouble``)."""
    lu = spla.splu(sp.csc_matrix(M), permc_spec="COLAMD")
    Ml = sp.csr_matrix(M).astype(np.longdouble)
    z = lu.solve(f).astype(np.longdouble)
    for _ in range(steps):
        z = z + lu.solve((np.asarray(f, np.longdouble) - Ml @ z).astype(float)).astype(np.longdouble)
    return z.astype(float)


def rel_error(z, ref):
    return float(np.max(np.abs(z - ref)) / np.max(np.abs(ref)))


# --------------------------------------------------------------------------
# Small matrices against dense LAPACK
# --------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_solve_det_and_row_change_match_dense_lapack(seed):
    rng = np.random.default_rng(seed)
    n = 12
    J = sp.random(n, n, density=0.3, random_state=seed, format="csc") + sp.diags(rng.uniform(0.5, 2, n))
    b, c, d = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal()
    M = bordered(J, b, c, d).toarray()
    s = bordered_solver(J, b, c, d)
    f = rng.standard_normal(n + 1)
    np.testing.assert_allclose(s.solve(f), np.linalg.solve(M, f), rtol=1e-11, atol=1e-12)
    sign, log = np.linalg.slogdet(M)
    assert s.det()[0] == sign and s.det()[1] == pytest.approx(log, rel=1e-11, abs=1e-11)
    new = rng.standard_normal(n + 1)
    t = s.with_last_row(np.append(c, d), new)
    M2 = M.copy()
    M2[-1] = new
    np.testing.assert_allclose(t.solve(f), np.linalg.solve(M2, f), rtol=1e-10, atol=1e-11)
    assert t.det()[0] == np.linalg.slogdet(M2)[0]
    assert t.lu is s and s.lu is None  # the tracker's chord takes the solver a row change came from


def test_exactly_singular_bordered_matrices_raise():
    """Where the bordered matrix is exactly singular the solver says so, as the LU of the whole matrix did:
    J and M singular (x^3 - p x = 0 at its branch point x = p = 0), and J regular with ``s = d - c.J^-1 b = 0``."""
    J = sp.csc_matrix(np.array([[0.0, 0.0], [0.0, 1.0]]))
    with pytest.raises(SingularMatrix):
        LU(bordered(J, np.array([0.0, -1.0]), np.array([0.3, 0.2]), 0.5))
    with pytest.raises(SingularMatrix):
        bordered_solver(J, np.array([0.0, -1.0]), np.array([0.3, 0.2]), 0.5)
    with pytest.raises(SingularMatrix):
        bordered_solver(sp.identity(3, format="csc"), np.array([1.0, 0, 0]), np.array([1.0, 0, 0]), 1.0)


def test_exactly_singular_J_in_a_regular_bordered_matrix_is_solved():
    """A fold hit to the last bit: J has a zero pivot, M is regular; the solver falls back to the LU of M."""
    J = sp.csc_matrix(np.diag([0.0, 2.0, 3.0]))
    b, c, d = np.array([1.0, 0.5, 0.0]), np.array([1.0, 0.0, 0.25]), 0.0
    M = bordered(J, b, c, d).toarray()
    s = bordered_solver(J, b, c, d)
    f = np.array([1.0, -2.0, 0.5, 3.0])
    np.testing.assert_allclose(s.solve(f), np.linalg.solve(M, f), rtol=1e-13)
    assert s.det()[0] == np.linalg.slogdet(M)[0]
    assert s.det()[1] == pytest.approx(np.linalg.slogdet(M)[1], rel=1e-13)


# --------------------------------------------------------------------------
# Finite-difference Bratu at its exact fold
# --------------------------------------------------------------------------
def fd_bratu_fold(n):
    """The fold of ``u_{i-1} - 2 u_i + u_{i+1} + h^2 lam e^{u_i} = 0`` (``u_0 = u_{n+1} = 0``): Newton on
    ``F = 0, J phi = 0, l.phi = 1`` (Moore and Spence), from the continuous fold's closed form."""
    h = 1.0 / (n + 1)
    S = np.linspace(0.0, 1.0, n + 2)[1:-1]
    lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc") / h**2
    q = brentq(lambda q: q * math.tanh(q) - 1.0, 0.5, 2.0)  # theta / 4 at the continuous fold
    u = -2 * np.log(np.cosh((S - 0.5) * 2 * q) / math.cosh(q))
    lam, phi = 8 * (q / math.cosh(q)) ** 2, np.sin(np.pi * S)
    ell = phi / (phi @ phi)
    for _ in range(8):
        e = np.exp(u)
        J = lap + sp.diags(lam * e)
        A = sp.bmat([[J, None, e[:, None]], [sp.diags(lam * e * phi), J, (e * phi)[:, None]],
                     [None, ell[None, :], None]], format="csc")
        step = spla.spsolve(A, -np.concatenate([lap @ u + lam * e, J @ phi, [ell @ phi - 1.0]]))
        u, phi, lam = u + step[:n], phi + step[n:2 * n], lam + step[-1]
        if np.max(np.abs(step)) < 1e-12:
            break
    return u, lam, phi


def fd_bratu_matrices(n, scaled):
    """``J`` and ``F_lam`` at the fold (scaled: the ``1/h^2`` form), the tracker's border row there (the
    tangent ``(phi, 0)`` weighted as the arclength, theta = 1/2) and a border of a point before the fold."""
    u, lam, phi = fd_bratu_fold(n)
    h2 = (1.0 / (n + 1)) ** 2
    scale = 1.0 / h2 if scaled else 1.0
    lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc")
    J = (scale * (lap + sp.diags(h2 * lam * np.exp(u)))).tocsc()
    Fp = scale * h2 * np.exp(u)
    w = 0.5 / n
    t = phi / math.sqrt(w * (phi @ phi))
    S = np.linspace(0.0, 1.0, n + 2)[1:-1]
    t2 = t + 0.3 * np.sin(2 * np.pi * S) / math.sqrt(w * n)
    return J, Fp, (w * t, 0.0), (w * t2, 0.5 * 0.3)


@pytest.mark.parametrize("scaled", [False, True])
def test_at_the_exact_fold_of_fd_bratu_the_solve_is_as_accurate_as_an_lu_of_the_whole_matrix(scaled):
    """J singular to rounding (its smallest pivot 1e-13 of the largest); elimination alone loses digits
    along J's null vector (measured 1e-1 of the solution), the solver's refinement brings it to the LU's
    accuracy; the determinant's sign is the LU's; the factors hold J's LU only."""
    n = 2000
    J, Fp, (c, d), (c2, d2) = fd_bratu_matrices(n, scaled)
    U = spla.splu(J, permc_spec="NATURAL").U.diagonal()
    assert np.min(np.abs(U)) < 1e-10 * np.max(np.abs(U))  # J is singular to rounding
    rng = np.random.default_rng(3)
    for row, drow in ((c, d), (c2, d2)):
        M = bordered(J, Fp, row, drow)
        s, whole = BorderedSolver(J, Fp, row, drow), LU(M)
        for f in (np.eye(1, n + 1, n).ravel(), rng.standard_normal(n + 1)):
            ref = reference(M, f)
            err, err_lu = rel_error(s.solve(f), ref), rel_error(whole.solve(f), ref)
            assert err <= 10 * err_lu + 1e-12, (err, err_lu)
        assert s.det()[0] == whole.det()[0]
        assert s.det()[1] == pytest.approx(whole.det()[1], rel=1e-9)
        assert s.fallbacks == 0 and s.factor_nonzeros() <= 5 * M.nnz
    # elimination alone (no refinement) is what refinement repairs
    f = rng.standard_normal(n + 1)
    M = bordered(J, Fp, c, d)
    assert rel_error(BorderedSolver(J, Fp, c, d)._eliminate(f), reference(M, f)) > 1e-6


def test_the_border_row_fills_an_lu_of_the_whole_matrix_and_not_the_solver():
    """Unscaled FD Bratu at its fold, n = 2000: a natural-order LU of the bordered matrix holds 50 times its
    nonzeros (the dense border row drawn into the pivots); the solver J's own (1.1 times), and its fallback,
    the LU with the border row scaled by 2^-40, stays near that."""
    n = 2000
    J, Fp, _, (c2, d2) = fd_bratu_matrices(n, scaled=False)
    M = bordered(J, Fp, c2, d2)
    whole = spla.splu(M, permc_spec="NATURAL")
    assert whole.L.nnz + whole.U.nnz > 20 * M.nnz
    s = BorderedSolver(J, Fp, c2, d2)
    assert s.factor_nonzeros() <= 1.5 * M.nnz
    s._factorise_full()  # the fallback's factors, forced here
    assert s.factor_nonzeros() <= 5 * M.nnz
    f = np.random.default_rng(0).standard_normal(n + 1)
    assert rel_error(s._solve_full_refined(f), reference(M, f)) < 1e-9


def test_a_solve_that_refinement_cannot_repair_falls_back_to_the_whole_matrix(monkeypatch):
    """With refinement disabled and a tolerance no solve meets, every solve goes to the LU of M (its
    fallback), and is right."""
    monkeypatch.setattr(linalg, "MAX_REFINE", 0)
    monkeypatch.setattr(linalg, "BACKWARD_TOL", -1.0)
    n = 2000
    J, Fp, (c, d), _ = fd_bratu_matrices(n, scaled=True)
    s = BorderedSolver(J, Fp, c, d)
    f = np.random.default_rng(1).standard_normal(n + 1)
    M = bordered(J, Fp, c, d)
    ref = reference(M, f)
    assert rel_error(s.solve(f), ref) <= 10 * rel_error(LU(M).solve(f), ref) + 1e-12
    assert s.fallbacks == 1 and s.det()[0] == LU(M).det()[0]


# --------------------------------------------------------------------------
# A collocation problem at its located fold
# --------------------------------------------------------------------------
def test_at_the_located_fold_of_collocation_bratu_the_solve_matches_the_whole_lu():
    """Bratu's u'' + lam e^u = 0 on the collocation core (rows scaled by 1/h^2), at the fold the tracker
    locates (|dp/ds| < 1e-10): the tangent solve, a random solve and the determinant's sign as the LU of the
    whole matrix gives them; the old solver (full_bordered_lu) still available."""
    from rodcont.collocation import BVProblem, Collocation
    from rodcont.continuation import ContinuationSettings, Tracker
    pb = BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                   bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"])
    disc = Collocation(pb, 60, 5)

    class Problem:
        def residual(self, x, lam):
            return disc.residual(x, [lam])

        def linearise(self, x, lam):
            F, J, (Fp,) = disc.linearise(x, [lam], [0])
            return F, J, Fp

    s = ContinuationSettings(ds=0.1, ds_max=0.5, p_max=3.6, p_min=0.0, max_steps=200)
    pts = list(Tracker(Problem(), np.zeros(disc.size), 0.0, s))
    fold = next(q for q in pts if q.kind == "fold")
    assert abs(fold.tp) < 1e-10
    _, J, (Fp,) = disc.linearise(fold.x, [fold.p], [0])
    w = 0.5 / disc.size
    c, d = w * fold.tx, 0.5 * fold.tp
    M = bordered(J, Fp, c, d)
    solver, whole = BorderedSolver(J, Fp, c, d), full_bordered_lu(J, Fp, c, d)
    rng = np.random.default_rng(4)
    for f in (np.eye(1, disc.size + 1, disc.size).ravel(), rng.standard_normal(disc.size + 1)):
        ref = reference(M, f)
        assert rel_error(solver.solve(f), ref) <= 10 * rel_error(whole.solve(f), ref) + 1e-12
    assert solver.det()[0] == whole.det()[0]
    assert solver.factor_nonzeros() <= 5 * M.nnz


# --------------------------------------------------------------------------
# The tracker's default solver (a problem without a bordered_solver hook)
# --------------------------------------------------------------------------
def test_the_tracker_traces_fd_bratu_through_its_fold_without_filling(monkeypatch):
    """Unscaled FD Bratu, n = 6000, a problem with no hook: the tracker's solvers are block eliminations
    whose factors stay J's (at most 1.5 times the bordered matrix's nonzeros; an LU of that matrix holds 50
    times them, test_the_border_row_fills_an_lu_of_the_whole_matrix_and_not_the_solver), and the fold it
    locates is the discrete fold found by Moore-Spence's extended system (fd_bratu_fold) to 1e-9."""
    import sys

    from rodcont.continuation import ContinuationSettings, Tracker
    continuation = sys.modules["rodcont.continuation"]  # (the package's name `continuation` is its function)
    n = 6000
    h2 = (1.0 / (n + 1)) ** 2
    lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csc")

    class FD:
        def residual(self, u, lam):
            return lap @ u + h2 * lam * np.exp(u)

        def linearise(self, u, lam):
            e = h2 * np.exp(u)
            return lap @ u + lam * e, (lap + sp.diags(lam * e)).tocsc(), e

    made = []

    def counted(J, b, c, d):
        s = linalg.bordered_solver(J, b, c, d)
        made.append(s.factor_nonzeros() / (J.nnz + 2 * J.shape[0] + 1))
        return s

    monkeypatch.setattr(continuation, "bordered_solver", counted)
    s = ContinuationSettings(ds=0.2, ds_max=0.5, p_max=3.6, p_min=0.5, max_steps=80)
    pts = list(Tracker(FD(), np.zeros(n), 0.5, s))
    fold = next(q for q in pts if q.kind == "fold")
    assert made and max(made) <= 1.5
    assert abs(fold.p - fd_bratu_fold(n)[1]) < 1e-9


def test_an_lu_with_a_row_scale_solves_and_takes_the_determinant_of_the_matrix_itself(monkeypatch):
    """LU(A, row_scale=r) factorises R A (powers of two: formed exactly, its pattern and explicit zeros kept) and
    answers for A: its solves, transposed solves and determinant against numpy's dense ones, on a matrix whose
    rows span 1e-6 .. 1e6; and full_bordered_lu scales J's rows, not the border row."""
    rng = np.random.default_rng(5)
    A = np.diag(rng.uniform(1, 2, 30)) + 0.1 * rng.standard_normal((30, 30))
    A[3, 7] = 0.0
    A = np.logspace(-6, 6, 30)[:, None] * A
    As = sp.csc_matrix((A.ravel(), np.nonzero(np.ones_like(A))), shape=A.shape)  # A[3, 7]: an explicit zero
    r = linalg.powers_of_two(np.abs(A).max(axis=1))
    assert np.all(np.frexp(r)[0] == 0.5)
    assert np.all((0.5 <= r * np.abs(A).max(axis=1)) & (r * np.abs(A).max(axis=1) <= 2))
    factorised, splu = [], spla.splu
    monkeypatch.setattr(spla, "splu", lambda B, **kw: factorised.append(B) or splu(B, **kw))
    lu = LU(As, row_scale=r)
    assert As.nnz == 30 * 30 and np.array_equal(factorised[0].indices, As.indices)
    assert np.array_equal(factorised[0].toarray(), r[:, None] * A)
    b = rng.standard_normal(30)
    assert np.allclose(lu.solve(b), np.linalg.solve(A, b), rtol=1e-10, atol=0)
    assert np.allclose(lu.solve(b, trans=True), np.linalg.solve(A.T, b), rtol=1e-10, atol=0)
    sign, log = np.linalg.slogdet(A)
    assert lu.det()[0] == sign and lu.det()[1] == pytest.approx(log, rel=1e-12)
    assert list(linalg.powers_of_two([0.0, np.inf, 3.0, 0.25])) == [1.0, 1.0, 0.25, 4.0]
    J = sp.csc_matrix(A[:-1, :-1])
    M = full_bordered_lu(J, A[:-1, -1], A[-1, :-1], A[-1, -1], row_scale=r[:-1])
    assert np.array_equal(M._r, np.append(r[:-1], 1.0))
    assert np.allclose(M.solve(b), np.linalg.solve(A, b), rtol=1e-10, atol=0)
