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


def test_the_jets_matrix_is_each_fields_spline_derivatives_at_the_collocation_points():
    """``E @ x`` (built field by field, without a dense block of bases) against each field's own spline evaluated at
    the collocation points (:meth:`SplineSpace.evaluate` on its coefficients), on a graded mesh of the rod."""
    from rodcont.rod import RodParameters
    from rodcont.system import RodSystem
    rod = RodParameters()
    s = RodSystem(rod, T=rod.tension(1.0), N=7, k=5, breakpoints=np.linspace(0.0, 1.0, 8) ** 1.5)
    d = s.disc
    x = np.random.default_rng(3).standard_normal(d.size)
    z = d.jets(x)
    for i, m in enumerate(d.problem.orders):
        for nu in range(m + 1):
            expected = d.spaces[i].evaluate(x[d.index[i]], d.S, nu)
            np.testing.assert_allclose(z[d.jet_rows[i] + nu], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_boundary_probes_kept_on_a_problem_give_the_pattern_a_fresh_problem_gets():
    """A second discretisation of one problem reuses its boundary probes: the same Jacobian pattern as a fresh copy
    of the problem gets; given another bc (one that reads the other end) the problem is probed again."""
    import dataclasses

    from rodcont.collocation import BVProblem, Collocation

    def residual(S, z, p):
        return np.stack([z[2] + p[0] * np.exp(z[0])])

    def bc_dirichlet(za, zb, p):
        return np.stack([za[0], zb[0]])

    def bc_mixed(za, zb, p):  # both conditions at the start: the pattern must follow
        return np.stack([za[0], za[1] - zb[0]])

    pb = BVProblem(orders=(2,), residual=residual, bc=bc_dirichlet, interval=(0.0, 1.0), params=("lam",))
    first, second = Collocation(pb, 6), Collocation(pb, np.linspace(0.0, 1.0, 10) ** 2)
    fresh = Collocation(dataclasses.replace(pb), np.linspace(0.0, 1.0, 10) ** 2)
    assert np.array_equal(second._bc_mask, fresh._bc_mask) and np.array_equal(second._perm, fresh._perm)
    pb.bc = bc_mixed  # the same problem object, another bc: probed again
    mixed = Collocation(pb, np.linspace(0.0, 1.0, 10) ** 2)
    copied = Collocation(dataclasses.replace(pb), np.linspace(0.0, 1.0, 10) ** 2)
    assert not np.array_equal(mixed._bc_mask, second._bc_mask) and np.array_equal(mixed._bc_mask, copied._bc_mask)
    x = np.linspace(0.1, 0.5, mixed.size)
    _, J, _ = mixed.linearise(x, np.array([1.0]))
    for j in (0, 1, mixed.size - 1):  # the columns of the two ends: the complex step of the residual (exact)
        e = np.zeros(mixed.size, complex)
        e[j] = 1e-30j
        cs = mixed.residual(x + e, np.array([1.0])).imag / 1e-30
        np.testing.assert_allclose(J[:, j].toarray().ravel(), cs, rtol=1e-12, atol=1e-12 * np.abs(cs).max())
    assert first.size != second.size
