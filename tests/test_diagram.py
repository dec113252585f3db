"""Whole response diagrams (issue 8), against things independent of the code under test.

* critical twists against the closed-form condition of the clamped twisted rod
  under tension (tests/closed_forms.py, derived separately);
* primary and secondary folds against the independent Lagrangian shooting code
  (tests/lagrangian_reference.py; its numbers in tests/data/lagrangian_folds.json);
* the convergence of a secondary fold under mesh refinement;
* deflation on a problem whose solutions are known in closed form.
"""

from __future__ import annotations

import json
import math
import os
import sys

import numpy as np
import pytest

import rodcont
from conftest import run
from rodcont.drivers.diagram import critical_twists, deflate

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from closed_forms import critical_twists as closed_form_twists  # noqa: E402

with open(os.path.join(HERE, "data", "lagrangian_folds.json")) as fh:
    REF = json.load(fh)
PRIMARY = {r["gamma"]: r for r in REF["primary_folds"]}
SECONDARY = {(r["gamma"], r["n"]): r for r in REF["secondary_folds"]}


@pytest.mark.parametrize("T", [0.0, 10.0, 20.0, 100.0, -20.0])
def test_critical_twists_match_the_closed_form(T):
    mine = critical_twists(rodcont.RodParameters(), T, phi_max=50.0)
    ref = closed_form_twists(T, phi_max=50.0)
    assert len(mine) == len(ref) >= 4
    np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-8)


def test_critical_command(capsys):
    code, out, err = run(["critical", "--gamma", "1"], capsys)
    assert code == 0, err
    rows = [ln.split() for ln in out.splitlines() if ln.strip() and ln.split()[0].isdigit()]
    assert [float(r[1]) for r in rows] == pytest.approx([13.83443036, 21.69758836, 29.85840987, 38.1162236],
                                                        abs=1e-8)


@pytest.mark.parametrize("gamma", [2.0, 5.0])
def test_plain_trace_finds_the_first_fold(gamma):
    """The default (adaptive) trace reaches the Gamma = 2 and 5 folds that a fixed N = 15 mesh cannot."""
    br = rodcont.trace(gamma, stretch_max=0.6)
    f, r = br.folds[0], PRIMARY[gamma]
    for name in ("phi_L", "stretch", "torque", "l0"):
        assert f[name] == pytest.approx(r[name], abs=1e-7), name


def _seed(gamma, n):
    crit = closed_form_twists(gamma * 10.0, phi_max=60.0)
    return 0.5 * (crit[n - 1] + crit[n])


@pytest.mark.parametrize("gamma,n", [(1.0, 1), (1.0, 2), (1.0, 3), (2.0, 1), (2.0, 2), (0.5, 1)])
def test_secondary_folds_match_the_lagrangian_reference(gamma, n):
    """From the straight twisted state between critical twists n and n+1, up to the fold: one more wave."""
    r = SECONDARY[(gamma, n)]
    br = rodcont.trace(gamma, from_straight=_seed(gamma, n), stretch_max=r["stretch"] + 0.05, phi_max=50.0)
    f = br.folds[0]
    for name in ("phi_L", "stretch", "torque", "l0"):
        assert f[name] == pytest.approx(r[name], abs=1e-6), name
    assert f["waves_after"] == n + 1 and f["waves_before"] == n


def test_secondary_fold_converges_under_mesh_refinement():
    """Gamma = 1, n = 1 on fixed uniform meshes: the fold's Phi error falls at a high order (O(h^2k))."""
    r = SECONDARY[(1.0, 1)]
    errs = []
    for N in (6, 8, 12):
        br = rodcont.trace(1.0, N=N, adapt=False, max_error=1.0, from_straight=_seed(1.0, 1),
                           stretch_max=r["stretch"] + 0.05)
        errs.append(abs(br.folds[0]["phi_L"] - r["phi_L"]))
    orders = [math.log(errs[i] / errs[i + 1]) / math.log(N2 / N1)
              for i, (N1, N2) in enumerate(zip((6, 8), (8, 12)))]
    print("fold Phi errors N = 6, 8, 12:", errs, "orders:", orders)
    assert errs[0] > errs[1] > errs[2]
    assert min(orders) > 6


