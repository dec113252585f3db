"""A trip in bit depth: the drill string's equilibrium as its bit runs from one measured depth to another, as one
branch with the parameter ``depth`` (``rodcont trace --param depth --range A B --string S --conduit WELL.toml``).

The string fills the well from the rig to the bit, so each depth has its own span, survey cut, section positions
and joins: the trip marches in depth (natural-parameter continuation), each point an equilibrium of
:func:`rodcont.drilling.torque_and_drag`, by default from its own cold start (``warm=True``: from the previous
depth's solution moved down with the bit, :func:`rodcont.drilling.carried_guess`; Newton needs 5-20 damped
iterations from it for steps of 0.1-5 m, and is slower than a cold start on the wells measured). Slack-off runs from
``A`` down to ``B`` (tripping in), pick-up from ``B`` up to ``A`` (tripping out), other operations from ``A`` to ``B``.

Events along a trip: ``lock_up`` where the hook load reaches zero in slack-off (the string can no longer be pushed
in: located by the secant in depth), and the end of the trip where no equilibrium is found at the next depth even
with its step halved four times (a fold of the trip in depth). The branch table (and file) has per point ``depth``,
``hook_load``, ``surface_torque``, ``side_force``, ``max_joint_side_force``, ``min_gap``, ``contact_zones``, ``T``,
``join_unknowns`` and ``force_scale`` (the contact law's at that point).

The file is self-describing: its root attribute ``drilling`` (JSON, :func:`rodcont.drilling.drilling_record`) holds
the well, the string, the operation, the friction factor, WOB and bit torque, so that each point's system is rebuilt
from its depth, mesh and force scale (:func:`rodcont.drilling.rebuild`; ``rodcont export``). :func:`write_point`
writes one equilibrium in the same layout (``solve --string ... --out F.h5``).
"""

from __future__ import annotations

import math

import numpy as np

from ..blas import with_one_blas_thread
from ..branch import CONTACT_COLUMNS, DRILLING_COLUMNS, Branch
from ..result import Status

TRIP_COLUMNS = ("depth", "T", "join_unknowns", "buckling_ratio", "max_joint_side_force", "force_scale") + \
    CONTACT_COLUMNS + DRILLING_COLUMNS
#: buckling events along a trip: label, the buckling ratio's level (rodcont.drilling.buckling_ratio)
BUCKLING_EVENTS = (("sinusoidal_buckling", 1.0), ("helical_buckling", 2.0 ** 0.5))


def trip_depths(depth_range, operation: str, points: int) -> np.ndarray:
    """``points`` depths from ``A`` to ``B`` (``A < B``), in the order the bit passes them (pick-up: upward)."""
    a, b = (float(v) for v in depth_range)
    if not (0 < a < b and math.isfinite(b)):
        raise ValueError(f"the depth range must be A B with 0 < A < B, got {a:g} {b:g}")
    if int(points) < 2:
        raise ValueError(f"a trip needs at least 2 depths, got {points}")
    d = np.linspace(a, b, int(points))
    return d[::-1] if operation == "pick-up" else d


def trip_row(r, origin: float, joint_length: float = 9.14) -> dict:
    """The branch row of the equilibrium ``r`` (a :class:`rodcont.drilling.TorqueDrag`); ``max_joint_side_force``
    the largest wall force on one joint of ``joint_length`` (:func:`rodcont.drilling.joint_side_forces`' ``side_force``,
    without its located maxima of the force per length, which the row does not keep)."""
    from ..drilling import _join_unknowns, buckling_ratio, collocated_integral, joint_edges
    sysm = r.system
    out = sysm.outputs(r.x, sysm.value())
    out.update(depth=r.depth, T=float(sysm.value()), error=r.error, unstable_modes=-1, arclength=abs(r.depth - origin),
               dphi_ds=0.0, join_unknowns=_join_unknowns(sysm), buckling_ratio=float(np.max(buckling_ratio(r))),
               kind="regular", located=True,
               max_joint_side_force=float(np.max(collocated_integral(sysm, r.x, r.params,
                                                                     joint_edges(r.depth, joint_length)))),
               force_scale=float(sysm.model.contact_scale))
    return out


