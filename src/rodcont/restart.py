"""Restarts and resumed runs, checked in the library (the command line calls these).

:func:`restart_from` turns a stored point into the arguments of :func:`rodcont.trace`, with the checks a
restart needs: the rod and its tension are the file's (a value given that equals the point's own is no
change; another is refused, with the parameter to trace in instead), so are its spline degree, reference
curve and conduit; ``switch`` needs a branch point; ``N`` carries the point onto another mesh. The trace
options are the file's (its ``settings``) unless given: a restart goes on with the steps, bounds and guards
it was traced with. Every refusal is a ``ValueError`` with a one-line message::

    args = restart_from(rodcont.load_branch("g1.h5"), -1)      # the last point, the file's options
    branch = rodcont.trace(**args, out="more.h5")

:func:`resume` continues an unfinished trace (interrupted, or still marked running after a kill) into
its own file: the points already there are kept and the trace goes on from the last one with the stored
options; a finished branch only with ``extend=True``. :func:`resume_diagram` finishes an interrupted
diagram: its complete branches are kept, the unfinished one is traced again from its seed, the rest traced.
"""

from __future__ import annotations

import json
import math
from dataclasses import fields

import numpy as np

from .result import Status

#: rod and tension inputs a restart keeps (the command line's option names)
ROD_INPUTS = ("gamma", "w", "EI", "GJ", "EA", "L", "T", "weight_direction")
_TRACEABLE = ("gamma", "T", "w", "EI", "GJ", "EA")
_UNFINISHED = (Status.RUNNING, Status.INTERRUPTED)


class StartArguments(dict):
    """Keyword arguments for :func:`rodcont.trace`; ``notes``: what the caller should tell the user
    (a start at a fold of the stored branch), ``inputs``: the files the restart reads."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.notes: list[str] = []
        self.inputs: list[str] = []


def _option_names() -> tuple:
    from .drivers.trace import TraceOptions
    return tuple(f.name for f in fields(TraceOptions))


def stored_options(data) -> dict:
    """The trace options a branch was traced with (its ``settings``; empty for files written before them)."""
    trace = dict(getattr(data, "settings", {}).get("trace", {}) or {})
    names = _option_names()
    out = {k: v for k, v in trace.items() if k in names}
    if isinstance(out.get("forced"), list):
        out["forced"] = tuple(out["forced"])
    if isinstance(out.get("p_range"), list):
        out["p_range"] = tuple(out["p_range"])
    return out


def carried_options(data, param: str, options: dict | None = None, pt: dict | None = None) -> dict:
    """The options of a restart in ``param``: the file's, overridden by ``options`` (those given).

    The direction is the restart's own; the range of a parameter is carried only for a restart in the
    stored branch's parameter. The file's ``stretch_max`` is not carried when the start point ``pt``
    already reached it (the point that stopped that trace starts this one: test_every_stored_point_is_a_valid_start).
    A first step the given ``ds_max`` (or ``ds_min``) excludes is brought inside it, unless ``ds`` was
    given too."""
    given = dict(options or {})
    out = stored_options(data)
    out.pop("direction", None)
    if param != data.param or out.get("p_range") is None:
        out.pop("p_range", None)
    smax = out.get("stretch_max")
    if smax is not None and pt is not None and float(pt.get("stretch", -math.inf)) >= float(smax) * (1 - 1e-9):
        out.pop("stretch_max")
    out.update(given)
    if "ds" not in given and {"ds", "ds_max", "ds_min"} <= set(out):
        out["ds"] = min(max(out["ds"], out["ds_min"]), out["ds_max"])
    return out


def rod_at_point(data, pt):
    """The rod of stored point ``pt``: the file's, with the continued rod parameter at the point's value."""
    from .rod import RodParameters
    r = data.rod
    a = dict(EI=r.EI, GJ=r.GJ, EA=r.EA, w=r.w, L=r.L, weight_direction=r.weight_direction)
    if data.param in ("EI", "GJ", "EA", "w"):
        a[data.param] = float(pt[data.param])
    return RodParameters(**a)


def tension_at_point(data, pt) -> float:
    """The tension of stored point ``pt`` (its own in a trace in ``T`` or ``gamma``, else the file's)."""
    if data.param == "T":
        return float(pt["T"])
    if data.param == "gamma":
        return float(pt["gamma"]) * data.rod.w * data.rod.L
    if "T" in pt and isinstance(pt["T"], (int, float)) and math.isfinite(pt["T"]):
        return float(pt["T"])  # a length-controlled branch stores its tension per point
    return data.tension


def _param_value(param: str, rod, T: float, pt) -> float:
    if param in ("torque", "l0"):
        return float(pt[param])
    return {"T": T, "gamma": rod.gamma(T), "w": rod.w, "EI": rod.EI, "GJ": rod.GJ, "EA": rod.EA}[param]


def check_changes(data, pt, changes: dict, spec: str) -> None:
    """Refuse rod or tension values that differ from the point's own (relative 1e-12): a restart keeps its rod."""
    rod, T = rod_at_point(data, pt), tension_at_point(data, pt)
    stored = dict(w=rod.w, EI=rod.EI, GJ=rod.GJ, EA=rod.EA, L=rod.L, T=T,
                  gamma=T / (rod.w * rod.L) if rod.w > 0 else None, weight_direction=tuple(rod.weight_direction))
    unknown = sorted(set(changes) - set(ROD_INPUTS))
    if unknown:
        raise TypeError(f"restart_from: unknown rod input(s) {', '.join(unknown)} (known: {', '.join(ROD_INPUTS)})")

    def same(name):
        a, b = changes[name], stored[name]
        if a is None or b is None:
            return False
        try:
            return bool(np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-12, atol=0.0))
        except (TypeError, ValueError):
            return False

    changed = [n for n in ROD_INPUTS if n in changes and not same(n)]
    if changed:
        names = ", ".join("--" + n.replace("_", "-") for n in changed)
        traceable = [n for n in _TRACEABLE if n in changed]
        raise ValueError(f"{names} {'differs' if len(changed) == 1 else 'differ'} from the start file's; a restart "
                         f"keeps its rod and tension: "
                         + (f"to change it, trace in that parameter from the point (--start {spec} --param "
                            f"{traceable[0]} --range A B)" if traceable else
                            "the span and the weight's direction are fixed along a branch (trace anew)"))


