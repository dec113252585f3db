"""Families of branches (Figure 2): one trace (or one diagram) per Gamma, in parallel.

Each Gamma is an independent job ``trace_to_file(gamma, path, rod, ...)``
(a plain, picklable top-level function) submitted to any
``concurrent.futures``-compatible executor: the default is a local
``ProcessPoolExecutor`` with one process per core; a Dask
``client.get_executor()`` or a Ray/MPI pool executor plugs in unchanged, with
the files written where the workers can see ``out_dir``. A Gamma that fails is
reported with its reason; the others finish.
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import Executor, ProcessPoolExecutor

from ..result import Status
from ..rod import RodParameters
from ..system import check_number


def gamma_name(gamma: float) -> str:
    """A file-name form of Gamma that reads back exactly: ``repr`` without a trailing ``.0``."""
    s = repr(float(gamma))
    return s[:-2] if s.endswith(".0") else s


def branch_path(out_dir: str, gamma: float, diagram: bool = False) -> str:
    return os.path.join(out_dir, f"{'diagram' if diagram else 'gamma'}_{gamma_name(gamma)}.h5")


def trace_to_file(gamma: float, path: str, rod: dict, queue=None, diagram: bool = False, **options) -> dict:
    """Trace one branch (or, with ``diagram``, the whole diagram) into ``path``; returns a summary.

    ``queue`` (optional) receives ``(gamma, n_points, phi_L, stretch)`` after every point.
    The summary names the run's ``status`` (a :class:`rodcont.result.Status` value) beside its
    ``stop_reason``. A failure is returned as a summary with ``error`` set, not raised.
    """
    n = [0]

    def report(pt):
        n[0] += 1
        if queue is not None:
            queue.put((gamma, n[0], pt.data["phi_L"], pt.data["stretch"]))

    t0 = time.perf_counter()
    try:
        if diagram:
            from .diagram import diagram as run_diagram
            d = run_diagram(gamma, RodParameters(**rod), out=path, callback=report, **options)
            folds = d.folds
            return dict(gamma=gamma, path=path, points=sum(len(b.branch) for b in d.branches),
                        branches=len(d.branches),
                        folds=len(folds), first_fold=folds[0]["phi_L"] if folds else None,
                        stop_reason=f"{len(d.branches)} branches", status=str(d.status),
                        elapsed=time.perf_counter() - t0, error=None)
        from .trace import trace
        br = trace(gamma, RodParameters(**rod), out=path, callback=report, **options)
        folds = br.folds
        return dict(gamma=gamma, path=path, points=len(br), folds=len(folds), branches=1,
                    first_fold=folds[0]["phi_L"] if folds else None, stop_reason=br.stop_reason,
                    status=str(br.status), elapsed=time.perf_counter() - t0, error=None)
    except Exception as exc:  # noqa: BLE001 - one failing Gamma is reported, the others go on
        return dict(gamma=gamma, path=path, points=0, folds=0, branches=0, first_fold=None,
                    stop_reason=f"failed: {exc}", status=str(getattr(exc, "status", Status.START_FAILED)),
                    elapsed=time.perf_counter() - t0, error=str(exc))


def _worker_init() -> None:
    """Worker processes: one BLAS thread each (the pool itself is the parallelism), and a SIGTERM that stops the
    worker without a word: the command line's handler, inherited, had each worker print 'rodcont: interrupted' as
    well (three lines for a broomstick on 2 workers; test_a_workers_sigterm_is_silent)."""
    import signal
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    signal.signal(signal.SIGTERM, _silent_stop)


def _silent_stop(signum, frame):
    raise SystemExit(143)  # unwinds the job's own cleanup (a sweep's worker writes its branch file)


def _stop_workers(executor) -> None:
    """Kill a process pool's workers (SIGKILL: a worker forked inside the command line's interrupt handler
    takes SIGTERM as a request to stop at its next point, which it has no callback to see)."""
    for process in list(getattr(executor, "_processes", {}).values()):
        if process.is_alive():
            process.kill()


def sweep(gammas, out_dir: str, rod: RodParameters | None = None, N: int = 15, k: int = 5, jobs: int | None = None,
          executor: Executor | None = None, progress: bool = False, plot: bool = True, diagram: bool = False,
          overwrite: bool = False, **options) -> dict:
    """Trace one branch (or diagram) per Gamma into ``out_dir`` and draw the combined response diagram.

    ``executor``: any ``concurrent.futures.Executor`` (default: a process pool of
    ``jobs`` workers, all cores if None). ``options`` go to :func:`rodcont.trace`.
    Returns ``{"branches": [summary per Gamma, in the order given], "diagram": path, "jobs": n}``.
    """
    gammas, rod, jobs = _checked(gammas, rod, jobs, options)
    _check_run(out_dir, N, k, executor)
    from ..branchfile import check_output
    from ..safeio import command_inputs
    os.makedirs(out_dir, exist_ok=True)
    paths = [branch_path(out_dir, g, diagram) for g in gammas]
    inputs = command_inputs(reference=options.get("curve") if isinstance(options.get("curve"), str) else None,
                            curves=[options["curve"]] if not isinstance(options.get("curve"), (str, type(None)))
                            else ())
    for p in paths + ([os.path.join(out_dir, "response_diagram.png")] if plot else []):
        check_output(p, inputs, overwrite=overwrite)  # never onto the survey the traces read
    own = executor is None
    jobs = jobs or os.cpu_count() or 1
    queue = manager = None
    if own:
        executor = ProcessPoolExecutor(max_workers=min(jobs, len(gammas)), initializer=_worker_init)
        if progress:
            import multiprocessing
            manager = multiprocessing.Manager()
            queue = manager.Queue()
    try:
        futures = {executor.submit(trace_to_file, g, p, rod.as_dict(), queue, diagram, N=N, k=k, overwrite=overwrite,
                                   **options): g for g, p in zip(gammas, paths)}
        results = _collect(futures, _Progress(gammas, progress), queue)
    finally:
        if own:
            executor.shutdown(wait=True, cancel_futures=True)
        if manager is not None:
            manager.shutdown()
    out = dict(branches=[results[g] for g in gammas], jobs=jobs if own else None, diagram=None)
    ok = [r["path"] for r in out["branches"] if r["error"] is None and os.path.exists(r["path"])]
    if plot and ok:
        out["diagram"] = _plot(ok, out_dir)
    return out


def _checked(gammas, rod, jobs, options):
    """The Gamma values, the rod and the number of jobs of a sweep, checked (one error naming the input)."""
    if isinstance(gammas, (str, bytes, dict)) or not hasattr(gammas, "__iter__"):
        raise TypeError(f"gammas must be a sequence of Gamma values (numbers), got {gammas!r}")
    gammas = list(gammas)
    if not gammas:
        raise ValueError("sweep needs at least one Gamma")
    gammas = [check_number("gamma", g) for g in gammas]
    rod = rod or RodParameters()
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    for g in gammas:
        check_number("T = gamma w L", rod.tension(g))
    names = [gamma_name(g) for g in gammas]
    if len(set(names)) != len(names):
        raise ValueError("Gamma values must be distinct")
    if jobs is not None:
        jobs = check_number("jobs", jobs, integer=True)
        if jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {jobs}")
    from .trace import TraceOptions
    TraceOptions(**{k_: v for k_, v in options.items() if k_ not in ("deflate_at", "store_every", "curve")})
    return gammas, rod, jobs


def _check_run(out_dir, N, k, executor) -> None:
    """The output directory, the mesh and the executor of a sweep, checked before any job starts (a wrong one
    would otherwise fail in every job, or in ``os.makedirs``)."""
    if not isinstance(out_dir, (str, os.PathLike)):
        raise TypeError(f"out_dir must be a directory name, got {out_dir!r}")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise ValueError(f"out_dir {os.fspath(out_dir)} exists and is not a directory")
    if not 1 <= check_number("N", N, integer=True) <= 100000:
        raise ValueError(f"N (number of subintervals) must be an integer >= 1, got {N}")
    if not 1 <= check_number("k", k, integer=True) <= 7:
        raise ValueError(f"k (Gauss points per subinterval) must be an integer in 1..7, got {k}")
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise TypeError(f"executor must be a concurrent.futures.Executor (with submit), got {executor!r}")


def _collect(futures: dict, display, queue) -> dict:
    """The summaries of the submitted jobs as they finish, the progress display kept up."""
    results = {}
    pending = set(futures)
    while pending:
        done = {f for f in pending if f.done()}
        for f in done:
            g = futures[f]
            results[g] = f.result()
            display.finish(g, results[g])
        pending -= done
        if queue is not None:
            while not queue.empty():
                display.update(*queue.get_nowait())
        if pending:
            time.sleep(0.1)
        display.draw(force=not pending)
    return results


def _plot(paths: list, out_dir: str) -> str:
    from ..branchfile import load_diagram
    from ..plots import response_diagram
    path = os.path.join(out_dir, "response_diagram.png")
    if os.path.lexists(path) and not os.path.isfile(os.path.realpath(path)):
        raise ValueError(f"cannot write {path}: not a regular file")
    response_diagram([load_diagram(p) for p in paths], path)
    return path


class _Progress:
    """One line per Gamma: rewritten in place on a terminal; otherwise one final line per Gamma."""

    def __init__(self, gammas, enabled: bool):
        self.enabled = enabled
        self.tty = enabled and sys.stderr.isatty()
        self.lines = {g: "queued" for g in gammas}
        self.drawn = False
        self.last = 0.0

    def update(self, g, n, phi, stretch):
        self.lines[g] = f"{n:5d} points  Phi {phi:9.4f}  stretch {stretch:9.5f}"

    def finish(self, g, r):
        self.lines[g] = (f"done: {r['points']} points, {r['folds']} folds, {r['elapsed']:.1f} s; {r['stop_reason']}")
        if self.enabled and not self.tty:
            sys.stderr.write(f"  Gamma {g:8g}: {self.lines[g]}\n")
            sys.stderr.flush()

    def draw(self, force: bool = False):
        if not self.tty or (time.monotonic() - self.last < 0.2 and not force):
            return
        self.last = time.monotonic()
        out = []
        if self.drawn:
            out.append("\x1b[%dA" % len(self.lines))
        for g, line in self.lines.items():
            out.append(f"  Gamma {g:8g}: {line}"[:200] + "\x1b[K\n")
        sys.stderr.write("".join(out))
        sys.stderr.flush()
        self.drawn = True
