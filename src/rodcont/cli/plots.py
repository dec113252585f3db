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
    from ..plots import DRILL_COLUMNS, PLOT_VARIABLES, is_drill_string
    allowed = PLOT_VARIABLES + ("gamma", "T", "w", "EI", "GJ", "EA") + CONTACT_COLUMNS
    if any(is_drill_string(d.attrs) for d in data):  # a drill string's columns, where every file holds them
        allowed += tuple(c for c in DRILL_COLUMNS if all(c in b.branch for d in data for b in d.branches))
        _same_axes(data, xvar, yvar)
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


def _same_axes(data, xvar, yvar) -> None:
    """A drill string's file drawn with others on the axes their defaults give: one variable each (a trip in depth
    beside a trace in T, or a rod's Φ, is refused unless --x and --y name them)."""
    from ..plots import default_axes
    for a, (name, given) in enumerate((("--x", xvar), ("--y", yvar))):
        seen = sorted({default_axes(d.attrs)[a] for d in data})
        if given is None and len(seen) > 1:
            raise UserError(f"{name}: the files are drawn against different variables by default "
                            f"({', '.join(seen)}): name one with {name}")


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
    from ..drivers.broomstick import is_broomstick_file
    if any(os.path.isfile(f) and is_broomstick_file(f) for f in files):
        return _plot_broomstick(files, output, xvar, yvar, labels, log, title)
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


def _plot_broomstick(files, output, xvar, yvar, labels, log, title) -> None:
    """``plot B.h5`` of a broomstick file: the broomstick's own figure (hook loads and the rotating torque against
    depth, the soft string beside), redrawn from the file; alone, and with no axes to choose."""
    from ..drivers.broomstick import plot_broomstick, read_broomstick
    if len(files) > 1:
        raise UserError("a broomstick file is plotted alone (its figure has its own axes): give one file")
    given = [name for name, v in (("--x", xvar), ("--y", yvar), ("--label", labels), ("--log/--linear", log))
             if v not in (None, ())]
    if given:
        raise UserError(f"{given[0]}: a broomstick file is drawn as the broomstick (hook load and surface torque "
                        f"against bit depth); only --title applies")
    try:
        plot_broomstick(read_broomstick(files[0]), output, title)
    except ValueError as exc:
        raise UserError(str(exc)) from None
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
    from ..export import is_drill_string
    if is_drill_string(data):  # each point has its own depth, sections and joins: rebuilt from the record
        return _drill_shape(file, data, points, output)
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


def _drill_points(file, data, points) -> list:
    """The points ``points`` of a drill string's file rebuilt (:func:`rodcont.export.drill_point`), one-line
    errors for a label the file does not hold or a file without the drilling record."""
    from ..branchfile import BranchFileError
    from ..export import ExportError, drill_point
    out = []
    for label in points:
        try:
            out.append((data.resolve(label), drill_point(data, data.resolve(label))))
        except (BranchFileError, ExportError) as exc:
            raise UserError(str(exc)) from None
    return out


def _drill_shape(file, data, points, output) -> None:
    """``shape`` of a trip's (or a drill string's) points: each centreline in its own well path to its bit (east,
    north, up), the deflections from the hole's axis and the deepest point's clearance magnified alike, the wall
    contacts (gap below 1 % of the clearance) as dots."""
    import numpy as np

    from ..plots import shape_figure
    tds = _drill_points(file, data, points)
    deep = max((td for _, td in tds), key=lambda td: td.depth)
    wall = deep.system.model.wall
    magnify = max(1.0, 0.12 * deep.depth / wall.c_max)
    curves, contacts = [], []
    for i, td in tds:
        S = np.linspace(0.0, td.depth, 400)
        R = td.placed.curve.jet(S).R
        r = R + magnify * (td.system.model.centreline(td.system.disc, td.x, S) - R)
        gap = td.system.model.contact(td.system.disc, td.x, td.params, S=S)["gap"]
        contacts.append(r[:, gap <= 0.01 * td.system.model.wall.clearance_at(S)])
        curves.append((r, f"#{i}: bit at {td.depth:.6g} m, hook load {td.hook_load / 1e3:.5g} kN"))
    if not all(np.all(np.isfinite(r)) for r, _ in curves):
        raise UserError(f"{file}: the stored solution gives a centreline that is not finite")
    title = (f"{os.path.basename(file)}  ({data.attrs.get('operation', '')}; east, north, up in m)\n"
             f"deflections from the hole's axis and clearance drawn ×{magnify:.3g}")
    try:
        shape_figure(curves, output, title, reference=deep.placed.curve.jet(np.linspace(0, deep.depth, 400)).R,
                     tube=_tube(deep.system.model, wall, magnify), contacts=contacts,
                     axes=("east (m)", "north (m)", "up (m)"))
    except (ValueError, OverflowError) as exc:
        raise UserError(f"cannot draw: {exc}") from None
    except OSError as exc:
        raise UserError(f"cannot write {output}: {exc.strerror or exc}") from None
    click.echo(f"wrote {output}")


def _tube(model, wall, magnify):
    """The conduit's wall as three (S, angle) coordinate arrays, its clearance times ``magnify``."""
    import numpy as np
    theta = np.linspace(0.0, 2 * np.pi, 25)
    St = np.linspace(*model.interval, 121)
    jt = model.curve.jet(St)
    cS = np.broadcast_to(wall.clearance_at(St), St.shape)[:, None]
    ring = magnify * cS * (jt.K[0][:, :, None] * np.cos(theta) + jt.K[1][:, :, None] * np.sin(theta))
    return tuple(jt.R[a][:, None] + ring[a] for a in range(3))
