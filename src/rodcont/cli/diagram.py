"""``rodcont critical``, ``diagram``, ``folds`` and ``fold-curve``: the straight rod's critical twists, the
whole response diagram at a tension, the fold table of a file, a fold continued in two parameters."""

from __future__ import annotations

import os
import sys
import time
from types import SimpleNamespace

import click

from .app import main_group
from .common import (
    UserError,
    check_out,
    explicit,
    file_meta,
    load_any_file,
    load_branch_file,
    make_rod,
    reference_curve,
    stretch_warning,
    tension_of,
    worded,
)
from .options import check_number, rod_options
from .progress import Interrupts, Progress
from .tables import diagram_branches, diagram_folds, diagram_unfinished, fold_table, user_folds
from .trace_options import given_options, rod_changes, trace_kwargs, trace_options


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=check_number("--gamma"),
              help="tension ratio T / (w L) (or --T)")
@click.option("--phi-max", type=float, default=40.0, show_default=True, callback=check_number("--phi-max"))
@click.option("--phi-min", type=float, default=0.0, show_default=True, callback=check_number("--phi-min"))
@rod_options
def critical(gamma, phi_max, phi_min, N, k, w, EI, GJ, EA, L):
    """Critical twists: where the straight weightless rod under the same tension buckles.

    From the tangent operator along the exact straight state (each double
    root, a circle of helical modes, listed once): Phi, torque m = GJ alpha
    Phi / L and m L / (alpha EI).
    """
    from ..drivers.diagram import critical_twists
    rod = make_rod(w, EI, GJ, EA, L)
    reference_curve(rod, "critical")
    gamma, T = tension_of(gamma, rod)
    try:
        crit = critical_twists(rod, T, phi_max=phi_max, phi_min=phi_min, k=k)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None
    stretch_warning(rod, T)
    alpha = 1 + T / EA
    g = f" (Gamma = {gamma:g})" if gamma is not None else ""
    click.echo(f"# straight weightless rod, T = {T:.10g}{g}, alpha = 1 + T/EA = {alpha:.10g}")
    click.echo(f"{'n':>3} {'phi_L':>18} {'torque':>18} {'m L/(alpha EI)':>16}")
    for n, phi in enumerate(crit, 1):
        m = GJ * alpha * phi / L
        click.echo(f"{n:3d} {phi:18.12f} {m:18.12f} {m * L / (alpha * EI):16.10f}")
    if not crit:
        click.echo(f"none below phi_max = {phi_max:g}")


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=check_number("--gamma"),
              help="tension ratio T / (w L) (or --T)")
@trace_options
@click.option("--deflate", "deflate_at", type=float, multiple=True, callback=check_number("--deflate"),
              help="a Phi where deflated Newton looks for solutions the seeds missed (repeatable)")