def _controls(data) -> dict:
    try:
        spec = json.loads(str(data.attrs.get("controls", "") or "{}"))
    except ValueError:
        return {}
    return spec if isinstance(spec, dict) else {}


def restart_from(data, label=-1, *, param: str = "phi_L", direction=1, switch: bool = False, N: int | None = None,
                 k: int | None = None, changes: dict | None = None, reference: str | None = None,
                 conduit: str | None = None, options: dict | None = None, spec: str | None = None) -> StartArguments:
    """The arguments of :func:`rodcont.trace` that restart from point ``label`` of ``data`` (a branch, in
    memory or read from a file; ``label`` an index, ``F<j>``, ``BP<j>``), continued in ``param``.

    ``direction``: +1 (``"up"``: on along the stored branch, or up in a new parameter) or -1 (``"down"``:
    back along it); ``switch``: leave a branch point along the other branch; ``N``: the mesh to carry the
    point onto (default its own); ``k``, ``changes`` (rod and tension values: ``gamma, w, EI, GJ, EA, L, T,
    weight_direction``), ``reference``, ``conduit``: what the caller gave, checked against the file's;
    ``options``: trace options given (:class:`rodcont.TraceOptions` fields), the rest carried from the
    file (:func:`carried_options`). ``spec``: how the caller named the point, for messages.
    ``ValueError`` (one line) for a restart that cannot be made.
    """
    from .drivers import trace as _trace
    params = getattr(_trace, "TRACE_PARAMS", _trace.SYSTEM_PARAMS)
    spec = spec or f"{getattr(data, 'label', 'the branch')}:{label}"
    direction = {"up": 1, "down": -1}.get(direction, direction)
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1 ('up' or 'down'), got {direction!r}")
    if param not in params:
        raise ValueError(f"param must be one of {', '.join(params)}, got {param!r}")
    if data.attrs.get("kind") == "fold_curve" and data.param != "phi_L":
        raise ValueError(f"{data.path} is a fold curve in {data.param}, not a branch: it cannot start a trace")
    pt = data.point(label)
    check_changes(data, pt, dict(changes or {}), spec)
    kfile = int(data.attrs.get("k", getattr(data, "k", 5)))
    if k is not None and int(k) != kfile:
        raise ValueError(f"--k {k} differs from the start file's k = {kfile}: a restart keeps its spline degree "
                         f"(--N chooses another mesh)")
    if switch and pt["kind"] != "branch_point":
        raise ValueError(f"--switch needs a branch point (BP<j>); point {label} is a {pt['kind']} point")
    if reference is not None and str(reference).strip() != "straight":
        raise ValueError("a restart keeps the start file's reference curve: drop --reference")
    if conduit is not None:
        raise ValueError("a restart keeps the start file's conduit: drop --conduit")
    rod, T = rod_at_point(data, pt), tension_at_point(data, pt)
    out = StartArguments(gamma=None, rod=rod, k=kfile, T=T, param=param, curve=data.curve, wall=data.wall,
                         switch=bool(switch))
    out.inputs = [p for p in (getattr(data, "path", ""),) if p]
    from .safeio import curve_files
    out.inputs += curve_files(out["curve"])
    controls = _controls(data)
    if controls.get("axial") == "l0" and param not in ("T", "gamma"):
        out["l0"], out["T"] = float(controls["l0"]), None
    if controls.get("twist") == "torque" and param not in ("phi_L", "torque"):
        out["torque"] = float(pt.get("torque", controls.get("torque", 0.0)))
    value = float(pt[data.param]) if data.param != "phi_L" else float(pt["phi_L"])
    if param == "phi_L":
        value = float(pt["phi_L"])
    else:
        value = _param_value(param, rod, T, pt)
        out["phi_L"] = float(pt["phi_L"])
    if pt["kind"] == "fold" and param != data.param:
        out.notes.append(f"point {label} is a fold of the stored branch, where the Jacobian is singular: it is a "
                         f"fold in {param} too, which moves the same way on both sides of it; --direction up "
                         f"and down follow the two sides")
    tangent = pt["direction"] if param == data.param else None
    if tangent is not None and direction == -1:
        tangent = (-np.asarray(tangent[0]), -tangent[1])
    b, x0 = np.asarray(pt["breakpoints"], float), np.asarray(pt["x"], float)
    if N is not None and int(N) != b.size - 1:
        x0, tangent, b = _carried(data, rod, T, kfile, b, x0, tangent, int(N))
    out.update(N=b.size - 1, start=(x0, value, tangent), breakpoints=b)
    opts = carried_options(data, param, options, pt)
    opts["direction"] = direction
    out.update(opts)
    store_every = data.attrs.get("store_every", 1)
    if "store_every" in (options or {}):
        store_every = options["store_every"]
    out["store_every"] = int(store_every) if isinstance(store_every, (int, np.integer, float)) else 1
    return out


