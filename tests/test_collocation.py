"""Tests of the generic Gauss-collocation core ``rodcont.collocation``.

Every test compares against something independent of the implementation:
exact solutions, convergence theory (Ascher, Christiansen & Russell 1979;
de Boor & Swartz 1973), finite differences, or exact polynomial reproduction.

Convergence theory used (k Gauss points per subinterval, field of order m in
P_{k+m} ∩ C^{m-1}, smooth exact solution, uniform mesh h = 1/N):

* uniform error of the j-th derivative:  O(h^{min(k+m-j, 2k)})   (0 <= j <= m)
* error of u^(j), j < m, at mesh points: O(h^{2k})               (superconvergence)

For k >= m (all cases below) the uniform order is k + m - j.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.polynomial import chebyshev as C
from scipy.optimize import brentq

from rodcont.collocation import (
    BVProblem,
    Collocation,
    NewtonResult,
    SplineSpace,
    gauss_points,
    newton_solve,
)
from rodcont.linalg import chord_solve

NOP = np.zeros(0)  # parameter vector of problems without parameters


def observed_orders(errors):
    """log2 of successive error ratios (meshes halved each time)."""
    e = np.asarray(errors, float)
    return np.log2(e[:-1] / e[1:])


# --------------------------------------------------------------------------
# A linear mixed-order problem with known exact solution
#     u'' + (1 + S) v = f1,     v' - u = f2,     S in [0, 1]
#     u(0) = u*(0),  u'(1) = u*'(1),  v(1) = v*(1)
# exact solution u* = sin(pi S) + e^S / 2,  v* = cos(2 S); the observed
# convergence to u*, v* itself shows the problem is well posed.
# --------------------------------------------------------------------------
def u_exact(S, d=0):
    S = np.asarray(S, float)
    e = np.exp(S) / 2
    return [np.sin(np.pi * S) + e,
            np.pi * np.cos(np.pi * S) + e,
            -np.pi ** 2 * np.sin(np.pi * S) + e,
            -np.pi ** 3 * np.cos(np.pi * S) + e][d]


def v_exact(S, d=0):
    S = np.asarray(S, float)
    return [np.cos(2 * S), -2 * np.sin(2 * S), -4 * np.cos(2 * S)][d]


def _lin_residual(S, z, p):
    u, du, ddu, v, dv = z
    f1 = u_exact(S, 2) + (1 + S) * v_exact(S)
    f2 = v_exact(S, 1) - u_exact(S)
    return np.array([ddu + (1 + S) * v - f1, dv - u - f2])


def _lin_bc(za, zb, p):
    return np.array([za[0] - u_exact(0.0), zb[1] - u_exact(1.0, 1), zb[3] - v_exact(1.0)])


LINEAR = BVProblem(orders=[2, 1], residual=_lin_residual, bc=_lin_bc, interval=(0.0, 1.0),
                   names=["u", "v"])


def solve_linear(N, k):
    c = Collocation(LINEAR, N, k)
    r = c.newton(np.zeros(c.size), NOP)
    assert r.converged, r.message
    return c, r.x


# --------------------------------------------------------------------------
# Bratu:  u'' + lam e^u = 0,  u(0) = u(1) = 0
# --------------------------------------------------------------------------
def _bratu_residual(S, z, p):
    return np.array([z[2] + p[0] * np.exp(z[0])])


def _bratu_bc(za, zb, p):
    return np.array([za[0], zb[0]])


BRATU = BVProblem(orders=[2], residual=_bratu_residual, bc=_bratu_bc, interval=(0.0, 1.0),
                  params=["lam"])


def bratu_exact(lam, upper=False):
    """u = -2 log(cosh((S - 1/2) theta/2) / cosh(theta/4)), theta = sqrt(2 lam) cosh(theta/4)."""
    g = lambda t: t - np.sqrt(2 * lam) * np.cosh(t / 4)
    # g(0) < 0; g has its maximum at sinh(t/4) = 4/sqrt(2 lam) and two roots for lam < lam_c
    t_max = 4 * np.arcsinh(4 / np.sqrt(2 * lam))
    theta = brentq(g, t_max, 40.0, xtol=1e-15) if upper else brentq(g, 0.0, t_max, xtol=1e-15)
    return lambda S: -2 * np.log(np.cosh((np.asarray(S) - 0.5) * theta / 2) / np.cosh(theta / 4))


# ==========================================================================
# 1. Convergence orders on the linear mixed-order problem
# ==========================================================================
S_FINE = np.linspace(0.0, 1.0, 2001)

# Mesh sequences chosen so that every error stays >= ~1e-12 (well above rounding,
# which is ~1e-14 here) and every pair is in the asymptotic regime.
UNIFORM_MESHES = {2: [4, 8, 16, 32], 3: [4, 8, 16, 32], 4: [4, 8, 16]}
MESHPOINT_MESHES = {2: [4, 8, 16, 32], 3: [4, 8, 16], 4: [2, 4, 8]}


@pytest.mark.parametrize("k", [2, 3, 4])
def test_uniform_error_order_is_k_plus_m(k):
    eu, ev = [], []
    for N in UNIFORM_MESHES[k]:
        c, x = solve_linear(N, k)
        eu.append(np.max(np.abs(c.evaluate(x, S_FINE, 0) - u_exact(S_FINE))))
        ev.append(np.max(np.abs(c.evaluate(x, S_FINE, 1) - v_exact(S_FINE))))
    assert min(eu + ev) > 1e-12  # not at rounding level: the measured orders are meaningful
    for err, m in ((eu, 2), (ev, 1)):
        q = observed_orders(err)
        theory = k + m
        # margin 0.3: pre-asymptotic terms are O(h) relative; the upper bound
        # checks that the rate really is k+m (the space is P_{k+m}, no more)
        assert np.all(q >= theory - 0.3), (m, q)
        assert q[-1] <= theory + 0.5, (m, q)


@pytest.mark.parametrize("k", [2, 3, 4])
def test_mesh_point_superconvergence_order_2k(k):
    errs = {"u": [], "u'": [], "v": []}
    for N in MESHPOINT_MESHES[k]:
        c, x = solve_linear(N, k)
        b = c.breakpoints
        errs["u"].append(np.max(np.abs(c.evaluate(x, b, 0, 0) - u_exact(b))))
        errs["u'"].append(np.max(np.abs(c.evaluate(x, b, 0, 1) - u_exact(b, 1))))
        errs["v"].append(np.max(np.abs(c.evaluate(x, b, 1, 0) - v_exact(b))))
    for name, err in errs.items():
        assert min(err) > 1e-12, (name, err)
        q = observed_orders(err)
        assert np.all(q >= 2 * k - 0.3), (name, q)
        assert q[-1] <= 2 * k + 0.5, (name, q)


# ==========================================================================
# 7. evaluate / derivatives at arbitrary S; SplineSpace structure
# ==========================================================================
def test_evaluate_derivatives_at_arbitrary_points_converge_at_theoretical_rates():
    k = 3
    S = np.sort(np.random.default_rng(7).uniform(0.0, 1.0, 3000))
    cases = {  # (field, derivative): theoretical order k + m - j
        (0, 0): k + 2, (0, 1): k + 1, (0, 2): k, (1, 0): k + 1, (1, 1): k,
    }
    exact = {(0, j): u_exact(S, j) for j in range(3)} | {(1, j): v_exact(S, j) for j in range(2)}
    errs = {key: [] for key in cases}
    for N in [8, 16, 32]:
        c, x = solve_linear(N, k)
        for (i, j) in cases:
            val = c.evaluate(x, S, i, j)
            # the sparse evaluation matrix is the same linear map, computed another way
            # (derivative recurrence on the coefficients, each step scaling rounding by
            # about degree/h): agreement to eps * (4 N)^j * |x|, here <= 1e-10 relative
            h_scale = (4.0 * N) ** j
            np.testing.assert_allclose(c.evaluation_matrix(S, i, j) @ x, val, rtol=0,
                                       atol=1e-15 * h_scale * max(np.max(np.abs(x)), 1.0) * 10)
            errs[(i, j)].append(np.max(np.abs(val - exact[(i, j)])))
    for key, theory in cases.items():
        q = observed_orders(errs[key])
        # 3000 random points, ~30 per subinterval: the sampled max is within a
        # few % of the true max, i.e. well inside the 0.3 margin on the order
        assert np.all(q >= theory - 0.3), (key, q)
        assert q[-1] <= theory + 0.5, (key, q)


def test_evaluate_at_interval_ends_is_finite_and_exact_for_bcs():
    c, x = solve_linear(8, 4)
    # boundary conditions hold exactly (to rounding) at the ends
    assert abs(c.evaluate(x, 0.0, 0) - u_exact(0.0)) < 1e-12
    assert abs(c.evaluate(x, 1.0, 0, 1) - u_exact(1.0, 1)) < 1e-12
    assert abs(c.evaluate(x, 1.0, 1) - v_exact(1.0)) < 1e-12
    za, zb = c.end_jets(x)
    np.testing.assert_allclose(za[[0, 1, 3]], [c.evaluate(x, 0.0, 0), c.evaluate(x, 0.0, 0, 1),
                                               c.evaluate(x, 0.0, 1)], rtol=1e-13, atol=1e-13)


def _random_breakpoints(rng, N, a=0.0, b=1.0):
    w = rng.uniform(0.3, 1.0, N)  # subinterval lengths within a factor ~3 of each other
    return a + (b - a) * np.concatenate([[0.0], np.cumsum(w) / np.sum(w)])


def _piece_polynomials(space, coef, nu_max):
    """Independent reconstruction of each polynomial piece: fit (exactly) the degree-d
    polynomial to d+1 Chebyshev points inside the subinterval, return the values of
    derivatives 0..nu_max at both ends of each piece."""
    s = lambda xs: space.evaluate(coef, xs)  # noqa: E731
    d = space.degree
    b = space.breakpoints
    left, right = [], []
    for lo, hi in zip(b[:-1], b[1:]):
        t = np.cos(np.pi * (np.arange(d + 1) + 0.5) / (d + 1))
        xs = lo + (hi - lo) * (t + 1) / 2
        P = np.polynomial.Polynomial.fit(xs, s(xs), d, domain=[lo, hi])
        left.append([P.deriv(nu)(lo) if nu else P(lo) for nu in range(nu_max + 1)])
        right.append([P.deriv(nu)(hi) if nu else P(hi) for nu in range(nu_max + 1)])
    return np.array(left), np.array(right)  # (N, nu_max+1)


@pytest.mark.parametrize("k,m", [(1, 1), (2, 1), (3, 2), (4, 3), (5, 4), (7, 2), (2, 4)])
def test_spline_space_dimension_and_continuity(k, m):
    rng = np.random.default_rng(100 * k + m)
    N = 5
    b = _random_breakpoints(rng, N)
    s = SplineSpace(b, k, m)
    assert s.dim == N * k + m
    assert s.order == k + m and s.degree == k + m - 1
    # the basis is linearly independent: full column rank on a fine sample
    B = s.basis(np.linspace(0, 1, 20 * s.dim))
    assert B.shape == (20 * s.dim, s.dim)
    assert np.linalg.matrix_rank(B) == s.dim
    # partition of unity
    np.testing.assert_allclose(B.sum(axis=1), 1.0, rtol=0, atol=1e-13)

    coef = rng.normal(size=s.dim)
    left, right = _piece_polynomials(s, coef, m)
    jumps = np.abs(left[1:] - right[:-1])  # (N-1, m+1) jump of derivative nu at interior breakpoints
    scale = np.max(np.abs(np.concatenate([left, right])), axis=0)  # per derivative order
    # C^{m-1}: derivatives 0..m-1 continuous, to rounding of the piece fits (cond ~ 10^2-10^4)
    assert np.all(jumps[:, :m] <= 1e-8 * scale[:m]), jumps[:, :m] / scale[:m]
    # ... but not C^m: the m-th derivative jumps (interior knots have multiplicity k exactly)
    assert np.all(jumps[:, m] >= 1e-4 * scale[m]), jumps[:, m] / scale[m]
    # the derivative basis agrees with the reconstructed pieces just inside each subinterval
    for nu in range(m + 1):
        np.testing.assert_allclose(s.basis(b[:-1], nu) @ coef, left[:, nu], rtol=1e-8,
                                   atol=1e-8 * scale[nu])


def test_gauss_points_integrate_degree_2k_minus_1_exactly():
    rng = np.random.default_rng(3)
    b = _random_breakpoints(rng, 4, -1.0, 2.0)
    for k in range(1, 8):
        S, W = gauss_points(b, k)
        assert S.shape == W.shape == (4 * k,)
        assert np.all(np.diff(S) > 0) and np.all((S > b[0]) & (S < b[-1]))
        # each subinterval holds exactly k points
        assert np.all(np.histogram(S, bins=b)[0] == k)
        for deg in range(2 * k):
            exact = (b[-1] ** (deg + 1) - b[0] ** (deg + 1)) / (deg + 1)
            assert abs(W @ S ** deg - exact) <= 1e-13 * max(1.0, 2.0 ** deg)
        # and not degree 2k: on [0, 1] the Gauss error for S^(2k) is exactly
        # (k!)^4 / ((2k+1) ((2k)!)^2)  (Davis & Rabinowitz, f^(2k) = (2k)! constant)
        S1, W1 = gauss_points(np.array([0.0, 1.0]), k)
        theory = math.factorial(k) ** 4 / ((2 * k + 1) * math.factorial(2 * k) ** 2)
        assert abs((1 / (2 * k + 1) - W1 @ S1 ** (2 * k)) / theory - 1) < 1e-6


# ==========================================================================
# 2. The tangent operator
# ==========================================================================
def _nl_residual(S, z, p):
    u, du, ddu, dddu, v, dv = z
    return np.array([
        dddu + p[0] * np.sin(du) * v + u * v ** 2 - p[1] * S * np.cos(ddu) + p[2] * u,
        dv - p[1] * np.exp(u * p[0]) + ddu ** 2 + S ** 2 * v * p[2] ** 2,
    ])


def _nl_bc(za, zb, p):
    return np.array([
        za[0] - p[0] * zb[4],
        za[1] * zb[0] - 1 + p[2],
        zb[2] + za[4] ** 2 * p[1],
        za[3] * zb[1] - p[2] ** 2,
        zb[0] + za[4] * np.exp(zb[4]) - p[1],
    ])


# third-order + first-order nonlinear system, third parameter free
NONLINEAR = BVProblem(orders=[3, 1], residual=_nl_residual, bc=_nl_bc, interval=(0.0, 1.0),
                      params=["a", "b", "c"], free=[2])
# Bratu does not depend on u': exercises the skipping of unused jet components
TANGENT_CASES = {
    "mixed-3-1-free": (NONLINEAR, np.array([0.7, 1.3, 123.0]), [0, 1]),
    "bratu": (BRATU, np.array([2.1]), [0]),
}


def _fd_jacobian(fun, x, h_rel):
    J = np.empty((fun(x).size, x.size))
    for j in range(x.size):
        h = h_rel * max(1.0, abs(x[j]))
        e = np.zeros_like(x)
        e[j] = h
        J[:, j] = (fun(x + e) - fun(x - e)) / (2 * h)
    return J


@pytest.mark.parametrize("case", list(TANGENT_CASES))
def test_assembled_jacobian_matches_central_differences(case):
    pb, p, dparams = TANGENT_CASES[case]
    c = Collocation(pb, 3, 3)
    x = 0.1 * np.random.default_rng(11).normal(size=c.size)
    F, J, dFp = c.linearise(x, p, dparams=dparams)
    assert sp.issparse(J) and J.shape == (c.size, c.size) and J.nnz <= c.nnz
    np.testing.assert_array_equal(F, c.residual(x, p))
    assert np.array_equal(J.toarray(), c.jacobian(x, p).toarray())
    Jd = J.toarray()
    Jfd = _fd_jacobian(lambda y: c.residual(y, p), x, 1e-6)
    # Central differences: truncation h^2/6 |F'''| ~ 1e-12 |J|, rounding eps |F| / h ~ 1e-10 |F|.
    # Per row, both are far below 1e-7 of the row's largest entry; a wrong, missing or
    # misplaced entry (including one outside the sparsity pattern) is O(1) of that scale.
    row_scale = np.max(np.abs(Jfd), axis=1, keepdims=True)
    assert np.all(row_scale > 0)
    err = np.abs(Jd - Jfd) / row_scale
    assert np.max(err) < 1e-7, np.unravel_index(np.argmax(err), err.shape)
    # the free-parameter column is a genuine (non-zero) column of J
    for j in c.free_index:
        assert np.max(np.abs(Jd[:, j])) > 0

    # parameter derivatives dF/dp_j against central differences in p
    assert len(dFp) == len(dparams)
    F_scale = np.max(np.abs(F))
    for j, d in zip(dparams, dFp):
        h = 1e-4
        e = np.zeros_like(p)
        e[j] = h
        fd = (c.residual(x, p + e) - c.residual(x, p - e)) / (2 * h)
        # truncation h^2/6 |d^3F/dp^3| ~ 1e-9 |dF/dp|; rounding eps |F| / h ~ 2e-12 |F|
        assert np.max(np.abs(d - fd)) <= 1e-7 * max(np.max(np.abs(fd)), 1e-3 * F_scale), j
        assert np.max(np.abs(fd)) > 0


def test_newton_with_the_assembled_jacobian_converges_fast_on_bratu():
    # Bratu lower branch: with an exact Jacobian Newton from u = 0 converges quadratically
    # (|u*| ~ 0.14, well inside the basin): a handful of iterations
    c = Collocation(BRATU, 8, 4)
    r = c.newton(np.zeros(c.size), np.array([1.0]))
    assert r.converged and r.iterations <= 6, r
    assert r.residual_norm < 1e-10


def test_pointwise_complex_step_jacobian_matches_central_differences():
    pb, p = NONLINEAR, np.array([0.7, 1.3, 0.4])
    c = Collocation(pb, 2, 2)
    rng = np.random.default_rng(5)
    nz, npts = pb.jet_size, 7
    S = rng.uniform(0, 1, npts)
    z = rng.uniform(-1, 1, (nz, npts))
    G, dG = c._pointwise_jacobian(S, z, p, np.arange(nz))
    np.testing.assert_allclose(G, pb.residual(S, z, p), rtol=1e-15, atol=1e-15)
    assert dG.shape == (2, nz, npts)
    for j in range(nz):
        h = 1e-5
        zp, zm = z.copy(), z.copy()
        zp[j] += h
        zm[j] -= h
        fd = (pb.residual(S, zp, p) - pb.residual(S, zm, p)) / (2 * h)
        # truncation h^2/6 |G'''| <~ 1e-10 * O(1) (G entries are O(1) functions of O(1) data)
        np.testing.assert_allclose(dG[:, j, :], fd, rtol=0, atol=1e-8)
    # the derivative with respect to a component G does not depend on is exactly 0
    c_b = Collocation(BRATU, 2, 2)
    Gb, dGb = c_b._pointwise_jacobian(S, z[:3], np.array([2.0]), np.arange(3))
    assert np.all(dGb[:, 1, :] == 0.0)
    np.testing.assert_allclose(dGb[0, 0], 2.0 * np.exp(z[0]), rtol=1e-14)
    np.testing.assert_allclose(dGb[0, 2], 1.0, rtol=0, atol=0)


# ==========================================================================
# 3. Free scalar parameter: eigenvalue problem
# ==========================================================================
def _eig_residual(S, z, p):
    return np.array([z[2] + p[0] * z[0]])


def _eig_bc(za, zb, p):
    return np.array([za[0], zb[0], za[1] - 1.0])


EIGEN = BVProblem(orders=[2], residual=_eig_residual, bc=_eig_bc, interval=(0.0, 1.0),
                  params=["lam"], free=[0])


def test_free_eigenvalue_converges_to_pi_squared():
    c = Collocation(EIGEN, 16, 4)
    assert c.n_free == 1 and c.size == 16 * 4 + 2 + 1
    x0 = c.project([lambda S: S * (1 - S)], [8.0])  # u'(0) = 1, lam 20% off
    # the value of the free entry in p is ignored (it is an unknown)
    r = c.newton(x0, np.array([-1e6]))
    assert r.converged, r.message
    lam = r.x[c.free_index][0]
    # eigenvalue error of Gauss collocation is superconvergent O(h^{2k}) = 16^-8 ~ 2e-10 * C
    assert abs(lam - np.pi ** 2) < 1e-10
    S = np.linspace(0, 1, 501)
    # eigenfunction: uniform O(h^{k+2}) ~ |u^(6)| h^6 / (6! 2^6) = pi^4 * 16^-6 / 46080 ~ 1e-10
    assert np.max(np.abs(c.evaluate(r.x, S, 0) - np.sin(np.pi * S) / np.pi)) < 1e-9
    # full_params puts the solved value back into p
    assert c.full_params(r.x, np.array([0.0]))[0] == lam


def test_free_eigenvalue_error_order_2k():
    k = 3
    errs = []
    for N in [4, 8, 16]:
        c = Collocation(EIGEN, N, k)
        r = c.newton(c.project([lambda S: S * (1 - S)], [8.0]), np.array([0.0]))
        assert r.converged
        errs.append(abs(r.x[c.free_index][0] - np.pi ** 2))
    q = observed_orders(errs)
    assert np.all(q >= 2 * k - 0.3) and q[-1] <= 2 * k + 0.5, q


# ==========================================================================
# 4. Bratu against its exact solution
# ==========================================================================
def test_bratu_lower_branch_matches_exact_solution():
    lam = 1.0
    exact = bratu_exact(lam)
    c = Collocation(BRATU, 16, 5)
    r = c.newton(np.zeros(c.size), np.array([lam]))
    assert r.converged, r.message
    # uniform error O(h^{k+2}) = 16^-7 ~ 4e-9 * C, C = |u^(7)|/7!-ish << 1 for this mild solution
    assert np.max(np.abs(c.evaluate(r.x, S_FINE, 0) - exact(S_FINE))) < 1e-10
    # mesh points: O(h^{2k}) = 16^-10 ~ 1e-12 * C
    b = c.breakpoints
    assert np.max(np.abs(c.evaluate(r.x, b, 0) - exact(b))) < 1e-12
    # the solution found is the lower one (u(1/2) ~ 0.14, the upper has u(1/2) ~ 4.1)
    assert 0.1 < c.evaluate(r.x, 0.5, 0) < 0.2


def test_bratu_upper_branch_from_a_nearby_guess():
    lam = 1.0
    exact = bratu_exact(lam, upper=True)
    c = Collocation(BRATU, 16, 5)
    # a crude guess of the right height; Newton must pick the upper solution
    x0 = c.project([lambda S: 4.0 * np.sin(np.pi * S)])
    r = c.newton(x0, np.array([lam]))
    assert r.converged, r.message
    # steeper solution (u(1/2) ~ 4.1): same order, larger constant; bound 1e-7
    err = np.max(np.abs(c.evaluate(r.x, S_FINE, 0) - exact(S_FINE)))
    assert err < 1e-7, err
    assert 3.5 < c.evaluate(r.x, 0.5, 0) < 5.0


# ==========================================================================
# 5. NewtonResult reporting
# ==========================================================================
def _check_result(r):
    assert isinstance(r, NewtonResult)
    assert isinstance(r.message, str) and r.message
    assert isinstance(r.converged, bool)
    assert isinstance(r.iterations, int)


@pytest.mark.parametrize("lam", [3.6, 5.0, 50.0])
def test_bratu_beyond_the_fold_reports_failure_without_raising(lam):
    # no solution exists for lam > lam_c = 3.5138...
    c = Collocation(BRATU, 8, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = c.newton(np.zeros(c.size), np.array([lam]), max_iter=40)
    _check_result(r)
    assert r.converged is False
    assert r.message != "converged"
    assert r.residual_norm > 1e-6  # it did not find a (non-existent) solution
    assert r.x.shape == (c.size,)


def test_non_finite_residual_is_reported():
    c = Collocation(BRATU, 8, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r1 = c.newton(np.full(c.size, 1000.0), np.array([1.0]))  # exp overflows to inf
        x0 = np.zeros(c.size)
        x0[3] = np.nan
        r2 = c.newton(x0, np.array([1.0]))
    for r in (r1, r2):
        _check_result(r)
        assert r.converged is False
        assert "finite" in r.message
        assert r.iterations == 0


def test_newton_solve_reports_singular_jacobian_and_iteration_limit():
    # F(x) = x^2 + 1 has no real root; F'(0) = 0 is singular
    lin = lambda x: (x ** 2 + 1.0, sp.csc_matrix(np.diag(2.0 * x)))
    res = lambda x: x ** 2 + 1.0
    r = newton_solve(lin, res, np.array([0.0]))
    _check_result(r)
    assert not r.converged and "singular" in r.message
    # with plenty of damping allowed, iteration on x^2 + 1 wanders without converging
    r = newton_solve(lin, res, np.array([0.3]), max_iter=5, min_damping=1e-300)
    _check_result(r)
    assert not r.converged
    # a scalar problem with a root: quadratic convergence to sqrt(2)
    lin2 = lambda x: (x ** 2 - 2.0, sp.csc_matrix(np.diag(2.0 * x)))
    r = newton_solve(lin2, lambda x: x ** 2 - 2.0, np.array([1.0]), tol=1e-14)
    assert r.converged and abs(r.x[0] - np.sqrt(2)) < 1e-15 * 4 and r.iterations <= 7


def test_chord_solve_reaches_newtons_root_with_fewer_factorisations_on_bratu():
    """The chord (a frozen Jacobian while the steps contract) on Bratu's lower branch at lam = 3 from u = 0: the
    closed-form solution to the discretisation's accuracy, Newton's discrete root to the tolerance's order,
    and fewer LUs than Newton's iterations (each one LU)."""
    c = Collocation(BRATU, 16, 5)
    p = np.array([3.0])
    lin, res = (lambda x: c.linearise(x, p)[:2]), (lambda x: c.residual(x, p))
    newton = newton_solve(lin, res, np.zeros(c.size), tol=1e-12)
    chord = chord_solve(lin, res, np.zeros(c.size), tol=1e-12)
    _check_result(chord)
    assert newton.converged and chord.converged, chord.message
    assert np.max(np.abs(chord.x - newton.x)) <= 1e-11 * (1 + np.max(np.abs(newton.x)))
    S = np.linspace(0, 1, 41)
    assert np.max(np.abs(c.evaluate(chord.x, S, 0) - bratu_exact(3.0)(S))) < 1e-8
    assert 1 <= chord.factorisations < newton.iterations, (chord.factorisations, newton.iterations)


