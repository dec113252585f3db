"""The ``rodcont`` command line: solve, trace, folds, plot, shape.

Every error a user can cause (bad numbers, missing or foreign files, an output
directory that does not exist, no convergence) ends in one line on stderr and
exit status 2; no traceback, no half-written output file.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time

import click
import numpy as np

EXIT_USAGE = 2


class UserError(click.ClickException):
    exit_code = EXIT_USAGE


# --------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------
def _positive(name):
    def check(ctx, param, value):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise click.BadParameter(f"must be a positive number, got {value:g}", param_hint=name)
        return value
    return check


def _finite(name):
    def check(ctx, param, value):
        if value is not None and not math.isfinite(value):
            raise click.BadParameter(f"must be a finite number, got {value}", param_hint=name)
        return value
    return check


def rod_options(f):
    """Rod and mesh options shared by every command that builds a rod (paper values by default)."""
    opts = [
        click.option("--N", "N", type=click.IntRange(1, 2000), default=15, show_default=True,
                     help="number of uniform subintervals"),
        click.option("--k", "k", type=click.IntRange(1, 7), default=5, show_default=True,
                     help="Gauss collocation points per subinterval"),
        click.option("--w", "w", type=float, default=10.0, show_default=True, callback=_finite("--w"),
                     help="weight per unit unstressed length (>= 0)"),
        click.option("--EI", "EI", type=float, default=1.0, show_default=True, callback=_positive("--EI"),
                     help="bending stiffness"),
        click.option("--GJ", "GJ", type=float, default=0.75, show_default=True, callback=_positive("--GJ"),
                     help="torsional stiffness"),
        click.option("--EA", "EA", type=float, default=255.0, show_default=True, callback=_positive("--EA"),
                     help="axial stiffness"),
        click.option("--L", "L", type=float, default=1.0, show_default=True, callback=_positive("--L"),
                     help="span (length of the straight reference curve)"),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def _rod(w, EI, GJ, EA, L):
    from .rod import RodParameters
    if w < 0:
        raise UserError(f"--w must be non-negative, got {w:g}")
    return RodParameters(EI=EI, GJ=GJ, EA=EA, w=w, L=L)


def _check_gamma(gamma, rod):
    """Below the Euler load of the clamped rod (T = -4 pi^2 EI / L^2) the untwisted start is buckled."""
    T = gamma * rod.w * rod.L
    T_euler = -4 * math.pi**2 * rod.EI / rod.L**2
    if T <= T_euler:
        lim = T_euler / (rod.w * rod.L) if rod.w > 0 else float("-inf")
        raise UserError(f"--gamma {gamma:g} is at or below the Euler buckling load of the clamped rod "
                        f"(Gamma = {lim:.6g}): the untwisted start is not unique")


def _out_path(path):
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        raise UserError(f"cannot write {path}: directory {d} does not exist")
    if os.path.isdir(path):
        raise UserError(f"cannot write {path}: it is a directory")
    return path


def _load(path):
    from .branchfile import BranchFileError, load_branch
    try:
        return load_branch(path)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None


def _split_label(spec, what="--start"):
    if ":" not in spec:
        raise UserError(f"{what} expects FILE.h5:POINT (a point index, F<j> or BP<j>), got {spec!r}")
    path, label = spec.rsplit(":", 1)
    return path, label


# --------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------
@click.group(context_settings=dict(help_option_names=["-h", "--help"]))
@click.version_option(package_name="rodcont")
def main_group():
    """Equilibrium branches, folds and bifurcations of the twisted heavy rod (Eulerian Cosserat rod)."""


@main_group.command()
@click.option("--gamma", type=float, required=True, callback=_finite("--gamma"), help="tension ratio T / (w L)")
@click.option("--phi", "phi", type=float, required=True, callback=_finite("--phi"), help="end rotation Phi [rad]")
@click.option("--load-step", type=float, default=0.5, show_default=True, callback=_positive("--load-step"),
              help="Phi increment of the natural continuation from 0")
@rod_options
def solve(gamma, phi, load_step, N, k, w, EI, GJ, EA, L):
    """One equilibrium at (Gamma, Phi), reached by loading Phi up from 0.

    Prints `name value` pairs: stretch, torque, l0, helical_waves,
    min_alignment (min d3.K3), Newton iterations and residual norm.
    """
    from .branch import ConvergenceError, solve_equilibrium
    rod = _rod(w, EI, GJ, EA, L)
    _check_gamma(gamma, rod)
    try:
        eq = solve_equilibrium(gamma, phi, rod, N=N, k=k, load_step=load_step)
    except ConvergenceError as exc:
        raise UserError(str(exc)) from None
    o = eq.outputs
    for name in ("phi_L", "stretch", "torque", "l0"):
        click.echo(f"{name} {o[name]:.15g}")
    click.echo(f"helical_waves {o['helical_waves']}")
    click.echo(f"min_alignment {o['min_alignment']:.15g}")
    click.echo(f"defect {o['defect']:.6g}")
    click.echo(f"newton_iterations {eq.newton.iterations}")
    click.echo(f"residual_norm {eq.newton.residual_norm:.6g}")


class _Progress:
    """One status line on a terminal (rewritten in place), a line every few seconds otherwise."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.last = 0.0
        self.n = 0
        self.t0 = time.perf_counter()
        self.folds = 0

    def __call__(self, pt):
        self.n += 1
        if pt.kind == "fold":
            self.folds += 1
        if self.quiet:
            return
        now = time.perf_counter()
        d = pt.data
        msg = (f"point {self.n:5d}  Phi {d['phi_L']:9.5f}  stretch {d['stretch']:10.6f}  "
               f"waves {d['helical_waves']}  min d3.K3 {d['min_alignment']:.3f}  folds {self.folds}  "
               f"{now - self.t0:6.1f} s")
        if pt.kind not in ("regular", "start"):
            click.echo(("\r" if self.tty else "") + f"  {pt.kind:<14s} at Phi = {d['phi_L']:.10f}, "
                       f"stretch = {d['stretch']:.10f}" + " " * 20, err=True)
        if self.tty:
            click.echo("\r" + msg, nl=False, err=True)
        elif now - self.last > 5.0:
            click.echo(msg, err=True)
            self.last = now

    def done(self):
        if self.tty and not self.quiet:
            click.echo("", err=True)


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=_finite("--gamma"),
              help="tension ratio T / (w L) (required unless --start)")