def _carried(data, rod, T, k, b, x0, tangent, N):
    """The point (and its tangent) moved onto a uniform mesh of ``N`` subintervals."""
    from .system import RodSystem
    src = RodSystem(rod, T=T, N=b.size - 1, k=k, breakpoints=b, curve=data.curve, wall=data.wall)
    dst = RodSystem(rod, T=T, N=N, k=k, curve=data.curve, wall=data.wall)
    x = dst.disc.transfer(x0, src.disc) if x0.size == src.disc.size else x0
    if tangent is not None and np.asarray(tangent[0]).size == src.disc.size:
        tangent = (dst.disc.transfer(np.asarray(tangent[0]), src.disc), tangent[1])
    return x, tangent, dst.disc.breakpoints


def start_hint(message: str) -> str:
    """What to add to a restart's failure to start: its bounds and guards are the file's unless given."""
    if "reached at the start" in message or "is outside the bounds" in message:
        return ("; a restart keeps the start file's bounds: give --phi-max / --phi-min (or --range) to go "
                "further")
    if "(already at the start)" in message:
        return "; the point is on that guard: --direction down goes back along the branch"
    return ""


# --------------------------------------------------------------------------
# Resuming a trace into its own file
# --------------------------------------------------------------------------
def unfinished(data) -> bool:
    """Did the run that wrote ``data`` stop before its end (interrupted, or killed while running)?"""
    return data.status in _UNFINISHED


