"""Issue 24: memory of the factorisations near a singular point, and the diagram's parallel run.

Counts, not clocks: the fill of every sparse LU (nonzeros of L + U against the matrix's own) along a trace
through the Gamma = 1 fold, where the Jacobian at fixed Phi is singular; the diagram traced on a process pool
against the same diagram traced one branch after the other, point for point and in its file.
"""

import collections
import sys

import h5py
import numpy as np
import pytest
import scipy.sparse.linalg as spla

import rodcont

MAX_FILL = 5.0  # issue 24: peak memory of any factorisation at most 5 times the matrix's own


def _caller(frame) -> str:
    while any(s in frame.f_code.co_filename for s in ("scipy", "linalg.py")):
        frame = frame.f_back
    return frame.f_code.co_filename.rsplit("/", 1)[-1]


def test_no_factorisation_near_the_fold_fills_more_than_five_times_its_matrix(monkeypatch):
    """Steps, fold location, error estimates and stability counts through the Gamma = 1 fold: every LU holds at
    most MAX_FILL times the nonzeros of the matrix it factorises (and each kind is seen)."""
    worst = collections.defaultdict(float)
    orig = spla.splu

    def splu(A, *args, **kwargs):
        lu = orig(A, *args, **kwargs)
        where = _caller(sys._getframe(1))
        worst[where] = max(worst[where], (lu.L.nnz + lu.U.nnz) / A.nnz)
        return lu

    monkeypatch.setattr(spla, "splu", splu)
    br = rodcont.trace(1.0, stretch_max=0.2)
    assert len(br.folds) == 1 and br.folds[0]["phi_L"] == pytest.approx(13.099993823047, abs=1e-9)
    assert {"continuation.py", "mesh.py", "stability.py"} <= set(worst), dict(worst)
    assert max(worst.values()) <= MAX_FILL, dict(worst)


def _columns(table):
    return {name: np.asarray(col) for name, col in table.items()}


def test_the_diagram_on_a_process_pool_is_the_serial_diagram(tmp_path):
    """jobs=2 (branches at once) and jobs=1 (one after the other): the same branches in the same order, the same
    tables and solutions, the same file groups and folds."""
    serial = rodcont.diagram(1.0, phi_max=22.0, jobs=1, out=str(tmp_path / "s.h5"))
    pooled = rodcont.diagram(1.0, phi_max=22.0, jobs=2, out=str(tmp_path / "p.h5"))
    assert len(serial.branches) == len(pooled.branches) == 3
    assert serial.skipped == pooled.skipped
    for a, b in zip(serial.branches, pooled.branches):
        assert (a.origin, a.ends, a.branch.status) == (b.origin, b.ends, b.branch.status)
        ca, cb = _columns(a.branch.table), _columns(b.branch.table)
        assert ca.keys() == cb.keys()
        for name in ca:
            assert np.array_equal(ca[name], cb[name]) if ca[name].dtype.kind in "fiub" else \
                list(ca[name]) == list(cb[name]), name
        assert all(np.array_equal(u, v) for u, v in zip(a.branch.coefficients, b.branch.coefficients))
    np.testing.assert_array_equal(serial.folds["phi_L"], pooled.folds["phi_L"])
    with h5py.File(tmp_path / "s.h5", "r") as fs, h5py.File(tmp_path / "p.h5", "r") as fp:
        assert sorted(fs["branches"]) == sorted(fp["branches"])
        for j in fs["branches"]:
            gs, gp = fs["branches"][j], fp["branches"][j]
            assert dict(gs.attrs) == dict(gp.attrs)
            for name in gs:
                if isinstance(gs[name], h5py.Dataset):
                    assert np.array_equal(gs[name][()], gp[name][()]), (j, name)
        np.testing.assert_array_equal(fs["folds"]["phi_L"][()], fp["folds"]["phi_L"][()])