@click.option("--l0", "l0", type=float, default=None, callback=check_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension is solved for at each point")
@click.option("--out", default=None, type=click.Path(dir_okay=False), help="diagram file to write (HDF5)")
@click.option("--resume", "resume_file", default=None, type=click.Path(dir_okay=False),
              help="finish the interrupted diagram in FILE.h5 (its complete branches kept), into FILE.h5 itself")
@click.option("--jobs", type=click.IntRange(1, 1024), default=None,
              help="branches traced at once on a pool of this many processes (the same branches as 1, which "
                   "traces them one after the other) [default: the usable cores]")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@click.option("--quiet", is_flag=True, help="no progress display")
@rod_options
def diagram(**given):
    """The whole response diagram at Gamma: every branch in [phi-min, phi-max], every fold.

    The primary branch from Phi = 0, one seed per interval between
    consecutive critical twists (traced both ways), --deflate for more;
    a branch reached twice is kept once. Prints one line per branch and the
    fold table with the waves on each side (+1 wave marks a fold that adds one),
    the wall-clock time and the CPU time (its own and its workers').
    """
    a = SimpleNamespace(**given)
    kw = trace_kwargs(a)
    rod = make_rod(a.w, a.EI, a.GJ, a.EA, a.L)
    reference_curve(rod, "diagram")
    if a.resume_file is not None:
        if a.jobs is not None and a.jobs > 1:
            raise UserError("--resume finishes a diagram's branches one after the other: drop --jobs")
        run, out = _resume_diagram(a.resume_file, a.out, kw, a.deflate_at, a.N, a.k), a.resume_file
    else:
        run, out = _new_diagram(a, rod, kw), a.out
    dg, elapsed, cpu = _run_diagram(run, out, a.quiet)
    click.echo(f"critical twists  {', '.join(f'{c:.8f}' for c in dg.critical)}")
    click.echo(f"branches         {len(dg.branches)}")
    diagram_branches(dg)
    click.echo(f"time             {elapsed:.2f} s")
    click.echo(f"cpu_time         {cpu:.2f} s")
    diagram_folds(dg.folds)


def _new_diagram(a, rod, kw):
    """The runner of a new diagram into ``--out`` (its tension from --gamma/--T, or --l0)."""
    from ..drivers.diagram import diagram as run_diagram
    if a.out is None:
        raise UserError("--out FILE.h5 is required (or --resume FILE.h5)")
    T = None
    if a.l0 is None:
        _, T = tension_of(a.gamma, rod)
        stretch_warning(rod, T)
    elif a.gamma is not None or click.get_current_context().meta.get("rodcont.T") is not None:
        raise UserError("give one of --gamma, --T and --l0")
    check_out(a.out, [], a.overwrite)

    def run(**more):
        return run_diagram(None, rod, N=a.N, k=a.k, T=T, l0=a.l0, out=a.out, overwrite=a.overwrite,
                           deflate_at=a.deflate_at, meta=file_meta(), jobs=a.jobs, **more, **kw)
    return run


def _cpu_seconds() -> float:
    """CPU time (user + system) of this process and of its children that have ended (a pool's workers, once
    it is shut down)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _run_diagram(run, out, quiet):
    """``run`` with Ctrl-C between points (the diagram file keeps its complete branches); ``(diagram, wall-clock
    seconds, CPU seconds)``."""
    with Interrupts() as intr:
        progress = Progress(True, intr)
        t0, c0 = time.perf_counter(), _cpu_seconds()
        interrupted = False
        try:
            dg = run(callback=progress, progress=None if quiet else (lambda m: click.echo(m, err=True)))
        except KeyboardInterrupt:
            interrupted = True
        except (ValueError, TypeError) as exc:
            raise UserError(str(exc)) from None
    if interrupted:
        if os.path.exists(out):
            click.echo(f"interrupted: {out} holds the branches completed so far; finish it with "
                       f"rodcont diagram --resume {out}", err=True)
        sys.exit(intr.exit_code)
    return dg, time.perf_counter() - t0, _cpu_seconds() - c0


def _resume_diagram(path, out, kw, deflate_at, N, k):
    """``diagram --resume FILE.h5``: the runner that finishes it in place (rodcont.restart.resume_diagram);
    options given must be the file's."""
    import numpy as np

    from ..branchfile import same_file
    from ..restart import resume_diagram
    if out is not None and not same_file(out, path):
        raise UserError(f"--resume finishes {path} in place: drop --out {out} (or resume a copy)")
    options = given_options(kw)
    options.pop("store_every", None)
    d = load_any_file(path)
    if d.attrs.get("kind") != "diagram":
        raise UserError(f"{path} is not a diagram file: resume a trace with rodcont trace --resume {path}")
    stored = [float(v) for v in np.atleast_1d(d.attrs.get("deflate_at", []))] if "deflate_at" in d.attrs else []
    if explicit("deflate_at") and sorted(deflate_at) != sorted(stored):
        raise UserError(f"--deflate differs from the diagram file's ({', '.join(f'{v:g}' for v in stored) or 'none'}"
                        f"): a resumed diagram keeps its options (drop it)")
    for name, given, own in (("N", N, d.attrs.get("N")), ("k", k, d.attrs.get("k"))):
        if explicit(name) and own is not None and int(given) != int(own):
            raise UserError(f"--{name} {given} differs from the diagram file's {name} = {own}: a resumed diagram keeps "
                            f"its mesh (drop it)")

    def check(args):  # the file itself is the output
        check_out(path, [], True)

    def run(**more):
        try:
            return resume_diagram(path, changes=rod_changes(), options=options, check=check, data=d, **more)
        except (ValueError, TypeError) as exc:
            raise UserError(str(exc)) from None

    return run


@main_group.command()
@click.argument("file")
def folds(file):
    """Print the fold table of a branch or diagram file."""
    d = load_any_file(file)
    if d.attrs.get("kind") == "bvp":
        user_folds(d.branches[0])
        return
    if d.attrs.get("kind") == "diagram":
        click.echo(f"# {file}: diagram at Gamma = {d.attrs.get('gamma'):g}, {len(d.branches)} branches"
                   + diagram_unfinished(file, d))
        diagram_folds(list(d.folds))
        return
    data = d.branches[0]
    click.echo(f"# {file}: Gamma = {data.gamma:g}, {len(data)} points, stop: {data.attrs.get('stop_reason')}")
    fold_table(data)


@main_group.command("fold-curve")
@click.argument("spec")
@click.option("--param", type=click.Choice(["gamma", "T", "w", "EI", "GJ", "EA"]), default="gamma", show_default=True,
              help="second parameter (gamma keeps w fixed; the others keep T fixed)")
@click.option("--range", "prange", type=float, nargs=2, required=True, callback=check_number("--range"),
              help="A B: the interval of the parameter")
@click.option("--ds", type=float, default=0.05, show_default=True, callback=check_number("--ds", positive=True))
@click.option("--ds-max", type=float, default=0.5, show_default=True, callback=check_number("--ds-max", positive=True))
@click.option("--max-steps", type=click.IntRange(1, 10**6), default=500, show_default=True)
@click.option("--max-error", type=float, default=1e-6, show_default=True,
              callback=check_number("--max-error", positive=True),
              help="accuracy guard on the estimated error of each fold")
@click.option("--forced", type=float, multiple=True, callback=check_number("--forced"),
              help="a parameter value that gets a point of its own")
@click.option("--uniform", is_flag=True, help="keep the fold's mesh (no adaptation)")
@click.option("--N-max", "N_max", type=click.IntRange(1, 20000), default=400, show_default=True)
@click.option("--out", required=True, type=click.Path(dir_okay=False), help="fold-curve file to write (HDF5)")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@click.option("--quiet", is_flag=True)
def fold_curve_cmd(spec, param, prange, ds, ds_max, max_steps, max_error, forced, uniform, N_max, out, overwrite,
                   quiet):
    """Continue a fold of a branch file in (Phi, PARAM): FILE.h5:I (or FILE.h5:BRANCH:I) is the I-th fold, from 0
    (or FILE.h5:F<j>, the j-th from 1)."""
    from ..drivers.foldcurve import fold_curve
    path, branch, fold = _fold_spec(spec)
    data = load_branch_file(path, branch)
    check_out(out, [path], overwrite, loaded=(data,))
    click.get_current_context().meta["rodcont.param"] = param
    with Interrupts() as intr:
        progress = Progress(quiet, intr, param)
        t0 = time.perf_counter()
        try:
            res = fold_curve(data, fold, param, prange[0], prange[1], out=out, ds=ds, ds_max=ds_max,
                             max_steps=max_steps, forced=forced, max_error=max_error, overwrite=overwrite,
                             adapt=not uniform, N_max=N_max, callback=progress)
        except KeyboardInterrupt:
            progress.done()
            click.echo(f"interrupted: {out} holds the points computed so far", err=True)
            sys.exit(intr.exit_code)
        except (ValueError, TypeError) as exc:
            raise UserError(worded(str(exc))) from None
    progress.done()
    if len(res) <= 1:
        raise UserError(f"the fold could not be continued: {worded(res.message_first)}; {worded(res.message)}")
    click.echo(f"points       {len(res)}")
    click.echo(f"stop reasons down: {worded(res.message_first)}; up: {worded(res.message)}")
    click.echo(f"time         {time.perf_counter() - t0:.3f} s")
    click.echo(f"{param:>12} {'phi_L':>18} {'stretch':>16} {'torque':>14} kind")
    for i in range(len(res)):
        d = res.row_at(i)
        click.echo(f"{d[param]:12.6f} {d['phi_L']:18.12f} {d['stretch']:16.10f} {d['torque']:14.8f} {d['kind']}")


def _fold_spec(spec):
    """``(path, branch, fold)`` of FILE.h5[:BRANCH]:I (I from 0) or :F<j> (the label ``folds`` prints)."""
    from ..branchfile import BranchFileError, split_spec
    try:
        path, branch, label = split_spec(spec, "fold-curve")
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    if label.strip().upper().startswith("F"):
        return path, branch, label
    try:
        return path, branch, int(label)
    except ValueError:
        raise UserError(f"fold-curve expects FILE.h5:I with I the fold number from 0 (or F<j> from 1), got "
                        f"{label!r}") from None