@click.option("--phi-max", type=float, default=40.0, show_default=True, callback=_finite("--phi-max"))
@click.option("--phi-min", type=float, default=-1.0, show_default=True, callback=_finite("--phi-min"))
@click.option("--stretch-max", type=float, default=None, callback=_finite("--stretch-max"),
              help="stop when the stretch reaches this value")
@click.option("--max-steps", type=click.IntRange(1, 10**7), default=2000, show_default=True)
@click.option("--ds", type=float, default=0.1, show_default=True, callback=_positive("--ds"),
              help="first pseudo-arclength step")
@click.option("--ds-max", type=float, default=0.5, show_default=True, callback=_positive("--ds-max"))
@click.option("--ds-min", type=float, default=1e-6, show_default=True, callback=_positive("--ds-min"),
              help="the trace stops when the step must shrink below this")
@click.option("--min-alignment", type=click.FloatRange(0, 1, max_open=True), default=0.05, show_default=True,
              help="validity guard: stop where min d3.K3 falls to this")
@click.option("--max-defect", type=float, default=1e-2, show_default=True, callback=_positive("--max-defect"),
              help="accuracy guard: stop where the relative residual between collocation points reaches this")
@click.option("--forced", type=float, multiple=True, help="a Phi value that gets a point of its own (repeatable)")
@click.option("--start", default=None, help="restart from FILE.h5:POINT (index from 0, F<j> or BP<j> from 1)")
@click.option("--switch", is_flag=True, help="with --start at a branch point: follow the other branch")
@click.option("--adapt", is_flag=True,
              help="move the N breakpoints to equidistribute the defect when it reaches max-defect/10")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="branch file to write (HDF5)")
