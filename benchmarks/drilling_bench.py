"""Torque-and-drag benchmark (issue 23's speed targets; a benchmark, not a test).

    python benchmarks/drilling_bench.py                       # every section
    python benchmarks/drilling_bench.py --only one --depth 1000
    python benchmarks/drilling_bench.py --only broom --points 2 --jobs 2

Sections (the 3-section string of examples/drill_string.toml in examples/well_s3d.toml, mu = 0.25):
  one    one equilibrium with friction (slack-off) at --depth (default the survey's end, 3500 m): wall and CPU
         time, N (target < 10 s)
  broom  the broomstick of 3 operations x --points depths from 1000 m to 3500 m on --jobs processes: wall time,
         extrapolated to 100 depths (target < 3 min on 2 cores); the soft string's time for 3 x 100 beside it
  warm   a depth step of 1 m and of 10 m from a solved depth: cold against warm (the previous depth's solution
         carried down with the bit, torque_and_drag(start=...))
The load average is printed beside the figures (the machine is shared).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))
EXAMPLES = os.path.join(HERE, "..", "examples")


def load():
    from rodcont.drilling import DrillString, Well
    return (Well.from_toml(os.path.join(EXAMPLES, "well_s3d.toml")),
            DrillString.from_toml(os.path.join(EXAMPLES, "drill_string.toml")))


def timed(f, *args, **kw):
    w, c = time.perf_counter(), time.process_time()
    out = f(*args, **kw)
    return out, time.perf_counter() - w, time.process_time() - c


def section_one(a):
    from rodcont.drilling import torque_and_drag
    well, string = load()
    d = a.depth or well.total_depth
    r, wall, cpu = timed(torque_and_drag, well, string, d, "slack-off")
    verdict = "met" if wall < 10 else "NOT met"
    print(f"one      equilibrium at {d:g} m, slack-off: {wall:.1f} s wall, {cpu:.1f} s CPU, N = {r.N}, "
          f"hook load {r.hook_load / 1e3:.3f} kN (target 10 s: {verdict})")


def section_broom(a):
    from rodcont.drilling import soft_string
    from rodcont.drivers.broomstick import OPERATIONS, broomstick
    well, string = load()
    depths = np.linspace(1000.0, well.total_depth, a.points)
    b, wall, _ = timed(broomstick, well, string, depths, [0.25], jobs=a.jobs)
    per = wall / (a.points * len(OPERATIONS))
    total = per * 100 * len(OPERATIONS)
    verdict = "met" if total < 180 else "NOT met"
    print(f"broom    3 operations x {a.points} depths on {a.jobs} processes: {wall:.1f} s wall "
          f"({len(b.failures)} failed); 3 x 100 extrapolated {total / 60:.1f} min (target 3 min: {verdict})")
    soft_depths = np.linspace(1000.0, well.total_depth, 100)
    t0 = time.perf_counter()
    for op in OPERATIONS:
        for d in soft_depths:
            soft_string(well, string, float(d), op)
    print(f"soft     soft string, 3 operations x 100 depths, one process: {time.perf_counter() - t0:.1f} s wall")


def section_warm(a):
    from rodcont.drilling import torque_and_drag
    well, string = load()
    d0 = a.depth or 1000.0
    r0 = torque_and_drag(well, string, d0, "slack-off")
    for h in (1.0, 10.0):
        cold, tc, _ = timed(torque_and_drag, well, string, d0 + h, "slack-off")
        warm, tw, _ = timed(torque_and_drag, well, string, d0 + h, "slack-off", start=r0)
        print(f"warm     step {h:g} m from {d0:g} m: cold {tc:.1f} s (N {cold.N}), warm {tw:.1f} s (N {warm.N}); "
              f"hook loads differ by {abs(warm.hook_load / cold.hook_load - 1):.1e}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", nargs="*", default=["one", "broom", "warm"])
    ap.add_argument("--depth", type=float, default=None)
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    print(f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}, {os.cpu_count()} cores")
    for name in a.only:
        globals()[f"section_{name}"](a)


if __name__ == "__main__":
    main()
