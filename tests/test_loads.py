"""Distributed loads and end conditions as objects (rodcont.loads, rodcont.ends), against closed forms.

A load written once (a class of a few lines here, as friction will be) enters the straight and the curved
residual alike; the end conditions assemble the boundary conditions, free the parameter they make unknown
and add the integral condition of a fixed unstressed length.
"""

import math

import numpy as np
import pytest

import rodcont
from conftest import assert_tangent_matches_differences
from rodcont.collocation import Collocation
from rodcont.curves import parse_reference
from rodcont.ends import Clamp, RodEnds, Rotation, Tension, Torque, UnstressedLength
from rodcont.loads import DistributedLoad, WallContact, Weight
from rodcont.rod import EulerianRod, Jet, RodParameters
from rodcont.system import RodSystem

WEIGHTLESS = RodParameters(w=0.0)


class UniformMoment(DistributedLoad):
    """A distributed moment ``t d3`` per unit S (a twist load, as friction's ``mu p r``): ``m' + t = 0``."""

    def __init__(self, t):
        self.t = t

    def moment(self, k):
        return self.t * k.d3


class AxialDrag(DistributedLoad):
    """A force ``f d3`` per unit S along the rod (as friction's axial part): ``F.d3`` falls by ``f`` per unit S."""

    def __init__(self, f):
        self.f = f

    def force(self, k):
        return self.f * k.d3


def _solve(model, T, phi_L, N=10):
    disc = model.discretise(N)
    p = model.params(phi_L, T=T)
    r = disc.newton(model.initial_guess(disc, T), p)
    assert r.converged, r.message
    return disc, r.x, p


def test_a_distributed_moment_makes_the_torque_fall_linearly_as_the_closed_form():
    """The straight weightless rod under a uniform distributed moment t stays straight with
    m(S) = m0 - t S, m = GJ alpha phi' (n = 1, alpha = 1 + T/EA): phi(L) = (m0 L - t L^2/2)/(GJ alpha) = Phi
    gives m0 = GJ alpha Phi / L + t L / 2. The load enters the torque equation and nothing else."""
    t, T, Phi = 0.8, 5.0, 2.0
    model = EulerianRod(WEIGHTLESS, loads=[Weight(), UniformMoment(t)])
    assert model.problem.jacobian is None  # not the weight-only fast path: the complex step
    disc, x, p = _solve(model, T, Phi)
    alpha = 1 + T / WEIGHTLESS.EA
    S = np.linspace(0, 1, 9)
    m = model._axial_quantities(S, (disc.jet_matrix(S) @ x).reshape(Jet.SIZE, -1), p)[0]
    m0 = WEIGHTLESS.GJ * alpha * Phi + t / 2
    assert np.allclose(m, m0 - t * S, rtol=0, atol=1e-11)
    assert np.max(np.abs([disc.evaluate(x, S, i) for i in (0, 1)])) < 1e-13  # straight


def test_a_distributed_axial_force_makes_the_tension_fall_linearly_as_the_closed_form():
    """An axial force f d3 per unit S on the straight weightless rod: F.K3 = T + f (L - S), the rod straight."""
    f, T = 3.0, 10.0
    disc, x, p = _solve(EulerianRod(WEIGHTLESS, loads=[Weight(), AxialDrag(f)]), T, 1.0)
    S = np.linspace(0, 1, 9)
    assert np.allclose(disc.evaluate(x, S, 5), T + f * (1 - S), rtol=0, atol=1e-11)


@pytest.mark.parametrize("curve", [None, "arc:0.6", "helix:0.05,1"])
def test_a_load_enters_the_straight_and_the_curved_residual_through_the_same_seam(curve):
    """For random jets, the residual with extra loads minus the residual without is exactly the loads'
    force in the force balance, their moment in the moment balance (K1, K2) and moment.d3 / GJ in the torque
    equation, on the straight and on moving frames alike."""
    rod = RodParameters()
    c = parse_reference(curve, 1.0) if curve else None
    base = EulerianRod(rod, c)
    loaded = EulerianRod(rod, c, loads=[Weight(), UniformMoment(0.7), AxialDrag(-2.0)])
    rng = np.random.default_rng(4)
    S = rng.uniform(*base.interval, 30)
    z = rng.uniform(-0.3, 0.3, (Jet.SIZE, 30))
    z[Jet.F] *= 30
    p = base.params(2.0, T=10.0)
    dG = loaded.residual(S, z, p) - base.residual(S, z, p)
    _, alpha, n, d3 = base._axial_quantities(S, z, p)
    scale = np.abs(base.residual(S, z, p)).max()
    assert np.allclose(dG[:3], -2.0 * d3, rtol=0, atol=1e-13 * scale)
    assert np.allclose(dG[3:5], 0.7 * d3[:2], rtol=0, atol=1e-13 * scale)
    assert np.allclose(dG[5], 0.7 * np.sum(d3 * d3, axis=0) / rod.GJ, rtol=0, atol=1e-13 * scale)


