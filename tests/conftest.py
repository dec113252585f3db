import os

# The tests run many small dense factorisations; on a shared 2-core machine
# OpenBLAS threads only contend with each other (set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
