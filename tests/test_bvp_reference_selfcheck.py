"""Self-checks of tests/bvp_reference.py (the closed forms of the "Your own problem" examples).

Each closed form is checked against a second, independent route that uses
none of its formulas: shooting (DOP853 initial value problems, rtol 1e-13)
with Newton or Brent on the shooting map, and, for Troesch, a quadrature of
the first integral.  These check the reference, not rodcont.  A few seconds.
"""

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

import bvp_reference as ref

RTOL = 1e-13


def _ivp(rhs, y0, t_end, dense=False):
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="DOP853", rtol=RTOL, atol=1e-16,
                    dense_output=dense)
    assert sol.success
    return sol


# ----------------------------------------------------------------------------
# Bratu
# ----------------------------------------------------------------------------
def _bratu_shoot(p, lam, dense=False):
    """u'' = -lam e^u with u(0) = 0, u'(0) = p, and v'' = -lam e^u v, v(0) = 0, v'(0) = 1."""
    rhs = lambda x, y: [y[1], -lam * np.exp(y[0]), y[3], -lam * np.exp(y[0]) * y[2]]
    return _ivp(rhs, [0.0, p, 0.0, 1.0], 1.0, dense)


def test_bratu_fold_value():
    f = ref.bratu_fold()
    assert f["lam"] == pytest.approx(3.513830719125162, abs=1e-15)       # issue 21
    assert f["lam"] == pytest.approx(3.5138307191251612062, abs=5e-16)   # 50-digit Newton
    assert f["slope"] == pytest.approx(4.0, abs=1e-14)      # theta* tanh(theta*/4) = 4 y tanh y = 4
    assert f["theta"] / 4 * np.tanh(f["theta"] / 4) == pytest.approx(1.0, abs=1e-15)
    assert float(ref.bratu_lambda(f["theta"])) == pytest.approx(f["lam"], abs=2e-15)


def test_bratu_fold_by_shooting():
    """Fold = (p, lam) with u(1) = 0 and a nontrivial v(1) = 0 (singular linearisation),
    solved by Newton from a rough start, with derivatives by finite differences."""
    x = np.array([3.0, 3.3])
    F = lambda x: np.array(_bratu_shoot(*x).y[[0, 2], -1])
    for _ in range(30):
        Fx = F(x)
        J = np.column_stack([(F(x + h) - Fx) / 1e-7 for h in np.eye(2) * 1e-7])
        dx = np.linalg.solve(J, -Fx)
        x += dx
        if np.max(np.abs(dx)) < 1e-13:
            break
    f = ref.bratu_fold()
    assert x[1] == pytest.approx(f["lam"], abs=1e-12)
    assert x[0] == pytest.approx(f["slope"], abs=1e-9)


@pytest.mark.parametrize("branch", ["lower", "upper"])
@pytest.mark.parametrize("lam", [0.2, 1.0, 2.5, 3.5])
def test_bratu_branches_by_shooting(lam, branch):
    """The closed form's u'(0) shoots onto u(1) = 0, and u(x), max u agree with the IVP."""
    th = ref.bratu_theta(lam, branch)
    assert float(ref.bratu_lambda(th)) == pytest.approx(lam, rel=1e-14)
    p = float(ref.bratu_slope(th))
    sol = _bratu_shoot(p, lam, dense=True)
    scale = 1.0 + p
    assert abs(sol.y[0, -1]) < 1e-11 * scale
    x = np.linspace(0.0, 1.0, 11)
    u, du = ref.bratu_solution(x, lam, branch)
    assert np.allclose(sol.sol(x)[0], u, rtol=0, atol=1e-11 * scale)
    assert np.allclose(sol.sol(x)[1], du, rtol=0, atol=1e-10 * scale)
    assert sol.sol(0.5)[0] == pytest.approx(float(ref.bratu_max(th)), abs=1e-11 * scale)
    # The shooting root in p (Brent) from its own bracket lands on the same slope.
    lo, hi = (0.0, 4.0) if branch == "lower" else (4.0, 60.0)
    ps = brentq(lambda q: _bratu_shoot(q, lam).y[0, -1], lo, hi, xtol=1e-14)
    assert ps == pytest.approx(p, rel=1e-11)


