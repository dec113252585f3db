"""``rodcont shape`` and ``rodcont plot`` on a drill string's files (issue 23): a trip's points drawn each in its own
well path to its own bit (east, north, up), its columns against bit depth in SI units, a broomstick file redrawn
from its arrays; what they cannot draw refused in one line. What is drawn is read back from the figures and checked
against the file's columns and a minimum-curvature survey computed here."""

import math
import os

import numpy as np
import pytest

import rodcont.drivers.broomstick as broom_mod
import rodcont.plots as plots_mod
from conftest import assert_picture, run
from rodcont.branchfile import load_branch
from rodcont.contact import MAX_PENETRATION
from rodcont.drilling import DrillString, Well
from rodcont.drivers.broomstick import Broomstick, write_broomstick
from rodcont.drivers.trip import trip
from short_well import COLLAR, DEPTHS, HOLE, PIPE, STATIONS

HERE = os.path.dirname(__file__)


@pytest.fixture(scope="module")
def trip_file(tmp_path_factory):
    """Rotating off bottom at 290 and 300 m (2 depths)."""
    out = str(tmp_path_factory.mktemp("trip") / "trip.h5")
    trip(Well(STATIONS, hole_diameter=HOLE, friction=0.25), DrillString((COLLAR, PIPE), 0.847), DEPTHS, "rotate",
         points=2, out=out)
    return out


def _bit_position(md):
    """East, north, up of the hole's axis at MD ``md`` on STATIONS by the textbook minimum-curvature formulas
    (ratio factor 2/beta tan(beta/2)); ``md`` in the last (hold) stretch, where the path is straight."""
    pos = np.zeros(3)
    for (m1, i1, a1), (m2, i2, a2) in zip(STATIONS[:-1], STATIONS[1:]):
        i1, a1, i2, a2 = map(math.radians, (i1, a1, i2, a2))
        beta = math.acos(math.cos(i2 - i1) - math.sin(i1) * math.sin(i2) * (1 - math.cos(a2 - a1)))
        rf = 1.0 if beta < 1e-12 else 2 / beta * math.tan(beta / 2)
        if m2 > md:   # inside the hold: straight along the station's tangent
            t = np.array([math.sin(i1) * math.sin(a1), math.sin(i1) * math.cos(a1), -math.cos(i1)])
            return pos + (md - m1) * t
        pos = pos + 0.5 * (m2 - m1) * rf * np.array([math.sin(i1) * math.sin(a1) + math.sin(i2) * math.sin(a2),
                                  math.sin(i1) * math.cos(a1) + math.sin(i2) * math.cos(a2),
                                  -(math.cos(i1) + math.cos(i2))])
    return pos


def _capture(monkeypatch, module, name):
    """Wrap ``module.name`` so a test reads what the command drew: (args, kwargs, returned figure)."""
    seen = []
    original = getattr(module, name)

    def wrapper(*args, **kwargs):
        out = original(*args, **kwargs)
        seen.append((args, kwargs, out))
        return out
    monkeypatch.setattr(module, name, wrapper)
    return seen


def _one_line_refusal(code, out, err, *fragments):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("rodcont: error:"), (code, err)
    assert "Traceback" not in out + err
    for f in fragments:
        assert f in lines[0], lines[0]


