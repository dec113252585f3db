"""Checks of the closed-form critical twists (tests/closed_forms.py).

Everything here is independent of the closed form itself:

* Greenhill's classical values (tan x = x, and the tabulated 10.42886);
* a dense Chebyshev collocation of the linearised boundary-value problem,
  written in the *unstressed* arclength s in [0, l0] with the stretch alpha
  kept explicit (so the "effective stiffness" reduction is not assumed), as a
  generalised eigenproblem in Phi;
* a shooting solution of the full NONLINEAR extensible Cosserat equations
  (quaternions), whose Jacobian at the straight state is obtained by
  complex-step differentiation (so the linearisation itself is not assumed).
"""

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from closed_forms import characteristic_function, critical_twists, extensible_euler_load, greenhill_torque

PAPER = dict(EI=1.0, GJ=0.75, EA=255.0, L=1.0)


# ---------------------------------------------------------------------------
# independent solver 1: Chebyshev collocation of the linearised BVP
# ---------------------------------------------------------------------------
def _cheb(N):
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.hstack([2.0, np.ones(N - 1), 2.0]) * (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    D = np.outer(c, 1.0 / c) / (X - X.T + np.eye(N + 1))
    return D - np.diag(D.sum(axis=1)), x


def _clenshaw_curtis(N):
    theta = np.pi * np.arange(N + 1) / N
    w = np.zeros(N + 1)
    ii = np.arange(1, N)
    v = np.ones(N - 1)
    assert N % 2 == 0
    w[0] = w[N] = 1.0 / (N ** 2 - 1)
    for k in range(1, N // 2):
        v -= 2.0 * np.cos(2 * k * theta[ii]) / (4 * k * k - 1)
    v -= np.cos(N * theta[ii]) / (N ** 2 - 1)
    w[ii] = 2.0 * v / N
    return w


def chebyshev_twists(T, EI=1.0, GJ=0.75, EA=255.0, L=1.0, N=48, nmax=4):
    """First nmax critical Phi from collocation on s in [0, l0].

    Unknowns: w(s) = complex tangent tilt at the N+1 nodes and the constant
    complex shear force c.  Equations: EI w'' - i m w' - alpha T w + alpha c = 0
    with m = GJ Phi / l0 (eigenvalue Phi), w(0) = w(l0) = 0, int w ds = 0.
    """
    alpha = 1.0 + T / EA
    l0 = L / alpha
    D, _ = _cheb(N)
    D = D * (2.0 / l0)
    n = N + 1
    A = np.zeros((n + 1, n + 1), complex)
    B = np.zeros_like(A)
    A[:n, :n] = EI * D @ D - alpha * T * np.eye(n)
    A[:n, n] = alpha
    B[:n, :n] = 1j * GJ / l0 * D
    for r in (0, N):
        A[r] = 0.0
        B[r] = 0.0
        A[r, r] = 1.0
    A[n, :n] = _clenshaw_curtis(N) * (l0 / 2.0)
    ev = sla.eigvals(A, B)
    ev = ev[np.isfinite(ev)]
    ev = ev[(np.abs(ev.imag) < 1e-7 * np.abs(ev)) & (ev.real > 1e-9)].real
    return np.sort(ev)[:nmax]


# ---------------------------------------------------------------------------
# independent solver 2: nonlinear Cosserat shooting, complex-step Jacobian
# (rod axis along e3 here; this is only a relabelling of the axes)
# ---------------------------------------------------------------------------
def _qmul(p, q):
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return np.array([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0])


def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _cosserat_rhs(y, EI, GJ, EA):
    """r' = (1 + n.d3/EA) d3, q' = q (0,u)/2, n' = 0, m' = -r' x n."""
    q, n, m = y[3:7], y[7:10], y[10:13]
    q0, q1, q2, q3 = q
    d1 = np.array([q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3,
                   2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)])
    d2 = np.array([2 * (q1 * q2 - q0 * q3),
                   q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 + q0 * q1)])
    d3 = np.array([2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1),
                   q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3])
    u = np.array([(m * d1).sum(0) / EI, (m * d2).sum(0) / EI, (m * d3).sum(0) / GJ])
    rs = (1.0 + (n * d3).sum(0) / EA) * d3
    qs = 0.5 * _qmul(q, np.concatenate([np.zeros((1,) + u.shape[1:]), u]))
    return np.concatenate([rs, qs, np.zeros_like(n), -_cross(rs, n)])


