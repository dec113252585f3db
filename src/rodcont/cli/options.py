"""The options shared by the commands: number checks, ``--config FILE.toml``, the rod/load/mesh options, the
trace options, and the echo of the problem as run (TOML comment lines)."""

from __future__ import annotations

import math

import click

from .common import UserError, explicit


def check_number(name, positive=False, nonnegative=False):
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
CONFIG_SECTIONS = {"rod": ("EI", "GJ", "EA", "w", "L", "weight_direction", "reference"),
                   "loads": ("gamma", "T", "phi", "torque", "l0"),
                   "mesh": ("N", "k", "N_max", "uniform")}


def _load_config(ctx, param, value):
    """Read a TOML problem file into the command's defaults (options on the command line still win)."""
    if value is None:
        return None
    import tomllib
    from ..safeio import InputFileError, read_input
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
    taken here and kept on the click context for :func:`make_rod` and :func:`tension_of`.
    """
    import functools

    @functools.wraps(f)
    def wrapper(*args, T=None, weight_direction=(0.0, 0.0, -1.0), config=None, reference="straight", **kwargs):
        ctx = click.get_current_context()
        ctx.meta["rodcont.T"] = T
        ctx.meta["rodcont.weight_direction"] = weight_direction
        ctx.meta["rodcont.reference"] = reference
        echo_config(ctx)
        return f(*args, **kwargs)

    opts = [
        click.option("--config", type=click.Path(dir_okay=False), default=None, is_eager=True,
                     callback=_load_config, expose_value=True,
                     help="TOML file holding the problem ([rod], [loads], [mesh], [trace]); options override it"),
        click.option("--T", "T", type=float, default=None, callback=check_number("--T"),
                     help="the tension itself (instead of --gamma; also with --w 0)"),
        click.option("--N", "N", type=click.IntRange(1, 20000), default=15, show_default=True,
                     help="number of subintervals of the (first) mesh"),
        click.option("--k", "k", type=click.IntRange(1, 7), default=5, show_default=True,
                     help="Gauss collocation points per subinterval"),
        click.option("--w", "w", type=float, default=10.0, show_default=True,
                     callback=check_number("--w", nonnegative=True),
                     help="weight per unit unstressed length (>= 0)"),
        click.option("--weight-direction", default=None, callback=_weight_direction,
                     help="direction of the weight X,Y,Z [default: 0,0,-1]; the span runs along e1"),
        click.option("--reference", default="straight", show_default=True,
                     help="reference curve KIND[:ARGS]: straight, bump:H,THETA, wiggle:H2,H3, arc:ANGLE[,THETA], "
                          "helix:RADIUS,TURNS, well:FILE (the rod is described as a perturbation of it)"),
        click.option("--EI", "EI", type=float, default=1.0, show_default=True,
                     callback=check_number("--EI", positive=True),
                     help="bending stiffness"),
        click.option("--GJ", "GJ", type=float, default=0.75, show_default=True,
                     callback=check_number("--GJ", positive=True),
                     help="torsional stiffness"),
        click.option("--EA", "EA", type=float, default=255.0, show_default=True,
                     callback=check_number("--EA", positive=True),
                     help="axial stiffness"),
        click.option("--L", "L", type=float, default=1.0, show_default=True,
                     callback=check_number("--L", positive=True),
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


def echo_config(ctx) -> None:
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
            if name != "phi" and name not in explicit("N"):
                params.pop(name, None)
        for sources in OPTION_SOURCES.values():
            for name in sources:
                if not explicit(name):
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
        click.option("--phi-max", type=float, default=40.0, show_default=True, callback=check_number("--phi-max")),
        click.option("--phi-min", type=float, default=-1.0, show_default=True, callback=check_number("--phi-min")),
        click.option("--stretch-max", type=float, default=None, callback=check_number("--stretch-max"),
                     help="stop when the stretch reaches this value"),
        click.option("--max-steps", type=click.IntRange(1, 10**7), default=2000, show_default=True),
        click.option("--ds", type=float, default=0.1, show_default=True, callback=check_number("--ds", positive=True),
                     help="first pseudo-arclength step"),
        click.option("--ds-max", type=float, default=0.5, show_default=True,
                     callback=check_number("--ds-max", positive=True)),
        click.option("--ds-min", type=float, default=1e-6, show_default=True,
                     callback=check_number("--ds-min", positive=True),
                     help="the trace stops when the step must shrink below this"),
        click.option("--min-alignment", type=float, default=0.05, show_default=True,
                     callback=check_number("--min-alignment"),
                     help="validity guard: stop where min d3.K3 falls to this (in [0, 1))"),
        click.option("--max-error", type=float, default=1e-6, show_default=True,
                     callback=check_number("--max-error", positive=True),
                     help="accuracy guard: the estimated error of the outputs and centreline (relative)"),
        click.option("--max-defect", type=float, default=None, callback=check_number("--max-defect", positive=True),
                     hidden=True, help="old name of --max-error"),
        click.option("--fold-error", type=float, default=1e-9, show_default=True,
                     callback=check_number("--fold-error", positive=True),
                     help="a fold with a larger estimated error is located again on a refined mesh"),
        click.option("--forced", type=float, multiple=True, callback=check_number("--forced"),
                     help="a Phi value that gets a point of its own (repeatable)"),
        click.option("--uniform", is_flag=True, help="keep the first mesh (no adaptation)"),
        click.option("--N-max", "N_max", type=click.IntRange(1, 20000), default=400, show_default=True,
                     help="largest number of subintervals the adaptive mesh may use"),
        click.option("--store-every", type=click.IntRange(1, 10**6), default=1, show_default=True,
                     help="keep the solution of every M-th point (and of special points and the last), in the file and "
                          "in memory: smaller files, less memory on long traces"),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def trace_kwargs(phi_max, phi_min, stretch_max, max_steps, ds, ds_max, ds_min, min_alignment, max_error,
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


def rod_changes() -> dict:
    """The rod and tension values given on the command line (a restart refuses those that differ)."""
    ctx = click.get_current_context()
    given = {n: ctx.params[n] for n in explicit("gamma", "w", "EI", "GJ", "EA", "L") if n in ctx.params}
    if ctx.meta.get("rodcont.T") is not None:
        given["T"] = ctx.meta["rodcont.T"]
    if explicit("weight_direction"):
        given["weight_direction"] = ctx.meta.get("rodcont.weight_direction")
    return given


# trace options (TraceOptions fields) and the command-line options that set them
OPTION_SOURCES = {"phi_max": ("phi_max",), "phi_min": ("phi_min",), "stretch_max": ("stretch_max",),
                   "max_steps": ("max_steps",), "ds": ("ds",), "ds_max": ("ds_max",), "ds_min": ("ds_min",),
                   "min_alignment": ("min_alignment",), "max_error": ("max_error", "max_defect"),
                   "fold_error": ("fold_error",), "forced": ("forced",), "adapt": ("uniform",),
                   "N_max": ("N_max",), "p_range": ("prange",), "store_every": ("store_every",)}


def given_options(kw) -> dict:
    """The trace options given on the command line or in --config (the rest a restart takes from its file)."""
    return {name: kw[name] for name, sources in OPTION_SOURCES.items() if name in kw and explicit(*sources)}


class GreedyFloats(click.Option):
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
