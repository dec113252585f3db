"""The broomstick's split into jobs (rodcont.drivers.broomstick.broom_tasks): one job a depth, the deepest first, and
the same arrays as the curves solved one depth after the other in one job (each depth is its own cold start)."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from rodcont.drilling import DrillString, Section, Well
from rodcont.drivers.broomstick import broom_job, broom_tasks, broomstick

# a straight hole inclined 80 degrees, a light pipe (tests/test_drilling_buckling.py's): a cheap broomstick
PIPE = Section("light pipe", None, 1e4, 7.7e3, 1e8, 100.0, 0.05)
STRING = DrillString((PIPE,), 1.0)
WELL = Well(np.array([[0.0, 80.0, 0.0], [400.0, 80.0, 0.0]]), hole_diameter=0.3, friction=0.4)


class CountingExecutor(ThreadPoolExecutor):
    """A thread pool that records the depths of each job submitted, in order."""

    def __init__(self):
        super().__init__(max_workers=1)
        self.submitted = []

    def submit(self, fn, *args, **kwargs):
        self.submitted.append((args[3], args[4], tuple(args[2])))
        return super().submit(fn, *args, **kwargs)


def test_broom_tasks_are_one_a_depth_and_case_the_deepest_first():
    cases = [("pick-up", 0.2), ("rotate", 0.3)]
    tasks = broom_tasks(np.array([100.0, 300.0, 200.0]), cases)
    assert tasks == [(op, mu, i) for i in (1, 2, 0) for op, mu in cases]


def test_broomstick_submits_one_job_a_depth_and_keeps_each_curves_answers():
    """2 operations x 2 depths: 4 jobs of one depth each (the deeper first), and every array (hook load, torque,
    side force, N, ...) exactly the one of the curve solved whole in one job (the previous split)."""
    depths = np.array([100.0, 150.0])
    ops = ("pick-up", "slack-off")
    with CountingExecutor() as ex:
        b = broomstick(WELL, STRING, depths, (0.4,), operations=ops, executor=ex)
        jobs = ex.submitted
    assert jobs == [(op, 0.4, (d,)) for d in (150.0, 100.0) for op in ops]
    assert not b.failures
    for i, op in enumerate(ops):
        whole = broom_job(WELL, STRING, depths, op, 0.4, {})
        for key in b.data:
            np.testing.assert_array_equal(b.data[key][:, i, 0], whole[key], err_msg=f"{op} {key}")
    assert set(b.elapsed) == {(op, 0.4) for op in ops} and all(v > 0 for v in b.elapsed.values())


def test_soft_string_evaluates_the_path_once_an_interval(monkeypatch):
    """The soft string's Runge-Kutta steps read the well path from one jet per interval between its cuts (the
    survey's arcs here: 2 in the S well cut at 1200 m), not one per stage (4 a step, 4800 at 1 m steps)."""
    from rodcont import curves, drilling
    well = Well(np.array([[0.0, 0.0, 0.0], [500.0, 0.0, 0.0], [1500.0, 60.0, 30.0]]), hole_diameter=0.3,
                friction=0.3)
    calls = []
    jet = curves.MinimumCurvatureWell.jet
    monkeypatch.setattr(curves.MinimumCurvatureWell, "jet", lambda self, S: calls.append(np.size(S)) or jet(self, S))
    drilling.soft_string(well, STRING, 1200.0, "rotate", mu=0.3)
    assert len(calls) == 2 and sum(calls) == 3 * 1200
