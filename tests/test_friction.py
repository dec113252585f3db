"""Coulomb friction on the wall (rodcont.loads.Friction) and the rig's ends (rodcont.ends), against things
independent of rodcont: the capstan's closed form, the soft-string reference (tests/softstring_reference.py,
numpy and scipy only) inside continuous-contact stretches and for the hook loads of the example well, and
central differences for the Jacobian.
"""

import math
import os

import numpy as np
import pytest

import softstring_reference as ss
from rodcont.contact import Wall
from rodcont.curves import CircularArc, MinimumCurvatureWell
from rodcont.drilling import DrillString, Section, Well, adapt, collocated_integral, settle, torque_and_drag
from rodcont.ends import hook_load, rig_ends, surface_torque
from rodcont.loads import Friction, Operation, WallContact, Weight
from rodcont.rod import RodParameters, Sections
from rodcont.system import RodSystem

HERE = os.path.dirname(__file__)
BUILD_HOLD = os.path.join(HERE, "..", "examples", "well_build_and_hold.csv")
W, R_PIPE, MU, C = 235.0, 0.0635, 0.25, 0.05   # the README's drill pipe in the example well (ss.reference_row)


def test_operation_split_is_the_velocity_vector_method():
    """s_a = V/|v|, s_r = Omega r/|v| (|v| smoothed by 1e-6 m/s): pure motions give 1, combined the ratio, rest 0."""
    assert Operation.named("pick-up").split(0.1)[0] == pytest.approx(1.0, abs=1e-12)
    assert Operation.named("slack-off").split(0.1)[0] == pytest.approx(-1.0, abs=1e-12)
    s_a, s_r = Operation.named("rotate").split(0.0635)
    assert s_a == 0.0 and s_r == pytest.approx(1.0, abs=1e-9)
    assert Operation.named("static").split(0.1) == (0.0, 0.0)
    op = Operation.named("pick-up", trip_speed=0.2, rpm=90.0)
    vr = 2 * math.pi * 90 / 60 * 0.0635
    want = ss.combined(0.2, 90).split(0.0635)           # the reference's split
    assert op.split(0.0635) == pytest.approx(want, rel=1e-10)
    assert op.split(0.0635)[0] == pytest.approx(0.2 / math.hypot(0.2, vr), rel=1e-10)
    with pytest.raises(ValueError, match="unknown operation"):
        Operation.named("tripping")


def _arc_hook_load(EI, c, op, R=10.0, beta=math.pi / 2, T=1e4, mu=MU):
    arc = CircularArc(1 / R, R * beta)
    rod = RodParameters(EI=EI, GJ=EI, EA=1e9, w=0.0, L=arc.span)
    wall = Wall(c, eps=1e-6, force_scale=T / R)
    s = RodSystem(rod, T=T, N=400, curve=arc, wall=wall, param="T", ends=rig_ends(),
                  loads=[Weight(), WallContact(wall), Friction(mu, 0.05, op)])
    s, x, err, _ = adapt(s, settle(s, s.model.initial_guess(s.disc, T)), N_max=4000)
    assert err < 1e-6
    return hook_load(s.model, s.disc, x, s.base)


def test_capstan_in_the_soft_limit():
    """A weightless string pulled round a quarter circle (R = 10) from its far end with T: F(0) = T e^{+-mu beta}
    for a cable. The stiff string leaves the wall over about sqrt(EI/T) + sqrt(2 R c) at each clamped end (it
    starts on the axis), so mu beta loses about that angle: the exponent's error stays below that estimate
    and falls with it (EI 100 -> 10, c 1e-3 -> 1e-4: the estimate falls 3.1 times, the error 0.021 -> 0.0070)."""
    R, beta, T = 10.0, math.pi / 2, 1e4
    errors = []
    for EI, c in ((1e2, 1e-3), (1e1, 1e-4)):
        lost = 2 * (math.sqrt(EI / T) + math.sqrt(2 * R * c)) / R / beta
        for op, sign in (("pick-up", 1), ("slack-off", -1)):
            H = _arc_hook_load(EI, c, op)
            ratio = math.log(H / T) / (sign * MU * beta)
            assert 0 < 1 - ratio < lost, (EI, c, op, ratio)
            errors.append(1 - ratio)
    assert max(errors[2:]) < min(errors[:2]) / 2.5


@pytest.fixture(scope="module")
def example_well():
    """The example well with the README's drill pipe (one section, no buoyancy), off bottom, mu = 0.25."""
    stations = MinimumCurvatureWell.from_file(BUILD_HOLD).stations
    well = Well(stations, hole_diameter=2 * (R_PIPE + C), friction=MU)
    string = DrillString((Section("5in drill pipe", None, 1.25e6, 9.6e5, 7.15e8, W, R_PIPE),))
    runs = {op: torque_and_drag(well, string, 1000.0, op) for op in ("pick-up", "slack-off", "rotate")}
    return ss.Survey(stations[:, 0], stations[:, 1], stations[:, 2]), runs


