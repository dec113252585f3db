"""rodcont works on one BLAS thread and gives the caller's count back (rodcont.blas).

OpenBLAS's idle threads spin: a step at N = 5000 took 1.02 s of CPU on its two default threads and 0.58 s on one,
in the same wall time. These tests read the thread count each loaded OpenBLAS reports, inside and after rodcont's
work; they skip where the process has no OpenBLAS that can run two threads.
"""
import os
import subprocess
import sys

import numpy as np
import pytest

import rodcont
from rodcont import blas


def _counts():
    return [get() for _, _, get in blas.openblas_libraries()]


@pytest.fixture
def two_threads():
    libs = blas.openblas_libraries()
    if not libs:
        pytest.skip("no OpenBLAS loaded in this process")
    before = _counts()
    for _, setter, _ in libs:
        setter(2)
    if _counts() != [2] * len(libs):
        pytest.skip("this OpenBLAS cannot run two threads")
    yield libs
    for (_, setter, _), n in zip(libs, before):
        setter(n)


def test_one_blas_thread_sets_every_openblas_to_one_and_gives_the_count_back(two_threads, monkeypatch):
    monkeypatch.delenv("RODCONT_BLAS_THREADS", raising=False)
    with blas.one_blas_thread():
        assert _counts() == [1] * len(two_threads)
        with blas.one_blas_thread():  # nested: the inner block leaves the outer's count
            pass
        assert _counts() == [1] * len(two_threads)
    assert _counts() == [2] * len(two_threads)


def test_a_trace_runs_on_one_blas_thread_and_rodcont_blas_threads_0_leaves_blas_alone(two_threads, monkeypatch):
    seen = []
    monkeypatch.delenv("RODCONT_BLAS_THREADS", raising=False)
    one = rodcont.trace(1.0, max_steps=8, callback=lambda pt: seen.append(_counts()))
    assert seen and all(c == [1] * len(two_threads) for c in seen)
    assert _counts() == [2] * len(two_threads)
    seen.clear()
    monkeypatch.setenv("RODCONT_BLAS_THREADS", "0")
    left = rodcont.trace(1.0, max_steps=8, callback=lambda pt: seen.append(_counts()))
    assert seen and all(c == [2] * len(two_threads) for c in seen)
    # the same branch either way (a threaded BLAS sums in another order: rounding, not more)
    assert len(one.table["phi_L"]) == len(left.table["phi_L"])
    np.testing.assert_allclose(one.table["phi_L"], left.table["phi_L"], rtol=0, atol=1e-10)


@pytest.mark.parametrize("given, expected", [({}, "1"), ({"OPENBLAS_NUM_THREADS": "3"}, "3"),
                                             ({"RODCONT_BLAS_THREADS": "2"}, "2"),
                                             ({"RODCONT_BLAS_THREADS": "0"}, "None")])
def test_a_command_tells_openblas_its_count_before_numpy_loads_it(given, expected):
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "RODCONT_BLAS_THREADS")}
    code = ("import sys; sys.argv = ['rodcont']; import rodcont, os; "
            "print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env={**env, **given}, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [expected, "False"]


def test_a_library_import_leaves_the_environment_alone():
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    code = "import rodcont, os; print(os.environ.get('OPENBLAS_NUM_THREADS'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["None"]


def test_a_solves_warning_points_at_the_callers_line_not_the_wrapper():
    # with_one_blas_thread adds a frame: a warning aimed at the caller of solve (stacklevel) landed on
    # rodcont/blas.py until its stacklevel counted the wrapper
    with pytest.warns(RuntimeWarning, match="exceeds its guard") as seen:
        rodcont.solve(gamma=1.0, phi_L=6.0, N=3, k=3, adapt=False)
    assert {w.filename for w in seen.list if "exceeds its guard" in str(w.message)} == {__file__}


def test_a_count_that_is_not_one_is_said_once(monkeypatch):
    monkeypatch.setattr(blas, "_SAID", set())
    monkeypatch.setenv("RODCONT_BLAS_THREADS", "two")
    with pytest.warns(RuntimeWarning, match="RODCONT_BLAS_THREADS='two' is not a count of threads"):
        assert blas._wanted() == 1
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert blas._wanted() == 1   # said once


def test_a_command_says_a_count_that_is_not_one_in_its_own_words():
    env = {**os.environ, "RODCONT_BLAS_THREADS": "x"}
    r = subprocess.run([sys.executable, "-m", "rodcont", "--version"], env=env, capture_output=True, text=True)
    assert r.returncode == 0
    assert r.stderr == "rodcont: warning: RODCONT_BLAS_THREADS='x' is not a count of threads: rodcont runs on one\n"