@pytest.fixture(scope="module")
def diagram_g1(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("dg") / "d1.h5")
    dg = rodcont.diagram(1.0, out=path)
    return dg, path


def test_diagram_has_every_wave_adding_fold_once(diagram_g1):
    dg, path = diagram_g1
    folds = dg.folds
    ref = [PRIMARY[1.0]] + [SECONDARY[(1.0, n)] for n in (1, 2, 3)]
    # five branches: the fifth from the interval of critical twists that straddles phi_max = 40 (38.12 to
    # 46.42), seeded at 39.06, folds beyond the window
    assert len(folds) == 4 and len(dg.branches) == 5 and not dg.branches[4].branch.folds
    assert dg.branches[4].seed_phi == pytest.approx(0.5 * (dg.critical[-1] + 40.0), abs=1e-9)
    for f, r in zip(folds, ref):
        assert f["phi_L"] == pytest.approx(r["phi_L"], abs=1e-6)
        assert f["waves_after"] == f["waves_before"] + 1
    assert [f["waves_after"] for f in folds] == [1, 2, 3, 4]
    assert sorted(f["branch"] for f in folds) == [0, 1, 2, 3]  # one fold per branch: no branch twice
    # every branch ends where the Eulerian description does, or at a bound
    for db in dg.branches:
        for end in db.ends[1:]:
            assert end.startswith("validity guard") or "bound" in end, end


def test_diagram_file_layout_and_readers(diagram_g1, tmp_path, capsys):
    dg, path = diagram_g1
    d = rodcont.load_diagram(path)
    assert d.attrs["kind"] == "diagram" and len(d.branches) == 5
    np.testing.assert_allclose(d.folds["phi_L"], [f["phi_L"] for f in dg.folds])
    assert [(b.status_first, b.status) for b in d.branches] == [db.statuses for db in dg.branches]
    for name in ("branch", "phi_L", "stretch", "torque", "l0", "waves_before", "waves_after", "index"):
        assert name in d.folds
    b1 = rodcont.load_branch(path, 1)
    assert b1.group_attrs["stop_reason_first"] and b1.group_attrs["stop_reason"]
    assert len(b1.folds["index"]) == 1
    code, out, err = run(["folds", path], capsys)
    assert code == 0 and out.count("+1 wave") == 4
    # a restart from a point of one branch of the diagram
    out_path = str(tmp_path / "r.h5")
    code, out, err = run(["trace", "--start", f"{path}:2:F1", "--max-steps", "3", "--out", out_path, "--quiet"],
                         capsys)
    assert code == 0, err
    assert rodcont.load_branch(out_path).branch["phi_L"][0] == pytest.approx(SECONDARY[(1.0, 2)]["phi_L"], abs=1e-6)
    code, out, err = run(["plot", path, "-o", str(tmp_path / "d.png")], capsys)
    assert code == 0
    import matplotlib.image as mpimg  # the command's picture is the figure tested in test_plots.py: same size
    img = mpimg.imread(str(tmp_path / "d.png"))
    assert img.shape[:2] == (754, 1066) and np.ptp(img[:, :, :3]) > 0.5


def test_a_seed_on_a_known_branch_is_not_traced_again():
    """Two seeds in one interval of critical twists lie on one branch: it is kept once."""
    from rodcont.drivers.diagram import Diagram, DiagramBranch, _on_known_branch
    from rodcont.drivers.trace import straight_seed
    rod = rodcont.RodParameters()
    T = rod.tension(1.0)
    br = rodcont.trace(1.0, from_straight=17.0, phi_max=25.0, forced=(18.5,), stretch_max=0.1)
    dg = Diagram(1.0, T, rod, [], [DiagramBranch(br, "seed at 17")])
    sysw, x = straight_seed(rod, T, 18.5)
    system = rodcont.RodSystem(rod, T=T, breakpoints=sysw.disc.breakpoints)
    assert _on_known_branch(dg, system, x, 18.5) == 0
    sysw, x = straight_seed(rod, T, 25.0)  # the next interval: another branch
    system = rodcont.RodSystem(rod, T=T, breakpoints=sysw.disc.breakpoints)
    assert _on_known_branch(dg, system, x, 18.5) is None


