"""Files rodcont reads and writes, made safe: bounded inputs, protected inputs, atomic outputs.

Everything here is small and imports nothing heavy (the command line's file checks run before numpy loads).

**Inputs.** :func:`read_input` reads a text input (a survey, a TOML problem or conduit file) without ever
blocking or growing without bound: the file is opened with ``O_NONBLOCK`` (a FIFO opens at once instead of
waiting for a writer), checked with ``fstat`` (only a regular file is read: not a device such as
``/dev/zero``, not a FIFO, a socket or a directory), refused above the limit of its kind
(:data:`LIMITS`) and read to at most one byte past it (a file that grows while read is refused too).

**Inputs are never outputs.** :func:`command_inputs` collects every file a command reads: its ``--config``
file, its conduit file and the survey that file names, a ``--reference well:FILE`` survey, its branch files
and the surveys their reference curves name. Every writer checks its target against that list
(:func:`rodcont.branchfile.check_writable`): the same file under another name (a symlink, a hard link,
``//``, a relative path) is refused whatever ``--overwrite`` says.

**Atomic outputs.** :func:`publish` writes a file whole to a temporary file beside the target, syncs it,
renames it over the target and syncs the directory: a reader, a crash or a full disk sees the old file or
the new one, never a truncated one. :class:`Staged` does the same for several files at once (a series
of VTK files and its ``.pvd``): all are written first, then all renamed, so a failure while writing leaves
every old file as it was.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat

#: the largest input of each kind, in bytes: a survey of 100 000 stations is about 3 MB; a problem or
#: conduit file is a few lines
LIMITS = {"survey": 16 << 20, "toml": 1 << 20}

_WHY = {errno.ENOSPC: "no space left on the device", errno.EFBIG: "file size limit exceeded",
        errno.EDQUOT: "disk quota exceeded"}


class InputFileError(ValueError):
    """An input file that cannot be read as one of its kind (message: one line, starting with the path);
    ``strerror``: the system's reason when it could not be opened or read at all (else None)."""

    strerror: str | None = None


def _unreadable(path: str, exc: OSError) -> InputFileError:
    err = InputFileError(f"{path}: cannot read it ({exc.strerror or exc})")
    err.strerror = exc.strerror or str(exc)
    return err


class OutputFileError(OSError):
    """An output that could not be written: ``str()`` is one line, ``cannot write PATH: why`` (``strerror``
    the why, ``errno`` the system's code); the target, if it existed, is as it was."""

    def __init__(self, path: str, reason: str, code: int = 0):
        super().__init__(code, reason)
        self.path = path

    def __str__(self) -> str:  # the sentence, not OSError's "[Errno n] ..."
        return f"cannot write {self.path}: {self.strerror}"


def _size(n: int) -> str:
    return f"{n / (1 << 20):g} MB" if n >= 1 << 20 else f"{n} bytes"


def read_input(path: str, kind: str, limit: int | None = None, what: str | None = None) -> bytes:
    """The bytes of the input file ``path`` of ``kind`` (a key of :data:`LIMITS`, or ``limit`` bytes at most).

    ``what`` names the kind in messages (default from ``kind``: "larger than a survey file can be").
    :class:`InputFileError` for a file that is missing, unreadable, not a regular file, or too large.
    """
    limit = LIMITS[kind] if limit is None else int(limit)
    what = what or {"survey": "survey file", "toml": "TOML file"}.get(kind, f"{kind} file")
    if not isinstance(path, str) or not path:
        raise InputFileError(f"a {what} needs a file name")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise _unreadable(path, exc) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind_of = "a directory" if stat.S_ISDIR(st.st_mode) else "a device, a pipe or a socket"
            raise InputFileError(f"{path}: not a regular file ({kind_of})")
        if st.st_size > limit:
            raise InputFileError(f"{path}: {_size(st.st_size)}, larger than a {what} can be ({_size(limit)})")
        chunks, total = [], 0
        while total <= limit:
            block = os.read(fd, min(1 << 20, limit + 1 - total))
            if not block:
                break
            chunks.append(block)
            total += len(block)
        if total > limit:
            raise InputFileError(f"{path}: larger than a {what} can be ({_size(limit)}; it grew while read)")
        return b"".join(chunks)
    except OSError as exc:
        raise _unreadable(path, exc) from None
    finally:
        os.close(fd)


