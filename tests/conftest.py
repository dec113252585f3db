import os

from hypothesis import settings

# The tests run many small dense factorisations; on a shared 2-core machine
# OpenBLAS threads only contend with each other (set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Property tests draw the same examples on every run (CI and laptops alike): a failure is reproducible.
settings.register_profile("rodcont", derandomize=True, deadline=None)
settings.load_profile("rodcont")