@with_one_blas_thread
def trip(well, string, depth_range, operation: str = "slack-off", *, points: int = 11, mu=None, out: str | None = None,
         overwrite: bool = False, meta: dict | None = None, warm: bool = False, joint_length: float = 9.14,
         callback=None, resume: Branch | None = None, **options) -> Branch:
    """The trip of ``string`` in ``well`` over ``depth_range = (A, B)`` (m, bit MD) at ``points`` depths for
    ``operation`` (friction factor ``mu``, default the well's; ``options`` go to
    :func:`rodcont.drilling.torque_and_drag`); ``out``: its branch file. ``warm``: start each depth from the
    previous one's solution carried down (off by default: measured slower than a cold start, README).
    ``callback(r, row)`` after each point is recorded (``r`` its :class:`rodcont.drilling.TorqueDrag`; an
    exception from it ends the trip, every point before on disk). ``resume``: the trip's own branch as its file
    holds it (:func:`resume_trip`): its points up to the last depth of the march are kept, the trip goes on from
    there. Returns the :class:`rodcont.branch.Branch` (parameter ``depth``)."""
    from ..drilling import torque_and_drag
    depths = trip_depths(depth_range, operation, points)
    run = _Run(well, string, operation, mu, warm, options, joint_length, float(depths[0]), callback)
    kept, done = _kept(resume, depths) if resume is not None else (0, 1)
    first = run.rebuilt(resume, 0) if resume is not None else \
        torque_and_drag(well, string, float(depths[0]), operation, mu=mu, **options)
    sysm = first.system
    attrs = _attrs(first, operation, meta, well, string,
                   dict(range=[float(v) for v in depth_range], points=int(points), warm=bool(warm),
                        joint_length=float(joint_length), options=options))
    branch = Branch(math.nan, sysm.rod, sysm.disc.N, sysm.disc.k, "depth", attrs=attrs, curve=sysm.curve,
                    wall=sysm.wall)
    writer, run.recorder = _open(out, overwrite, attrs, branch, sysm)
    # an ending the loop does not reach (Ctrl-C, SIGTERM, an error) is said as the traces say it, not as the bound
    status, message = Status.INTERRUPTED, "interrupted"
    try:
        if resume is None:
            prev = run.record(first, "start")
        else:
            if writer is not None:
                writer.min_points = kept  # a kill while copying leaves the old file, not a shorter one
            for i in range(kept):
                run.recorder.copy(resume, i)
            prev = run.rebuilt(resume, kept - 1)
        status, message = _march(run, prev, depths[done - 1:], depths[-1])
    except BaseException as exc:
        message = "interrupted" if isinstance(exc, KeyboardInterrupt) else \
            f"interrupted by {type(exc).__name__}: {exc}"
        raise
    finally:
        branch.status, branch.message = status, message
        if writer is not None:
            run.recorder.sync()
            writer.close(message, status)
    return branch


class _Run:
    """What every solve and record of one trip shares: the well, string, operation, friction and options of
    :func:`rodcont.drilling.torque_and_drag`, the recorder, the joint length, the first depth (a point's
    arclength is its distance from it) and the callback."""

    def __init__(self, well, string, operation, mu, warm, options, joint_length, origin, callback):
        self.well, self.string, self.operation, self.mu, self.warm = well, string, operation, mu, warm
        self.options, self.joint_length, self.origin, self.callback = options, joint_length, origin, callback
        self.recorder = None

    def solve(self, depth: float, near=None):
        """The equilibrium with the bit at ``depth`` (from ``near`` carried down where the trip is warm)."""
        from ..drilling import torque_and_drag
        return torque_and_drag(self.well, self.string, depth, self.operation, mu=self.mu,
                               start=near if self.warm else None, **self.options)

    def record(self, r, kind: str, message: str = ""):
        """``r`` appended to the trip's branch (and file), then the callback; returns ``r``."""
        row = _record(self.recorder, self.joint_length, r, self.origin, kind, message)
        if self.callback is not None:
            self.callback(r, row)
        return r

    def rebuilt(self, branch: Branch, i: int):
        """Point ``i`` of a trip's stored branch as an equilibrium (:func:`rodcont.drilling.rebuild`)."""
        from ..drilling import read_record, rebuild
        t = branch.table
        return rebuild(read_record(branch.attrs["drilling"]), float(t["depth"][i]), branch.meshes[i],
                       branch.coefficients[i], float(t["force_scale"][i]))


def _kept(branch: Branch, depths) -> tuple:
    """``(points kept, depths done)`` of a stored trip on the march ``depths``: its points up to its last one at a
    depth of the march (an event found after it is located again), and how many depths of the march that is."""
    d = np.asarray(branch.table["depth"], float)
    kinds = [str(k) for k in branch.table["kind"]]
    on = [i for i, k in enumerate(kinds) if k in ("start", "regular") and d[i] in depths]
    if not on or on[0] != 0 or d[0] != depths[0]:
        raise ValueError("the stored trip does not start at the first depth of its march")
    last = on[-1]
    return last + 1, int(np.flatnonzero(depths == d[last])[0]) + 1


