"""Self-checks of tests/twisted_reference.py (length control, localized helix, Maddocks).

These check the reference, not rodcont, against routes that do not share its
formulas: the Lagrangian shooting Jacobians (singular where the closed forms
put the critical twists), Kirchhoff's equations integrated from the centre of
the localized helix, PyElastica's published constants, the finite clamped
rod solved by multiple shooting (the infinite-rod relations approached
exponentially), two parametrisations of the branch and a collocation
(solve_bvp) re-solution for the Maddocks point.  About 30 s of CPU.
"""

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

import closed_forms as cf
import lagrangian_reference as lag
import twisted_reference as tw

EI, GJ, EA, L = 1.0, 0.75, 255.0, 1.0


def _smallest_singular_values(l0, phi, k=3):
    T = tw.straight_length_control(l0, EA, L)["T"]
    G, J = tw.length_control_jacobian(l0, phi, [T, 0, 0], [GJ * phi / l0, 0, 0], EI, GJ, EA, L)
    sv = np.linalg.svd(J, compute_uv=False)
    return G, sv[-k:] / sv[0]


# ----------------------------------------------------------------------------
# A. Length control of the straight weightless rod
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("l0", [0.95, 1.0, 1.02])     # tension 13.4, none, compression -5
@pytest.mark.parametrize("n", [1, 2])
def test_length_control_jacobian_singular_at_closed_form_twist(l0, n):
    """The straight state solves the length-control shooting problem exactly, and its
    Jacobian (unknowns: end force and moment, l0 held) loses rank 2 at the closed-form
    Phi_n(T(l0)) of the tension-controlled rod, not 0.05 away."""
    phi = tw.critical_twist_length_control(l0, EI, GJ, EA, L, n)
    G, s = _smallest_singular_values(l0, phi)
    assert np.max(np.abs(G)) < 1e-11
    assert s[-1] < 1e-12 and s[-2] < 1e-12 and s[0] > 1e-3
    for d in (-0.05, 0.05):
        assert _smallest_singular_values(l0, phi + d)[1][-1] > 1e-4


def test_transverse_modes_leave_l0_and_torque_unchanged():
    """Tension control at T(l0): the 2-dimensional kernel of the shooting Jacobian
    (unknowns F2, F3, M1, M2, M3, l0) has no l0 and no torque (M1) component."""
    l0 = 0.95
    T = tw.straight_length_control(l0, EA, L)["T"]
    phi = tw.critical_twist_length_control(l0, EI, GJ, EA, L)
    x = np.array([0.0, 0.0, GJ * phi / l0, 0.0, 0.0, l0, phi, 0.0])
    _, J, _ = lag._shoot_ext(x, T, (EI, GJ, EA, L), 1e-12)
    _, sv, Vt = np.linalg.svd(J[:6, :6])
    assert sv[-1] < 1e-12 * sv[0] and sv[-2] < 1e-12 * sv[0]
    kernel = Vt[-2:]
    assert np.max(np.abs(kernel[:, [2, 5]])) < 1e-10
    assert np.linalg.matrix_rank(kernel[:, [0, 1, 3, 4]], tol=0.1) == 2


def test_length_control_limits():
    """l0 = L: T = 0, Greenhill (mu = 8.98682); Euler: l0_E = L (1 + 4 pi^2 EI/(EA L^2)),
    where the untwisted length-controlled rod has a double zero singular value."""
    assert tw.critical_twist_length_control(1.0, EI, GJ, EA, L) == pytest.approx(
        8.986818916 * EI / GJ, abs=1e-8)
    e = tw.euler_length_control(EI, EA, L)
    assert e["l0"] == pytest.approx(1.0 + 4 * np.pi ** 2 / 255.0, rel=1e-15)
    assert e["T"] == pytest.approx(cf.extensible_euler_load(EI, EA, L), rel=1e-15)
    T = tw.straight_length_control(e["l0"], EA, L)["T"]
    assert cf.effective_tension(T, EI, EA, L) == pytest.approx(-4 * np.pi ** 2, rel=1e-13)
    _, s = _smallest_singular_values(e["l0"], 0.0)
    assert s[-1] < 1e-13 and s[-2] < 1e-13
    for d in (-1e-3, 1e-3):
        assert _smallest_singular_values(e["l0"] + d, 0.0)[1][-1] > 1e-3
    with pytest.raises(ValueError):
        tw.critical_twist_length_control(e["l0"] + 1e-3, EI, GJ, EA, L)