def test_torque_is_the_integral_of_the_friction_moment(example_well):
    """Rotating: M(0) - M(L) = int mu p r dS of the stiff string's own wall force, as the collocation equations
    carry it (the Gauss rule of the collocation points, drilling.collocated_integral) to 1e-9; and, independent
    of the mesh the guard chose (N 496 at max_error 1e-6), within 1e-5 of the torque refined to max_error 1e-8
    (N 1086), whose own trapezoids on the 16-point grid agree with it to 1e-6 (at N 496 they read the point
    contacts 2.9e-4 low, the side force's finding in test_drilling_joints). The torque at the bit is the bit
    torque (0 off bottom). The torque falls down-hole on the refined profile; on the guard's mesh the spline
    between collocation points rises up to 0.6 N m past a point contact (S 302 m), within the contact guard's 1e-3
    of the torque on the refined profile (1.0 N m). Pick-up and slack-off carry no torque."""
    _, runs = example_well
    rot = runs["rotate"]
    P = rot.profile
    carried = MU * R_PIPE * collocated_integral(rot.system, rot.x, rot.params, [0.0, rot.depth])[0]
    assert rot.surface_torque == pytest.approx(carried, rel=1e-9)
    fine = torque_and_drag(rot.well, rot.string, 1000.0, "rotate", max_error=1e-8)
    assert fine.N > rot.N
    assert rot.surface_torque == pytest.approx(fine.surface_torque, rel=1e-5)
    Pf = fine.profile
    assert fine.surface_torque == pytest.approx(np.trapezoid(MU * R_PIPE * Pf["pressure"], Pf["S"]), rel=1e-6)
    assert P["torque"][-1] == pytest.approx(0.0, abs=1e-6 * rot.surface_torque)
    assert np.all(np.diff(Pf["torque"]) <= 1e-9 * fine.surface_torque)   # falls down-hole
    off = np.abs(P["torque"] - np.interp(P["S"], Pf["S"], Pf["torque"])).max()
    assert off < 1e-3 * rot.surface_torque
    for op in ("pick-up", "slack-off"):
        assert abs(runs[op].surface_torque) < 1e-9 * rot.surface_torque


@pytest.mark.parametrize("a, b", [(330, 540), (650, 940)])
def test_continuous_contact_stretches_obey_the_soft_string_equations(example_well, a, b):
    """Inside a stretch of continuous contact (high side of the build, low side of the hold) the stiff string
    carries no shear: integrating the soft-string equations (the reference, RK4 in 1 m steps) from the stiff
    string's F and M at MD b up to MD a gives its F(a) to 1e-4 and the torque gained to 1e-4."""
    survey, runs = example_well
    for name, op in (("pick-up", ss.pick_up), ("slack-off", ss.slack_off), ("rotate", ss.rotating)):
        P = runs[name].profile
        S, F, M = P["S"], P["axial_force"], P["torque"]
        assert np.all(P["in_contact"][(S >= a) & (S <= b)])
        Fb, Mb = np.interp(b, S, F), np.interp(b, S, M)
        o = op(Fb)
        prof = ss.soft_string(survey, [ss.Section(None, W, R_PIPE)], b,
                              ss.Operation(o.trip_speed, o.omega, Fb, Mb, name), MU, step=1.0)
        assert np.interp(a, S, F) == pytest.approx(np.interp(a, prof.md, prof.axial_force), rel=1e-4), name
        if name == "rotate":
            gained = np.interp(a, prof.md, prof.torque) - Mb
            assert np.interp(a, S, M) - Mb == pytest.approx(gained, rel=1e-4)


def test_hook_loads_against_the_soft_string_reference(example_well):
    """The reference's hook loads (tests/softstring_reference.py: pick-up 243.580, slack-off 198.945,
    rotating 219.229 kN, torque 1409.6 N m). The stiff string: rotating (no axial friction) within 1.5e-4, the
    drags (pick-up and slack-off minus rotating) and the torque 2-3 % smaller: where the string crosses the
    hole (the end of the build, 12 m of free span at F = 80 kN) and near the bit (held on the axis) it does
    not touch the wall, where the soft string presses on it everywhere (README, torque and drag)."""
    survey, runs = example_well
    string = [ss.Section(None, W, R_PIPE)]
    ref = {name: ss.soft_string(survey, string, 1000.0, op, MU, step=1.0)
           for name, op in (("pick-up", ss.pick_up()), ("slack-off", ss.slack_off()), ("rotate", ss.rotating()))}
    assert ref["pick-up"].hook_load == pytest.approx(243580, abs=1)
    rot = runs["rotate"].hook_load
    assert rot == pytest.approx(ref["rotate"].hook_load, rel=1.5e-4)
    for name in ("pick-up", "slack-off"):
        drag, want = runs[name].hook_load - rot, ref[name].hook_load - ref["rotate"].hook_load
        assert 0.96 < drag / want < 0.99, name
    assert 0.97 < runs["rotate"].surface_torque / ref["rotate"].surface_torque < 0.99