def _march(run: _Run, prev, depths, bound: float) -> tuple:
    """The trip's points after ``prev`` (at ``depths[0]``), recorded as they come: ``(status, message)`` of its
    end (the bound, a lock-up, or no equilibrium at the next depth)."""
    for d in depths[1:]:
        r, why = _advance(run, prev, float(d))
        if r is None:
            return Status.NO_CONVERGENCE, why
        for label, level in BUCKLING_EVENTS:
            if _ratio(prev) < level <= _ratio(r):
                ev = _locate(run, prev, r, lambda q, v=level: _ratio(q) - v)
                run.record(ev, f"event:{label}", f"{label.replace('_', ' ')} at depth {ev.depth:.6g} m: the "
                           f"compression reaches {level:.4g} times the Dawson-Paslay load somewhere along the string")
        if run.operation == "slack-off" and r.hook_load <= 0 < prev.hook_load:
            lock = _locate(run, prev, r, lambda q: q.hook_load)
            run.record(lock, "event:lock_up", f"lock-up at depth {lock.depth:.6g} m: the hook load reaches zero "
                       f"(the string cannot be pushed further in)")
            return Status.EVENT, f"lock-up at depth {lock.depth:.6g} m"
        prev = run.record(r, "regular" if d != bound else "bound")
    return Status.BOUND, f"parameter bound depth = {bound:g} reached"


