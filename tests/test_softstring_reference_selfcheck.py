"""Self-checks of the independent soft-string reference (tests/softstring_reference.py).

Closed forms (capstan, straight hole, frictionless hook load, rotating torque, heavy string on a
circular build), a second integrator (planar form, DOP853), the order of convergence, the buckling
and lock-up estimates, and welleng 0.30 as a second implementation (skipped without welleng).
"""
import math
import os

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

import softstring_reference as ss

HERE = os.path.dirname(__file__)
S3D = "/work/shared/data/well_s3d.csv"
BUILD_HOLD = os.path.join(HERE, "..", "examples", "well_build_and_hold.csv")
OPS = ss.STANDARD_OPERATIONS


def _build_hold():
    md, inc, azi = np.loadtxt(BUILD_HOLD, delimiter=",", comments="#").T
    return md, inc, azi, ss.Survey(md, inc, azi)


def _s3d():
    if not os.path.exists(S3D):
        pytest.skip("benchmark survey not present")
    return ss.Survey.from_csv(S3D)


@pytest.mark.parametrize("stations", [([0, 1000], [0, 90], [0, 0]),              # a planar quarter turn
                                      ([0, 500, 1500], [30, 30, 60], [0, 0, 90])])  # an arc in 3D
def test_capstan(stations):
    """Weightless string around an arc of dogleg beta: F_out/F_in = exp(s_a mu beta); with combined motion
    ``dM/dphi = s_r mu r F`` gives ``M = s_r r F_in (exp(s_a mu beta) - 1)/s_a``."""
    sv = ss.Survey(*stations)
    beta, mu, r, F_in = sv.dogleg.sum(), 0.3, 0.0635, 1e5
    string = [ss.Section(None, 0.0, r)]
    bit = sv.md[-1]
    for op in (ss.pick_up(F_in), ss.slack_off(F_in)):
        p = ss.soft_string(sv, string, bit, op, mu)
        assert p.hook_load / F_in == pytest.approx(ss.capstan_ratio(op.trip_speed * mu, beta), rel=1e-10)
    p = ss.soft_string(sv, string, bit, ss.rotating(F_in), mu)
    assert p.hook_load == pytest.approx(F_in, rel=1e-14)
    assert p.surface_torque == pytest.approx(mu * r * F_in * beta, rel=1e-10)
    op = ss.combined(0.2, 90, bit_force=F_in)
    s_a, s_r = op.split(r)
    p = ss.soft_string(sv, string, bit, op, mu)
    assert p.hook_load / F_in == pytest.approx(math.exp(s_a * mu * beta), rel=1e-10)
    assert p.surface_torque == pytest.approx(s_r * r * F_in * (math.exp(s_a * mu * beta) - 1) / s_a, rel=1e-10)


def test_straight_inclined_hole():
    """F changes by w L (cos I +- mu sin I), by w L cos I rotating, with M = mu w sin(I) r L; and with
    the friction factor given by MD stations, by the sum over its intervals."""
    w, L, inc, r = 250.0, 2000.0, 60.0, 0.0635
    sv = ss.Survey([0, L], [inc, inc], [10, 10])
    string = [ss.Section(None, w, r)]
    for op, s_a in zip(OPS, (1, -1, 0)):
        p = ss.soft_string(sv, string, L, op, 0.25)
        assert p.hook_load == pytest.approx(ss.straight_hole_force_change(w, L, inc, 0.25, s_a), rel=1e-12)
        assert p.normal_force == pytest.approx(w * math.sin(math.radians(inc)), rel=1e-12)
    p = ss.soft_string(sv, string, L, ss.rotating(), 0.25)
    assert p.surface_torque == pytest.approx(ss.straight_hole_rotating_torque(w, L, inc, 0.25, r), rel=1e-12)
    cased = [(0.0, 0.15), (1200.0, 0.35)]
    p = ss.soft_string(sv, string, L, ss.pick_up(), cased)
    want = (ss.straight_hole_force_change(w, 1200, inc, 0.15, 1)
            + ss.straight_hole_force_change(w, L - 1200, inc, 0.35, 1))
    assert p.hook_load == pytest.approx(want, rel=1e-12)


def test_frictionless_hook_load_is_buoyed_vertical_projection():
    """mu = 0: F(surface) - F(bit) = sum of w_i times the TVD span of section i, for any survey (the
    reference's closed-form TVD against its Runge-Kutta quadrature of cos I)."""
    rng = np.random.default_rng(7)
    md = np.concatenate([[0.0], np.cumsum(rng.uniform(50, 400, 12))])
    random_well = ss.Survey(md, np.concatenate([[0.0], rng.uniform(0, 100, 12)]), rng.uniform(0, 360, 13))
    string = ss.benchmark_string()
    for sv in (_s3d(), random_well):
        for bit in (0.4 * sv.md[-1], sv.md[-1]):
            spans = ss.section_spans(string, bit)
            want = sum(sec.w * np.ptp(sv.tvd([top, bot])) for top, bot, sec in spans)
            for op in (ss.pick_up(-3e4), ss.slack_off(-3e4)):
                p = ss.soft_string(sv, string, bit, op, 0.0, step=2.0)   # doglegs up to 0.03 rad/m
                assert p.hook_load + 3e4 == pytest.approx(want, rel=1e-10)


