"""The moving frame's hand-derived pointwise Jacobian (EulerianRod._jacobian_curved) against the complex step.

The complex step of the residual (``Im G(z + i h e_j) / h``, h = 1e-30) is exact to rounding and shares no
derivative code with the hand-derived chain rule: the two must agree to rounding at random states, on the
1 km well, the arc and the helix conduit, with the wall's contact active and inactive, with friction (axial
and turning), a varying clearance and a rod of sections.
"""

import dataclasses
import os

import numpy as np
import pytest

from rodcont.collocation import Collocation
from rodcont.contact import Wall, load_conduit
from rodcont.curves import Helix, parse_reference
from rodcont.loads import DistributedLoad, Friction, Kinematics, WallContact, Weight
from rodcont.rod import EulerianRod, Jet, RodParameters, Sections

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")
WELL_L = 973.077121578337
PIPE = RodParameters(EI=1.25e6, GJ=9.6e5, EA=7.15e8, w=235.0, L=WELL_L)


def _conduit(name, rod):
    curve, wall = load_conduit(os.path.join(EXAMPLES, name), rod.L)
    return curve, wall


def _random_state(model, rng, npts, deflection, force):
    """Random jets: deflections of size ``deflection`` (its derivatives scaled by the span), forces ``force``."""
    a, b = model.interval
    S = rng.uniform(a, b, npts)
    z = rng.uniform(-1.0, 1.0, (Jet.SIZE, npts))
    for rows in (Jet.D1, Jet.D2):
        for j, r in enumerate(rows):
            z[r] *= deflection / (0.05 * (b - a)) ** j
    z[list(Jet.PHI)] *= 0.5
    z[Jet.F] *= force
    z[Jet.FP] *= force / (b - a)
    return S, z


def _compare(model, S, z, p):
    """Largest difference of the hand-derived dG from the complex step's, relative to each equation's largest
    derivative, and to each (equation, component)'s own largest one where that is not a cancellation's
    rounding (above 1e-8 of the equation's)."""
    disc = model.discretise(6, 3)
    assert model.problem.jacobian is not None  # the hand-derived path
    G, dG = disc._pointwise_jacobian(S, z, p, disc.active)
    cs = Collocation(dataclasses.replace(model.problem, jacobian=None), disc.breakpoints, 3)
    Gc, dGc = cs._pointwise_jacobian(S, z, p, cs.active)
    assert dG.shape == dGc.shape == (6, disc.active.size, S.size)
    np.testing.assert_array_equal(G, model.residual(S, z, p))  # the residual's own values
    assert np.max(np.abs(G - Gc)) <= 1e-14 * np.abs(Gc).max()
    eq = np.abs(dGc).max(axis=(1, 2), keepdims=True)
    col = np.abs(dGc).max(axis=2, keepdims=True)
    own = np.where(col > 1e-8 * eq, col, np.inf)
    return np.max(np.abs(dG - dGc) / eq), np.max(np.abs(dG - dGc) / own)


def _pressure_range(model, S, z):
    """Smallest and largest wall force over the contact scale at the points."""
    P = model.contact_scale
    pr = model.wall.pressure(z[Jet.D1[0]], z[Jet.D2[0]], P, S) / P
    return pr.min(), pr.max()


