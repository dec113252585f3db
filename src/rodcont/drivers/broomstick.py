"""The broomstick: hook load against bit depth for pick-up, slack-off and rotating off bottom, one curve per
friction factor, the soft-string estimate beside each, and the surface torque against depth.

Each ``(operation, friction factor)`` is one job (:func:`broom_job`, a plain top-level function) on any
``concurrent.futures`` executor, the default a local process pool as :func:`rodcont.drivers.sweep.sweep` uses;
the broomstick submits one job a depth (:func:`broom_tasks`: each depth is its own cold start of
:func:`rodcont.drilling.torque_and_drag`, so the split changes no answer), the deepest first. A depth that
fails is stored as NaN with its reason; the others go on. Each finished equilibrium is filled in as it comes
(:meth:`Broomstick.fill`, then the ``callback``), so a broomstick interrupted is kept as far as it went
(``complete`` says which cells) and one started from it (``start=``) solves only the rest.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import FIRST_COMPLETED, Executor, ProcessPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from ..blas import with_one_blas_thread

OPERATIONS = ("pick-up", "slack-off", "rotate")
#: the arrays of a broomstick, one number per depth, operation and friction factor
BROOM_KEYS = ("hook_load", "surface_torque", "soft_hook_load", "soft_surface_torque", "side_force", "error", "N",
              "buckling_ratio", "max_compression")


@with_one_blas_thread
def broom_job(well, string, depths, operation: str, mu: float, options: dict) -> dict:
    """One curve: the stiff and the soft string at every depth for ``operation`` and ``mu``."""
    from ..drilling import buckling_ratio, soft_string, torque_and_drag
    n = len(depths)
    out = {key: np.full(n, np.nan) for key in BROOM_KEYS}
    out["failures"] = []
    t0 = time.perf_counter()
    for i, d in enumerate(depths):
        try:
            r = torque_and_drag(well, string, float(d), operation, mu=mu, **options)
            out["hook_load"][i], out["surface_torque"][i] = r.hook_load, r.surface_torque
            out["side_force"][i], out["error"][i], out["N"][i] = r.side_force, r.error, r.N
            out["buckling_ratio"][i] = float(np.max(buckling_ratio(r)))
            out["max_compression"][i] = max(0.0, -float(np.min(r.profile["axial_force"])))
        except Exception as exc:  # noqa: BLE001 - one failing depth is reported, the others go on
            out["failures"].append((float(d), str(exc)))
        out["soft_hook_load"][i], out["soft_surface_torque"][i] = soft_string(well, string, float(d), operation, mu=mu)
    out["elapsed"] = time.perf_counter() - t0
    return out


@dataclass
class Broomstick:
    """Arrays ``(len(depths), len(operations), len(mus))``: ``hook_load``, ``surface_torque``, their soft-string
    estimates ``soft_hook_load``, ``soft_surface_torque``, ``side_force``, ``error``, ``N``, the string's largest
    ``buckling_ratio`` and ``max_compression`` (N, 0 in tension); ``failures``
    ``[(operation, mu, depth, reason)]``, ``elapsed`` (s) per job; ``complete`` (bool, same shape) where the
    equilibrium was solved or failed (False: not reached, NaN; all True unless given); ``attrs`` a file's
    attributes (:func:`read_broomstick`)."""

    depths: np.ndarray
    operations: tuple
    mus: tuple
    data: dict
    failures: list = field(default_factory=list)
    elapsed: dict = field(default_factory=dict)
    complete: np.ndarray | None = None
    attrs: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.complete is None:
            self.complete = np.ones((len(self.depths), len(self.operations), len(self.mus)), bool)

    @classmethod
    def empty(cls, depths, operations, mus) -> Broomstick:
        """A broomstick with no equilibrium yet: every array NaN, nothing ``complete``."""
        shape = (len(depths), len(operations), len(mus))
        return cls(np.asarray(depths, float), tuple(operations), tuple(float(m) for m in mus),
                   {key: np.full(shape, np.nan) for key in BROOM_KEYS}, [],
                   {(op, float(mu)): 0.0 for op in operations for mu in mus}, np.zeros(shape, bool))

    def __getattr__(self, name):
        data = self.__dict__.get("data", {})
        if name in data:
            return data[name]
        raise AttributeError(name)

    def cell(self, op: str, mu: float, k: int) -> tuple:
        """The index ``(depth, operation, friction)`` of depth number ``k`` of ``op`` at ``mu``."""
        return k, self.operations.index(op), self.mus.index(float(mu))

    def fill(self, op: str, mu: float, k: int, res: dict) -> None:
        """Depth number ``k`` of ``op`` at ``mu`` from a one-depth :func:`broom_job`'s ``res``."""
        at = self.cell(op, mu, k)
        for key in self.data:
            self.data[key][at] = res[key][0]
        self.failures += [(op, float(mu), d, why) for d, why in res["failures"]]
        self.elapsed[(op, float(mu))] = self.elapsed.get((op, float(mu)), 0.0) + res["elapsed"]
        self.complete[at] = True

    def same_cases(self, depths, operations, mus) -> bool:
        """Whether this broomstick's depths, operations and friction factors are these, in this order."""
        d = np.asarray(depths, float)
        return (self.depths.shape == d.shape and bool(np.array_equal(self.depths, d))
                and tuple(self.operations) == tuple(operations) and self.mus == tuple(float(m) for m in mus))


