"""Self-checks of the independent flat-wall contact reference (tests/contact_reference.py).

They check the *reference*, not rodcont, against facts that do not come from
it: hand-derived small-slope beam solutions, the independent Lagrangian
collocation code (lagrangian_reference.planar_sag), an exact first integral
of the heavy extensible elastica, continuity at the regime changes and a
re-integration of the whole rod (without using symmetry) with the global
balance.  Sign conventions: see the module docstring (m = EI dth/ds0 > 0 for
sagging curvature, V0 = F(0).e3 with F the force of the part s' > s on s' < s).

Exact first integral (used below).  With N = F.d3, alpha = 1 + N/EA,
m' = -alpha Q, N' = w sin th + Q m/EI, z' = alpha sin th on a free span,

    H = m^2/(2 EI) + N + N^2/(2 EA) - w z   is constant

(dH/ds = -alpha Q m/EI + alpha (w sin th + Q m/EI) - w alpha sin th = 0).
Where th = 0 (clamp, midspan, touchdown) N = T, so between the clamp (z = 0)
and a point with th = 0 at height z: M0^2 - m^2 = 2 EI w (-z) exactly; in the
flat regime (m = 0 at z = -c) M0 = -sqrt(2 EI w c) for every T and EA.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import contact_reference as cr
from lagrangian_reference import planar_sag

W, EI, EA, L = 10., 1., 255., 1.          # paper values


# ----------------------------------------------------------------------------
# 1. small-slope limits (inextensible: EA = 1e9)
# ----------------------------------------------------------------------------
def _beam_T0(c, w=W, EI=EI):
    """EI y'''' = -w on [0, a], y(0) = y'(0) = 0, y(a) = -c, y'(a) = y''(a) = 0.

    With xi = a - x: y = -c + p xi^3 - w xi^4/(24 EI); y'(xi=a) = 0 gives
    p = w a/(18 EI); y(xi=a) = 0 gives w a^4/(72 EI) = c.  Hence
        a = (72 EI c/w)^(1/4),  M0 = EI y''(0) = -w a^2/6,
        V0 = T y' - EI y''' = -2 w a/3 at x = 0,  R = V(a) = w a/3,
    and the largest slope (at xi = 2a/3) is 2 w a^3/(81 EI).
    """
    a = (72 * EI * c / w) ** 0.25
    return dict(a=a, M0=-w * a * a / 6, V0=-2 * w * a / 3, R=w * a / 3,
                slope=2 * w * a ** 3 / (81 * EI))


def _beam_T(c, T, w=W, EI=EI):
    """EI y'''' - T y'' = -w on [0, a], same five conditions, k^2 = T/EI:
    y = A + B x + C cosh kx + D sinh kx + w x^2/(2T); the four linear
    conditions y(0) = y'(0) = y'(a) = y''(a) = 0 fix (A, B, C, D) for a given
    a, then y(a) = -c is solved for a (brentq).  M0 = EI y''(0),
    V0 = T y'(0) - EI y'''(0), R = V(a) = -EI y'''(a)."""
    k = np.sqrt(T / EI)

    def coef(a):
        ch, sh = np.cosh(k * a), np.sinh(k * a)
        A = np.array([[1, 0, 1, 0], [0, 1, 0, k], [0, 1, k * sh, k * ch],
                      [0, 0, k * k * ch, k * k * sh]])
        return np.linalg.solve(A, -np.array([0, 0, w * a / T, w / T]))

    def y_plus_c(a):
        A_, B, C, D = coef(a)
        return A_ + B * a + C * np.cosh(k * a) + D * np.sinh(k * a) + w * a * a / (2 * T) + c

    a = brentq(y_plus_c, 1e-3, 0.5, xtol=1e-15, rtol=1e-15)
    _, B, C, D = coef(a)
    x = np.linspace(0, a, 2001)
    slope = np.max(np.abs(B + k * (C * np.sinh(k * x) + D * np.cosh(k * x)) + w * x / T))
    return dict(a=a, M0=EI * (k * k * C + w / T), V0=-EI * k ** 3 * D,
                R=-EI * k ** 3 * (C * np.sinh(k * a) + D * np.cosh(k * a)), slope=slope)


def _rel_errors(out, ref):
    return np.array([out["x_touchdown"] / ref["a"] - 1, out["R"] / ref["R"] - 1,
                     out["M0"] / ref["M0"] - 1, out["V0"] / ref["V0"] - 1])


def test_small_slope_flat_contact_T0():
    """Nonlinear minus linear theory is O(slope^2): |rel. error| < slope^2 (the
    observed coefficients are 0.03-0.14), and it really is quadratic: at 4c the
    slope grows by 4^(3/4), the error of a by 8 (to 5 %)."""
    errs = []
    for c in (1e-4, 4e-4):
        out = cr.heavy_rod_on_flat_wall(c, 0.0, EA=1e9)
        ref = _beam_T0(c)
        assert out["regime"] == "flat"
        e = _rel_errors(out, ref)
        assert np.all(np.abs(e) < ref["slope"] ** 2), (e, ref["slope"])
        assert ref["slope"] < 4e-3
        errs.append(e)
    assert errs[1][0] / errs[0][0] == pytest.approx(8.0, rel=0.05)


def test_small_slope_flat_contact_with_tension():
    for T in (10.0, 40.0):
        c = 1e-4
        out = cr.heavy_rod_on_flat_wall(c, T, EA=1e9)
        ref = _beam_T(c, T)
        assert out["regime"] == "flat"
        assert ref["R"] == pytest.approx(ref["V0"] + W * ref["a"], abs=1e-12)
        e = _rel_errors(out, ref)
        assert np.all(np.abs(e) < ref["slope"] ** 2), (T, e, ref["slope"])


def test_small_slope_point_contact_and_onsets_T0():
    """Light rod (w = 0.01, slopes ~1e-4): clamped-clamped beam with a midspan
    support at height -c: free sag delta = w L^4/(384 EI), point reaction
    P = 192 EI (delta - c)/L^3, midspan moment w L^2/24 - P L/8 >= 0, i.e.
    point contact for w L^4/(1152 EI) <= c <= w L^4/(384 EI)."""
    w = 0.01
    delta = w / 384
    slope = w * L ** 3 / (72 * np.sqrt(3) * EI)   # largest slope of the free sag (~8e-5)
    tol = 10 * slope ** 2
    assert cr.onset_clearance(0.0, w=w, EA=1e9) == pytest.approx(delta, rel=tol)
    c1, _ = cr.flat_onset_clearance(0.0, w=w, EA=1e9)
    assert c1 == pytest.approx(w / 1152, rel=tol)
    c = 0.6 * delta
    out = cr.heavy_rod_on_flat_wall(c, 0.0, w=w, EA=1e9)
    P = 192 * EI * (delta - c)
    assert out["regime"] == "point"
    assert out["total_side_force"] == pytest.approx(P, rel=tol)
    assert out["M_mid"] == pytest.approx(w / 24 - P / 8, rel=tol)
    assert out["min_z"] == -c and out["x_touchdown"] == 0.5


# ----------------------------------------------------------------------------
# 2. no contact: the independent Lagrangian collocation solution
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("gamma", [1.0, 2.0])
def test_free_case_matches_planar_sag(gamma):
    T = gamma * W * L
    ps = planar_sag(gamma)
    c0 = cr.onset_clearance(T)
    out = cr.heavy_rod_on_flat_wall(1.5 * c0, T)
    assert out["regime"] == "free" and not out["contact"]
    assert out["stretch"] == pytest.approx(ps["stretch"], abs=1e-9)
    assert out["l0"] == pytest.approx(ps["l0"], abs=1e-9)
    assert out["M0"] == pytest.approx(-ps["M0"][1], abs=1e-8)     # planar_sag: M = -m e2
    assert out["V0"] == pytest.approx(ps["F0"][2], abs=1e-8)
    assert out["V0"] == pytest.approx(-W * out["l0"] / 2, abs=1e-13)
    assert c0 == pytest.approx(ps["max_sag"], abs=1e-9)
    assert out["min_z"] == pytest.approx(-c0, abs=1e-14)
    x = np.linspace(0, L, 13)
    assert np.allclose(out["shape"](x), ps["deflection"](x), atol=1e-9)
    if gamma == 1.0:                       # shared/PROBLEM.md numbers
        assert out["stretch"] == pytest.approx(9.2449753e-4, abs=1e-11)
        assert out["l0"] == pytest.approx(0.96282043, abs=1e-8)


# ----------------------------------------------------------------------------
# exact first integral, every regime
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("T,frac", [(0., 1.5), (10., 0.7), (10., 0.25), (20., 0.1),
                                    (10., 0.02)])
def test_first_integral(T, frac):
    c = frac * cr.onset_clearance(T)
    out = cr.heavy_rod_on_flat_wall(c, T)
    zmid = out["min_z"]
    assert out["M0"] ** 2 - out["M_mid"] ** 2 == pytest.approx(-2 * EI * W * zmid, rel=1e-10)
    if out["regime"] == "flat":
        assert out["M0"] == pytest.approx(-np.sqrt(2 * EI * W * c), rel=1e-10)


# ----------------------------------------------------------------------------
# 3. continuity at the onset of contact and at the point -> flat transition
# ----------------------------------------------------------------------------
def test_continuity_at_onset():
    T = 10.0
    c0 = cr.onset_clearance(T)
    free = cr.heavy_rod_on_flat_wall(c0 * (1 + 1e-9), T)
    assert free["regime"] == "free"
    d = {}
    for eps in (1e-4, 2e-4):
        out = cr.heavy_rod_on_flat_wall(c0 * (1 - eps), T)
        assert out["regime"] == "point" and out["x_touchdown"] == 0.5 * L
        d[eps] = (out["R"], out["stretch"] - free["stretch"], out["M0"] - free["M0"])
        # small and first order in eps (changes ~ eps times an O(1) derivative)
        assert 0 < out["R"] < 1e3 * eps * W * L
        assert abs(d[eps][1]) < 10 * eps * free["stretch"]
    for k in range(3):
        assert d[2e-4][k] / d[1e-4][k] == pytest.approx(2.0, rel=1e-3)   # linear


def test_continuity_at_point_to_flat_transition():
    """At c1 the point solution has m_mid = 0 and equals the flat one with a = L/2."""
    T = 10.0
    c1, st = cr.flat_onset_clearance(T)
    assert st["M0"] == pytest.approx(-np.sqrt(2 * EI * W * c1), rel=1e-10)
    pt = cr.heavy_rod_on_flat_wall(c1 * (1 + 1e-4), T)
    fl = cr.heavy_rod_on_flat_wall(c1 * (1 - 1e-4), T)
    fl2 = cr.heavy_rod_on_flat_wall(c1 * (1 - 2e-4), T)
    assert pt["regime"] == "point" and fl["regime"] == "flat"
    assert 0 < pt["M_mid"] < 1e-2 * abs(pt["M0"])
    assert 0 < 0.5 * L - fl["x_touchdown"] < 1e-2 * L
    for key in ("R", "M0", "V0", "stretch", "l0", "total_side_force"):
        assert pt[key] == pytest.approx(fl[key], rel=2e-3), key
        # the flat branch is smooth through c1: linear in (c1 - c)
        assert (fl2[key] - st_value(st, key, T, c1)) / (fl[key] - st_value(st, key, T, c1)) \
            == pytest.approx(2.0, rel=2e-3), key


def st_value(st, key, T, c1):
    """Quantities of the transition state (a = L/2, zone of zero length)."""
    sol = cr.integrate_span(st["M0"], st["V0"], st["s_half"], T)
    return dict(R=st["R"], M0=st["M0"], V0=st["V0"], l0=2 * st["s_half"],
                stretch=(2 * sol.y[5, -1] - L) / L, total_side_force=2 * st["R"])[key]


def test_flat_solution_would_overlap_in_point_regime():
    """Why the point regime exists: between c1 and c0 the flat-contact shooting
    problem has its touchdown beyond midspan (a > L/2)."""
    T = 10.0
    c = 0.5 * cr.onset_clearance(T)
    c1, st = cr.flat_onset_clearance(T)
    assert c > c1
    par = (T, W, EI, EA)
    z = cr._newton(lambda zz: cr._sys_flat(zz, par, 1e-12, c), [st["s_half"], st["M0"], st["V0"]])
    a = cr.integrate_span(z[1], z[2], z[0], T).y[0, -1]
    assert a > 0.5 * L


# ----------------------------------------------------------------------------
# 4. whole rod re-integrated from the clamp (no symmetry used), global balance
# ----------------------------------------------------------------------------
def _zone_rhs(s, y, T):
    dy = cr.span_rhs(s, y, T, W, EI, EA)
    dy[4] -= W                                # distributed reaction p = w
    return dy


@pytest.mark.parametrize("T,frac", [(10., 0.25), (10., 0.5), (20., 0.05), (0., 0.2)])
def test_whole_rod_and_global_balance(T, frac):
    c = frac * cr.onset_clearance(T)
    out = cr.heavy_rod_on_flat_wall(c, T)
    assert out["contact"]
    s_a, R, l0 = out["s_touchdown"], out["R"], out["l0"]
    y = cr.integrate_span(out["M0"], out["V0"], s_a, T).y[:, -1]
    assert y[1] == pytest.approx(-c, abs=1e-12) and abs(y[2]) < 1e-12
    assert y[3] == pytest.approx(out["M_mid"], abs=1e-11)       # 0 for 'flat'
    y = y.copy()
    y[4] -= R                                 # first concentrated reaction
    if out["regime"] == "flat":
        lz0 = l0 - 2 * s_a
        assert lz0 > 0
        zone = solve_ivp(_zone_rhs, (0, lz0), y, method="DOP853", rtol=1e-12, atol=1e-14,
                         args=(T,))
        y = zone.y[:, -1].copy()
        assert y[0] == pytest.approx(L - out["x_touchdown"], abs=1e-12)
        assert abs(y[1] + c) < 1e-12 and abs(y[4]) < 1e-12
        # distributed reaction per unit x = w ds0/dx
        assert out["contact_force_per_x"] == pytest.approx(W * lz0 / (L - 2 * out["x_touchdown"]),
                                                           rel=1e-12)
        y[4] -= R                             # second concentrated reaction
    else:
        lz0 = 0.0
        assert out["M_mid"] >= 0
        y[4] -= R                             # coincident touchdowns: P = 2R at midspan
    end = cr.integrate_span(0, 0, s_a, T, y0=y).y[:, -1]
    # lands on the second clamp, mirror image of the first span
    assert np.allclose(end[:3], [L, 0.0, 0.0], atol=1e-11)
    assert end[3] == pytest.approx(out["M0"], abs=1e-10)
    assert end[5] == pytest.approx(out["l"], abs=1e-12)
    # vertical balance: clamps (-F(0) and +F(l0)) + wall = total weight
    clamps = -out["V0"] + end[4]
    assert clamps + out["total_side_force"] == pytest.approx(W * l0, abs=1e-10)
    assert end[4] == pytest.approx(-out["V0"], abs=1e-10)
    assert out["total_side_force"] == pytest.approx(2 * R + W * lz0, abs=1e-13)
    assert R >= 0
    # horizontal: reactions are vertical, so F.e1 = T in the whole rod; it enters
    # through alpha, checked by x(l0) = L above and by l - L = T/EA (L - 2a) +
    # spans in the zone: ds/ds0 = 1 + T/EA there
    if out["regime"] == "flat":
        assert (L - 2 * out["x_touchdown"]) / lz0 == pytest.approx(1 + T / EA, rel=1e-13)
    # shape: symmetric, above the wall, -c at the contact
    x = np.linspace(0, L, 41)
    zx = out["shape"](x)
    assert np.allclose(zx, zx[::-1], atol=1e-12) and np.all(zx >= -c - 1e-13)
    assert zx[20] == pytest.approx(-c, abs=1e-13) and abs(zx[0]) < 1e-15


def test_regimes_and_keys():
    T = 10.0
    c0 = cr.onset_clearance(T)
    c1, _ = cr.flat_onset_clearance(T)
    assert 0 < c1 < c0
    keys = {"contact", "x_touchdown", "s_touchdown", "R", "M0", "V0", "l0", "l", "stretch",
            "min_z", "contact_force_per_x", "total_side_force", "shape"}
    for c, regime in ((1.1 * c0, "free"), (0.5 * (c0 + c1), "point"), (0.5 * c1, "flat")):
        out = cr.heavy_rod_on_flat_wall(c, T)
        assert keys <= set(out) and out["regime"] == regime
        assert out["stretch"] == pytest.approx((out["l"] - L) / L, abs=1e-15)
    free = cr.heavy_rod_on_flat_wall(1.1 * c0, T)
    assert np.isnan(free["R"]) and np.isnan(free["x_touchdown"]) and free["total_side_force"] == 0


def test_flat_span_by_collocation():
    """A second discretisation: the free span of the flat regime re-solved by
    solve_bvp (unknown span length as parameter) agrees with the shooting."""
    from scipy.integrate import solve_bvp
    T = 10.0
    c = 0.25 * cr.onset_clearance(T)
    out = cr.heavy_rod_on_flat_wall(c, T)

    def fun(t, y, p):
        _, _, th, m, Fz, _ = y
        C, S = np.cos(th), np.sin(th)
        a = 1 + (T * C + Fz * S) / EA
        return p[0] * np.vstack([a * C, a * S, m / EI, a * (T * S - Fz * C), W + 0 * t, a])

    def bc(ya, yb, p):
        return np.array([ya[0], ya[1], ya[2], ya[5], yb[1] + c, yb[2], yb[3]])

    t = np.linspace(0, 1, 41)
    y = np.zeros((6, t.size))
    y[0], y[1], y[3], y[4], y[5] = 0.4 * t, -c * t, -0.3 * (1 - t), -3.0, 0.4 * t
    s = solve_bvp(fun, bc, t, y, p=[0.4], tol=1e-10, bc_tol=1e-12, max_nodes=100000)
    assert s.status == 0
    assert s.p[0] == pytest.approx(out["s_touchdown"], abs=1e-10)
    assert s.y[0, -1] == pytest.approx(out["x_touchdown"], abs=1e-10)
    assert s.y[3, 0] == pytest.approx(out["M0"], abs=1e-9)
    assert s.y[4, 0] == pytest.approx(out["V0"], abs=1e-9)
