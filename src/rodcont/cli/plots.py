"""``rodcont plot`` and ``rodcont shape``: response diagrams and centrelines as PNG."""

from __future__ import annotations

import os

import click

from .app import main_group
from .common import UserError, image_out, load_any_file, load_branch_file


def _check_plot_variables(data, xvar, yvar) -> None:
    """``--x``/``--y`` among the rod's variables (the contact columns where every file holds them), or, for
    files of a user's problem, their columns."""
    from ..branch import CONTACT_COLUMNS
    from ..plots import PLOT_VARIABLES
    allowed = PLOT_VARIABLES + ("gamma", "T", "w", "EI", "GJ", "EA") + CONTACT_COLUMNS
    users = [b for d in data if d.attrs.get("kind") == "bvp" for b in d.branches]
    if users:
        common = set.intersection(*(set(b.table) for b in users)) - {"kind", "located"}
        allowed = tuple(c for c in users[0].table if c in common)
    for name, v in (("--x", xvar), ("--y", yvar)):
        if v is not None and v not in allowed:
            raise UserError(f"{name} {v!r}: choose one of {', '.join(allowed)}")
        if v in CONTACT_COLUMNS and not users:
            for d in data:
                if any(v not in b.branch for b in d.branches):
                    raise UserError(f"{name} {v}: {d.path} holds no {v} (a branch traced in a conduit does: "
                                    f"trace --conduit FILE)")


@main_group.command()
@click.argument("files", nargs=-1, required=True)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="PNG to write")
@click.option("--x", "xvar", default=None, help="horizontal variable [default: stretch; a fold curve's parameter]")
@click.option("--y", "yvar", default=None, help="vertical variable [default: phi_L]")
@click.option("--label", "labels", multiple=True, help="legend label of each file, in order (repeatable)")
@click.option("--log/--linear", "log", default=None, help="horizontal scale [default: log for a positive stretch]")
@click.option("--title", default=None)
@click.option("--overwrite", is_flag=True, help="replace -o if it exists")
def plot(files, output, xvar, yvar, labels, log, title, overwrite):
    """Response diagrams: any two of phi_L, stretch, torque, l0, helical_waves, min_alignment, in a
    conduit side_force, min_gap or contact_zones, or a continued parameter (torque against Phi is the
    distinguished diagram); one colour per file, stable parts solid, unstable dashed, folds marked and
    labelled with the waves on each side."""
    image_out(output, files, overwrite)
    if not output.lower().endswith(".png"):
        raise UserError(f"-o {output}: plots are written as PNG (name it .png)")
    if labels and len(labels) != len(files):
        raise UserError(f"--label: give one per file ({len(files)}), got {len(labels)}")
    data = [load_any_file(f) for f in files]
    image_out(output, files, overwrite, loaded=data)  # nor a survey the files' reference curves read
    _check_plot_variables(data, xvar, yvar)
    if any(sum(len(b) for b in d.branches) == 0 for d in data):
        raise UserError("a branch file with no points cannot be plotted")
    from ..plots import response_diagram
    try:
        response_diagram(data, output, title, x=xvar, y=yvar, labels=list(labels) or None,
                         xscale=None if log is None else ("log" if log else "linear"))
    except (ValueError, OverflowError) as exc:
        raise UserError(f"cannot draw: {exc}") from None
    except OSError as exc:
        raise UserError(f"cannot write {output}: {exc.strerror or exc}") from None
    click.echo(f"wrote {output}")


@main_group.command()
@click.argument("file")
@click.option("--point", "points", multiple=True, default=("-1",), show_default=True,
              help="point index (from 0, negative from the end), F<j> or BP<j>; repeatable")