def test_chord_solve_falls_back_on_newtons_line_search_and_reports_failure():
    """atan(x) = 0 from x = 3: the full Newton step overshoots to a larger residual, so the first steps are
    damped (each on a fresh Jacobian) before the chord takes over; x^2 + 1 = 0 has no root (F'(0) singular)."""
    def lin(x):
        return np.arctan(x), sp.csc_matrix(np.diag(1.0 / (1.0 + x * x)))

    r = chord_solve(lin, np.arctan, np.array([3.0]), tol=1e-13)
    _check_result(r)
    assert r.converged and abs(r.x[0]) < 1e-12 and r.factorisations >= 2
    def lin2(x):
        return x ** 2 + 1.0, sp.csc_matrix(np.diag(2.0 * x))

    r = chord_solve(lin2, lambda x: x ** 2 + 1.0, np.array([0.0]))
    assert not r.converged and "singular" in r.message
    r = chord_solve(lin2, lambda x: x ** 2 + 1.0, np.array([0.3]), max_iter=5)
    _check_result(r)
    assert not r.converged
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = chord_solve(lambda x: (np.log(x), sp.csc_matrix(np.diag(1.0 / x))), np.log, np.array([-1.0]))
    assert not r.converged and "finite" in r.message


def _off_domain_problem(which):
    """u'' = log(u) or sqrt(u), u(0) = -1, u(1) = -2: no real solution near u < 0, where the
    real-valued residual is NaN."""
    def residual(S, z, p):
        u, du, ddu = z
        return np.array([ddu - (np.log(u) if which == "log" else np.sqrt(u))])

    def bc(za, zb, p):
        return np.array([za[0] + 1.0, zb[0] + 2.0])

    c = Collocation(BVProblem([2], residual, bc, (0.0, 1.0)), 4, 3)
    return c, c.project([lambda S: -1.0 - S])  # u < 0 everywhere