def broomstick(well, string, depths, mus, operations=OPERATIONS, *, executor: Executor | None = None,
               jobs: int | None = None, callback=None, start: Broomstick | None = None, out: str | None = None,
               meta: dict | None = None, **options) -> Broomstick:
    """The broomstick of ``string`` in ``well`` at ``depths`` (m, bit MD) for each friction factor of ``mus``
    and each operation; ``options`` go to :func:`rodcont.drilling.torque_and_drag` (``N_max``, ``max_error``).
    ``callback(b, (operation, mu, k))`` is called in this process after each equilibrium is filled in (its
    ``idle()``, where it has one, every 0.2 s while the jobs run: an exception from either stops the jobs and
    is raised, ``b`` kept as far as it went). ``start``: a broomstick of the same depths, operations and friction
    factors whose ``complete`` cells are kept (copied), not solved again. ``out``: the broomstick's file
    (:func:`write_broomstick`, ``meta`` and the record :func:`resume_broomstick` rebuilds the run from as its
    attributes), published again after each equilibrium: an interrupted run keeps every one it finished."""
    from ..drilling import check_solve_options
    depths = np.asarray(depths, float)
    mus = [float(mu) for mu in mus]
    _check_cases(well, depths, mus, operations, jobs)
    check_solve_options(options)
    b = Broomstick.empty(depths, operations, mus)
    if start is not None:
        _carry(b, start)
    lock = _locked(out)
    try:
        if out is not None:
            callback = _Checkpoint(out, {**(meta or {}), "drilling": run_record(well, string, options)}, callback)
        return _solve_cells(b, well, string, options, executor, jobs, callback)
    finally:
        if lock is not None:
            lock.release()


def _locked(out: str | None):
    """The one-writer lock of the broomstick's file (:class:`rodcont.branchfile.OutputLock`), None without one;
    a second writer is refused (``ValueError``, one line: test_a_second_writer_of_a_broomstick_is_refused)."""
    from ..branchfile import BranchFileError, OutputLock
    if out is None:
        return None
    try:
        return OutputLock(out)
    except BranchFileError as exc:
        raise ValueError(str(exc)) from None


def _solve_cells(b: Broomstick, well, string, options, executor, jobs, callback) -> Broomstick:
    """The cells of ``b`` not ``complete`` solved on ``executor`` (default a process pool of ``jobs``), each filled
    in and passed to ``callback`` as it comes; the jobs still running stopped on an interrupt or an error."""
    from .sweep import _stop_workers, _worker_init
    cases = [(op, mu) for op in b.operations for mu in b.mus]
    tasks = [t for t in broom_tasks(b.depths, cases) if not b.complete[b.cell(t[0], t[1], t[2])]]
    if not tasks:
        return b
    depths = b.depths
    own = executor is None
    if own:
        jobs = jobs or os.cpu_count() or 1
        executor = ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), initializer=_worker_init)
    futures, finished = {}, False
    try:
        futures = {executor.submit(broom_job, well, string, depths[i:i + 1], op, mu, options): (op, mu, i)
                   for op, mu, i in tasks}
        _collect(futures, b, callback)
        finished = True
    finally:
        if not finished:
            for future in futures:
                future.cancel()
        if own:
            if not finished:  # an interrupt or an error: the jobs still running are not waited for
                _stop_workers(executor)
            executor.shutdown(wait=True, cancel_futures=True)
    return b