def test_shape_draws_each_trip_point_in_its_own_well_to_its_bit(trip_file, tmp_path, capsys, monkeypatch):
    """``shape trip.h5 --point 0 --point -1``: two centrelines, each from the rig at (0, 0, 0) to its bit on the
    hole's axis at its own depth (290 and 300 m: the minimum-curvature position computed here, 1e-9 m; before, the
    first depth's 290 m curve was used for both and the command failed), labelled with its depth and the stored
    hook load; their magnified deflection from the well path never exceeds the clearance of the pipe there (hole
    radius less the pipe's, computed here) by more than the penetration guard; contact dots are points of the
    curves, present (the collar lies on the low side), and the axes say east, north, up."""
    seen = _capture(monkeypatch, plots_mod, "shape_figure")
    png = tmp_path / "s.png"
    code, out, err = run(["shape", trip_file, "--point", "0", "--point", "-1", "-o", png], capsys)
    assert code == 0, err
    assert_picture(png)
    (args, kwargs, fig), = seen
    curves, title = args[0], args[2]
    data = load_branch(trip_file)
    magnify = float(title.split("×")[1])
    assert len(curves) == 2 and "rotate" in title
    for (r, label), depth, hook in zip(curves, DEPTHS, data.branch["hook_load"]):
        assert np.allclose(r[:, 0], 0.0, atol=1e-9)
        assert np.allclose(r[:, -1], _bit_position(depth), rtol=0, atol=1e-9)
        assert f"bit at {depth:g} m" in label and f"hook load {hook / 1e3:.5g} kN" in label
        S = np.linspace(0.0, depth, r.shape[1])
        axis = np.array([_bit_position(s) if s >= 250.0 else np.full(3, np.nan) for s in S]).T
        hold = S >= 250.0   # the straight stretch, where the axis is computed here
        c = np.where(S >= depth - COLLAR.length, HOLE / 2 - COLLAR.radius, HOLE / 2 - PIPE.radius)
        dev = np.linalg.norm(r[:, hold] - axis[:, hold], axis=0) / magnify
        assert np.all(dev <= c[hold] * (1 + MAX_PENETRATION)) and dev.max() > 0.5 * c[hold].min()
    contacts = kwargs["contacts"]
    assert all(pts.size for pts in contacts)
    for pts, (r, _) in zip(contacts, curves):
        assert all(np.min(np.linalg.norm(r - p[:, None], axis=0)) == 0.0 for p in pts.T)
    assert np.allclose(kwargs["reference"][:, -1], _bit_position(300.0), atol=1e-9)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()) == ("east (m)", "north (m)", "up (m)")


def test_shape_of_a_drill_string_refuses_in_one_line(trip_file, tmp_path, capsys):
    """A point the trip does not hold, and a broomstick file (no equilibria in it): one line, exit 2, no file."""
    png = tmp_path / "s.png"
    _one_line_refusal(*run(["shape", trip_file, "--point", "7", "-o", png], capsys), "out of range")
    b = tmp_path / "b.h5"
    write_broomstick(_synthetic_broomstick(), str(b))
    _one_line_refusal(*run(["shape", b, "-o", png], capsys), "a broomstick file")
    _one_line_refusal(*run(["export", f"{b}:0", "-o", tmp_path / "e.csv"], capsys), "a broomstick file")
    assert not png.exists() and not (tmp_path / "e.csv").exists()


def test_plot_of_a_trip_draws_its_columns_against_bit_depth(trip_file, tmp_path, capsys, monkeypatch):
    """``plot trip.h5`` draws the stored hook load against the stored depth (before: Φ against depth, labelled
    stretch), labelled in SI units, the legend the operation and friction factor of the drilling record;
    ``--y surface_torque`` and ``--y max_joint_side_force`` draw those columns; a trip beside a rod's trace in
    Φ (tests/data/old_trace_g1.h5) with no --x is refused in one line (their default axes differ), no file."""
    seen = _capture(monkeypatch, plots_mod, "response_diagram")
    data = load_branch(trip_file)
    for y in (None, "surface_torque", "max_joint_side_force"):
        png = tmp_path / f"{y}.png"
        code, out, err = run(["plot", trip_file, "-o", png] + (["--y", y] if y else []), capsys)
        assert code == 0, err
        assert_picture(png)
        ax = seen[-1][2].axes[0]
        line = next(ln for ln in ax.get_lines() if len(ln.get_xdata()) > 1)
        assert np.array_equal(line.get_xdata(), data.branch["depth"])
        assert np.array_equal(line.get_ydata(), data.branch[y or "hook_load"])
        assert ax.get_xlabel() == "bit measured depth  [m]" and ax.get_ylabel().endswith("[N]" if y != "surface_torque"
                                                                                          else "[N m]")
        assert line.get_label() == "rotate, μ = 0.25"
    png = tmp_path / "mixed.png"
    _one_line_refusal(*run(["plot", trip_file, os.path.join(HERE, "data", "old_trace_g1.h5"), "-o", png], capsys),
                      "--x", "depth", "stretch")
    assert not png.exists()