def test_a_new_load_has_an_exact_jacobian_from_the_complex_step():
    model = EulerianRod(RodParameters(), parse_reference("arc:0.6", 1.0), loads=[Weight(), UniformMoment(0.5)])
    disc = model.discretise(3, 3)
    x = model.initial_guess(disc, 10.0) + 1e-3 * np.random.default_rng(2).standard_normal(disc.size)
    assert_tangent_matches_differences(disc, x, model.params(1.0, T=10.0), 1e-6)


def test_the_weight_alone_on_the_straight_rod_keeps_the_hand_derived_jacobian():
    """The performance paths: weight only on the straight reference (with any end conditions), and a moving
    frame whose loads all have tangents (tests/test_rod_curved_jacobian.py); a straight rod in a wall and a
    load without tangents take the complex step."""
    assert EulerianRod().problem.jacobian is not None
    assert EulerianRod(ends=RodEnds(end=(Clamp(), Torque(1.0), Tension()))).problem.jacobian is not None
    from rodcont.contact import Wall
    assert EulerianRod(wall=Wall(0.01)).problem.jacobian is None
    assert EulerianRod(curve=parse_reference("arc:0.6", 1.0)).problem.jacobian is not None
    assert EulerianRod(curve=parse_reference("arc:0.6", 1.0),
                       loads=[Weight(), UniformMoment(0.5)]).problem.jacobian is None


def test_loads_and_ends_are_checked():
    from rodcont.contact import Wall
    with pytest.raises(TypeError, match="DistributedLoad"):
        EulerianRod(loads=["weight"])
    with pytest.raises(TypeError, match="RodEnds"):
        EulerianRod(ends=(Clamp(),))
    with pytest.raises(ValueError, match="one conduit wall"):
        EulerianRod(wall=Wall(0.01), loads=[Weight(), WallContact(Wall(0.02))])
    with pytest.raises(ValueError, match="one axial condition"):
        RodEnds(start=(Clamp(), Rotation(), Tension()))
    with pytest.raises(ValueError, match="at S = L only"):
        RodEnds(start=(Clamp(), Torque(1.0)))
    with pytest.raises(ValueError, match="two twist"):
        RodEnds(end=(Clamp(), Rotation(), Torque(1.0), Tension()))
    with pytest.raises(ValueError, match="needs a position"):
        RodEnds(end=(Rotation(), Tension()))
    with pytest.raises(ValueError, match="positive"):
        UnstressedLength(-1.0) and RodEnds(end=(Clamp(), Rotation(), UnstressedLength(-1.0)))
    with pytest.raises(TypeError, match="finite number"):
        RodEnds(end=(Clamp(), Torque("x"), Tension()))


def test_the_default_ends_are_affine_and_a_torque_is_not():
    assert EulerianRod().problem.affine_bc and EulerianRod().problem.free == []
    m = EulerianRod(ends=RodEnds(end=(Clamp(), Torque(2.0), Tension())))
    assert not m.problem.affine_bc
    assert m.param_names[-1] == "torque" and m.problem.free == [0] and m.params()[-1] == 2.0
    m = EulerianRod(ends=RodEnds(end=(Clamp(), Rotation(), UnstressedLength(0.9))))
    assert m.problem.affine_bc and m.problem.free == [1] and m.params()[-1] == 0.9 and m.problem.integrals


def test_a_prescribed_end_torque_gives_the_closed_form_rotation_and_an_exact_tangent():
    """The straight weightless rod under end torque M: m = GJ alpha phi' constant, phi_L = M L / (GJ (1 + T/EA))
    (phi_L an unknown of the discretisation); its Jacobian, free column included, against differences."""
    M, T = 1.5, 4.0
    model = EulerianRod(WEIGHTLESS, ends=RodEnds(end=(Clamp(), Torque(M), Tension())))
    disc, x, p = _solve(model, T, 0.0)
    phi_L = disc.full_params(x, p)[0]
    assert phi_L == pytest.approx(M / (WEIGHTLESS.GJ * (1 + T / WEIGHTLESS.EA)), rel=1e-12)
    small = EulerianRod(RodParameters(), ends=RodEnds(end=(Clamp(), Torque(M), Tension())))
    d = small.discretise(3, 3)
    xs = small.initial_guess(d, 10.0) + 1e-3 * np.random.default_rng(8).standard_normal(d.size)
    ps = small.params(0.0, T=10.0)
    J = d.linearise(xs, ps)[1].toarray()
    h, E = 1e-6, np.eye(d.size)
    Jfd = np.stack([(d.residual(xs + h * e, ps) - d.residual(xs - h * e, ps)) / (2 * h) for e in E], axis=1)
    assert np.allclose(J, Jfd, rtol=1e-6, atol=1e-6) and np.any(J[:, d.free_index[0]] != 0)


