"""welleng 0.30 (PyPI, a second soft-string implementation) against rodcont's soft and stiff string on the example
build-and-hold well, and which sign the weight's normal component takes in a build, decided by the stiff string
(its wall force comes from the rod's own equilibrium, not from a cable equation)."""

import os

import numpy as np
import pytest

import softstring_reference as ss
from rodcont.curves import MinimumCurvatureWell
from rodcont.drilling import DrillString, Section, Well, soft_string, torque_and_drag

HERE = os.path.dirname(__file__)
BUILD_HOLD = os.path.join(HERE, "..", "examples", "well_build_and_hold.csv")
W, R_PIPE, MU, C = 235.0, 0.0635, 0.25, 0.05    # the README's drill pipe (tests/test_friction.py)
OPS = ("pick-up", "slack-off", "rotate")


@pytest.fixture(scope="module")
def example():
    stations = MinimumCurvatureWell.from_file(BUILD_HOLD).stations
    well = Well(stations, hole_diameter=2 * (R_PIPE + C), friction=MU)
    string = DrillString((Section("5in drill pipe", None, 1.25e6, 9.6e5, 7.15e8, W, R_PIPE),))
    return stations, well, string


@pytest.fixture(scope="module")
def rotating(example):
    _, well, string = example
    return torque_and_drag(well, string, 1000.0, "rotate")


def test_welleng_against_rodcont_soft_and_stiff_string(example, rotating):
    """welleng resampled every metre: its rotating hook load (no axial friction) equals rodcont's soft string and
    stiff string (to 2e-4: welleng's first-order steps); its drags and rotating torque are larger than rodcont's
    soft string's by what the sign of the weight's normal component makes (welleng equals the reference with its
    sign, rodcont's soft string the reference with the cable equation's, each to 1e-3)."""
    pytest.importorskip("welleng")
    stations, well, string = example
    md, inc, azi = stations.T
    wl = ss.welleng_model(md, inc, azi, 1000.0, [(None, W, 2 * R_PIPE)], MU, spacing=1.0)
    hook = dict(zip(OPS, (wl.tension[k][0] for k in ("pickup", "slackoff", "rotating"))))
    soft = {op: soft_string(well, string, 1000.0, op) for op in OPS}
    assert hook["rotate"] == pytest.approx(soft["rotate"][0], rel=2e-4)
    assert hook["rotate"] == pytest.approx(rotating.hook_load, rel=2e-4)
    sv, sec = ss.Survey(md, inc, azi), [ss.Section(None, W, R_PIPE)]
    for sign, model in ((-1.0, "welleng"), (1.0, "rodcont")):
        ref = {name: ss.soft_string(sv, sec, 1000.0, op, MU, step=1.0, weight_normal_sign=sign)
               for name, op in zip(OPS, (ss.pick_up(), ss.slack_off(), ss.rotating()))}
        got = (hook, wl.torque["rotating"][0]) if model == "welleng" else ({op: soft[op][0] for op in OPS},
                                                                           soft["rotate"][1])
        for op in ("pick-up", "slack-off"):
            drag = got[0][op] - got[0]["rotate"]
            assert drag == pytest.approx(ref[op].hook_load - ref["rotate"].hook_load, rel=1e-3), (model, op)
        assert got[1] == pytest.approx(ref["rotate"].surface_torque, rel=1e-3), model
    assert wl.torque["rotating"][0] > 1.35 * soft["rotate"][1]    # 1982 against 1410 N m


def test_the_stiff_strings_wall_force_in_the_build_subtracts_the_weight(rotating):
    """In the build (MD 330-540: continuous contact on the high side, tension F, curvature kappa = dI/ds, the
    well planar there) the stiff string's wall force per length p is |F kappa - w sin I| (the cable equation:
    tension pulls up to the high side, weight down to the low side), to 2e-3; welleng's |F kappa + w sin I| is
    larger there by 2 w sin I (10-40 % of p)."""
    P = rotating.profile
    S = P["S"]
    keep = (S > 350) & (S < 520)
    jet = rotating.placed.curve.jet(S[keep])
    kappa = np.hypot(jet.k[0, 0], jet.k[1, 0])
    sin_i = np.hypot(jet.K[2][0], jet.K[2][1])
    F, p = P["axial_force"][keep], P["pressure"][keep]
    cable, plus = np.abs(F * kappa - W * sin_i), F * kappa + W * sin_i
    assert np.max(np.abs(p - cable) / cable) < 2e-3
    assert np.min((plus - p) / p) > 0.1


def test_side_force_per_joint_in_the_build_is_the_cable_equations_integral(rotating):
    """Side force per joint (9.14 m, counted from the bit up): on each joint inside the build (MD 350-520,
    continuous contact) it is the integral over the joint of |F kappa - w sin I| (the soft string's wall force per
    length with the stiff string's own axial force F), by the trapezoid rule on 2001 points per joint, to 1e-3
    (measured 2.6e-4 on 18 joints); the joints tile the string from the rig (a short top joint) to the bit; their
    sum is the integral of the pressure over the string (the trapezoid rule on 256 points per mesh interval) to
    1e-6 (measured 1e-10)."""
    from rodcont.drilling import joint_side_forces
    from rodcont.ends import axial_force_and_torque
    j = joint_side_forces(rotating)
    top, bottom = j["top"], j["bottom"]
    assert top[0] == 0.0 and bottom[-1] == 1000.0 and np.all(top[1:] == bottom[:-1])
    assert np.allclose(bottom[1:] - top[1:], 9.14, rtol=0, atol=1e-9) and 0 < bottom[0] <= 9.14
    sysm, x, p = rotating.system, rotating.x, rotating.params
    inside = np.flatnonzero((top > 350) & (bottom < 520))
    assert inside.size >= 15
    for i in inside:
        S = np.linspace(top[i], bottom[i], 2001)
        F = axial_force_and_torque(sysm.model, sysm.disc, x, p, S)[0]
        jet = rotating.placed.curve.jet(S)
        cable = np.abs(F * np.hypot(jet.k[0, 0], jet.k[1, 0]) - W * np.hypot(jet.K[2][0], jet.K[2][1]))
        assert j["side_force"][i] == pytest.approx(np.trapezoid(cable, S), rel=1e-3), (top[i], bottom[i])
    whole = sysm.model.contact(sysm.disc, x, p, per_interval=256)["side_force"]
    assert j["side_force"].sum() == pytest.approx(whole, rel=1e-6)