@pytest.mark.parametrize("which", ["log", "sqrt"])
def test_newton_never_reports_convergence_where_the_residual_is_not_finite(which):
    c, x0 = _off_domain_problem(which)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert not np.all(np.isfinite(c.residual(x0, NOP)))  # real residual is NaN here
        r = c.newton(x0, NOP, max_iter=8)
        F = c.residual(r.x, NOP)
    _check_result(r)
    assert not (r.converged and not np.all(np.isfinite(F))), (r.message, r.residual_norm)


@pytest.mark.parametrize("which", ["log", "sqrt"])
def test_linearise_residual_is_the_real_residual_off_the_real_domain(which):
    c, x0 = _off_domain_problem(which)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        F_res = c.residual(x0, NOP)
        F_lin = c.linearise(x0, NOP)[0]
        r = c.newton(x0, NOP, max_iter=8)
    assert not r.converged and "finite" in r.message, (r.message, r.residual_norm)
    np.testing.assert_array_equal(F_lin, F_res)  # NaN positions must agree too


# ==========================================================================
# 6. Input validation
# ==========================================================================
@pytest.mark.parametrize("k", [0, 8, -1, 2.0, 3.5])
def test_invalid_k_raises(k):
    with pytest.raises(ValueError, match=r"k .*1\.\.7"):
        Collocation(BRATU, 4, k)