# --------------------------------------------------------------------------
# The files a command reads
# --------------------------------------------------------------------------
def survey_of(spec, base: str | None = None) -> str | None:
    """The survey file a reference curve specification ``well:FILE`` reads (``FILE`` relative to the
    directory ``base`` when given, as a conduit file's is), or None for other kinds."""
    if not isinstance(spec, str):
        return None
    kind, _, args = spec.strip().partition(":")
    if kind.strip().lower() != "well" or not args.strip():
        return None
    name = args.strip()
    return os.path.join(base, name) if base and not os.path.isabs(name) else name


def conduit_survey(path: str) -> str | None:
    """The survey file a conduit file's ``reference = "well:FILE"`` names (relative to the conduit file), or
    None (no such key, or a file that does not read: its command says why when it reads it)."""
    import tomllib
    try:
        doc = tomllib.loads(read_input(path, "toml").decode("utf-8"))
    except (InputFileError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError, ValueError):
        return None
    sec = doc.get("conduit")
    spec = sec.get("reference") if isinstance(sec, dict) else None
    well = doc.get("well")  # a well file (rodcont.drilling.Well): its survey = "FILE"
    if spec is None and isinstance(well, dict) and isinstance(well.get("survey"), str):
        spec = "well:" + well["survey"]
    return survey_of(spec, os.path.dirname(os.path.abspath(path)))


def curve_files(curve) -> list[str]:
    """The files a reference curve object was read from (a well's survey: ``curve.source``)."""
    src = getattr(curve, "source", None)
    return [src] if isinstance(src, str) and src else []


def command_inputs(*, config: str | None = None, reference: str | None = None, conduit: str | None = None,
                   branch_files=(), loaded=(), curves=()) -> list[str]:
    """Every file a command reads, for its writers to refuse (:func:`rodcont.branchfile.check_writable`).

    ``config``: the ``--config`` file; ``reference``: the ``--reference`` specification (a ``well:FILE``
    names its survey); ``conduit``: the conduit file (and the survey its ``reference`` names);
    ``branch_files``: branch files read (paths); ``loaded``: branches or diagrams read (anything with
    ``attrs`` and ``path``: their files and the surveys of their ``reference`` attributes); ``curves``:
    reference curve objects (their surveys).
    """
    out: list[str] = []

    def add(p):
        if isinstance(p, str) and p and p not in out:
            out.append(p)

    add(config)
    add(survey_of(reference))
    if conduit is not None:
        add(conduit)
        add(conduit_survey(conduit))
    for p in branch_files:
        add(p)
    for d in loaded:
        add(getattr(d, "path", None))
        for attrs in [getattr(d, "attrs", None)] + [getattr(b, "attrs", None) for b in getattr(d, "branches", ())]:
            attrs = attrs or {}
            add(survey_of(str(attrs.get("reference", ""))))
            for key in ("well", "string"):  # a drill string's file records its well and string files (solve --out)
                if isinstance(attrs.get(key), str) and os.path.isfile(attrs[key]):
                    add(attrs[key])
                    if key == "well":
                        add(conduit_survey(attrs[key]))
    for c in curves:
        for p in curve_files(c):
            add(p)
    return out


