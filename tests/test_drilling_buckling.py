"""Buckling of a compressed drill string with friction (rodcont.drilling.buckling_ratio): in a straight inclined
hole the onset of sinusoidal buckling against the soft string's closed form and Dawson and Paslay's load, and its
shift with the friction factor; the broomstick's buckling markers against the stored compression."""

import math

import numpy as np
import pytest

from rodcont.drilling import DrillString, Section, Well, buckling_ratio, torque_and_drag

# a straight hole inclined I = 80 degrees from the rig down (a slant well), 0.3 m across; a light, flexible pipe so
# that the Dawson-Paslay load is reached by 100 m of string: EI 1e4 N m^2, w 100 N/m, outer radius 0.05 m
INC, HOLE, EI, W, RADIUS = 80.0, 0.3, 1e4, 100.0, 0.05
PIPE = Section("light pipe", None, EI, 7.7e3, 1e8, W, RADIUS)
STRING = DrillString((PIPE,), 1.0)


def dawson_paslay(EI, w, inc_deg, clearance):
    """Dawson and Paslay (1984): F_s = 2 sqrt(EI w sin I / r_c), the sinusoidal buckling load of a pipe lying on the
    low side of an inclined hole of radial clearance r_c."""
    return 2.0 * math.sqrt(EI * w * math.sin(math.radians(inc_deg)) / clearance)


def slant_well(mu, depth=400.0):
    return Well(np.array([[0.0, INC, 0.0], [depth, INC, 0.0]]), hole_diameter=HOLE, friction=mu)


def _slide(well, L, mu, wob, start=None):
    """Slide drilling: on bottom (WOB), moving down, not rotating: the friction all axial, against the motion."""
    return torque_and_drag(well, STRING, L, "drill", mu=mu, wob=wob, trip_speed=-1.0, rpm=0.0, start=start)


def _onset(well, L, mu, guess):
    """The weight on bit where the string's largest buckling ratio reaches 1: solves at 0.5, 0.9 and 1.1 times
    ``guess`` (each from the previous one), the secant through the last two, a solve there: ``(wob, solve)``."""
    r = _slide(well, L, mu, 0.0)
    for f in (0.5, 0.9):
        r = _slide(well, L, mu, f * guess, start=r)
    a = r
    b = _slide(well, L, mu, 1.1 * guess, start=a)
    qa, qb = float(np.max(buckling_ratio(a))), float(np.max(buckling_ratio(b)))
    wob = a.wob + (b.wob - a.wob) * (1.0 - qa) / (qb - qa)
    return wob, _slide(well, L, mu, wob, start=b)


def test_buckling_onset_with_friction_shifts_as_the_soft_string_closed_form():
    """Slide drilling (WOB, the string moving down, friction mu against it) in the straight hole at I = 80 degrees,
    100 m of string. Soft string: F(s) = -WOB + w (cos I - mu sin I) s (s up from the bit); with mu sin I > cos I
    the compression grows towards the rig and reaches F_s (Dawson-Paslay, written above) at
    WOB* = F_s - w (mu sin I - cos I) L. The stiff string's onset (its largest buckling ratio reaching 1), for mu =
    0.4 and 0.6: the compression peaks near the rig, not at the bit (S < 10 m); its ratio there is linear in WOB
    (the secant's solve lands on 1 to 1e-3); WOB* within 2 % of F_s of the closed form (measured 0.25 % and 1.7 %:
    the string lifts off the wall near the rig's clamp and the bit, so it drags on less than L), and the shift
    between the two, w sin I (0.6 - 0.4) L, to 6 % (measured 4.6 %: the same shorter contact)."""
    c = HOLE / 2 - RADIUS
    Fs = dawson_paslay(EI, W, INC, c)
    s, co = math.sin(math.radians(INC)), math.cos(math.radians(INC))
    L = 100.0
    onsets = {}
    for mu in (0.4, 0.6):
        closed = Fs - W * (mu * s - co) * L
        wob, r = _onset(slant_well(mu), L, mu, closed)
        q = buckling_ratio(r)
        assert float(np.max(q)) == pytest.approx(1.0, abs=1e-3)
        assert r.profile["S"][int(np.argmax(q))] < 10.0
        assert abs(wob - closed) < 0.02 * Fs, (mu, wob, closed)
        onsets[mu] = wob
    shift = onsets[0.4] - onsets[0.6]
    assert shift == pytest.approx(W * s * 0.2 * L, rel=0.06)


