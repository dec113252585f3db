"""HDF5 branch files: written point by point as a trace goes, readable at any moment.

Layout (names are read by other tools; keep them)::

    /                      attrs: rodcont_version, gamma, w, EI, GJ, EA, L, N, k,
                                  stop_reason, param, weight_direction, min_alignment_guard
    /branch/phi_L          (n,)   imposed end rotation, rad
    /branch/stretch        (n,)   (l - L) / L
    /branch/torque         (n,)   axial moment GJ u3
    /branch/l0             (n,)   unstressed length inside the span
    /branch/helical_waves  (n,)   int
    /branch/min_alignment  (n,)   min over S of d3 . K3
    /branch/arclength      (n,)   pseudo-arclength of the tracker
    /branch/defect         (n,)   relative residual between collocation points (error indicator)
    /branch/kind           (n,)   bytes: start, regular, fold, branch_point, forced, bound, event:...
    /branch/coefficients   (n, m) unknown vector x (B-spline coefficients, see /mesh)
    /branch/breakpoints    (n, N+1) the partition each point was computed on (moves with --adapt)
    /branch/dphi_ds        (n,)   parameter component of the unit tangent (0 at a fold)
    /folds/phi_L, stretch, torque, l0, waves_before, waves_after, index
    /branch_points/index, phi_L, stretch
    /mesh/breakpoints      (N+1,) attrs: k, orders, fields, layout

Datasets are chunked, gzip-compressed and flushed after every point, so an
interrupted run leaves a valid file holding every completed point.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import h5py
import numpy as np

from . import __version__
from .rod import FIELDS, ORDERS, RodParameters

SCALARS = ("phi_L", "stretch", "torque", "l0", "min_alignment", "arclength", "defect", "dphi_ds")
FOLD_FIELDS = ("phi_L", "stretch", "torque", "l0", "waves_before", "waves_after", "index")


class BranchFileError(Exception):
    """A file that cannot be read as a branch file (message says why)."""


class BranchWriter:
    """Appends points to a branch file; ``close(stop_reason)`` ends it.

    ``meta``: root attributes (gamma, rod parameters, N, k, ...).
    """

    def __init__(self, path: str, meta: dict, size: int, breakpoints: np.ndarray, extra_columns: tuple = ()):
        self.path = path
        self.f = h5py.File(path, "w")
        self.f.attrs["rodcont_version"] = __version__
        self.f.attrs["stop_reason"] = "running"
        for key, val in meta.items():
            self.f.attrs[key] = val
        g = self.f.create_group("branch")
        self.columns = SCALARS + tuple(extra_columns)
        for name in self.columns:
            g.create_dataset(name, (0,), maxshape=(None,), dtype="f8", chunks=(256,), compression="gzip")
        g.create_dataset("helical_waves", (0,), maxshape=(None,), dtype="i4", chunks=(256,), compression="gzip")
        g.create_dataset("kind", (0,), maxshape=(None,), dtype="S32", chunks=(256,), compression="gzip")
        g.create_dataset("coefficients", (0, size), maxshape=(None, size), dtype="f8",
                         chunks=(16, size), compression="gzip", shuffle=True)
        nb = len(breakpoints)
        g.create_dataset("breakpoints", (0, nb), maxshape=(None, nb), dtype="f8", chunks=(64, nb), compression="gzip")
        fo = self.f.create_group("folds")
        for name in FOLD_FIELDS:
            dt = "f8" if name in ("phi_L", "stretch", "torque", "l0") else "i8"
            fo.create_dataset(name, (0,), maxshape=(None,), dtype=dt, chunks=(64,))
        bp = self.f.create_group("branch_points")
        for name in ("index", "phi_L", "stretch"):
            bp.create_dataset(name, (0,), maxshape=(None,), dtype="i8" if name == "index" else "f8", chunks=(64,))
        mesh = self.f.create_group("mesh")
        mesh.create_dataset("breakpoints", data=np.asarray(breakpoints, float))
        mesh.attrs["orders"] = np.asarray(ORDERS)
        mesh.attrs["fields"] = ",".join(FIELDS)
        mesh.attrs["layout"] = "rodcont.collocation.Collocation interleaved coefficients"
        self.n = 0
        self.f.flush()

    @staticmethod
    def _append(ds, value):
        n = ds.shape[0]
        ds.resize(n + 1, axis=0)
        ds[n] = value

    def add(self, data: dict, kind: str, x: np.ndarray, breakpoints: np.ndarray | None = None):
        g = self.f["branch"]
        for name in self.columns:
            self._append(g[name], float(data[name]))
        self._append(g["helical_waves"], int(data["helical_waves"]))
        self._append(g["kind"], kind.encode()[:32])
        self._append(g["coefficients"], x)
        self._append(g["breakpoints"], self.f["mesh/breakpoints"][()] if breakpoints is None else breakpoints)
        self.n += 1
        self.f.flush()

    def add_fold(self, fold: dict) -> None:
        fo = self.f["folds"]
        for name in FOLD_FIELDS:
            self._append(fo[name], fold[name])
        self.f.flush()

    def add_branch_point(self, index: int, data: dict) -> None:
        bp = self.f["branch_points"]
        self._append(bp["index"], index)
        self._append(bp["phi_L"], data["phi_L"])
        self._append(bp["stretch"], data["stretch"])
        self.f.flush()

    def set_attr(self, key, value) -> None:
        self.f.attrs[key] = value
        self.f.flush()

    def close(self, stop_reason: str) -> None:
        if self.f:
            self.f.attrs["stop_reason"] = stop_reason
            self.f.close()
            self.f = None


@dataclass
class BranchData:
    """A branch file read into memory."""

    path: str
    attrs: dict
    branch: dict
    folds: dict
    branch_points: dict
    breakpoints: np.ndarray

    def __len__(self) -> int:
        return len(self.branch["phi_L"])

    @property
    def rod(self) -> RodParameters:
        a = self.attrs
        return RodParameters(EI=a["EI"], GJ=a["GJ"], EA=a["EA"], w=a["w"], L=a["L"],
                             weight_direction=tuple(a.get("weight_direction", (0.0, 0.0, -1.0))))

    @property
    def gamma(self) -> float:
        return float(self.attrs["gamma"])

    def resolve(self, label: str | int) -> int:
        """Point index of ``label``: an integer (point, from 0; negative from the end),
        ``F<j>`` the j-th fold or ``BP<j>`` the j-th branch point (both counted from 1)."""
        s = str(label).strip()
        n = len(self)
        try:
            if s.upper().startswith("BP"):
                j = int(s[2:])
                idx = self.branch_points["index"]
                if not 1 <= j <= len(idx):
                    raise BranchFileError(f"{self.path} has {len(idx)} branch point(s); {s} does not exist")
                return int(idx[j - 1])
            if s.upper().startswith("F"):
                j = int(s[1:])
                idx = self.folds["index"]
                if not 1 <= j <= len(idx):
                    raise BranchFileError(f"{self.path} has {len(idx)} fold(s); {s} does not exist")
                return int(idx[j - 1])
            i = int(s)
        except ValueError:
            raise BranchFileError(f"point label {s!r}: expected an integer index, F<j> or BP<j>") from None
        if not -n <= i < n:
            raise BranchFileError(f"{self.path} has {n} point(s); index {i} is out of range")
        return i % n

    def point(self, label) -> dict:
        i = self.resolve(label)
        out = {name: self.branch[name][i] for name in self.branch if self.branch[name].ndim == 1}
        out["x"] = self.branch["coefficients"][i]
        out["breakpoints"] = self.branch["breakpoints"][i] if "breakpoints" in self.branch else self.breakpoints
        out["index"] = i
        out["direction"] = self.direction(i)
        return out

    def direction(self, i: int) -> tuple[np.ndarray, float]:
        """Direction of travel at point ``i``: the secant from the previous point
        (from point 0: towards the next one, or increasing phi_L)."""
        X, P = self.branch["coefficients"], self.branch["phi_L"]
        B = self.branch.get("breakpoints")

        def same_mesh(a, b):  # coefficients on different meshes cannot be subtracted
            return B is None or np.array_equal(B[a], B[b])

        if i > 0 and same_mesh(i, i - 1):
            return X[i] - X[i - 1], float(P[i] - P[i - 1])
        if i + 1 < len(P) and same_mesh(i, i + 1):
            return X[i + 1] - X[i], float(P[i + 1] - P[i])
        dphi = float(P[i] - P[i - 1]) if i > 0 else 1.0
        return np.zeros_like(X[0]), 1.0 if dphi >= 0 else -1.0


def load_branch(path: str) -> BranchData:
    """Read a branch file; raises :class:`BranchFileError` with a one-line reason if it is not one."""
    if not os.path.exists(path):
        raise BranchFileError(f"{path}: no such file")
    if not os.path.isfile(path):
        raise BranchFileError(f"{path}: not a file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise BranchFileError(f"{path}: not a readable HDF5 file ({str(exc).split(':')[0]})") from None
    with f:
        if "rodcont_version" not in f.attrs or "branch" not in f:
            raise BranchFileError(f"{path}: an HDF5 file, but not a rodcont branch file")
        try:
            attrs = {k: _plain(v) for k, v in f.attrs.items()}
            branch = {k: f["branch"][k][()] for k in f["branch"]}
            folds = {k: f["folds"][k][()] for k in f["folds"]} if "folds" in f else {}
            bps = {k: f["branch_points"][k][()] for k in f["branch_points"]} if "branch_points" in f else {"index": np.zeros(0, int)}
            breakpoints = f["mesh"]["breakpoints"][()] if "mesh" in f else None
        except (KeyError, OSError) as exc:
            raise BranchFileError(f"{path}: damaged branch file ({exc})") from None
    lengths = {k: len(v) for k, v in branch.items()}
    n = min(lengths.values()) if lengths else 0
    branch = {k: v[:n] for k, v in branch.items()}  # an interrupted write may leave one column longer
    if "kind" in branch:
        branch["kind"] = np.array([k.decode() if isinstance(k, bytes) else str(k) for k in branch["kind"]])
    return BranchData(path, attrs, branch, folds, bps, breakpoints)


def _plain(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v