@click.option("--branch", default=None, help="the branch of a diagram file")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False), help="PNG to write")
@click.option("--overwrite", is_flag=True, help="replace -o if it exists")
def shape(file, points, branch, output, overwrite):
    """3D centreline of stored points of a branch file."""
    import numpy as np

    from ..plots import shape_figure
    from ..rod import EulerianRod
    image_out(output, [file], overwrite)
    if not output.lower().endswith(".png"):
        raise UserError(f"-o {output}: shapes are written as PNG (name it .png)")
    data = load_branch_file(file, branch)
    image_out(output, [file], overwrite, loaded=(data,))  # nor the survey its reference curve reads
    wall = data.wall
    model = EulerianRod(data.rod, data.curve, wall)
    # inside a conduit the deflections and the clearance are drawn magnified (else a thin pipe is a line)
    magnify = 1.0 if wall is None else max(1.0, 0.12 * model.interval[1] / wall.c_max)
    jet = model.curve.jet(np.linspace(*model.interval, 400))
    curves, contacts = _centrelines(file, data, model, points, magnify)
    title = f"{os.path.basename(file)}  (Γ = {data.gamma:g})"
    tube = None
    if wall is not None:
        tube = _tube(model, wall, magnify)
        title += (f"\nconduit of clearance {wall.c_min:g} to {wall.c_max:g}" if wall.varying else
                  f"\nconduit of clearance {wall.clearance:g}") + (
            f"; deflections and clearance drawn ×{magnify:.3g}" if magnify > 1 else "")
    try:
        shape_figure(curves, output, title, reference=jet.R if not model.constant_frame or wall else None,
                     tube=tube, contacts=contacts)
    except (ValueError, OverflowError) as exc:
        raise UserError(f"cannot draw: {exc}") from None
    except OSError as exc:
        raise UserError(f"cannot write {output}: {exc.strerror or exc}") from None
    click.echo(f"wrote {output}")


def _centrelines(file, data, model, points, magnify):
    """``(curves, contacts)``: the centreline of each stored point (its deflection from the axis times
    ``magnify`` in a conduit) with its label, and the parts of it in contact with the wall."""
    import numpy as np

    from ..branchfile import BranchFileError
    wall = data.wall
    S = np.linspace(*model.interval, 400)
    jet = model.curve.jet(S)
    curves, contacts = [], []
    for label in points:
        try:
            pt = data.point(label)
        except BranchFileError as exc:
            raise UserError(str(exc)) from None
        try:  # a file edited by hand (unverified) can hold a mesh that is not the rod's
            disc = model.discretise(breakpoints=pt["breakpoints"], k=int(data.attrs["k"]))
        except ValueError as exc:
            raise UserError(f"{file}: point {pt['index']}: {exc}") from None
        r = model.centreline(disc, pt["x"], S)
        if wall is not None:
            r = jet.R + magnify * (r - jet.R)  # r - R = Delta1 K1 + Delta2 K2
            p = model.params(float(pt["phi_L"]), T=data.tension)
            pressure = model.contact(disc, pt["x"], p, S=S)["pressure"]
            contacts.append(r[:, pressure >= wall.contact_level * model.contact_scale])
        curves.append((r, f"#{pt['index']}: Φ = {pt['phi_L']:.4f}, stretch = {pt['stretch']:.4f}"))
    if not all(np.all(np.isfinite(r)) and np.max(np.abs(r)) < 1e100 for r, _ in curves):
        raise UserError(f"{file}: the stored solution gives a centreline that is not finite")
    return curves, contacts


def _tube(model, wall, magnify):
    """The conduit's wall as three (S, angle) coordinate arrays, its clearance times ``magnify``."""
    import numpy as np
    theta = np.linspace(0.0, 2 * np.pi, 25)
    St = np.linspace(*model.interval, 121)
    jt = model.curve.jet(St)
    cS = np.broadcast_to(wall.clearance_at(St), St.shape)[:, None]
    ring = magnify * cS * (jt.K[0][:, :, None] * np.cos(theta) + jt.K[1][:, :, None] * np.sin(theta))
    return tuple(jt.R[a][:, None] + ring[a] for a in range(3))