def resume_trip(path: str, *, callback=None, check=None) -> Branch:
    """The interrupted trip of the file ``path`` finished in place: its well, string, operation, range and options
    from the file (attributes ``drilling`` and ``trip_run``), its points kept, the march going on from its last
    depth (:func:`trip` with ``resume``); ``check(paths)`` called with the files it reads before it writes. A
    ``ValueError`` (one line) for a file it cannot finish."""
    import json

    from ..branchfile import BranchFileError, load_branch
    from ..drilling import DrillingError, read_record
    from ..restart import unfinished
    try:
        data = load_branch(path)
    except BranchFileError as exc:
        raise ValueError(str(exc)) from None
    if data.param != "depth" or "drilling" not in data.attrs:
        raise ValueError(f"{path} is not a trip in bit depth")
    if str(data.message).startswith("one equilibrium"):  # write_point's file
        raise ValueError(f"{path} holds one equilibrium (rodcont solve --out), not a trip: nothing to resume")
    if "trip_run" not in data.attrs:
        raise ValueError(f"{path} was written before trips could be resumed: run the trip again")
    if not unfinished(data):
        raise ValueError(f"{path} is a finished trip ({data.message or data.status}): nothing to resume")
    if getattr(data, "unverified", False):  # its record would be trusted, and the result stamped as rodcont's
        raise ValueError(f"{path} has lost rodcont's checksum (rewritten by another program or by hand): a trip "
                         f"resumes only from the file rodcont wrote; run it again")
    try:
        rec, run = read_record(data.attrs["drilling"]), json.loads(data.attrs["trip_run"])
        depth_range, points, options = tuple(run["range"]), int(run["points"]), dict(run["options"])
    except (DrillingError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: a damaged trip record ({type(exc).__name__}: {exc})") from None
    if check is not None:
        check([p for p in (rec["well"].survey,) if p])
    meta = {key: data.attrs[key] for key in ("config", "command") if key in data.attrs}
    return trip(rec["well"], rec["string"], depth_range, rec["operation"].name, points=points, mu=rec["mu"],
                out=path, overwrite=True, meta=meta or None, warm=bool(run["warm"]),
                joint_length=float(run["joint_length"]), callback=callback, resume=data, **options)


def write_point(well, string, td, out: str, overwrite: bool = False, meta: dict | None = None,
                joint_length: float = 9.14) -> None:
    """The equilibrium ``td`` (:func:`rodcont.drilling.torque_and_drag` of ``string`` in ``well``) as a one-point
    file in a trip's layout (parameter ``depth``), read back by ``rodcont export`` as a trip's points are."""
    sysm = td.system
    attrs = _attrs(td, td.operation.name, meta, well, string)
    branch = Branch(math.nan, sysm.rod, sysm.disc.N, sysm.disc.k, "depth", attrs=attrs, curve=sysm.curve,
                    wall=sysm.wall)
    writer, recorder = _open(out, overwrite, attrs, branch, sysm)
    try:
        _record(recorder, joint_length, td, td.depth, "start")
    finally:
        recorder.sync()
        writer.close("one equilibrium (rodcont solve)", Status.COMPLETE)  # resume_trip reads this


def _attrs(first, operation, meta, well, string, trip_run: dict | None = None) -> dict:
    """The root attributes of a trip's file: the rod at the rig, the wall of the first depth, the run, the
    drilling record that rebuilds every point (:func:`rodcont.drilling.drilling_record`) and, for a trip,
    ``trip_run`` (JSON: its depth range, points, warm start, joint length and solve options: what
    :func:`resume_trip` goes on with)."""
    import dataclasses
    import json

    from .. import __version__
    from ..drilling import drilling_record
    sysm, rod = first.system, first.system.rod
    wall = dataclasses.replace(sysm.wall, force_scale=sysm.model.contact_scale)
    T = float(sysm.value())
    attrs = dict(kind="branch", gamma=rod.gamma(T) if rod.w > 0 else 0.0, T=T, w=rod.w, EI=rod.EI, GJ=rod.GJ, EA=rod.EA,
                 L=rod.L, N=int(sysm.disc.N), k=int(sysm.disc.k), param="depth",
                 weight_direction=np.asarray(rod.weight_direction), min_alignment_guard=0.0, max_error=first_error(),
                 conduit=wall.spec, reference="straight", operation=operation, trip="depth",
                 drilling=drilling_record(well, string, first),
                 settings=json.dumps(dict(rodcont_version=__version__)))
    if trip_run is not None:
        attrs["trip_run"] = json.dumps(trip_run, default=float)
    attrs.update(meta or {})
    return attrs


def first_error() -> float:
    """The error guard of a trip's solves (:func:`rodcont.drilling.torque_and_drag`'s default)."""
    return 1e-6


def _open(out, overwrite, attrs, branch, sysm):
    from .trace import Recorder, _mesh_group
    if out is None:
        return None, Recorder(branch)
    from ..branchfile import BranchWriter, check_output
    check_output(out, (), overwrite=overwrite)
    writer = BranchWriter(out, attrs)
    group = writer.group("/", extra_columns=TRIP_COLUMNS)
    _mesh_group(writer, sysm)
    return writer, Recorder(branch, writer, group)


def _record(recorder, joint_length, r, origin, kind, message=""):
    row = dict(trip_row(r, origin, joint_length), kind=kind)
    x = r.system.stored(r.x)
    tangent = np.append(np.zeros(x.size), 1.0)  # along the parameter: a restart starts by a step in depth
    recorder.add_row(row, x, tangent, r.system.disc.breakpoints, message)
    return row


def _advance(run: _Run, prev, depth):
    """The equilibrium at ``depth`` from ``prev``: the step halved (up to four times) where no solve converges;
    ``(None, why)`` when none does."""
    from .solve import ConvergenceError
    target, here, why = depth, prev, ""
    for _ in range(5):
        try:
            r = run.solve(target, here)
        except ConvergenceError as exc:
            why = str(exc)
            target = 0.5 * (here.depth + target)
            continue
        if target == depth:
            return r, ""
        here, target = r, depth
    return None, (f"no equilibrium at depth {target:.6g} m (step from {here.depth:.6g} m halved four times: the "
                  f"trip folds in depth or the string cannot be moved there): {why}")


def _ratio(r) -> float:
    from ..drilling import buckling_ratio
    return float(np.max(buckling_ratio(r)))


def _locate(run: _Run, a, b, g, tol: float = 1e-3):
    """The equilibrium between ``a`` and ``b`` where ``g`` (of a :class:`rodcont.drilling.TorqueDrag`; of opposite
    signs at them) is 0: regula falsi in depth (Illinois) until ``|g|`` is within ``tol`` of its scale, or the
    bracket within 1 mm."""
    ga, gb = g(a), g(b)
    scale = max(abs(ga), abs(gb))
    r = a
    for _ in range(10):
        if abs(b.depth - a.depth) < 1e-3:
            break
        d = a.depth + (b.depth - a.depth) * ga / (ga - gb)
        r = run.solve(d, a)
        gr = g(r)
        if abs(gr) <= tol * scale:
            break
        if (gr > 0) == (ga > 0):
            a, ga, gb = r, gr, gb / 2
        else:
            b, gb, ga = r, gr, ga / 2
    return r