# ----------------------------------------------------------------------------
# B. Localized helix
# ----------------------------------------------------------------------------
def _integrate_from_centre(T, M, EIh, GJh, S):
    c = tw.localized_helix_centre(T, M, EIh, GJh)
    y0 = np.zeros(14)
    y0[0:3], y0[3:7] = c["r0"], lag.directors_to_quat(c["D0"])
    y0[7:10], y0[10:13] = c["F0"], c["M0"]
    f = lambda s, y: lag.kirchhoff_rhs(y, 0.0, EIh, GJh, np.inf, np.zeros(3))
    return solve_ivp(f, (0.0, S), y0, method="DOP853", rtol=1e-13, atol=1e-14, dense_output=True)


@pytest.mark.parametrize("T, M, EIh, GJh, S", [(1.0, 1.8, 1.0, 0.75, 16.0),
                                              (0.39018358617904175, 1.3253831235025157,
                                               1.345, 0.789, 30.0)])
def test_localized_helix_solves_kirchhoff(T, M, EIh, GJh, S):
    """Kirchhoff's equations (inextensible, weightless) integrated both ways from the
    closed-form centre state reproduce the centreline, the directors, the moment and
    the tangent angle to 1e-9 while sin(theta/2) decays by e^-7 (PyElastica's loads: e^-6.5)."""
    for sgn in (1.0, -1.0):
        sol = _integrate_from_centre(T, M, EIh, GJh, sgn * S)
        s = np.linspace(0.0, sgn * S, 241)
        y = sol.sol(s)
        h = tw.localized_helix(s, T, M, EIh, GJh)
        D = lag.quat_to_directors(y[3:7])
        theta = np.arctan2(np.hypot(D[0, 2], D[1, 2]), D[2, 2])
        assert np.max(np.abs(y[0:3] - h["r"])) < 1e-9
        assert np.max(np.abs(D - h["directors"])) < 1e-9
        assert np.max(np.abs(y[10:13] - h["moment"])) < 1e-9
        assert np.max(np.abs(theta - h["theta"])) < 1e-9
        assert np.max(np.abs(np.hypot(y[0], y[1]) - h["envelope"])) < 1e-9
        assert h["theta"][-1] < 3e-3 * h["theta_max"]


def test_localized_helix_shortening_and_rotation_integrals():
    """D = int (1 - cos theta) ds (quadrature of the closed form) and the loop's extra end
    rotation = (phi + psi - M s/GJ) from -inf to +inf = 4 arccos(mu)."""
    T, M = 1.0, 1.8
    h = lambda s: tw.localized_helix(s, T, M)
    D, _ = quad(lambda s: 1.0 - np.cos(h(s)["theta"][0]), -80, 80, epsabs=1e-14, limit=200)
    ctl = tw.localized_helix_controls(T, M, 1.0)
    assert D == pytest.approx(ctl["D"], rel=1e-12)
    far = h(np.array([-80.0, 80.0]))
    extra = np.diff(far["phi"] + far["psi"] - M * np.array([-80.0, 80.0]) / 0.75)[0]
    assert extra == pytest.approx(4 * np.arccos(ctl["mu"]), abs=1e-12)
    # z(s) = s - A tanh(c s/2) is the integral of cos(theta)
    z, _ = quad(lambda s: np.cos(h(s)["theta"][0]), 0.0, 3.0, epsabs=1e-14)
    assert z == pytest.approx(h(3.0)["r"][2, 0], abs=1e-12)


