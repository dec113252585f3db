"""Continue a fold of a stored branch in a second parameter: the fold locus in ``(phi_L, q)``.

Minimally augmented system (:class:`rodcont.bifurcation.FoldProblem`) traced
from the stored fold in both directions of ``q`` within ``[lo, hi]`` (both
bounds located on both sides), starting on the mesh the fold was stored on
(adapted or not). As in a trace, the mesh adapts to the fold state when its
estimated error passes ``max_error / 10`` (``adapt``, up to ``N_max``
subintervals), a point above ``max_error`` is never stored, and the validity
and accuracy guards stop each direction; the file records why each ended.
"""

from __future__ import annotations

import json
import math
import time
from typing import Callable, Sequence

import numpy as np

from ..continuation import ContinuationSettings, Event, Kind, Point, StopContinuation, Tracker
from ..linalg import LU, bordered
from ..mesh import ErrorEstimator
from ..system import RodSystem, RodSystem2, check_number

CURVE_PARAMS = ("gamma", "T", "w", "EI", "GJ", "EA")


def fold_curve(data, fold: int, param: str, lo: float, hi: float, out: str | None = None,
               ds: float = 0.05, ds_max: float = 0.5, max_steps: int = 500, forced: Sequence[float] = (),
               min_alignment: float | None = None, max_error: float = 1e-6, overwrite: bool = False,
               adapt: bool = True, N_max: int = 400, callback: Callable[[Point], None] | None = None) -> dict:
    """Continue the ``fold``-th fold (from 0) of a loaded branch in ``(phi_L, param)`` over ``[lo, hi]``.

    Returns ``{"points": [...], "stop_reasons": (down, up), "param": param}`` with
    the points ordered along the locus; ``out`` writes them as a fold-curve file
    (rows in the order computed; ``arclength`` is negative on the way down).
    """
    if isinstance(fold, bool) or not isinstance(fold, (int, np.integer)):
        raise TypeError(f"fold must be an integer (counted from 0), got {fold!r}")
    if param not in CURVE_PARAMS:
        raise ValueError(f"param must be one of {', '.join(CURVE_PARAMS)}, got {param!r}")
    lo, hi = check_number("lo", lo), check_number("hi", hi)
    ds, ds_max = check_number("ds", ds, positive=True), check_number("ds_max", ds_max, positive=True)
    max_steps = check_number("max_steps", max_steps, integer=True)
    max_error = check_number("max_error", max_error, positive=True)
    if not lo < hi:
        raise ValueError("the range must be given as A B with A < B")
    if ds > ds_max:
        raise ValueError(f"need ds <= ds_max, got {ds:g} > {ds_max:g}")
    if max_steps < 1:
        raise ValueError("max_steps must be >= 1")
    forced = tuple(check_number("forced", v) for v in forced)
    if data.param != "phi_L":
        raise ValueError(f"{data.label} is a {data.attrs.get('kind', 'curve')} in {data.param}, not a branch in "
                         f"phi_L: its folds cannot be continued")
    folds = data.folds
    nf = len(folds.get("index", []))
    if not 0 <= fold < nf:
        raise ValueError(f"{data.label} has {nf} fold(s); fold {fold} (counted from 0) does not exist")
    guard = float(data.attrs.get("min_alignment_guard", 0.05)) if min_alignment is None else min_alignment
    pt = data.point(int(folds["index"][fold]))
    k = int(data.attrs["k"])
    b = pt["breakpoints"]
    one = RodSystem(data.rod, T=data.tension, N=b.size - 1, k=k, breakpoints=b, curve=data.curve, wall=data.wall)
    two = RodSystem2(one, param)
    q0 = two.value()
    if not lo <= q0 <= hi:
        raise ValueError(f"the fold's {param} = {q0:g} is outside the range [{lo:g}, {hi:g}]")
    x0, phi0 = np.asarray(pt["x"], float), float(pt["phi_L"])
    if x0.size != one.disc.size:
        raise ValueError(f"{data.label}: the stored fold does not fit its mesh")
    J, F1, _ = two.tangent(x0, phi0, q0)
    tx, tp = pt["direction"]
    v0 = np.asarray(tx, float) if np.size(tx) == x0.size and np.any(tx != 0) else _fold_null_vector(J, F1)
    from ..bifurcation import FoldProblem
    X0 = np.append(x0, phi0)

    events = [Event(f"validity guard: min d3.K3 reached min_alignment = {guard:g}",
                    lambda q_: q_.data["min_alignment"] - guard, stop=True, tol=1e-6)]
    writer = group = None
    if out is not None:
        from ..branchfile import BranchWriter, check_output
        check_output(out, inputs=[data.path], overwrite=overwrite)
        from .trace import _mesh_group
        meta = dict(kind="fold_curve", gamma=data.gamma, T=data.tension, w=data.rod.w, EI=data.rod.EI,
                    GJ=data.rod.GJ, EA=data.rod.EA, L=data.rod.L, N=int(b.size - 1), k=k, param=param,
                    weight_direction=np.asarray(data.rod.weight_direction), min_alignment_guard=guard,
                    reference=str(data.attrs.get("reference", "straight")),
                    conduit=str(data.attrs.get("conduit", "")),
                    max_error=max_error, source=f"{data.label}: fold {fold}",
                    settings=json.dumps(dict(range=[lo, hi], ds=ds, ds_max=ds_max, max_steps=max_steps,
                                             forced=list(forced), max_error=max_error)))
        writer = BranchWriter(out, meta, min_points=2)
        group = writer.group("/", extra_columns=(param,))
        _mesh_group(writer, one)
    parts, reasons = [], []
    t0 = time.perf_counter()
    trigger = max_error / 10.0
    try:
        for direction in (-1, 1):
            s = ContinuationSettings(ds=ds, ds_min=min(1e-7, ds), ds_max=ds_max, direction=direction, p_min=lo,
                                     p_max=hi, max_steps=max_steps, detect_folds=True, detect_branch_points=False,
                                     forced=forced, max_angle=0.3)
            # each direction from a fresh fold problem: the other direction moved its borders and mesh
            one_d = one.with_mesh(one.disc.breakpoints)
            two_d = RodSystem2(one_d, param)
            seg = _FoldSegment(one_d, two_d, FoldProblem(two_d, x0, phi0, q0, v0), ErrorEstimator(one_d), X0, q0,
                               None)
            pts, reason, remeshes = [], "", 0
            while True:
                tr = Tracker(seg.fp, seg.X, seg.q, s, monitor=seg.monitor, events=events, tangent0=seg.tangent)
                next_seg, last_ok = None, None
                try:
                    for p_ in tr:
                        if p_.kind == Kind.START and (direction > 0 or pts):
                            last_ok = p_
                            continue  # the start point once
                        err = seg.error(p_)
                        p_.data["error"] = err
                        if err > max_error or (err > trigger and adapt):
                            if adapt and seg.one.disc.N < N_max and remeshes < 40:
                                base = last_ok if err > max_error and last_ok is not None else p_
                                keep = err <= max_error
                                next_seg = seg.remeshed(base, max(err, trigger), trigger / 10, N_max)
                                remeshes += 1
                                if not keep:
                                    break
                            elif err > max_error:
                                reason = (f"accuracy guard: estimated error {err:.2g} > max_error = {max_error:g} at "
                                          f"{param} = {p_.p:.10g}" + ("" if adapt else " (the mesh is fixed)"))
                                break
                        p_.data["arclength"] = p_.arclength * direction  # the tracker reads p_.arclength
                        pts.append(p_)
                        last_ok = p_
                        if writer is not None:
                            row = dict(p_.data, dphi_ds=0.0)
                            writer.add_point(group, row, str(p_.kind), p_.located, p_.x[:-1],
                                             np.append(p_.tx[:-1], p_.tx[-1]), seg.one.disc.breakpoints)
                            writer.maybe_flush()
                        if callback is not None:
                            callback(p_)
                        if next_seg is not None:
                            break
                    if next_seg is None:
                        reason = reason or tr.stop_reason
                except StopContinuation as exc:
                    reason = str(exc)
                    next_seg = None
                if next_seg is None:
                    break
                seg = next_seg
            parts.append(pts)
            reasons.append(reason)
    finally:
        if writer is not None:
            writer.close(f"down: {reasons[0] if reasons else 'interrupted'}; "
                         f"up: {reasons[1] if len(reasons) > 1 else 'interrupted'}")
    down, up = parts
    ordered = list(reversed(down)) + up
    return {"points": ordered, "stop_reasons": tuple(reasons), "param": param,
            "elapsed": time.perf_counter() - t0}


