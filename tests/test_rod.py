"""The Eulerian rod model against things it does not share code with.

Exact solutions, Greenhill's buckling torques, an independent Lagrangian
solve_bvp solution of the planar sag, PROBLEM.md's reference numbers, and a
re-integration of the Kirchhoff equations in the Lagrangian coordinate.
"""

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import lagrangian_reference as lag
from conftest import assert_tangent_matches_differences
from rodcont.collocation import Collocation
from rodcont.drivers.solve import solve_equilibrium
from rodcont.rod import EulerianRod, RodParameters, helical_waves

PAPER = RodParameters()


def straight_solution(model, disc, phi_L, T):
    """Exact straight solution of the weightless rod: Delta = 0, phi = Phi S / L, F = T K3.

    (Force unknowns are components on the frame K1, K2, K3.)"""
    L = model.rod.L
    zero = lambda S: 0 * S
    return disc.project([zero, zero, lambda S: phi_L * S / L, zero, zero, lambda S: T + 0 * S])


# --------------------------------------------------------------------------
# pointwise residual and its derivatives
# --------------------------------------------------------------------------
def test_pointwise_jacobian_matches_central_differences():
    """Complex-step dG/dz of the rod residual against central differences at a random 3D state."""
    model = EulerianRod(PAPER)
    rng = np.random.default_rng(3)
    S = rng.uniform(0, 1, 7)
    z = rng.uniform(-0.4, 0.4, (17, 7))
    z[[11, 13, 15]] *= 20  # forces of the size seen on the branch
    p = model.params(3.0, T=10.0)
    disc = model.discretise(2, 3)
    G, dG = disc._pointwise_jacobian(S, z, p, np.arange(17))
    h = 1e-6
    for j in range(17):
        zp, zm = z.copy(), z.copy()
        zp[j] += h
        zm[j] -= h
        fd = (model.residual(S, zp, p) - model.residual(S, zm, p)) / (2 * h)
        # central differences: truncation O(h^2) ~ 1e-12, rounding ~ eps |G| / h ~ 1e-9
        assert np.allclose(dG[:, j, :], fd, rtol=1e-6, atol=1e-7), j
    assert np.allclose(G, model.residual(S, z, p), rtol=1e-14, atol=1e-13)


@pytest.mark.parametrize("direction,scale", [((0.0, 0.0, -1.0), 0.4), ((0.3, -0.5, -1.0), 0.4),
                                             ((1.0, 2.0, 0.5), 2.0)])
def test_analytic_pointwise_jacobian_matches_the_complex_step(direction, scale):
    """The straight reference's hand-derived dG/dz (EulerianRod.jacobian, what the collocation uses) against
    the complex step of the residual, to rounding: random 3D states up to steep slopes and large forces."""
    import dataclasses
    model = EulerianRod(RodParameters(weight_direction=direction, EA=37.0, GJ=0.6, EI=1.3))
    rng = np.random.default_rng(11)
    npts = 40
    S = rng.uniform(0, 1, npts)
    z = rng.uniform(-scale, scale, (17, npts))
    z[[11, 13, 15]] *= 30
    z[[12, 14, 16]] *= 10
    p = model.params(7.0, T=10.0)
    disc = model.discretise(2, 3)
    G, dG = disc._pointwise_jacobian(S, z, p, disc.active)  # the problem's own jacobian
    complex_step = Collocation(dataclasses.replace(model.problem, jacobian=None), 2, 3)
    Gc, dGc = complex_step._pointwise_jacobian(S, z, p, complex_step.active)
    assert dG.shape == dGc.shape == (6, disc.active.size, npts)
    assert np.allclose(G, Gc, rtol=0, atol=1e-14 * np.abs(Gc).max())
    scale_eq = np.abs(dGc).max(axis=(1, 2), keepdims=True)
    assert np.max(np.abs(dG - dGc) / scale_eq) < 1e-12
    # and the assembled Jacobian of the discretisation
    x = rng.standard_normal(disc.size) * 0.1
    J = disc.linearise(x, p)[1].toarray()
    Jc = complex_step.linearise(x, p)[1].toarray()
    assert np.max(np.abs(J - Jc)) < 1e-12 * np.abs(Jc).max()


