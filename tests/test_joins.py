"""Joins: breakpoints where fields are only C^0 and interface conditions hold (collocation core, rod model).

A reference curve whose curvature jumps (a minimum-curvature well) makes its stations joins: the exact
Eulerian fields Delta', Delta'', phi' jump there. Evidence: a two-material bar solved exactly by the core;
the assembled Jacobian (interface rows included) against differences of the residual; and the physical
rod on an S-shaped well path against the same rod on the straight reference (it must not depend on the
reference curve).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rodcont.collocation import BVProblem, Collocation
from rodcont.curves import MinimumCurvatureWell
from rodcont.rod import EulerianRod, RodParameters
from test_curves import PAPER, assert_fold_as_on_the_straight_reference, centreline_distance


# --------------------------------------------------------------------------
# The collocation core: a two-material bar
# --------------------------------------------------------------------------
def bar_problem(joins=(1.0,)):
    """``(a u')' = -1`` on ``[0, 2]``, ``a = 1`` left of 1, ``a = p0`` right of it, ``u(0) = u(2) = 0``: at the
    join ``u`` is C^0 and the flux is continuous, ``u'(1-) = p1 u'(1+)``, with ``p1`` a free parameter fixed
    by the boundary condition ``p1 = p0`` (so the interface rows read a free parameter)."""
    def residual(S, z, p):
        a = np.where(S < 1.0, 1.0, p[0])
        return (a * z[2] + 1.0)[None]

    def bc(za, zb, p):
        return np.stack([za[0], zb[0], p[1] - p[0] + 0 * za[0]])

    def interface(zl, zr, p, S):
        return (zl[1] - p[1] * zr[1])[None]

    return BVProblem(orders=(2,), residual=residual, bc=bc, interval=(0.0, 2.0), params=("a", "ratio"), free=(1,),
                     joins=joins, join_continuity=(0,) if joins else None, interface=interface if joins else None)


def bar_exact(S, a):
    """Flux ``a u' = C - S``, ``C = (a + 3) / (2 (a + 1))`` from ``u(2) = 0`` and continuity at 1."""
    C = (a + 3) / (2 * (a + 1))
    D = (C - 0.5) * (1 - 1 / a)
    return np.where(S < 1.0, C * S - S**2 / 2, (C * S - S**2 / 2) / a + D)


def dense_fd_jacobian(f, x, h=1e-6):
    """Central differences of ``f`` at ``x``, column by column."""
    cols = []
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=1)


def test_a_join_gives_the_kinked_solution_exactly():
    """Piecewise quadratic with a kink at the join: reproduced to rounding by C^0 joins (one interface row,
    one more unknown), on either side of the join and after transfer to a finer mesh; the C^1 space
    without the join misses it by O(h)."""
    a = 3.0
    p = np.array([a, 0.0])
    b = np.array([0.0, 0.3, 1.0, 1.4, 2.0])
    disc = Collocation(bar_problem(), b, k=3)
    plain = Collocation(bar_problem(joins=()), b, k=3)
    assert disc.size == plain.size + 1 and disc.n_interface == 1 and disc.n_bc == plain.n_bc == 3
    r = disc.newton(np.zeros(disc.size), p)
    assert r.converged
    S = np.linspace(0, 2, 201)
    assert np.max(np.abs(disc.evaluate(r.x, S, 0) - bar_exact(S, a))) < 1e-13
    assert r.x[disc.free_index[0]] == pytest.approx(a, abs=1e-13)
    # one-sided jets at the join (a point on a join belongs to the right subinterval)
    C = (a + 3) / (2 * (a + 1))
    left = (disc.jet_matrix(np.array([1.0]), interval=np.array([1])) @ r.x)
    right = (disc.jet_matrix(np.array([1.0])) @ r.x)
    assert left[1] == pytest.approx(C - 1, abs=1e-13) and right[1] == pytest.approx((C - 1) / a, abs=1e-13)
    assert left[0] == pytest.approx(right[0], abs=1e-14) and disc.evaluate(r.x, 1.0, 0, 1) == right[1]
    # transfer to a finer mesh with the same join: exact (the solution lies in both spaces)
    fine = Collocation(bar_problem(), np.union1d(b, [0.7, 1.2, 1.7]), k=4)
    xf = fine.transfer(r.x, disc)
    assert np.max(np.abs(fine.evaluate(xf, S, 0) - bar_exact(S, a))) < 1e-13
    assert np.max(np.abs(fine.residual(xf, p))) < 1e-12
    rp = plain.newton(np.zeros(plain.size), p)
    assert rp.converged and np.max(np.abs(plain.evaluate(rp.x, S, 0) - bar_exact(S, a))) > 1e-3