def _fold_null_vector(J, F1):
    """Right null vector of ``J`` at a fold: the x part of the tangent of ``[J, F_phi]`` there."""
    n = J.shape[0]
    rng = np.random.default_rng(3)
    c = rng.standard_normal(n + 1)
    e = np.zeros(n + 1)
    e[-1] = 1.0
    t = LU(bordered(J, np.asarray(F1, float), c[:-1], c[-1])).solve(e)
    return t[:-1]


class _FoldSegment:
    """The fold problem on one mesh: the systems, the estimator, where it starts and which way."""

    def __init__(self, one: RodSystem, two: RodSystem2, fp, estimator: ErrorEstimator, X, q, tangent):
        self.one, self.two, self.fp, self.estimator = one, two, fp, estimator
        self.X, self.q, self.tangent = X, q, tangent

    def monitor(self, X, q):
        o = self.two.outputs(X, q)
        o["error"] = math.nan
        return o

    def error(self, pt) -> float:
        """Estimated error of the fold state at ``pt`` (its branch tangent is the null vector ``c``)."""
        self.one.base = self.two.params(float(pt.x[-1]), pt.p)
        self.estimator.fine.base = self.one.base.copy()
        return self.estimator.estimate(pt.x[:-1], float(pt.x[-1]), (self.fp.c, 0.0))

    def remeshed(self, pt, err: float, target: float, N_max: int) -> "_FoldSegment":
        """The same fold problem from ``pt`` on a mesh adapted to the fold state there."""
        from ..bifurcation import FoldProblem
        from ..mesh import adapted_mesh
        x, phi = pt.x[:-1], float(pt.x[-1])
        self.one.base = self.two.params(phi, pt.p)
        ind = self.one.interval_defect(x, phi)
        b = adapted_mesh(self.one.disc.breakpoints, ind, self.one.disc.k, err, target, N_max=N_max)
        one = self.one.with_mesh(self.one.conform(b))
        two = RodSystem2(one, self.two.param)
        xn = one.disc.transfer(x, self.one.disc)
        vn = one.disc.transfer(np.asarray(self.fp.c, float), self.one.disc)
        fp = FoldProblem(two, xn, phi, pt.p, vn)
        tx = np.append(one.disc.transfer(pt.tx[:-1], self.one.disc), pt.tx[-1])
        return _FoldSegment(one, two, fp, ErrorEstimator(one), np.append(xn, phi), pt.p, (tx, pt.tp))