def test_pyelastica_constants_and_curve():
    """PyElastica's HelicalBucklingCase: L = 100, slack 3, 27 turns, B = 1.345, C = 0.789;
    their hard-coded m = M L/B and t = T L^2/B (vpasolve of eqs 14-15) and their
    analytic centreline (amplitude sqrt(4t - mz^2)/(2 pi t) L, mz = M L/(2 pi B))."""
    B, C, Lr = 1.345, 0.789, 100.0
    g = tw.localized_helix_loads(3.0, 54 * np.pi, Lr, B, C)
    assert g["M"] * Lr / B == pytest.approx(98.541496171190744, rel=1e-13)
    assert g["T"] * Lr ** 2 / B == pytest.approx(2.900993205792131e3, rel=1e-13)
    ctl = tw.localized_helix_controls(g["T"], g["M"], Lr, B, C)
    assert ctl["D"] == pytest.approx(3.0, rel=1e-14) and ctl["Phi"] == pytest.approx(54 * np.pi, rel=1e-14)
    t, mz = g["T"] * Lr ** 2 / (4 * np.pi ** 2 * B), g["M"] * Lr / (2 * np.pi * B)
    root = np.sqrt(4 * t - mz ** 2)
    u = np.linspace(-0.5, 0.5, 101)
    amp = root / (2 * np.pi * t) / np.cosh(np.pi * u * root)
    r = np.array([amp * np.sin(mz * np.pi * u), -amp * np.cos(mz * np.pi * u),
                  u - root / (2 * np.pi * t) * np.tanh(np.pi * u * root)]) * Lr
    assert np.max(np.abs(tw.localized_helix(u * Lr, g["T"], g["M"], B, C)["r"] - r)) < 1e-12
    assert np.degrees(g["theta_max"]) == pytest.approx(47.6515073, abs=1e-6)
    low = tw.localized_helix_loads(3.0, 54 * np.pi, Lr, B, C, branch="lower")
    assert low["mu"] < 1 / np.sqrt(2) < g["mu"]
    assert tw.localized_helix_controls(low["T"], low["M"], Lr, B, C)["Phi"] == pytest.approx(54 * np.pi, rel=1e-13)


def test_localized_helix_axial_inverts():
    T, M = 1.0, 1.8
    z = np.array([-5.0, -0.3, 0.0, 2.0, 9.0])
    a = tw.localized_helix_axial(z, T, M)
    assert np.allclose(tw.localized_helix(a["s"], T, M)["r"][2], z, atol=1e-13, rtol=0)


_B, _C = 1.345, 0.789                      # PyElastica's bending and twisting stiffness


@pytest.fixture(scope="module")
def pyelastica_loads():
    return tw.localized_helix_loads(3.0, 54 * np.pi, 100.0, _B, _C)


@pytest.fixture(scope="module")
def clamped_runs(pyelastica_loads):
    """Finite clamped rods at the (D, Phi) of the closed form for PyElastica's (T, M):
    l = 40 and PyElastica's own l = 100 (span 97, 27 turns)."""
    T, M = pyelastica_loads["T"], pyelastica_loads["M"]
    out = {}
    for l, seg in ((40.0, 10), (100.0, 24)):
        ctl = tw.localized_helix_controls(T, M, l, _B, _C)
        out[l] = tw.clamped_helix(l, l - ctl["D"], ctl["Phi"], _B, _C, segments=seg)
    assert out[100.0]["guess"]["T"] == pytest.approx(T, rel=1e-13)      # Phi = 54 pi there
    return out


def test_clamped_rod_approaches_the_localized_helix(pyelastica_loads, clamped_runs):
    """The finite clamped rod (multiple shooting) at the (D, Phi) of the closed form for
    given (T, M) has T converging to it like exp(-c l / 2) as l grows (l = 40, 100;
    c l/2 = 8.7, 21.8), the torque too, and at l = 100 its envelope peaks at A
    mid-span; the clamp and continuity equations hold to 1e-11."""
    T, M = pyelastica_loads["T"], pyelastica_loads["M"]
    h = tw.localized_helix(0.0, T, M, _B, _C)
    errs = [abs(clamped_runs[l]["T"] / T - 1) for l in (40.0, 100.0)]
    for r in clamped_runs.values():
        assert r["residual"] < 1e-11
    assert errs[0] < 3e-3 and errs[1] < 3e-8
    rate = np.log(errs[0] / errs[1]) / 60.0
    assert 0.5 * h["c"] * 0.9 < rate < 0.5 * h["c"] * 1.1
    r = clamped_runs[100.0]
    assert r["length"] == pytest.approx(100.0, abs=1e-12)
    assert abs(r["torque"] / M - 1) < 1e-9
    assert r["envelope_max"] == pytest.approx(h["A"], rel=1e-5)
    assert r["theta_max"] == pytest.approx(h["theta_max"], rel=1e-5)
    y = r["profile"](np.array([50.0]))
    assert np.hypot(y[1], y[2])[0] == pytest.approx(r["envelope_max"], rel=1e-9)   # centred