def test_assembled_tangent_matches_dense_finite_differences():
    """Sparse Jacobian of the whole discretisation (and dF/dPhi) against a dense central-difference one."""
    model = EulerianRod(PAPER)
    disc = model.discretise(3, 3)
    rng = np.random.default_rng(5)
    eq = solve_equilibrium(1.0, 6.0, PAPER, N=3, k=3, adapt=False)  # on disc's own mesh
    x = eq.x + 1e-3 * rng.standard_normal(disc.size)
    p = model.params(6.0, T=10.0)
    assert_tangent_matches_differences(disc, x, p, 1e-6)


# --------------------------------------------------------------------------
# exact solutions
# --------------------------------------------------------------------------
@pytest.mark.parametrize("T,phi_L", [(0.0, 2.0), (7.5, 5.0), (-3.0, 1.0)])
def test_straight_weightless_rod_is_exact(T, phi_L):
    """w = 0: Delta = 0, alpha = 1 + T/EA, l = L, l0 = L/alpha, torque = GJ Phi / l0 (PROBLEM.md)."""
    rod = RodParameters(w=0.0)
    model = EulerianRod(rod)
    disc = model.discretise(6, 5)
    p = model.params(phi_L, T=T)
    x0 = straight_solution(model, disc, phi_L, T) + 1e-3  # start off the solution
    r = disc.newton(x0, p)
    assert r.converged, r.message
    o = model.outputs(disc, r.x, p)
    alpha = 1 + T / rod.EA
    assert abs(o["stretch"]) < 1e-12
    assert o["l0"] == pytest.approx(rod.L / alpha, abs=1e-12)
    assert o["torque"] == pytest.approx(rod.GJ * phi_L / (rod.L / alpha), abs=1e-12)
    S = np.linspace(0, 1, 50)
    assert np.max(np.abs(disc.evaluate(r.x, S, 0))) < 1e-12
    assert np.max(np.abs(disc.evaluate(r.x, S, 1))) < 1e-12
    assert np.max(np.abs(disc.evaluate(r.x, S, 2) - phi_L * S)) < 1e-12


def _smallest_singular_value(model, disc, phi_L, T):
    x = straight_solution(model, disc, phi_L, T)
    J = disc.jacobian(x, model.params(phi_L, T=T)).toarray()
    return np.linalg.svd(J, compute_uv=False)[-1]


@pytest.mark.parametrize("tension,expected", [(0.0, 8.9868), (10.0, 10.42886)])
def test_greenhill_buckling_torque(tension, expected):
    """Weightless, nearly inextensible rod: the straight branch loses uniqueness at Greenhill's torque.

    Located as the zero of the smallest singular value of the tangent operator
    along the exact straight branch (the isotropic rod's buckling mode is a
    circle of helices, so the kernel is two-dimensional and det does not change sign).
    """
    rod = RodParameters(w=0.0, EA=1e8)
    model = EulerianRod(rod)
    disc = model.discretise(8, 5)
    T = tension * rod.EI / rod.L**2
    alpha = 1 + T / rod.EA
    guess = expected * rod.EI / rod.GJ  # Phi for torque L / EI = expected
    res = minimize_scalar(lambda ph: _smallest_singular_value(model, disc, ph, T),
                          bounds=(0.8 * guess, 1.2 * guess), method="bounded", options=dict(xatol=1e-7))
    torque = rod.GJ * res.x * alpha / rod.L
    sigma_far = _smallest_singular_value(model, disc, 0.8 * guess, T)
    assert res.fun < 1e-4 * sigma_far  # a genuine singularity, not a shallow minimum
    assert torque * rod.L / rod.EI == pytest.approx(expected, abs=1e-3)


# --------------------------------------------------------------------------
# planar heavy beam
# --------------------------------------------------------------------------
def test_planar_sag_matches_independent_lagrangian_solution():
    """Phi = 0: planar solution (Delta1 = 0, torque 0) equals a Lagrangian solve_bvp solution."""
    for gamma in (0.0, 1.0, 3.0):
        eq = solve_equilibrium(gamma, 0.0, PAPER)
        ref = lag.planar_sag(gamma)
        o = eq.outputs
        assert o["stretch"] == pytest.approx(ref["stretch"], abs=1e-7)
        assert o["l0"] == pytest.approx(ref["l0"], abs=1e-7)
        assert abs(o["torque"]) < 1e-12
        S = np.linspace(0, 1, 41)
        d = eq.system.disc
        assert np.max(np.abs(d.evaluate(eq.x, S, 0))) < 1e-12  # no lateral deflection
        # the centreline x3(x1) against the Lagrangian one
        r = eq.centreline(S)
        assert np.max(np.abs(r[2] - ref["deflection"](r[0]))) < 1e-7


