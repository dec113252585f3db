"""The command line of torque and drag (issue 23): ``solve --string`` and ``rodcont broomstick``.

* :func:`drilling_options`: the options ``solve`` (and ``trace``) take for a drill string in a well:
  ``--operation``, ``--trip-speed``, ``--rpm``, ``--friction``, ``--string``, ``--mud-density``, ``--wob``,
  ``--bit-torque``, ``--depth``, ``--joint-length`` (9.14 m), ``--joints FILE.csv`` (solve). With ``--string``
  the command solves the string with its bit at ``--depth`` in the well file given as ``--conduit`` (a ``[well]``
  file, ``examples/well_s3d.toml``): call :func:`run_drilling_solve` with the parsed values; it prints
  ``name value`` lines (``hook_load``, ``surface_torque``, ..., the side force per length and per joint).
* :func:`run_drilling_trace`: ``trace --param depth --range A B --string S.toml --conduit WELL.toml``, the trip
  in bit depth (call it with the parsed values, the range, ``--out`` and ``--overwrite``).
* :func:`broomstick_command`: ``rodcont broomstick WELL.toml --string S.toml --friction 0.15 0.25 0.35
  --depth A B -o broom.png --out B.h5``.
* :func:`register`: adds the commands to the CLI's group (``register(main_group)``).

User errors are ``click.UsageError`` (the CLI's ``main`` prints one line ``rodcont: error: ...``, exit 2).
"""

from __future__ import annotations

import os
import sys

import click

# rodcont.loads.OPERATIONS' names (not imported: it loads numpy, and rodcont --version does not)
OPERATIONS = ("pick-up", "slack-off", "rotate", "drill", "static")
DRILLING_KEYS = ("operation", "trip_speed", "rpm", "friction", "string", "mud_density", "wob", "bit_torque", "depth",
                 "joint_length", "joints")
JOINT_LENGTH = 9.14  # rodcont.drilling.JOINT_LENGTH (not imported: it loads numpy)


