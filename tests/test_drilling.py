"""The drill string in the well (rodcont.drilling): string and well files, the bit at a depth, sections as joins,
each against something independent (DRILLING.md's table, the soft-string reference's well path, the hanging
string's closed form)."""

import math
import os

import numpy as np
import pytest

import softstring_reference as ss
from rodcont.drilling import DrillingError, DrillString, Section, SteppedWall, Well, place_string, torque_and_drag

HERE = os.path.dirname(__file__)
EXAMPLES = os.path.join(HERE, "..", "examples")


def test_string_file_and_buoyancy_against_drilling_md():
    """examples/drill_string.toml: three sections from the bit up, buoyancy factor 1 - 1200/7850 = 0.8471; a
    section given by OD/ID alone gets E I, G 2I, E A and rho g A (5" drill pipe body: EI 1.23e6, DRILLING.md)."""
    s = DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    assert [x.length for x in s.sections] == [200.0, 150.0, None]
    assert s.buoyancy_factor == pytest.approx(ss.buoyancy_factor(1200.0), rel=1e-15)
    from rodcont.drilling import STEEL, _section
    body = _section({"od": 0.127, "id": 0.1086}, STEEL, "t")
    assert body.EI == pytest.approx(1.23e6, rel=5e-3)
    assert body.w_air == pytest.approx(262.0, rel=0.02)
    assert body.radius == 0.0635
    with pytest.raises(DrillingError, match="needs od"):
        _section({"length": 10.0, "EI": 1.0}, STEEL, "t")


def test_bit_depth_cuts_the_survey_on_its_arc():
    """The well path to a bit between stations is the survey's own arc: its end equals the reference's
    minimum-curvature position at that MD (independent code, axes converted) to 1e-9 m."""
    well = Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    sv = ss.Survey.from_csv(os.path.join(EXAMPLES, "well_s3d.csv"))
    for depth in (1234.5, 2650.0, 3500.0):
        c = well.curve(depth)
        assert c.length == pytest.approx(depth, abs=1e-9)
        end = c.jet(np.array([c.length])).R[:, 0]
        assert end == pytest.approx(ss.to_rodcont_axes(sv.position(depth))[0], abs=1e-9)
    with pytest.raises(DrillingError, match="outside the survey"):
        well.curve(4000.0)


def test_clearance_steps_at_the_section_boundaries():
    well = Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    placed = place_string(well, DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml")), 1000.0)
    assert placed.sections.boundaries.tolist() == [650.0, 800.0]
    wall = SteppedWall(placed.clearance)
    c = wall.clearance_at(np.array([10.0, 700.0, 799.999, 800.0, 999.0]))
    assert c == pytest.approx([0.04445, 0.04445, 0.04445, 0.00635, 0.00635], abs=1e-12)


def test_hanging_string_of_two_sections_is_the_closed_form():
    """A vertical hole, frictionless, off bottom: the string hangs on the axis and F' = -w/(1 + F/EA) in each
    section (weight per unstressed length), so F + F^2/(2 EA_i) changes by w_i times its length: the hook
    load from the bit's 0 up through the collar and the pipe, to 1e-9."""
    well = Well(np.array([[0.0, 0.0, 0.0], [500.0, 0.0, 0.0]]), hole_diameter=0.25, friction=0.0)
    collar = Section("collar", 100.0, 1.7e7, 1.3e7, 5.9e7, 2000.0, 0.1)
    pipe = Section("pipe", None, 1.2e6, 9.5e5, 7.0e6, 280.0, 0.0635)
    r = torque_and_drag(well, DrillString((collar, pipe)), 500.0, "static")

    def up(F0, w, EA, length):  # F + F^2/(2 EA) = F0 + F0^2/(2 EA) + w length
        k = F0 + F0 * F0 / (2 * EA) + w * length
        return EA * (math.sqrt(1 + 2 * k / EA) - 1)
    want = up(up(0.0, 2000.0, 5.9e7, 100.0), 280.0, 7.0e6, 400.0)
    assert r.hook_load == pytest.approx(want, rel=1e-9)
    assert max(abs(r.profile["gap"] - r.system.model.wall.clearance_at(r.profile["S"]))) < 1e-9


def test_the_depth_is_the_stretched_strings(tmp_path):
    """In a vertical hole the hook load is the buoyed weight of the unstressed string, which fills the stretched
    MD: 300 m of sections carry w (L - stretch), the stretch of each its own F/EA integrated over it (first order:
    F the weight below; the README's 24 N, 5.7e-5 below the weight of 300 m of pipe)."""
    (tmp_path / "v.csv").write_text("0,0,0\n1000,0,0\n")
    (tmp_path / "v.toml").write_text('[well]\nsurvey = "v.csv"\n')
    well = Well.from_toml(str(tmp_path / "v.toml"))
    string = DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    td = torque_and_drag(well, string, 300.0, "static")
    spans = string.spans(300.0)            # (top, bottom, section) from the rig down
    w = [s.w_air * string.buoyancy_factor for _, _, s in spans]
    below = np.cumsum([wi * (b - a) for wi, (a, b, _) in zip(w[::-1], spans[::-1])])[::-1]   # weight below each top
    stretch = [((below[i] - wi * (b - a)) * (b - a) + wi * (b - a) ** 2 / 2) / s.EA
               for i, (wi, (a, b, s)) in enumerate(zip(w, spans))]
    weight = sum(wi * (b - a) for wi, (a, b, _) in zip(w, spans))
    expected = weight - sum(wi * e for wi, e in zip(w, stretch))
    assert abs(td.hook_load - expected) < 0.02 * (weight - expected)     # the first-order stretch to 2 %
    assert round(weight - td.hook_load) == 24 and round((weight - td.hook_load) / weight, 6) == 5.7e-5


def test_a_survey_must_start_at_the_rig_and_a_string_names_its_buoyancy_once(tmp_path):
    (tmp_path / "s.csv").write_text("100,0,0\n1000,0,0\n")
    (tmp_path / "w.toml").write_text('[well]\nsurvey = "s.csv"\n')
    with pytest.raises(DrillingError, match=r"starts at MD 100 m: a well's survey starts at the rig, MD 0"):
        Well.from_toml(str(tmp_path / "w.toml"))
    text = open(os.path.join(EXAMPLES, "drill_string.toml")).read()
    both = text.replace("mud_density = 1200.0", "mud_density = 1200.0\nbuoyancy_factor = 0.9")
    (tmp_path / "d.toml").write_text(both)
    with pytest.raises(DrillingError, match="mud_density or buoyancy_factor in \\[string\\], not both"):
        DrillString.from_toml(str(tmp_path / "d.toml"))