def _synthetic_broomstick():
    """3 operations x 2 friction factors x 4 depths of made-up values (no solve): what the plot must redraw."""
    d = np.array([100.0, 200.0, 300.0, 400.0])
    shape = (d.size, 3, 2)
    base = d[:, None, None] * np.array([1.1, 0.9, 1.0])[None, :, None] * np.array([1.0, 1.2])[None, None, :]
    ratio = np.zeros(shape)
    ratio[:, 1, 1] = [0.2, 0.8, 1.2, 1.6]  # slack-off at mu 0.35 buckles sinusoidally at 250 m, helically at 355 m
    data = dict(hook_load=1e3 * base, soft_hook_load=1.01e3 * base, surface_torque=2.0 * base,
                soft_surface_torque=2.1 * base, side_force=base, error=np.full(shape, 1e-7), N=np.full(shape, 40.0),
                buckling_ratio=ratio, max_compression=np.zeros(shape))
    return Broomstick(d, ("pick-up", "slack-off", "rotate"), (0.15, 0.35), data)


def test_plot_of_a_broomstick_file_redraws_its_curves(tmp_path, capsys, monkeypatch):
    """``plot B.h5`` of a broomstick file (before: refused as not a branch file) draws, from the file, each
    operation and friction factor's hook load (kN) against depth with its soft string dashed, the rotating surface
    torque beside, and the buckling onsets where the stored ratio crosses 1 and sqrt(2) (250 m and 353.6 m, linear
    between the depths); --title goes on top. Another file beside it or --y: one line, exit 2, no file."""
    b = _synthetic_broomstick()
    path = tmp_path / "b.h5"
    write_broomstick(b, str(path))
    seen = _capture(monkeypatch, broom_mod, "broomstick_figure")
    png = tmp_path / "b.png"
    code, out, err = run(["plot", path, "--title", "my broomstick", "-o", png], capsys)
    assert code == 0, err
    assert_picture(png)
    (_, _, (fig, markers)), = seen
    ax, axt = fig.axes
    lines = [(tuple(ln.get_xdata()), tuple(ln.get_ydata()), ln.get_linestyle()) for ln in ax.get_lines()]
    for i in range(3):
        for j in range(2):
            assert (tuple(b.hook_load[:, i, j] / 1e3), tuple(b.depths), "-") in lines
            assert (tuple(b.soft_hook_load[:, i, j] / 1e3), tuple(b.depths), "--") in lines
    torque = [tuple(ln.get_xdata()) for ln in axt.get_lines()]
    assert torque == [tuple(b.surface_torque[:, 2, 0] / 1e3), tuple(b.soft_surface_torque[:, 2, 0] / 1e3),
                      tuple(b.surface_torque[:, 2, 1] / 1e3), tuple(b.soft_surface_torque[:, 2, 1] / 1e3)]
    onsets = {m[0]: m[4] for m in markers if m[1] == "slack-off" and m[2] == 0.35}
    assert onsets["sinusoidal_buckling"] == pytest.approx(250.0, abs=1e-9)
    assert onsets["helical_buckling"] == pytest.approx(300.0 + 100.0 * (math.sqrt(2) - 1.2) / 0.4, abs=1e-9)
    assert fig.get_suptitle() == "my broomstick"
    for extra in ([os.path.join(HERE, "data", "old_trace_g1.h5")], ["--y", "hook_load"]):
        other = tmp_path / "x.png"
        _one_line_refusal(*run(["plot", path, *extra, "-o", other], capsys), "broomstick")
        assert not other.exists()