def test_a_join_must_be_a_breakpoint():
    with pytest.raises(ValueError, match="join must be an interior breakpoint"):
        Collocation(bar_problem(), np.array([0.0, 0.5, 1.5, 2.0]), k=3)
    with pytest.raises(ValueError, match="interface function"):
        Collocation(dataclasses.replace(bar_problem(), interface=None), np.array([0.0, 1.0, 2.0]), k=3)


def test_bar_jacobian_with_a_join_equals_differences():
    """Rows of the collocation, the boundary and the interface, the free parameter's column and a
    parameter derivative: against central differences."""
    disc = Collocation(bar_problem(), np.array([0.0, 0.4, 1.0, 2.0]), k=3)
    rng = np.random.default_rng(1)
    x, p = rng.normal(size=disc.size), np.array([2.5, 0.0])
    F, J, (Fa,) = disc.linearise(x, p, [0])
    assert np.allclose(F, disc.residual(x, p), atol=1e-14)
    assert np.max(np.abs(J.toarray() - dense_fd_jacobian(lambda y: disc.residual(y, p), x))) < 1e-7
    pa = lambda v: disc.residual(x, np.array([v, 0.0]))  # noqa: E731
    assert np.max(np.abs(Fa - (pa(2.5 + 1e-6) - pa(2.5 - 1e-6)) / 2e-6)) < 1e-7


# --------------------------------------------------------------------------
# The rod on a well path
# --------------------------------------------------------------------------
def s_well(span: float | None = 1.0):
    """A vertical S through the straight span: leaves it 10 degrees down, crosses it 10 degrees up, returns
    to it along e1 (inclination 90, azimuth 90: east): curvature 0.69 down, up, down on its three arcs
    (jumps of 1.4 at both interior stations). The end point lies on the e1 axis, so with MD
    scaled to ``span`` it has the straight span's ends and end tangents."""
    st = np.array([[0, 90, 90], [0.25, 80, 90], [0.75, 100, 90], [1.0, 90, 90]], float)
    if span is not None:
        st[:, 0] *= span / MinimumCurvatureWell(st).span
    return MinimumCurvatureWell(st)


def test_rod_jacobian_with_joins_equals_the_complex_step():
    """The assembled Jacobian of the rod on the S-well (5 interface rows at each of its 2 stations) equals
    the complex step of the whole residual, column by column; dF/dEA central differences."""
    well = s_well()
    model = EulerianRod(RodParameters(L=well.span), well)
    disc = model.discretise(6, k=4)
    assert disc.n_interface == 10
    rng = np.random.default_rng(7)
    x = model.initial_guess(disc, 10.0) + 1e-2 * rng.normal(size=disc.size)
    p = model.params(3.0, T=10.0)
    F, J, (FEA,) = disc.linearise(x, p, [5])
    h = 1e-30
    cs = np.stack([disc.residual(x + 1j * h * np.eye(disc.size)[j], p).imag / h for j in range(disc.size)], 1)
    Jd = J.toarray()
    assert np.max(np.abs(Jd - cs)) < 1e-12 * max(1.0, np.max(np.abs(cs)))
    iface = disc.row_order >= disc.size - disc.n_interface  # the interface rows, in the solver's order
    assert np.all(np.count_nonzero(Jd[iface], axis=1) >= 4)  # each reads both sides (one-sided jets)
    dp = 1e-5 * p[5]
    fd = (disc.residual(x, p + dp * np.eye(6)[5]) - disc.residual(x, p - dp * np.eye(6)[5])) / (2 * dp)
    assert np.max(np.abs(FEA - fd)) < 1e-7 * np.max(np.abs(FEA))


