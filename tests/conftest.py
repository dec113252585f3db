import os

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