class _Checkpoint:
    """The callback that publishes the broomstick to ``path`` after each equilibrium, then calls ``then``
    (its ``idle`` passed on)."""

    def __init__(self, path: str, meta: dict, then=None):
        self.path, self.meta, self.then = path, meta, then
        self.idle = getattr(then, "idle", None)

    def __call__(self, b: Broomstick, cell: tuple) -> None:
        write_broomstick(b, self.path, self.meta)
        if self.then is not None:
            self.then(b, cell)


def run_record(well, string, options: dict) -> str:
    """The JSON a broomstick's file keeps (attribute ``drilling``) to be finished by :func:`resume_broomstick`:
    the well and the string (:func:`rodcont.drilling.well_and_string_record`) and the solve's ``options``."""
    from ..drilling import RECORD_VERSION, well_and_string_record
    return json.dumps(dict(version=RECORD_VERSION, **well_and_string_record(well, string), options=dict(options)))


def resume_broomstick(path: str, *, executor: Executor | None = None, jobs: int | None = None,
                      callback=None) -> Broomstick:
    """The broomstick of the file ``path`` (an interrupted ``rodcont broomstick --out``) finished in place: its
    well, string and options from its record (:func:`run_record`), its complete cells kept, the others solved
    (:func:`broomstick` with ``start``); a ``ValueError`` (one line) for a file it cannot finish."""
    from ..drilling import RECORD_VERSION, DrillingError, check_solve_options, place_string, well_and_string_back
    b0 = read_broomstick(path)
    text = b0.attrs.get("drilling")
    if not isinstance(text, str):
        raise ValueError(f"{path} keeps no record of its well and string (written before broomsticks could be "
                         f"resumed): run it again")
    damaged = (ValueError, KeyError, TypeError, AttributeError, IndexError, ZeroDivisionError, DrillingError)
    try:
        rec = json.loads(text)
        version = int(rec.get("version", 0))
    except damaged as exc:
        raise ValueError(f"{path}: a damaged broomstick record ({type(exc).__name__}: {exc})") from None
    if version > RECORD_VERSION:
        raise ValueError(f"{path}: its record is version {version}, newer than this rodcont's ({RECORD_VERSION}): "
                         f"update rodcont")
    try:
        well, string = well_and_string_back(rec)
        options = dict(rec.get("options", {}))
        check_solve_options(options)
        _check_cases(well, b0.depths, list(b0.mus), b0.operations, jobs)
        place_string(well, string, float(np.max(b0.depths)))  # the record's numbers used once, here
    except damaged as exc:
        raise ValueError(f"{path}: a damaged broomstick record ({type(exc).__name__}: {exc})") from None
    _check_cells(b0, path)
    meta = {key: v for key, v in b0.attrs.items() if key not in ("kind", "status", "drilling")}
    return broomstick(well, string, b0.depths, b0.mus, b0.operations, executor=executor, jobs=jobs,
                      callback=callback, start=b0, out=path, meta=meta, **options)


def _check_cases(well, depths, mus, operations, jobs) -> None:
    """Each friction factor (a number >= 0) and operation (a named one) once, ``jobs`` a count, each depth inside
    the well (one line each)."""
    from ..loads import OPERATIONS as NAMED
    for what, values in (("friction factor", mus), ("operation", list(operations))):
        twice = [v for v in values if values.count(v) > 1]
        if twice:  # one curve each: a second copy's cells were never filled (uninitialised numbers printed)
            raise ValueError(f"the {what} {twice[0]} is given twice: give each once")
    bad = [mu for mu in mus if not (np.isfinite(mu) and mu >= 0)]
    if bad:
        raise ValueError(f"a friction factor must be a number >= 0, got {bad[0]!r}")
    unknown = [op for op in operations if op not in NAMED]
    if unknown:
        raise ValueError(f"unknown operation {unknown[0]!r} (known: {', '.join(NAMED)})")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 0):
        raise ValueError(f"jobs must be a non-negative integer (0: the cores), got {jobs!r}")
    for d in depths:  # refused here in one line, not as a failure of every job at that depth
        well.check_depth(d)