def test_order_of_convergence():
    """Classical RK4 with the steps aligned with stations and section ends: order 4.  Also on a build
    where the wall force changes sign (the kink |N| = 0 located inside a step, test the sign change)."""
    sv = _s3d()
    string = ss.benchmark_string()
    cases = [(op, 0.25) for op in OPS]
    ref = np.array(ss.hook_loads(sv, string, 3500, cases, step=0.5))           # (hook load, torque) x ops
    e = np.array([np.array(ss.hook_loads(sv, string, 3500, cases, step=h)) - ref for h in (50.0, 25.0, 12.5)])
    assert np.all(e[:, 1, :2] == 0.0)                                         # no torque without rotation
    for k, col in ((0, 0), (0, 1), (0, 2), (1, 2)):                           # every hook load, the torque
        assert 15.0 < e[1, k, col] / e[2, k, col] < 17.5 and 14.0 < e[0, k, col] / e[1, k, col] < 20.0, e
    *_, bh = _build_hold()
    string = [ss.Section(None, 235.0, 0.0635)]
    op = ss.slack_off(-5e4)
    fine = ss.soft_string(bh, string, 1000, op, 0.25, step=0.5)
    i, di, _, _, _ = bh.inclination_rates(fine.md[(fine.md > 300) & (fine.md < 600)])
    q = fine.axial_force[(fine.md > 300) & (fine.md < 600)] * di - 235 * np.sin(i)
    assert q.max() > 100 and q.min() < -50          # the string crosses from the high to the low side
    hs = np.array([50.0, 25.0, 12.5, 6.25])
    e = [abs(ss.soft_string(bh, string, 1000, op, 0.25, step=h).hook_load - fine.hook_load) for h in hs]
    slope = np.polyfit(np.log(hs), np.log(e), 1)[0]
    assert 3.5 < slope < 4.5, (e, slope)


def test_planar_form_equals_vector_form_on_planar_well():
    """The build-and-hold well is planar: the 3D integrator equals the planar form |F I' - w sin I|
    solved by DOP853 (a different formulation and integrator), for every operation."""
    md, inc, _, sv = _build_hold()
    w, r = 235.0, 0.0635
    string = [ss.Section(None, w, r)]
    for op in OPS + (ss.combined(0.5, 60), ss.drilling(5e4, 3e3), ss.slack_off(-5e4)):
        p = ss.soft_string(sv, string, 1000, op, 0.25, step=5)
        hl, tq = ss.planar_soft_string(md, inc, w, r, 0.25, op)
        assert p.hook_load == pytest.approx(hl, rel=1e-9)
        assert p.surface_torque == pytest.approx(tq, rel=1e-9, abs=1e-6)


def test_normal_force_forms_agree():
    """Johancsik's form sqrt((F I' - w sin I)^2 + (F A' sin I)^2) equals |F kappa n + w_perp|."""
    sv = _s3d()
    s = np.linspace(401, 3499, 777)
    inc, dinc, dazi, t, kn = sv.inclination_rates(s)
    F = np.linspace(-2e5, 8e5, s.size)
    assert ss.normal_force_angles(F, inc, dinc, dazi, 300.0) == pytest.approx(
        ss.normal_force_vector(F, t, kn, 300.0), rel=1e-10)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_heavy_string_on_circular_build(sign):
    """A planar build of 3 deg/30 m from 20 to 60 deg under 200 kN at the bit: the closed form of the
    linear ODE (pressed to the high side), for the cable equation and for welleng's sign.  The two
    differ: in a build, the weight's normal component is subtracted from F kappa, not added."""
    R = 30 / math.radians(3)
    L = R * math.radians(40)
    sv = ss.Survey([0, L], [20, 60], [45, 45])
    w, mu, F_bit = 250.0, 0.3, 2e5
    string = [ss.Section(None, w, 0.0635)]
    for op in OPS:
        s_a, _ = op.split(0.0635)
        op = ss.Operation(op.trip_speed, op.omega, bit_force=F_bit)
        p = ss.soft_string(sv, string, L, op, mu, step=5, weight_normal_sign=sign)
        assert p.hook_load == pytest.approx(ss.build_arc_closed_form(F_bit, w, R, 20, 60, mu, s_a, sign),
                                            rel=1e-10)
        inc = np.radians(20 + 40 * p.md / L)
        assert p.normal_force == pytest.approx(p.axial_force / R - sign * w * np.sin(inc), rel=1e-12)


