"""The ``rodcont`` command line: solve, trace, critical, diagram, folds, plot, shape, fold-curve, sweep.

Every error a user can cause (bad numbers, missing, foreign or damaged files,
an output that exists or is an input, no convergence) ends in one line on
stderr and exit status 2; no traceback (``--debug`` shows one), no half-written
output file, no input changed. Ctrl-C and SIGTERM end a trace between two
points with every point on disk (exit 130 / 143). Only what a command needs is
imported: ``rodcont --version`` costs no numpy.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time

import click

EXIT_USAGE = 2


class UserError(click.ClickException):
    exit_code = EXIT_USAGE


# --------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------
def _number(name, positive=False, nonnegative=False):
    def check(ctx, param, value):
        if value is None:
            return value
        values = value if isinstance(value, tuple) else (value,)
        for v in values:
            if not math.isfinite(v):
                raise click.BadParameter(f"must be a finite number, got {v}", param_hint=name)
            if positive and not v > 0:
                raise click.BadParameter(f"must be a positive number, got {v:g}", param_hint=name)
            if nonnegative and not v >= 0:
                raise click.BadParameter(f"must be a non-negative number, got {v:g}", param_hint=name)
        return value
    return check


ROD_OPTION_NAMES = ("N", "k", "w", "EI", "GJ", "EA", "L")

# --config FILE.toml: sections and the options their keys set (any trace option goes in [trace])
CONFIG_SECTIONS = {"rod": ("EI", "GJ", "EA", "w", "L", "weight_direction", "reference"), "loads": ("gamma", "T", "phi", "torque", "l0"),
                   "mesh": ("N", "k", "N_max", "uniform")}


def _load_config(ctx, param, value):
    """Read a TOML problem file into the command's defaults (options on the command line still win)."""
    if value is None:
        return None
    import tomllib
    from .safeio import InputFileError, read_input
    try:  # a regular file of a problem file's size: never a device, a FIFO or a huge file
        text = read_input(value, "toml", what="problem file")
    except InputFileError as exc:
        raise click.BadParameter(str(exc), param_hint="--config") from None
    try:
        doc = tomllib.loads(text.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        raise click.BadParameter(f"{value} is not valid TOML ({' '.join(str(exc).split())[:120]})",
                                 param_hint="--config") from None
    params = {p.name: p for p in ctx.command.params}
    names = set(params)
    defaults = {}
    for section, table in doc.items():
        if not isinstance(table, dict):
            raise click.BadParameter(f"{value}: '{section}' must be a section ([{section}])", param_hint="--config")
        allowed = CONFIG_SECTIONS.get(section)
        if allowed is None and section != "trace":
            raise click.BadParameter(f"{value}: unknown section [{section}] (sections: rod, loads, mesh, trace)",
                                     param_hint="--config")
        for key, v in table.items():
            name = key.replace("-", "_")
            if (allowed is not None and name not in allowed) or name not in names:
                raise click.BadParameter(f"{value}: [{section}] {key} is not an option of this command",
                                         param_hint="--config")
            if name == "weight_direction" and isinstance(v, list):
                if len(v) != 3 or not all(isinstance(u, (int, float)) and not isinstance(u, bool) for u in v):
                    raise click.BadParameter(f"{value}: [{section}] {key} must be three numbers",
                                             param_hint="--config")
                v = ",".join(str(u) for u in v)
            _check_config_value(value, section, key, v, params[name])
            defaults[name] = v
    ctx.default_map = dict(ctx.default_map or {}, **defaults)
    ctx.meta["rodcont.config_file"] = value
    return value


def _check_config_value(path, section, key, v, param):
    """A config value of the option's kind: numbers for numbers (integers for counts), strings for
    text, true/false for switches, lists for repeatable options; no dates, tables or booleans as numbers."""
    def bad(what):
        raise click.BadParameter(f"{path}: [{section}] {key} must be {what}, got {v!r}", param_hint="--config")

    def number(u, integer=False):
        if isinstance(u, bool) or not isinstance(u, (int, float)):
            return False
        return not integer or isinstance(u, int)

    if getattr(param, "is_flag", False):
        if not isinstance(v, bool):
            bad("true or false")
        return
    t = param.type
    integer = isinstance(t, click.types.IntParamType)
    numeric = integer or isinstance(t, click.types.FloatParamType)
    if getattr(param, "multiple", False) or (param.nargs or 1) != 1:
        if not isinstance(v, list) or not all(number(u, integer) if numeric else isinstance(u, str) for u in v):
            bad("a list of " + ("integers" if integer else "numbers" if numeric else "strings"))
        return
    if numeric and not number(v, integer):
        bad("an integer" if integer else "a number")
    if not numeric and not isinstance(v, str):
        bad("a string")


def _weight_direction(ctx, param, value):
    if value is None:
        return (0.0, 0.0, -1.0)
    try:
        v = tuple(float(u) for u in str(value).replace(" ", "").split(","))
    except ValueError:
        raise click.BadParameter(f"expects X,Y,Z (three numbers), got {value!r}", param_hint="--weight-direction") \
            from None
    if len(v) != 3 or not all(math.isfinite(u) for u in v) or not any(v):
        raise click.BadParameter(f"expects a non-zero direction X,Y,Z, got {value!r}",
                                 param_hint="--weight-direction")
    return v


def rod_options(f):
    """Rod, load and mesh options shared by every command that builds a rod (paper values by default).

    ``--T`` (the tension itself), ``--weight-direction`` and ``--config`` are
    taken here and kept on the click context for :func:`_rod` and :func:`_tension`.
    """
    import functools

    @functools.wraps(f)
    def wrapper(*args, T=None, weight_direction=(0.0, 0.0, -1.0), config=None, reference="straight", **kwargs):
        ctx = click.get_current_context()
        ctx.meta["rodcont.T"] = T
        ctx.meta["rodcont.weight_direction"] = weight_direction
        ctx.meta["rodcont.reference"] = reference
        _echo_config(ctx)
        return f(*args, **kwargs)

    opts = [
        click.option("--config", type=click.Path(dir_okay=False), default=None, is_eager=True,
                     callback=_load_config, expose_value=True,
                     help="TOML file holding the problem ([rod], [loads], [mesh], [trace]); options override it"),
        click.option("--T", "T", type=float, default=None, callback=_number("--T"),
                     help="the tension itself (instead of --gamma; also with --w 0)"),
        click.option("--N", "N", type=click.IntRange(1, 20000), default=15, show_default=True,
                     help="number of subintervals of the (first) mesh"),
        click.option("--k", "k", type=click.IntRange(1, 7), default=5, show_default=True,
                     help="Gauss collocation points per subinterval"),
        click.option("--w", "w", type=float, default=10.0, show_default=True, callback=_number("--w", nonnegative=True),
                     help="weight per unit unstressed length (>= 0)"),
        click.option("--weight-direction", default=None, callback=_weight_direction,
                     help="direction of the weight X,Y,Z [default: 0,0,-1]; the span runs along e1"),
        click.option("--reference", default="straight", show_default=True,
                     help="reference curve KIND[:ARGS]: straight, bump:H,THETA, wiggle:H2,H3, arc:ANGLE[,THETA], "
                          "helix:RADIUS,TURNS, well:FILE (the rod is described as a perturbation of it)"),
        click.option("--EI", "EI", type=float, default=1.0, show_default=True, callback=_number("--EI", positive=True),
                     help="bending stiffness"),
        click.option("--GJ", "GJ", type=float, default=0.75, show_default=True, callback=_number("--GJ", positive=True),
                     help="torsional stiffness"),
        click.option("--EA", "EA", type=float, default=255.0, show_default=True, callback=_number("--EA", positive=True),
                     help="axial stiffness"),
        click.option("--L", "L", type=float, default=1.0, show_default=True, callback=_number("--L", positive=True),
                     help="span (length of the straight reference curve)"),
    ]
    for opt in reversed(opts):
        wrapper = opt(wrapper)
    return wrapper


_CONFIG_SKIP = {"config", "quiet", "out", "out_dir", "overwrite", "start", "output", "points", "files", "file",
                "spec", "debug", "max_defect", "resume_file", "extend"}


def config_toml(params: dict) -> str:
    """The effective problem as a TOML document (what ``--config`` reads back)."""
    rows = {"rod": [], "loads": [], "mesh": [], "trace": []}
    for name, v in params.items():
        if name in _CONFIG_SKIP or v is None or v == ():
            continue
        section = next((s for s, keys in CONFIG_SECTIONS.items() if name in keys), "trace")
        if isinstance(v, tuple):
            v = list(v)
        if isinstance(v, bool):
            text = "true" if v else "false"
        elif isinstance(v, str):
            text = '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        elif isinstance(v, list):
            text = "[" + ", ".join(repr(float(u)) if isinstance(u, float) else str(u) for u in v) + "]"
        else:
            text = repr(v)
        rows[section].append(f"{name} = {text}")
    out = []
    for section, lines in rows.items():
        if lines:
            out.append(f"[{section}]")
            out.extend(lines)
    return "\n".join(out)


def _echo_config(ctx) -> None:
    """Every command says, first, the problem it runs (as TOML comment lines on stdout)."""
    params = dict(ctx.params)
    params["T"] = ctx.meta.get("rodcont.T")
    params["weight_direction"] = ctx.meta.get("rodcont.weight_direction")
    params["reference"] = ctx.meta.get("rodcont.reference", "straight")
    start = params.get("start") or params.get("resume_file")
    if start is not None:
        # a restart's rod, loads, reference curve, conduit and mesh are the start file's, not the defaults;
        # only an explicit --N is its own (a --k other than the file's is refused, so it is not echoed); so
        # are the trace options not given (rodcont.restart.carried_options)
        for name in CONFIG_SECTIONS["rod"] + CONFIG_SECTIONS["loads"] + ("N", "k"):
            if name != "phi" and name not in _explicit("N"):
                params.pop(name, None)
        for sources in _OPTION_SOURCES.values():
            for name in sources:
                if not _explicit(name):
                    params.pop(name, None)
    text = config_toml(params)
    ctx.meta["rodcont.config"] = text
    src = ctx.meta.get("rodcont.config_file")
    click.echo(f"# rodcont {ctx.info_name}" + (f" (--config {src})" if src else "") + ": the problem as run")
    if start is not None:
        how = "--start" if params.get("start") else "--resume"
        click.echo(f"#   (the rod, its loads, reference curve, conduit, mesh and the trace options not given "
                   f"are those of {how} {start})")
    for line in text.splitlines():
        click.echo(f"#   {line}")



def trace_options(f):
    """Options of every traced branch (trace, diagram, sweep)."""
    opts = [
        click.option("--phi-max", type=float, default=40.0, show_default=True, callback=_number("--phi-max")),
        click.option("--phi-min", type=float, default=-1.0, show_default=True, callback=_number("--phi-min")),
        click.option("--stretch-max", type=float, default=None, callback=_number("--stretch-max"),
                     help="stop when the stretch reaches this value"),
        click.option("--max-steps", type=click.IntRange(1, 10**7), default=2000, show_default=True),
        click.option("--ds", type=float, default=0.1, show_default=True, callback=_number("--ds", positive=True),
                     help="first pseudo-arclength step"),
        click.option("--ds-max", type=float, default=0.5, show_default=True,
                     callback=_number("--ds-max", positive=True)),
        click.option("--ds-min", type=float, default=1e-6, show_default=True,
                     callback=_number("--ds-min", positive=True),
                     help="the trace stops when the step must shrink below this"),
        click.option("--min-alignment", type=float, default=0.05, show_default=True,
                     callback=_number("--min-alignment"),
                     help="validity guard: stop where min d3.K3 falls to this (in [0, 1))"),
        click.option("--max-error", type=float, default=1e-6, show_default=True,
                     callback=_number("--max-error", positive=True),
                     help="accuracy guard: the estimated error of the outputs and centreline (relative)"),
        click.option("--max-defect", type=float, default=None, callback=_number("--max-defect", positive=True),
                     hidden=True, help="old name of --max-error"),
        click.option("--fold-error", type=float, default=1e-9, show_default=True,
                     callback=_number("--fold-error", positive=True),
                     help="a fold with a larger estimated error is located again on a refined mesh"),
        click.option("--forced", type=float, multiple=True, callback=_number("--forced"),
                     help="a Phi value that gets a point of its own (repeatable)"),
        click.option("--uniform", is_flag=True, help="keep the first mesh (no adaptation)"),
        click.option("--N-max", "N_max", type=click.IntRange(1, 20000), default=400, show_default=True,
                     help="largest number of subintervals the adaptive mesh may use"),
        click.option("--store-every", type=click.IntRange(1, 10**6), default=1, show_default=True,
                     help="keep the solution of every M-th point (and of special points and the last), in the file and in memory: smaller files, less memory on long traces"),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def _trace_kwargs(phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
                  max_defect, fold_error, forced, uniform, N_max, store_every=1):
    ctx = click.get_current_context()
    if ds > ds_max and ctx.get_parameter_source("ds") == click.core.ParameterSource.DEFAULT:
        ds = ds_max  # only --ds-max was given: start at it
    if not ds_min <= ds <= ds_max:
        raise UserError(f"need --ds-min <= --ds <= --ds-max, got {ds_min:g}, {ds:g}, {ds_max:g}")
    if phi_min >= phi_max:
        raise UserError("--phi-min must be below --phi-max")
    if not 0 <= min_alignment < 1:
        raise UserError(f"--min-alignment must be in [0, 1), got {min_alignment:g}")
    if max_defect is not None:
        max_error = max_defect
    return dict(phi_max=phi_max, phi_min=phi_min, stretch_max=stretch_max, max_steps=max_steps, ds=ds,
                ds_max=ds_max, ds_min=ds_min, min_alignment=min_alignment, max_error=max_error,
                fold_error=fold_error, forced=tuple(forced), adapt=not uniform, N_max=N_max, store_every=store_every)


def _rod(w, EI, GJ, EA, L):
    from .rod import RodParameters
    wd = click.get_current_context().meta.get("rodcont.weight_direction", (0.0, 0.0, -1.0))
    try:
        return RodParameters(EI=EI, GJ=GJ, EA=EA, w=w, L=L, weight_direction=wd)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None


def _curve(rod, straight_only: str | None = None, source: str | None = None):
    """The --reference curve for ``rod`` (None for the straight span); ``straight_only`` names a
    command that needs the straight reference. ``source``: where the specification comes from when
    it is not ``--reference`` (a conduit file's ``reference`` key), the label of its errors."""
    spec = click.get_current_context().meta.get("rodcont.reference", "straight")
    label = source or f"--reference {spec}"
    if spec is None or not spec.strip():
        raise UserError(f"{source}: needs KIND[:ARGS] (straight, bump:H,THETA, ...)" if source else
                        "--reference needs KIND[:ARGS] (straight, bump:H,THETA, ...)")
    if spec.strip() == "straight":
        return None
    if straight_only:
        raise UserError(f"{straight_only} needs the straight reference (the straight rod state lives there); "
                        f"got {label}")
    from .curves import parse_reference
    try:
        with np_errstate():
            curve = parse_reference(spec, rod.L)
    except (ValueError, ArithmeticError) as exc:
        msg = str(exc)
        if source:  # parse_reference words its errors for --reference: say where the specification is
            kind = spec.strip().partition(":")[0].strip()
            for prefix in (f"--reference {spec}: ", f"--reference {kind}: ", "--reference: ", "--reference "):
                if msg.startswith(prefix):
                    msg = msg[len(prefix):]
                    break
            raise UserError(f"{source}: {msg}") from None
        raise UserError(f"--reference {spec}: {msg}" if not msg.startswith("--reference") else msg) from None
    if abs(curve.span - rod.L) > 1e-9 * rod.L:
        raise UserError(f"{label}: its span {curve.span:.15g} differs from --L {rod.L:.15g}; "
                        f"give --L {curve.span:.15g}")
    return curve


def _conduit(path, rod):
    """``(curve, wall)`` of a ``--conduit FILE`` (:func:`rodcont.contact.load_conduit`); ``(None, None)`` without
    one. Without a ``reference`` in the file the axis is ``--reference``."""
    if path is None:
        return _curve(rod), None
    from .contact import ConduitError, load_conduit
    ctx = click.get_current_context()
    given = ctx.meta.get("rodcont.reference", "straight")
    try:
        curve, wall = load_conduit(path, rod.L, reference=given)
    except ConduitError as exc:
        raise UserError(f"--conduit {exc}") from None
    # a file without an axis (or naming "straight", which then is --reference's too) leaves --reference's
    return (_curve(rod) if curve is None else curve), wall


def np_errstate():
    import numpy as np
    return np.errstate(all="ignore")


def _tension(gamma, rod):
    """``(gamma, T)``: exactly one of --gamma and --T; Gamma needs a weight."""
    T = click.get_current_context().meta.get("rodcont.T")
    if T is not None and gamma is not None:
        raise UserError("give --gamma or --T, not both")
    if T is None and gamma is None:
        raise UserError("--gamma (T = gamma w L) or --T is required")
    if T is None:
        if rod.w == 0:
            raise UserError("--gamma needs a weight (--w > 0): give the tension with --T")
        T = rod.tension(gamma)
        if not math.isfinite(T):
            raise UserError(f"--gamma {gamma:g} gives a tension that is not finite")
    return gamma, T


def _stretch_warning(rod, T) -> None:
    """Warn of a tension beyond half of EA: the model is right for any stretch, a real rod is not, and this
    is nearly always a forgotten --EA. Said once the command has ended: a command the library then refuses
    (T = 1e30 'is not a usable number') gives its one-line error alone (the fuzz's numeric probes)."""
    from .drivers.solve import euler_tension
    # (below the Euler load, or not finite, the tension is refused anyway)
    if math.isfinite(T) and abs(T) > 0.5 * rod.EA and T > euler_tension(rod):
        _warn_later(f"T = {T:g} stretches the rod by T/EA = {T / rod.EA:.3g} (EA = {rod.EA:g}"
                    f"{', the paper default' if rod.EA == 255.0 else ''}): give the rod's --EA if it is not meant")


def _meta():
    return {"config": click.get_current_context().meta.get("rodcont.config", "")}


# warnings printed once the command has ended (on an error its one line stands alone)
_PENDING: list = []


def _warn_later(message: str) -> None:
    if message not in _PENDING:
        _PENDING.append(message)


def _flush_pending() -> None:
    while _PENDING:
        _err(f"rodcont: warning: {_PENDING.pop(0)}")


def _read(loader, *args):
    """A branch or diagram file read by ``loader``; a file without rodcont's checksum is read and said so."""
    import warnings
    from .branchfile import BranchFileError, UnverifiedFileWarning
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", UnverifiedFileWarning)
            data = loader(*args)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    for w in said:
        if issubclass(w.category, UnverifiedFileWarning):
            _warn_later(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return data


def _load(path, branch=None):
    from .branchfile import load_branch
    return _read(load_branch, path, branch)


def _load_any(path):
    from .branchfile import load_diagram
    return _read(load_diagram, path)


def _point_spec(spec, what="--start"):
    from .branchfile import BranchFileError, split_spec
    try:
        path, branch, label = split_spec(spec, what)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    data = _load(path, branch)
    try:
        pt = data.point(label)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    return data, pt, label


def _explicit(*names):
    ctx = click.get_current_context()
    return [n for n in names if ctx.get_parameter_source(n) not in (click.core.ParameterSource.DEFAULT, None)]


def _inputs(loaded=(), files=()) -> list:
    """Every file this command reads (:func:`rodcont.safeio.command_inputs`): its --config file, the survey of
    --reference well:FILE, its --conduit file and that file's survey, the branch files ``files`` and the
    ``loaded`` branches or diagrams (with the surveys of their reference curves)."""
    from .safeio import command_inputs
    ctx = click.get_current_context()
    return command_inputs(config=ctx.meta.get("rodcont.config_file"), reference=ctx.meta.get("rodcont.reference"),
                          conduit=ctx.params.get("conduit"), branch_files=files, loaded=loaded)


def _check_out(out, inputs=(), overwrite=False, what="--out", loaded=()):
    """An output that is none of the command's inputs (any name), kept if it exists unless ``overwrite``."""
    from .branchfile import BranchFileError, check_output
    try:
        return check_output(out, list(inputs) + _inputs(loaded), overwrite, what)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None


def _image_out(path, inputs=(), overwrite=False, loaded=()):
    """A PNG/GIF/MP4 output path: a writable name that is not an input, an existing file only with
    --overwrite (the suffix is checked by each command)."""
    return _check_out(path, inputs, overwrite, "-o", loaded)


# --------------------------------------------------------------------------
# Interrupts: Ctrl-C and SIGTERM are taken between points
# --------------------------------------------------------------------------
class _Interrupts:
    """While active, SIGINT and SIGTERM set a flag that the point callback turns into
    ``KeyboardInterrupt`` (after the point is stored); a second one interrupts at once."""

    def __init__(self):
        self.signum = None

    def __enter__(self):
        self.previous = {s: signal.signal(s, self._handler) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _handler(self, signum, frame):
        if self.signum is not None:
            raise KeyboardInterrupt
        self.signum = signum

    def check(self):
        if self.signum is not None:
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        for s, h in self.previous.items():
            signal.signal(s, h)
        return False

    @property
    def exit_code(self) -> int:
        return 143 if self.signum == signal.SIGTERM else 130


class _Progress:
    """One status line on a terminal (rewritten in place), a line every few seconds otherwise."""

    def __init__(self, quiet: bool, interrupts: _Interrupts | None = None):
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.last = 0.0
        self.n = 0
        self.t0 = time.perf_counter()
        self.folds = 0
        self.interrupts = interrupts

    def __call__(self, pt):
        self.n += 1
        if str(pt.kind) == "fold":
            self.folds += 1
        if not self.quiet:
            now = time.perf_counter()
            d = pt.data
            msg = (f"point {self.n:5d}  Phi {d['phi_L']:9.5f}  stretch {d['stretch']:10.6f}  "
                   f"waves {d['helical_waves']}  min d3.K3 {d['min_alignment']:.3f}  folds {self.folds}  "
                   f"{now - self.t0:6.1f} s")
            if str(pt.kind) not in ("regular", "start"):
                click.echo(("\r" if self.tty else "") + f"  {str(pt.kind)[:60]:<14s} at Phi = {d['phi_L']:.10f}, "
                           f"stretch = {d['stretch']:.10f}" + " " * 20, err=True)
            if self.tty:
                click.echo("\r" + msg, nl=False, err=True)
            elif now - self.last > 5.0:
                click.echo(msg, err=True)
                self.last = now
        if self.interrupts is not None:
            self.interrupts.check()

    def done(self):
        if self.tty and not self.quiet:
            click.echo("", err=True)


# --------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------
@click.group(context_settings=dict(help_option_names=["-h", "--help"]))
@click.version_option(package_name="rodcont", message="%(prog)s %(version)s")
@click.option("--debug", is_flag=True, help="show tracebacks of unexpected failures")
@click.pass_context
def main_group(ctx, debug):
    """Equilibrium branches, folds and bifurcations of the twisted heavy rod (Eulerian Cosserat rod)."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=_number("--gamma"), help="tension ratio T / (w L) (or --T)")
@click.option("--phi", "phi", type=float, default=None, callback=_number("--phi"),
              help="end rotation Phi [rad] (or --torque)")
@click.option("--torque", type=float, default=None, callback=_number("--torque"),
              help="end torque M instead of --phi: Phi becomes an unknown (printed as phi_L)")
@click.option("--l0", "l0", type=float, default=None, callback=_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension becomes an unknown (printed as T)")
@click.option("--load-step", type=float, default=0.5, show_default=True, callback=_number("--load-step", positive=True),
              help="Phi increment of the natural continuation from 0 (under --torque: GJ/L times it)")
@click.option("--conduit", type=click.Path(dir_okay=False), default=None,
              help="TOML file of a conduit around the reference curve ([conduit] clearance, reference, eps): "
                   "the rod stays inside it, touching its wall where it must")
@click.option("--max-error", type=float, default=1e-6, show_default=True,
              callback=_number("--max-error", positive=True), help="accuracy guard on the estimated error")
@click.option("--uniform", is_flag=True, help="keep the first mesh (no refinement)")
@click.option("--N-max", "N_max", type=click.IntRange(1, 20000), default=4000, show_default=True,
              help="largest mesh the refinement may reach")
@click.option("--out", default=None, type=click.Path(dir_okay=False),
              help="write the equilibrium as a one-point branch file (export, shape, trace --start read it)")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@rod_options
def solve(gamma, phi, torque, l0, load_step, conduit, max_error, uniform, N_max, out, overwrite, N, k, w, EI, GJ, EA,
          L):
    """One equilibrium at (Gamma, Phi), reached by loading Phi (or the end torque) up from 0.

    The mesh starts from the problem's lengths (or --N) and is refined until the
    estimated error (a re-solve in a richer space, as trace's accuracy guard) is
    below --max-error and, in a conduit, the side force's below 1e-3; a result far
    above them is refused. Prints `name value` lines: the controls (T, gamma,
    phi_L, torque, l0) and responses (stretch, helical_waves, min_alignment, in a
    conduit min_gap, side_force and the contact zones), Newton's iterations and
    residual norm, the mesh N, the error estimates (what to trust).
    """
    from .drivers.solve import ConvergenceError, solve_equilibrium, write_equilibrium
    rod = _rod(w, EI, GJ, EA, L)
    T = click.get_current_context().meta.get("rodcont.T")
    if l0 is not None and (gamma is not None or T is not None):
        raise UserError("give one of --gamma, --T and --l0")
    if l0 is None:
        gamma, T = _tension(gamma, rod)
    if (phi is None) == (torque is None):
        raise UserError("give --phi (the end rotation) or --torque (the end torque), one of them")
    try:
        curve, wall = _conduit(conduit, rod)
        if out is not None:
            _check_out(out, [conduit] if conduit is not None else [], overwrite)
        if T is not None:
            _stretch_warning(rod, T)
        eq = solve_equilibrium(None if T is not None else gamma, phi, rod, N=N if _explicit("N") else None, k=k,
                               load_step=load_step, T=T, curve=curve, wall=wall, torque=torque, l0=l0,
                               adapt=not uniform, max_error=max_error, N_max=N_max, strict=True)
    except (ConvergenceError, ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None
    _print_equilibrium(eq, wall is not None)
    if out is not None:
        write_equilibrium(eq, out, overwrite=overwrite, meta=_meta(), max_error=max_error)
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


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=_number("--gamma"),
              help="tension ratio T / (w L) (required unless --start)")
@trace_options
@click.option("--start", default=None, help="restart from FILE.h5:POINT (or FILE.h5:BRANCH:POINT of a diagram); "
                                            "POINT: index from 0, F<j> or BP<j> from 1; the file's options "
                                            "unless given")
@click.option("--resume", "resume_file", default=None, type=click.Path(dir_okay=False),
              help="continue the unfinished (interrupted) trace in FILE.h5 into FILE.h5 itself, with its options")
@click.option("--extend", is_flag=True, help="with --resume: go on past the end of a finished branch")
@click.option("--switch", is_flag=True, help="with --start at a branch point: follow the other branch")
@click.option("--from-straight", type=float, default=None, callback=_number("--from-straight"),
              help="start near the straight twisted state at this Phi (weight homotopy)")
@click.option("--from-critical", type=click.IntRange(1, 1000), default=None,
              help="N: start at the N-th critical twist of the weightless straight rod (--w 0), along its helical "
                   "branch (a phase condition fixes the branch's turn about the axis)")
@click.option("--l0", "l0", type=float, default=None, callback=_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension is solved for at each point (column T)")
@click.option("--torque", type=float, default=None, callback=_number("--torque"),
              help="end torque held fixed (Phi solved for) in a trace of a rod parameter from --start")
@click.option("--param", type=click.Choice(["phi_L", "w", "T", "gamma", "EI", "GJ", "EA", "torque", "l0"]),
              default="phi_L", show_default=True,
              help="the continued parameter (others than phi_L with --range; torque: the end rotation free)")
@click.option("--range", "prange", type=float, nargs=2, default=None, callback=_number("--range"),
              help="A B: the interval of --param (when it is not phi_L)")
@click.option("--direction", type=click.Choice(["up", "down"]), default="up", show_default=True,
              help="which way the parameter goes first")
@click.option("--conduit", type=click.Path(dir_okay=False), default=None,
              help="TOML file of a conduit around the reference curve ([conduit] clearance, reference, eps): "
                   "the rod stays inside it, touching its wall where it must")
@click.option("--out", default=None, type=click.Path(dir_okay=False), help="branch file to write (HDF5)")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@click.option("--quiet", is_flag=True, help="no progress display")
@rod_options
def trace(gamma, phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error, max_defect,
          fold_error, forced, uniform, N_max, store_every, start, resume_file, extend, switch, from_straight,
          from_critical, l0, torque, param, prange, direction, conduit, out, overwrite, quiet, N, k, w, EI, GJ, EA, L):
    """Trace a branch (in Phi, or in a rod parameter) through its folds and write it to a branch file.

    Folds, branch points, forced values and the guards are located, not just
    bracketed; the mesh adapts to the shape unless --uniform. With --start the
    rod, the tension, the mesh and the trace options come from the file (options
    given override them); --resume FILE.h5 continues an interrupted trace in place.
    """
    from .drivers.trace import trace as run_trace
    kw = _trace_kwargs(phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
                       max_defect, fold_error, forced, uniform, N_max, store_every)
    kw["direction"] = 1 if direction == "up" else -1
    if resume_file is not None:
        return _resume_trace(resume_file, extend, out, start, from_straight, switch, param, prange, conduit, k,
                             kw, quiet)
    if extend:
        raise UserError("--extend goes with --resume FILE.h5")
    if out is None:
        raise UserError("--out FILE.h5 is required (or --resume FILE.h5)")
    if param != "phi_L" and prange is not None:
        kw["p_range"] = tuple(prange)
    elif prange is not None:
        raise UserError("--range is for --param other than phi_L (use --phi-min/--phi-max)")
    if start is not None:
        if from_straight is not None:
            raise UserError("give --start or --from-straight, not both")
        data, pt, label = _point_spec(start)
        if param != "phi_L" and prange is None and param != data.param:
            raise UserError(f"--param {param} needs --range A B")
        if from_critical is not None:
            raise UserError("give --start or --from-critical, not both")
        args = _restart_args(data, label, start, param, switch, N, k, conduit, kw)
        if torque is not None:  # a torque held from the point on (its Phi solved for), or an unstressed length
            args["torque"] = torque
        if l0 is not None:
            args["l0"], args["T"] = l0, None
        _check_out(out, args.inputs, overwrite, loaded=(data,))
        for note in args.notes:
            click.echo(f"rodcont: note: {note}", err=True)
        rod, N, T, k = args.pop("rod"), args.pop("N"), args.pop("T"), args.pop("k")
        args.pop("gamma", None)
        if param in ("T", "gamma") and prange is not None:
            _stretch_warning(rod, max([v if param == "T" else v * rod.w * rod.L for v in prange], key=abs))
        _run_trace(run_trace, None, rod, N, k, T, {}, dict(args, meta=_meta()), out, overwrite, quiet,
                   restart=True)
        return
    if param != "phi_L" and prange is None:
        raise UserError(f"--param {param} needs --range A B")
    extra = dict(param=param, l0=l0, torque=torque, from_critical=from_critical)
    T = None
    if switch:
        raise UserError("--switch needs --start FILE.h5:BP<j>")
    rod = _rod(w, EI, GJ, EA, L)
    if l0 is not None:  # the tension solved for
        if gamma is not None or click.get_current_context().meta.get("rodcont.T") is not None:
            raise UserError("give one of --gamma, --T and --l0")
    elif gamma is None and click.get_current_context().meta.get("rodcont.T") is None:
        raise UserError("--gamma or --T is required (or --l0, or --start FILE.h5:POINT)")
    else:
        gamma, T = _tension(gamma, rod)
        gamma = None
    if conduit is not None:
        if from_straight is not None:
            raise UserError("--from-straight is not available inside a conduit (trace from the sag)")
        extra["curve"], extra["wall"] = _conduit(conduit, rod)
    else:
        extra["curve"] = _curve(rod, "--from-straight" if from_straight is not None else
                                "--from-critical" if from_critical is not None else None)
    if from_straight is not None:
        extra["from_straight"] = from_straight
        if param != "phi_L":
            extra["phi_L"] = from_straight
    elif param not in ("phi_L", "torque"):
        raise UserError(f"--param {param} starts from --start FILE:POINT or --from-straight PHI")
    _check_out(out, [], overwrite)  # nor the --conduit file, its survey, --config, --reference well:FILE
    if T is not None:
        _stretch_warning(rod, T)
    extra["meta"] = _meta()
    if param in ("T", "gamma") and prange is not None:
        # a trace in the tension reaches the ends of its range: warn for the farther one
        ends = [v if param == "T" else v * rod.w * rod.L for v in prange]
        _stretch_warning(rod, max(ends, key=abs))
    _run_trace(run_trace, gamma if T is None else None, rod, N, k, T, kw, extra, out, overwrite, quiet)


def _restart_args(data, label, spec, param, switch, N, k, conduit, kw):
    """The arguments of a trace from a stored point (:func:`rodcont.restart.restart_from`: its checks, the
    file's options unless given on the command line)."""
    from .restart import restart_from
    ctx = click.get_current_context()
    try:
        return restart_from(data, label, param=param, direction=kw["direction"], switch=switch,
                            N=N if _explicit("N") else None, k=k if _explicit("k") else None,
                            changes=_rod_changes(), reference=ctx.meta.get("rodcont.reference")
                            if _explicit("reference") else None, conduit=conduit,
                            options=_given_options(kw), spec=spec)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None


def _rod_changes() -> dict:
    """The rod and tension values given on the command line (a restart refuses those that differ)."""
    ctx = click.get_current_context()
    given = {n: ctx.params[n] for n in _explicit("gamma", "w", "EI", "GJ", "EA", "L") if n in ctx.params}
    if ctx.meta.get("rodcont.T") is not None:
        given["T"] = ctx.meta["rodcont.T"]
    if _explicit("weight_direction"):
        given["weight_direction"] = ctx.meta.get("rodcont.weight_direction")
    return given


# trace options (TraceOptions fields) and the command-line options that set them
_OPTION_SOURCES = {"phi_max": ("phi_max",), "phi_min": ("phi_min",), "stretch_max": ("stretch_max",),
                   "max_steps": ("max_steps",), "ds": ("ds",), "ds_max": ("ds_max",), "ds_min": ("ds_min",),
                   "min_alignment": ("min_alignment",), "max_error": ("max_error", "max_defect"),
                   "fold_error": ("fold_error",), "forced": ("forced",), "adapt": ("uniform",),
                   "N_max": ("N_max",), "p_range": ("prange",), "store_every": ("store_every",)}


def _given_options(kw) -> dict:
    """The trace options given on the command line or in --config (the rest a restart takes from its file)."""
    return {name: kw[name] for name, sources in _OPTION_SOURCES.items() if name in kw and _explicit(*sources)}


def _resume_trace(path, extend, out, start, from_straight, switch, param, prange, conduit, k, kw, quiet):
    """``trace --resume FILE.h5``: the unfinished trace continued into the same file (rodcont.restart.resume)."""
    from .branchfile import same_file
    from .restart import resume
    if out is not None and not same_file(out, path):
        raise UserError(f"--resume continues {path} in place: drop --out {out} (or resume a copy)")
    for given, what in ((start, "--start"), (from_straight, "--from-straight"), (switch or None, "--switch"),
                        (conduit, "--conduit")):
        if given is not None:
            raise UserError(f"--resume goes on from the file's last point: drop {what}")
    if _explicit("reference"):
        raise UserError("--resume keeps the file's reference curve: drop --reference")
    if _explicit("N"):
        raise UserError("--resume goes on on the file's own mesh (it adapts): drop --N")
    d = _load_any(path)
    kind = d.attrs.get("kind", "branch")
    if kind == "diagram":
        raise UserError(f"{path} is a diagram: finish it with rodcont diagram --resume {path}")
    if kind != "branch":
        raise UserError(f"{path} is a {str(kind).replace('_', ' ')} file, not a trace: it cannot be resumed")
    data = d.branches[0]
    if _explicit("param") and param != data.param:
        raise UserError(f"--resume goes on in the file's parameter ({data.param}): drop --param {param}")
    if kw["direction"] != 1:
        raise UserError("--resume goes on the way the trace went: drop --direction down")
    if prange is not None:
        kw["p_range"] = tuple(prange)
    options = _given_options(kw)
    if _explicit("k") and k != int(data.attrs["k"]):
        raise UserError(f"--k {k} differs from the file's k = {int(data.attrs['k'])}: a resumed trace keeps it")

    def check(args):  # the file itself is the output: refused only onto another input (its survey, --config)
        _check_out(path, [p for p in args.inputs if not same_file(p, path)], True)

    def run(callback):
        return resume(path, extend=extend, changes=_rod_changes(), options=options, callback=callback, check=check,
                      data=d)

    _traced(run, path, quiet, resumed=True)


def _run_trace(run_trace, gamma, rod, N, k, T, kw, extra, out, overwrite, quiet, restart=False):
    def run(callback):
        return run_trace(gamma, rod, N=N, k=k, T=T, out=out, overwrite=overwrite, callback=callback, **extra, **kw)

    _traced(run, out, quiet, restart=restart)


def _traced(run, out, quiet, restart=False, resumed=False):
    """Run a trace into ``out`` with progress and Ctrl-C between points; print its summary."""
    from .restart import start_hint
    before = _identity(out)
    with _Interrupts() as intr:
        progress = _Progress(quiet, intr)
        t0 = time.perf_counter()
        interrupted = False
        try:
            run(progress)
        except KeyboardInterrupt:
            interrupted = True
        except (ValueError, TypeError) as exc:
            raise UserError(str(exc) + (start_hint(str(exc)) if restart else "")) from None
        finally:
            progress.done()
    elapsed = time.perf_counter() - t0
    if _identity(out) == before:  # nothing published: the target (if any) is as it was
        what = "interrupted before the first point" if interrupted else "no point"
        raise UserError(f"no branch traced: {what}" + (f" ({out} is as it was)" if before is not None else ""))
    data = _load(out)
    _summary(data, elapsed)
    if interrupted:
        click.echo(f"interrupted: {out} holds the {len(data)} completed point(s); go on with "
                   f"rodcont trace --resume {out}", err=True)
        sys.exit(intr.exit_code)


def _identity(path):
    """What tells one published version of ``path`` from another (a publication renames a new file over it)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_dev, st.st_mtime_ns, st.st_size


def _summary(data, elapsed):
    click.echo(f"points       {len(data)}")
    click.echo(f"folds        {len(data.folds.get('index', []))}")
    click.echo(f"branch pts   {len(data.branch_points.get('index', []))}")
    click.echo(f"stop reason  {data.attrs.get('stop_reason')}")
    click.echo(f"time         {elapsed:.3f} s")
    import json
    for a, b, n0, n1 in json.loads(data.attrs.get("missed_crossings", "[]")):
        click.echo(f"warning      unstable modes {n0} -> {n1} between {data.param} = {a:.10g} and {b:.10g}: "
                   f"more eigenvalues crossed zero than the located folds and branch points account for "
                   f"(unseen bifurcations; retrace with a smaller --ds-max)")
    _fold_warnings(data)
    for kind, a, b in json.loads(data.attrs.get("unlocated", "[]")):
        click.echo(f"warning      a {kind.replace('_', ' ')} between {data.param} = {a:.10g} and {b:.10g} was "
                   f"detected but could not be located (no point between them converged); it is not in the "
                   f"tables")
    _fold_table(data)
    bp = data.branch_points
    for j in range(len(bp.get("index", []))):
        click.echo(f"BP{j + 1:<3d} {bp['index'][j]:6d} {bp['phi_L'][j]:18.12f} {bp['stretch'][j]:18.12f}  "
                   f"(follow the other branch: --start FILE:BP{j + 1} --switch)")


def _fold_warnings(data) -> None:
    """A fold only bracketed, or located above --fold-error, is said in the summary (the table marks it too); so is
    where a trace in a conduit went deeper than the penetration guard."""
    import json
    f = data.folds
    index = list(f.get("index", []))
    located = list(f.get("located", [1] * len(index)))
    fold_error = (data.settings.get("adaptive") or {}).get("fold_error")
    deep = json.loads(data.attrs.get("penetration_guard", "[]") or "[]")  # a contact law too soft for the loads
    if deep:
        click.echo(f"warning      the rod sits deeper than 1e-3 of the clearance inside the wall from {data.param} "
                   f"between {deep[0]:.10g} and {deep[1]:.10g} ({deep[2]:.2g} there): the contact law is too soft "
                   f"for these loads (a larger force_scale in the conduit file)")
    for j, i in enumerate(index):
        phi = f["phi_L"][j]
        if not located[j]:
            click.echo(f"warning      fold F{j + 1} at phi_L = {phi:.10g} is bracketed, not located: its location did "
                       f"not converge (the values are those of the nearest converged point); a smaller --ds-max "
                       f"or a larger --N-max may locate it")
        err = float(data.table["error"][int(i)]) if "error" in data.table else math.nan
        if fold_error and err > float(fold_error):
            click.echo(f"warning      fold F{j + 1} at phi_L = {phi:.10g} has an estimated error {err:.2g} above "
                       f"--fold-error {float(fold_error):g} (its mesh could not be refined enough: --N-max)")


def _fold_table(data):
    f = data.folds
    if not len(f.get("index", [])):
        click.echo("no folds")
        return
    # a branch traced in another parameter folds in that parameter: its value leads the row
    param = data.param if data.param != "phi_L" else None
    head = f" {param:>18}" if param else ""
    click.echo(f"{'fold':>4} {'index':>6}{head} {'phi_L':>18} {'stretch':>18} {'torque':>16} {'l0':>16} "
               f"waves before->after")
    located = f.get("located", [1] * len(f["index"]))
    for j in range(len(f["index"])):
        mark = "  (+1 wave)" if f["waves_after"][j] > f["waves_before"][j] else ""
        mark += _stable_side(f, j)
        mark += "" if located[j] else "  (bracketed, not located)"
        value = f" {float(data.point(int(f['index'][j]))[param]):18.12g}" if param else ""
        click.echo(f"F{j + 1:<3d} {f['index'][j]:6d}{value} {f['phi_L'][j]:18.12f} {f['stretch'][j]:18.12f} "
                   f"{f['torque'][j]:16.10f} {f['l0'][j]:16.10f} {f['waves_before'][j]:d} -> {f['waves_after'][j]:d}"
                   f"{mark}")


@main_group.command()
@click.option("--gamma", type=float, default=None, callback=_number("--gamma"), help="tension ratio T / (w L) (or --T)")
@click.option("--phi-max", type=float, default=40.0, show_default=True, callback=_number("--phi-max"))
@click.option("--phi-min", type=float, default=0.0, show_default=True, callback=_number("--phi-min"))
@rod_options
def critical(gamma, phi_max, phi_min, N, k, w, EI, GJ, EA, L):
    """Critical twists: where the straight weightless rod under the same tension buckles.

    From the tangent operator along the exact straight state (each double
    root, a circle of helical modes, listed once): Phi, torque m = GJ alpha
    Phi / L and m L / (alpha EI).
    """
    from .drivers.diagram import critical_twists
    rod = _rod(w, EI, GJ, EA, L)
    _curve(rod, "critical")
    gamma, T = _tension(gamma, rod)
    try:
        crit = critical_twists(rod, T, phi_max=phi_max, phi_min=phi_min, k=k)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None
    _stretch_warning(rod, T)
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
@click.option("--gamma", type=float, default=None, callback=_number("--gamma"), help="tension ratio T / (w L) (or --T)")
@trace_options
@click.option("--deflate", "deflate_at", type=float, multiple=True, callback=_number("--deflate"),
              help="a Phi where deflated Newton looks for solutions the seeds missed (repeatable)")
@click.option("--l0", "l0", type=float, default=None, callback=_number("--l0", positive=True),
              help="unstressed length instead of --gamma/--T: the tension is solved for at each point")
@click.option("--out", default=None, type=click.Path(dir_okay=False), help="diagram file to write (HDF5)")
@click.option("--resume", "resume_file", default=None, type=click.Path(dir_okay=False),
              help="finish the interrupted diagram in FILE.h5 (its complete branches kept), into FILE.h5 itself")
@click.option("--overwrite", is_flag=True, help="replace --out if it exists")
@click.option("--quiet", is_flag=True, help="no progress display")
@rod_options
def diagram(gamma, phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
            max_defect, fold_error, forced, uniform, N_max, store_every, deflate_at, l0, out, resume_file, overwrite,
            quiet, N, k, w, EI, GJ, EA, L):
    """The whole response diagram at Gamma: every branch in [phi-min, phi-max], every fold.

    The primary branch from Phi = 0, one seed per interval between
    consecutive critical twists (traced both ways), --deflate for more;
    a branch reached twice is kept once. Prints one line per branch and the
    fold table with the waves on each side (+1 wave marks a fold that adds one).
    """
    from .drivers.diagram import diagram as run_diagram
    kw = _trace_kwargs(phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
                       max_defect, fold_error, forced, uniform, N_max, store_every)
    rod = _rod(w, EI, GJ, EA, L)
    _curve(rod, "diagram")
    if resume_file is not None:
        run, out = _resume_diagram(resume_file, out, kw, deflate_at, N, k), resume_file
    else:
        if out is None:
            raise UserError("--out FILE.h5 is required (or --resume FILE.h5)")
        T = None
        if l0 is None:
            gamma, T = _tension(gamma, rod)
            _stretch_warning(rod, T)
        elif gamma is not None or click.get_current_context().meta.get("rodcont.T") is not None:
            raise UserError("give one of --gamma, --T and --l0")
        _check_out(out, [], overwrite)

        def run(**more):
            return run_diagram(None, rod, N=N, k=k, T=T, l0=l0, out=out, overwrite=overwrite, deflate_at=deflate_at,
                               meta=_meta(), **more, **kw)
    with _Interrupts() as intr:
        progress = _Progress(True, intr)
        t0 = time.perf_counter()
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
    elapsed = time.perf_counter() - t0
    click.echo(f"critical twists  {', '.join(f'{c:.8f}' for c in dg.critical)}")
    click.echo(f"branches         {len(dg.branches)}")
    for j, db in enumerate(dg.branches):
        click.echo(f"  {j}: {len(db.branch):4d} points {len(db.branch.folds):2d} folds {db.time:6.2f} s  "
                   f"{db.origin}")
        if db.ends[0] == db.ends[1]:  # both directions stopped by the same guard: say it once
            click.echo(f"       both ends: {db.ends[0]}")
        else:
            click.echo(f"       ends: {db.ends[0]}")
            click.echo(f"             {db.ends[1]}")
        for kind, a, b in db.branch.unlocated:
            click.echo(f"       warning: a {kind.replace('_', ' ')} between phi_L = {a:.10g} and {b:.10g} was "
                       f"detected but could not be located; it is not in the tables")
        for a, b, n0, n1 in db.branch.missed_crossings:
            click.echo(f"       warning: unstable modes {n0} -> {n1} between phi_L = {a:.10g} and {b:.10g}: more "
                       f"eigenvalues crossed zero than the located folds and branch points account for (unseen "
                       f"bifurcations; the counts between are corrected)")
    for origin, why in dg.skipped:
        click.echo(f"  not traced: {origin}: {why}")
    click.echo(f"time             {elapsed:.2f} s")
    _diagram_folds(dg.folds)


def _resume_diagram(path, out, kw, deflate_at, N, k):
    """``diagram --resume FILE.h5``: the runner that finishes it in place (rodcont.restart.resume_diagram);
    options given must be the file's."""
    import numpy as np
    from .branchfile import same_file
    from .restart import resume_diagram
    if out is not None and not same_file(out, path):
        raise UserError(f"--resume finishes {path} in place: drop --out {out} (or resume a copy)")
    options = _given_options(kw)
    options.pop("store_every", None)
    d = _load_any(path)
    if d.attrs.get("kind") != "diagram":
        raise UserError(f"{path} is not a diagram file: resume a trace with rodcont trace --resume {path}")
    stored = [float(v) for v in np.atleast_1d(d.attrs.get("deflate_at", []))] if "deflate_at" in d.attrs else []
    if _explicit("deflate_at") and sorted(deflate_at) != sorted(stored):
        raise UserError(f"--deflate differs from the diagram file's ({', '.join(f'{v:g}' for v in stored) or 'none'}"
                        f"): a resumed diagram keeps its options (drop it)")
    for name, given, own in (("N", N, d.attrs.get("N")), ("k", k, d.attrs.get("k"))):
        if _explicit(name) and own is not None and int(given) != int(own):
            raise UserError(f"--{name} {given} differs from the diagram file's {name} = {own}: a resumed diagram keeps "
                            f"its mesh (drop it)")

    def check(args):  # the file itself is the output
        _check_out(path, [], True)

    def run(**more):
        try:
            return resume_diagram(path, changes=_rod_changes(), options=options, check=check, data=d, **more)
        except (ValueError, TypeError) as exc:
            raise UserError(str(exc)) from None

    return run


def _stable_side(f, j) -> str:
    ub = f.get("unstable_before", [-1] * (j + 1))[j]
    ua = f.get("unstable_after", [-1] * (j + 1))[j]
    if ub < 0 or ua < 0:
        return ""
    side = {(True, False): "before", (False, True): "after", (True, True): "both", (False, False): "neither"}
    return f"  stable: {side[(ub == 0, ua == 0)]} ({ub} | {ua} unstable)"


def _diagram_folds(folds):
    if not folds:
        click.echo("no folds")
        return
    click.echo(f"{'branch':>6} {'phi_L':>18} {'stretch':>16} {'torque':>14} {'l0':>14} waves")
    for f in folds:
        mark = "  <- +1 wave" if f["waves_after"] > f["waves_before"] else ""
        mark += _stable_side({k: [v] for k, v in f.items()}, 0)
        click.echo(f"{f['branch']:6d} {f['phi_L']:18.12f} {f['stretch']:16.10f} {f['torque']:14.8f} "
                   f"{f['l0']:14.10f} {f['waves_before']} -> {f['waves_after']}{mark}")


def _user_folds(data) -> None:
    """The folds and branch points of a user's problem (``kind = "bvp"``, rodcont.bvp): every number column."""
    from .bvp import describe
    click.echo(describe(data))
    skip = ("arclength", "kind", "located", "defect", "dp_ds")
    cols = [data.param] + [c for c in data.table if c not in skip and c != data.param]
    for what, table in (("fold", data.folds), ("branch point", data.branch_points)):
        if not len(table):
            click.echo(f"no {what}s")
            continue
        click.echo(f"{'label':<6} {'index':>6} " + " ".join(f"{c:>22}" for c in cols))
        for row in table:
            i = int(row["index"])
            mark = "" if data.table["located"][i] else "  (bracketed, not located)"
            click.echo(f"{row['label']:<6} {i:6d} " + " ".join(f"{float(data.table[c][i]):22.15g}" for c in cols)
                       + mark)


@main_group.command()
@click.argument("file")
def folds(file):
    """Print the fold table of a branch or diagram file."""
    d = _load_any(file)
    if d.attrs.get("kind") == "bvp":
        _user_folds(d.branches[0])
        return
    if d.attrs.get("kind") == "diagram":
        click.echo(f"# {file}: diagram at Gamma = {d.attrs.get('gamma'):g}, {len(d.branches)} branches"
                   + _diagram_unfinished(file, d))
        _diagram_folds(list(d.folds))
        return
    data = d.branches[0]
    click.echo(f"# {file}: Gamma = {data.gamma:g}, {len(data)} points, stop: {data.attrs.get('stop_reason')}")
    _fold_table(data)


def _diagram_unfinished(file, d) -> str:
    """What the header of an interrupted diagram adds: which branch is unfinished, and how to finish it."""
    if d.attrs.get("status") not in ("interrupted", "running"):
        return ""
    open_ = [b.name for b in d.branches if str(b.status) in ("interrupted", "running")]
    part = f"; branch {', '.join(open_)} unfinished, its folds not listed" if open_ else ""
    return f" (INTERRUPTED{part}: finish it with rodcont diagram --resume {file})"


def _check_plot_variables(data, xvar, yvar) -> None:
    """``--x``/``--y`` among the rod's variables, or, for files of a user's problem, their columns."""
    from .plots import PLOT_VARIABLES
    allowed = PLOT_VARIABLES + ("gamma", "T", "w", "EI", "GJ", "EA")
    users = [b for d in data if d.attrs.get("kind") == "bvp" for b in d.branches]
    if users:
        common = set.intersection(*(set(b.table) for b in users)) - {"kind", "located"}
        allowed = tuple(c for c in users[0].table if c in common)
    for name, v in (("--x", xvar), ("--y", yvar)):
        if v is not None and v not in allowed:
            raise UserError(f"{name} {v!r}: choose one of {', '.join(allowed)}")


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
    """Response diagrams: any two of phi_L, stretch, torque, l0, helical_waves, min_alignment or a
    continued parameter (torque against Phi is the distinguished diagram); one colour per file,
    stable parts solid, unstable dashed, folds marked and labelled with the waves on each side."""
    _image_out(output, files, overwrite)
    if not output.lower().endswith(".png"):
        raise UserError(f"-o {output}: plots are written as PNG (name it .png)")
    if labels and len(labels) != len(files):
        raise UserError(f"--label: give one per file ({len(files)}), got {len(labels)}")
    data = [_load_any(f) for f in files]
    _image_out(output, files, overwrite, loaded=data)  # nor a survey the files' reference curves read
    _check_plot_variables(data, xvar, yvar)
    if any(sum(len(b) for b in d.branches) == 0 for d in data):
        raise UserError("a branch file with no points cannot be plotted")
    from .plots import response_diagram
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
    from .branchfile import BranchFileError
    from .rod import EulerianRod
    _image_out(output, [file], overwrite)
    if not output.lower().endswith(".png"):
        raise UserError(f"-o {output}: shapes are written as PNG (name it .png)")
    data = _load(file, branch)
    _image_out(output, [file], overwrite, loaded=(data,))  # nor the survey its reference curve reads
    wall = data.wall
    model = EulerianRod(data.rod, data.curve, wall)
    curves, contacts = [], []
    S = np.linspace(*model.interval, 400)
    # inside a conduit the deflections and the clearance are drawn magnified (else a thin pipe is a line)
    magnify = 1.0 if wall is None else max(1.0, 0.12 * model.interval[1] / wall.c_max)
    jet = model.curve.jet(S)
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
    from .plots import shape_figure
    if not all(np.all(np.isfinite(r)) and np.max(np.abs(r)) < 1e100 for r, _ in curves):
        raise UserError(f"{file}: the stored solution gives a centreline that is not finite")
    title = f"{os.path.basename(file)}  (Γ = {data.gamma:g})"
    tube = None
    if wall is not None:
        theta = np.linspace(0.0, 2 * np.pi, 25)
        St = np.linspace(*model.interval, 121)
        jt = model.curve.jet(St)
        cS = np.broadcast_to(wall.clearance_at(St), St.shape)[:, None]
        ring = magnify * cS * (jt.K[0][:, :, None] * np.cos(theta) + jt.K[1][:, :, None] * np.sin(theta))
        tube = tuple(jt.R[a][:, None] + ring[a] for a in range(3))
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


@main_group.command("fold-curve")
@click.argument("spec")
@click.option("--param", type=click.Choice(["gamma", "T", "w", "EI", "GJ", "EA"]), default="gamma", show_default=True,
              help="second parameter (gamma keeps w fixed; the others keep T fixed)")
@click.option("--range", "prange", type=float, nargs=2, required=True, callback=_number("--range"),
              help="A B: the interval of the parameter")
@click.option("--ds", type=float, default=0.05, show_default=True, callback=_number("--ds", positive=True))
@click.option("--ds-max", type=float, default=0.5, show_default=True, callback=_number("--ds-max", positive=True))
@click.option("--max-steps", type=click.IntRange(1, 10**6), default=500, show_default=True)
@click.option("--max-error", type=float, default=1e-6, show_default=True, callback=_number("--max-error", positive=True),
              help="accuracy guard on the estimated error of each fold")
@click.option("--forced", type=float, multiple=True, callback=_number("--forced"),
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
    from .branchfile import BranchFileError, split_spec
    from .drivers.foldcurve import fold_curve
    try:
        path, branch, label = split_spec(spec, "fold-curve")
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    fold = label if label.strip().upper().startswith("F") else None
    if fold is None:
        try:
            fold = int(label)
        except ValueError:
            raise UserError(f"fold-curve expects FILE.h5:I with I the fold number from 0 (or F<j> from 1), got "
                            f"{label!r}") from None
    data = _load(path, branch)
    _check_out(out, [path], overwrite, loaded=(data,))
    with _Interrupts() as intr:
        progress = _Progress(quiet, intr)
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
            raise UserError(str(exc)) from None
    progress.done()
    if len(res) <= 1:
        raise UserError(f"the fold could not be continued: {res.message_first}; {res.message}")
    click.echo(f"points       {len(res)}")
    click.echo(f"stop reasons down: {res.message_first}; up: {res.message}")
    click.echo(f"time         {time.perf_counter() - t0:.3f} s")
    click.echo(f"{param:>12} {'phi_L':>18} {'stretch':>16} {'torque':>14} kind")
    for i in range(len(res)):
        d = res.row_at(i)
        click.echo(f"{d[param]:12.6f} {d['phi_L']:18.12f} {d['stretch']:16.10f} {d['torque']:14.8f} {d['kind']}")


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
@click.option("--gamma", "gammas", cls=_GreedyFloats, type=float, required=True, callback=_number("--gamma"),
              help="tension ratios, e.g. 0 0.5 1 2 5")
@trace_options
@click.option("--diagram", "whole", is_flag=True, help="the whole diagram per Gamma, not only the primary branch")
@click.option("--jobs", type=click.IntRange(1, 1024), default=None, help="parallel processes [default: all cores]")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="directory for the files")
@click.option("--overwrite", is_flag=True, help="replace files that exist in the directory")
@click.option("--quiet", is_flag=True)
@rod_options
def sweep(gammas, phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
          max_defect, fold_error, forced, uniform, N_max, store_every, whole, jobs, out_dir, overwrite, quiet,
          N, k, w, EI, GJ, EA, L):
    """A family, one branch (or --diagram) per Gamma, traced in parallel, and their combined response diagram."""
    from .drivers.solve import check_tension
    from .drivers.sweep import branch_path, gamma_name, sweep as run_sweep
    if click.get_current_context().meta.get("rodcont.T") is not None:
        raise UserError("sweep runs one branch per --gamma; --T is for a single trace or diagram")
    kw = _trace_kwargs(phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
                       max_defect, fold_error, forced, uniform, N_max, store_every)
    rod = _rod(w, EI, GJ, EA, L)
    curve = _curve(rod, "sweep --diagram" if whole else None)
    if curve is not None:
        kw["curve"] = curve.spec
    for g in gammas:
        try:
            check_tension(rod, rod.tension(g), f"--gamma {g:g}:")
        except ValueError as exc:
            raise UserError(str(exc)) from None
    if len({gamma_name(g) for g in gammas}) != len(gammas):
        raise UserError("--gamma values must be distinct")
    if not out_dir.strip():
        raise UserError("--out needs a directory name")
    parent = os.path.dirname(os.path.abspath(out_dir))
    if not os.path.isdir(parent):
        raise UserError(f"cannot create {out_dir}: directory {parent} does not exist")
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise UserError(f"--out {out_dir} exists and is not a directory")
    for g in gammas:
        _stretch_warning(rod, rod.tension(g))
    from .drivers.trace import TraceOptions
    try:
        TraceOptions(**{key: v for key, v in kw.items() if key not in ("store_every", "curve")})
        for g in gammas:
            tension = rod.tension(g)
            if not math.isfinite(tension):
                raise ValueError(f"--gamma {g:g} gives a tension that is not finite")
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None
    from .branchfile import same_file
    for p in [branch_path(out_dir, g, whole) for g in gammas] + [os.path.join(out_dir, "response_diagram.png")]:
        for src in _inputs():  # --config, --reference well:FILE
            if same_file(p, src):
                raise UserError(f"--out {out_dir}: its file {p} is the input file {src}: write to another directory")
    made = not os.path.exists(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create {out_dir}: {exc.strerror}") from None
    t0 = time.perf_counter()
    try:
        res = run_sweep(list(gammas), out_dir, rod=rod, N=N, k=k, jobs=jobs, progress=not quiet, diagram=whole,
                        overwrite=overwrite, **kw)
    except (ValueError, TypeError, OSError) as exc:
        if made and not os.listdir(out_dir):
            os.rmdir(out_dir)
        msg = f"{exc.strerror}: {exc.filename}" if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise UserError(msg) from None
    click.echo(f"{'gamma':>8} {'branches':>8} {'points':>7} {'folds':>6} {'first fold phi_L':>18}  stop reason")
    for r in res["branches"]:
        ff = f"{r['first_fold']:18.10f}" if r["first_fold"] is not None else f"{'-':>18}"
        click.echo(f"{r['gamma']:8g} {r['branches']:8d} {r['points']:7d} {r['folds']:6d} {ff}  {r['stop_reason']}")
    click.echo(f"diagram      {res['diagram']}")
    click.echo(f"time         {time.perf_counter() - t0:.2f} s ({res['jobs']} processes)")
    failed = [r for r in res["branches"] if r["error"]]
    if failed:
        if made and not os.listdir(out_dir):
            os.rmdir(out_dir)
        first = failed[0]
        raise UserError(f"{len(failed)} of {len(res['branches'])} Gamma failed (Gamma {first['gamma']:g}: "
                        f"{first['error']}); the others are in {out_dir}" if len(failed) < len(res["branches"])
                        else f"every Gamma failed (Gamma {first['gamma']:g}: {first['error']})")


def _register_extra_commands():
    from .cli_export import animate_cmd, export_cmd
    main_group.add_command(export_cmd)
    main_group.add_command(animate_cmd)


_register_extra_commands()


# --------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------
def main(argv=None):
    """Entry point: click's parsing with one-line errors and exit status 2."""
    import warnings
    warnings.simplefilter("ignore", RuntimeWarning)
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    _PENDING.clear()
    try:
        rv = main_group.main(args=argv, prog_name="rodcont", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except SystemExit as exc:
        if exc.code in (0, None, 130, 143):  # an ending, not an error: what it read is said now
            _flush_pending()
        # click turns a write to a closed pipe (`rodcont ... | head`) into exit 1: the reader went
        # away, not an error of ours
        if exc.code == 1 and type(sys.stdout).__name__.endswith("PacifyFlushWrapper"):  # click >= 8.2: _Pacify...
            _quiet_stdout()
            sys.exit(0)
        raise
    except click.ClickException as exc:
        msg = exc.format_message() if not isinstance(exc, click.UsageError) else _usage_message(exc)
        _err(f"rodcont: error: {' '.join(msg.split())}")
        sys.exit(EXIT_USAGE)
    except (click.exceptions.Abort, KeyboardInterrupt):
        _err("rodcont: interrupted")
        sys.exit(130)
    except BrokenPipeError:
        _quiet_stdout()
        sys.exit(0)
    except Exception as exc:  # a bug, or the machine (memory, disk): one line, and say which
        if debug:
            raise
        from .branchfile import BranchFileError
        from .safeio import InputFileError, OutputFileError
        if isinstance(exc, (BranchFileError, InputFileError, OutputFileError)):
            _err(f"rodcont: error: {exc}")
            sys.exit(EXIT_USAGE)
        if isinstance(exc, (MemoryError, OSError)):
            _err(f"rodcont: error: {type(exc).__name__}: {' '.join(str(exc).split())}")
            sys.exit(1)
        _err(f"rodcont: error: unexpected failure ({type(exc).__name__}: {' '.join(str(exc).split())}); "
             f"please report it with the command line (--debug shows the traceback)")
        sys.exit(1)
    _flush_pending()
    sys.exit(rv if isinstance(rv, int) else 0)


def _quiet_stdout() -> None:
    try:
        sys.stdout = open(os.devnull, "w")
    except OSError:
        pass


def _err(msg: str) -> None:
    try:
        click.echo(msg, err=True)
    except OSError:
        pass


def _usage_message(exc: click.UsageError) -> str:
    msg = exc.format_message().replace("\n", " ")
    if exc.ctx is not None and exc.ctx.command_path:
        msg += f" (see '{exc.ctx.command_path} --help')"
    return msg


if __name__ == "__main__":
    main()