def broomstick_inputs(b: Broomstick) -> tuple:
    """The files a broomstick read, as its file names them: the well file, its survey (the record's) and the
    string file; those that exist (a resume's outputs may replace none of them)."""
    try:
        survey = json.loads(b.attrs.get("drilling", ""))["well"].get("survey")
    except (ValueError, TypeError, KeyError, AttributeError):
        survey = None
    return tuple(p for p in (b.attrs.get("well"), survey, b.attrs.get("string")) if isinstance(p, str) and
                 os.path.isfile(p))


def _check_cells(b: Broomstick, path: str) -> None:
    """A file's cells agree with themselves: every array of :data:`BROOM_KEYS` one number per cell, a complete
    cell solved (a finite hook load) or failed (its reason kept), an interrupted file's ``complete`` kept; else a
    ``ValueError`` before the file is touched (such a file had been 'finished' with nothing solved)."""
    shape = b.complete.shape
    wrong = [key for key in BROOM_KEYS if key not in b.data or b.data[key].shape != shape]
    if wrong:
        raise ValueError(f"{path}: a damaged broomstick file ({wrong[0]} is not one number per depth, operation "
                         f"and friction factor)")
    failed = np.zeros(shape, bool)
    for op, mu, d, _ in b.failures:
        failed[b.cell(op, mu, int(np.flatnonzero(b.depths == d)[0]))] = True
    empty = b.complete & ~np.isfinite(b.data["hook_load"]) & ~failed
    if empty.any() or (b.attrs.get("status") == "interrupted" and b.complete.all()):
        raise ValueError(f"{path}: a damaged broomstick file (cells marked complete hold no equilibrium and no "
                         f"reason it failed)")


def _carry(b: Broomstick, start: Broomstick) -> None:
    """``start``'s complete cells copied into ``b`` (the same cases, else a ``ValueError``)."""
    if not start.same_cases(b.depths, b.operations, b.mus):
        raise ValueError("the broomstick to start from has other depths, operations or friction factors")
    done = np.asarray(start.complete, bool)
    for key in b.data:
        if key in start.data:
            b.data[key][done] = np.asarray(start.data[key])[done]
        elif done.any():
            raise ValueError(f"the broomstick to start from has no {key!r}")
    b.complete[done] = True
    b.failures += list(start.failures)  # each a complete cell's (a failed depth is an answer, NaN)
    for case, t in start.elapsed.items():
        b.elapsed[case] = b.elapsed.get(case, 0.0) + t


def _collect(futures: dict, b: Broomstick, callback) -> None:
    """Each job's result filled into ``b`` as it ends (those ending together in the order submitted), then
    ``callback``; its ``idle()`` before each wait of at most 0.2 s, and before a job's error is raised (a
    SIGTERM to the process group ends the workers too: the interrupt, not their broken pool, is said)."""
    order = {f: n for n, f in enumerate(futures)}
    idle = getattr(callback, "idle", None)
    pending = set(futures)
    while pending:
        if idle is not None:
            idle()
        done, pending = wait(pending, timeout=None if idle is None else 0.2, return_when=FIRST_COMPLETED)
        for future in sorted(done, key=order.get):
            try:
                res = future.result()
            except BaseException:
                if idle is not None:
                    idle()
                raise
            op, mu, k = futures[future]
            b.fill(op, mu, k, res)
            if callback is not None:
                callback(b, (op, mu, k))


def broom_tasks(depths, cases) -> list:
    """``(operation, mu, depth index)``, one task a depth: each depth is a cold start, so the jobs need not be
    whole curves, and the deepest (slowest) first keeps every core busy to the end (3 curves on 2 cores left one
    idle for a third of the run)."""
    order = np.argsort(-np.asarray(depths, float), kind="stable")
    return [(op, mu, int(i)) for i in order for op, mu in cases]