@click.option("--quiet", is_flag=True, help="no progress display")
@rod_options
def trace(gamma, phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_defect, forced,
          start, switch, adapt, out, quiet, N, k, w, EI, GJ, EA, L):
    """Trace a branch in Phi through its folds and write it to a branch file.

    Folds, branch points, forced values and the guards are located, not just
    bracketed. With --start the rod, Gamma and mesh come from the file.
    """
    from .branch import trace as run_trace
    ctx = click.get_current_context()
    if ds > ds_max and ctx.get_parameter_source("ds") == click.core.ParameterSource.DEFAULT:
        ds = ds_max  # only --ds-max was given: start at it
    if not ds_min <= ds <= ds_max:
        raise UserError(f"need --ds-min <= --ds <= --ds-max, got {ds_min:g}, {ds:g}, {ds_max:g}")
    if phi_min >= phi_max:
        raise UserError("--phi-min must be below --phi-max")
    start_data = None
    breakpoints = None
    if start is not None:
        path, label = _split_label(start)
        data = _load(path)
        if data.attrs.get("param", "phi_L") != "phi_L":
            raise UserError(f"{path} is a fold curve in {data.attrs['param']}, not a branch in phi_L: "
                            f"it cannot start a trace")
        from .branchfile import BranchFileError
        try:
            pt = data.point(label)
        except BranchFileError as exc:
            raise UserError(str(exc)) from None
        rod = data.rod
        gamma = data.gamma
        N, k = int(data.attrs["N"]), int(data.attrs["k"])
        start_data = (pt["x"], float(pt["phi_L"]), pt["direction"])
        breakpoints = pt["breakpoints"]
        if switch and pt["kind"] != "branch_point":
            raise UserError(f"--switch needs a branch point (BP<j>); point {label} is a {pt['kind']} point")
        if os.path.abspath(path) == os.path.abspath(out):
            raise UserError("--out must differ from the --start file")
    else:
        if switch:
            raise UserError("--switch needs --start FILE.h5:BP<j>")
        if gamma is None:
            raise UserError("--gamma is required (or --start FILE.h5:POINT)")
        rod = _rod(w, EI, GJ, EA, L)
        _check_gamma(gamma, rod)
    _out_path(out)
    progress = _Progress(quiet)
    t0 = time.perf_counter()
    interrupted = False
    # Ctrl-C is taken between points (after the point is on disk), so it never lands in
    # the middle of a write; a second Ctrl-C interrupts at once.
    pending = []

    def on_sigint(signum, frame):
        if pending:
            raise KeyboardInterrupt
        pending.append(signum)

    def callback(pt):
        progress(pt)
        if pending:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        run_trace(gamma, rod, N=N, k=k, phi_max=phi_max, phi_min=phi_min, stretch_max=stretch_max,
                  min_alignment=min_alignment, max_defect=max_defect, max_steps=max_steps, ds=ds,
                  ds_max=ds_max, ds_min=ds_min, forced=forced, start=start_data, switch=switch, out=out,
                  callback=callback, adapt=adapt, breakpoints=breakpoints)
    except KeyboardInterrupt:
        interrupted = True
    except ValueError as exc:
        _remove_if_empty(out)
        raise UserError(str(exc)) from None
    finally:
        signal.signal(signal.SIGINT, previous)
    progress.done()
    elapsed = time.perf_counter() - t0
    data = _load(out)
    if len(data) == 0:
        reason = data.attrs.get("stop_reason", "")
        os.remove(out)
        raise UserError(f"no branch traced: {reason}")
    _summary(data, elapsed)
    if interrupted:
        click.echo(f"interrupted: {out} holds the {len(data)} completed point(s); "
                   f"restart with --start {out}:-1", err=True)
        sys.exit(130)


def _remove_if_empty(path):
    try:
        from .branchfile import load_branch
        if os.path.exists(path) and len(load_branch(path)) == 0:
            os.remove(path)
    except Exception:
        pass


def _summary(data, elapsed):
    click.echo(f"points       {len(data)}")
    click.echo(f"folds        {len(data.folds.get('index', []))}")
    click.echo(f"branch pts   {len(data.branch_points.get('index', []))}")
    click.echo(f"stop reason  {data.attrs.get('stop_reason')}")
    click.echo(f"time         {elapsed:.3f} s")
    _fold_table(data)
    bp = data.branch_points
    for j in range(len(bp.get("index", []))):
        click.echo(f"BP{j + 1:<3d} {bp['index'][j]:6d} {bp['phi_L'][j]:18.12f} {bp['stretch'][j]:18.12f}  "
                   f"(follow the other branch: --start FILE:BP{j + 1} --switch)")


def _fold_table(data):
    f = data.folds
    if not len(f.get("index", [])):
        click.echo("no folds")
        return
    click.echo(f"{'fold':>4} {'index':>6} {'phi_L':>18} {'stretch':>18} {'torque':>16} {'l0':>16} waves before->after")
    for j in range(len(f["index"])):
        click.echo(f"F{j + 1:<3d} {f['index'][j]:6d} {f['phi_L'][j]:18.12f} {f['stretch'][j]:18.12f} "
                   f"{f['torque'][j]:16.10f} {f['l0'][j]:16.10f} {f['waves_before'][j]:d} -> {f['waves_after'][j]:d}")


