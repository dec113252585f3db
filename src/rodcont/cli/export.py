"""``rodcont export`` and ``rodcont animate``: stored equilibria as CSV, VTK, NumPy files and animations.

Errors a user can cause end, through :class:`rodcont.cli.common.UserError`, in one line and exit
status 2. Only click is imported here; numpy, h5py and matplotlib are imported when a command runs.
"""

from __future__ import annotations

import os

import click

from .common import UserError, image_out, input_files, load_any_file

MAX_SAMPLES = 1_000_000           # rodcont.export.MAX_SAMPLES (not imported: it loads numpy)
MAX_SERIES_VALUES = 20_000_000    # samples x points for --all
SUFFIXES = {".csv": "csv", ".vtp": "vtk", ".pvd": "vtk", ".npz": "npz"}


def _branch_spec(spec: str):
    """``FILE``, ``FILE:BRANCH`` (diagram) or ``FILE:POINT`` (single branch), ``FILE:BRANCH:POINT``.

    Returns ``(path, branch, point, diagram)``: the names not in ``spec`` are None;
    ``diagram`` is the loaded :class:`DiagramData`.
    """
    path, tail = spec, []
    if not os.path.exists(spec) and ":" in spec:
        parts = spec.rsplit(":", 2)
        if len(parts) == 3 and os.path.exists(parts[0]) and not os.path.exists(parts[0] + ":" + parts[1]):
            path, tail = parts[0], parts[1:]
        else:
            head, last = spec.rsplit(":", 1)
            if os.path.exists(head):
                path, tail = head, [last]
    if any(not t.strip() for t in tail):
        raise UserError(f"expected FILE.h5, FILE.h5:BRANCH or FILE.h5:BRANCH:POINT, got {spec!r}")
    # a file without rodcont's checksum is read, and said so
    diagram = load_any_file(path)
    is_diagram = diagram.attrs.get("kind") == "diagram" or any(b.name for b in diagram.branches)
    branch = point = None
    if len(tail) == 2:
        branch, point = tail
        if not is_diagram:
            raise UserError(f"{path} is a single branch, not a diagram: no branch {branch} "
                              f"(give {path}:POINT or --point)")
    elif len(tail) == 1:
        if is_diagram:
            branch = tail[0]
        else:
            point = tail[0]
    return path, branch, point, diagram


def _pick_branch(path, diagram, branch, branch_opt):
    if branch is not None and branch_opt is not None and str(branch) != str(branch_opt):
        raise UserError(f"two branches named: {path}:{branch} and --branch {branch_opt}")
    branch = branch if branch is not None else branch_opt
    names = [b.name for b in diagram.branches]
    is_diagram = diagram.attrs.get("kind") == "diagram" or any(names)
    if not is_diagram:
        if branch is not None:
            raise UserError(f"{path} is a single branch, not a diagram: no branch {branch}")
        data = diagram.branches[0]
    else:
        if branch is None:
            if len(names) != 1:
                raise UserError(f"{path} is a diagram of {len(names)} branches: name one as {path}:<j> "
                                  f"or --branch <j> (j in {', '.join(names)})")
            branch = names[0]
        if str(branch).strip() not in names:
            raise UserError(f"{path} has no branch {branch} (branches: {', '.join(names)})")
        data = diagram.branches[names.index(str(branch).strip())]
    if len(data) == 0:
        raise UserError(f"{data.label} holds no point")
    return data


def _is_branch_file(path: str) -> bool:
    from ..branchfile import MAGIC
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(MAGIC))
        if head == MAGIC:
            return True
        with open(path, "rb") as fh:
            return fh.read(8) == b"\x89HDF\r\n\x1a\n"
    except OSError:
        return False


def _check_output(path: str, diagram, overwrite: bool = False, what: str = "-o", series: bool = False):
    """The output path: a name, none of the command's inputs (the branch file, the surveys it names: any name
    of them), in a directory that exists and is writable, not a branch file, an existing file only with
    ``--overwrite`` (a series' files are checked when it is written)."""
    if os.path.isfile(path) and _is_branch_file(path) and not any(
            os.path.samefile(path, p) for p in [diagram.path] if os.path.exists(p)):
        raise UserError(f"{path} is an HDF5 (branch) file: export will not overwrite it, choose another name")
    return image_out(path, [diagram.path], overwrite or series, loaded=(diagram,))