def buckling_onsets(b: Broomstick) -> dict:
    """``{"sinusoidal_buckling": ..., "helical_buckling": ...}``: arrays ``(operation, friction)`` of the first bit
    depth (in the order of ``b.depths``) where the string's largest buckling ratio
    (:func:`rodcont.drilling.buckling_ratio`) reaches 1 (Dawson-Paslay) and sqrt(2) (Chen), linear between the
    depths; NaN where it does not."""
    from .trip import BUCKLING_EVENTS
    ratio, d = b.data["buckling_ratio"], b.depths
    out = {}
    for label, level in BUCKLING_EVENTS:
        at = np.full(ratio.shape[1:], np.nan)
        for i, j in np.ndindex(*at.shape):
            q = ratio[:, i, j]
            k = np.flatnonzero(q >= level)
            if k.size and k[0] == 0:
                at[i, j] = d[0]
            elif k.size and np.isfinite(q[k[0]]) and np.isfinite(q[k[0] - 1]):
                a = k[0] - 1
                at[i, j] = d[a] + (d[a + 1] - d[a]) * (level - q[a]) / (q[a + 1] - q[a])
            elif k.size:
                at[i, j] = d[k[0]]
        out[label] = at
    return out


def write_broomstick(b: Broomstick, path: str, meta: dict | None = None) -> None:
    """The broomstick as HDF5 (:func:`broomstick_image`, written whole beside ``path``, synced, renamed over it:
    :func:`rodcont.safeio.publish`)."""
    from ..safeio import publish
    publish(path, broomstick_image(b, meta))


def broomstick_image(b: Broomstick, meta: dict | None = None) -> bytes:
    """The bytes of the broomstick's HDF5 file: ``depth``, ``friction``, ``operations`` and one dataset per array
    of :class:`Broomstick` (``depth x operation x friction``), ``complete`` (bool) and ``failure`` (the reason
    a cell failed, empty where it did not), ``meta`` as attributes and ``status`` (``complete``, or
    ``interrupted`` while cells are missing). Built in memory, so that it and the plot can be published
    together (:class:`rodcont.safeio.Staged`)."""
    import io

    import h5py
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        f.attrs["kind"] = "broomstick"
        for key, v in (meta or {}).items():
            f.attrs[key] = v
        f.attrs["status"] = "complete" if b.complete.all() else "interrupted"
        f["depth"] = b.depths
        f["friction"] = np.asarray(b.mus)
        f["operations"] = np.array(b.operations, dtype=h5py.string_dtype())
        for key, v in b.data.items():
            f[key] = v
        f["complete"] = np.asarray(b.complete, bool)
        f["failure"] = np.array(_failure_cells(b), dtype=h5py.string_dtype())
        if "buckling_ratio" in b.data:
            for key, v in buckling_onsets(b).items():  # (operation x friction) bit depths, NaN: none
                f[key] = v
    return buf.getvalue()


def _failure_cells(b: Broomstick) -> np.ndarray:
    """The reasons of ``b.failures`` on the broomstick's cells (``""`` where none)."""
    cells = np.full(b.complete.shape, "", dtype=object)
    for op, mu, d, why in b.failures:
        k = np.flatnonzero(b.depths == d)
        if k.size:
            cells[b.cell(op, mu, int(k[0]))] = why
    return cells


def read_broomstick(path: str) -> Broomstick:
    """The broomstick a file of :func:`write_broomstick` holds (its arrays, depths, operations, friction factors,
    ``complete`` cells, failures and attributes); a ``ValueError`` (one line) for another file."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("kind") != "broomstick":
                raise ValueError(f"{path}: not a broomstick file (rodcont broomstick --out)")
            ops = tuple(_text(v) for v in f["operations"][()])
            skip = {"depth", "friction", "operations", "sinusoidal_buckling", "helical_buckling", "complete",
                    "failure"}
            data = {key: np.asarray(f[key][()], float) for key in f if key not in skip}
            b = Broomstick(np.asarray(f["depth"][()], float), ops, tuple(float(m) for m in f["friction"][()]), data,
                           attrs={key: _text(v) for key, v in f.attrs.items()})
            if "complete" in f:  # files before the resume: whole
                b.complete = np.asarray(f["complete"][()], bool)
                for at in zip(*np.nonzero(np.vectorize(len)(f["failure"][()].astype(object)))):
                    why = _text(f["failure"][at])
                    b.failures.append((ops[at[1]], b.mus[at[2]], float(b.depths[at[0]]), why))
            if b.complete.shape != (b.depths.size, len(ops), len(b.mus)):
                raise ValueError(f"{path}: a damaged broomstick file (its cells do not match its depths)")
            return b
    except (OSError, KeyError, TypeError, IndexError, RuntimeError) as exc:  # RuntimeError: h5py's damaged links
        raise ValueError(f"{path}: not a readable broomstick file ({type(exc).__name__}: {exc})") from None


def _text(v):
    """An HDF5 string (bytes or str) as ``str``; anything else as it is."""
    return v.decode() if isinstance(v, bytes) else (str(v) if isinstance(v, np.str_) else v)


def is_broomstick_file(path: str) -> bool:
    """Whether ``path`` is an HDF5 file of :func:`write_broomstick` (False for anything else, unreadable too)."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("kind") == "broomstick"
    except (OSError, ValueError, RuntimeError):
        return False