@pytest.mark.parametrize("N", [0, -3])
def test_invalid_N_raises(N):
    with pytest.raises(ValueError, match=r"N .*>= 1"):
        Collocation(BRATU, N, 3)


@pytest.mark.parametrize("b", [[0.0, 0.5, 0.5, 1.0], [1.0, 0.5, 0.0], [0.0], [0.0, np.nan, 1.0],
                               [[0.0, 1.0], [2.0, 3.0]]])
def test_non_increasing_breakpoints_raise(b):
    with pytest.raises(ValueError, match="strictly increasing"):
        Collocation(BRATU, np.array(b), 3)


def test_nonuniform_breakpoints_accepted():
    c = Collocation(BRATU, np.array([0.0, 0.1, 0.5, 1.0]), 3)
    assert c.N == 3 and c.size == 3 * 3 + 2


@pytest.mark.parametrize("nbc", [1, 3])
def test_bc_with_wrong_number_of_conditions_raises(nbc):
    def bc(za, zb, p):
        return np.array([za[0], zb[0], za[1]][:nbc])

    pb = BVProblem([2], _bratu_residual, bc, (0.0, 1.0), params=["lam"])
    with pytest.raises(ValueError, match=r"bc must return 2 conditions"):
        c = Collocation(pb, 4, 3)
        c.residual(np.zeros(c.size), np.array([1.0]))