def _series_not_inputs(output: str, n: int, diagram) -> None:
    """No file of a ``.pvd`` series is one of the command's inputs (under any name)."""
    from ..branchfile import same_file
    from ..export import series_files
    inputs = input_files(loaded=(diagram,))
    for target in series_files(output, n):
        for src in inputs:
            if same_file(target, src):
                raise UserError(f"-o {output}: its series file {target} is the input file {src}: write to "
                                  f"another name")


def _format(output: str, fmt: str | None, all_points: bool) -> str:
    ext = os.path.splitext(output)[1].lower()
    implied = SUFFIXES.get(ext)
    if fmt is None:
        if implied is None:
            raise UserError(f"cannot tell the format of -o {output}: give --format csv|vtk|npz "
                              f"or name it .csv, .vtp (.pvd with --all) or .npz")
        fmt = implied
    fmt = fmt.lower()
    if implied is not None and implied != fmt:
        raise UserError(f"-o {output} has the suffix of {implied} files, not {fmt}: name it "
                          f"{ {'csv': '.csv', 'vtk': '.vtp (or .pvd with --all)', 'npz': '.npz'}[fmt]}")
    if fmt == "csv" and all_points:
        raise UserError("--all writes a series: use --format vtk (a .pvd collection for ParaView) or npz "
                          "(arrays stacked by point); a CSV holds one point (--point I)")
    if fmt == "vtk":
        if all_points and ext != ".pvd":
            raise UserError(f"--all --format vtk writes a ParaView collection: name it .pvd "
                              f"(-o {os.path.splitext(output)[0]}.pvd; the .vtp files go beside it)")
        if not all_points and ext == ".pvd":
            raise UserError(f"-o {output}: a .pvd collection is written with --all; name one point's file .vtp")
    return fmt


@click.command("export")
@click.argument("file")
@click.option("--point", default=None,
              help="the point: index (from 0, negative from the end), F<j> (fold j) or BP<j> (branch point j)")
@click.option("--all", "all_points", is_flag=True,
              help="every point of the branch: a .pvd series of .vtp files (vtk) or stacked arrays (npz)")
@click.option("--branch", default=None, help="the branch of a diagram file (or FILE.h5:<j>)")
@click.option("--samples", type=click.IntRange(2, MAX_SAMPLES), default=200, show_default=True,
              help="number of points along the rod")
@click.option("--grid", type=click.Choice(["S", "s", "mesh"]), default="S", show_default=True,
              help="sample uniformly in the reference coordinate S or in the unstressed arclength s, or on the "
                   "solution's mesh (16 points per subinterval, --samples unused: point contacts fall on it)")
@click.option("--format", "fmt", type=click.Choice(["csv", "vtk", "npz"], case_sensitive=False), default=None,
              help="output format [default: from the suffix of -o: .csv, .vtp/.pvd, .npz]")
@click.option("-o", "--output", required=True, help="file to write")
@click.option("--overwrite", is_flag=True, help="replace -o (and the files of its series) if they exist")
def export_cmd(file, point, all_points, branch, samples, grid, fmt, output, overwrite):
    """Fields along the rod at a stored point: centreline, directors, curvatures and twist, internal force
    and moment (global and director components), stretch, sampled uniformly in S (or s).

    FILE is a branch file, FILE.h5:<j> a branch of a diagram (also FILE.h5:<j>:POINT).
    CSV: '#' comment lines (point, rod, units), one header row (S,s,x,y,z,d1_x,...).
    VTK: XML PolyData (.vtp), one polyline with every field as point data, for ParaView;
    --all writes a .pvd time series (timestep = point index) with one .vtp per point.
    A drill string's file (a trip, solve --string --out): S is the measured depth, x, y, z east, north, up (m),
    with axial_force, torque (at S = 0 the hook load and the surface torque), pressure, gap and in_contact.
    """
    path, spec_branch, spec_point, diagram = _branch_spec(file)
    if spec_point is not None and point is not None and spec_point.strip() != point.strip():
        raise UserError(f"two points named: {file} and --point {point}")
    point = point if point is not None else spec_point
    if all_points and point is not None:
        raise UserError("give --point or --all, not both")
    if not all_points and point is None:
        raise UserError("which point? give --point I|F<j>|BP<j> (or --all for the whole branch)")
    _check_output(output, diagram, overwrite, series=all_points)
    fmt = _format(output, fmt, all_points)
    data = _pick_branch(path, diagram, spec_branch, branch)
    from ..branchfile import BranchFileError
    from ..export import ExportError, export_point
    if all_points and fmt == "vtk":
        _series_not_inputs(output, len(data), diagram)
    if all_points:
        return _export_series(data, output, fmt, samples, grid, overwrite)
    try:
        i = data.resolve(point)
        samples = int(export_point(data, point.strip(), output, fmt, samples, grid)["S"].size)
    except (ExportError, BranchFileError) as exc:
        raise UserError(str(exc)) from None
    except OSError as exc:
        raise UserError(f"cannot write {output}: {exc.strerror or exc}") from None
    where = (f"depth {float(data.branch['depth'][i]):.10g} m" if data.param == "depth"
             else f"T = {float(data.branch['T'][i]):.10g} N at depth {float(data.attrs['depth']):.10g} m"
             if data.param == "T" and "drilling" in data.attrs else f"Φ = {float(data.branch['phi_L'][i]):.10g}")
    click.echo(f"wrote {output} (point {i}, {where}, {samples} samples)")