CASES = {
    "well": lambda: (PIPE, *_conduit("conduit_well.toml", PIPE)),
    "arc": lambda: (RodParameters(), *_conduit("conduit_arc.toml", RodParameters())),
    "helix": lambda: (RodParameters(), *_conduit("conduit_helix.toml", RodParameters())),
    # the Frenet frame twists (k3 = tau != 0): the frame's own turn in r', F' and tau_q
    "helix-frenet": lambda: (RodParameters(L=1.5), Helix(0.05, 1.5, 2.0, frame="frenet"), Wall(0.01, eps=1e-5)),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("contact", ["inactive", "active"])
def test_the_curved_jacobian_is_the_complex_step_to_rounding(case, contact):
    """Weight and wall: inside the clearance (the wall's force below 1e-3 of its scale at every point) and
    across it (above the scale at some points, below at others)."""
    rod, curve, wall = CASES[case]()
    model = EulerianRod(rod, curve, wall=wall)
    assert case != "helix-frenet" or np.all(model._curve_data(np.array([0.3]))[0][2, 0] != 0)
    rng = np.random.default_rng(7)
    c = wall.c_max
    T = 1e5 if case == "well" else 10.0
    S, z = _random_state(model, rng, 60, 0.6 * c / np.sqrt(2) if contact == "inactive" else 1.3 * c, 3 * T)
    lo, hi = _pressure_range(model, S, z)
    if contact == "inactive":
        assert hi < 1e-3
    else:
        assert hi > 1.0 and lo < 1e-3
    by_eq, by_col = _compare(model, S, z, model.params(1.3, T=T))
    assert by_eq < 1e-13
    assert by_col < 1e-10


@pytest.mark.parametrize("operation", ["pick-up", "slack-off", "rotate"])
def test_the_curved_jacobian_with_friction_is_the_complex_step_to_rounding(operation):
    """Friction on the wall's force along d3 (the trip) and about it (the rotation: the torque equation)."""
    rod, curve, wall = CASES["helix"]()
    model = EulerianRod(rod, curve, loads=[Weight(), WallContact(wall), Friction(0.3, 0.02, operation)])
    S, z = _random_state(model, np.random.default_rng(3), 60, 1.3 * wall.c_max, 30.0)
    assert _pressure_range(model, S, z)[1] > 1.0
    by_eq, by_col = _compare(model, S, z, model.params(-0.7, T=10.0))
    assert by_eq < 1e-13
    assert by_col < 1e-10


def test_the_curved_jacobian_with_a_varying_clearance_and_sections_is_the_complex_step_to_rounding():
    """A tapered conduit (the wall's axial force p c' |Delta|^2 / c^2) on the arc, a rod of two sections
    (the weight and the stiffnesses vary with S)."""
    rod = RodParameters()
    wall = Wall(((0.0, 0.01), (1.0, 0.03)), eps=1e-4)
    model = EulerianRod(rod, parse_reference("arc:0.6", 1.0), wall=wall,
                        sections=Sections([0.45], [[1.0, 1.0, 1.0, 1.0], [2.5, 3.0, 0.5, 4.0]]))
    S, z = _random_state(model, np.random.default_rng(5), 80, 0.03, 30.0)
    lo, hi = _pressure_range(model, S, z)
    assert hi > 1.0 and lo < 1e-3
    by_eq, by_col = _compare(model, S, z, model.params(2.0, T=-4.0))
    assert by_eq < 1e-13
    assert by_col < 1e-10


def test_the_assembled_jacobian_of_the_well_is_the_complex_steps():
    """The collocation's whole Jacobian on a coarse mesh of the well (joins at its stations), both ways."""
    curve, wall = _conduit("conduit_well.toml", PIPE)
    model = EulerianRod(PIPE, curve, wall=wall)
    disc = model.discretise(12, 4)
    cs = Collocation(dataclasses.replace(model.problem, jacobian=None), disc.breakpoints, 4)
    x = model.initial_guess(disc, 1e5) + 1e-3 * np.random.default_rng(2).standard_normal(disc.size)
    p = model.params(0.5, T=1e5)
    F, J = disc.linearise(x, p)[:2]
    Fc, Jc = cs.linearise(x, p)[:2]
    np.testing.assert_array_equal(F, disc.residual(x, p))
    assert np.max(np.abs(F - Fc)) <= 1e-14 * np.abs(Fc).max()
    J, Jc = J.toarray(), Jc.toarray()
    assert np.max(np.abs(J - Jc)) <= 1e-13 * np.abs(Jc).max()


class _NoTangent(DistributedLoad):
    """A load without tangents: the model must take the complex step."""

    def force(self, k: Kinematics):
        return 0.1 * k.d3


def test_a_load_without_tangents_sends_the_curved_rod_to_the_complex_step():
    curve = parse_reference("arc:0.6", 1.0)
    assert EulerianRod(RodParameters(), curve).problem.jacobian is not None
    assert EulerianRod(RodParameters(), curve, loads=[Weight(), _NoTangent()]).problem.jacobian is None


def test_the_curved_jacobian_in_blocks_of_points_is_the_same_arrays(monkeypatch):
    """Long rods are differentiated in blocks of points (bounded memory): the same values, bit for bit."""
    import rodcont.rod as rod_module
    rod, curve, wall = CASES["well"]()
    model = EulerianRod(rod, curve, wall=wall)
    S, z = _random_state(model, np.random.default_rng(9), 50, 0.06, 3e5)
    p = model.params(0.2, T=1e5)
    G, dG = model._jacobian_curved(S, z, p)
    monkeypatch.setattr(rod_module, "JACOBIAN_BLOCK", 7)
    Gb, dGb = model._jacobian_curved(S, z, p)
    np.testing.assert_array_equal(G, Gb)
    np.testing.assert_array_equal(dG, dGb)