@main_group.command()
@click.argument("file")
def folds(file):
    """Print the fold table of a branch file."""
    data = _load(file)
    click.echo(f"# {file}: Gamma = {data.gamma:g}, {len(data)} points, stop: {data.attrs.get('stop_reason')}")
    _fold_table(data)


@main_group.command()
@click.argument("files", nargs=-1, required=True)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="PNG to write")
@click.option("--title", default=None)
def plot(files, output, title):
    """Response diagram (Phi against stretch, one curve per file, folds marked)."""
    from .plots import response_diagram
    data = [_load(f) for f in files]
    if any(len(d) == 0 for d in data):
        raise UserError("a branch file with no points cannot be plotted")
    response_diagram(data, _out_path(output), title)
    click.echo(f"wrote {output}")


@main_group.command()
@click.argument("file")
@click.option("--point", "points", multiple=True, default=("-1",), show_default=True,
              help="point index (from 0, negative from the end), F<j> or BP<j>; repeatable")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="PNG to write")
def shape(file, points, output):
    """3D centreline of stored points of a branch file."""
    from .branchfile import BranchFileError
    from .plots import shape_figure
    from .rod import EulerianRod
    data = _load(file)
    model = EulerianRod(data.rod)
    curves = []
    S = np.linspace(0, data.rod.L, 400)
    for label in points:
        try:
            pt = data.point(label)
        except BranchFileError as exc:
            raise UserError(str(exc)) from None
        disc = model.discretise(breakpoints=pt["breakpoints"], k=int(data.attrs["k"]))
        if pt["x"].size != disc.size:
            raise UserError(f"{file}: stored coefficients do not fit the stored mesh")
        r = model.centreline(disc, pt["x"], S)
        curves.append((r, f"#{pt['index']}: Φ = {pt['phi_L']:.4f}, stretch = {pt['stretch']:.4f}"))
    shape_figure(curves, _out_path(output), f"{os.path.basename(file)}  (Γ = {data.gamma:g})")
    click.echo(f"wrote {output}")


@main_group.command("fold-curve")
@click.argument("spec")
@click.option("--param", type=click.Choice(["gamma", "T", "w", "EI", "GJ", "EA"]), default="gamma", show_default=True,
              help="second parameter (gamma keeps w fixed; the others keep T fixed)")
@click.option("--range", "prange", type=float, nargs=2, required=True, help="A B: the interval of the parameter")
@click.option("--ds", type=float, default=0.05, show_default=True, callback=_positive("--ds"))
@click.option("--ds-max", type=float, default=0.5, show_default=True, callback=_positive("--ds-max"))
@click.option("--max-steps", type=click.IntRange(1, 10**6), default=500, show_default=True)
@click.option("--forced", type=float, multiple=True, help="a parameter value that gets a point of its own")
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="fold-curve file to write (HDF5)")
@click.option("--quiet", is_flag=True)
def fold_curve_cmd(spec, param, prange, ds, ds_max, max_steps, forced, out, quiet):
    """Continue a fold of a branch file in (Phi, PARAM): FILE.h5:I is the I-th fold, counted from 0."""
    from .branch import fold_curve
    path, label = _split_label(spec, "fold-curve")
    try:
        fold = int(label)
    except ValueError:
        raise UserError(f"fold-curve expects FILE.h5:I with I the fold number from 0, got {label!r}") from None
    if not all(math.isfinite(v) for v in prange):
        raise UserError("--range needs two finite numbers")
    data = _load(path)
    _out_path(out)
    progress = _Progress(quiet)
    t0 = time.perf_counter()
    try:
        res = fold_curve(data, fold, param, prange[0], prange[1], out=out, ds=ds, ds_max=ds_max,
                         max_steps=max_steps, forced=forced, callback=progress)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    progress.done()
    pts = res["points"]
    if len(pts) <= 1:
        raise UserError(f"the fold could not be continued: {'; '.join(res['stop_reasons'])}")
    click.echo(f"points       {len(pts)}")
    click.echo(f"stop reasons down: {res['stop_reasons'][0]}; up: {res['stop_reasons'][1]}")
    click.echo(f"time         {time.perf_counter() - t0:.3f} s")
    click.echo(f"{param:>12} {'phi_L':>18} {'stretch':>16} {'torque':>14} kind")
    for pt in pts:
        d = pt.data
        click.echo(f"{d[param]:12.6f} {d['phi_L']:18.12f} {d['stretch']:16.10f} {d['torque']:14.8f} {pt.kind}")


