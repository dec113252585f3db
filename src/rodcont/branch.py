"""A traced branch in memory: the table of outputs per point, its special points, its solutions.

A :class:`Branch` is filled point by point by the drivers (trace, diagram) and
written to a branch file by :class:`rodcont.branchfile.BranchWriter`. Its
fold table labels every fold with the helical waves on its two sides
(:meth:`Branch.folds`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .continuation import Kind, Point
from .rod import RodParameters

OUTPUTS = ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment", "defect")
COLUMNS = OUTPUTS + ("error", "unstable_modes", "arclength", "dphi_ds", "kind", "located")


@dataclass
class Branch:
    """A traced branch: table of outputs per point, the special points, and the unknowns for restarts.

    ``table[name]`` lists one value per point for every name of :data:`COLUMNS`
    (and the continued parameter when it is not ``phi_L``); ``coefficients``,
    ``tangents`` and ``meshes`` hold each point's unknown vector, unit tangent
    ``(tx, tp)`` and breakpoints (they differ from point to point when the
    mesh adapts).
    """

    gamma: float
    rod: RodParameters
    N: int
    k: int
    param: str = "phi_L"
    table: dict = field(default_factory=dict)
    coefficients: list = field(default_factory=list)
    tangents: list = field(default_factory=list)
    meshes: list = field(default_factory=list)
    stop_reason: str = ""
    stop_reasons: tuple = ()      # (backward, forward) for a branch traced both ways from a seed
    elapsed: float = 0.0
    steps: int = 0
    newton_iterations: int = 0
    remeshes: int = 0
    # (value before, value after, count before, count after): eigenvalue crossings no fold or branch point
    # accounts for (rodcont.drivers.trace.StabilityCount)
    missed_crossings: list = field(default_factory=list)
    # (kind, value before, value after): folds and branch points detected in a step but not located
    # (rodcont.continuation.Tracker.not_located)
    unlocated: list = field(default_factory=list)

    def __post_init__(self):
        names = COLUMNS + ((self.param,) if self.param != "phi_L" else ())
        for name in names:
            self.table.setdefault(name, [])

    def __len__(self) -> int:
        return len(self.coefficients)

    def add(self, pt: Point, breakpoints: np.ndarray) -> int:
        """Append a point; returns its index."""
        for name in OUTPUTS:
            self.table[name].append(pt.data[name])
        self.table["error"].append(float(pt.data.get("error", np.nan)))
        self.table["unstable_modes"].append(int(pt.data.get("unstable_modes", -1)))
        self.table["arclength"].append(pt.arclength)
        self.table["dphi_ds"].append(float(pt.tp) if self.param == "phi_L" else 0.0)
        self.table["kind"].append(str(pt.kind))
        self.table["located"].append(bool(pt.located))
        if self.param != "phi_L":
            self.table[self.param].append(float(pt.data[self.param]))
        for name in ("min_gap", "side_force", "contact_zones"):  # inside a conduit
            if name in pt.data:
                self.table.setdefault(name, []).append(pt.data[name])
        self.coefficients.append(np.asarray(pt.x, float))
        self.tangents.append(np.append(pt.tx, pt.tp))
        self.meshes.append(np.asarray(breakpoints, float))
        return len(self.coefficients) - 1

    def thin(self, i: int, every: int) -> None:
        """Drop what a file with ``store_every = every`` does not keep of point ``i`` (not the last point):
        :func:`rodcont.branchfile.kept`. Dropped arrays become empty."""
        from .branchfile import kept
        solution, tangent = kept(i, self.table["kind"][i], every)
        if not solution:
            self.coefficients[i] = np.empty(0)
        if not tangent:
            self.tangents[i] = np.empty(0)

    def column(self, name: str) -> np.ndarray:
        return np.asarray(self.table[name])

    def reversed(self) -> "Branch":
        """The same points in the opposite order (arclength and tangents negated)."""
        out = Branch(self.gamma, self.rod, self.N, self.k, self.param)
        for name, col in self.table.items():
            out.table[name] = list(reversed(col))
        out.table["arclength"] = [-a for a in out.table["arclength"]]
        out.table["dphi_ds"] = [-a for a in out.table["dphi_ds"]]
        out.coefficients = list(reversed(self.coefficients))
        out.tangents = [-t for t in reversed(self.tangents)]
        out.meshes = list(reversed(self.meshes))
        return out

    def extend(self, other: "Branch", skip_first: bool = False) -> None:
        """Append ``other``'s points (without its first when it repeats our last)."""
        s = 1 if skip_first else 0
        for name in self.table:
            self.table[name].extend(other.table[name][s:])
        self.coefficients.extend(other.coefficients[s:])
        self.tangents.extend(other.tangents[s:])
        self.meshes.extend(other.meshes[s:])

    @property
    def folds(self) -> list[dict]:
        """Fold table: outputs at each fold, the helical waves on its two sides, index along the branch.

        The two arcs that meet at a fold are told apart by the stretch: the
        *before* side is the one of smaller stretch (less material in the span,
        as the response diagram is read from left to right). ``waves_before``
        is the fewest helical waves on that arc, back to the previous fold or
        the end of the branch; ``waves_after`` the waves at the fold, which the
        arc of larger stretch leaves with. A fold "adds a wave" when
        ``waves_after > waves_before``. ``unstable_before``, ``unstable_after``:
        the unstable modes on the two sides next to the fold (-1: not counted).
        """
        kinds = self.table["kind"]
        waves = self.table["helical_waves"]
        stretch = self.table["stretch"]
        n = len(kinds)
        fold_idx = [i for i, kd in enumerate(kinds) if kd == Kind.FOLD]
        out = []
        for j, i in enumerate(fold_idx):
            lo = fold_idx[j - 1] + 1 if j > 0 else 0
            hi = fold_idx[j + 1] if j + 1 < len(fold_idx) else n
            prev_arc = list(range(lo, i))
            next_arc = list(range(i + 1, hi))
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
        return out

    @staticmethod
    def _smaller_stretch_side(i, prev_arc, next_arc, stretch):
        if not prev_arc:
            return next_arc
        if not next_arc:
            return prev_arc
        return prev_arc if stretch[prev_arc[-1]] <= stretch[next_arc[0]] else next_arc

    @property
    def branch_points(self) -> list[int]:
        return [i for i, kd in enumerate(self.table["kind"]) if kd == Kind.BRANCH_POINT]