def test_clamped_rod_discretisation_independent(clamped_runs):
    """l = 40 (well conditioned): 10 vs 16 segments and rtol 1e-12 vs 1e-11 give the same
    tension and torque to 1e-10; the torque is M . d3 all along (constant)."""
    a = clamped_runs[40.0]
    b = tw.clamped_helix(40.0, 37.0, 40.0 * a["guess"]["M"] / _C + 4 * np.arccos(a["guess"]["mu"]),
                         _B, _C, segments=16, rtol=1e-11)
    assert a["T"] == pytest.approx(b["T"], rel=1e-10)
    assert a["torque"] == pytest.approx(b["torque"], rel=1e-10)
    s = np.linspace(0.0, 40.0, 9)
    y = a["profile"](s)
    D = lag.quat_to_directors(y[3:7])
    assert np.allclose(np.einsum("in,in->n", y[10:13], D[:, 2]), a["torque"], atol=1e-10)


# ----------------------------------------------------------------------------
# C. Maddocks: torque maximum of the Gamma = 1 primary branch; the issue's controls
# ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def torque_max():
    return tw.primary_torque_maximum(route="phi")


def test_torque_maximum_two_routes(torque_max):
    a, b = torque_max, tw.primary_torque_maximum(route="stretch")
    for k in ("phi_L", "torque", "stretch", "l0"):
        assert a[k] == pytest.approx(b[k], abs=1e-10)
    assert a["phi_L"] == pytest.approx(12.6959184929, abs=1e-9)
    assert a["torque"] == pytest.approx(9.5114650332, abs=1e-9)
    assert a["phi_L"] < 13.0999938            # before the Phi fold (rotation control)


def test_torque_maximum_is_a_maximum(torque_max):
    """Shooting at Phi* +- h (Newton at fixed Phi): torque below the maximum on both sides,
    and a quartic through five points peaks at Phi* (checks the implicit derivative)."""
    par, z = (10.0, EI, GJ, EA, L), torque_max["z"]
    hs = np.array([-2e-3, -1e-3, 0.0, 1e-3, 2e-3])
    m = np.array([lag._newton(z, 10.0, par, 1e-12, "phi", target=z[6] + h)[0][2] for h in hs])
    assert m[2] == pytest.approx(torque_max["torque"], abs=1e-12)
    assert np.all(m[[0, 1, 3, 4]] < m[2])
    p = np.polynomial.Polynomial.fit(hs, m, 4).convert()
    roots = p.deriv().roots()
    h0 = roots[np.argmin(np.abs(roots))].real
    assert abs(h0) < 1e-8


def test_torque_maximum_by_collocation(torque_max):
    """solve_bvp (another discretisation) at Phi*: the same torque to 1e-9."""
    c = lag.twisted_bvp(1.0, torque_max["z"], tol=1e-9)
    assert c["torque"] == pytest.approx(torque_max["torque"], abs=1e-9)
    assert c["l0"] == pytest.approx(torque_max["l0"], abs=1e-9)


def test_issue_control_values_at_phi_5():
    """Gamma = 1, Phi = 5: torque 3.89224684363973 (solve --torque) and l0
    0.963014577275618 (solve --l0 ... --w 10 gives T = 10), by shooting and by collocation."""
    s = tw.primary_state(1.0, 5.0)
    assert s["torque"] == pytest.approx(3.89224684363973, abs=1e-12)
    assert s["l0"] == pytest.approx(0.963014577275618, abs=1e-12)
    c = lag.twisted_bvp(1.0, s["z"], tol=1e-10)
    assert c["torque"] == pytest.approx(s["torque"], abs=1e-11)
    assert c["l0"] == pytest.approx(s["l0"], abs=1e-11)