class _GreedyFloats(click.Option):
    """An option taking one or more numbers: ``--gamma 0 0.5 1 2 5``."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("multiple", True)
        super().__init__(*args, **kwargs)

    def add_to_parser(self, parser, ctx):
        super().add_to_parser(parser, ctx)
        opt = parser._long_opt.get(self.opts[0])
        if opt is None:
            return
        orig = opt.process

        def process(value, state):
            orig(value, state)
            while state.rargs and not state.rargs[0].startswith("--"):
                orig(state.rargs.pop(0), state)

        opt.process = process


@main_group.command()
@click.option("--gamma", "gammas", cls=_GreedyFloats, type=float, required=True, help="tension ratios, e.g. 0 0.5 1 2 5")
@click.option("--phi-max", type=float, default=40.0, show_default=True, callback=_finite("--phi-max"))
@click.option("--phi-min", type=float, default=-1.0, show_default=True, callback=_finite("--phi-min"))
@click.option("--max-steps", type=click.IntRange(1, 10**7), default=2000, show_default=True)
@click.option("--min-alignment", type=click.FloatRange(0, 1, max_open=True), default=0.05, show_default=True)
@click.option("--max-defect", type=float, default=1e-2, show_default=True, callback=_positive("--max-defect"))
@click.option("--adapt", is_flag=True, help="move the breakpoints with the shape (see trace --adapt)")
@click.option("--jobs", type=click.IntRange(1, 1024), default=None, help="parallel processes [default: all cores]")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="directory for the files")
@click.option("--quiet", is_flag=True)
@rod_options
def sweep(gammas, phi_max, phi_min, max_steps, min_alignment, max_defect, adapt, jobs, out_dir, quiet,
          N, k, w, EI, GJ, EA, L):
    """A family of branches, one per Gamma, traced in parallel, and their combined diagram."""
    from .family import sweep as run_sweep
    rod = _rod(w, EI, GJ, EA, L)
    for g in gammas:
        if not math.isfinite(g):
            raise UserError(f"--gamma values must be finite numbers, got {g}")
        _check_gamma(g, rod)
    if len(set(gammas)) != len(gammas):
        raise UserError("--gamma values must be distinct")
    parent = os.path.dirname(os.path.abspath(out_dir))
    if not os.path.isdir(parent):
        raise UserError(f"cannot create {out_dir}: directory {parent} does not exist")
    os.makedirs(out_dir, exist_ok=True)
    t0 = time.perf_counter()
    res = run_sweep(list(gammas), out_dir, rod=rod, N=N, k=k, jobs=jobs, progress=not quiet,
                    phi_max=phi_max, phi_min=phi_min, max_steps=max_steps, min_alignment=min_alignment,
                    max_defect=max_defect, adapt=adapt)
    click.echo(f"{'gamma':>8} {'points':>7} {'folds':>6} {'first fold phi_L':>18}  stop reason")
    for r in res["branches"]:
        ff = f"{r['first_fold']:18.10f}" if r["first_fold"] is not None else f"{'-':>18}"
        click.echo(f"{r['gamma']:8g} {r['points']:7d} {r['folds']:6d} {ff}  {r['stop_reason']}")
    click.echo(f"diagram      {res['diagram']}")
    click.echo(f"time         {time.perf_counter() - t0:.2f} s ({res['jobs']} processes)")


def main(argv=None):
    """Entry point: click's parsing with one-line errors and exit status 2."""
    try:
        rv = main_group.main(args=argv, prog_name="rodcont", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except click.ClickException as exc:
        msg = exc.format_message() if not isinstance(exc, click.UsageError) else _usage_message(exc)
        click.echo(f"rodcont: error: {msg}", err=True)
        sys.exit(EXIT_USAGE)
    except click.exceptions.Abort:
        click.echo("rodcont: aborted", err=True)
        sys.exit(130)
    except KeyboardInterrupt:
        click.echo("rodcont: interrupted", err=True)
        sys.exit(130)
    except (MemoryError, OSError) as exc:
        click.echo(f"rodcont: error: {type(exc).__name__}: {exc}", err=True)
        sys.exit(1)
    except Exception as exc:  # a bug, not a user error: one line, and say so
        click.echo(f"rodcont: error: unexpected failure ({type(exc).__name__}: {exc}); please report it "
                   f"with the command line", err=True)
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


def _usage_message(exc: click.UsageError) -> str:
    msg = exc.format_message().replace("\n", " ")
    if exc.ctx is not None and exc.ctx.command_path:
        msg += f" (see '{exc.ctx.command_path} --help')"
    return msg


if __name__ == "__main__":
    main()
