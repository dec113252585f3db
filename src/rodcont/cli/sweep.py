"""``rodcont sweep``: one branch (or diagram) per Gamma, traced in parallel."""

from __future__ import annotations

import contextlib
import math
import os
import time
from types import SimpleNamespace

import click

from .app import main_group
from .common import UserError, input_files, make_rod, reference_curve, stretch_warning
from .options import GreedyFloats, check_number, rod_options
from .trace_options import trace_kwargs, trace_options

SCHEDULER_TIMEOUT = "10s"  # to connect to --scheduler: a wrong address is an error, not a wait


@main_group.command()
@click.option("--gamma", "gammas", cls=GreedyFloats, type=float, required=True, callback=check_number("--gamma"),
              help="tension ratios, e.g. 0 0.5 1 2 5")
@trace_options
@click.option("--diagram", "whole", is_flag=True, help="the whole diagram per Gamma, not only the primary branch")
@click.option("--jobs", type=click.IntRange(1, 1024), default=None, help="parallel processes [default: all cores]")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="run on the running Dask scheduler at ADDRESS (tcp://HOST:8786; its workers must see --out) "
                   "instead of a process pool")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="directory for the files")
@click.option("--overwrite", is_flag=True, help="replace files that exist in the directory")
@click.option("--quiet", is_flag=True)
@rod_options
def sweep(**given):
    """A family, one branch (or --diagram) per Gamma, traced in parallel, and their combined response diagram."""
    a = SimpleNamespace(**given)
    from ..drivers.sweep import sweep as run_sweep
    if click.get_current_context().meta.get("rodcont.T") is not None:
        raise UserError("sweep runs one branch per --gamma; --T is for a single trace or diagram")
    kw = trace_kwargs(a)
    rod = make_rod(a.w, a.EI, a.GJ, a.EA, a.L)
    curve = reference_curve(rod, "sweep --diagram" if a.whole else None)
    if curve is not None:
        kw["curve"] = curve.spec
    _check_gammas(a.gammas, rod, kw)
    if a.scheduler is not None and a.jobs is not None:
        raise UserError("give --jobs (a process pool here) or --scheduler (a Dask cluster's workers), not both")
    made = _make_out_dir(a.out_dir, a.gammas, a.whole)
    t0 = time.perf_counter()
    try:
        with _executor(a.scheduler) as executor:
            res = run_sweep(list(a.gammas), a.out_dir, rod=rod, N=a.N, k=a.k, jobs=a.jobs, executor=executor,
                            progress=not a.quiet, diagram=a.whole, overwrite=a.overwrite, **kw)
    except (ValueError, TypeError, OSError, UserError) as exc:
        if made and not os.listdir(a.out_dir):
            os.rmdir(a.out_dir)
        if isinstance(exc, UserError):
            raise
        msg = f"{exc.strerror}: {exc.filename}" if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise UserError(msg) from None
    _print_sweep(res, time.perf_counter() - t0, a.scheduler)
    failed = [r for r in res["branches"] if r["error"]]
    if failed:
        if made and not os.listdir(a.out_dir):
            os.rmdir(a.out_dir)
        first = failed[0]
        raise UserError(f"{len(failed)} of {len(res['branches'])} Gamma failed (Gamma {first['gamma']:g}: "
                        f"{first['error']}); the others are in {a.out_dir}" if len(failed) < len(res["branches"])
                        else f"every Gamma failed (Gamma {first['gamma']:g}: {first['error']})")


def _check_gammas(gammas, rod, kw) -> None:
    """Every --gamma a usable, distinct tension, and the trace options consistent, before any file is made."""
    from ..drivers.solve import check_tension
    from ..drivers.sweep import gamma_name
    from ..drivers.trace import TraceOptions
    for g in gammas:
        try:
            check_tension(rod, rod.tension(g), f"--gamma {g:g}:")
        except ValueError as exc:
            raise UserError(str(exc)) from None
    if len({gamma_name(g) for g in gammas}) != len(gammas):
        raise UserError("--gamma values must be distinct")
    for g in gammas:
        stretch_warning(rod, rod.tension(g))
    try:
        TraceOptions(**{key: v for key, v in kw.items() if key not in ("store_every", "curve")})
        for g in gammas:
            if not math.isfinite(rod.tension(g)):
                raise ValueError(f"--gamma {g:g} gives a tension that is not finite")
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None


def _make_out_dir(out_dir, gammas, whole) -> bool:
    """The output directory, made if it is not there (True then); none of its files is an input."""
    from ..branchfile import same_file
    from ..drivers.sweep import branch_path
    if not out_dir.strip():
        raise UserError("--out needs a directory name")
    parent = os.path.dirname(os.path.abspath(out_dir))
    if not os.path.isdir(parent):
        raise UserError(f"cannot create {out_dir}: directory {parent} does not exist")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise UserError(f"--out {out_dir} exists and is not a directory")
    for p in [branch_path(out_dir, g, whole) for g in gammas] + [os.path.join(out_dir, "response_diagram.png")]:
        for src in input_files():  # --config, --reference well:FILE
            if same_file(p, src):
                raise UserError(f"--out {out_dir}: its file {p} is the input file {src}: write to another directory")
    made = not os.path.exists(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create {out_dir}: {exc.strerror}") from None
    return made


@contextlib.contextmanager
def _executor(address):
    """None (the sweep's own process pool), or the executor of a Dask client of the scheduler at ``address``."""
    if address is None:
        yield None
        return
    try:
        from dask.distributed import Client
    except ImportError:
        raise UserError("--scheduler needs dask.distributed: pip install 'rodcont[dask]'") from None
    try:
        client = Client(address, timeout=SCHEDULER_TIMEOUT)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise UserError(f"cannot reach the Dask scheduler at {address}: {' '.join(str(exc).split())}") from None
    with client:
        yield client.get_executor()


def _print_sweep(res, elapsed, scheduler=None) -> None:
    click.echo(f"{'gamma':>8} {'branches':>8} {'points':>7} {'folds':>6} {'first fold phi_L':>18}  stop reason")
    for r in res["branches"]:
        ff = f"{r['first_fold']:18.10f}" if r["first_fold"] is not None else f"{'-':>18}"
        click.echo(f"{r['gamma']:8g} {r['branches']:8d} {r['points']:7d} {r['folds']:6d} {ff}  {r['stop_reason']}")
    click.echo(f"diagram      {res['diagram']}")
    where = f"on the Dask scheduler {scheduler}" if scheduler else f"{res['jobs']} processes"
    click.echo(f"time         {elapsed:.2f} s ({where})")
