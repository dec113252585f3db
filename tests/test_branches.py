"""Regression data: the Figure 2 family kept in branches/ (N = 30, k = 5, paper values)."""

import glob
import os

import numpy as np
import pytest

import rodcont
from rodcont.system import point_system

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FILES = sorted(glob.glob(os.path.join(ROOT, "branches", "gamma_*.h5")))

# PROBLEM.md, Gamma = 1, first fold (Lagrangian code, converged to about 1e-8)
G1_FOLD = dict(phi_L=13.0999938, stretch=0.14544795, torque=8.3135475, l0=1.1043872)


def load(gamma):
    return rodcont.load_branch(os.path.join(ROOT, "branches", f"gamma_{gamma:g}.h5"))


def test_family_is_there():
    gammas = sorted(rodcont.load_branch(f).gamma for f in FILES)
    assert {0.0, 1.0} <= set(gammas) and len(gammas) >= 4
    assert sum(os.path.getsize(f) for f in FILES) < 4e6


@pytest.mark.parametrize("path", FILES, ids=os.path.basename)
def test_stored_branch_is_consistent(path):
    """Every file: a finished trace from Phi = 0, one located fold where phi_L is maximal,
    stored points that solve the equations, outputs that match a recomputation."""
    d = rodcont.load_branch(path)
    b = d.branch
    assert d.attrs["stop_reason"] not in ("running", "interrupted")
    assert b["phi_L"][0] == 0.0 and b["kind"][0] == "start"
    folds = d.folds
    assert len(folds["index"]) >= 1
    i = int(folds["index"][0])
    assert b["kind"][i] == "fold"
    assert b["phi_L"][i] == pytest.approx(np.max(b["phi_L"][: i + 3]), abs=1e-12)  # a maximum of Phi
    assert abs(b["dphi_ds"][i]) < 1e-9
    for j in (0, i, len(d) - 1):
        sysm = point_system(d, j)
        x, ph = d.point(j)["x"], b["phi_L"][j]
        assert np.max(np.abs(sysm.residual(x, ph))) < 1e-8
        o = sysm.outputs(x, ph)
        for name in ("stretch", "torque", "l0", "min_alignment"):
            assert o[name] == pytest.approx(b[name][j], abs=1e-12)
        assert o["helical_waves"] == b["helical_waves"][j]


def test_gamma1_first_fold_matches_problem_md():
    f = load(1).folds
    for name, ref in G1_FOLD.items():
        assert f[name][0] == pytest.approx(ref, abs=1e-6), name


def test_retrace_matches_stored_folds():
    """Re-trace Gamma = 1 from Phi = 0 past the first fold: the fold agrees with the stored one to 1e-8."""
    d = load(1)
    f = d.folds
    br = rodcont.trace(d.gamma, d.rod, N=int(d.attrs["N"]), k=int(d.attrs["k"]),
                       stretch_max=float(f["stretch"][0]) + 0.05)
    assert len(br.folds) == 1
    new = br.folds[0]
    for name in ("phi_L", "stretch", "torque", "l0"):
        assert new[name] == pytest.approx(f[name][0], abs=1e-8), name


def test_folds_move_up_with_tension():
    """Across the family the first fold's Phi grows with Gamma (more tension, more twist to buckle)."""
    pts = sorted((rodcont.load_branch(p).gamma, rodcont.load_branch(p).folds["phi_L"][0]) for p in FILES)
    phis = [p for _, p in pts]
    assert all(b > a for a, b in zip(phis, phis[1:]))


def test_helical_waves_along_gamma0_branch():
    """What the Gamma = 0 branch does with its helical waves: 0 for the planar sag at Phi = 0,
    one wave as soon as the rod is twisted, and no change across the first fold
    (the paper's 'each fold adds a wave' is not what this branch shows up to the accuracy guard)."""
    d = load(0)
    b, f = d.branch, d.folds
    assert b["helical_waves"][0] == 0
    assert set(np.unique(b["helical_waves"])) <= {0, 1}
    first_one = int(np.argmax(b["helical_waves"] == 1))
    assert 0 < first_one < int(f["index"][0])
    assert f["waves_before"][0] == 1 and f["waves_after"][0] == 1