def test_a_fixed_unstressed_length_gives_the_closed_form_tension():
    """The straight weightless rod of unstressed length l0 spanning L: L = l0 (1 + T/EA), T an unknown."""
    l0 = 0.99
    model = EulerianRod(WEIGHTLESS, ends=RodEnds(end=(Clamp(), Rotation(), UnstressedLength(l0))))
    disc, x, p = _solve(model, 0.0, 1.0)
    assert disc.full_params(x, p)[1] == pytest.approx(WEIGHTLESS.EA * (1 / l0 - 1), rel=1e-12)
    assert model.outputs(disc, x, p)["l0"] == pytest.approx(l0, rel=1e-13)


def test_torque_and_length_control_invert_rotation_and_tension_control():
    """The Gamma = 1 rod at Phi = 5 has torque 3.89224684363973 and unstressed length 0.963014577275618
    (rotation and tension controlled). Under torque control the same torque gives Phi = 5, under length
    control the same l0 gives T = 10: two other boundary value problems (a nonlinear torque condition with
    Phi unknown; an integral condition with T unknown), the same equilibrium, to 1e-8 (issue 21)."""
    eq = rodcont.solve(gamma=1.0, phi_L=5.0)
    assert eq.outputs["torque"] == pytest.approx(3.89224684363973, abs=1e-11)
    assert eq.outputs["l0"] == pytest.approx(0.963014577275618, abs=1e-13)
    by_torque = rodcont.solve(gamma=1.0, torque=3.89224684363973)
    assert abs(by_torque.outputs["phi_L"] - 5.0) < 1e-8
    by_length = rodcont.solve(l0=0.963014577275618, phi_L=5.0)
    assert abs(by_length.outputs["T"] - 10.0) < 1e-8 and by_length.outputs["gamma"] == pytest.approx(1.0)
    for other in (by_torque, by_length):
        assert np.max(np.abs(other.centreline() - eq.centreline())) < 1e-9


def test_torque_control_on_a_curved_reference_matches_rotation_control():
    """On a moving frame the torque condition reads the frame's twist: the arc's equilibrium at Phi = 2 has
    torque M; prescribing M gives Phi = 2 back."""
    eq = rodcont.solve(gamma=1.0, phi_L=2.0, curve="arc:0.6")
    back = rodcont.solve(gamma=1.0, torque=eq.outputs["torque"], curve="arc:0.6")
    assert abs(back.outputs["phi_L"] - 2.0) < 1e-8


def test_the_system_of_a_controlled_rod_keeps_its_ends_on_another_mesh():
    eq = rodcont.solve(gamma=1.0, torque=2.0)
    s = eq.system
    assert isinstance(s, RodSystem) and s.model.ends.find(Torque) == Torque(2.0)
    finer = s.with_mesh(np.linspace(0, 1, 31))
    x = finer.disc.transfer(eq.x, s.disc)
    r = finer.disc.newton(x, s.base)
    assert r.converged and finer.disc.full_params(r.x, s.base)[0] == pytest.approx(eq.outputs["phi_L"], abs=1e-9)
    assert isinstance(finer.disc, Collocation)


def test_a_torque_beyond_the_primary_maximum_is_a_clear_error():
    """Under torque control the Gamma = 1 branch folds at its torque maximum (below the Phi fold's torque):
    natural loading in the torque stops there and says where."""
    with pytest.raises(rodcont.ConvergenceError, match="loading stopped at torque"):
        rodcont.solve(gamma=1.0, torque=12.0)


def test_solve_under_torque_control_steps_in_the_rods_own_units():
    """A torque step is load_step radians of uniform twist (GJ/L each): an SI rod loads in as many steps."""
    si = RodParameters(EI=3.57e5, GJ=2.75e5, EA=3.13e8, w=115.0, L=10.0)
    a = rodcont.solve(gamma=1.0, phi_L=3.0, rod=si)
    b = rodcont.solve(gamma=1.0, torque=a.outputs["torque"], rod=si)
    assert abs(b.outputs["phi_L"] - 3.0) < 1e-8 and math.isfinite(b.error)


# --------------------------------------------------------------------------
# solve: the controls on the command line and in the API (issues 21 and 22)
# --------------------------------------------------------------------------
def _lines(out):
    return dict(line.split(" ", 1) for line in out.splitlines() if line and not line.startswith("#"))