def test_gamma1_reference_numbers():
    """PROBLEM.md (Gamma = 1, paper values, N = 15, k = 5): Phi = 0 and Phi = 10."""
    o0 = solve_equilibrium(1.0, 0.0, PAPER).outputs
    assert o0["stretch"] == pytest.approx(9.2449753e-4, abs=1e-7 * 9.2449753e-4 + 5e-12)
    assert o0["l0"] == pytest.approx(0.96282043, abs=1e-8)
    o10 = solve_equilibrium(1.0, 10.0, PAPER).outputs
    assert o10["stretch"] == pytest.approx(3.1059074e-3, abs=1e-10)
    assert o10["torque_spread"] < 1e-7  # torque constant along S (to discretisation accuracy)


# --------------------------------------------------------------------------
# 3D solution in the Lagrangian coordinate
# --------------------------------------------------------------------------
def _end_state(eq):
    """r, directors (columns), F and M at S = 0 from the Eulerian solution, global components."""
    model, disc, x = eq.system.model, eq.system.disc, eq.x
    rod = model.rod
    S0 = np.array([0.0])
    D = model.directors(disc, x, S0)[:, :, 0].T  # columns d1, d2, d3
    D1 = np.stack([disc.evaluate(x, S0, 0, nu) for nu in range(4)])
    D2 = np.stack([disc.evaluate(x, S0, 1, nu) for nu in range(4)])
    r, r1, r2, _ = model.curve.centreline_jets(S0, D1, D2)
    n = np.linalg.norm(r1[:, 0])
    F = model.force(disc, x, S0)[:, 0]
    d3 = r1[:, 0] / n
    alpha = 1 + F @ d3 / rod.EA
    u_perp = alpha * np.cross(r1[:, 0], r2[:, 0]) / n**3
    M = rod.EI * u_perp + eq.outputs["torque"] * d3
    return r[:, 0], D, F, M


def clamp_miss(eq) -> tuple[float, float]:
    """Integrate the Kirchhoff equations (independent code) from S = 0 with the solution's end
    force and moment over its unstressed length; how far the end lands from the far clamp
    (position, directors turned by phi_L about e1)."""
    ph = eq.outputs["phi_L"]
    r0, D0, F0, M0 = _end_state(eq)
    rod = eq.system.model.rod
    out = lag.kirchhoff_integrate(r0, D0, F0, M0, eq.outputs["l0"], w=rod.w, EI=rod.EI, GJ=rod.GJ, EA=rod.EA)
    c, s = math.cos(ph), math.sin(ph)
    clamp = np.array([[0, 0, 1], [c, -s, 0], [s, c, 0]])
    return float(np.max(np.abs(out["r"] - [rod.L, 0, 0]))), float(np.max(np.abs(out["D"] - clamp)))


def test_twisted_solution_satisfies_kirchhoff_equations():
    """Gamma = 1, Phi = 10: integrating paper eqs 3-6 in s from S = 0 with the computed end force and
    moment lands on the computed centreline and clamp at S = L (1e-6)."""
    eq = solve_equilibrium(1.0, 10.0, PAPER)
    model, disc = eq.system.model, eq.system.disc
    r0, D0, F0, M0 = _end_state(eq)
    out = lag.kirchhoff_integrate(r0, D0, F0, M0, eq.outputs["l0"], w=PAPER.w, EI=PAPER.EI, GJ=PAPER.GJ, EA=PAPER.EA)
    rL = model.centreline(disc, eq.x, np.array([1.0]))[:, 0]
    DL = model.directors(disc, eq.x, np.array([1.0]))[:, :, 0].T
    assert np.max(np.abs(out["r"] - rL)) < 1e-6
    assert np.max(np.abs(out["D"] - DL)) < 1e-6
    # and the clamp itself: r(L) = L e1, d3 = e1, section turned by Phi about e1
    c, s = math.cos(10.0), math.sin(10.0)
    assert np.max(np.abs(out["r"] - [1, 0, 0])) < 1e-6
    assert np.max(np.abs(out["D"] - np.array([[0, 0, 1], [c, -s, 0], [s, c, 0]]))) < 1e-6
    # the centreline in between, at the Lagrangian positions of Eulerian sections
    S = np.linspace(0, 1, 11)
    sol = out["sol"]
    s_of_S = np.array([_unstressed_arclength(eq, Si) for Si in S])
    assert np.max(np.abs(sol(s_of_S) - model.centreline(disc, eq.x, S))) < 1e-6


