"""``rodcont trace``: a branch traced into a branch file, from a start, a stored point (--start) or the
end of an interrupted trace (--resume)."""

from __future__ import annotations

import sys
import time
from types import SimpleNamespace

import click

from .app import main_group
from .common import (
    UserError,
    check_out,
    conduit_of,
    explicit,
    file_identity,
    file_meta,
    load_any_file,
    load_branch_file,
    make_rod,
    point_spec,
    reference_curve,
    stretch_warning,
    tension_of,
    worded,
)
from .drilling import DRILLING_KEYS, drilling_options, run_drilling_trace
from .options import check_number, rod_options
from .progress import Interrupts, Progress
from .tables import fold_table, fold_warnings
from .trace_options import OPTION_SOURCES, given_options, rod_changes, trace_kwargs, trace_options


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=check_number("--gamma"),
              help="tension ratio T / (w L) (required unless --start)")
@trace_options
@click.option("--start", default=None, help="restart from FILE.h5:POINT (or FILE.h5:BRANCH:POINT of a diagram); "
                                            "POINT: index from 0, F<j> or BP<j> from 1; the file's options "
                                            "unless given")
@click.option("--resume", "resume_file", default=None, type=click.Path(dir_okay=False),
              help="continue the unfinished (interrupted) trace in FILE.h5 into FILE.h5 itself, with its options")
@click.option("--extend", is_flag=True, help="with --resume: go on past the end of a finished branch")
@click.option("--switch", is_flag=True, help="with --start at a branch point: follow the other branch")
@click.option("--from-straight", type=float, default=None, callback=check_number("--from-straight"),
              help="start near the straight twisted state at this Phi (weight homotopy)")
@click.option("--from-critical", type=click.IntRange(1, 1000), default=None,
              help="N: start at the N-th critical twist of the weightless straight rod (--w 0), along its helical "
                   "branch (a phase condition fixes the branch's turn about the axis)")