def test_deflation_finds_the_other_solutions_of_bratu():
    """u'' + lam e^u = 0, u(0) = u(1) = 0 has two solutions for lam < 3.5138: from one, deflation finds the other."""
    from rodcont.collocation import BVProblem, Collocation

    class Bratu:
        param = "lam"

        def __init__(self):
            pb = BVProblem([2], lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                           lambda za, zb, p: np.stack([za[0], zb[0]]), (0.0, 1.0), params=["lam"])
            self.disc = Collocation(pb, 10, 5)
            self.base = np.array([2.0])

        def params(self, value):
            return np.array([value])

    b = Bratu()
    lower = b.disc.newton(np.zeros(b.disc.size), b.params(2.0)).x
    found = deflate(b, 2.0, [lower], [np.zeros(b.disc.size), lower])
    assert len(found) == 1
    # the upper solution, theta = sqrt(2 lam) cosh(theta/4) (the larger root)
    from scipy.optimize import brentq
    th = brentq(lambda t: t - math.sqrt(2 * 2.0) * math.cosh(t / 4), 4.0, 20.0)
    umid = 2 * math.log(math.cosh(th / 4))  # u = -2 log(cosh((x - 1/2) theta/2) / cosh(theta/4))
    assert float(b.disc.evaluate(found[0], 0.5, 0)) == pytest.approx(umid, abs=1e-8)


def test_sweep_of_diagrams(tmp_path, capsys):
    code, out, err = run(["sweep", "--gamma", "1", "--diagram", "--phi-max", "22", "--jobs", "1",
                          "--out", str(tmp_path / "fam"), "--quiet"], capsys)
    assert code == 0, err
    d = rodcont.load_diagram(str(tmp_path / "fam" / "diagram_1.h5"))
    # the primary branch, the one seeded between the critical twists 13.83 and 21.70, and the one seeded
    # in the interval that straddles phi_max = 22 (21.70 to 29.86)
    assert len(d.branches) == 3 and (tmp_path / "fam" / "response_diagram.png").exists()


def test_fold_curve_in_gamma_passes_through_the_lagrangian_folds(tmp_path):
    """The fold locus continued from the Gamma = 1 fold (adaptive mesh) meets the independent
    primary folds at Gamma = 0, 0.5, 2 and 5 to 1e-8 in Phi."""
    from rodcont.drivers.foldcurve import fold_curve
    path = str(tmp_path / "g1.h5")
    rodcont.trace(1.0, stretch_max=0.3, out=path)
    res = fold_curve(rodcont.load_branch(path), 0, "gamma", 0.0, 5.0, forced=(0.5, 2.0))
    at = {round(sp.value, 12): res.row_at(sp.index) for sp in res.special if sp.kind in ("bound", "forced")}
    for g in (0.0, 0.5, 2.0, 5.0):
        assert at[g]["phi_L"] == pytest.approx(PRIMARY[g]["phi_L"], abs=1e-8), g
        assert at[g]["stretch"] == pytest.approx(PRIMARY[g]["stretch"], abs=1e-7), g


def test_a_diagram_branch_says_which_folds_it_detected_but_could_not_locate(tmp_path, capsys, monkeypatch):
    """As a trace does (test_cli.py): a fold whose location fails is warned in the summary, per branch, and
    kept in the branch group's ``unlocated`` attribute, not dropped silently."""
    import json

    import h5py

    from conftest import run
    from rodcont.continuation import Tracker
    monkeypatch.setattr(Tracker, "locate", lambda self, *a, **k: None)
    out = tmp_path / "d.h5"
    code, stdout, err = run(["diagram", "--gamma", "1", "--phi-max", "14", "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    lines = [s for s in stdout.splitlines() if "warning: a fold between phi_L = " in s]
    assert lines, stdout
    with h5py.File(out, "r") as f:
        kept = [k for g in f["branches"].values() for k, a, b in json.loads(g.attrs.get("unlocated", "[]"))]
    assert kept and set(kept) == {"fold"} and len(kept) == len(lines)
