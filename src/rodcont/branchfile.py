"""HDF5 branch files: complete at every moment, never written in place, checked when read.

Layout (names are read by other tools; keep them)::

    /                      attrs: rodcont_version, kind (branch | fold_curve | diagram), gamma, T,
                                  w, EI, GJ, EA, L, N, k, param, weight_direction,
                                  min_alignment_guard, max_error, stop_reason, status (the
                                  rodcont.result.Status of stop_reason: bound, validity_guard,
                                  accuracy_guard, event, interrupted, ...; status_first for the
                                  first end of a fold curve), settings (JSON; continuation_settings,
                                  adaptive_settings: the tracker's and the adaptive loop's),
                                  missed_crossings (JSON, when any: [value before, value after,
                                  unstable modes before, after] of eigenvalue crossings that no
                                  located fold or branch point accounts for)
    /branch/phi_L          (n,)   imposed end rotation, rad
    /branch/stretch        (n,)   (l - L) / L
    /branch/torque         (n,)   axial moment GJ u3
    /branch/l0             (n,)   unstressed length inside the span
    /branch/helical_waves  (n,)   int
    /branch/unstable_modes (n,)   unstable modes under the trace's controls (-1: not counted)
    /branch/min_alignment  (n,)   min over S of d3 . K3
    /branch/arclength      (n,)   pseudo-arclength of the tracker
    /branch/defect         (n,)   relative residual between collocation points (indicator)
    /branch/error          (n,)   estimated error of the outputs and the centreline (halved mesh)
    /branch/dphi_ds        (n,)   parameter component of the unit tangent (0 at a fold)
    /branch/kind           (n,)   start, regular, fold, branch_point, forced, bound, event:<label>
                                  (files written before labels: event:<whole sentence>)
    /branch/located        (n,)   1, or 0 for a special point bracketed but not located
    /branch/<param>        (n,)   the continued parameter, when it is not phi_L
    /branch/coefficients   (n, m) unknown vector x of each point, NaN-padded (meshes differ)
    /branch/breakpoints    (n, N+1) the partition each point lives on, NaN-padded
    /branch/tangent        (n, m+1) unit tangent (x part, then parameter), float32, NaN-padded
    /folds/phi_L, stretch, torque, l0, waves_before, waves_after, index, located,
           unstable_before, unstable_after (the two sides of the fold: smaller stretch first)
    /branch_points/index, phi_L, stretch
    /special_points/index, kind, label, located, value, message
                           every special point: kind (start, fold, branch_point, forced, bound,
                           event), label (F1, BP1, P1, an event's label), the parameter's value,
                           the message (an event's sentence, why a bound stopped)
    /mesh/breakpoints      (N+1,) the first partition; attrs: k, orders, fields, layout

Inside a conduit (``trace --conduit``; root attribute ``conduit``: the wall's
clearance and contact law, :class:`rodcont.contact.Wall`), the branch table
gains ``min_gap`` (min over S of c - |Delta|), ``side_force`` (the integral
of the wall pressure) and ``contact_zones`` (their number), and::

    /contact               attrs: clearance, eps, force_scale, contact_level, law
    /contact/S             (s,)   sample points of the span
    /contact/pressure      (n, s) wall force per unit S at the samples, float32
    /contact/gap           (n, s) c - |Delta|, float32
    /contact/axial_force   (n, s) F . d3, float32
    /contact/torque        (n, s) m, float32
    /contact/zones         (z, 4) point, S_start, S_end, force of every contact zone
                                  (S_start == S_end: a point contact)

``/contact`` is written when the run ends (also when it is interrupted: its rows are computed
as the points are recorded, so closing the file does not wait for them).

A diagram file holds ``/branches/<j>/`` with the ``branch``, ``folds``,
``branch_points`` and ``special_points`` groups of each branch (and its end reasons
as attributes: ``stop_reason_first``, ``stop_reason``, ``status_first``, ``status``,
``missed_crossings`` and ``unlocated`` when any), and a top-level ``/folds`` table of
every fold with a ``branch`` column.

A user's problem (``kind = "bvp"``, :mod:`rodcont.bvp`) has the same publication, checksum and lock,
the root attributes of its problem (``problem``, ``param``, ``fields``, ``orders``, ``params``, ``free``,
``held``, ``interval``, ``k``, ``scales``, ``outputs``: JSON where they are lists), one ``/branch``
column per name of its table, and ``/special_points``, ``/folds``, ``/branch_points``; it reads as a
:class:`rodcont.bvp.BVPResult`.

Reading: :func:`load_branch` returns a :class:`rodcont.branch.Branch`, the type the drivers
return (files written before the status and the special points were stored read too: the
status is inferred from ``stop_reason``, the labels from the kinds).

Safety. The file is built in memory (HDF5 core driver) and *published*:
written whole to a temporary file beside the target, flushed to disk, and
renamed over it (atomic on POSIX). A reader, a crash or a full disk therefore
only ever sees the previous complete version or the new one. Each published
file starts with a 512-byte user block (ignored by HDF5 readers: h5py,
h5dump, MATLAB) holding a magic string and a BLAKE2 checksum of the rest, so
a damaged file is rejected before HDF5 reads a byte of it; a file without it reads with
``unverified = True`` (:class:`UnverifiedFileWarning`). One writer per target: a lock
file taken with ``flock`` refuses a second writer. No output is one of the command's
inputs under any name (:func:`check_writable`; :func:`rodcont.safeio.command_inputs`
collects them).
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import struct
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

from . import __version__
from .branch import FOLD_FIELDS, Branch
from .result import Table

SCALARS = ("phi_L", "stretch", "torque", "l0", "min_alignment", "arclength", "defect", "error", "dphi_ds")
#: the loaded-branch type (a Branch read from a file is a Branch)
BranchData = Branch
MAGIC = b"RODCONT-BRANCH-FILE\x00"


def kept(i: int, kind: str, store_every: int) -> tuple[bool, bool]:
    """Whether point ``i`` of a branch thinned with ``store_every`` keeps its solution and its tangent.

    Solutions: every ``store_every``-th point's and those of the folds, branch points, starts and ends
    (events); tangents: the special points' only (a restart elsewhere starts along the parameter). The
    last point keeps both whatever its index (the writer and :class:`rodcont.branch.Branch` see to it).
    """
    if store_every <= 1:
        return True, True
    special = str(kind) not in ("regular", "forced")
    return special or i % store_every == 0, special
HEADER = 512


class BranchFileError(Exception):
    """A file that cannot be read or written as a branch file (message says why, in one line)."""


class UnverifiedFileWarning(UserWarning):
    """A branch file read without rodcont's checksum header: written by another program, or rewritten by
    hand (h5py keeps no user block), so nothing vouches that its tables are what rodcont wrote (a deleted
    fold table reads as no folds). The loaded branch says so: ``unverified = True``."""


# --------------------------------------------------------------------------
# Paths: distinct inputs and outputs, locks, atomic publication
# --------------------------------------------------------------------------
def same_file(a: str, b: str) -> bool:
    """Do two paths name the same file (symlinks, hard links, ``//``, ``/proc/self/cwd``...)?"""
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def side_file(path: str, kind: str) -> str:
    """A hidden file beside the (resolved) target for ``kind`` (``lock``, ``tmp``): a short name
    (a hash of the target's), so a target name of any allowed length has one."""
    real = os.path.realpath(path)
    tag = hashlib.blake2b(os.path.basename(real).encode("utf-8", "surrogateescape"), digest_size=8).hexdigest()
    extra = f".{os.getpid()}" if kind == "tmp" else ""
    return os.path.join(os.path.dirname(real), f".rodcont-{tag}{extra}.{kind}")


def check_regular_target(path: str, what: str = "--out") -> None:
    """Refuse an output that exists (through any link) and is not a regular file: a device, a FIFO,
    a socket, a directory (rodcont writes a new file and renames it over the target: a device
    node would be replaced)."""
    if path.endswith(os.sep):
        raise BranchFileError(f"cannot write {path}: a directory name (it ends with {os.sep})")
    if len(os.path.basename(path).encode("utf-8", "surrogateescape")) > 255:
        raise BranchFileError(f"cannot write {path}: file name too long")
    if os.path.lexists(path):
        real = os.path.realpath(path)
        if os.path.isdir(real):
            raise BranchFileError(f"cannot write {path}: it is a directory")
        if os.path.exists(real) and not os.path.isfile(real):
            raise BranchFileError(f"cannot write {path}: not a regular file (a device, a pipe, a socket)")


def check_writable(path: str, inputs=(), what: str = "--out") -> str:
    """An output path that can be written: a name, not an input (as a file, through any link), a
    regular file or nothing, in a directory that exists and is writable. Returns the path; raises
    ``BranchFileError`` (``TypeError`` for what is not a name; a ``pathlib.Path`` is one, returned as str).
    (An existing file is not refused here: see :func:`check_output`.)"""
    path = os.fspath(path) if isinstance(path, os.PathLike) else path
    if not isinstance(path, str):
        raise TypeError(f"{what} must be a file name, got {path!r}")
    if not path.strip():
        raise BranchFileError(f"{what} needs a file name")
    for src in inputs:
        if src is not None and same_file(path, src):
            raise BranchFileError(f"{what} {path} is the input file {src}: write to another file")
    check_regular_target(path, what)
    d = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(d):
        raise BranchFileError(f"cannot write {path}: directory {d} does not exist")
    if os.path.isdir(path):
        raise BranchFileError(f"cannot write {path}: it is a directory")
    if not os.access(d, os.W_OK | os.X_OK):
        raise BranchFileError(f"cannot write {path}: directory {d} is not writable")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise BranchFileError(f"cannot write {path}: permission denied")
    return path


def check_output(path: str, inputs=(), overwrite: bool = False, what: str = "--out") -> str:
    """:func:`check_writable`, and an existing file only with ``overwrite`` (checked before any work)."""
    path = check_writable(path, inputs, what)
    if os.path.lexists(path) and not overwrite:
        raise BranchFileError(f"{path} exists: choose another {what} or add --overwrite to replace it")
    return path


class OutputLock:
    """``flock`` on ``.<name>.lock`` beside the (resolved) target: one writer per file."""

    def __init__(self, path: str):
        import fcntl
        self.lock_path = side_file(path, "lock")
        try:
            self.fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise BranchFileError(f"cannot write {path}: {exc.strerror}") from None
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise BranchFileError(f"{path} is being written by another rodcont process: "
                                  f"wait for it or choose another output") from None

    def release(self) -> None:
        if self.fd is not None:
            try:
                os.unlink(self.lock_path)
            except OSError:
                pass
            os.close(self.fd)
            self.fd = None


def _header(image: bytes) -> bytes:
    digest = hashlib.blake2b(image, digest_size=32).digest()
    head = MAGIC + struct.pack("<IQ", 1, len(image)) + digest
    return head + b"\0" * (HEADER - len(head))


def publish(path: str, image: bytes) -> None:
    """Write ``header + image`` to a temporary file beside ``path``, sync it, rename it over ``path``."""
    real = os.path.realpath(path)
    d = os.path.dirname(real)
    tmp = side_file(path, "tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            # header and image written one after the other: ``header + image`` would copy the image, a
            # whole branch file (430 MB for a 2100-point trace at 60 000 unknowns) once more in memory
            for part in (_header(image), image):
                view = memoryview(part)
                while view:
                    n = os.write(fd, view)
                    view = view[n:]
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, real)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        why = {errno.ENOSPC: "no space left on the device", errno.EFBIG: "file size limit exceeded",
               errno.EDQUOT: "disk quota exceeded"}.get(exc.errno, exc.strerror or str(exc))
        raise BranchFileError(f"cannot write {path}: {why}") from None
    try:
        dfd = os.open(d, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------
def _h5py():
    import h5py
    return h5py


class _Group:
    """One branch's ``branch``, ``folds`` and ``branch_points`` groups inside the in-memory file."""

    def __init__(self, root, extra_columns: tuple, attrs: dict | None = None):
        h5py = _h5py()
        self.root = root
        for key, val in (attrs or {}).items():
            root.attrs[key] = val
        g = root.create_group("branch")
        self.columns = SCALARS + tuple(c for c in dict.fromkeys(extra_columns) if c not in SCALARS)
        for name in self.columns:
            g.create_dataset(name, (0,), maxshape=(None,), dtype="f8", chunks=(256,), compression="gzip")
        g.create_dataset("helical_waves", (0,), maxshape=(None,), dtype="i4", chunks=(256,), compression="gzip")
        g.create_dataset("unstable_modes", (0,), maxshape=(None,), dtype="i4", chunks=(256,), compression="gzip")
        g.create_dataset("located", (0,), maxshape=(None,), dtype="i1", chunks=(256,), compression="gzip")
        g.create_dataset("kind", (0,), maxshape=(None,), dtype=h5py.string_dtype(), chunks=(256,))
        self.width = 0
        self.nb = 0
        self.n = 0
        self.g = g
        self.store_every = 1
        self._pending = None  # (row, x, tangent) of the last point whose solution was not stored
        self._queue: list[dict] = []  # points added but not yet written (see drain)
        self._special = None  # the tables set_special last wrote

    def _matrix(self, name, width, dtype):
        g = self.g
        if name not in g:  # gzip level 1: the Gamma = 1 trace's file 1 % larger than at 6, written in 2/3 the time
            g.create_dataset(name, (self.n, width), maxshape=(None, None), dtype=dtype, fillvalue=np.nan,
                             chunks=(16, max(min(width, 4096), 1)), compression="gzip", compression_opts=1,
                             shuffle=True)
        ds = g[name]
        if ds.shape[1] < width:
            ds.resize(width, axis=1)
        return ds

    def add(self, row: dict, kind: str, located: bool, x, tangent, breakpoints) -> None:
        """Queue one point; :meth:`drain` writes the queue (one resize and one write per dataset:
        per-point writes into HDF5 cost more than the continuation step that made the point)."""
        i = self.n
        store, store_tangent = kept(i, kind, self.store_every)
        x, tangent = np.array(x, dtype=float), np.array(tangent, dtype=float)
        self._queue.append(dict(
            scalars=[float(row[name]) for name in self.columns],
            helical_waves=int(row["helical_waves"]), located=int(bool(located)),
            unstable_modes=int(row.get("unstable_modes", -1)), kind=str(kind),
            coefficients=x, tangent=tangent, breakpoints=np.array(breakpoints, dtype=float),
            keep=dict(coefficients=store, tangent=store_tangent, breakpoints=True)))
        self._pending = None if store else (i, x, tangent)
        self.n += 1

    def drain(self) -> None:
        """Write the queued points into the in-memory file."""
        q, self._queue = self._queue, []
        if not q:
            return
        g, i0, m = self.g, self.n - len(q), len(q)
        scalars = np.array([r["scalars"] for r in q], dtype=float).reshape(m, len(self.columns))
        for j, name in enumerate(self.columns):
            ds = g[name]
            ds.resize(i0 + m, axis=0)
            ds[i0:] = scalars[:, j]
        for name, dtype in (("helical_waves", "i4"), ("located", "i1"), ("unstable_modes", "i4")):
            ds = g[name]
            ds.resize(i0 + m, axis=0)
            ds[i0:] = np.array([r[name] for r in q], dtype=dtype)
        ds = g["kind"]
        ds.resize(i0 + m, axis=0)
        ds[i0:] = np.array([r["kind"] for r in q], dtype=object)
        for name, dtype in (("coefficients", "f8"), ("tangent", "f4"), ("breakpoints", "f8")):
            ds = self._matrix(name, max(r[name].size for r in q), dtype)
            ds.resize(i0 + m, axis=0)
            block = np.full((m, ds.shape[1]), np.nan)
            for k, r in enumerate(q):
                if r["keep"][name]:
                    block[k, :r[name].size] = r[name]
            ds[i0:, :] = block.astype(dtype)

    def fill_pending(self) -> None:
        """Store the solution of the last point if it was thinned out (so the file always ends restartable)."""
        self.drain()
        if self._pending is not None:
            i, x, t = self._pending
            self.g["coefficients"][i, :x.size] = x
            self._matrix("tangent", t.size, "f4")[i, :t.size] = t
            self._pending = None

    def correct(self, name: str, i: int, value) -> None:
        """Change the value of column ``name`` at point ``i`` (queued or written)."""
        q0 = self.n - len(self._queue)
        if i >= q0:
            r = self._queue[i - q0]
            if name in r:
                r[name] = value
            else:
                r["scalars"][self.columns.index(name)] = float(value)
        else:
            self.g[name][i] = value

    def set_special(self, folds: list[dict], branch_points: list[dict], special: list | None = None) -> None:
        """Rewrite the fold, branch-point and special-point tables (waves and sides are known only as the
        branch grows); tables equal to those last written are left as they are."""
        tables = self._special_tables(folds, branch_points, special)
        last = self._special or {}
        h5py = _h5py()
        for group in ("special_points", "folds", "branch_points"):
            if group in tables and group in last and group in self.root and _same_columns(last[group], tables[group]):
                continue  # each publication rewrote the same tables (15 datasets)
            if group in self.root:
                del self.root[group]
            if group not in tables:
                continue
            g = self.root.create_group(group)
            for name, data in tables[group].items():
                if data.dtype == object:
                    g.create_dataset(name, data=data, dtype=h5py.string_dtype())
                else:
                    g.create_dataset(name, data=data)
        self._special = tables

    @staticmethod
    def _special_tables(folds: list[dict], branch_points: list[dict], special: list | None) -> dict:
        """The columns :meth:`set_special` writes, group by group, in the order it creates them."""
        tables = {}
        if special is not None:
            sp = dict(index=np.array([p.index for p in special], dtype="i8"),
                      located=np.array([p.located for p in special], dtype="i1"),
                      value=np.array([p.value for p in special], dtype="f8"))
            for name in ("kind", "label", "message"):
                sp[name] = np.array([getattr(p, name) for p in special], dtype=object)
            tables["special_points"] = sp
        tables["folds"] = {name: np.array([f[name] for f in folds], dtype="f8" if name in (
            "phi_L", "stretch", "torque", "l0") else "i8").reshape(-1) for name in FOLD_FIELDS}
        tables["branch_points"] = {name: np.array([b[name] for b in branch_points], dtype="i8" if name == "index"
                                                  else "f8").reshape(-1) for name in ("index", "phi_L", "stretch")}
        return tables


def _same_columns(a: dict, b: dict) -> bool:
    """Whether two tables hold the same columns, dtypes and values (NaN equal to NaN)."""
    if list(a) != list(b):
        return False
    for name, x in a.items():
        y = b[name]
        if x.dtype != y.dtype or x.shape != y.shape:
            return False
        if not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
            return False
    return True


class BranchWriter:
    """A branch file (or a diagram file of several branches) built in memory and published.

    ``meta``: root attributes. ``group(path)`` opens a branch group (``"/"`` for
    a trace file, ``"branches/<j>"`` in a diagram). ``flush()`` publishes the
    file now; ``maybe_flush()`` when ``interval`` seconds have passed (the
    interval grows if publishing gets slow, so that at most about a tenth of
    the time goes into it). Nothing is written to ``path`` before the first
    point: a run that finds none leaves the target as it was.
    """

    def __init__(self, path: str, meta: dict, interval: float = 1.0, lock: bool = True, store_every: int = 1,
                 min_points: int = 1):
        h5py = _h5py()
        self.path = path
        self.store_every = int(store_every)
        self.min_points = int(min_points)  # publish nothing before this many points (a lone start is no result)
        self.lock = OutputLock(path) if lock else None
        self.f = h5py.File(f"rodcont-{id(self)}-{time.monotonic_ns()}", "w", driver="core", backing_store=False)
        self.f.attrs["rodcont_version"] = __version__
        self.f.attrs["stop_reason"] = "running"
        self.f.attrs["status"] = "running"
        self.f.attrs["store_every"] = self.store_every
        for key, val in meta.items():
            self.f.attrs[key] = _attr(val)
        self.groups: dict[str, _Group] = {}
        self.interval = interval
        self.last = time.monotonic()
        self.flush_time = 0.0
        self.points = 0
        self.published = 0
        self.closed = False

    def group(self, where: str = "/", extra_columns: tuple = (), attrs: dict | None = None) -> _Group:
        if where not in self.groups:
            root = self.f if where == "/" else self.f.require_group(where)
            self.groups[where] = _Group(root, extra_columns, {k: _attr(v) for k, v in (attrs or {}).items()})
            self.groups[where].store_every = self.store_every
        return self.groups[where]

    def set_attr(self, key, value, where: str = "/") -> None:
        (self.f if where == "/" else self.f[where]).attrs[key] = _attr(value)

    def add_point(self, grp: _Group, row, kind, located, x, tangent, breakpoints) -> None:
        grp.add(row, kind, located, x, tangent, breakpoints)
        self.points += 1

    def flush(self) -> None:
        """Publish the file as it is now (only once it holds a point)."""
        if self.points < max(self.min_points, 1) or self.closed:
            return
        t = time.monotonic()
        for grp in self.groups.values():
            grp.drain()
        self.f.flush()
        publish(self.path, self.f.id.get_file_image())
        self.published = self.points
        self.flush_time = time.monotonic() - t
        self.last = time.monotonic()
        self.interval = max(self.interval, 10.0 * self.flush_time)

    def due(self) -> bool:
        """Is a publication due (the first point, or ``interval`` seconds since the last one)?"""
        return self.published == 0 or time.monotonic() - self.last >= self.interval

    def maybe_flush(self) -> None:
        if self.due():
            self.flush()

    def close(self, stop_reason: str | None = None, status=None) -> None:
        """Set the stop reason (and its status), publish (if any point) and release the lock; idempotent."""
        if self.closed:
            return
        try:
            if stop_reason is not None:
                self.f.attrs["stop_reason"] = stop_reason
            if status is not None:
                self.f.attrs["status"] = str(status)
            for grp in self.groups.values():
                grp.fill_pending()  # a finished (or interrupted) file ends on a restartable point
            self.flush()
        finally:
            # whatever happened (a full disk), the memory file is dropped and the lock released:
            # the target keeps its last published version
            self.closed = True
            try:
                self.f.close()
            except (OSError, RuntimeError, ValueError):  # an in-memory file: nothing on disk to lose
                pass
            if self.lock is not None:
                self.lock.release()


def _attr(v):
    if isinstance(v, (dict, list)) and not isinstance(v, np.ndarray):
        return json.dumps(v, default=float)
    if v is None:
        return "none"
    return v


# --------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------
@dataclass
class DiagramData:
    """A diagram file: its branches (each a :class:`rodcont.branch.Branch`) and the fold table of all
    of them (a :class:`rodcont.result.Table` with a ``branch`` column)."""

    path: str
    attrs: dict
    branches: list
    folds: Table
    unverified: bool = False  # read without rodcont's checksum (UnverifiedFileWarning)

    def __len__(self) -> int:
        return len(self.branches)


def _check_file(path: str) -> bool:
    """Refuse a file that is not there, not a file, or damaged, before HDF5 reads it; True when its
    checksum vouches for it.

    A file with rodcont's header must match its checksum. A file without one (written by
    another program, or edited in place) is first opened in a child process: HDF5 can
    crash on a damaged file, and a crash there is a refusal here, not a crash of ours;
    it is read, unverified (:class:`UnverifiedFileWarning`).
    """
    if not os.path.exists(path):
        raise BranchFileError(f"{path}: no such file")
    if not os.path.isfile(path):
        raise BranchFileError(f"{path}: not a file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(HEADER)
            if head.startswith(MAGIC) and len(head) == HEADER:
                _, length = struct.unpack("<IQ", head[len(MAGIC):len(MAGIC) + 12])
                digest = head[len(MAGIC) + 12:len(MAGIC) + 44]
                image = fh.read()
                if len(image) != length or hashlib.blake2b(image, digest_size=32).digest() != digest:
                    raise BranchFileError(f"{path}: damaged branch file (checksum mismatch: the file was "
                                          f"changed or truncated after rodcont wrote it)")
                return True
    except OSError as exc:
        raise BranchFileError(f"{path}: cannot read ({exc.strerror})") from None
    code = ("import sys, h5py\nf = h5py.File(sys.argv[1], 'r')\n"
            "def visit(name, obj):\n    obj.attrs.keys()\n    [obj.attrs[k] for k in obj.attrs]\n"
            "    if isinstance(obj, h5py.Dataset):\n        obj[()]\n"
            "f.visititems(visit)\n[f.attrs[k] for k in f.attrs]\n")
    try:
        r = subprocess.run([sys.executable, "-c", code, path], capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        raise BranchFileError(f"{path}: cannot be checked (reading it took too long)") from None
    if r.returncode != 0:
        kind = "crashes HDF5" if r.returncode < 0 else "not a readable HDF5 file"
        raise BranchFileError(f"{path}: {kind}")
    return False


def _plain(v):
    if isinstance(v, bytes):
        return v.decode("utf-8", errors="replace")
    if isinstance(v, np.generic):
        return v.item()
    return v


_ROOT_NUMBERS = {"EI": "positive", "GJ": "positive", "EA": "positive", "L": "positive", "w": "nonnegative",
                 "gamma": "finite", "k": "k"}


def _validate_attrs(path: str, attrs: dict) -> dict:
    if attrs.get("w") == 0 and isinstance(attrs.get("gamma"), float) and math.isnan(attrs["gamma"]):
        attrs = dict(attrs, gamma=0.0, gamma_undefined=True)  # weightless: the tension T is the load
    for key, rule in _ROOT_NUMBERS.items():
        if key not in attrs:
            raise BranchFileError(f"{path}: not a rodcont branch file (attribute {key} missing)")
        v = attrs[key]
        if isinstance(v, (bool, str, bytes)) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BranchFileError(f"{path}: damaged branch file (attribute {key} = {v!r} is not a finite number)")
        if rule == "positive" and v <= 0 or rule == "nonnegative" and v < 0:
            raise BranchFileError(f"{path}: damaged branch file (attribute {key} = {v!r} out of range)")
        if rule == "k" and not (float(v).is_integer() and 1 <= v <= 7):
            raise BranchFileError(f"{path}: damaged branch file (k = {v!r} is not an integer in 1..7)")
    wd = np.asarray(attrs.get("weight_direction", (0.0, 0.0, -1.0)))
    if wd.shape != (3,) or not np.all(np.isfinite(wd.astype(float))) or not np.any(wd != 0):
        raise BranchFileError(f"{path}: damaged branch file (weight_direction)")
    if "T" in attrs and not (isinstance(attrs["T"], (int, float)) and not isinstance(attrs["T"], bool)
                             and math.isfinite(attrs["T"])):
        raise BranchFileError(f"{path}: damaged branch file (attribute T)")
    from .rod import RodParameters
    try:  # the rod the file describes must be one rodcont computes with
        RodParameters(EI=attrs["EI"], GJ=attrs["GJ"], EA=attrs["EA"], w=attrs["w"], L=attrs["L"],
                      weight_direction=tuple(float(u) for u in wd))
    except (ValueError, TypeError) as exc:
        raise BranchFileError(f"{path}: damaged branch file ({exc})") from None
    param = attrs.get("param", "phi_L")
    if param not in ("phi_L", "gamma", "T", "w", "EI", "GJ", "EA", "torque", "l0", "depth"):
        raise BranchFileError(f"{path}: damaged branch file (param = {param!r})")
    return attrs


def _join_unknowns(where: str, attrs: dict) -> int:
    """Unknowns a solution has beyond ``6 N k + 11``: those of the joins at its reference curve's curvature
    jumps (a well's stations), the same on every mesh of the curve."""
    if "join_unknowns" in attrs:  # stored by a drill string's trace (its sections are joins too)
        return int(attrs["join_unknowns"])
    spec = str(attrs.get("reference", "straight"))
    if spec == "straight":
        return 0
    from .curves import parse_reference
    from .rod import UNKNOWNS_PER_JOIN
    try:
        curve = parse_reference(spec, float(attrs["L"]))
    except (ValueError, TypeError, OSError) as exc:
        raise BranchFileError(f"{where}: damaged branch file (reference {spec!r}: {exc})") from None
    return 0 if curve.constant_frame else UNKNOWNS_PER_JOIN * int(np.size(curve.curvature_jumps))


def _read_group(path: str, root, attrs: dict, name: str = "") -> BranchData:
    h5py = _h5py()
    where = f"{path}:{name}" if name else path
    if "branch" not in root or not isinstance(root["branch"], h5py.Group):
        raise BranchFileError(f"{where}: not a rodcont branch (no /branch group)")
    branch = {}
    for key, obj in root["branch"].items():
        if not isinstance(obj, h5py.Dataset):
            raise BranchFileError(f"{where}: damaged branch file (/branch/{key} is not a dataset)")
        branch[key] = obj[()]
    for req in ("phi_L", "stretch", "torque", "l0", "coefficients", "kind"):
        if req not in branch:
            raise BranchFileError(f"{where}: damaged branch file (/branch/{req} missing)")
    for key in ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "arclength", "defect",
                "error", "dphi_ds", "located", "unstable_modes"):
        if key in branch and (np.asarray(branch[key]).ndim != 1 or np.asarray(branch[key]).dtype.kind not in "fiub"):
            raise BranchFileError(f"{where}: damaged branch file (/branch/{key} is not a column of numbers)")
    param = attrs.get("param", "phi_L")
    if param != "phi_L" and param not in branch:
        raise BranchFileError(f"{where}: damaged branch file (/branch/{param} missing)")
    n = min(len(v) for v in branch.values())
    branch = {k: v[:n] for k, v in branch.items()}
    if np.asarray(branch["kind"]).dtype.kind not in "OSU":
        raise BranchFileError(f"{where}: damaged branch file (/branch/kind does not hold names)")
    branch["kind"] = np.array([_plain(k) for k in branch["kind"]], dtype=object).astype(str)
    X = np.asarray(branch["coefficients"], float)
    if X.ndim != 2:
        raise BranchFileError(f"{where}: damaged branch file (/branch/coefficients is not a table)")
    if "breakpoints" not in branch:
        b0 = root["mesh"]["breakpoints"][()] if "mesh" in root else root.file["mesh"]["breakpoints"][()]
        branch["breakpoints"] = np.tile(b0, (n, 1))
    B = np.asarray(branch["breakpoints"], float)
    k = int(attrs["k"])
    extra = _join_unknowns(where, attrs)
    for i in range(n):
        b = B[i][np.isfinite(B[i])]
        x = X[i][np.isfinite(X[i])]
        if x.size == 0 and int(attrs.get("store_every", 1)) > 1 and b.size >= 2:
            continue  # a thinned-out point: no solution stored
        # a trip in bit depth: the joins (survey stations, section boundaries) change from point to point
        joins = int(branch["join_unknowns"][i]) if "join_unknowns" in branch else extra
        if b.size < 2 or np.any(np.diff(b) <= 0) or x.size != 6 * (b.size - 1) * k + 11 + joins:
            raise BranchFileError(f"{where}: damaged branch file (point {i}: coefficients do not fit its mesh)")
    folds, bps = _read_tables(where, root, n)
    special = _read_special(where, root, n)
    gattrs = {k: _plain(v) for k, v in root.attrs.items()} if name else None
    mesh = root.file["mesh"]["breakpoints"][()] if "mesh" in root.file else B[0][np.isfinite(B[0])]
    if "status" in (gattrs if gattrs is not None else attrs):
        from .result import Status
        value = (gattrs if gattrs is not None else attrs)["status"]
        if value not in {s.value for s in Status}:
            raise BranchFileError(f"{where}: damaged branch file (status = {value!r})")
    return Branch.from_file(path, attrs, branch, folds, bps, special, mesh, gattrs, name)


def _read_tables(where: str, root, n: int) -> tuple[dict, dict]:
    """``/folds`` and ``/branch_points`` as columns, checked."""
    h5py = _h5py()
    folds, bps = {}, {"index": np.zeros(0, int)}
    for group, target in (("folds", folds), ("branch_points", bps)):
        if group in root:
            if not isinstance(root[group], h5py.Group):
                raise BranchFileError(f"{where}: damaged branch file (/{group} is not a group)")
            for key, obj in root[group].items():
                if not isinstance(obj, h5py.Dataset):
                    raise BranchFileError(f"{where}: damaged branch file (/{group}/{key} is not a dataset)")
                target[key] = np.asarray(obj[()])
            need = FOLD_FIELDS[:7] if group == "folds" else ("index", "phi_L", "stretch")
            if target:
                lengths = set()
                for key in need:
                    v = target.get(key)
                    if v is None or v.ndim != 1 or v.dtype.kind not in "fiu":
                        raise BranchFileError(f"{where}: damaged branch file (/{group}/{key} missing or not numbers)")
                    lengths.add(len(v))
                if len(lengths) > 1:
                    raise BranchFileError(f"{where}: damaged branch file (/{group} columns of different lengths)")
            idx = np.asarray(target.get("index", np.zeros(0, int)))
            if idx.size and (idx.dtype.kind not in "iu" or idx.min() < 0 or idx.max() >= n):
                raise BranchFileError(f"{where}: damaged branch file (/{group}/index out of range)")
    return folds, bps


def _read_special(where: str, root, n: int) -> dict | None:
    """``/special_points`` as columns (None in files written before it)."""
    h5py = _h5py()
    if "special_points" not in root:
        return None
    g = root["special_points"]
    if not isinstance(g, h5py.Group) or any(not isinstance(g[k], h5py.Dataset) for k in g):
        raise BranchFileError(f"{where}: damaged branch file (/special_points)")
    out = {k: g[k][()] for k in g}
    idx = np.asarray(out.get("index", np.zeros(0, int)))
    if idx.ndim != 1 or idx.dtype.kind not in "iu" or (idx.size and (idx.min() < 0 or idx.max() >= n)) or \
            any(np.asarray(v).shape != idx.shape for v in out.values()):
        raise BranchFileError(f"{where}: damaged branch file (/special_points)")
    out["message"] = [_plain(m) for m in out.get("message", [""] * idx.size)]
    return out


def _open(path: str):
    h5py = _h5py()
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise BranchFileError(f"{path}: not a readable HDF5 file ({str(exc).split(':')[0]})") from None


def _root_attrs(path: str, f) -> dict:
    if f.attrs.get("kind") == "broomstick":  # rodcont's, but curves against depth with no equilibria in it
        raise BranchFileError(f"{path}: a broomstick file (hook loads and torques against bit depth, no stored "
                              f"equilibria): rodcont plot draws it; for a string's shape or fields use a trip's "
                              f"file (trace --param depth --out) or solve --string --out")
    if "rodcont_version" not in f.attrs:
        raise BranchFileError(f"{path}: an HDF5 file, but not a rodcont branch file")
    try:
        attrs = {k: _plain(v) for k, v in f.attrs.items()}
    except (OSError, ValueError, TypeError) as exc:
        raise BranchFileError(f"{path}: damaged branch file ({exc})") from None
    return _validate_attrs(path, attrs)


def _user_problem(path: str, f, branch=None):
    """A branch of a user's problem (``kind = "bvp"``, :mod:`rodcont.bvp`), or None for the rod's files."""
    if "rodcont_version" not in f.attrs or _plain(f.attrs.get("kind")) != "bvp":
        return None
    if branch is not None:
        raise BranchFileError(f"{path} is a single branch, not a diagram: no branch {branch}")
    from .bvp import read_file
    return read_file(path, f)


_READ_ERRORS = (KeyError, OSError, ValueError, TypeError, IndexError, UnicodeDecodeError, AttributeError,
                RuntimeError, OverflowError)


def unverified_message(path: str) -> str:
    return (f"{path} has no rodcont checksum (written by another program, or rewritten by hand): it is read "
            f"as it is, unverified")


def _marked(path: str, verified: bool, data):
    """``data`` (a branch or a diagram) flagged ``unverified`` (each branch too) and, if so, warned."""
    for obj in [data] + list(getattr(data, "branches", [])):
        try:
            obj.unverified = not verified
        except AttributeError:
            pass
    if not verified:
        import warnings
        warnings.warn(unverified_message(path), UnverifiedFileWarning, stacklevel=3)
    return data


def _check_path(path) -> None:
    """A file name, not whatever object (a ``TypeError`` naming it, not ``os.stat``'s)."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a file name (str or os.PathLike), got {path!r}")


def _check_branch_index(branch) -> None:
    """``branch`` is None, an int or a str (a name the file may not hold is a :class:`BranchFileError` that lists
    the branches it has); another type is a ``TypeError`` naming it."""
    if isinstance(branch, bool) or not (branch is None or isinstance(branch, (int, np.integer, str))):
        raise TypeError(f"branch must be a branch index (an int >= 0), got {branch!r}")


def load_branch(path: str, branch: str | int | None = None) -> Branch:
    """Read a branch file (or branch ``<j>`` of a diagram file) as a :class:`rodcont.branch.Branch`;
    :class:`BranchFileError` with a one-line reason otherwise. A file without rodcont's checksum reads
    with ``unverified = True`` and an :class:`UnverifiedFileWarning`."""
    _check_path(path)
    _check_branch_index(branch)
    verified = _check_file(path)
    return _marked(path, verified, _load_branch(path, branch))


def _load_branch(path: str, branch: str | int | None = None) -> Branch:
    f = _open(path)
    try:
        with f:
            user = _user_problem(path, f, branch)
            if user is not None:
                return user
            attrs = _root_attrs(path, f)
            if "branches" in f:
                names = sorted(f["branches"].keys(), key=lambda s: (len(s), s))
                if branch is None:
                    if len(names) != 1:
                        raise BranchFileError(f"{path} is a diagram of {len(names)} branches: "
                                              f"name one as {path}:<j>:POINT (j in {', '.join(names)})")
                    branch = names[0]
                if str(branch) not in names:
                    raise BranchFileError(f"{path} has no branch {branch} (branches: {', '.join(names)})")
                return _read_group(path, f["branches"][str(branch)], attrs, str(branch))
            if branch is not None:
                raise BranchFileError(f"{path} is a single branch, not a diagram: no branch {branch}")
            return _read_group(path, f, attrs)
    except BranchFileError:
        raise
    except _READ_ERRORS as exc:
        raise BranchFileError(f"{path}: damaged branch file ({type(exc).__name__}: {str(exc)[:120]})") from None


def load_diagram(path: str) -> DiagramData:
    """Read a diagram file (a trace file reads as a diagram of one branch, with its folds); unverified as
    :func:`load_branch` says."""
    _check_path(path)
    verified = _check_file(path)
    return _marked(path, verified, _load_diagram(path))


def _load_diagram(path: str) -> DiagramData:
    f = _open(path)
    try:
        with f:
            user = _user_problem(path, f)
            if user is not None:
                return DiagramData(path, user.attrs, [user], Table([dict(row, branch=0) for row in user.folds],
                                                                   columns=tuple(user.folds.columns) + ("branch",)))
            attrs = _root_attrs(path, f)
            if "branches" not in f:
                one = _read_group(path, f, attrs)
                return DiagramData(path, attrs, [one], Table([dict(row, branch=0) for row in one.folds],
                                                             columns=tuple(one.folds.columns) + ("branch",)))
            names = sorted(f["branches"].keys(), key=lambda s: (len(s), s))
            if not names:
                raise BranchFileError(f"{path}: a diagram file with no branch")
            branches = [_read_group(path, f["branches"][nm], attrs, nm) for nm in names]
            folds = {k: np.asarray(v[()]) for k, v in f["folds"].items()} if "folds" in f else {}
            if folds:
                cols = FOLD_FIELDS[:7] + ("branch",)
                if any(c not in folds or folds[c].ndim != 1 or folds[c].dtype.kind not in "fiu" for c in cols) or \
                        len({len(folds[c]) for c in cols}) > 1 or \
                        (len(folds["branch"]) and (folds["branch"].min() < 0 or folds["branch"].max() >= len(names))):
                    raise BranchFileError(f"{path}: damaged diagram file (/folds)")
            from .branch import _table
            return DiagramData(path, attrs, branches, _table(folds, ("branch",) + FOLD_FIELDS))
    except BranchFileError:
        raise
    except _READ_ERRORS as exc:
        raise BranchFileError(f"{path}: damaged branch file ({type(exc).__name__}: {str(exc)[:120]})") from None


def split_spec(spec: str, what: str = "--start") -> tuple[str, str | None, str]:
    """``FILE.h5:POINT`` or ``FILE.h5:<j>:POINT`` (a branch of a diagram) -> ``(path, branch, point)``."""
    parts = spec.rsplit(":", 2)
    if len(parts) < 2 or not parts[-1]:
        raise BranchFileError(f"{what} expects FILE.h5:POINT or FILE.h5:BRANCH:POINT (a point index, F<j> "
                              f"or BP<j>), got {spec!r}")
    if len(parts) == 3 and os.path.exists(parts[0]) and not os.path.exists(parts[0] + ":" + parts[1]):
        return parts[0], parts[1], parts[2]
    return ":".join(parts[:-1]), None, parts[-1]