# --------------------------------------------------------------------------
# Atomic outputs
# --------------------------------------------------------------------------
def side_file(path: str, kind: str, suffix: str = "") -> str:
    """A hidden file beside the (resolved) target for ``kind`` (``lock``, ``tmp``): a short name (a hash of
    the target's), so a target name of any allowed length has one; ``tmp`` files carry the process id."""
    real = os.path.realpath(path)
    tag = hashlib.blake2b(os.path.basename(real).encode("utf-8", "surrogateescape"), digest_size=8).hexdigest()
    extra = f".{os.getpid()}" if kind == "tmp" else ""
    return os.path.join(os.path.dirname(real), f".rodcont-{tag}{extra}.{kind}{suffix}")


def reason(exc: OSError) -> str:
    """Why a write failed, in the words of :class:`OutputFileError` (a full disk, a size limit, a quota)."""
    return _WHY.get(exc.errno, exc.strerror or str(exc))


_reason = reason


def _write_all(fd: int, parts) -> None:
    for part in parts:
        if isinstance(part, str):
            part = part.encode("utf-8")
        view = memoryview(part)
        while view:
            n = os.write(fd, view)
            view = view[n:]


def sync_directory(path: str) -> None:
    """Sync the directory that holds ``path`` (a rename is durable once its directory is)."""
    try:
        dfd = os.open(os.path.dirname(os.path.realpath(path)) or ".", os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)
    except OSError:
        pass


def write_temporary(path: str, parts, suffix: str = "") -> str:
    """Write ``parts`` (bytes or str pieces) to a new temporary file beside ``path`` and sync it; returns its
    name. :class:`OutputFileError` (the temporary file removed) when it cannot."""
    tmp = side_file(path, "tmp", suffix)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0), 0o644)
        try:
            _write_all(fd, parts)
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        discard(tmp)
        raise OutputFileError(path, _reason(exc), exc.errno or 0) from None
    except BaseException:
        discard(tmp)
        raise
    return tmp


def commit(tmp: str, path: str) -> None:
    """Rename the synced temporary file ``tmp`` over ``path`` (its resolved target) and sync the directory."""
    try:
        os.replace(tmp, os.path.realpath(path))
    except OSError as exc:
        discard(tmp)
        raise OutputFileError(path, _reason(exc), exc.errno or 0) from None
    sync_directory(path)


def discard(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass


def publish(path: str, parts) -> None:
    """Write ``parts`` (an iterable of bytes or str pieces, or one bytes object) to ``path`` atomically:
    a temporary file beside it, synced, renamed over it. The old file stays whole if anything fails."""
    if isinstance(parts, (bytes, bytearray, memoryview, str)):
        parts = (parts,)
    commit(write_temporary(path, parts), path)


def synced(tmp: str) -> None:
    """Sync a temporary file another writer filled (matplotlib's animation writers)."""
    try:
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        raise OutputFileError(tmp, _reason(exc), exc.errno or 0) from None


class Staged:
    """Several outputs replaced together: :meth:`add` writes each to a synced temporary file, :meth:`commit`
    renames them all (in the order added), :meth:`abort` (or leaving a ``with`` block by an exception)
    removes the temporary files, every old file untouched."""

    def __init__(self):
        self.pending: list[tuple[str, str]] = []

    def add(self, path: str, parts) -> None:
        if isinstance(parts, (bytes, bytearray, memoryview, str)):
            parts = (parts,)
        self.pending.append((write_temporary(path, parts), path))

    def commit(self) -> None:
        pending, self.pending = self.pending, []
        try:
            for i, (tmp, path) in enumerate(pending):  # noqa: B007 - i is read by the except below
                os.replace(tmp, os.path.realpath(path))
        except OSError as exc:
            for tmp, _ in pending[i:]:
                discard(tmp)
            raise OutputFileError(path, _reason(exc), exc.errno or 0) from None
        for d in {os.path.dirname(os.path.realpath(p)) for _, p in pending}:
            sync_directory(os.path.join(d, "x"))

    def abort(self) -> None:
        pending, self.pending = self.pending, []
        for tmp, _ in pending:
            discard(tmp)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if kind is not None:
            self.abort()
        return False