def test_bc_count_includes_free_parameters():
    pb = BVProblem([2], _eig_residual, _bratu_bc, (0.0, 1.0), params=["lam"], free=[0])
    with pytest.raises(ValueError, match=r"bc must return 3 conditions"):
        Collocation(pb, 4, 3)


def test_residual_with_wrong_number_of_equations_raises():
    def residual(S, z, p):
        return np.array([z[2], z[0], z[1]])  # 3 equations for 1 field

    pb = BVProblem([2], residual, _bratu_bc, (0.0, 1.0))
    with pytest.raises(ValueError, match="residual"):
        c = Collocation(pb, 4, 3)
        c.residual(np.zeros(c.size), NOP)


def test_param_index():
    assert BRATU.param_index("lam") == 0 and BRATU.param_index(0) == 0
    with pytest.raises(KeyError, match="lam"):
        BRATU.param_index("mu")


# ==========================================================================
# 8. Property tests
# ==========================================================================
@settings(max_examples=40, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(k=st.integers(1, 7), m=st.integers(1, 4), N=st.integers(1, 8),
       seed=st.integers(0, 2 ** 32 - 1), uniform=st.booleans())
def test_projection_reproduces_polynomials_of_degree_below_k_plus_m(k, m, N, seed, uniform):
    rng = np.random.default_rng(seed)
    a, L = rng.uniform(-2, 2), rng.uniform(0.5, 3)
    b = np.linspace(a, a + L, N + 1) if uniform else _random_breakpoints(rng, N, a, a + L)
    s = SplineSpace(b, k, m)
    d = k + m - 1  # the degree of the space
    cheb = rng.uniform(-1, 1, d + 1)  # Chebyshev coefficients on [a, a+L]
    to_t = lambda S: (2 * np.asarray(S) - 2 * a - L) / L

    def f(S, nu=0):
        return C.chebval(to_t(S), C.chebder(cheb, nu) if nu else cheb) * (2 / L) ** nu

    coef = s.interpolant_coefficients(f)
    S = np.concatenate([b, rng.uniform(a, a + L, 50)])
    hmin = np.min(np.diff(b))
    for nu in range(m + 1):
        got = s.evaluate(coef, S, nu)
        # Markov: |f^(nu)| <= sum|c| d^{2 nu} (2/L)^nu; rounding of the coefficients
        # (least squares, cond <~ 1e3) is amplified by h^-nu in the derivatives
        scale = np.sum(np.abs(cheb)) * max(d, 1) ** (2 * nu) * (2 / L) ** nu
        tol = 1e-10 * scale * (L / hmin) ** nu
        assert np.max(np.abs(got - f(S, nu))) <= tol, (nu, np.max(np.abs(got - f(S, nu))), tol)
        # the basis matrix gives the same values
        np.testing.assert_allclose(s.basis(S, nu) @ coef, got, rtol=1e-12, atol=1e-12 * scale)


@pytest.mark.parametrize("k,m", [(1, 1), (3, 2), (7, 4)])
def test_projection_does_not_reproduce_degree_k_plus_m(k, m):
    """Sharpness of the previous property: one degree more is not in the space."""
    s = SplineSpace(np.array([0.0, 1.0]), k, m)
    Tn = np.zeros(k + m + 1)
    Tn[-1] = 1.0  # T_{k+m} on [0, 1]: best approximation error by degree k+m-1 is 1
    f = lambda S: C.chebval(2 * S - 1, Tn)
    S = np.linspace(0, 1, 201)
    assert np.max(np.abs(s.evaluate(s.interpolant_coefficients(f), S) - f(S))) > 0.5


def polynomial_problem(orders, k, N, seed):
    """Linear system  u_i^(m_i) + sum_{j, l < m_j} A_ijl(S) u_j^(l) = f_i  on random
    non-uniform breakpoints, with exact solution u_i* a random polynomial of degree
    k + m_i - 1 (Chebyshev coefficients in [-1, 1] on [a, a+L]).  Conditions for field i:
    u_i^(l)(a) = u_i*^(l)(a) for l < m_i - 1 and u_i^(m_i-1)(b) = u_i*^(m_i-1)(b).
    The lower-order coupling is small (|A| <= 0.2, L <= 1.5): the problem is a perturbation
    of the uniquely solvable decoupled one u_i^(m_i) = f_i, hence well posed."""
    rng = np.random.default_rng(seed)
    n = len(orders)
    a, L = rng.uniform(-1, 1), rng.uniform(0.5, 1.5)
    breakpoints = _random_breakpoints(rng, N, a, a + L)
    to_t = lambda S: (2 * np.asarray(S) - 2 * a - L) / L
    cheb = [rng.uniform(-1, 1, k + m) for m in orders]  # degree k + m - 1

    def exact(i, S, nu=0):
        return C.chebval(to_t(S), C.chebder(cheb[i], nu) if nu else cheb[i]) * (2 / L) ** nu

    A = 0.2 * rng.uniform(-1, 1, (n, n, 3, 2))
    rows = np.concatenate([[0], np.cumsum([m + 1 for m in orders])])

    def lower(S, z):
        out = []
        for i in range(n):
            acc = 0.0
            for j, mj in enumerate(orders):
                for l in range(mj):
                    acc = acc + (A[i, j, l, 0] + A[i, j, l, 1] * S) * z[rows[j] + l]
            out.append(acc)
        return out

    z_exact = lambda S: [exact(i, S, nu) for i, m in enumerate(orders) for nu in range(m + 1)]

    def residual(S, z, p):
        lo, lo_ex = lower(S, z), lower(S, z_exact(S))
        return np.array([z[rows[i] + m] + lo[i] - (exact(i, S, m) + lo_ex[i])
                         for i, m in enumerate(orders)])

    bc_list = [(i, l, 0 if l < m - 1 else 1) for i, m in enumerate(orders) for l in range(m)]
    ends = (a, a + L)

    def bc(za, zb, p):
        return np.array([(za, zb)[e][rows[i] + l] - exact(i, ends[e], l) for i, l, e in bc_list])

    pb = BVProblem(orders, residual, bc, (a, a + L))
    return pb, breakpoints, exact, cheb, rng


@settings(max_examples=40, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(orders=st.lists(st.integers(1, 3), min_size=1, max_size=3), k=st.integers(1, 7),
       N=st.integers(1, 6), seed=st.integers(0, 2 ** 32 - 1))
def test_collocation_reproduces_polynomial_solutions_of_mixed_order_systems(orders, k, N, seed):
    """u_i* lies in the trial space P_{k+m_i} ∩ C^{m_i-1}, so it satisfies every collocation
    equation and bc: the discrete solution (unique for a nonsingular collocation matrix)
    is u* up to rounding.  The problem is linear, so the discrete solution is one linear
    solve from any x0 (Newton's stopping logic is tested separately)."""
    pb, breakpoints, exact, cheb, rng = polynomial_problem(orders, k, N, seed)
    a, b = breakpoints[0], breakpoints[-1]
    L = b - a
    c = Collocation(pb, breakpoints, k)
    assert c.size == N * k * len(orders) + sum(orders)
    x0 = np.zeros(c.size)
    F0, J, _ = c.linearise(x0, NOP)
    x = x0 + sp.linalg.spsolve(J, -F0)
    S = np.concatenate([breakpoints, rng.uniform(a, b, 40)])
    hmin = np.min(np.diff(breakpoints))
    for i, m in enumerate(orders):
        for nu in range(m + 1):
            ex = exact(i, S, nu)
            scale = np.sum(np.abs(cheb[i])) * (k + m) ** (2 * nu) * (2 / L) ** nu  # Markov bound
            err = np.max(np.abs(c.evaluate(x, S, i, nu) - ex))
            # rounding: cond(J) ~ h^-max(m), amplified by h^-nu in the derivatives
            assert err <= 1e-9 * scale * (L / hmin) ** nu, (i, nu, err)


def test_newton_converges_in_two_iterations_on_linear_problems():
    failures = []
    for seed in range(30):
        pb, breakpoints, exact, cheb, rng = polynomial_problem([3, 3], 5, 4, seed)
        c = Collocation(pb, breakpoints, 5)
        r = c.newton(np.zeros(c.size), NOP)
        # linear: the first step lands on the solution, the second (|dx| ~ rounding
        # <= tol (1+|x|)) confirms it -- the documented convergence criterion
        if not (r.converged and r.iterations <= 2):
            failures.append((seed, r.message, r.iterations, r.residual_norm, r.step_norm))
    for N, k in [(8, 3), (16, 4), (32, 2)]:
        c = Collocation(LINEAR, N, k)
        r = c.newton(np.zeros(c.size), NOP)
        if not (r.converged and r.iterations <= 2):
            failures.append(((N, k), r.message, r.iterations, r.residual_norm, r.step_norm))
    assert not failures, failures


@pytest.mark.parametrize("k,m", [(1, 1), (2, 3), (3, 2), (5, 3), (7, 1)])
def test_spline_values_and_derivatives_match_scipy(k, m):
    """The vectorised Cox-de Boor / Piegl-Tiller evaluation against scipy's BSpline."""
    from scipy.interpolate import BSpline
    rng = np.random.default_rng(7 * k + m)
    b = _random_breakpoints(rng, 6)
    s = SplineSpace(b, k, m)
    coef = rng.normal(size=s.dim)
    ref = BSpline(s.knots, coef, s.degree)
    x = np.concatenate([rng.uniform(0, 1, 40), b])
    for nu in range(min(m + 2, s.degree + 1)):
        np.testing.assert_allclose(s.evaluate(coef, x, nu), ref(x, nu), rtol=1e-12,
                                   atol=1e-12 * np.max(np.abs(ref(x, nu))))


def test_blocks_of_points_give_the_same_jacobian(monkeypatch):
    """Long rods evaluate the complex step in blocks of points: the same residual and Jacobian as one call
    (block sizes that do and do not divide the number of points)."""
    import rodcont.collocation as col
    from rodcont.contact import Wall
    from rodcont.curves import parse_reference
    from rodcont.rod import EulerianRod, RodParameters
    model = EulerianRod(RodParameters(), parse_reference("wiggle:0.05,0.03", 1.0), Wall(0.02, eps=1e-3))
    import dataclasses
    model.problem = dataclasses.replace(model.problem, jacobian=None)  # the complex step (not the rod's own)
    disc = model.discretise(20)
    rng = np.random.default_rng(3)
    x = model.initial_guess(disc, 10.0) + 1e-3 * rng.standard_normal(disc.size)
    p = model.params(2.0, T=10.0)
    F0, J0, _ = disc.linearise(x, p)
    for block in (7, 50):
        monkeypatch.setattr(col, "POINT_BLOCK", block)
        F, J, _ = disc.linearise(x, p)
        assert np.array_equal(F, F0)
        assert abs(J - J0).max() <= 1e-14 * abs(J0).max()


def _affine_bc(za, zb, p):
    return np.array([za[0] - 2.0 * zb[4] + p[2], za[1] - p[0], zb[2] + 3.0 * za[4] - p[1] * 0.5 + 1.0,
                     za[3] + zb[1] - p[2], zb[0] - za[4]])


@pytest.mark.parametrize("N", [3, 5])
def test_affine_bc_declaration_keeps_the_jacobian(N):
    """Declared affine boundary conditions (derivatives kept from the first linearisation) give the same
    residual, Jacobian and parameter derivatives as differentiating them every time, at other points and
    for parameters first asked for later; a free parameter enters them too."""
    import dataclasses
    pb = dataclasses.replace(NONLINEAR, bc=_affine_bc)
    every, once = Collocation(pb, N, 3), Collocation(dataclasses.replace(pb, affine_bc=True), N, 3)
    p = np.array([0.7, 1.3, 123.0])
    rng = np.random.default_rng(5)
    for dparams in ([0], [0, 1], [1]):
        x = 0.1 * rng.normal(size=every.size)
        F1, J1, d1 = every.linearise(x, p, dparams)
        F2, J2, d2 = once.linearise(x, p, dparams)
        np.testing.assert_array_equal(F1, F2)
        np.testing.assert_array_equal(J1.toarray(), J2.toarray())
        for a, b in zip(d1, d2):
            np.testing.assert_array_equal(a, b)


def test_affine_bc_declaration_contradicted_by_the_probes_is_refused():
    """A bc declared affine whose derivatives change between the two probe points (in the jets, or only in
    the parameters) is refused: kept derivatives would give a wrong Jacobian."""
    import dataclasses
    with pytest.raises(ValueError, match="affine"):
        Collocation(dataclasses.replace(NONLINEAR, affine_bc=True), 3, 3)

    def bc(za, zb, p):  # affine in the jets, not in the parameters
        g = _affine_bc(za, zb, p)
        return np.array([g[0], g[1], g[2] + p[1] ** 2, g[3], g[4]])
    with pytest.raises(ValueError, match="affine"):
        Collocation(dataclasses.replace(NONLINEAR, bc=bc, affine_bc=True), 3, 3)
    Collocation(dataclasses.replace(NONLINEAR, bc=_affine_bc, affine_bc=True), 3, 3)


# ==========================================================================
# Integral conditions (AUTO's NINT)
# ==========================================================================
def _int_nl(S, z, p):
    """Two integrands, nonlinear in the jets of both fields, in S and in every parameter."""
    u, du, ddu, _, v, dv = z
    return np.array([u * v ** 2 + p[0] * np.sin(du) - S * p[1] * np.exp(v) + p[2] ** 2,
                     ddu * dv + np.cos(u * p[1]) - S ** 2 * p[0] * p[2]])


# the nonlinear system with two integral conditions in place of one boundary condition and a second free
# parameter (4 boundary + 2 integral = 4 orders + 2 free)
NONLINEAR_INT = BVProblem(orders=[3, 1], residual=_nl_residual, bc=lambda za, zb, p: _nl_bc(za, zb, p)[:4],
                          interval=(0.0, 1.0), params=["a", "b", "c"], free=[1, 2], integrals=_int_nl)


def _join_int_problem(integral_dependence=None):
    """``p0 u'' + u^2 + p2 u = S`` on ``[0, 1]``, a C^0 join at 0.4 with ``u'(0.4-) = p1 u'(0.4+)``, ``u(0) = 0``,
    ``u(1) = 1``, ``p1 = p0``, and ``int (u^2 + p2 u' - S p0) dS = 0`` fixing the free ``p2``."""
    def residual(S, z, p):
        return (p[0] * z[2] + z[0] ** 2 + p[2] * z[0] - S)[None]

    def bc(za, zb, p):
        return np.stack([za[0], zb[0] - 1.0, p[1] - p[0] + 0 * za[0]])

    def interface(zl, zr, p, S):
        return (zl[1] - p[1] * zr[1])[None]

    def integrals(S, z, p):
        return (z[0] ** 2 + p[2] * z[1] - S * p[0])[None]

    return BVProblem(orders=(2,), residual=residual, bc=bc, interval=(0.0, 1.0), params=("a", "ratio", "c"),
                     free=(1, 2), joins=(0.4,), join_continuity=(0,), interface=interface, integrals=integrals,
                     integral_dependence=integral_dependence)


@pytest.mark.parametrize("case", ["mixed-3-1", "join"])
def test_integral_condition_jacobian_matches_central_differences(case):
    """The dense integral rows (jets, free parameters) and dF/dp_0 against central differences, with a
    join too; the rows come last in the row order."""
    from conftest import assert_tangent_matches_differences
    if case == "join":
        c, p = Collocation(_join_int_problem(), np.array([0.0, 0.2, 0.4, 0.7, 1.0]), 3), np.array([1.7, 0.0, 0.0])
        assert c.n_interface == 1 and c.n_int == 1 and c.n_bc == 3
    else:
        c, p = Collocation(NONLINEAR_INT, 3, 3), np.array([0.7, 1.3, 123.0])
        assert c.n_int == 2 and c.n_bc == 4
    x = 0.3 * np.random.default_rng(5).normal(size=c.size)
    assert_tangent_matches_differences(c, x, p, 1e-6)
    natural = np.arange(c.size - c.n_int, c.size)
    assert set(c.row_order[-c.n_int:]) == set(natural)
    J = c.jacobian(x, p).toarray()
    assert np.all(J[-c.n_int:, :c.size - c.n_free] != 0)  # dense rows: every coefficient enters the integrals


def test_integral_dependence_declaration_gives_the_same_jacobian():
    """Declaring the components an integrand reads (u, u') gives the Jacobian of declaring all of them."""
    b = np.array([0.0, 0.2, 0.4, 0.7, 1.0])
    full, lean = Collocation(_join_int_problem(), b, 4), Collocation(_join_int_problem([0, 1]), b, 4)
    x, p = np.random.default_rng(2).normal(size=full.size), np.array([1.7, 0.0, 0.0])
    assert lean.int_active.tolist() == [0, 1]
    np.testing.assert_array_equal(full.jacobian(x, p).toarray(), lean.jacobian(x, p).toarray())


# u'' + u = lam, u(0) = u(1) = 0, int_0^1 u dS = 1 with lam free:
# u = lam (1 - cos S - (1 - cos 1) / sin 1 sin S), so int u = lam (1 - sin 1 - (1 - cos 1)^2 / sin 1) = 1
LAM_INT = 1.0 / (1.0 - np.sin(1.0) - (1.0 - np.cos(1.0)) ** 2 / np.sin(1.0))


def _u_int(S):
    return LAM_INT * (1.0 - np.cos(S) - (1.0 - np.cos(1.0)) / np.sin(1.0) * np.sin(S))


def _int_linear_problem(joins=()):
    return BVProblem(orders=[2], residual=lambda S, z, p: np.array([z[2] + z[0] - p[0]]),
                     bc=lambda za, zb, p: np.array([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"], free=[0],
                     integrals=lambda S, z, p: np.array([z[0] - 1.0]),
                     joins=joins, join_continuity=(0,) if joins else None,
                     interface=(lambda zl, zr, p, S: (zl[1] - zr[1])[None]) if joins else None)


@pytest.mark.parametrize("k", [2, 3, 4])
def test_integral_condition_solves_to_the_closed_form_at_the_collocation_order(k):
    """The free lam of an integral condition converges at the superconvergent O(h^2k) of a functional, the
    solution uniformly at O(h^(k+2)); with a C^0 join (u' continuity as its interface condition) the same."""
    meshes = {2: [2, 4, 8, 16], 3: [2, 4], 4: [1, 2]}[k]  # errors above 1e-12, in the asymptotic range
    S = np.linspace(0.0, 1.0, 1001)
    for joins in ((), (0.5,)):
        el, eu = [], []
        for N in meshes:
            c = Collocation(_int_linear_problem(joins), 2 * N, k)
            r = c.newton(np.zeros(c.size), np.array([-1e3]))  # the free entry of p is ignored
            assert r.converged and r.iterations <= 2, r.message
            el.append(abs(r.x[c.free_index][0] - LAM_INT))
            eu.append(np.max(np.abs(c.evaluate(r.x, S, 0) - _u_int(S))))
        ql, qu = observed_orders(el), observed_orders(eu)
        assert np.all(ql >= 2 * k - 0.3) and np.all(ql <= 2 * k + 0.5), (joins, el, ql)
        assert np.all(qu >= k + 2 - 0.3), (joins, eu, qu)
        assert el[-1] < 1e-7 * abs(LAM_INT)


def test_integral_condition_count_errors():
    res = lambda S, z, p: np.array([z[2] + z[0] - p[0]])
    two = lambda za, zb, p: np.array([za[0], zb[0]])
    one_int = lambda S, z, p: np.array([z[0] - 1.0])
    # 2 orders + 1 free = 3 conditions: 2 boundary + 1 integral; 3 boundary conditions are one too many
    pb = BVProblem([2], res, lambda za, zb, p: np.array([za[0], zb[0], za[1]]), (0.0, 1.0), params=["lam"],
                   free=[0], integrals=one_int)
    with pytest.raises(ValueError, match=r"bc must return 2 conditions \(sum of orders \+ free parameters - 1 "
                                         r"integral condition\), got 3"):
        Collocation(pb, 4, 3)
    # without the free parameter there is no room for the integral condition beside two boundary conditions
    pb = BVProblem([2], res, two, (0.0, 1.0), params=["lam"], integrals=one_int)
    with pytest.raises(ValueError, match=r"bc must return 1 conditions .* - 1 integral condition\), got 2"):
        Collocation(pb, 4, 3)
    # more integral conditions than the orders and free parameters allow
    pb = BVProblem([2], res, two, (0.0, 1.0), params=["lam"], free=[0],
                   integrals=lambda S, z, p: np.array([z[0], z[1], z[2], z[0] * z[1]]))
    with pytest.raises(ValueError, match=r"4 integral conditions, but .* allow 3 conditions in all"):
        Collocation(pb, 4, 3)
    # an integrand of the wrong shape
    pb = BVProblem([2], res, two, (0.0, 1.0), params=["lam"], free=[0], integrals=lambda S, z, p: z[0] - 1.0)
    with pytest.raises(ValueError, match=r"integrals must return an array \(number of integral conditions"):
        Collocation(pb, 4, 3)
