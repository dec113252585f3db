"""The broomstick: hook load against bit depth for pick-up, slack-off and rotating off bottom, one curve per
friction factor, the soft-string estimate beside each, and the surface torque against depth.

Each ``(operation, friction factor)`` is one job (:func:`broom_job`, a plain top-level function) on any
``concurrent.futures`` executor, the default a local process pool as :func:`rodcont.drivers.sweep.sweep` uses;
the broomstick submits one job a depth (:func:`broom_tasks`: each depth is its own cold start of
:func:`rodcont.drilling.torque_and_drag`, so the split changes no answer), the deepest first. A depth that
fails is stored as NaN with its reason; the others go on.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..blas import with_one_blas_thread

OPERATIONS = ("pick-up", "slack-off", "rotate")


@with_one_blas_thread
def broom_job(well, string, depths, operation: str, mu: float, options: dict) -> dict:
    """One curve: the stiff and the soft string at every depth for ``operation`` and ``mu``."""
    from ..drilling import buckling_ratio, soft_string, torque_and_drag
    n = len(depths)
    out = {key: np.full(n, np.nan) for key in ("hook_load", "surface_torque", "soft_hook_load",
                                               "soft_surface_torque", "side_force", "error", "N", "buckling_ratio",
                                               "max_compression")}
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
    ``[(operation, mu, depth, reason)]``, ``elapsed`` (s) per job."""

    depths: np.ndarray
    operations: tuple
    mus: tuple
    data: dict
    failures: list = field(default_factory=list)
    elapsed: dict = field(default_factory=dict)

    def __getattr__(self, name):
        data = self.__dict__.get("data", {})
        if name in data:
            return data[name]
        raise AttributeError(name)


def broomstick(well, string, depths, mus, operations=OPERATIONS, *, executor: Executor | None = None,
               jobs: int | None = None, **options) -> Broomstick:
    """The broomstick of ``string`` in ``well`` at ``depths`` (m, bit MD) for each friction factor of ``mus``
    and each operation; ``options`` go to :func:`rodcont.drilling.torque_and_drag` (``N_max``, ``max_error``)."""
    from .sweep import _worker_init
    depths = np.asarray(depths, float)
    mus = [float(mu) for mu in mus]
    for what, values in (("friction factor", mus), ("operation", list(operations))):
        twice = [v for v in values if values.count(v) > 1]
        if twice:  # one curve each: a second copy's cells were never filled (uninitialised numbers printed)
            raise ValueError(f"the {what} {twice[0]} is given twice: give each once")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 0):
        raise ValueError(f"jobs must be a non-negative integer (0: the cores), got {jobs!r}")
    for d in depths:  # refused here in one line, not as a failure of every job at that depth
        well.check_depth(d)
    cases = [(op, mu) for op in operations for mu in mus]
    tasks = broom_tasks(depths, cases)
    own = executor is None
    if own:
        jobs = jobs or os.cpu_count() or 1
        executor = ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), initializer=_worker_init)
    try:
        futures = {executor.submit(broom_job, well, string, depths[i:i + 1], op, mu, options): (op, mu, i)
                   for op, mu, i in tasks}
        done = {futures[f]: f.result() for f in futures}
    finally:
        if own:
            executor.shutdown(wait=True, cancel_futures=True)
    shape = (depths.size, len(operations), len(mus))
    data = {key: np.empty(shape) for key in next(iter(done.values())) if key not in ("failures", "elapsed")}
    failures, elapsed = [], {case: 0.0 for case in cases}
    for (op, mu, k), res in sorted(done.items(), key=lambda item: item[0][2]):
        i, j = list(operations).index(op), list(mus).index(mu)
        for key in data:
            data[key][k, i, j] = res[key][0]
        failures += [(op, mu, d, why) for d, why in res["failures"]]
        elapsed[(op, mu)] += res["elapsed"]
    return Broomstick(depths, tuple(operations), tuple(float(m) for m in mus), data, failures, elapsed)


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
    of :class:`Broomstick` (``depth x operation x friction``), ``meta`` as attributes. Built in memory, so that
    it and the plot can be published together (:class:`rodcont.safeio.Staged`)."""
    import io

    import h5py
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        f.attrs["kind"] = "broomstick"
        for key, v in (meta or {}).items():
            f.attrs[key] = v
        f["depth"] = b.depths
        f["friction"] = np.asarray(b.mus)
        f["operations"] = np.array(b.operations, dtype=h5py.string_dtype())
        for key, v in b.data.items():
            f[key] = v
        if "buckling_ratio" in b.data:
            for key, v in buckling_onsets(b).items():  # (operation x friction) bit depths, NaN: none
                f[key] = v
    return buf.getvalue()


def read_broomstick(path: str) -> Broomstick:
    """The broomstick a file of :func:`write_broomstick` holds (its arrays, depths, operations, friction factors);
    a ``ValueError`` (one line) for another file."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("kind") != "broomstick":
                raise ValueError(f"{path}: not a broomstick file (rodcont broomstick --out)")
            ops = tuple(v.decode() if isinstance(v, bytes) else str(v) for v in f["operations"][()])
            skip = {"depth", "friction", "operations", "sinusoidal_buckling", "helical_buckling"}
            data = {key: np.asarray(f[key][()], float) for key in f if key not in skip}
            return Broomstick(np.asarray(f["depth"][()], float), ops,
                              tuple(float(m) for m in f["friction"][()]), data)
    except (OSError, KeyError) as exc:
        raise ValueError(f"{path}: not a readable broomstick file ({type(exc).__name__}: {exc})") from None


def is_broomstick_file(path: str) -> bool:
    """Whether ``path`` is an HDF5 file of :func:`write_broomstick` (False for anything else, unreadable too)."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("kind") == "broomstick"
    except (OSError, ValueError):
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