def test_string_sections_and_errors():
    spans = ss.section_spans(ss.benchmark_string(), 1000.0)
    assert [(t, b) for t, b, _ in spans] == [(800.0, 1000.0), (650.0, 800.0), (0.0, 650.0)]
    assert [(t, b) for t, b, _ in ss.section_spans(ss.benchmark_string(), 300.0)] == [(100.0, 300.0), (0.0, 100.0)]
    sv = _s3d()
    with pytest.raises(ValueError, match="does not reach the surface"):
        ss.soft_string(sv, [ss.Section(100, 1.0, 0.1)], 500)
    with pytest.raises(ValueError, match="outside the survey"):
        ss.soft_string(sv, ss.benchmark_string(), 3600)
    with pytest.raises(ValueError, match="increasing MD"):
        ss.Survey([0, 100, 100], [0, 1, 2], [0, 0, 0])


def test_benchmark_table():
    """The table of the module docstring is what the reference computes (to its printed digits)."""
    sv = _s3d()
    doc = ss.__doc__.split("bit MD (m)")[1].splitlines()[1:5]
    for line in doc:
        depth, *want = map(float, line.split())
        hl, tq = ss.hook_loads(sv, ss.benchmark_string(), depth, [(op, 0.25) for op in OPS])
        assert np.round(hl / 1e3, 2) == pytest.approx(want[:3], abs=1e-9)
        assert round(tq[2], 1) == pytest.approx(want[3], abs=1e-9)
        assert hl[0] > hl[2] > hl[1] and tq[0] == tq[1] == 0.0


def test_buckling_loads():
    EI, w, rc = 1.23e6, 241.4, 0.04445
    fs = ss.sinusoidal_buckling_load(EI, w, 90, rc)
    assert fs == pytest.approx(2 * math.sqrt(EI * w / rc))
    assert ss.sinusoidal_buckling_load(EI, w, 30, rc) == pytest.approx(fs * math.sqrt(0.5))
    assert ss.helical_buckling_load(EI, w, 90, rc) == pytest.approx(math.sqrt(2) * fs)
    assert ss.helical_buckling_load(EI, w, 90, rc, "wu") == pytest.approx((2 * math.sqrt(2) - 1) * fs)
    assert ss.helical_contact_force(fs, EI, rc) == pytest.approx(w)   # at F_s the helix presses like the weight


@pytest.mark.parametrize("toe", [0.0, 1e5, 4e5])
def test_lockup_length_against_quadrature(toe):
    """L_lock = int dP / (mu N(P)) from the toe force to infinity (scipy quad) equals the closed form, and
    max_transmitted_force inverts it."""
    EI, w, rc, mu = 1.23e6, 241.4, 0.04445, 0.25
    ph = ss.helical_buckling_load(EI, w, 90, rc)
    lin = max(ph - toe, 0.0) / (mu * w)
    hel = quad(lambda P: 1.0 / (mu * (w + ss.helical_contact_force(P, EI, rc))), max(toe, ph), np.inf,
               epsabs=1e-9, epsrel=1e-12)[0]
    L = ss.lockup_length(EI, w, rc, mu, toe)
    assert L == pytest.approx(lin + hel, rel=1e-9)
    assert ss.max_transmitted_force(EI, w, rc, mu, L) == pytest.approx(toe, rel=1e-9, abs=1e-3)
    assert ss.max_transmitted_force(EI, w, rc, mu, 0.9 * L) > toe


def test_max_transmitted_force_against_ode():
    """Pushing a horizontal section from the heel: the closed form against solve_ivp of the model."""
    EI, w, rc, mu = 1.23e6, 241.4, 0.04445, 0.25
    ph = ss.helical_buckling_load(EI, w, 90, rc)

    def f(x, y):
        P = y[0]
        return [-mu * (w + (ss.helical_contact_force(P, EI, rc) if P >= ph else 0.0))]
    for heel, L in ((6e5, 1500.0), (6e5, 6000.0), (1.5e5, 2000.0), (1.5e5, 20000.0)):
        def stop(x, y):
            return y[0]
        stop.terminal = True
        sol = solve_ivp(f, (0, L), [heel], method="DOP853", rtol=1e-12, atol=1e-6, events=stop, max_step=10)
        want = max(sol.y[0, -1], 0.0)
        assert ss.max_transmitted_force(EI, w, rc, mu, L, heel) == pytest.approx(want, rel=1e-7, abs=1e-3)


