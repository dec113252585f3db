"""Self-checks of the independent Lagrangian reference (tests/lagrangian_reference.py).

These check the *reference*, not rodcont, against facts that do not come from
it: exact solutions, classical closed forms (Greenhill), the numbers of
shared/PROBLEM.md, the nonlinear shooting Jacobian (for the linearised
critical twists), and a second discretisation (collocation by solve_bvp) for
a stored secondary fold.  The stored folds are in
tests/data/lagrangian_folds.json (regenerate with
tests/data/make_lagrangian_folds.py).  Runs in ~10 s.
"""

import json
import os

import numpy as np
import pytest

import lagrangian_reference as lag

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                    "lagrangian_folds.json")
PAR = (1., 0.75, 255., 1.)           # EI, GJ, EA, L (paper values), w = 10


@pytest.fixture(scope="module")
def folds():
    with open(DATA) as f:
        return json.load(f)


def test_straight_weightless_state_is_exact():
    """w = 0: alpha = 1 + T/EA, l0 = L/alpha, torque = GJ Phi/l0 land on the clamp."""
    gamma, phi = 1.0, 17.3
    T = gamma * 10.
    x = lag.straight_weightless_state(gamma, phi)
    assert x[5] == pytest.approx(1 / (1 + T / 255.), rel=1e-15)
    assert x[2] == pytest.approx(0.75 * phi / x[5], rel=1e-15)
    out = lag.kirchhoff_integrate(np.zeros(3), np.array([[0., 0., 1.], [1., 0., 0.], [0., 1., 0.]]),
                                  np.array([T, 0., 0.]), x[2:5], x[5], w=0.)
    assert np.allclose(out["r"], [1., 0., 0.], atol=1e-12)
    Dend = lag.quat_to_directors(lag.clamp_quaternion(phi))
    assert np.allclose(out["D"], Dend, atol=1e-11)
    assert out["length"] == pytest.approx(1., abs=1e-13)
    G, _, sc = lag._shoot_ext(x, T, PAR, 1e-12)
    assert np.max(np.abs(G[:6])) < 1e-11 and abs(G[6]) < 1e-13 and sc > 0


def test_critical_twists_classical_values():
    """Greenhill (T = 0): M L/EI = 2 x 4.4934094579 (tan(x/2) = x/2); T L^2/EI = 10,
    inextensible: 10.42886 (shared/PROBLEM.md)."""
    c0 = lag.critical_twists(0.0)
    assert c0["torque"][0] == pytest.approx(8.986818916, abs=1e-8)
    assert c0["phi_L"][0] == pytest.approx(8.986818916 / 0.75, abs=1e-8)
    c10 = lag.critical_twists(1.0, EA=1e12)
    assert c10["torque"][0] == pytest.approx(10.42886, abs=1e-5)


def test_critical_condition_equals_linearised_determinant():
    """The closed form is the 3x3 determinant of the linearised BVP
    EI z'' - i M z' - alpha T z = -alpha V, z(0) = z(l0) = 0, int z = 0."""
    T, EA, EI, GJ = 10., 255., 1., 0.75
    alpha = 1 + T / EA
    l0 = 1 / alpha

    def det(phi):
        M = GJ * phi / l0
        lam = np.roots([EI, -1j * M, -alpha * T])
        E = np.exp(lam * l0)
        A = np.array([[1, 1, 1], [1, E[0], E[1]], [l0, (E[0] - 1) / lam[0], (E[1] - 1) / lam[1]]])
        return abs(np.linalg.det(A))

    phis = lag.critical_twists(1.0)["phi_L"]
    for p in phis[:3]:
        assert det(p) < 1e-10 * det(p + 0.05)


def test_critical_twists_are_double_zeros_of_the_shooting_jacobian():
    """Nonlinear shooting map at the straight state: two singular values of the
    6x6 Jacobian (F2, F3, M1, M2, M3, l0) vanish at Phi_n (rotational symmetry),
    and grow linearly away from it."""
    for _n, phi in enumerate(lag.critical_twists(1.0, 2)["phi_L"]):
        x = lag.straight_weightless_state(1.0, phi)
        s = np.linalg.svd(lag._shoot_ext(x, 10., PAR, 1e-12)[1][:6, :6], compute_uv=False)
        assert s[-1] < 1e-12 and s[-2] < 1e-12 and s[-3] > 1e-2
        x[6] += 1e-4
        x[2] = 0.75 * x[6] / x[5]
        s2 = np.linalg.svd(lag._shoot_ext(x, 10., PAR, 1e-12)[1][:6, :6], compute_uv=False)
        assert s2[-1] > 1e3 * s[-1]


def _fold_check(entry, gamma):
    """Re-evaluate a stored fold: residual ~ 0 and the branch tangent has no Phi component."""
    x = np.array(entry["x"])
    G, J, sc = lag._shoot_ext(x, gamma * 10., PAR, 1e-12)
    assert np.max(np.abs(G[:6])) < 1e-11 and sc > 0
    assert G[6] == pytest.approx(entry["stretch"], abs=1e-12)
    t = np.linalg.svd(J[:6, :7])[2][-1]
    assert abs(t[6]) < 1e-8


def test_primary_fold_gamma1_matches_problem_md(folds):
    e = next(f for f in folds["primary_folds"] if f["gamma"] == 1.0)
    assert e["status"] == "fold"
    assert e["phi_L"] == pytest.approx(13.0999938, abs=1e-7)
    assert e["stretch"] == pytest.approx(0.14544795, abs=1e-8)
    assert e["torque"] == pytest.approx(8.3135475, abs=1e-7)
    assert e["l0"] == pytest.approx(1.1043872, abs=1e-7)
    assert e["min_d3_e1"] == pytest.approx(0.815, abs=1e-3)
    _fold_check(e, 1.0)


def test_stored_folds_are_folds(folds):
    for e in folds["primary_folds"] + folds["secondary_folds"]:
        if e["status"] == "fold":
            _fold_check(e, e["gamma"])
            assert e["accuracy"]["phi_L"] < 1e-8 and e["route_check"]["phi_L"] < 1e-9


def test_secondary_fold_by_collocation(folds):
    """Gamma = 1, n = 1: solve_bvp (another discretisation) at the stored fold
    stretch gives the same Phi, and Phi(stretch) from three collocation
    solutions peaks at the stored stretch."""
    e = next(f for f in folds["secondary_folds"] if f["gamma"] == 1.0 and f["n"] == 1)
    assert e["status"] == "fold"
    assert e["phi_L"] == pytest.approx(21.0228, abs=1e-4)      # code-under-test value ~21.02
    x, s0, d = np.array(e["x"][:7]), e["stretch"], 5e-5
    p = [lag.twisted_bvp(1.0, x, stretch=s0 + k * d, tol=1e-9)["phi_L"] for k in (-1, 0, 1)]
    assert p[1] == pytest.approx(e["phi_L"], abs=1e-9)
    assert p[0] < p[1] and p[2] < p[1]
    vertex = s0 + 0.5 * d * (p[0] - p[2]) / (p[0] - 2 * p[1] + p[2])
    assert vertex == pytest.approx(s0, abs=1e-7)
