"""The friction loading of a compressed string (rodcont.drilling._loaded_gradually): raised under the softer law
RAMP_EPS and stiffened to the well's at the full load, it reaches the equilibrium the wall's own law reaches
raised the same way (the path it replaced: ~27 damped Newton iterations a step instead of five)."""

import os

import numpy as np
import pytest

from rodcont import drilling
from rodcont.ends import hook_load
from rodcont.loads import Operation

EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "examples")


def test_the_softer_laws_loading_reaches_the_wall_laws_equilibrium(monkeypatch):
    # the 2875 m slack-off of well_s3d, whose straight start fails, on 300 subintervals (the CLI's at N 2412)
    well = drilling.Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml"))
    placed = drilling.place_string(well, string, 2875.0)
    P = drilling.build_system(placed, None, 0.0, 0.0, well.eps, 300, 5).model.contact_scale
    solved, raised, raise_load = {}, [], drilling._raise_load
    monkeypatch.setattr(drilling, "_raise_load", lambda *a: raised.append(a[5]) or raise_load(*a))
    for ramp in (drilling.RAMP_EPS, well.eps):
        monkeypatch.setattr(drilling, "RAMP_EPS", ramp)
        s, x = drilling._loaded_gradually(placed, 0.25, Operation.named("slack-off"), 0.0, 0.0, well.eps, 300, 5, P,
                                          1e-10)
        assert s.model.wall.eps == well.eps
        solved[ramp] = (hook_load(s.model, s.disc, x, s.base), x)
    assert raised == [1e-3, well.eps]   # each path its own law, no fallback from the softer one
    (soft, xs), (own, xo) = solved.values()
    assert soft == pytest.approx(own, rel=1e-10)
    assert np.max(np.abs(xs - xo)) <= 1e-10 * np.max(np.abs(xo))