def solve_pair(N: int, phi: float, joins: bool = True, k: int = 5):
    """The Gamma = 1 rod at ``phi`` on the straight reference and on the S-well (``joins=False``: the
    well's stations as plain C^2 / C^1 breakpoints, as before joins)."""
    from test_curves import solve_at
    straight = EulerianRod(PAPER)
    well = EulerianRod(PAPER, s_well())
    ds, xs, p = solve_at(straight, phi, N, k)
    if not joins:
        bare = dataclasses.replace(well.problem, joins=(), join_continuity=None, interface=None)
        well.discretise = lambda N, k, _d=well.discretise: Collocation(bare, _d(N, k).breakpoints, k)
    dw, xw, _ = solve_at(well, phi, N, k)
    os_, ow = straight.outputs(ds, xs, p), well.outputs(dw, xw, p)
    return dict(centre=centreline_distance(straight, ds, xs, well, dw, xw),
                **{q: abs(os_[q] - ow[q]) for q in ("stretch", "torque", "l0")})


@pytest.mark.parametrize("phi", [5.0, 10.0])
def test_the_physical_rod_does_not_depend_on_a_well_reference(phi):
    """The decisive test. Heavy clamped-clamped rod (paper values, Gamma = 1) twisted by ``phi``, on the
    straight reference and on the S-well between the same ends: centreline at equal x, stretch, torque, l0
    agree to the discretisation error and converge at the spline rate (centreline like h^(k+3)). Measured
    (k = 5) at N = 8, 16, 32: centreline 2.4e-11, 1.1e-13, 4e-15 (phi = 5), 1.2e-10, 5.3e-13, 4e-14 (phi = 10);
    stretch, torque, l0 to 1e-12: below the straight rod's own discretisation error (centreline 4.5e-11,
    2.6e-13 at phi = 5). Without joins the stations' spurious moment EI |jump of k| leaves 4.0e-2,
    6.9e-2 in the centreline, 9.0e-3, 3.0e-2 in the stretch and 5e-2, 3.3e-1 in the torque on all three."""
    after = {N: solve_pair(N, phi) for N in (8, 16)}
    before = {N: solve_pair(N, phi, joins=False) for N in (8, 16)}
    assert after[8]["centre"] < 5e-10 and after[16]["centre"] < 5e-12
    assert after[16]["centre"] < after[8]["centre"] / 50
    for q in ("stretch", "torque", "l0"):
        assert after[8][q] < 1e-11 and after[16][q] < 1e-11, q
    assert before[8]["centre"] > 1e-2 and before[16]["centre"] > 0.9 * before[8]["centre"]
    assert before[8]["stretch"] > 1e-3 and before[16]["stretch"] > 0.9 * before[8]["stretch"]


def test_the_fold_on_a_well_reference_is_the_problem_fold():
    """The first fold of the Gamma = 1 branch traced on the S-well (N = 15, k = 5): PROBLEM.md's fold, and the
    straight reference's on the same mesh size: measured 1.3e-9 (Phi), 1.9e-9 (stretch, l0), 2.0e-8 (torque),
    2.1e-9 (centreline)."""
    assert_fold_as_on_the_straight_reference(EulerianRod(PAPER, s_well()))


def test_an_adaptive_trace_on_a_well_keeps_its_joins():
    """rodcont.trace on the S-well remeshes (error estimate in a richer space, equidistribution, stations
    conformed) with the joins in every mesh, and locates the problem's fold (measured 13.0999938235 on
    meshes of 16 .. 77 subintervals; the straight reference's trace gives 13.0999938230)."""
    import rodcont
    well = s_well()
    b = rodcont.trace(1.0, N=15, curve=well, p_range=(0, 16))
    assert b.remeshes >= 1 and len({np.asarray(m).size for m in b.meshes}) > 1
    assert all(np.all(np.isin(well.breakpoints, np.asarray(m))) for m in b.meshes)
    assert b.folds[0]["phi_L"] == pytest.approx(13.099993823, abs=1e-9)  # tests/lagrangian_reference.py