def resume(path: str, *, extend: bool = False, changes: dict | None = None, options: dict | None = None,
           callback=None, check=None, data=None):
    """Continue the trace in ``path`` into the same file: its points kept, the trace going on from the last one
    with the stored options (``options`` override them); returns the whole branch.

    An unfinished trace (interrupted, or killed while running) goes on; a finished one only with
    ``extend=True`` (e.g. with a larger ``phi_max``). ``changes``: rod and tension values given, refused if
    they differ from the file's. ``check(args)``: called with the start arguments before the file is
    touched (the command line checks its output there). ``data``: ``path`` as already read (a diagram or a
    branch). ``ValueError`` for a file that cannot be resumed.
    """
    from .branchfile import load_diagram
    from .drivers.trace import trace
    d = data if data is not None else load_diagram(path)
    kind = d.attrs.get("kind", "branch")
    if kind == "diagram":
        raise ValueError(f"{path} is a diagram: resume it with rodcont diagram --resume {path}")
    if kind not in ("branch",):
        raise ValueError(f"{path} is a {str(kind).replace('_', ' ')} file, not a trace: it cannot be resumed")
    data = d.branches[0] if hasattr(d, "branches") else d
    if len(data) == 0:
        raise ValueError(f"{path} holds no point to resume from")
    if not unfinished(data) and not extend:
        raise ValueError(f"{path} is a finished branch ({data.stop_reason}): --extend continues it past its end "
                         f"(with options that let it go on: a larger --phi-max, --max-steps, ...)")
    args = restart_from(data, -1, param=data.param, direction=1, changes=changes, options=options,
                        spec=f"{path}:-1")
    if check is not None:
        check(args)
    meta = {"config": str(data.attrs.get("config", ""))} if "config" in data.attrs else None
    return trace(**args, out=path, overwrite=True, meta=meta, callback=callback, resume=data)


def continuing(recorder, prefix, *, extend: bool = False):
    """A recorder that writes the points of ``prefix`` (a branch read from the file being resumed) before the
    new ones: all but the last are copied; the run's start, the last point converged again, takes the last
    one's place, kind and arclength. The file is published only once it holds every old point again."""
    from .drivers.trace import Recorder

    class Continuing(Recorder):
        def __init__(self):
            super().__init__(recorder.branch, recorder.writer, recorder.group, recorder.contact, recorder.thin)
            self.first = True
            n = len(prefix)
            self.branch.missed_crossings.extend(prefix.missed_crossings)
            self.branch.unlocated.extend(prefix.unlocated)
            if self.writer is not None:
                self.writer.min_points = n  # a kill while copying leaves the old file, not a shorter one
            if self.contact is not None:
                _prefill_contact(self.contact, prefix, n - 1)
            for i in range(n - 1):
                self.copy(prefix, i)

        def add(self, pt, problem) -> int:
            if not self.first:
                return super().add(pt, problem)
            self.first = False
            i = len(prefix) - 1
            kind = str(prefix.table["kind"][i])
            keep = kind in ("fold", "branch_point", "forced") or kind.startswith("event:contact") or i == 0
            pt.arclength = float(prefix.table["arclength"][i])  # the points after it go on from there
            own = pt.kind, pt.located, pt.message
            pt.kind = kind if keep else "regular"
            pt.located = bool(prefix.table["located"][i]) if keep else True
            pt.message = prefix.messages.get(i, "") if keep else ""
            try:
                return super().add(pt, problem)
            finally:
                pt.kind, pt.located, pt.message = own

    return Continuing()


