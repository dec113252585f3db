"""Continue a fold of a stored branch in a second parameter: the fold locus in ``(phi_L, q)``.

Minimally augmented system (:class:`rodcont.bifurcation.FoldProblem`, a meshed problem) traced
by the generic adaptive engine (:mod:`rodcont.adaptive`) from the stored fold in both
directions of ``q`` within ``[lo, hi]`` (both bounds located on both sides), starting on the
mesh the fold was stored on (adapted or not). As in a trace, the mesh adapts to the fold state
when its estimated error (measured at every point) passes ``max_error / 10`` (``adapt``, up to
``N_max`` subintervals), a point above ``max_error`` is never stored, and the validity and
accuracy guards stop each direction. The result is a :class:`rodcont.branch.Branch` in ``q``
ordered along the locus (the way down reversed, then the way up; ``arclength`` negative on
the way down), as its file is; ``status_first``/``message_first`` say why the way down ended,
``status``/``message`` the way up.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence

import numpy as np

from ..adaptive import AdaptiveContinuation, AdaptiveSettings, StartError
from ..blas import with_one_blas_thread
from ..branch import Branch
from ..continuation import ContinuationSettings, Event, Kind, Point
from ..linalg import LU, bordered
from ..result import Status
from ..system import RodSystem, RodSystem2, check_callable, check_number, check_numbers
from .trace import Recorder

CURVE_PARAMS = ("gamma", "T", "w", "EI", "GJ", "EA")


@with_one_blas_thread
def fold_curve(data, fold: int | str, param: str, lo: float, hi: float, out: str | None = None,
               ds: float = 0.05, ds_max: float = 0.5, max_steps: int = 500, forced: Sequence[float] = (),
               min_alignment: float | None = None, max_error: float = 1e-6, overwrite: bool = False,
               adapt: bool = True, N_max: int = 400, callback: Callable[[Point], None] | None = None) -> Branch:
    """Continue fold ``fold`` of a branch (in memory or loaded) in ``(phi_L, param)`` over ``[lo, hi]``.

    ``fold``: its number from 0, or its label ``F<j>`` (from 1). Returns a
    :class:`rodcont.branch.Branch` in ``param`` (rows along the locus); ``out`` writes it as a
    fold-curve file.
    """
    if not isinstance(data, Branch):
        raise TypeError(f"data must be a branch (rodcont.trace's result, or rodcont.load_branch(path)), "
                        f"got {type(data).__name__}")
    fold = _fold_number(fold)
    if param not in CURVE_PARAMS:
        raise ValueError(f"param must be one of {', '.join(CURVE_PARAMS)}, got {param!r}")
    lo, hi = check_number("lo", lo), check_number("hi", hi)
    ds, ds_max = check_number("ds", ds, positive=True), check_number("ds_max", ds_max, positive=True)
    max_steps = check_number("max_steps", max_steps, integer=True)
    max_error = check_number("max_error", max_error, positive=True)
    N_max = check_number("N_max", N_max, integer=True)
    if N_max < 1:
        raise ValueError(f"N_max (most subintervals) must be an integer >= 1, got {N_max}")
    if not lo < hi:
        raise ValueError("the range must be given as A B with A < B")
    if ds > ds_max:
        raise ValueError(f"need ds <= ds_max, got {ds:g} > {ds_max:g}")
    if max_steps < 1:
        raise ValueError("max_steps must be >= 1")
    forced = check_numbers("forced", forced)
    check_callable("callback", callback, "a function of the point")
    if min_alignment is not None:
        min_alignment = check_number("min_alignment", min_alignment)
        if not 0 <= min_alignment < 1:
            raise ValueError(f"min_alignment must be in [0, 1), got {min_alignment!r}")
    start = _FoldStart(data, fold, param, lo, hi)
    guard = float(data.attrs.get("min_alignment_guard", 0.05)) if min_alignment is None else min_alignment
    settings = dict(range=[lo, hi], ds=ds, ds_max=ds_max, max_steps=max_steps, forced=list(forced),
                    max_error=max_error)
    steps = ContinuationSettings(ds=ds, ds_min=min(1e-7, ds), ds_max=ds_max, p_min=lo, p_max=hi, max_steps=max_steps,
                                 detect_folds=True, detect_branch_points=False, forced=forced, max_angle=0.3)
    # the locus's own folds (cusps) are located to the guard, not to a branch's fold_error
    adaptive = AdaptiveSettings(max_error=max_error, fold_error=max_error, adapt=adapt, N_max=N_max, measure_every=1)
    meta = _file_meta(data, start, param, guard, max_error, fold, settings)
    result = Branch(data.gamma, data.rod, start.N, start.k, param, attrs=meta, curve=data.curve, wall=data.wall)
    result.settings.update(fold_curve=settings)
    events = [Event(f"validity guard: min d3.K3 reached min_alignment = {guard:g}",
                    lambda q_: q_.data["min_alignment"] - guard, stop=True, tol=1e-6, label="validity_guard",
                    status=Status.VALIDITY_GUARD)]
    writer, recorder = _open(out, data, meta, result, start, overwrite)

    def one_way(direction, rec):
        _run_way(start, dataclasses.replace(steps, direction=direction), adaptive, events, rec, callback)

    try:
        _both_ways(one_way, result, recorder)
    finally:
        if writer is not None:
            writer.set_attr("status_first", str(result.status_first or Status.INTERRUPTED))
            writer.close(f"down: {result.message_first or 'interrupted'}; up: {result.message or 'interrupted'}",
                         result.status if result.message else Status.INTERRUPTED)
    return result


def _fold_number(fold) -> int:
    """A fold's number from 0 (``F<j>`` counts from 1)."""
    if isinstance(fold, str) and fold.strip().upper().startswith("F") and fold.strip()[1:].isdigit():
        return int(fold.strip()[1:]) - 1
    if isinstance(fold, bool) or not isinstance(fold, (int, np.integer)):
        raise TypeError(f"fold must be an integer (counted from 0) or F<j> (from 1), got {fold!r}")
    return int(fold)