_H = 1e-30  # complex step


def shooting_jacobian(Phi, T, EI=1.0, GJ=0.75, EA=255.0, L=1.0):
    """Jacobian of the clamped-clamped shooting map at the straight state.

    Unknowns (n_x, n_y, m_x, m_y, m_z, l0) (n_z = T prescribed); residuals
    r(l0) - L e3 and the vector part of q_target^* q(l0).
    """
    alpha = 1.0 + T / EA
    l0 = L / alpha
    y0 = np.zeros(13)
    y0[3] = 1.0
    y0[9] = T
    y0[12] = GJ * Phi / l0
    idx = [7, 8, 10, 11, 12]
    D0 = np.zeros((13, 5))
    D0[idx, range(5)] = 1.0

    def rhs(s, Y):
        y, D = Y[:13], Y[13:].reshape(13, 5)
        dz = _cosserat_rhs(y[:, None] + 1j * _H * D, EI, GJ, EA).imag / _H
        return np.concatenate([_cosserat_rhs(y, EI, GJ, EA), dz.ravel()])

    sol = solve_ivp(rhs, (0.0, l0), np.concatenate([y0, D0.ravel()]),
                    method="DOP853", rtol=1e-13, atol=1e-13)
    yE = sol.y[:13, -1]
    DE = np.hstack([sol.y[13:, -1].reshape(13, 5),
                    _cosserat_rhs(yE, EI, GJ, EA)[:, None]])  # d/dl0
    qt_conj = np.array([np.cos(Phi / 2), 0.0, 0.0, -np.sin(Phi / 2)])

    def resid(y):
        e = _qmul(qt_conj, y[3:7])
        return np.concatenate([y[0:3] - np.array([0.0, 0.0, L])[:, None], e[1:4]])

    assert np.max(np.abs(resid(yE[:, None] + 0j).real)) < 1e-10  # base state
    return resid(yE[:, None] + 1j * _H * DE).imag / _H


def transverse_det(Phi, T, **kw):
    """Complex 2x2 determinant of the rotation-symmetric transverse block."""
    J = shooting_jacobian(Phi, T, **kw)
    cols, rows = [(0, 1), (2, 3)], [(0, 1), (3, 4)]
    C = np.empty((2, 2), complex)
    for a, (r0, r1) in enumerate(rows):
        for b, (c0, c1) in enumerate(cols):
            # the block commutes with rotations about the axis
            assert abs(J[r0, c1] + J[r1, c0]) < 1e-8
            assert abs(J[r1, c1] - J[r0, c0]) < 1e-8
            C[a, b] = J[r0, c0] + 1j * J[r1, c0]
    return np.linalg.det(C)


# ---------------------------------------------------------------------------
# (a) Greenhill
# ---------------------------------------------------------------------------
def test_greenhill_untensioned():
    x1 = brentq(lambda x: np.sin(x) - x * np.cos(x), np.pi, 1.45 * np.pi, xtol=1e-15)
    mu = greenhill_torque(0.0)
    assert abs(mu - 8.98682) < 5e-6
    assert abs(mu - 2.0 * x1) < 1e-12            # twice the root of tan x = x
    assert abs(np.tan(mu / 2) - mu / 2) < 1e-10  # i.e. root of tan(x/2) = x/2
    # inextensible rod via critical_twists (GJ = EI so Phi = m L / EI)
    phi = critical_twists(0.0, EI=1.0, GJ=1.0, EA=1e15, L=1.0)
    assert abs(phi[0] - 8.98682) < 5e-6


def test_greenhill_tensioned():
    assert abs(greenhill_torque(10.0) - 10.42886) < 5e-6
    phi = critical_twists(10.0, EI=1.0, GJ=1.0, EA=1e15, L=1.0)
    assert abs(phi[0] - 10.42886) < 5e-6
    # torque grows with tension and exceeds the helical value 2 sqrt(tau)
    taus = [-30.0, -10.0, 0.0, 10.0, 50.0, 200.0]
    mus = [greenhill_torque(t) for t in taus]
    assert np.all(np.diff(mus) > 0)
    assert mus[-1] > 2 * np.sqrt(200.0)


# ---------------------------------------------------------------------------
# (b) independent numerics, paper stiffnesses
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("T", [10.0, 20.0, 0.0, -20.0, 100.0])
def test_against_chebyshev(T):
    ref = chebyshev_twists(T, **PAPER, nmax=4)
    cf = critical_twists(T, **PAPER, phi_max=60.0)[:4]
    assert ref.size == 4 and cf.size == 4
    np.testing.assert_allclose(cf, ref, rtol=0, atol=1e-8)


