"""``rodcont solve``: one equilibrium, reached by loading Phi (or the end torque) up from 0."""

from __future__ import annotations

import math
from types import SimpleNamespace

import click

from .app import main_group
from .common import UserError, check_out, conduit_of, explicit, file_meta, make_rod, stretch_warning, tension_of
from .drilling import DRILLING_KEYS, drilling_options, run_drilling_solve
from .options import check_number, rod_options


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=check_number("--gamma"),
              help="tension ratio T / (w L) (or --T)")
@click.option("--phi", "phi", type=float, default=None, callback=check_number("--phi"),
              help="end rotation Phi [rad] (or --torque)")
@click.option("--torque", type=float, default=None, callback=check_number("--torque"),
              help="end torque M instead of --phi: Phi becomes an unknown (printed as phi_L)")
@click.option("--l0", "l0", type=float, default=None, callback=check_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension becomes an unknown (printed as T)")
@click.option("--load-step", type=float, default=0.5, show_default=True,
              callback=check_number("--load-step", positive=True),
              help="Phi increment of the natural continuation from 0 (under --torque: GJ/L times it)")
@click.option("--conduit", type=click.Path(dir_okay=False), default=None,
              help="TOML file of a conduit around the reference curve ([conduit] clearance, reference, eps): "
                   "the rod stays inside it, touching its wall where it must")
@click.option("--max-error", type=float, default=1e-6, show_default=True,
              callback=check_number("--max-error", positive=True), help="accuracy guard on the estimated error")
@click.option("--uniform", is_flag=True, help="keep the first mesh (no refinement)")
@click.option("--N-max", "N_max", type=click.IntRange(1, 20000), default=4000, show_default=True,
              help="largest mesh the refinement may reach")
@click.option("--out", default=None, type=click.Path(dir_okay=False),
              help="write the equilibrium as a one-point branch file (export, shape, trace --start read it)")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@drilling_options
@rod_options
def solve(**given):
    """One equilibrium at (Gamma, Phi), reached by loading Phi (or the end torque) up from 0.

    The mesh starts from the problem's lengths (or --N) and is refined until the
    estimated error (a re-solve in a richer space, as trace's accuracy guard) is
    below --max-error and, in a conduit, the side force's below 1e-3; a result far
    above them is refused. Prints `name value` lines: the controls (T, gamma,
    phi_L, torque, l0) and responses (stretch, helical_waves, min_alignment, in a
    conduit min_gap, side_force and the contact zones), Newton's iterations and
    residual norm, the mesh N, the error estimates (what to trust).

    With --string S.toml a drill string in the well file --conduit WELL.toml: its
    bit at --depth, under --operation, --friction, ... (torque and drag); prints
    hook_load, surface_torque, side_force, the contact zones, error and N.
    """
    a = SimpleNamespace(**given)
    if a.string is not None:
        return _solve_string(a)
    said = explicit(*DRILLING_KEYS)
    if said:
        raise UserError(f"--{said[0].replace('_', '-')} is an option of a drill string: give --string S.toml "
                        f"(and the well as --conduit WELL.toml)")
    _solve_rod(a.gamma, a.phi, a.torque, a.l0, a.load_step, a.conduit, a.max_error, a.uniform, a.N_max, a.out,
               a.overwrite, a.N, a.k, a.w, a.EI, a.GJ, a.EA, a.L)


def _solve_string(a) -> None:
    """``solve --string S.toml --conduit WELL.toml``: torque and drag (:func:`.drilling.run_drilling_solve`)."""
    for name in ("gamma", "phi", "torque", "l0"):
        if getattr(a, name) is not None:
            raise UserError(f"--{name} is not an option of a drill string (--string): its loads are the string's "
                            f"weight, the operation, --wob and --bit-torque; drop --{name}")
    if click.get_current_context().meta.get("rodcont.T") is not None:
        raise UserError("--T is not an option of a drill string (--string): drop it")
    said = explicit("w", "EI", "GJ", "EA", "L", "uniform", "weight_direction", "reference", "load_step")
    if said:  # the string file and the survey give them (test_drilling_cli: they were ignored)
        raise UserError(f"--{said[0].replace('_', '-')} is not an option of a drill string (--string): its sections "
                        f"give w, EI, GJ and EA, the well file its path, --depth its length, gravity is down the "
                        f"true vertical depth; drop --{said[0].replace('_', '-')} (cap the mesh with --N-max)")
    values = {key: getattr(a, key) for key in DRILLING_KEYS}
    values.update(max_error=a.max_error, N_max=a.N_max, N=a.N if explicit("N") else None, k=a.k)
    run_drilling_solve(a.conduit, values, overwrite=a.overwrite, out=a.out)


def _solve_rod(gamma, phi, torque, l0, load_step, conduit, max_error, uniform, N_max, out, overwrite, N, k, w, EI, GJ,
               EA, L):
    """One equilibrium of the rod (``solve`` without --string)."""
    from ..drivers.solve import ConvergenceError, solve_equilibrium, write_equilibrium
    rod = make_rod(w, EI, GJ, EA, L)
    T = click.get_current_context().meta.get("rodcont.T")
    if l0 is not None and (gamma is not None or T is not None):
        raise UserError("give one of --gamma, --T and --l0")
    if l0 is None:
        gamma, T = tension_of(gamma, rod)
    if (phi is None) == (torque is None):
        raise UserError("give --phi (the end rotation) or --torque (the end torque), one of them")
    try:
        curve, wall = conduit_of(conduit, rod)
        if out is not None:
            check_out(out, [conduit] if conduit is not None else [], overwrite)
        if T is not None:
            stretch_warning(rod, T)
        eq = solve_equilibrium(None if T is not None else gamma, phi, rod, N=N if explicit("N") else None, k=k,
                               load_step=load_step, T=T, curve=curve, wall=wall, torque=torque, l0=l0,
                               adapt=not uniform, max_error=max_error, N_max=N_max, strict=True)
    except (ConvergenceError, ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None
    _print_equilibrium(eq, wall is not None)
    if out is not None:
        write_equilibrium(eq, out, overwrite=overwrite, meta=file_meta(), max_error=max_error)
        click.echo(f"wrote {out}", err=True)


def _print_equilibrium(eq, conduit: bool) -> None:
    o = eq.outputs
    for name in ("T", "gamma", "phi_L", "torque", "l0", "stretch"):
        if name != "gamma" or math.isfinite(o[name]):
            click.echo(f"{name} {o[name]:.15g}")
    click.echo(f"helical_waves {o['helical_waves']}")
    click.echo(f"min_alignment {o['min_alignment']:.15g}")
    if conduit:
        c = eq.contact()
        click.echo(f"min_gap {c['min_gap']:.6g}")
        click.echo(f"side_force {c['side_force']:.10g}")
        for a, b, f in c["zones"]:
            click.echo(f"contact {a:.6g} {b:.6g} {f:.10g}" + ("  (point)" if a == b else ""))
        click.echo(f"force_scale {o['force_scale']:.6g}")
    click.echo(f"newton_iterations {eq.newton.iterations}")
    click.echo(f"residual_norm {eq.newton.residual_norm:.6g}")
    click.echo(f"N {o['N']}")
    click.echo(f"error {eq.error:.2g}")
    if conduit:
        click.echo(f"side_force_error {eq.side_force_error:.2g}")
    for said in eq.notes:
        click.echo(f"rodcont: note: {said}", err=True)
    for said in eq.warnings:
        click.echo(f"rodcont: warning: {said}", err=True)