def drilling_options(f):
    """The drill-string options of ``solve`` / ``trace`` (values under :data:`DRILLING_KEYS`)."""
    opts = [
        click.option("--operation", type=click.Choice(list(OPERATIONS)), default=None,
                     help="rig operation: pick-up (tripping out), slack-off (tripping in), rotate (off bottom), "
                          "drill (on bottom, with --wob and --bit-torque), static"),
        click.option("--trip-speed", type=float, default=None, help="axial speed V, m/s (> 0 out of the hole)"),
        click.option("--rpm", type=float, default=None, help="rotation rate, rev/min (with --trip-speed: combined)"),
        click.option("--friction", type=float, default=None, help="friction factor mu (default: the well file's)"),
        click.option("--string", "string", type=click.Path(dir_okay=False), default=None,
                     help="drill string file (TOML: sections from the bit up)"),
        click.option("--mud-density", type=float, default=None, help="mud density, kg/m^3 (buoyancy)"),
        click.option("--wob", type=float, default=0.0, show_default=True, help="weight on bit, N (drill)"),
        click.option("--bit-torque", type=float, default=0.0, show_default=True, help="bit torque, N m (drill)"),
        click.option("--depth", type=float, default=None, help="bit measured depth, m (default: the survey's end)"),
        click.option("--joint-length", type=float, default=JOINT_LENGTH, show_default=True,
                     help="length of a joint of pipe, m (the side force per joint; joints counted from the bit up)"),
        click.option("--joints", type=click.Path(dir_okay=False), default=None,
                     help="write the side force of every joint to FILE.csv (solve)"),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def _load(well_path: str, string_path: str, mud_density):
    from ..drilling import DrillingError, DrillString, Well
    try:
        return Well.from_toml(well_path), DrillString.from_toml(string_path, mud_density)
    except DrillingError as exc:
        raise click.UsageError(str(exc)) from None


def _inputs(well_path: str, string_path: str, well) -> tuple:
    """The files a drilling command reads: the well file, the survey it names, the string file."""
    return tuple(p for p in (well_path, well.survey, string_path) if p)


def _check_depths(well, *depths) -> None:
    """Each bit depth inside the survey and deeper than the hole is wide (:meth:`rodcont.drilling.Well.check_depth`),
    or the usage error before any output is touched."""
    from ..drilling import DrillingError
    for depth in depths:
        try:
            well.check_depth(depth)
        except DrillingError as exc:
            raise click.UsageError(str(exc)) from None


def _check(name: str, v, positive=False, nonnegative=False):
    import math
    if v is None:
        return None
    if not math.isfinite(v) or (positive and not v > 0) or (nonnegative and not v >= 0):
        raise click.UsageError(f"--{name} must be a {'positive' if positive else 'non-negative'} finite number, "
                               f"got {v!r}")
    return v


def run_drilling_solve(conduit: str | None, values: dict, echo=click.echo, overwrite: bool = False,
                       out: str | None = None):
    """Solve the string of ``values["string"]`` in the well file ``conduit`` (``solve --conduit WELL.toml
    --string S.toml ...``) and print ``name value`` lines: ``depth``, ``operation``, ``friction``,
    ``hook_load`` (N), ``surface_torque`` (N m), ``side_force`` (N), ``contact_zones``, ``error``, ``N``, the largest
    side force per length and per joint with their MD (``--joint-length``, :func:`rodcont.drilling.joint_side_forces`);
    ``values["joints"]``: the joints' table as CSV (:func:`joints_csv`); ``out``: the equilibrium as a one-point
    file in a trip's layout (:func:`rodcont.drivers.trip.write_point`, read by ``rodcont export``). Returns the
    :class:`rodcont.drilling.TorqueDrag`."""
    from ..drilling import DrillingError, torque_and_drag
    from ..drivers.solve import ConvergenceError
    from ..loads import motion_name
    if conduit is None:
        raise click.UsageError("--string needs the well: --conduit WELL.toml (a [well] file)")
    well, string = _load(conduit, values["string"], _check("mud-density", values.get("mud_density"), nonnegative=True))
    op = values.get("operation") or motion_name(values.get("trip_speed"), values.get("rpm"),
                                                 bool(values.get("wob") or values.get("bit_torque")))
    depth = _check("depth", values.get("depth"), positive=True) or well.total_depth
    _check_depths(well, depth)
    joint_length = _joint_length(values, depth)
    from ..branchfile import BranchFileError, check_output
    for path, what in ((values.get("joints"), "--joints"), (out, "--out")):
        if path is None:
            continue
        try:
            check_output(path, _inputs(conduit, values["string"], well), overwrite=overwrite, what=what)
        except (BranchFileError, ValueError, OSError) as exc:
            raise click.UsageError(str(exc)) from None
    if out is not None and values.get("joints") is not None and os.path.realpath(out) == os.path.realpath(
            values["joints"]):
        raise click.UsageError(f"--out and --joints name the same file {out}: give two names")
    try:
        r = torque_and_drag(well, string, depth, op, mu=_check("friction", values.get("friction"), nonnegative=True),
                            wob=_check("wob", values.get("wob") or 0.0, nonnegative=True),
                            bit_torque=values.get("bit_torque") or 0.0,
                            trip_speed=values.get("trip_speed"), rpm=values.get("rpm"),
                            **{key: values[key] for key in ("max_error", "N_max", "N", "k")
                               if values.get(key) is not None})
    except (DrillingError, ValueError) as exc:
        raise click.UsageError(str(exc)) from None
    except ConvergenceError as exc:
        raise click.ClickException(str(exc)) from None
    for name, v in (("depth", r.depth), ("operation", r.operation.name), ("friction", r.mu),
                    ("hook_load", r.hook_load), ("surface_torque", r.surface_torque), ("side_force", r.side_force),
                    ("contact_zones", len(r.zones)), ("error", r.error), ("N", r.N)):
        echo(f"{name} {v!r}" if isinstance(v, float) else f"{name} {v}")
    from ..drilling import law_error
    for name, v in law_error(r).items():  # the smoothing's, which the mesh's error does not see (1e-3 rotating)
        echo(f"{name}_law_error {abs(v)!r}")
    table = _echo_joints(r, joint_length, echo)
    _write_outputs(r, well, string, out, values.get("joints"), table, joint_length, overwrite,
                   dict(well=os.path.abspath(conduit), string=os.path.abspath(values["string"])), echo)
    return r


def _write_outputs(r, well, string, out, joints, table, joint_length, overwrite, meta, echo) -> None:
    """``--out`` and ``--joints`` published together: the joints' table staged, the point's file written, then the
    table renamed over its name; a Ctrl-C before that leaves neither (it had left the table alone)."""
    from ..safeio import Staged
    with Staged() as stage:
        if joints is not None:
            stage.add(joints, joints_csv(table))
        if out is not None:
            from ..drivers.trip import write_point
            write_point(well, string, r, out, overwrite=overwrite, joint_length=joint_length, meta=meta)
        stage.commit()
    for path in (out, joints):
        if path is not None:
            click.echo(f"wrote {path}", err=True)
    if joints is not None:
        echo(f"joints {joints}")


def _joint_length(values: dict, depth: float) -> float:
    """``--joint-length`` (default 9.14 m), refused in one line before any solve where it makes too many joints
    over ``depth`` (a table of millions ran out of memory after the solve)."""
    from ..drilling import DrillingError, check_joints
    v = values.get("joint_length")
    length = JOINT_LENGTH if v is None else _check("joint-length", v, positive=True)
    try:
        check_joints(depth, length)
    except DrillingError as exc:
        raise click.UsageError(str(exc)) from None
    return length


def _echo_joints(r, joint_length: float, echo) -> dict:
    """The largest side force per unit length and per joint, with their MD (the joint's top and bottom); returns
    the table of every joint (:func:`rodcont.drilling.joint_side_forces`)."""
    import numpy as np

    from ..drilling import joint_side_forces
    j = joint_side_forces(r, joint_length)
    i = int(np.argmax(j["max_pressure"]))  # the largest p of the table's rows (and of the profile)
    echo(f"max_side_force_per_length {float(j['max_pressure'][i])!r}")
    echo(f"max_side_force_per_length_md {float(j['max_pressure_md'][i])!r}")
    k = int(np.argmax(j["side_force"]))
    echo(f"joint_length {joint_length!r}")
    echo(f"max_joint_side_force {float(j['side_force'][k])!r}")
    echo(f"max_joint_side_force_md {float(j['top'][k])!r} {float(j['bottom'][k])!r}")
    return j


def joints_csv(j: dict) -> str:
    """The joints' table as CSV text, from the bit up: ``joint`` (1 at the bit), ``md_top``, ``md_bottom`` (m),
    ``side_force`` (N), ``max_side_force_per_length`` (N/m)."""
    rows = ["joint,md_top,md_bottom,side_force,max_side_force_per_length"]
    n = j["top"].size
    for i in range(n - 1, -1, -1):
        rows.append(",".join([str(n - i)] + [repr(float(j[key][i])) for key in ("top", "bottom", "side_force",
                                                                                  "max_pressure")]))
    return "\n".join(rows) + "\n"


def run_drilling_trace(conduit: str | None, values: dict, param: str, p_range, out: str | None,
                       overwrite: bool = False, points: int = 11, echo=click.echo, quiet: bool = False):
    """``trace --param depth --range A B --string S.toml --conduit WELL.toml [--operation OP] [--out F.h5]``: the
    trip in bit depth (:func:`rodcont.drivers.trip.trip`, ``points`` depths; slack-off from A down to B,
    pick-up from B up) and ``name value`` lines: ``points``, ``status``, ``hook_load`` and ``surface_torque`` at
    the trip's last point, ``lock_up`` (m) when it locks up (:func:`tripped`: progress on stderr, Ctrl-C between
    depths, ``quiet``). Returns the :class:`rodcont.branch.Branch`."""
    from ..drivers.trip import trip
    from ..loads import motion_name
    if param != "depth":
        raise click.UsageError(f"--string traces in --param depth (a trip), got --param {param}")
    if conduit is None:
        raise click.UsageError("--string needs the well: --conduit WELL.toml (a [well] file)")
    if p_range is None or len(p_range) != 2:
        raise click.UsageError("--param depth needs --range A B (bit depths, m)")
    well, string = _load(conduit, values["string"], _check("mud-density", values.get("mud_density"), nonnegative=True))
    a, b = (float(v) for v in p_range)
    if not (0 < a < b) or b > well.total_depth * (1 + 1e-12):
        raise click.UsageError(f"--range A B needs 0 < A < B <= {well.total_depth:g} (the survey), got {a:g} {b:g}")
    _check_depths(well, a)
    if out is not None:
        from ..branchfile import BranchFileError, check_output
        try:
            check_output(out, _inputs(conduit, values["string"], well), overwrite=overwrite)
        except (BranchFileError, ValueError, OSError) as exc:
            raise click.UsageError(str(exc)) from None
    op = values.get("operation") or (motion_name(values.get("trip_speed"), None) if values.get("trip_speed")
                                     else "slack-off")
    joint_length = _joint_length(values, b)
    mu = _check("friction", values.get("friction"), nonnegative=True)
    wob = _check("wob", values.get("wob") or 0.0, nonnegative=True)

    def run(callback):
        return trip(well, string, (a, b), op, points=points, out=out, overwrite=overwrite, mu=mu,
                    trip_speed=values.get("trip_speed"), rpm=values.get("rpm"), wob=wob,
                    bit_torque=values.get("bit_torque") or 0.0, joint_length=joint_length, callback=callback)
    return tripped(run, out, points, quiet, echo)


def tripped(run, out, points: int, quiet: bool, echo=click.echo, done: int = 0):
    """``run(callback)``, a trip, with a progress line on stderr a few seconds apart and Ctrl-C or SIGTERM taken
    between two depths (what ``out`` holds is said, exit 130 / 143); then its ``name value`` lines. ``done``: the
    depths a resumed trip's file holds (the progress counts on from them). Returns the
    :class:`rodcont.branch.Branch`."""
    from ..drilling import DrillingError
    from ..drivers.solve import ConvergenceError
    from .common import file_identity
    from .progress import Interrupts
    before = file_identity(out) if out is not None else None
    with Interrupts() as intr:
        progress = _TripProgress(quiet, intr, points, done)
        try:
            br = run(progress)
        except KeyboardInterrupt:
            br = None
        except (DrillingError, ValueError) as exc:
            raise click.UsageError(str(exc)) from None
        except ConvergenceError as exc:
            raise click.ClickException(str(exc)) from None
    if br is None:
        _say_interrupted(out, before)
        sys.exit(intr.exit_code)
    echo(f"points {len(br)}")
    echo(f"status {br.status}")
    echo(f"hook_load {float(br.table['hook_load'][-1])!r}")
    echo(f"surface_torque {float(br.table['surface_torque'][-1])!r}")
    if br.table["kind"][-1] == "event:lock_up":
        echo(f"lock_up {float(br.table['depth'][-1])!r}")
    return br


@click.command("broomstick")
@click.argument("well", type=click.Path(dir_okay=False), required=False)
@click.argument("more_friction", nargs=-1, type=float, metavar="")
@click.option("--string", "string", type=click.Path(dir_okay=False), default=None, help="drill string file (TOML)")
@click.option("--friction", type=float, multiple=True,
              help="friction factors, one curve each (--friction 0.15 --friction 0.25, or --friction 0.15 0.25 0.35)")
@click.option("--depth", nargs=2, type=float, default=None, help="bit depths from A to B, m")
@click.option("--points", type=int, default=11, show_default=True, help="depths between A and B")
@click.option("--mud-density", type=float, default=None, help="mud density, kg/m^3 (default: the string file's)")
@click.option("-o", "--output", "png", type=click.Path(dir_okay=False), default="broom.png", show_default=True)
@click.option("--out", "h5", type=click.Path(dir_okay=False), default=None,
              help="HDF5 file of every point, written again as each is solved")
@click.option("--resume", "resume_file", type=click.Path(dir_okay=False), default=None,
              help="finish an interrupted broomstick's --out file in place (its own well, string and cases)")
@click.option("--jobs", type=int, default=None, help="parallel jobs (default: the cores)")
@click.option("--overwrite", is_flag=True, help="replace existing outputs")
@click.option("--quiet", is_flag=True, help="no progress display")
def broomstick_command(well, more_friction, string, friction, depth, points, mud_density, png, h5, resume_file, jobs,
                       overwrite, quiet):
    """Hook load against bit depth for pick-up, slack-off and rotating off bottom, one curve per friction
    factor, the soft-string estimate beside each, and the surface torque against depth. With --out, the file
    holds every equilibrium solved so far; --resume B.h5 finishes an interrupted one."""
    if jobs is not None and jobs < 0:
        raise click.UsageError(f"--jobs must be 0 (the cores) or more, got {jobs}")
    if resume_file is not None:
        h5, run = _resumed_broom(resume_file, well, more_friction, string, friction, depth, mud_density, png, h5,
                                 overwrite, jobs)
    else:
        h5, run = _new_broom(well, more_friction, string, friction, depth, points, mud_density, png, h5, overwrite,
                             jobs)
    br = _run_broom(run, h5, quiet)
    for op, mu, d, why in br.failures:
        click.echo(f"rodcont: warning: {op}, mu {mu:g}, depth {d:g}: {why}", err=True)
    _write_plot(br, png)
    i = -1  # the deepest point of each curve, as name value lines
    for k, op in enumerate(br.operations):
        for j, mu in enumerate(br.mus):
            click.echo(f"hook_load {op} {mu:g} {float(br.hook_load[i, k, j])!r}")
    for j, mu in enumerate(br.mus if "rotate" in br.operations else ()):
        click.echo(f"surface_torque rotate {mu:g} {float(br.surface_torque[i, br.operations.index('rotate'), j])!r}")
    click.echo(f"plot {png}")
    if h5 is not None:
        click.echo(f"wrote {h5}", err=True)  # as solve and trace say their file


def _new_broom(well, more_friction, string, friction, depth, points, mud_density, png, h5, overwrite, jobs):
    """``(out, run)`` of a new broomstick, every input and output checked first (one line each)."""
    import numpy as np

    from ..drivers.broomstick import broomstick
    missing = [name for name, v in (("WELL.toml", well), ("--string", string), ("--friction", friction),
                                    ("--depth", depth)) if not v]
    if missing:
        raise click.UsageError(f"broomstick needs {', '.join(missing)} (or --resume B.h5 to finish one)")
    # click's options take one value each: the further numbers of --friction 0.15 0.25 0.35 arrive as arguments
    friction = [_check("friction", f, nonnegative=True) for f in tuple(friction) + tuple(more_friction)]
    if len(set(friction)) < len(friction):
        raise click.UsageError(f"--friction {next(f for f in friction if friction.count(f) > 1):g} is given twice: "
                               f"give each factor once")
    a, b = depth
    if not (a > 0 and b > a) or points < 2:
        raise click.UsageError(f"--depth A B needs 0 < A < B and --points at least 2, got {a:g} {b:g}, {points}")
    w, s = _load(well, string, _check("mud-density", mud_density, nonnegative=True))
    if b > w.total_depth * (1 + 1e-12):
        raise click.UsageError(f"--depth {b:g} lies beyond the survey's end ({w.total_depth:g} m)")
    _check_depths(w, a)
    _check_broom_outputs(png, h5, _inputs(well, string, w), overwrite)
    meta = dict(well=os.path.abspath(well), string=os.path.abspath(string))

    def run(callback):
        return broomstick(w, s, np.linspace(a, b, points), friction, jobs=jobs, callback=callback, out=h5, meta=meta)
    return h5, run


def _resumed_broom(path, well, more_friction, string, friction, depth, mud_density, png, h5, overwrite, jobs):
    """``(out, run)`` that finishes the broomstick file ``path`` in place: its own well, string, friction factors
    and depths (each given again is refused), the plot checked as a new one's is."""
    from ..branchfile import same_file
    from ..drivers.broomstick import broomstick_inputs, read_broomstick, resume_broomstick
    from .common import explicit
    given = [name for name, v in (("--friction", friction), ("WELL.toml", well), ("--string", string),
                                  ("--friction", more_friction), ("--depth", depth), ("--mud-density", mud_density))
             if v not in (None, ())]  # --mud-density 0 is given too
    given += ["--points"] if explicit("points") else []
    if given:
        raise click.UsageError(f"--resume finishes {path} with its own well, string, friction factors and depths: "
                               f"drop {given[0]}")
    if h5 is not None and not same_file(h5, path):
        raise click.UsageError(f"--resume finishes {path} in place: drop --out {h5} (or resume a copy)")
    if not os.path.isfile(path):
        raise click.UsageError(f"--resume {path}: no such file")
    try:
        b0 = read_broomstick(path)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    # -o onto the file, or onto the well's survey: 'is the input file'
    _check_broom_outputs(png, None, broomstick_inputs(b0) + (path,), overwrite)

    def run(callback):
        return resume_broomstick(path, jobs=jobs, callback=callback)
    return path, run


class _BroomProgress:
    """The broomstick's callback: a line on stderr a few seconds apart (rewritten in place on a terminal), and
    an interrupt taken between two equilibria or while the workers solve (``idle``)."""

    def __init__(self, quiet: bool, interrupts):
        import time
        self.quiet, self.interrupts, self.tty = quiet, interrupts, sys.stderr.isatty()
        self.t0, self.last, self.clock = time.perf_counter(), 0.0, time.perf_counter

    def __call__(self, b, cell) -> None:
        op, mu, k = cell
        now = self.clock()
        if not self.quiet and (self.tty or now - self.last > 5.0):
            at = b.cell(op, mu, k)
            msg = (f"equilibrium {int(b.complete.sum()):4d} of {b.complete.size}  {op} mu {mu:g} depth "
                   f"{b.depths[k]:g} m  hook_load {b.hook_load[at] / 1e3:.1f} kN  {now - self.t0:6.1f} s")
            click.echo(("\r" + msg) if self.tty else msg, nl=not self.tty, err=True)
            self.last = now
        self.idle()

    def idle(self) -> None:
        self.interrupts.check()

    def done(self) -> None:
        if self.tty and not self.quiet:
            click.echo("", err=True)


def _run_broom(run, out, quiet):
    """``run(callback)`` with progress and Ctrl-C or SIGTERM between equilibria: on an interrupt, what ``out``
    holds is said and the command exits 130 (143)."""
    from ..drivers.broomstick import read_broomstick
    from .common import file_identity
    from .progress import Interrupts
    before = file_identity(out) if out is not None else None
    with Interrupts() as intr:
        progress = _BroomProgress(quiet, intr)
        try:
            return run(progress)
        except KeyboardInterrupt:
            pass
        except ValueError as exc:
            raise click.UsageError(str(exc)) from None
        finally:
            progress.done()
    if out is None:
        click.echo("interrupted: nothing kept (--out B.h5 keeps each equilibrium as it is solved)", err=True)
    elif file_identity(out) == before:
        click.echo(f"interrupted before the first equilibrium: {out} is as it was", err=True)
    else:
        b = read_broomstick(out)
        click.echo(f"interrupted: {out} holds {int(b.complete.sum())} of the {b.complete.size} equilibria; finish "
                   f"it with rodcont broomstick --resume {out}", err=True)
    sys.exit(intr.exit_code)


def _say_interrupted(out, before) -> None:
    """An interrupted trip's line: how many depths its file holds and how to go on (as an interrupted trace says),
    or that it published none."""
    from .common import file_identity
    if out is None:
        click.echo("interrupted: nothing kept (--out F.h5 keeps each depth as it is solved)", err=True)
        return
    if file_identity(out) == before:
        click.echo(f"interrupted before the first depth: {out} is as it was", err=True)
        return
    from ..branchfile import load_branch
    click.echo(f"interrupted: {out} holds the {trip_depths_done(load_branch(out))} completed depth(s) of the trip; "
               f"go on with rodcont trace --resume {out}", err=True)


def trip_depths_done(branch) -> int:
    """The depths of the march a trip's branch holds (its rows but the events found between them)."""
    return sum(not str(kind).startswith("event:") for kind in branch.table["kind"])


class _TripProgress:
    """A trip's callback: ``depth K of N  D m  hook_load H kN  T s`` on stderr a few seconds apart (every depth on
    a terminal), an event's line as it is found, and an interrupt taken after each recorded point."""

    def __init__(self, quiet: bool, interrupts, points: int, done: int = 0):
        import time
        self.quiet, self.interrupts, self.points, self.tty = quiet, interrupts, points, sys.stderr.isatty()
        self.clock, self.t0, self.last, self.n = time.perf_counter, time.perf_counter(), 0.0, done

    def __call__(self, r, row) -> None:
        kind = str(row["kind"])
        self.n += not kind.startswith("event:")
        now = self.clock()
        if not self.quiet and (self.tty or kind.startswith("event:") or now - self.last > 5.0):
            what = kind[6:].replace("_", " ") + " at" if kind.startswith("event:") else \
                f"depth {self.n} of {self.points}"
            click.echo(f"{what} {r.depth:g} m  hook_load {r.hook_load / 1e3:.1f} kN  {now - self.t0:6.1f} s",
                       err=True)
            self.last = now
        self.interrupts.check()


def _check_broom_outputs(png, h5, inputs, overwrite) -> None:
    """The plot and the points' file checked before any solve, as ``solve`` checks its outputs: writable, not an
    input, not there unless ``overwrite``, and not one file for both (the second write replaced the first)."""
    from ..branchfile import BranchFileError, check_output, same_file
    for path, what in ((png, "-o"), (h5, "--out")):
        if path is None:
            continue
        try:
            check_output(path, inputs, overwrite=overwrite, what=what)
        except (BranchFileError, ValueError, OSError) as exc:
            raise click.UsageError(str(exc) + (_unfinished_hint(path) if what == "--out" else "")) from None
    if h5 is not None and same_file(png, h5):  # links too
        raise click.UsageError(f"-o and --out name the same file {h5}: give two names")


def _unfinished_hint(path: str) -> str:
    """`` (an interrupted broomstick: ...)`` where ``path`` is one, so that an --out refused as existing says how
    to finish it; empty otherwise."""
    from ..drivers.broomstick import read_broomstick
    try:
        b = read_broomstick(path) if os.path.isfile(path) else None
    except ValueError:
        return ""
    if b is None or b.complete.all():
        return ""
    return (f" ({path} is an interrupted broomstick, {int(b.complete.sum())} of {b.complete.size} equilibria: "
            f"finish it with rodcont broomstick --resume {path})")


def _write_plot(br, png) -> None:
    """The broomstick's plot, written beside ``png`` and renamed over it (:func:`rodcont.safeio.publish`); the
    points' file is already whole (published after each equilibrium)."""
    from ..drivers.broomstick import broomstick_picture
    from ..safeio import publish
    publish(png, broomstick_picture(br, png)[0])


def register(group) -> None:
    """Add the torque-and-drag commands to the CLI's click group."""
    group.add_command(broomstick_command)
