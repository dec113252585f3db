"""A traced branch of the rod, in memory or read from a branch file: one type for both.

:class:`Branch` is the rod's :class:`rodcont.result.ContinuationResult`: the drivers (trace,
diagram, fold curves) fill it point by point, :class:`rodcont.branchfile.BranchWriter` writes it,
and :func:`rodcont.branchfile.load_branch` reads one back as a :class:`Branch` too, so code
written against a branch in memory works on one read from a file. What it adds to the generic
result: the rod's columns (:data:`COLUMNS`), the rod, its tension, reference curve and wall,
the file's attributes, and the fold table that labels every fold with the helical waves and the
unstable modes on its two sides (:attr:`Branch.folds`).
"""

from __future__ import annotations

import json
import math

import numpy as np

from .continuation import Kind, Point
from .result import (
    ContinuationResult,
    PointNotFound,
    SpecialPoint,
    Status,
    Table,
    _Rows,
    event_label,
    special_points,
    status_from_message,
)
from .rod import RodParameters

OUTPUTS = ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "defect")
COLUMNS = OUTPUTS + ("error", "unstable_modes", "arclength", "dphi_ds", "kind", "located")
# branch-table columns of a trace inside a conduit (rodcont.contact): the narrowest gap c - |Delta|,
# the integral of the wall force, the number of contact zones
CONTACT_COLUMNS = ("min_gap", "side_force", "contact_zones")
# and of a drill string (friction on the wall, rodcont.drilling): the axial force and the torque at the rig
DRILLING_COLUMNS = ("hook_load", "surface_torque")
FOLD_FIELDS = ("phi_L", "stretch", "torque", "l0", "waves_before", "waves_after", "index", "located",
               "unstable_before", "unstable_after")

#: the rod's events: their labels, and the first words of their sentences in files written before labels
EVENT_LABELS = (("validity guard", "validity_guard"), ("the stretch factor reached 0", "stretch_factor_zero"),
                ("stretch_max", "stretch_max"), ("contact onset", "contact"), ("left the Eulerian domain",
                                                                               "eulerian_domain"))


def rod_event_label(kind: str) -> tuple[str, str]:
    """``(label, message)`` of an event kind, the rod's old sentences mapped to their labels."""
    label, message = event_label(kind)
    for start, name in EVENT_LABELS:
        if message.startswith(start):
            return name, message
    return label, message


def infer_status(message: str) -> Status:
    """The status of a stop sentence (files written before the status was stored)."""
    m = str(message).strip()
    if m.startswith("validity guard") or m.startswith("the stretch factor reached 0"):
        return Status.VALIDITY_GUARD
    if m.startswith("start of the trace"):
        return Status.START
    if m.endswith(" branches") and m.split()[0].isdigit():
        return Status.COMPLETE
    if m.startswith("down: ") and "; up: " in m:
        return infer_status(m.split("; up: ", 1)[1])
    return status_from_message(m)


