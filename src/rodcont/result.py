"""What a continuation run returns: one result type for every driver and for files read back.

:class:`ContinuationResult` (knows nothing of rods; the rod's :class:`rodcont.branch.Branch`
extends it) holds

* the **table**: ``table[name]`` lists one value per point for every column (the continued
  parameter, ``arclength``, ``kind``, ``located`` and the problem's named outputs), and per point
  the solution ``coefficients[i]``, the unit tangent ``tangents[i]`` (``(tx, tp)`` concatenated) and
  the mesh ``meshes[i]`` it lives on, for restarts (a thinned run, ``store_every = M``, keeps
  empty arrays where it dropped them);
* the **special points** (:attr:`ContinuationResult.special`): each a :class:`SpecialPoint` with
  its kind (fold, branch_point, forced, bound, event, start), a short label (``F1, F2, ...`` for
  folds, ``BP1, ...`` for branch points, ``P1, ...`` for forced values, the bound's name, an
  event's own label), its index in the table, the parameter's name and value, whether it was
  located or only bracketed, and a message;
* the **status**: a :class:`Status` with a ``message`` (``stop_reason`` is the message, for
  scripts that read it), as scipy's ``OptimizeResult.status`` / ``message``;
* the **settings** of the run (its settings dataclasses as dicts, by section).

:class:`Table` is a list of rows (dicts) that also answers a column name with the column as an
array: ``result.folds[0]["p"]`` and ``result.folds["p"]`` both work.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np


class Status(str, Enum):
    """Why a run ended (a string enum: ``Status.BOUND == "bound"``)."""

    RUNNING = "running"                # a file still being written
    BOUND = "bound"                    # a parameter bound reached
    VALIDITY_GUARD = "validity_guard"  # the model's own domain ends (a stopping event declares it)
    ACCURACY_GUARD = "accuracy_guard"  # the estimated error above max_error on a mesh that may not grow
    EVENT = "event"                    # another stopping event
    INTERRUPTED = "interrupted"        # Ctrl-C or SIGTERM
    NO_CONVERGENCE = "no_convergence"  # no converged solution even on refined meshes
    STEP_TOO_SMALL = "step_too_small"
    MAX_STEPS = "max_steps"
    START_FAILED = "start_failed"      # no first point
    AT_START = "at_start"              # a stopping event or bound already violated at the first point
    SEGMENT = "segment"                # a tracker's segment ended (internal: the engine goes on)
    COMPLETE = "complete"              # a run of several branches (a diagram) that finished
    START = "start"                    # a branch's first end is its starting point (not a stop)

    def __str__(self) -> str:
        return self.value


#: point kinds that are special points (events are ``event:<label>``)
SPECIAL_KINDS = ("start", "fold", "branch_point", "forced", "bound")


def event_label(kind: str) -> tuple[str, str]:
    """``(label, message)`` of an event's point kind: ``event:<label>`` as written now, or the whole
    sentence (``event:<message>``) as files written before labels did (the label is then the
    sentence's first words joined by ``_``)."""
    text = str(kind)[len("event:"):]
    if " " not in text:
        return text, ""
    words = []
    for w in "".join(c if c.isalnum() or c == "_" else " " for c in text.split(":")[0]).split():
        if any(c.isdigit() for c in w) or len(words) == 3:
            break
        words.append(w)
    return "_".join(words).lower() or "event", text


def in_terms_of(message: str, param: str) -> str:
    """An engine message, which calls the continued parameter ``p`` (its bounds ``p_min``, ``p_max``), in the
    words of a trace in ``param``: ``T = 5``, ``T_max``. A trace in ``phi_L`` keeps them (``p`` is Phi there)."""
    if param in (None, "phi_L"):
        return message
    import re
    message = re.sub(r"\bp_(min|max)\b", lambda m: f"{param}_{m.group(1)}", message)
    return re.sub(r"\bp = ", f"{param} = ", message)


def status_from_message(message: str) -> Status:
    """The status a stop sentence of the generic tracker and engine stands for (files written before the
    status was stored). Drivers extend it with their own events (:func:`rodcont.branch.infer_status`)."""
    m = str(message).strip()
    rules = (("running", Status.RUNNING), ("interrupted", Status.INTERRUPTED),
             ("accuracy guard: no converged solution", Status.NO_CONVERGENCE),
             ("accuracy guard", Status.ACCURACY_GUARD), ("step size fell below", Status.STEP_TOO_SMALL),
             ("maximum number of steps", Status.MAX_STEPS), ("no convergence at the starting point",
                                                              Status.START_FAILED),
             ("the starting point is singular", Status.START_FAILED), ("the restart direction is zero",
                                                                       Status.START_FAILED),
             ("not started", Status.START_FAILED))
    for prefix, status in rules:
        if m.startswith(prefix):
            return status
    if "(already at the start)" in m or "is outside the bounds" in m:
        return Status.AT_START
    if m.startswith("parameter bound"):
        return Status.BOUND
    return Status.EVENT


@dataclass
class SpecialPoint:
    """A labelled point of a result: ``kind`` fold, branch_point, forced, bound, event or start."""

    kind: str
    label: str
    index: int
    param: str
    value: float
    located: bool = True
    message: str = ""


class PointNotFound(KeyError):
    """A point label that names no point of the result (the message says why)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class Table(list):
    """Rows (dicts) that also answer a column name: ``t[0]["p"]`` is a row's value, ``t["p"]`` the column.

    ``columns`` names the columns (an empty table knows them too); ``t.get(name, default)`` is the
    column or ``default``; ``name in t`` asks for a column.
    """

    def __init__(self, rows=(), columns: tuple = ()):
        super().__init__(rows)
        names = list(columns)
        for row in self:
            names += [k for k in row if k not in names]
        self.columns = tuple(names)

    def __getitem__(self, key):
        if isinstance(key, str):
            if key not in self.columns:
                raise KeyError(key)
            values = [row.get(key, math.nan) for row in self]
            if not values:
                return np.zeros(0, int if key in ("index", "branch") else float)
            return np.asarray(values)
        return super().__getitem__(key)

    def __contains__(self, key):
        if isinstance(key, str):
            return key in self.columns
        return super().__contains__(key)

    def get(self, key, default=None):
        return self[key] if key in self.columns else default

    def keys(self):
        return self.columns


class _Rows:
    """Per-point arrays kept as rows of a NaN-padded matrix (a file's), read as the finite prefix of each row."""

    def __init__(self, matrix):
        self.matrix = matrix

    def __len__(self):
        return len(self.matrix)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        row = np.asarray(self.matrix[i], float)
        n = int(np.isfinite(row).sum())
        return row[:n] if n and np.all(np.isfinite(row[:n])) else row[np.isfinite(row)]

    def __iter__(self):
        return (self[i] for i in range(len(self)))


class ContinuationResult:
    """One continued branch: the table of points, the special points, the status and the settings.

    Filled point by point with :meth:`add` (a driver's recorder does it), or read from a file.
    ``param`` names the continued parameter (its column). See the module docstring.
    """

    #: columns every result has, besides the parameter and the problem's outputs
    BASE_COLUMNS = ("arclength", "kind", "located")

    def __init__(self, param: str = "p", settings: dict | None = None):
        self.param = param
        self.table: dict[str, list] = {name: [] for name in (param,) + self.BASE_COLUMNS}
        self.coefficients: list = []
        self.tangents: list = []
        self.meshes: list = []
        self.messages: dict[int, str] = {}
        self.status: Status = Status.RUNNING
        self.message: str = ""
        # a branch traced both ways from a seed: the status and message of its first end
        self.status_first: Status | None = None
        self.message_first: str = ""
        self.settings: dict = dict(settings or {})
        # (kind, value before, value after): folds and branch points detected in a step but not located
        self.unlocated: list = []
        self.elapsed = 0.0
        self.steps = 0
        self.newton_iterations = 0
        self.remeshes = 0
        self._stored_special: dict | None = None  # tables read from a file, used as they are
        self._branch_cache = None

    # ---- points ------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.table[self.param])

    def row(self, pt) -> dict:
        """The table's values of a tracker point (a hook: a driver's result names its own columns)."""
        out = {self.param: float(pt.p), "arclength": float(pt.arclength), "kind": str(pt.kind),
               "located": bool(pt.located)}
        for name, v in pt.data.items():
            if isinstance(v, (int, float, bool, str, np.integer, np.floating, np.bool_)):
                out.setdefault(name, v)
        return out

    def add(self, pt, mesh=None, solution=None, tangent=None) -> int:
        """Append a tracker point (its row, solution, tangent and mesh); returns its index."""
        return self.add_row(self.row(pt), pt.x if solution is None else solution,
                            np.append(pt.tx, pt.tp) if tangent is None else tangent, mesh,
                            getattr(pt, "message", ""))

    def add_row(self, row: dict, solution, tangent, mesh=None, message: str = "") -> int:
        """Append a point given by its row of values, solution, tangent and mesh; returns its index."""
        i = len(self)
        for name, v in row.items():
            col = self.table.get(name)
            if col is None:  # a column that appears later: earlier points did not have it
                col = self.table[name] = [math.nan] * i
            col.append(v)
        for name, col in self.table.items():
            if len(col) == i:
                col.append(math.nan)
        self.coefficients.append(np.asarray(solution, float))
        self.tangents.append(np.asarray(tangent, float))
        self.meshes.append(np.zeros(0) if mesh is None else np.asarray(mesh, float))
        if message:
            self.messages[i] = message
        self._branch_cache = None
        return i

    def thin(self, i: int, every: int) -> None:
        """Drop what a run with ``store_every = every`` does not keep of point ``i`` (not the last):
        the solution of all but every ``every``-th and the special points, the tangent of all but
        the special points. Dropped arrays become empty."""
        if every <= 1:
            return
        special = str(self.table["kind"][i]) not in ("regular", "forced")
        if not (special or i % every == 0):
            self.coefficients[i] = np.empty(0)
        if not special:
            self.tangents[i] = np.empty(0)

    def row_at(self, i: int) -> dict:
        """The table's values at point ``i``."""
        return {name: col[i] for name, col in self.table.items()}

    def column(self, name: str) -> np.ndarray:
        return np.asarray(self.table[name])

    # ---- status ----------------------------------------------------------------------
    @property
    def stop_reason(self) -> str:
        """Why the run ended, as a sentence (the status's message)."""
        return self.message

    @stop_reason.setter
    def stop_reason(self, text: str) -> None:
        self.message = str(text)

    def set_status(self, status, message: str) -> None:
        self.status, self.message = Status(status), str(message)

    # ---- special points -----------------------------------------------------------------
    @property
    def special(self) -> list[SpecialPoint]:
        """Every special point in table order, labelled (folds F1, F2, ...; branch points BP1, ...;
        forced values P1, ...; a bound by its name; an event by its own label)."""
        if self._stored_special is not None and "special" in self._stored_special:
            return list(self._stored_special["special"])
        return special_points(self.table["kind"], self.table["located"], self.table[self.param], self.param,
                              self.messages)

    def fold_row(self, i: int) -> dict:
        """A row of :attr:`folds` (a hook: a driver adds its own columns)."""
        out = {"index": i}
        out.update({name: col[i] for name, col in self.table.items()})
        return out

    @property
    def folds(self) -> Table:
        """One row per fold (``index``, ``label`` F1, F2, ..., the point's columns), as rows or as columns."""
        if self._stored_special is not None and "folds" in self._stored_special:
            return self._stored_special["folds"]
        idx = [i for i, k in enumerate(self.table["kind"]) if k == "fold"]
        return Table([dict(self.fold_row(i), label=f"F{j}") for j, i in enumerate(idx, 1)],
                     columns=("index", "label", self.param))

    @property
    def branch_points(self) -> Table:
        """One row per branch point: ``index``, ``label`` (BP1, ...), the parameter and ``located``."""
        if self._stored_special is not None and "branch_points" in self._stored_special:
            return self._stored_special["branch_points"]
        idx = [i for i, k in enumerate(self.table["kind"]) if k == "branch_point"]
        return Table([dict(self.branch_point_row(i), label=f"BP{j}") for j, i in enumerate(idx, 1)],
                     columns=("index", "label", self.param))

    def branch_point_row(self, i: int) -> dict:
        return {"index": i, self.param: self.table[self.param][i], "located": bool(self.table["located"][i])}

    # ---- points by label ------------------------------------------------------------------
    def resolve(self, label) -> int:
        """Point index of ``label``: an integer (from 0; negative from the end), ``F<j>`` the j-th fold,
        ``BP<j>`` the j-th branch point (from 1), or any special point's label; :class:`PointNotFound`
        (a ``KeyError`` with the reason) otherwise; a label of another type is a ``TypeError``."""
        if isinstance(label, bool) or not isinstance(label, (int, np.integer, str)):
            raise TypeError(f"a point label is an int or a str (F<j>, BP<j>, a special point's label), got {label!r}")
        s = str(label).strip()
        n = len(self)
        for prefix, table, what in (("BP", self.branch_points, "branch point"), ("F", self.folds, "fold")):
            if s.upper().startswith(prefix) and s[len(prefix):].strip().lstrip("+-").isdigit():
                j = int(s[len(prefix):])
                idx = table.get("index", [])
                if not 1 <= j <= len(idx):
                    raise PointNotFound(f"{self.label} has {len(idx)} {what}(s); {s} does not exist")
                return int(idx[j - 1])
        try:
            i = int(s)
        except ValueError:
            for sp in self.special:
                if sp.label.lower() == s.lower():
                    return sp.index
            raise PointNotFound(f"point label {s!r}: expected an integer index, F<j>, BP<j> or the label of a "
                           f"special point") from None
        if not -n <= i < n:
            raise PointNotFound(f"{self.label} has {n} point(s); index {i} is out of range")
        return i % n

    @property
    def label(self) -> str:
        return "the branch"

    def point(self, label) -> dict:
        """Point ``label`` (see :meth:`resolve`): its columns, ``x`` (solution), ``breakpoints`` (mesh),
        ``index`` and ``direction`` (the unit tangent ``(tx, tp)``, or the secant to the point before)."""
        i = self.resolve(label)
        out = {name: col[i] for name, col in self.table.items()}
        x = np.asarray(self.coefficients[i], float)
        if x.size == 0:
            stored = [j for j in range(len(self)) if np.size(self.coefficients[j])]
            near = min(stored, key=lambda j: abs(j - i)) if stored else None
            raise PointNotFound(f"{self.label}: point {i} has no stored solution (the run kept every "
                           f"{self.settings.get('store_every', '?')}-th point and the special ones)"
                           + (f"; the nearest stored one is {near}" if near is not None else ""))
        out.update(x=x, breakpoints=np.asarray(self.meshes[i], float), index=i, direction=self.direction(i))
        return out

    def direction(self, i: int) -> tuple[np.ndarray, float]:
        """Direction of travel at point ``i``: the stored unit tangent (its parameter part last), or the
        secant from the point before (same mesh), or the parameter's direction."""
        t = np.asarray(self.tangents[i], float)
        if t.size and np.all(np.isfinite(t)) and np.any(t != 0):
            return t[:-1], float(t[-1])
        P = self.table[self.param]
        x1 = np.asarray(self.coefficients[i], float)
        if i > 0:
            x0 = np.asarray(self.coefficients[i - 1], float)
            if x0.size and x0.size == x1.size:
                return x1 - x0, float(P[i] - P[i - 1])
        return np.zeros(x1.size), 1.0

    # ---- whole-branch operations --------------------------------------------------------------
    def _empty_like(self) -> ContinuationResult:
        out = self.__class__.__new__(self.__class__)
        out.__dict__.update({k: v for k, v in self.__dict__.items()})
        out.table = {name: [] for name in self.table}
        out.coefficients, out.tangents, out.meshes, out.messages = [], [], [], {}
        out._stored_special, out._branch_cache = None, None
        for name, v in self.__dict__.items():  # lists of notes are the copy's own
            if isinstance(v, list) and name not in ("coefficients", "tangents", "meshes"):
                out.__dict__[name] = list(v)
        if "_raw" in out.__dict__:
            out._raw = None
        return out

    def reversed(self) -> ContinuationResult:
        """The same points in the opposite order (arclength, tangents and signed tangent columns negated)."""
        out = self._empty_like()
        for name, col in self.table.items():
            out.table[name] = list(reversed(col))
        for name in ("arclength",) + self.SIGNED_COLUMNS:
            if name in out.table:
                out.table[name] = [-a for a in out.table[name]]
        out.coefficients = list(reversed(list(self.coefficients)))
        out.tangents = [-np.asarray(t) for t in reversed(list(self.tangents))]
        out.meshes = list(reversed(list(self.meshes)))
        n = len(self)
        out.messages = {n - 1 - i: m for i, m in self.messages.items()}
        return out

    #: columns that change sign with the direction of travel (a driver's tangent components)
    SIGNED_COLUMNS: tuple = ()

    def extend(self, other: ContinuationResult, skip_first: bool = False) -> None:
        """Append ``other``'s points (without its first when it repeats our last)."""
        s = 1 if skip_first else 0
        n = len(self)
        for name in self.table:
            self.table[name].extend(other.table[name][s:])
        self.coefficients.extend(list(other.coefficients)[s:])
        self.tangents.extend(list(other.tangents)[s:])
        self.meshes.extend(list(other.meshes)[s:])
        self.messages.update({n + i - s: m for i, m in other.messages.items() if i >= s})
        self._branch_cache = None

    @property
    def branch(self) -> dict:
        """The table as a dict of column arrays, with ``coefficients``, ``breakpoints`` and ``tangent``
        as NaN-padded matrices (the layout of a branch file's ``/branch`` group)."""
        if self._branch_cache is not None and self._branch_cache[0] == len(self):
            return self._branch_cache[1]
        out = {name: np.asarray(col) for name, col in self.table.items()}
        for name, rows in (("coefficients", self.coefficients), ("breakpoints", self.meshes),
                           ("tangent", self.tangents)):
            rows = [np.asarray(r, float) for r in rows]
            m = max((r.size for r in rows), default=0)
            mat = np.full((len(rows), m), np.nan)
            for i, r in enumerate(rows):
                mat[i, :r.size] = r
            out[name] = mat
        self._branch_cache = (len(self), out)
        return out


def special_points(kinds, located, values, param: str, messages: dict | None = None,
                   label_of=event_label) -> list[SpecialPoint]:
    """Label the special points of a kind column (see :attr:`ContinuationResult.special`); ``label_of(kind)
    -> (label, message)`` reads an event's kind."""
    messages = messages or {}
    counts = {"fold": 0, "branch_point": 0, "forced": 0}
    prefix = {"fold": "F", "branch_point": "BP", "forced": "P"}
    out = []
    for i, k in enumerate(kinds):
        k = str(k)
        if k.startswith("event:"):
            label, message = label_of(k)
            kind = "event"
        elif k in SPECIAL_KINDS:
            kind, message = k, ""
            if k in counts:
                counts[k] += 1
                label = f"{prefix[k]}{counts[k]}"
            elif k == "bound":
                label = "bound"
            else:
                label = k
        else:
            continue
        out.append(SpecialPoint(kind, label, i, param, float(values[i]), bool(located[i]),
                                messages.get(i, message)))
    return out