def _export_series(data, output, fmt, samples, grid, overwrite) -> None:
    """``export --all``: every point of the branch, a .pvd series of .vtp files or stacked arrays (.npz)."""
    from ..branchfile import BranchFileError
    from ..export import ExportError, export_branch, series_dir
    if samples * len(data) > MAX_SERIES_VALUES:
        raise UserError(f"--all with --samples {samples} on {len(data)} points is {samples * len(data):,} "
                        f"samples (at most {MAX_SERIES_VALUES:,}): lower --samples")
    d = series_dir(output) if fmt == "vtk" else None
    if d is not None and os.path.lexists(d) and not os.path.isdir(d):
        raise UserError(f"cannot write the series: {d} exists and is not a directory")
    made = d is not None and not os.path.exists(d)
    try:
        n = export_branch(data, output, fmt, samples, grid, overwrite=overwrite)
    except (ExportError, BranchFileError, OSError) as exc:
        if made:  # leave nothing half-written behind
            import shutil
            shutil.rmtree(d, ignore_errors=True)
        msg = f"cannot write {output}: {exc.strerror}" if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise UserError(msg) from None
    extra = f", one .vtp per point in {series_dir(output)}" if fmt == "vtk" else ""
    click.echo(f"wrote {output} ({n} points, {samples} samples each{extra})")


@click.command("animate")
@click.argument("file")
@click.option("--branch", default=None, help="the branch of a diagram file (or FILE.h5:<j>)")
@click.option("-o", "--output", required=True, help="animation to write: .gif (or .mp4, needs ffmpeg)")
@click.option("--fps", type=click.IntRange(1, 60), default=10, show_default=True, help="frames per second")
@click.option("--samples", type=click.IntRange(2, 10000), default=120, show_default=True,
              help="points along the rod in each frame")
@click.option("--max-frames", type=click.IntRange(1, 10000), default=300, show_default=True,
              help="at most this many frames (points spread evenly along the branch)")
@click.option("--title", default=None, help="title over the response diagram")
@click.option("--overwrite", is_flag=True, help="replace -o if it exists")
def animate_cmd(file, branch, output, fps, samples, max_frames, title, overwrite):
    """The rod's shape along a branch (3-D, ticks of d1 show the twist) beside the response
    diagram (Phi against stretch) with the current point marked: a GIF, or an MP4 with ffmpeg.

    FILE is a branch file or FILE.h5:<j> (a branch of a diagram; the others are drawn in grey).
    """
    ext = os.path.splitext(output)[1].lower()
    if ext not in (".gif", ".mp4"):
        raise UserError(f"-o {output}: animations are written as .gif or .mp4 (name it so)")
    path, spec_branch, spec_point, diagram = _branch_spec(file)
    if spec_point is not None:
        raise UserError(f"animate shows a whole branch: give {path} or {path}:<branch>, not a point")
    _check_output(output, diagram, overwrite)
    from ..export import ExportError, animate, ffmpeg_available
    if ext == ".mp4" and not ffmpeg_available():
        raise UserError("writing MP4 needs ffmpeg, which is not installed (not on PATH): install it, "
                          "or write a .gif")
    data = _pick_branch(path, diagram, spec_branch, branch)
    others = [b for b in diagram.branches if b is not data]
    try:
        n = animate(data, output, fps=fps, samples=samples, max_frames=max_frames, others=others, title=title)
    except ExportError as exc:
        raise UserError(str(exc)) from None
    except OSError as exc:
        raise UserError(f"cannot write {output}: {exc.strerror or exc}") from None
    click.echo(f"wrote {output} ({n} frames of {len(data)} points)")