def test_jacobian_with_friction_sections_and_the_rig_ends_against_differences():
    """The complex-step Jacobian of a string of two sections (EI, GJ, EA and w jump at S = 0.6) in an arc,
    with the wall, friction of combined motion varying along S, the bit on the axis and a bit torque, against
    central differences; its residual at a random state near the wall."""
    arc = CircularArc(0.8, 1.2)
    rod = RodParameters(EI=1.0, GJ=0.8, EA=300.0, w=2.0, L=arc.span)
    wall = Wall(((0.0, 0.05), (0.5, 0.05), (0.6, 0.03), (1.2, 0.03)), eps=1e-2, force_scale=3.0)
    friction = Friction([(0.0, 0.2), (0.9, 0.35)], [(0.0, 0.02), (0.6, 0.04)],
                        Operation("combined", trip_speed=0.1, rpm=30.0))
    sections = Sections([0.6], [(1, 1, 1, 1), (3.0, 2.0, 1.5, 2.5)])
    s = RodSystem(rod, T=-0.5, N=5, curve=arc, wall=wall, param="T", ends=rig_ends(0.3),
                  loads=[Weight(), WallContact(wall), friction], sections=sections)
    assert {0.6, 0.9} <= set(np.round(s.disc.breakpoints, 12))
    rng = np.random.default_rng(3)
    x = s.model.initial_guess(s.disc, -0.5)
    x = x + 0.02 * rng.standard_normal(x.size)
    disc, p, h = s.disc, s.base, 1e-5
    F, J, (Fp,) = disc.linearise(x, p, [1])
    J = J.toarray()

    def differences(f):  # fourth-order central differences: truncation ~ h^4, rounding ~ 1e-16 |f| / h
        return (8 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12 * h)
    Jfd = np.empty_like(J)
    for j in range(disc.size):
        e = np.zeros(disc.size)
        e[j] = 1.0
        Jfd[:, j] = differences(lambda t, e=e: disc.residual(x + t * e, p))
    # each row against its own size (the wall's rows reach 1e5)
    rows = np.maximum(np.abs(J).max(axis=1), 1.0)[:, None]
    assert np.all(np.abs(J - Jfd) <= 1e-9 * rows)
    e1 = np.eye(p.size)[1]
    assert np.allclose(Fp, differences(lambda t: disc.residual(x, p + t * e1)), rtol=1e-8, atol=1e-8)
    assert np.allclose(F, disc.residual(x, p), rtol=1e-13, atol=1e-13)


def test_friction_needs_a_wall_and_valid_data():
    with pytest.raises(ValueError, match="needs a conduit"):
        RodSystem(RodParameters(), T=1.0, loads=[Weight(), Friction(0.2, 0.01, "pick-up")], param="T",
                  ends=rig_ends())
    with pytest.raises(ValueError, match="non-negative"):
        Friction(-0.1, 0.01)
    with pytest.raises(ValueError, match="strictly increasing"):
        Friction([(0.0, 0.2), (0.0, 0.3)], 0.01)


def test_surface_torque_reads_the_bit_torque_through_a_frictionless_string():
    """Frictionless, rotating on bottom: the torque is constant, M(0) = the bit torque (m(L) = -M)."""
    stations = MinimumCurvatureWell.from_file(BUILD_HOLD).stations
    well = Well(stations[:3], hole_diameter=2 * (R_PIPE + C), friction=0.0)
    string = DrillString((Section("pipe", None, 1.25e6, 9.6e5, 7.15e8, W, R_PIPE),))
    r = torque_and_drag(well, string, 400.0, "drill", wob=2e4, bit_torque=3000.0)
    assert r.surface_torque == pytest.approx(3000.0, rel=1e-9)
    # F . K3(L) = -WOB on the hole's axis; the pinned bit tilts, so F . d3 there differs by the shear's part
    from rodcont.rod import Jet
    assert r.system.disc.end_jets(r.x)[1][Jet.F[2]] == pytest.approx(-2e4, rel=1e-12)
    assert r.profile["axial_force"][-1] == pytest.approx(-2e4, rel=1e-3)
    assert surface_torque(r.system.model, r.system.disc, r.x, r.system.base) == r.surface_torque
