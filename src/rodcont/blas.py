"""One BLAS thread while rodcont works, the caller's setting given back when it returns.

rodcont's linear algebra is sparse (SuperLU) and vector work on long arrays; numpy's OpenBLAS threads the long
vector operations and its idle threads then spin: on a 2-core machine a continuation step at N = 5000 took
1.02 s of CPU with OpenBLAS's default two threads and 0.58 s with one, in the same wall time, and a process pool
(``diagram``, ``broomstick``) has them spin on the cores its other workers need (README, Performance).

:func:`one_blas_thread` finds the OpenBLAS libraries the process has loaded (numpy's and scipy's wheels each
bundle one) through ``/proc/self/maps`` and their ``openblas_set_num_threads`` (any of the prefixes and suffixes
the wheels export); where there is none (another BLAS, another system) it does nothing. The environment variable
``RODCONT_BLAS_THREADS`` sets the count (``0``: leave BLAS as it is). A command (:func:`command_environment`,
called before numpy is imported) sets ``OPENBLAS_NUM_THREADS`` instead, unless the user has: OpenBLAS then starts
no threads at all (a count set after loading leaves the started ones spinning, ~0.05 s a trace), and the
workers of its process pools inherit it.
"""
from __future__ import annotations

import ctypes
import functools
import os
from contextlib import contextmanager

_LIBRARIES: list | None = None
_NAMES = [(f"{pre}openblas_set_num_threads{suf}", f"{pre}openblas_get_num_threads{suf}")
          for pre in ("scipy_", "") for suf in ("64_", "", "_")]


def _loaded_paths() -> list[str]:
    try:
        with open("/proc/self/maps") as f:
            return sorted({ln.split()[-1] for ln in f if "openblas" in ln.lower() and ln.split()[-1].startswith("/")})
    except OSError:  # not Linux: no way to list the loaded libraries without a dependency
        return []


def openblas_libraries() -> list[tuple]:
    """``(path, set_num_threads, get_num_threads)`` of each loaded OpenBLAS (found once, after numpy and
    scipy's sparse solvers are imported, as every caller of :func:`one_blas_thread` has them)."""
    global _LIBRARIES
    if _LIBRARIES is None:
        import numpy  # noqa: F401 - their BLAS loaded before the search
        import scipy.sparse.linalg  # noqa: F401
        found = []
        for path in _loaded_paths():
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            for set_name, get_name in _NAMES:
                if hasattr(lib, set_name) and hasattr(lib, get_name):
                    setter, getter = getattr(lib, set_name), getattr(lib, get_name)
                    setter.argtypes, setter.restype, getter.restype = [ctypes.c_int], None, ctypes.c_int
                    found.append((path, setter, getter))
                    break
        _LIBRARIES = found
    return _LIBRARIES


def _wanted() -> int:
    """The count ``RODCONT_BLAS_THREADS`` asks for (1 when unset; 0: leave BLAS alone); a value that is not a count
    is said once (a ``RuntimeWarning``) and read as 1."""
    raw = os.environ.get("RODCONT_BLAS_THREADS", "1").strip()
    if raw.isdigit():
        return int(raw)
    if raw not in _SAID:
        _SAID.add(raw)
        import warnings
        warnings.warn(f"RODCONT_BLAS_THREADS={raw!r} is not a count of threads: rodcont runs on one",
                      RuntimeWarning, stacklevel=3)
    return 1


_SAID: set = set()


def command_environment(environ=os.environ) -> None:
    """``OPENBLAS_NUM_THREADS`` set to :func:`_wanted`'s count for a command's process, unless already set (a
    value that is not a count said as the command line says warnings)."""
    import sys
    import warnings
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        n = _wanted()
    for w in said:
        sys.stderr.write(f"rodcont: warning: {w.message}\n")
    if n:
        environ.setdefault("OPENBLAS_NUM_THREADS", str(n))


@contextmanager
def one_blas_thread():
    """Every loaded OpenBLAS at :func:`_wanted`'s count inside the block, each back at its own count after."""
    n = _wanted()
    libs = openblas_libraries() if n else []
    before = [get() for _, _, get in libs]
    changed = [(setter, b) for (_, setter, _), b in zip(libs, before) if b != n]
    for setter, _ in changed:
        setter(n)
    try:
        yield
    finally:
        for setter, b in changed:
            setter(b)


def with_one_blas_thread(f):
    """``f`` run under :func:`one_blas_thread` (the public entry points: traces, solves, the drilling jobs)."""
    @functools.wraps(f)
    def wrapped(*args, **kwargs):
        with one_blas_thread():
            return f(*args, **kwargs)
    return wrapped