def test_broomstick_marks_buckling_where_the_stored_compression_reaches_dawson_paslay(tmp_path):
    """A slack-off broomstick in the straight hole at I = 80 degrees (mu 0.4 and 0.6, bit at 100, 150, 200 m; off
    bottom, the compression is the friction's, largest near the rig): from the HDF5 file's ``max_compression`` the
    test's own Dawson-Paslay load gives the buckling ratio at each depth (its constant F_s: the hole is straight);
    where that ratio passes 1 (linear between the depths) is the stored ``sinusoidal_buckling`` depth (to 1e-9
    m), NaN where it does not (mu 0.4; and no helical onset, the ratio staying below sqrt(2)); the markers drawn on
    the plot are those depths, at the hook load the stored curve has there."""
    import h5py

    from rodcont.drivers.broomstick import broomstick, plot_broomstick, write_broomstick
    depths = np.array([100.0, 150.0, 200.0])
    mus = (0.4, 0.6)
    b = broomstick(slant_well(0.4), STRING, depths, mus, operations=("slack-off",), jobs=1)
    assert not b.failures, b.failures
    write_broomstick(b, str(tmp_path / "b.h5"))
    markers = plot_broomstick(b, str(tmp_path / "b.png"))
    Fs = dawson_paslay(EI, W, INC, HOLE / 2 - RADIUS)
    with h5py.File(tmp_path / "b.h5") as f:
        ratio = f["max_compression"][:, 0, :] / Fs
        stored = f["sinusoidal_buckling"][0, :]
        assert np.all(np.isnan(f["helical_buckling"][:]))
        hook = f["hook_load"][:, 0, :]
    assert ratio[-1, 0] < 1 < ratio[-1, 1] and ratio[0, 1] < 1      # mu 0.6 buckles between two depths, 0.4 not
    assert np.isnan(stored[0])
    k = int(np.flatnonzero(ratio[:, 1] >= 1)[0])
    onset = depths[k - 1] + (depths[k] - depths[k - 1]) * (1 - ratio[k - 1, 1]) / (ratio[k, 1] - ratio[k - 1, 1])
    assert stored[1] == pytest.approx(onset, abs=1e-9)
    assert len(markers) == 1
    label, op, mu, H, depth = markers[0]
    assert (label, op, mu) == ("sinusoidal_buckling", "slack-off", 0.6) and depth == stored[1]
    assert H == pytest.approx(np.interp(onset, depths, hook[:, 1]), rel=1e-12)


def test_the_stiff_strings_own_stability_count_turns_just_above_dawson_paslay():
    """Frictionless, the bit on bottom (WOB, no motion) in the straight hole at I = 80 degrees, 100 m of string: the
    compression is largest at the bit (WOB, falling by w cos I per metre up). The stiff string's own count of unstable
    modes (rodcont.stability.unstable_modes, the linearised dynamics) is 0 up to the Dawson-Paslay load at the bit
    and 1 or more at 1.12 times it: the equilibrium on the low side loses its stability between (a trace in the
    WOB, measured: the first branch point at 1.073 F_s; above F_s because the string is 100 m long, its compression
    falls upwards and its bit is held on the axis)."""
    from rodcont.stability import unstable_modes
    well = slant_well(0.0)
    Fs = dawson_paslay(EI, W, INC, HOLE / 2 - RADIUS)
    counts = {}
    r = None
    for f in (0.5, 0.9, 1.0, 1.12):
        r = torque_and_drag(well, STRING, 100.0, "drill", mu=0.0, wob=f * Fs, trip_speed=0.0, rpm=0.0, start=r)
        counts[f] = unstable_modes(r.system, r.x, float(r.params[0]))
    assert counts[0.9] == counts[1.0] == 0 and counts[1.12] >= 1, counts


def test_a_slack_off_trip_locates_the_onset_the_closed_form_shifts_by():
    """Tripping in off bottom (slack-off, no WOB) in the straight hole at I = 80 degrees: the compression is the
    friction's, w (mu sin I - cos I) per metre of string, so the soft string reaches Dawson-Paslay's F_s at the bit
    depth d* = F_s / (w (mu sin I - cos I)). The trip from 0.8 d* to 1.2 d* locates its sinusoidal_buckling event
    (the largest buckling ratio 1 to 1e-3) within 3 % of d* for mu = 0.5 and 0.6 (measured 1.8 % and 2.4 % deeper:
    the same 3.6 m in both, the string's lengths off the wall at the rig and the bit, which drag on nothing), and
    the shift of the onset between the two friction factors equals the closed form's to 1 % (measured 0.1 %)."""
    from rodcont.drivers.trip import trip
    Fs = dawson_paslay(EI, W, INC, HOLE / 2 - RADIUS)
    s, co = math.sin(math.radians(INC)), math.cos(math.radians(INC))
    found, closed = {}, {}
    for mu in (0.5, 0.6):
        closed[mu] = Fs / (W * (mu * s - co))
        t = trip(slant_well(mu), STRING, (0.8 * closed[mu], 1.2 * closed[mu]), "slack-off", points=2, mu=mu).table
        assert t["kind"] == ["start", "event:sinusoidal_buckling", "bound"], t["kind"]
        assert t["buckling_ratio"][1] == pytest.approx(1.0, abs=1e-3)
        found[mu] = t["depth"][1]
        assert found[mu] == pytest.approx(closed[mu], rel=0.03)
    assert found[0.5] - found[0.6] == pytest.approx(closed[0.5] - closed[0.6], rel=0.01)