def test_bratu_branch_labels_invert():
    for th in [0.3, 2.0, ref.bratu_fold()["theta"], 7.0, 15.0]:
        assert ref.bratu_theta_from_slope(float(ref.bratu_slope(th))) == pytest.approx(th, rel=1e-13)
        assert ref.bratu_theta_from_max(float(ref.bratu_max(th))) == pytest.approx(th, rel=1e-13)
    with pytest.raises(ValueError):
        ref.bratu_theta(3.52)


# ----------------------------------------------------------------------------
# Troesch
# ----------------------------------------------------------------------------
def _troesch_quadrature_slope(lam):
    """Root of int_0^{t_max} dt / sqrt(1 + (s^2/4) sinh^2 t) = lam, t_max = asinh(2 sinh(lam/2)/s).

    This is the first integral x(u) = int du / sqrt(s^2 + 4 sinh^2(lam u/2)) at u = 1
    after sinh(lam u/2) = (s/2) sinh t (which removes the 1/s peak at u = 0).
    """
    def g(ls):
        s = np.exp(ls)
        tmax = np.arcsinh(2.0 * np.sinh(lam / 2) / s)
        knee = np.log(4.0 / s)         # where (s/2) sinh t reaches 1: split there
        pts = [knee] if knee < tmax else None
        val, _err = quad(lambda t: 1.0 / np.sqrt(1.0 + 0.25 * s * s * np.sinh(t) ** 2),
                        0.0, tmax, epsabs=0.0, epsrel=3e-14, limit=400, points=pts)
        return val - lam
    return np.exp(brentq(g, np.log(8.0) - lam - 5.0, 0.0, xtol=1e-15, rtol=1e-15))


def _troesch_shoot(s, lam, dense=False):
    rhs = lambda x, y: [y[1], lam * np.sinh(lam * y[0])]
    return _ivp(rhs, [0.0, s], 1.0, dense)


def _troesch_shooting_slope(lam):
    """Brent in ln s on u(1) - 1; a trajectory that passes u = 2 (it blows up before
    x = 1 for s a little too large) counts as overshoot."""
    rhs = lambda x, y: [y[1], lam * np.sinh(lam * y[0])]
    past = lambda x, y: y[0] - 2.0
    past.terminal = True

    def g(ls):
        sol = solve_ivp(rhs, (0.0, 1.0), [0.0, np.exp(ls)], method="DOP853", rtol=RTOL,
                        atol=1e-16, events=past)
        return 1.0 if sol.status == 1 else sol.y[0, -1] - 1.0
    return np.exp(brentq(g, np.log(8.0) - lam - 6.0, 0.0, xtol=1e-15, rtol=1e-15))


@pytest.mark.parametrize("lam", [0.5, 1.0, 2.0, 5.0, 8.0, 10.0])
def test_troesch_slope_quadrature_and_shooting(lam):
    s = ref.troesch_slope(lam)
    assert _troesch_quadrature_slope(lam) == pytest.approx(s, rel=1e-12)
    assert _troesch_shooting_slope(lam) == pytest.approx(s, rel=1e-11)


def test_troesch_literal_sc_form():
    """sinh(lam/2) = (s/2) sc(lam | 1 - s^2/4) with scipy's parameter m: the same root;
    at lam = 10 the rounding of m = 1 - 3.2e-8 limits ellipj (documented ~1e-10)."""
    for lam in [0.1, 1.0, 3.0, 5.0]:
        assert ref.troesch_slope_ellipj(lam) == pytest.approx(ref.troesch_slope(lam), rel=1e-13)
    assert ref.troesch_slope_ellipj(10.0) == pytest.approx(ref.troesch_slope(10.0), rel=1e-9)


def test_troesch_lambda_10_matches_literature():
    s = ref.troesch_slope(10.0)
    assert s == pytest.approx(3.5833778e-4, rel=2e-8)     # published u'(0) at lam = 10
    assert ref.troesch_slope(0.0) == 1.0
    assert ref.troesch_slope(1e-6) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("lam", [1.0, 10.0])
def test_troesch_solution_by_shooting(lam):
    s = ref.troesch_slope(lam)
    sol = _troesch_shoot(s, lam, dense=True)
    x = np.array([0.0, 0.25, 0.5, 0.8, 0.95, 0.99, 1.0])
    u, du = ref.troesch_solution(x, lam)
    assert np.allclose(sol.sol(x)[0], u, rtol=0, atol=1e-11)
    assert np.allclose(sol.sol(x)[1], du, rtol=1e-10, atol=0)
    assert u[-1] == 1.0 and u[0] == 0.0


