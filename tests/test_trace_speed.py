"""Issue 24, the first trace's cost: work the error estimate need not do, checked against the outputs' own values."""

import numpy as np

import rodcont


def test_the_error_estimate_reads_lengths_and_torque_without_the_output_grids():
    """The richer twin's stretch, l0 and torque (rod.integral_outputs) are the outputs' own, to the bit, on the
    coarse and the richer mesh of a point past the Gamma = 1 fold; estimating builds no output grids there."""
    from rodcont.mesh import ErrorEstimator
    from rodcont.system import point_system

    br = rodcont.trace(1.0, stretch_max=0.2)
    i = len(br) - 1
    s = point_system(br, i)
    x, value = s.expanded(br.point(i)["x"]), float(br.table["phi_L"][i])
    est = ErrorEstimator(s)
    assert est.estimate(x, value, (np.asarray(br.tangents[i][:-1]), float(br.tangents[i][-1]))) < 1e-6
    assert getattr(est.fine.disc, "_rod_outputs", None) is None
    for system, y in ((s, x), (est.fine, est._to_fine(x))):
        p = system.params(value)
        o = system.model.outputs(system.disc, y, p)
        assert system.model.integral_outputs(system.disc, y, p) == (o["stretch"], o["l0"], o["torque"])


def test_the_papers_rod_factorises_its_bordered_matrix_without_a_row_scaled_copy(monkeypatch):
    """In the paper's units every row scale of the rod's bordered LU is 1 (RodSystem.equation_scale): no scaled copy
    of the matrix is formed at any step (0.2 ms a step), and the LU is the raw matrix's (test_units.py). A rod whose
    forces are in units of 2^20 still has its collocation rows scaled."""
    from rodcont import linalg
    from rodcont.rod import RodParameters
    from rodcont.system import RodSystem

    scaled = []

    class Counting(linalg.LU):
        def __init__(self, A, ordering="NATURAL", row_scale=None):
            scaled.append(row_scale is not None)
            super().__init__(A, ordering, row_scale)

    monkeypatch.setattr(linalg, "LU", Counting)
    rodcont.trace(1.0, max_steps=3)
    assert scaled and not any(scaled)
    s = RodSystem(RodParameters(EI=2.0 ** 20, GJ=0.75 * 2.0 ** 20, EA=255.0 * 2.0 ** 20, w=10.0 * 2.0 ** 20),
                  gamma=1.0, N=15)
    F, J, Fp = s.linearise(np.zeros(s.disc.size), 0.0)
    scaled.clear()
    s.bordered_solver(J, Fp, np.full(J.shape[0], 1e-4), 0.0)
    assert scaled == [True]
