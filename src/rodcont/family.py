"""Families of branches (Figure 2): one trace per Gamma, in parallel.

Each branch is an independent job ``trace_to_file(gamma, path, **options)``
(a plain, picklable top-level function), submitted to any
``concurrent.futures``-compatible executor: the default is a local
``ProcessPoolExecutor`` with one process per core; a Dask
``client.get_executor()`` or a Ray/MPI pool executor plugs in unchanged, with
the branch files written where the workers can see ``out_dir``.
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed

from .rod import RodParameters


def branch_path(out_dir: str, gamma: float) -> str:
    return os.path.join(out_dir, f"gamma_{gamma:g}.h5")


def trace_to_file(gamma: float, path: str, rod: dict, queue=None, **options) -> dict:
    """Trace one branch into ``path``; returns a summary. ``queue`` (optional) receives
    ``(gamma, points, phi_L, stretch)`` after every point for a progress display."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from .branch import trace

    def report(pt):
        if queue is not None:
            queue.put((gamma, None, pt.data["phi_L"], pt.data["stretch"]))

    br = trace(gamma, RodParameters(**rod), out=path, callback=report, **options)
    folds = br.folds
    return dict(gamma=gamma, path=path, points=len(br), folds=len(folds),
                first_fold=folds[0]["phi_L"] if folds else None, stop_reason=br.stop_reason,
                elapsed=br.elapsed)


def sweep(gammas, out_dir: str, rod: RodParameters | None = None, N: int = 15, k: int = 5, jobs: int | None = None,
          executor: Executor | None = None, progress: bool = False, diagram: bool = True, **options) -> dict:
    """Trace one branch per Gamma into ``out_dir`` and draw the combined response diagram.

    ``executor``: any ``concurrent.futures.Executor`` (default: a process pool of
    ``jobs`` workers, all cores if None). ``options`` go to :func:`rodcont.trace`.
    Returns ``{"branches": [summary per Gamma, in the order given], "diagram": path, "jobs": n}``.
    """
    rod = rod or RodParameters()
    os.makedirs(out_dir, exist_ok=True)
    rod_d = rod.as_dict()
    own = executor is None
    jobs = jobs or os.cpu_count() or 1
    queue = None
    manager = None
    if own:
        executor = ProcessPoolExecutor(max_workers=min(jobs, len(gammas)))
        if progress:
            import multiprocessing
            manager = multiprocessing.Manager()
            queue = manager.Queue()
    status = {g: "queued" for g in gammas}
    counts = {g: 0 for g in gammas}
    results = {}
    try:
        futures = {executor.submit(trace_to_file, g, branch_path(out_dir, g), rod_d, queue, N=N, k=k, **options): g
                   for g in gammas}
        pending = set(futures)
        last = 0.0
        while pending:
            done = {f for f in pending if f.done()}
            for f in done:
                g = futures[f]
                results[g] = f.result()
                status[g] = "done: " + results[g]["stop_reason"][:60]
            pending -= done
            if queue is not None:
                while not queue.empty():
                    g, _, phi, stretch = queue.get_nowait()
                    counts[g] += 1
                    if not status[g].startswith("done"):
                        status[g] = f"Phi {phi:9.4f}  stretch {stretch:9.5f}"
            if progress and (time.monotonic() - last > 1.0 or not pending):
                last = time.monotonic()
                _show(status, counts)
            if pending:
                if queue is None:
                    next(as_completed(pending))  # no per-point reports: wait for a branch to finish
                else:
                    time.sleep(0.2)
    finally:
        if own:
            executor.shutdown(wait=True, cancel_futures=True)
        if manager is not None:
            manager.shutdown()
    out = dict(branches=[results[g] for g in gammas], jobs=jobs if own else None, diagram=None)
    if diagram:
        from .branchfile import load_branch
        from .plots import response_diagram
        path = os.path.join(out_dir, "response_diagram.png")
        response_diagram([load_branch(r["path"]) for r in out["branches"]], path)
        out["diagram"] = path
    return out


def _show(status, counts):
    lines = [f"  Gamma {g:8g}: {counts[g]:5d} points  {st}" for g, st in status.items()]
    if sys.stderr.isatty():
        sys.stderr.write("\x1b[%dA" % len(lines) if getattr(_show, "drawn", False) else "")
        _show.drawn = True
        sys.stderr.write("\n".join(line + "\x1b[K" for line in lines) + "\n")
    else:
        sys.stderr.write("\n".join(lines) + "\n")
    sys.stderr.flush()