class Branch(ContinuationResult):
    """A traced branch of the rod: the generic result with the rod's columns, rod and file attributes.

    ``table[name]`` lists one value per point for every name of :data:`COLUMNS` (and the
    continued parameter when it is not ``phi_L``, and :data:`CONTACT_COLUMNS` in a conduit);
    ``coefficients``, ``tangents`` and ``meshes`` hold each point's unknown vector, unit tangent
    ``(tx, tp)`` and breakpoints (they differ from point to point when the mesh adapts).
    ``attrs``: the root attributes of its file (the rod, loads, mesh and settings: the same in
    memory and read back); ``path``, ``name`` (a diagram's branch number), ``group_attrs`` (a
    diagram branch's group) for one read from a file. ``branch`` is the table as arrays, with the
    NaN-padded ``coefficients``, ``breakpoints`` and ``tangent`` matrices of the file.
    """

    SIGNED_COLUMNS = ("dphi_ds",)

    def __init__(self, gamma: float = math.nan, rod: RodParameters | None = None, N: int = 15, k: int = 5,
                 param: str = "phi_L", attrs: dict | None = None, curve=None, wall=None):
        super().__init__(param)
        self.table = {name: [] for name in COLUMNS + ((param,) if param != "phi_L" else ())}
        self.gamma_value, self.rod, self.N, self.k = gamma, rod or RodParameters(), N, k
        self.attrs = dict(attrs or {})
        self.path, self.name, self.group_attrs = "", "", None
        self._curve, self._wall = curve, wall
        self._raw = None          # a file's /branch group, as read
        self._first_mesh = None
        # (value before, value after, count before, count after): eigenvalue crossings no fold or branch
        # point accounts for (rodcont.drivers.trace.StabilityCount)
        self.missed_crossings: list = []

    # ---- the rod's columns and fold table ---------------------------------------------
    def row(self, pt: Point) -> dict:
        out = {name: pt.data[name] for name in OUTPUTS}
        # dphi_ds: the tangent's phi_L component (the parameter's, or, under a torque, the unknown's; 0 at fixed phi_L)
        dphi = float(pt.tp) if self.param == "phi_L" else float(pt.data.get("dphi_ds", 0.0))
        out.update(error=float(pt.data.get("error", np.nan)), unstable_modes=int(pt.data.get("unstable_modes", -1)),
                   arclength=pt.arclength, dphi_ds=dphi, kind=str(pt.kind), located=bool(pt.located))
        if self.param != "phi_L":
            out[self.param] = float(pt.data[self.param])
        for name in CONTACT_COLUMNS + DRILLING_COLUMNS + ("T",):  # inside a conduit; T solved for under length control
            if name in pt.data:
                out[name] = pt.data[name]
        return out

    @property
    def folds(self) -> Table:
        """Fold table: outputs at each fold, the helical waves on its two sides, index along the branch.

        The two arcs that meet at a fold are told apart by the stretch: the
        *before* side is the one of smaller stretch (less material in the span,
        as the response diagram is read from left to right). ``waves_before``
        is the fewest helical waves on that arc, back to the previous fold or
        the end of the branch; ``waves_after`` the waves at the fold, which the
        arc of larger stretch leaves with. A fold "adds a wave" when
        ``waves_after > waves_before``. ``unstable_before``, ``unstable_after``:
        the unstable modes on the two sides next to the fold (-1: not counted).
        A branch read from a file has the table the file stores.
        """
        if self._stored_special is not None and "folds" in self._stored_special:
            return self._stored_special["folds"]
        kinds, waves, stretch = self.table["kind"], self.table["helical_waves"], self.table["stretch"]
        n = len(kinds)
        fold_idx = [i for i, kd in enumerate(kinds) if kd == Kind.FOLD]
        out = []
        for j, i in enumerate(fold_idx):
            lo = fold_idx[j - 1] + 1 if j > 0 else 0
            hi = fold_idx[j + 1] if j + 1 < len(fold_idx) else n
            prev_arc, next_arc = list(range(lo, i)), list(range(i + 1, hi))
            before = self._smaller_stretch_side(i, prev_arc, next_arc, stretch)
            after = next_arc if before is prev_arc else prev_arc
            wb = min((waves[q] for q in before), default=waves[i])
            um = self.table["unstable_modes"]
            ub = um[before[-1] if before is prev_arc else before[0]] if before else -1
            ua = um[after[0] if after is next_arc else after[-1]] if after else -1
            out.append(dict(index=i, phi_L=self.table["phi_L"][i], stretch=stretch[i],
                            torque=self.table["torque"][i], l0=self.table["l0"][i],
                            waves_before=int(wb), waves_after=int(waves[i]),
                            located=bool(self.table["located"][i]), error=self.table["error"][i],
                            unstable_before=int(ub), unstable_after=int(ua)))
        return Table(out, columns=FOLD_FIELDS + ("error",))

    @staticmethod
    def _smaller_stretch_side(i, prev_arc, next_arc, stretch):
        if not prev_arc:
            return next_arc
        if not next_arc:
            return prev_arc
        return prev_arc if stretch[prev_arc[-1]] <= stretch[next_arc[0]] else next_arc

    def branch_point_row(self, i: int) -> dict:
        return dict(index=i, phi_L=self.table["phi_L"][i], stretch=self.table["stretch"][i])

    @property
    def branch_points(self) -> Table:
        if self._stored_special is not None and "branch_points" in self._stored_special:
            return self._stored_special["branch_points"]
        return Table([self.branch_point_row(i) for i, k in enumerate(self.table["kind"]) if k == "branch_point"],
                     columns=("index", "phi_L", "stretch"))

    @property
    def special(self) -> list[SpecialPoint]:
        if self._stored_special is not None and "special" in self._stored_special:
            return list(self._stored_special["special"])
        return special_points(self.table["kind"], self.table["located"], self.table[self.param], self.param,
                              self.messages, label_of=rod_event_label)

    # ---- the rod, its loads and its file -----------------------------------------------------
    @property
    def gamma(self) -> float:
        return float(self.attrs["gamma"]) if "gamma" in self.attrs else float(self.gamma_value)

    @property
    def tension(self) -> float:
        a = self.attrs
        if "T" in a:
            return float(a["T"])
        if "gamma" in a:
            return float(a["gamma"]) * float(a["w"]) * float(a["L"])
        return self.rod.tension(self.gamma_value)

    @property
    def curve(self):
        """The reference curve the solutions are written on (``reference`` attribute)."""
        if self._curve is not None:
            return self._curve
        from .curves import parse_reference
        spec = str(self.attrs.get("reference", "straight"))
        try:
            return parse_reference(spec, float(self.attrs.get("L", self.rod.L)))
        except ValueError as exc:
            raise self._error(f"{self.path}: damaged branch file (reference {spec!r}: {exc})") from None

    @property
    def wall(self):
        """The conduit wall of the rod (``conduit`` attribute; None: no wall)."""
        if self._wall is not None:
            return self._wall
        spec = str(self.attrs.get("conduit", ""))
        if not spec:
            return None
        from .contact import Wall
        try:
            return Wall.from_spec(spec)
        except (ValueError, TypeError) as exc:
            raise self._error(f"{self.path}: damaged branch file (conduit {spec!r}: {exc})") from None

    @property
    def label(self) -> str:
        if not self.path:
            return "the branch"
        return f"{self.path}:{self.name}" if self.name else self.path

    @property
    def breakpoints(self) -> np.ndarray:
        """The first mesh (``/mesh/breakpoints`` of a file)."""
        if self._first_mesh is not None:
            return self._first_mesh
        return np.asarray(self.meshes[0], float) if len(self) else np.zeros(0)

    @property
    def branch(self) -> dict:
        return self._raw if self._raw is not None else ContinuationResult.branch.fget(self)

    @staticmethod
    def _error(message: str):
        from .branchfile import BranchFileError
        return BranchFileError(message)

    def resolve(self, label) -> int:
        """Point index of ``label``: an integer (point, from 0; negative from the end), ``F<j>`` the j-th
        fold or ``BP<j>`` the j-th branch point (both counted from 1), or a special point's label;
        :class:`rodcont.branchfile.BranchFileError` with the reason otherwise."""
        try:
            return super().resolve(label)
        except PointNotFound as exc:
            raise self._error(str(exc)) from None

    def point(self, label) -> dict:
        i = self.resolve(label)
        if not np.size(self.coefficients[i]):
            stored = [j for j in range(len(self)) if np.size(self.coefficients[j])]
            near = min(stored, key=lambda j: abs(j - i)) if stored else None
            raise self._error(f"{self.label}: point {i} has no stored solution (the file keeps every "
                              f"{self.attrs.get('store_every', '?')}-th point and the special ones)"
                              + (f"; the nearest stored one is {near}" if near is not None else ""))
        return super().point(i)

    # ---- read from a file -----------------------------------------------------------------------
    @classmethod
    def from_file(cls, path: str, attrs: dict, raw: dict, folds: dict, branch_points: dict, special: dict | None,
                  mesh: np.ndarray, group_attrs: dict | None = None, name: str = "") -> Branch:
        """A branch read back (``rodcont.branchfile``): the columns, solutions and tables as stored."""
        a = attrs
        rod = RodParameters(EI=a["EI"], GJ=a["GJ"], EA=a["EA"], w=a["w"], L=a["L"],
                            weight_direction=tuple(a.get("weight_direction", (0.0, 0.0, -1.0))))
        out = cls(float(a["gamma"]), rod, int(a.get("N", len(mesh) - 1)), int(a["k"]), str(a.get("param", "phi_L")),
                  attrs=a)
        out.path, out.name, out.group_attrs, out._raw, out._first_mesh = path, name, group_attrs, raw, mesh
        n = len(raw["phi_L"])
        out.table = {}
        for key, v in raw.items():
            v = np.asarray(v)
            if v.ndim == 1:
                out.table[key] = [bool(u) for u in v] if key == "located" else v.tolist()
        out.coefficients, out.meshes = _Rows(raw["coefficients"]), _Rows(raw["breakpoints"])
        out.tangents = _Rows(raw["tangent"]) if "tangent" in raw else [np.empty(0)] * n
        tables = {"folds": _table(folds, FOLD_FIELDS), "branch_points": _table(branch_points,
                                                                               ("index", "phi_L", "stretch"))}
        if special is not None:
            out.messages = {int(i): str(m) for i, m in zip(special.get("index", []), special.get("message", []))
                            if str(m)}
        out._stored_special = tables
        where = group_attrs if group_attrs is not None else a
        out.message = str(where.get("stop_reason", a.get("stop_reason", "")))
        if a.get("kind") == "fold_curve" and out.message.startswith("down: ") and "; up: " in out.message:
            out.message_first, out.message = out.message[len("down: "):].split("; up: ", 1)
            out.status_first = Status(a["status_first"]) if "status_first" in a else infer_status(out.message_first)
        out.status = Status(where["status"]) if "status" in where else infer_status(out.message)
        first = where.get("stop_reason_first")
        if first is not None:
            out.message_first = str(first or "")
            out.status_first = Status(where["status_first"]) if "status_first" in where else infer_status(first)
        out.settings = _settings(a)
        out.unlocated = _json_list(where.get("unlocated", "[]"))
        out.missed_crossings = _json_list(where.get("missed_crossings", "[]"))
        return out


def _table(group: dict, order: tuple) -> Table:
    """A stored table (a group of columns) as a :class:`Table` of rows."""
    names = [k for k in order if k in group] + [k for k in group if k not in order]
    n = min((len(group[k]) for k in names), default=0)
    rows = [{k: np.asarray(group[k])[j].item() for k in names} for j in range(n)]
    return Table(rows, columns=tuple(names))


def _json_list(text) -> list:
    try:
        v = json.loads(text)
    except (TypeError, ValueError):
        return []
    return v if isinstance(v, list) else []


def _settings(attrs: dict) -> dict:
    out = {}
    for section, key in (("trace", "settings"), ("continuation", "continuation_settings"),
                         ("adaptive", "adaptive_settings")):
        if key in attrs:
            try:
                v = json.loads(attrs[key])
            except (TypeError, ValueError):
                continue
            if isinstance(v, dict):
                out[section] = v
    return out