def test_a_rod_in_a_three_dimensional_well_satisfies_kirchhoff():
    """A non-planar well (inclination and azimuth change at both interior stations: both curvature
    components jump, the frame turns by end_twist = 0.0157), Gamma = 1, Phi = 8, clamped along the well's
    end tangents: the Kirchhoff equations integrated from S = 0 with the solution's start force and moment
    (independent code, smooth across the stations) land on the computed far end and directors. Measured
    1.0e-12, 9e-14 (position) and 4.1e-12, 5.7e-13 (directors) for N = 10, 20; without joins 0.25 and 0.86
    on every mesh."""
    from test_curves import kirchhoff_end, solve_at
    well = MinimumCurvatureWell([[0, 90, 90], [0.3, 80, 100], [0.7, 95, 75], [1.0, 90, 90]])
    assert well.curvature_jumps.size == 2
    model = EulerianRod(RodParameters(L=well.span), well)
    L = np.array([well.length])
    for N, tol in ((10, 2e-11), (20, 5e-12)):
        disc, x, p = solve_at(model, 8.0, N=N)
        o = model.outputs(disc, x, p)
        rL, DL = kirchhoff_end(model, disc, x, p, o["torque"], o["l0"])
        assert np.max(np.abs(rL - model.centreline(disc, x, L)[:, 0])) < tol
        assert np.max(np.abs(DL - model.directors(disc, x, L)[:, :, 0].T)) < tol


def test_a_trace_on_a_well_with_stations_writes_a_file_rodcont_reads_back(tmp_path, capsys):
    """The joins add 5 unknowns per station: a branch file of such a well once failed its own check
    ("coefficients do not fit its mesh") as the trace ended, so folds, export and restarts refused it."""
    import rodcont
    from conftest import run
    well = tmp_path / "kink.csv"
    well.write_text("0, 90, 0\n0.5, 95, 0\n1, 90, 0\n")
    out, again = tmp_path / "k.h5", tmp_path / "k2.h5"
    code, _, err = run(["trace", "--reference", f"well:{well}", "--gamma", "1", "--phi-max", "2", "--out", str(out),
                        "--quiet"], capsys)
    assert code == 2 and "give --L" in err  # the span is not 1
    L = err.split("give --L ")[1].split()[0]
    code, _, err = run(["trace", "--reference", f"well:{well}", "--L", L, "--gamma", "1", "--phi-max", "2",
                        "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    data = rodcont.load_branch(str(out))
    assert len(data) > 3
    code, _, err = run(["trace", "--start", f"{out}:3", "--N", "30", "--phi-max", "3", "--out", str(again),
                        "--quiet"], capsys)
    assert code == 0, err
    assert rodcont.load_branch(str(again)).point(0)["phi_L"] == pytest.approx(data.point(3)["phi_L"], abs=1e-9)


def test_stations_closer_than_a_subinterval_still_solve(tmp_path, capsys):
    """Stations 0.005 apart (a straight well: the same answer as the straight reference) and a clearance
    step over 0.002: the starting guess's least-squares fit once had too few points in the short
    subinterval, a singular normal matrix and 'residual is not finite' (found by the adversarial pass)."""
    from conftest import run
    well = tmp_path / "close.csv"
    well.write_text("0, 90, 0\n0.005, 90, 0\n1, 90, 0\n")

    def stretch(args):
        code, out, err = run(["solve", "--gamma", "1"] + args, capsys)
        assert code == 0 and "Warning" not in err, err
        return float(dict(line.split(" ", 1) for line in out.splitlines() if line and line[0] != "#")["stretch"])

    assert stretch(["--phi", "3", "--reference", f"well:{well}"]) == pytest.approx(stretch(["--phi", "3"]), abs=1e-12)
    step = tmp_path / "step.toml"
    step.write_text("[conduit]\nclearance = [[0, 0.01], [0.5, 0.01], [0.502, 0.012], [1, 0.012]]\neps = 1e-5\n")
    assert 0 < stretch(["--phi", "0", "--conduit", str(step)]) < 1e-3
