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