def broomstick_figure(b: Broomstick, title: str | None = None) -> tuple:
    """``(figure, markers)``: hook load (kN) against bit depth, one line per operation and friction factor, the
    soft string dashed; the rotating surface torque (kN m) against depth beside it; the buckling onsets
    (:func:`buckling_onsets`) marked on each hook-load curve, ``markers`` ``(label, operation, mu, hook_load N,
    depth m)``. Matplotlib's object interface (no pyplot: the caller's backend is left alone)."""
    from ..plots import _figure
    fig = _figure(11, 6)
    ax = fig.add_subplot(1, 2, 1)
    axt = fig.add_subplot(1, 2, 2, sharey=ax)
    colours = {"pick-up": "tab:red", "slack-off": "tab:blue", "rotate": "tab:green"}
    for i, op in enumerate(b.operations):
        for j, mu in enumerate(b.mus):
            alpha = 0.4 + 0.6 * (j + 1) / len(b.mus)
            c = colours.get(op, "k")
            ax.plot(b.hook_load[:, i, j] / 1e3, b.depths, color=c, alpha=alpha, label=f"{op}, mu {mu:g}")
            ax.plot(b.soft_hook_load[:, i, j] / 1e3, b.depths, color=c, alpha=alpha, ls="--")
            if op == "rotate":
                axt.plot(b.surface_torque[:, i, j] / 1e3, b.depths, color=c, alpha=alpha, label=f"mu {mu:g}")
                axt.plot(b.soft_surface_torque[:, i, j] / 1e3, b.depths, color=c, alpha=alpha, ls="--")
    markers = _mark_onsets(b, ax)
    ax.set_xlabel("hook load (kN)")
    ax.set_ylabel("bit measured depth (m)")
    ax.invert_yaxis()
    ax.legend(fontsize=7, title="stiff string; soft string dashed")
    axt.set_xlabel("surface torque, rotating off bottom (kN m)")
    if axt.lines:
        axt.legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig, markers


def _mark_onsets(b: Broomstick, ax) -> list:
    """Where the string first buckles along each curve: o sinusoidal, x helical (the markers drawn)."""
    markers = []
    if "buckling_ratio" not in b.data:
        return markers
    for (label, at), marker in zip(buckling_onsets(b).items(), ("o", "x")):
        for i, j in np.ndindex(*at.shape):
            if np.isfinite(at[i, j]):
                H = np.interp(at[i, j], b.depths, b.hook_load[:, i, j]) if b.depths[-1] > b.depths[0] else \
                    np.interp(at[i, j], b.depths[::-1], b.hook_load[::-1, i, j])
                ax.plot([H / 1e3], [at[i, j]], marker=marker, color="k", ms=6, ls="none",
                        label=label.replace("_", " ") if not any(m[0] == label for m in markers) else None)
                markers.append((label, b.operations[i], b.mus[j], float(H), float(at[i, j])))
    return markers


def plot_broomstick(b: Broomstick, path: str, title: str | None = None) -> list:
    """:func:`broomstick_figure` written to ``path`` as PNG (atomically, :func:`rodcont.plots.save_figure`).
    Returns the markers drawn: ``(label, operation, mu, hook_load N, depth m)``."""
    from ..plots import save_figure
    fig, markers = broomstick_figure(b, title)
    save_figure(fig, path, dpi=120)
    return markers


def broomstick_picture(b: Broomstick, path: str, title: str | None = None) -> tuple:
    """``(bytes, markers)``: :func:`broomstick_figure` rendered as :func:`plot_broomstick` writes it to ``path``
    (the format of its suffix when matplotlib writes it, else PNG), kept in memory to be published with the
    broomstick's file (:class:`rodcont.safeio.Staged`)."""
    from ..plots import rendered
    fig, markers = broomstick_figure(b, title)
    return rendered(fig, path, dpi=120), markers