# ----------------------------------------------------------------------------
# Pinned elastica with the end shortening prescribed and the load free
# ----------------------------------------------------------------------------
def _elastica_shoot(theta0, P, dense=False):
    """theta'' = -P sin(theta), theta(0) = theta0, theta'(0) = 0; also x, y = int cos, sin."""
    rhs = lambda s, y: [y[1], -P * np.sin(y[0]), np.cos(y[0]), np.sin(y[0])]
    return _ivp(rhs, [theta0, 0.0, 0.0, 0.0], 1.0, dense)


def _elastica_newton(delta, guess):
    """Unknowns (theta0, P); equations theta'(1) = 0 and int cos(theta) = 1 - delta."""
    x = np.array(guess, dtype=float)
    F = lambda x: _elastica_shoot(*x).y[[1, 2], -1] - [0.0, 1.0 - delta]
    for _ in range(40):
        Fx = F(x)
        J = np.column_stack([(F(x + h) - Fx) / 1e-7 for h in np.eye(2) * 1e-7])
        dx = np.linalg.solve(J, -Fx)
        x += dx
        if np.max(np.abs(dx)) < 1e-13 * (1 + np.abs(x)).max():
            return x
    raise RuntimeError("elastica Newton did not converge")


def test_elastica_by_shooting_along_the_branch():
    """Continuation in delta from the small-delta start (theta0 = 2 sqrt(delta),
    P = pi^2 (1 + delta/2)), no closed form used: theta0, P, theta(s), x(s), y(s)."""
    x = None
    s = np.linspace(0.0, 1.0, 9)
    for delta in [0.01, 0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85, 1.0, 1.15, 1.3, 1.4, 1.5]:
        guess = x if x is not None else (2 * np.sqrt(delta), np.pi ** 2 * (1 + delta / 2))
        x = _elastica_newton(delta, guess)
        assert x[0] == pytest.approx(ref.elastica_theta0(delta), abs=1e-11)
        assert x[1] == pytest.approx(ref.elastica_load(delta), rel=1e-11)
        if delta in (0.1, 1.0, 1.5):
            sol = _elastica_shoot(*x, dense=True)
            th, dth = ref.elastica_theta(s, delta)
            xs, ys = ref.elastica_shape(s, delta)
            y = sol.sol(s)
            assert np.allclose(y[0], th, atol=1e-10) and np.allclose(y[1], dth, atol=1e-9)
            assert np.allclose(y[2], xs, atol=1e-10) and np.allclose(y[3], ys, atol=1e-10)


def test_elastica_integral_condition_by_quadrature():
    """int_0^1 cos(theta(s)) ds of the closed-form shape = 1 - delta (quad), theta odd about 1/2."""
    for delta in [1e-3, 0.3, 1.0, 1.6]:
        val, _ = quad(lambda s, d=delta: np.cos(ref.elastica_theta(s, d)[0]), 0.0, 1.0,
                      epsabs=1e-13, epsrel=1e-13, limit=200)
        assert val == pytest.approx(1.0 - delta, abs=1e-12)
        th = ref.elastica_theta(np.array([0.0, 0.3, 0.7, 1.0]), delta)[0]
        assert th[0] == pytest.approx(ref.elastica_theta0(delta), abs=1e-12)
        assert th[0] == pytest.approx(-th[3], abs=1e-12) and th[1] == pytest.approx(-th[2], abs=1e-12)


def test_elastica_bifurcation_and_limits():
    """delta -> 0: P -> pi^2 (1 + delta/2); delta = 1: ends meet (x(1) = 0);
    delta -> 2: P ~ 16 / (2 - delta)^2 (E -> 1, K = 2 / (2 - delta))."""
    d = 1e-5
    assert (ref.elastica_load(d) / np.pi ** 2 - 1) / d == pytest.approx(0.5, abs=1e-4)
    assert ref.elastica_theta0(d) == pytest.approx(2 * np.sqrt(d), rel=1e-4)
    assert ref.elastica_shape(1.0, 1.0)[0] == pytest.approx(0.0, abs=1e-14)
    assert ref.elastica_shape(1.0, 1.2)[0] == pytest.approx(-0.2, abs=1e-14)
    assert ref.elastica_load(1.99) == pytest.approx(16 / 0.01 ** 2, rel=1e-12)
    with pytest.raises(ValueError):
        ref.elastica_load(2.0)