def test_count_matches_chebyshev_below_phi_max():
    for T in (10.0, 20.0):
        cf = critical_twists(T, **PAPER)          # phi_max = 40
        ref = chebyshev_twists(T, **PAPER, nmax=50)
        ref = ref[ref < 40.0]
        assert cf.size == ref.size == 4
        np.testing.assert_allclose(cf, ref, rtol=0, atol=1e-8)


@pytest.mark.parametrize("T,n", [(10.0, 0), (20.0, 3)])
def test_against_nonlinear_shooting(T, n):
    phi = critical_twists(T, **PAPER)[n]
    d = 1e-3
    slope = (transverse_det(phi + d, T, **PAPER)
             - transverse_det(phi - d, T, **PAPER)) / (2 * d)
    step = transverse_det(phi, T, **PAPER) / slope   # Newton step, ~ phi - Phi_n
    assert abs(step) < 1e-8
    # and the determinant does vanish linearly there (a genuine simple root
    # of the complex determinant, not a uniformly small function)
    off = transverse_det(phi + 0.01, T, **PAPER) / slope
    assert abs(off - 0.01) < 1e-3


# ---------------------------------------------------------------------------
# (c) T = 0, T < 0, the characteristic function's cases
# ---------------------------------------------------------------------------
def test_untensioned_all_roots_tan():
    roots = []
    for k in range(1, 5):
        roots.append(brentq(lambda x: np.sin(x) - x * np.cos(x),
                            k * np.pi + 1e-9, (k + 0.5) * np.pi - 1e-9, xtol=1e-15))
    expect = 2 * np.array(roots) * 1.0 / 0.75
    for EA in (255.0, 1e12):                     # tau = 0 whatever EA
        phi = critical_twists(0.0, EI=1.0, GJ=0.75, EA=EA, phi_max=50.0)
        np.testing.assert_allclose(phi[:4], expect, rtol=0, atol=1e-11)


def test_compression_below_euler():
    TE = extensible_euler_load(EI=1.0, EA=255.0, L=1.0)
    assert -4 * np.pi ** 2 < TE < -30.0
    Ts = [20.0, 0.0, -10.0, -20.0, -30.0, 0.99 * TE, 0.9999 * TE]
    first = [critical_twists(T, **PAPER)[0] for T in Ts]
    assert np.all(np.diff(first) < 0) and first[-1] > 0
    assert first[-1] < 0.5                        # -> 0 at the Euler load
    for T in (-30.0, 0.99 * TE):
        np.testing.assert_allclose(critical_twists(T, **PAPER)[:3],
                                   chebyshev_twists(T, **PAPER, nmax=3),
                                   rtol=0, atol=1e-8)
    # at the clamped Euler load mu = 0 is a root of H (excluded from output)
    assert abs(characteristic_function(0.0, -4 * np.pi ** 2)[0]) < 1e-15
    assert np.all(critical_twists(TE, **PAPER) > 0)


def test_characteristic_function_cases():
    # D = 4 tau - mu^2 >= 0: strictly negative (no critical twist there)
    for tau in (1e-3, 1.0, 10.0, 100.0):
        mu = np.linspace(0.0, 2 * np.sqrt(tau), 201)
        assert np.all(characteristic_function(mu, tau) < 0)
    # continuity across D = 0, across the internal switch kappa = a/2, tau = 0
    tau = 10.0
    for mu0 in (2 * np.sqrt(tau), 2 * np.sqrt(tau / 0.75)):
        e = 1e-9
        lo, mid, hi = characteristic_function([mu0 - e, mu0, mu0 + e], tau)
        assert abs(lo - mid) < 1e-7 and abs(hi - mid) < 1e-7
    mu = np.linspace(0.5, 30.0, 50)
    a = mu / 2
    H0 = (a * np.cos(a) - np.sin(a)) / (4 * a ** 3)
    for tau in (0.0, 1e-12, -1e-12, 1e-8):
        np.testing.assert_allclose(characteristic_function(mu, tau), H0,
                                   rtol=0, atol=1e-14 + 10 * abs(tau))
    # each root listed once (the double real root is one complex root)
    phi = critical_twists(10.0, **PAPER)
    assert np.all(np.diff(phi) > 1.0)