def _unstressed_arclength(eq, S):
    """s(S) = integral_0^S |r'| / alpha dS (Gauss rule on a fine grid)."""
    from scipy.integrate import quad
    model, disc, x = eq.system.model, eq.system.disc, eq.x
    p = eq.system.params(eq.outputs["phi_L"])

    def ds(Si):
        Sv = np.array([Si])
        z = np.concatenate([np.stack([disc.evaluate(x, Sv, i, nu) for nu in range(m + 1)])
                            for i, m in enumerate(disc.problem.orders)])
        _, alpha, n, _ = model._axial_quantities(Sv, z, p)
        return float(n[0] / alpha[0])

    return quad(ds, 0, S, epsabs=1e-13, epsrel=1e-13, limit=200)[0] if S > 0 else 0.0


def test_helical_waves_of_a_planar_shape_in_any_plane_do_not_follow_rounding():
    """A planar shape with its slope through zero eight times, in the plane at 45 degrees (the 1 km well's):
    0 waves however rounding tilts it (np.unwrap took each crossing as +-pi and counted 1 in 4 of 10)."""
    S = np.linspace(0, 1, 2001)
    shape = -0.005 * np.sin(np.pi * S) ** 2 * (1 + 0.9 * np.cos(6 * np.pi * S))
    slope = np.gradient(shape, S)
    rng = np.random.default_rng(7)
    for _ in range(20):
        d1, d2 = (slope * (1 + 1e-12 * rng.standard_normal(S.size)) for _ in range(2))
        assert helical_waves(S, shape, shape, d1, d2) == 0
    # a helix in that plane's frame still counts its turn
    env = np.sin(np.pi * S) ** 2
    D1 = shape + 0.02 * env * np.cos(2 * np.pi * S)
    D2 = shape + 0.02 * env * np.sin(2 * np.pi * S)
    assert helical_waves(S, D1, D2, np.gradient(D1, S), np.gradient(D2, S)) == 1


def test_helical_waves_counts_turns_of_the_slope():
    """A helix of n turns about a (slightly sagging) axis counts n; the planar sag counts 0."""
    S = np.linspace(0, 1, 2001)
    sag = -0.005 * np.sin(np.pi * S) ** 2
    sagp = np.gradient(sag, S)
    assert helical_waves(S, 0 * S, sag, 0 * S, sagp) == 0
    for n in (1, 2, 3):
        env = np.sin(np.pi * S) ** 2
        D1 = 0.02 * env * np.cos(2 * np.pi * n * S)
        D2 = sag + 0.02 * env * np.sin(2 * np.pi * n * S)
        assert helical_waves(S, D1, D2, np.gradient(D1, S), np.gradient(D2, S)) == n
    # a sag whose slope exceeds the helix's keeps the slope vector from circling: not a wave
    D1 = 0.002 * np.sin(np.pi * S) ** 2 * np.cos(2 * np.pi * S)
    D2 = -0.05 * np.sin(np.pi * S) ** 2
    assert helical_waves(S, D1, D2, np.gradient(D1, S), np.gradient(D2, S)) == 0


def test_the_residual_is_the_one_before_loads_became_objects():
    """The weight and the wall are load objects now (rodcont.loads) and the boundary conditions are assembled
    from end objects (rodcont.ends): on random jets and unknowns, straight and curved references, with and
    without a wall (constant or tapered), a well with joins, the pointwise residual, the discrete residual,
    the Jacobian and the parameter derivatives are those of the code before (commit 0ee0293, stored by
    tests/data/make_rod_residual_reference.py), to rounding."""
    import os
    import sys
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")
    sys.path.insert(0, here)
    try:
        from make_rod_residual_reference import cases, evaluate
    finally:
        sys.path.remove(here)
    ref = np.load(os.path.join(here, "rod_residual_reference.npz"))
    for i, (name, (make, scale)) in enumerate(cases().items()):
        with np.errstate(all="ignore"):
            new = evaluate(make(), scale, seed=100 + i)
        for key, value in new.items():
            old = ref[f"{name}/{key}"]
            assert value.shape == old.shape, (name, key)
            assert np.max(np.abs(value - old)) <= 1e-14 * np.max(np.abs(old)), (name, key)
