"""What the response diagram shows, read back from the figure and from the saved pixels.

The reference for where the folds are is the independent Lagrangian shooting code
(tests/data/lagrangian_folds.json), not the branch file being drawn.
"""

import json
import os

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.colors import to_rgb

from rodcont.branchfile import load_diagram
from rodcont.plots import response_diagram

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DIAGRAM_1 = os.path.join(ROOT, "branches", "diagram_1.h5")
with open(os.path.join(ROOT, "tests", "data", "lagrangian_folds.json")) as fh:
    _REF = json.load(fh)
FOLDS_1 = sorted([(r["stretch"], r["phi_L"]) for r in _REF["primary_folds"] if r["gamma"] == 1.0]
                 + [(r["stretch"], r["phi_L"]) for r in _REF["secondary_folds"] if r["gamma"] == 1.0 and r["n"] <= 3],
                 key=lambda v: v[1])


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    d = load_diagram(DIAGRAM_1)
    png = str(tmp_path_factory.mktemp("plot") / "d.png")
    fig = response_diagram([d], png)
    return d, fig, png


def _curves(ax):
    return [ln for ln in ax.get_lines() if ln.get_marker() in ("None", "", None)]


def test_every_point_is_drawn_solid_where_stable_and_dashed_where_not(drawn):
    d, fig, _ = drawn
    ax = fig.axes[0]
    stability = {}
    for b in d.branches:
        br = b.branch
        for x, y, u in zip(br["stretch"], br["phi_L"], br["unstable_modes"]):
            stability[(float(x), float(y))] = int(u)
    seen = set()
    styles = set()
    for ln in _curves(ax):
        pts = [(float(x), float(y)) for x, y in zip(ln.get_xdata(), ln.get_ydata())]
        assert all(p in stability for p in pts), "a drawn point that is not in the file"
        # a segment ends on the first point of the next one (no gap): all but its last share its style
        modes = [stability[p] for p in pts[:-1]] or [stability[pts[0]]]
        style = ln.get_linestyle()
        styles.add(style)
        if style == "-":
            assert all(m <= 0 for m in modes)
        else:
            assert style == "--" and all(m > 0 for m in modes)
        seen.update(pts)
    assert seen == set(stability)  # every stored point, nothing else
    assert styles == {"-", "--"}  # the primary branch is stable up to its fold, the rest is not


def test_folds_are_marked_and_labelled_where_the_lagrangian_reference_has_them(drawn):
    _, fig, _ = drawn
    ax = fig.axes[0]
    marks = sorted(((float(x), float(y)) for ln in ax.get_lines() if ln.get_marker() == "o"
                    for x, y in zip(ln.get_xdata(), ln.get_ydata())), key=lambda v: v[1])
    assert len(marks) == len(FOLDS_1) == 4
    for (x, y), (xr, yr) in zip(marks, FOLDS_1):
        assert y == pytest.approx(yr, abs=1e-8) and x == pytest.approx(xr, rel=1e-7)
    labels = sorted((t.xy[1], t.get_text()) for t in ax.texts)
    assert [t for _, t in labels] == ["0→1", "1→2", "2→3", "3→4"]
    for (y, _), (_, yr) in zip(labels, FOLDS_1):
        assert y == pytest.approx(yr, abs=1e-8)
    assert ax.get_xscale() == "log"


def test_the_legend_does_not_cover_the_data(drawn):
    _, fig, _ = drawn
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    legend, frame = ax.get_legend().get_window_extent(renderer), ax.get_window_extent(renderer)
    assert legend.x0 >= frame.x1


def test_the_saved_picture_has_the_fold_markers_where_the_axes_put_them(drawn):
    _, fig, png = drawn
    ax = fig.axes[0]
    img = mpimg.imread(png)[:, :, :3]
    scale = 130 / fig.dpi  # saved at dpi 130
    colour = np.array(to_rgb(ax.get_lines()[0].get_color()))

    def window(x, y, r):
        px, py = ax.transData.transform((x, y)) * scale
        row, col = int(round(img.shape[0] - py)), int(round(px))
        return img[max(row - r, 0):row + r + 1, max(col - r, 0):col + r + 1]

    def has_colour(x, y, r=6, c=colour):
        return bool(np.any(np.abs(window(x, y, r) - c).max(axis=2) < 0.12))

    for x, y in FOLDS_1:
        # a ring of the branch's colour with a white face, over the curve that runs through it
        assert has_colour(x, y) and has_colour(x, y, r=1, c=np.ones(3))
    # and not where there is no branch (left of every branch at Phi = 30: stretch 1e-4 is outside the data)
    assert ax.get_xlim()[0] < 4e-4
    assert not has_colour(4e-4, 30.0)


def test_other_variables_on_the_axes(tmp_path):
    d = load_diagram(DIAGRAM_1)
    fig = response_diagram([d], str(tmp_path / "t.png"), x="phi_L", y="torque")
    ax = fig.axes[0]
    torque = np.concatenate([b.branch["torque"] for b in d.branches])
    drawn = np.concatenate([ln.get_ydata() for ln in _curves(ax)])
    assert set(np.round(drawn, 12)) == set(np.round(torque, 12))
    assert ax.get_xscale() == "linear" and "torque" in ax.get_ylabel()


def test_the_shape_drawn_at_the_fold_is_the_lagrangian_rod(tmp_path, monkeypatch):
    # `rodcont shape` at the primary fold: the drawn polyline, measured as a curve, has the length
    # (1 + stretch) L and the smallest alignment min d3.e1 that the independent shooting code gives there
    import rodcont.plots
    from rodcont.cli import main

    made = []
    original = rodcont.plots.shape_figure
    monkeypatch.setattr(rodcont.plots, "shape_figure", lambda *a, **k: made.append(original(*a, **k)) or made[-1])
    with pytest.raises(SystemExit) as exc:
        main(["shape", DIAGRAM_1, "--branch", "0", "--point", "F1", "-o", str(tmp_path / "s.png")])
    assert exc.value.code == 0
    ax = made[0].axes[0]
    rod = np.array(ax.get_lines()[0].get_data_3d())
    ref = next(r for r in _REF["primary_folds"] if r["gamma"] == 1.0)
    assert np.allclose(rod[:, 0], 0.0, atol=1e-12) and np.allclose(rod[:, -1], [1.0, 0.0, 0.0], atol=1e-9)
    seg = np.diff(rod, axis=1)
    length = np.sqrt((seg ** 2).sum(axis=0))
    assert length.sum() - 1.0 == pytest.approx(ref["stretch"], abs=5e-5)  # chord of 400 samples: 5e-6 short
    assert np.min(seg[0] / length) == pytest.approx(ref["min_d3_e1"], abs=5e-5)
    lims = np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()])
    assert np.allclose(np.diff(lims, axis=1), lims[0, 1] - lims[0, 0])  # equal scales: the shape is not distorted