def test_solve_prints_every_control_and_response_and_what_to_trust(capsys):
    """`name value` lines for the controls (T, gamma, phi_L, torque, l0) and the responses; the error
    estimate is printed, the defect (a residual, 0.598 beside an error of 2.6e-9) is not."""
    from conftest import run
    code, out, err = run(["solve", "--gamma", "1", "--phi", "5"], capsys)
    assert code == 0, err
    lines = _lines(out)
    for name in ("T", "gamma", "phi_L", "torque", "l0", "stretch", "helical_waves", "min_alignment",
                 "newton_iterations", "residual_norm", "N", "error"):
        assert name in lines, name
    assert "defect" not in lines
    assert float(lines["T"]) == 10.0 and float(lines["gamma"]) == 1.0 and float(lines["phi_L"]) == 5.0
    assert float(lines["torque"]) == pytest.approx(3.89224684363973, abs=1e-11)


def test_solve_under_length_and_torque_control_on_the_command_line(capsys):
    """`rodcont solve --l0 0.963014577275618 --phi 5 --w 10` gives T = 10, `rodcont solve --gamma 1 --torque
    3.89224684363973` gives phi_L = 5, both to 1e-8 (issue 21 item 5); both unknowns printed."""
    from conftest import run
    code, out, err = run(["solve", "--l0", "0.963014577275618", "--phi", "5", "--w", "10"], capsys)
    assert code == 0, err
    lines = _lines(out)
    assert abs(float(lines["T"]) - 10.0) < 1e-8 and float(lines["l0"]) == pytest.approx(0.963014577275618, abs=1e-14)
    code, out, err = run(["solve", "--gamma", "1", "--torque", "3.89224684363973"], capsys)
    assert code == 0, err
    lines = _lines(out)
    assert abs(float(lines["phi_L"]) - 5.0) < 1e-8
    for args, message in ((["--l0", "1", "--gamma", "1", "--phi", "1"], "one of --gamma, --T and --l0"),
                          (["--gamma", "1", "--phi", "1", "--torque", "1"], "--phi (the end rotation) or --torque"),
                          (["--gamma", "1"], "--phi (the end rotation) or --torque"),
                          (["--l0", "-1", "--phi", "1"], "positive")):
        code, out, err = run(["solve"] + args, capsys)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err


def test_solve_refuses_contradicting_controls_and_names_its_arguments():
    """solve(gamma=..., T=...) ignored gamma; solve(phi=...) named an internal function (issue 22)."""
    with pytest.raises(ValueError, match="not gamma and T"):
        rodcont.solve(gamma=1.0, T=10.0, phi_L=1.0)
    with pytest.raises(TypeError, match=r"unexpected keyword argument\(s\) 'phi' \(the end rotation is phi_L\)") as e:
        rodcont.solve(gamma=1.0, phi=1.0)
    assert "solve_equilibrium" not in str(e.value)
    with pytest.raises(ValueError, match="not phi_L and torque"):
        rodcont.solve(gamma=1.0, phi_L=1.0, torque=1.0)


@pytest.mark.parametrize("kwargs", [dict(rod="abc"), dict(curve=5), dict(curve="nosuch:1"), dict(wall="abc"),
                                    dict(N="x"), dict(N=2.5), dict(k="x"), dict(load_step="x"), dict(tol="x"),
                                    dict(gamma="x"), dict(phi_L="x"), dict(adapt="yes"), dict(N_max=0),
                                    dict(max_error=-1.0), dict(N=10**9)])
def test_wrong_api_arguments_are_type_or_value_errors(kwargs):
    args = dict(gamma=1.0, phi_L=1.0)
    args.update(kwargs)
    with pytest.raises((TypeError, ValueError)) as e:
        rodcont.solve(**args)
    assert not isinstance(e.value, AttributeError)


def test_the_axial_force_may_be_prescribed_at_either_end():
    """A rod hanging along its axis (weight along -K3, w = 2): F3' = w n / alpha with n = 1, alpha = 1 + F3/EA,
    so F3 + F3^2/(2 EA) = w S + C. Prescribing F.K3 = T at S = 0 instead of S = L moves the constant:
    C = T + T^2/(2 EA)."""
    rod = RodParameters(w=2.0, EA=50.0, weight_direction=(-1.0, 0.0, 0.0))
    T = 3.0
    ends = RodEnds(start=(Clamp(), Rotation(), Tension()), end=(Clamp(), Rotation()))
    model = EulerianRod(rod, ends=ends)
    disc, x, p = _solve(model, T, 0.5)
    S = np.linspace(0, 1, 11)
    F3 = disc.evaluate(x, S, 5)
    assert np.allclose(F3 + F3**2 / (2 * rod.EA), rod.w * S + T + T**2 / (2 * rod.EA), rtol=0, atol=1e-11)
    assert np.max(np.abs([disc.evaluate(x, S, i) for i in (0, 1)])) < 1e-12  # it hangs straight