@click.option("--l0", "l0", type=float, default=None, callback=check_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension is solved for at each point (column T)")
@click.option("--torque", type=float, default=None, callback=check_number("--torque"),
              help="end torque held fixed (Phi solved for) in a trace of a rod parameter from --start")
@click.option("--param", type=click.Choice(["phi_L", "w", "T", "gamma", "EI", "GJ", "EA", "torque", "l0", "depth"]),
              default="phi_L", show_default=True,
              help="the continued parameter (others than phi_L with --range; torque: the end rotation free; "
                   "depth: a trip of the drill string --string in the well --conduit)")
@click.option("--range", "prange", type=float, nargs=2, default=None, callback=check_number("--range"),
              help="A B: the interval of --param (when it is not phi_L)")
@click.option("--points", type=click.IntRange(2, 100_000), default=None,
              help="a trip's depths from A to B (--param depth; default 11)")
@click.option("--direction", type=click.Choice(["up", "down"]), default="up", show_default=True,
              help="which way the parameter goes first")
@click.option("--conduit", type=click.Path(dir_okay=False), default=None,
              help="TOML file of a conduit around the reference curve ([conduit] clearance, reference, eps): "
                   "the rod stays inside it, touching its wall where it must")
@click.option("--out", default=None, type=click.Path(dir_okay=False), help="branch file to write (HDF5)")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@click.option("--quiet", is_flag=True, help="no progress display")
@drilling_options
@rod_options
def trace(**given):
    """Trace a branch (in Phi, or in a rod parameter) through its folds and write it to a branch file.

    Folds, branch points, forced values and the guards are located, not just
    bracketed; the mesh adapts to the shape unless --uniform. With --start the
    rod, the tension, the mesh and the trace options come from the file (options
    given override them); --resume FILE.h5 continues an interrupted trace in place.
    """
    a = SimpleNamespace(**given)
    if a.string is not None or (a.param == "depth" and a.resume_file is None):  # a trip's resume: its file says
        return _trace_string(a)
    if a.resume_file is None:  # a trip's file refuses them as its own (_resume_trip), a trace's as here
        _no_drilling_options()
    if a.points is not None and a.resume_file is None:
        raise UserError("--points is the number of depths of a trip (--param depth with --string)")
    kw = trace_kwargs(a)
    kw["direction"] = 1 if a.direction == "up" else -1
    if a.resume_file is not None:
        return _resume_trace(a.resume_file, a.extend, a.out, a.start, a.from_straight, a.switch, a.param, a.prange,
                             a.conduit, a.k, kw, a.quiet)
    if a.extend:
        raise UserError("--extend goes with --resume FILE.h5")
    if a.out is None:
        raise UserError("--out FILE.h5 is required (or --resume FILE.h5)")
    if a.param != "phi_L" and a.prange is not None:
        kw["p_range"] = tuple(a.prange)
    elif a.prange is not None:
        raise UserError("--range is for --param other than phi_L (use --phi-min/--phi-max)")
    if a.start is not None:
        return _trace_from_point(a, kw)
    _trace_from_start(a, kw)


def _no_drilling_options() -> None:
    """A drill string's options given to a trace of a rod: refused in one line."""
    said = explicit(*DRILLING_KEYS)
    if said:
        raise UserError(f"--{said[0].replace('_', '-')} is an option of a drill string: give --string S.toml "
                        f"(and the well as --conduit WELL.toml)")


def _trace_string(a) -> None:
    """``trace --string S.toml --conduit WELL.toml --param depth --range A B``: a trip in bit depth
    (:func:`.drilling.run_drilling_trace`); the rod's own trace options do not apply to it."""
    if a.string is None:
        raise UserError("--param depth is a trip of a drill string: give --string S.toml and --conduit WELL.toml")
    for name in ("start", "resume_file", "from_straight", "from_critical", "l0", "torque", "depth", "joints"):
        if getattr(a, name) not in (None, False):
            raise UserError(f"--{name.replace('_file', '').replace('_', '-')} is not an option of a trip "
                            f"(--string): drop it")
    rod_and_trace = [n for sources in OPTION_SOURCES.values() for n in sources if n != "prange"]
    said = explicit(*rod_and_trace, "direction", "gamma", "w", "EI", "GJ", "EA", "L", "N", "k", "reference")
    if said:  # a trip marches in depth with the string's own data: these would be ignored
        raise UserError(f"--{said[0].replace('_', '-')} is not an option of a trip (--string): drop it")
    run_drilling_trace(a.conduit, {key: getattr(a, key) for key in DRILLING_KEYS}, a.param, a.prange, a.out,
                       a.overwrite, points=a.points or 11, quiet=a.quiet)


def _range_stretch_warning(rod, param, prange) -> None:
    """A trace in the tension reaches the ends of its range: warn for the farther one."""
    if param in ("T", "gamma") and prange is not None:
        stretch_warning(rod, max([v if param == "T" else v * rod.w * rod.L for v in prange], key=abs))


def _trace_from_point(a, kw) -> None:
    """``trace --start FILE.h5:POINT``: the file's rod, tension, mesh and options unless given."""
    from ..drivers.trace import trace as run_trace
    if a.from_straight is not None:
        raise UserError("give --start or --from-straight, not both")
    data, pt, label = point_spec(a.start)
    if a.param != "phi_L" and a.prange is None and a.param != data.param:
        raise UserError(f"--param {a.param} needs --range A B")
    if a.from_critical is not None:
        raise UserError("give --start or --from-critical, not both")
    args = _restart_args(data, label, a.start, a.param, a.switch, a.N, a.k, a.conduit, kw)
    if a.torque is not None:  # a torque held from the point on (its Phi solved for), or an unstressed length
        args["torque"] = a.torque
    if a.l0 is not None:
        args["l0"], args["T"] = a.l0, None
    check_out(a.out, args.inputs, a.overwrite, loaded=(data,))
    for note in args.notes:
        click.echo(f"rodcont: note: {note}", err=True)
    rod, N, T, k = args.pop("rod"), args.pop("N"), args.pop("T"), args.pop("k")
    args.pop("gamma", None)
    _range_stretch_warning(rod, a.param, a.prange)
    _run_trace(run_trace, None, rod, N, k, T, {}, dict(args, meta=file_meta()), a.out, a.overwrite, a.quiet,
               restart=True, param=args.get("param", a.param))


def _trace_tension(a, rod):
    """The tension of a new trace: --gamma or --T, or none with --l0 (then it is solved for)."""
    given_T = click.get_current_context().meta.get("rodcont.T")
    if a.l0 is not None:
        if a.gamma is not None or given_T is not None:
            raise UserError("give one of --gamma, --T and --l0")
        return None
    if a.gamma is None and given_T is None:
        raise UserError("--gamma or --T is required (or --l0, or --start FILE.h5:POINT)")
    return tension_of(a.gamma, rod)[1]


def _trace_from_start(a, kw) -> None:
    """A new trace: from the sag at Phi = 0, the straight state (--from-straight) or a critical twist."""
    from ..drivers.trace import trace as run_trace
    if a.param != "phi_L" and a.prange is None:
        raise UserError(f"--param {a.param} needs --range A B")
    extra = dict(param=a.param, l0=a.l0, torque=a.torque, from_critical=a.from_critical)
    if a.switch:
        raise UserError("--switch needs --start FILE.h5:BP<j>")
    rod = make_rod(a.w, a.EI, a.GJ, a.EA, a.L)
    T = _trace_tension(a, rod)
    if a.conduit is not None:
        if a.from_straight is not None:
            raise UserError("--from-straight is not available inside a conduit (trace from the sag)")
        extra["curve"], extra["wall"] = conduit_of(a.conduit, rod)
    else:
        extra["curve"] = reference_curve(rod, "--from-straight" if a.from_straight is not None else
                                         "--from-critical" if a.from_critical is not None else None)
    if a.from_straight is not None:
        extra["from_straight"] = a.from_straight
        if a.param != "phi_L":
            extra["phi_L"] = a.from_straight
    elif a.param not in ("phi_L", "torque"):
        raise UserError(f"--param {a.param} starts from --start FILE:POINT or --from-straight PHI")
    check_out(a.out, [], a.overwrite)  # nor the --conduit file, its survey, --config, --reference well:FILE
    if T is not None:
        stretch_warning(rod, T)
    extra["meta"] = file_meta()
    _range_stretch_warning(rod, a.param, a.prange)
    _run_trace(run_trace, None, rod, a.N, a.k, T, kw, extra, a.out, a.overwrite, a.quiet, param=a.param)


def _restart_args(data, label, spec, param, switch, N, k, conduit, kw):
    """The arguments of a trace from a stored point (:func:`rodcont.restart.restart_from`: its checks, the
    file's options unless given on the command line)."""
    from ..restart import restart_from
    ctx = click.get_current_context()
    try:
        return restart_from(data, label, param=param, direction=kw["direction"], switch=switch,
                            N=N if explicit("N") else None, k=k if explicit("k") else None,
                            changes=rod_changes(), reference=ctx.meta.get("rodcont.reference")
                            if explicit("reference") else None, conduit=conduit,
                            options=given_options(kw), spec=spec)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None


def _resume_trace(path, extend, out, start, from_straight, switch, param, prange, conduit, k, kw, quiet):
    """``trace --resume FILE.h5``: the unfinished trace continued into the same file (rodcont.restart.resume)."""
    from ..branchfile import same_file
    from ..restart import resume
    if out is not None and not same_file(out, path):
        raise UserError(f"--resume continues {path} in place: drop --out {out} (or resume a copy)")
    for given, what in ((start, "--start"), (from_straight, "--from-straight"), (switch or None, "--switch"),
                        (conduit, "--conduit")):
        if given is not None:
            raise UserError(f"--resume goes on from the file's last point: drop {what}")
    if explicit("reference"):
        raise UserError("--resume keeps the file's reference curve: drop --reference")
    if explicit("N"):
        raise UserError("--resume goes on on the file's own mesh (it adapts): drop --N")
    d = load_any_file(path)
    kind = d.attrs.get("kind", "branch")
    if kind == "diagram":
        raise UserError(f"{path} is a diagram: finish it with rodcont diagram --resume {path}")
    if kind != "branch":
        raise UserError(f"{path} is a {str(kind).replace('_', ' ')} file, not a trace: it cannot be resumed")
    data = d.branches[0]
    if data.param == "depth":  # a trip: its well, string and march are in the file (rodcont.drivers.trip)
        return _resume_trip(path, data, quiet)
    _no_drilling_options()
    if explicit("points"):
        raise UserError("--points is the number of depths of a trip (--param depth with --string)")
    if explicit("param") and param != data.param:
        raise UserError(f"--resume goes on in the file's parameter ({data.param}): drop --param {param}")
    if kw["direction"] != 1:
        raise UserError("--resume goes on the way the trace went: drop --direction down")
    if prange is not None:
        kw["p_range"] = tuple(prange)
    options = given_options(kw)
    if explicit("k") and k != int(data.attrs["k"]):
        raise UserError(f"--k {k} differs from the file's k = {int(data.attrs['k'])}: a resumed trace keeps it")

    def check(args):  # the file itself is the output: refused only onto another input (its survey, --config)
        check_out(path, [p for p in args.inputs if not same_file(p, path)], True)

    def run(callback):
        return resume(path, extend=extend, changes=rod_changes(), options=options, callback=callback, check=check,
                      data=d)

    _traced(run, path, quiet, resumed=True, param=data.param)


def _resume_trip(path, data, quiet):
    """``trace --resume TRIP.h5``: the interrupted trip finished in place (rodcont.drivers.trip.resume_trip), with
    the file's own well, string, operation, range and options (each option given is refused)."""
    import json

    from ..branchfile import same_file
    from ..drivers.trip import resume_trip
    from .drilling import trip_depths_done, tripped
    ctx = click.get_current_context()
    given = [n for n in ctx.params if n not in ("resume_file", "quiet", "out")
             and ctx.get_parameter_source(n) not in (click.core.ParameterSource.DEFAULT, None)
             and not (n == "param" and ctx.params[n] == "depth")]  # its own parameter may be said
    if given:
        raise UserError(f"--resume finishes the trip {path} with its own well, string, operation and range: "
                        f"drop --{given[0].replace('_', '-').replace('prange', 'range')}")

    def check(inputs):
        check_out(path, [p for p in inputs if not same_file(p, path)], True)

    def run(callback):
        return resume_trip(path, callback=callback, check=check)
    try:  # the progress line's count; a file without the record is refused by resume_trip in its own words
        points = int(json.loads(data.attrs["trip_run"])["points"])
    except (KeyError, TypeError, ValueError):
        points = 0
    tripped(run, path, points, quiet, done=trip_depths_done(data))


def _run_trace(run_trace, gamma, rod, N, k, T, kw, extra, out, overwrite, quiet, restart=False, param="phi_L"):
    def run(callback):
        return run_trace(gamma, rod, N=N, k=k, T=T, out=out, overwrite=overwrite, callback=callback, **extra, **kw)

    _traced(run, out, quiet, restart=restart, param=param)


def _traced(run, out, quiet, restart=False, resumed=False, param="phi_L"):
    """Run a trace in ``param`` into ``out`` with progress and Ctrl-C between points; print its summary (what
    the library says, in the words of ``param``)."""
    from ..restart import start_hint
    click.get_current_context().meta["rodcont.param"] = param
    before = file_identity(out)
    with Interrupts() as intr:
        progress = Progress(quiet, intr, param)
        t0 = time.perf_counter()
        interrupted = False
        try:
            run(progress)
        except KeyboardInterrupt:
            interrupted = True
        except (ValueError, TypeError) as exc:
            raise UserError(worded(str(exc)) + (start_hint(str(exc)) if restart else "")) from None
        finally:
            progress.done()
    elapsed = time.perf_counter() - t0
    if file_identity(out) == before:  # nothing published: the target (if any) is as it was
        what = "interrupted before the first point" if interrupted else "no point"
        raise UserError(f"no branch traced: {what}" + (f" ({out} is as it was)" if before is not None else ""))
    data = load_branch_file(out)
    click.get_current_context().meta["rodcont.param"] = data.param
    _summary(data, elapsed)
    if interrupted:
        click.echo(f"interrupted: {out} holds the {len(data)} completed point(s); go on with "
                   f"rodcont trace --resume {out}", err=True)
        sys.exit(intr.exit_code)


def _summary(data, elapsed):
    click.echo(f"points       {len(data)}")
    click.echo(f"folds        {len(data.folds.get('index', []))}")
    click.echo(f"branch pts   {len(data.branch_points.get('index', []))}")
    click.echo(f"stop reason  {worded(data.attrs.get('stop_reason'))}")
    click.echo(f"time         {elapsed:.3f} s")
    import json
    for a, b, n0, n1 in json.loads(data.attrs.get("missed_crossings", "[]")):
        click.echo(f"warning      unstable modes {n0} -> {n1} between {data.param} = {a:.10g} and {b:.10g}: "
                   f"more eigenvalues crossed zero than the located folds and branch points account for "
                   f"(unseen bifurcations): {_crossing_advice(data)}")
    fold_warnings(data)
    for kind, a, b in json.loads(data.attrs.get("unlocated", "[]")):
        click.echo(f"warning      a {kind.replace('_', ' ')} between {data.param} = {a:.10g} and {b:.10g} was "
                   f"detected but could not be located (no point between them converged); it is not in the "
                   f"tables")
    fold_table(data)
    bp = data.branch_points
    for j in range(len(bp.get("index", []))):
        click.echo(f"BP{j + 1:<3d} {bp['index'][j]:6d} {bp['phi_L'][j]:18.12f} {bp['stretch'][j]:18.12f}  "
                   f"(follow the other branch: --start FILE:BP{j + 1} --switch)")


def _crossing_advice(data) -> str:
    """What the library advises for crossings unseen on the rod of ``data`` (its symmetry about the axis)."""
    from ..drivers.trace import crossing_advice
    from ..rod import EulerianRod
    return crossing_advice(EulerianRod(data.rod, data.curve, data.wall), data.param)
