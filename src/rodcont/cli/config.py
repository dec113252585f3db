"""``--config FILE.toml`` read into a command's defaults, and the problem as run echoed in the same form
(TOML comment lines on stdout; branch files store it)."""

from __future__ import annotations

import click

from .common import explicit
from .drilling import DRILLING_KEYS
from .trace_options import OPTION_SOURCES

# --config FILE.toml: sections and the options their keys set (any trace option goes in [trace])
CONFIG_SECTIONS = {"rod": ("EI", "GJ", "EA", "w", "L", "weight_direction", "reference"),
                   "loads": ("gamma", "T", "phi", "torque", "l0"),
                   "mesh": ("N", "k", "N_max", "uniform"), "drilling": DRILLING_KEYS}


def load_config(ctx, param, value):
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
            raise click.BadParameter(f"{value}: unknown section [{section}] (sections: rod, loads, mesh, trace, "
                                     f"drilling)", param_hint="--config")
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


_CONFIG_SKIP = {"config", "quiet", "out", "out_dir", "overwrite", "start", "output", "points", "files", "file",
                "spec", "debug", "max_defect", "resume_file", "extend"}


def config_toml(params: dict) -> str:
    """The effective problem as a TOML document (what ``--config`` reads back)."""
    rows = {section: [] for section in CONFIG_SECTIONS} | {"trace": []}
    for name, v in params.items():
        trip_points = name == "points" and isinstance(v, int)  # a trip's count, not shape's --point list
        if (name in _CONFIG_SKIP and not trip_points) or v is None or v == ():
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
    _drop_drilling_or_rod(params)
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
        if params.get("resume_file"):  # it goes on in the file's parameter, direction and branch (a trip's too)
            for name in ("param", "direction", "switch"):
                if not explicit(name):
                    params.pop(name, None)
    text = config_toml(params)
    ctx.meta["rodcont.config"] = text
    src = ctx.meta.get("rodcont.config_file")
    click.echo(f"# rodcont {ctx.info_name}" + (f" (--config {src})" if src else "") + ": the problem as run")
    if start is not None:
        if params.get("start"):
            click.echo(f"#   (the rod, its loads, reference curve, conduit, mesh and the trace options not given "
                       f"are those of --start {start})")
        else:  # a trace's or a trip's (its well, string, operation and range): the file says which
            click.echo(f"#   (the problem and every option not given here are those of --resume {start})")
    for line in text.splitlines():
        click.echo(f"#   {line}")


# what a trip (trace --string ... --param depth) reads besides the drill-string options
TRIP_KEYS = ("conduit", "param", "prange", "points")


def _drop_drilling_or_rod(params: dict) -> None:
    """``solve`` without --string runs no drill string (its options are not echoed); with --string, the
    string's files and operation are the problem, not the rod, its loads and its mesh; a trip (``trace``) takes
    none of the rod's trace options, nor a depth (its range is the depth); weight and torque on bit only drilling."""
    if "string" not in params:
        return
    if params["string"] is None:
        for name in DRILLING_KEYS:
            params.pop(name, None)
        return
    trip = "prange" in params
    keep = set(DRILLING_KEYS) - {"depth", "joints"} | set(TRIP_KEYS) if trip else None
    rod = CONFIG_SECTIONS["rod"] + CONFIG_SECTIONS["loads"] + CONFIG_SECTIONS["mesh"] + ("load_step", "max_error")
    if not trip:  # solve --string reads its guard and cap, and a --N or --k given (run_drilling_solve)
        from .common import explicit
        rod = tuple(n for n in rod if n not in {"max_error", "N_max", *explicit("N", "k")})
    for name in list(params):
        if (keep is not None and name not in keep and name not in _CONFIG_SKIP) or name in rod:
            params.pop(name, None)
    op = params.get("operation") or ("slack-off" if trip else None)
    for name in ("wob", "bit_torque"):
        if op != "drill" and not params.get(name):
            params.pop(name, None)