def _prefill_contact(contact, prefix, n: int) -> None:
    """The contact rows of the first ``n`` points of ``prefix`` from its file (a thinned point has no solution
    to compute them from)."""
    import h5py
    try:
        with h5py.File(prefix.path, "r") as f:
            g = f["contact"]
            prof = {name: np.asarray(g[name][:n], np.float32) for name in ("pressure", "gap", "axial_force",
                                                                         "torque")}
            zones = np.asarray(g["zones"][()], float).reshape(-1, 4)
    except (OSError, KeyError, ValueError):
        return  # no stored rows: they are computed from the solutions
    if any(v.shape[0] != n for v in prof.values()):
        return
    contact.profiles = [{name: prof[name][i] for name in prof} for i in range(n)]
    contact.zones = [tuple(z) for z in zones if int(z[0]) < n]


# --------------------------------------------------------------------------
# Finishing an interrupted diagram
# --------------------------------------------------------------------------
def resume_diagram(path: str, *, changes: dict | None = None, options: dict | None = None, callback=None,
                   progress=None, check=None, data=None):
    """Finish the interrupted diagram in ``path``, into the same file: its complete branches kept (not traced
    again), the unfinished one traced again from its seed, the rest traced, with the file's rod, tension,
    mesh and options (``options``, ``changes``: values given, refused where they differ from the file's).
    Returns the :class:`rodcont.drivers.diagram.Diagram`; ``data``: ``path`` as already read."""
    from .branchfile import load_diagram
    from .drivers.diagram import DiagramBranch, diagram
    d = data if data is not None else load_diagram(path)
    if d.attrs.get("kind") != "diagram":
        raise ValueError(f"{path} is not a diagram file: resume a trace with rodcont trace --resume {path}")
    status = d.attrs.get("status")
    if status not in (Status.RUNNING.value, Status.INTERRUPTED.value):
        raise ValueError(f"{path} is a complete diagram ({d.attrs.get('stop_reason')}): nothing to resume")
    first = d.branches[0]
    rod, T = first.rod, float(d.attrs["T"])
    pt = dict(T=T)
    check_changes(_Frame(first, rod, T), pt, dict(changes or {}), path)
    stored = stored_options(first)
    stored.pop("direction", None)
    stored.pop("p_range", None)
    for name, v in (options or {}).items():
        if name not in stored or not _same_value(v, stored[name]):
            shown = f"{stored[name]!r}" if name in stored else "unset"
            raise ValueError(f"--{name.replace('_', '-')} differs from the diagram file's ({shown}): a resumed "
                             f"diagram keeps its options (drop it)")
    done = [DiagramBranch(b, str((b.group_attrs or {}).get("origin", "")), (b.message_first, b.message))
            for b in d.branches if b.status not in _UNFINISHED and b.group_attrs is not None]
    if check is not None:
        check(dict(rod=rod, T=T))
    deflate = [float(v) for v in np.atleast_1d(d.attrs.get("deflate_at", []))]
    meta = {"config": str(d.attrs.get("config", ""))} if "config" in d.attrs else None
    return diagram(None, rod, int(d.attrs["N"]), int(d.attrs["k"]), T=T, out=path, overwrite=True,
                   deflate_at=deflate, callback=callback, progress=progress, meta=meta,
                   store_every=int(d.attrs.get("store_every", 1)), resumed=done, jobs=1, **stored)


class _Frame:
    """What :func:`check_changes` reads of a branch, with the diagram's rod and tension."""

    def __init__(self, branch, rod, T):
        self.rod, self.tension, self.param = rod, T, "phi_L"
        self.attrs = branch.attrs


def _same_value(a, b) -> bool:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same_value(u, v) for u, v in zip(a, b))
    if isinstance(a, bool) or isinstance(b, bool) or a is None or b is None:
        return a == b
    try:
        return bool(np.isclose(float(a), float(b), rtol=1e-12, atol=0.0))
    except (TypeError, ValueError):
        return a == b