def test_compression_height_matches_profile():
    """Slack-off with WOB in a straight 85 deg hole: the height where the compression reaches the
    Dawson-Paslay load, from the closed form and from the integrated profile."""
    EI, w, rc, mu, inc = 1.23e6, 241.4, 0.04445, 0.3, 85.0
    fs = ss.sinusoidal_buckling_load(EI, w, inc, rc)
    h = ss.compression_height(fs, w, inc, mu, bit_force=-5e4)
    sv = ss.Survey([0, 5000], [inc, inc], [0, 0])
    p = ss.soft_string(sv, [ss.Section(None, w, 0.0635)], 5000, ss.slack_off(-5e4), mu, step=1)
    assert np.interp(5000 - h, p.md, -p.axial_force) == pytest.approx(fs, rel=1e-10)
    assert ss.compression_height(fs, w, 60.0, mu, -5e4) == math.inf


# --------------------------------------------------------------------------------------------
# welleng 0.30 as a second implementation
# --------------------------------------------------------------------------------------------
WELLENG_GRID_WARNING = "ignore:azimuths are GRID-referenced:UserWarning"


@pytest.mark.filterwarnings(WELLENG_GRID_WARNING)
def test_welleng_agrees_with_its_sign_of_the_weight():
    """On the build-and-hold well (1 km of w = 235 N/m, r = 0.0635 m, mu = 0.25), welleng resampled every
    metre equals this reference with welleng's sign (weight_normal_sign=-1) to its first-order
    discretisation, and reproduces the issue's numbers (rotating torque 1982 N m; with 100 kN at the bit
    a pick-up drag of 48 kN over rotating); the cable equation gives 1410 N m and 38 kN.  welleng's path
    equals the reference's minimum curvature to 1e-9 m."""
    pytest.importorskip("welleng")
    from welleng.survey import Survey as WSurvey
    md, inc, azi, sv = _build_hold()
    ws = WSurvey(md=md, inc=inc, azi=azi).interpolate_mds(np.arange(0, 1000.0001, 7.0))
    assert np.abs(np.stack([ws.n, ws.e, ws.tvd], 1) - sv.position(ws.md)).max() < 1e-9
    string = [ss.Section(None, 235.0, 0.0635)]
    ref = {g: [ss.soft_string(sv, string, 1000, op, 0.25, step=2, weight_normal_sign=g) for op in OPS]
           for g in (1.0, -1.0)}
    errs = []
    for spacing in (10.0, 1.0):
        td = ss.welleng_model(md, inc, azi, 1000.0, [(None, 235.0, 0.127)], 0.25, spacing=spacing)
        got = [td.tension[k][0] for k in ("pickup", "slackoff", "rotating")] + [td.torque["rotating"][0]]
        want = [p.hook_load for p in ref[-1.0]] + [ref[-1.0][2].surface_torque]
        errs.append(np.abs(np.subtract(got, want)))
    assert errs[1].max() / 219e3 < 1e-4 and abs(got[3] - want[3]) < 1.0
    assert np.all(errs[0][[0, 1, 3]] / errs[1][[0, 1, 3]] > 7)        # first order in the spacing
    assert round(got[3]) == 1982 and round(ref[1.0][2].surface_torque) == 1410
    drag = {g: ss.soft_string(sv, string, 1000, ss.pick_up(1e5), 0.25, weight_normal_sign=g).hook_load
            - ss.soft_string(sv, string, 1000, ss.rotating(1e5), 0.25).hook_load for g in (1.0, -1.0)}
    assert round(drag[-1.0] / 1e3) == 48 and round(drag[1.0] / 1e3) == 38


@pytest.mark.filterwarnings(WELLENG_GRID_WARNING)
def test_welleng_radius_order_with_several_sections():
    """With the 3-section benchmark string, welleng's hook loads match the reference (its sign) and its
    torque does only after its radius array is put in bit-to-surface order."""
    pytest.importorskip("welleng")
    sv = _s3d()
    d = np.loadtxt(S3D, delimiter=",", comments="#")
    secs = [(200, 2189.0, 0.2032), (150, 624.0, 0.127), (None, 285.0, 0.127)]
    ref = ss.soft_string(sv, ss.benchmark_string(), 2000, ss.rotating(), 0.25, weight_normal_sign=-1)
    raw = ss.welleng_model(d[:, 0], d[:, 1], d[:, 2], 2000.0, secs, 0.25, mud_sg=1.2, spacing=1.0)
    fixed = ss.welleng_model(d[:, 0], d[:, 1], d[:, 2], 2000.0, secs, 0.25, mud_sg=1.2, spacing=1.0,
                             fix_radius=True)
    assert raw.tension["rotating"][0] == pytest.approx(ref.hook_load, rel=1e-7)   # average angle, 1 m
    assert fixed.torque["rotating"][0] == pytest.approx(ref.surface_torque, rel=3e-4)
    assert raw.torque["rotating"][0] < 0.9 * ref.surface_torque
