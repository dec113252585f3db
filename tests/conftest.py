import os

import pytest
from hypothesis import settings

# The tests run many small dense factorisations; on a shared 2-core machine
# OpenBLAS threads only contend with each other (set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Property tests draw the same examples on every run (CI and laptops alike): a failure is reproducible.
settings.register_profile("rodcont", derandomize=True, deadline=None)
settings.load_profile("rodcont")


def assert_picture(path):
    """A PNG that decodes and is not blank (what is drawn is tested in test_plots.py)."""
    import matplotlib.image as mpimg
    import numpy as np
    img = mpimg.imread(str(path))
    assert img.ndim == 3 and min(img.shape[:2]) > 300 and np.ptp(img[:, :, :3]) > 0.5


def run(args, capsys):
    """Run the CLI in-process; returns (exit status, stdout, stderr)."""
    import pytest

    from rodcont.cli import main
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def assert_tangent_matches_differences(disc, x, p, h):
    """The assembled sparse Jacobian ``dF/dx`` and ``dF/dp_0`` of a discretisation against dense central
    differences with step ``h`` (truncation O(h^2), rounding ~ eps |F| / h), and ``F`` against the residual."""
    import numpy as np
    F, J, (Fp,) = disc.linearise(x, p, [0])
    Jfd = np.empty((disc.size, disc.size))
    for j in range(disc.size):
        e = np.zeros(disc.size)
        e[j] = h
        Jfd[:, j] = (disc.residual(x + e, p) - disc.residual(x - e, p)) / (2 * h)
    assert np.allclose(J.toarray(), Jfd, rtol=1e-6, atol=1e-6)
    pp, pm = p.copy(), p.copy()
    pp[0] += h
    pm[0] -= h
    assert np.allclose(Fp, (disc.residual(x, pp) - disc.residual(x, pm)) / (2 * h), atol=1e-7)
    assert np.allclose(F, disc.residual(x, p), atol=1e-13)


@pytest.fixture
def interrupt_solve(monkeypatch):
    """``interrupt_solve(n)``: rodcont.drilling.torque_and_drag raises KeyboardInterrupt on its n-th call (a Ctrl-C
    between two depths of a trip), the calls before it solved as usual."""
    import rodcont.drilling as drilling
    real = drilling.torque_and_drag

    def arm(n):
        calls = []

        def interrupted(*args, **kw):
            calls.append(1)
            if len(calls) == n:
                raise KeyboardInterrupt
            return real(*args, **kw)
        monkeypatch.setattr(drilling, "torque_and_drag", interrupted)
    return arm