class _FoldStart:
    """The stored fold a locus starts from: its state, null vector and mesh."""

    def __init__(self, data, fold: int, param: str, lo: float, hi: float):
        if data.param != "phi_L":
            raise ValueError(f"{data.label} is a {data.attrs.get('kind', 'curve')} in {data.param}, not a branch in "
                             f"phi_L: its folds cannot be continued")
        nf = len(data.folds.get("index", []))
        if not 0 <= fold < nf:
            raise ValueError(f"{data.label} has {nf} fold(s); fold {fold} (counted from 0; F{fold + 1} as folds "
                             f"labels it) does not exist")
        pt = data.point(int(data.folds["index"][fold]))
        self.k = int(data.attrs["k"]) if "k" in data.attrs else int(data.k)
        b = pt["breakpoints"]
        self.N = b.size - 1
        self.one = RodSystem(data.rod, T=data.tension, N=self.N, k=self.k, breakpoints=b, curve=data.curve,
                             wall=data.wall)
        self.param = param
        two = RodSystem2(self.one, param)
        self.q0 = two.value()
        if not lo <= self.q0 <= hi:
            raise ValueError(f"the fold's {param} = {self.q0:g} is outside the range [{lo:g}, {hi:g}]")
        self.x0, self.phi0 = np.asarray(pt["x"], float), float(pt["phi_L"])
        if self.x0.size != self.one.disc.size:
            raise ValueError(f"{data.label}: the stored fold does not fit its mesh")
        J, F1, _ = two.tangent(self.x0, self.phi0, self.q0)
        tx, _ = pt["direction"]
        self.v0 = np.asarray(tx, float) if np.size(tx) == self.x0.size and np.any(tx != 0) else \
            _fold_null_vector(J, F1)
        self.label = data.label

    def problem(self):
        """A fresh fold problem on the fold's mesh (each direction its own: the other moved its borders)."""
        from ..bifurcation import FoldProblem
        one = self.one.with_mesh(self.one.disc.breakpoints)
        return FoldProblem(RodSystem2(one, self.param), self.x0, self.phi0, self.q0, self.v0)


class _FoldRecorder(Recorder):
    """A fold-curve point stored as a branch's: the state ``x`` (without ``phi_L``) and the tangent of
    ``(x, phi_L)``."""

    def add(self, pt: Point, problem) -> int:
        return self.add_row(self.branch.row(pt), pt.x[:-1], pt.tx, problem.breakpoints, pt.message)


def _run_way(start: _FoldStart, steps, adaptive, events, recorder, callback) -> None:
    engine = AdaptiveContinuation(start.problem(), np.append(start.x0, start.phi0), start.q0, steps, adaptive,
                                  events=events, recorder=recorder, callback=callback)
    try:
        engine.run()
    except StartError as exc:  # a way that cannot start is a way that ends there, said so
        recorder.branch.set_status(exc.status, str(exc))


def _both_ways(one_way, result: Branch, recorder: Recorder) -> None:
    """The way down into memory, stored reversed (without its start, which the way up repeats), then the way
    up from the start: rows along the curve. Interrupted on the way down, what it found is stored."""
    down = Branch(result.gamma_value, result.rod, result.N, result.k, result.param, attrs=result.attrs)
    try:
        one_way(-1, _FoldRecorder(down))
    finally:
        rev = down.reversed()
        for i in range(len(rev) - 1):
            recorder.copy(rev, i, kind=Kind.REGULAR if rev.table["kind"][i] == Kind.START else None)
        result.status_first, result.message_first = down.status, down.message
        result.missed_crossings += down.missed_crossings
        result.unlocated += down.unlocated
    one_way(1, recorder)


def _file_meta(data, start: _FoldStart, param, guard, max_error, fold, settings) -> dict:
    return dict(kind="fold_curve", gamma=data.gamma, T=data.tension, w=data.rod.w, EI=data.rod.EI, GJ=data.rod.GJ,
                EA=data.rod.EA, L=data.rod.L, N=int(start.N), k=start.k, param=param,
                weight_direction=np.asarray(data.rod.weight_direction), min_alignment_guard=guard,
                reference=str(data.attrs.get("reference", "straight")), conduit=str(data.attrs.get("conduit", "")),
                max_error=max_error, source=f"{data.label}: fold {fold}", settings=json.dumps(settings))


def _open(out, data, meta, result, start: _FoldStart, overwrite):
    if out is None:
        return None, _FoldRecorder(result)
    from ..branchfile import BranchWriter, check_output
    from ..safeio import command_inputs
    from .trace import _mesh_group
    out = check_output(out, inputs=command_inputs(loaded=[data]), overwrite=overwrite)  # nor the survey it names
    writer = BranchWriter(out, meta, min_points=2)
    group = writer.group("/", extra_columns=(start.param,))
    _mesh_group(writer, start.one)
    return writer, _FoldRecorder(result, writer, group)


def _fold_null_vector(J, F1):
    """Right null vector of ``J`` at a fold: the x part of the tangent of ``[J, F_phi]`` there."""
    n = J.shape[0]
    rng = np.random.default_rng(3)
    c = rng.standard_normal(n + 1)
    e = np.zeros(n + 1)
    e[-1] = 1.0
    t = LU(bordered(J, np.asarray(F1, float), c[:-1], c[-1])).solve(e)
    return t[:-1]
