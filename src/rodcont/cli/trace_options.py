"""The trace options (trace, diagram, sweep), made from the fields of :class:`rodcont.settings.TraceOptions`:
each option's name, default, help and check are the field's, so each is written once (there)."""

from __future__ import annotations

from dataclasses import fields

import click

from ..settings import TraceOptions, trace_relations
from .common import UserError, explicit


def option_name(field_name: str) -> str:
    """``--phi-max`` for the field ``phi_max`` (``--N-max`` for ``N_max``)."""
    return "--" + field_name.replace("_", "-")


def _shared_fields():
    """The TraceOptions fields that are options of every traced command, in their order."""
    return [f for f in fields(TraceOptions) if f.metadata.get("option", True)]


def _dest(f) -> str:
    """The command's parameter a field's option sets (its name; ``uniform`` for ``adapt``)."""
    return f.metadata["flag"].lstrip("-") if f.metadata.get("flag") else f.name


def _bound_callback(name, bound):
    """A click callback refusing what ``bound`` refuses (each value of a repeated option)."""
    def check(ctx, param, value):
        for v in (value if isinstance(value, tuple) else () if value is None else (value,)):
            said = bound.problem(v)
            if said:
                raise click.BadParameter(said, param_hint=name)
        return value
    return check


def _option(f):
    """The click option of a TraceOptions field: a switch for a field with ``flag``, an integer range for a
    count, a (repeatable) checked number otherwise."""
    help_, bound = f.metadata.get("help"), f.metadata.get("bound")
    if f.metadata.get("flag"):
        return click.option(f.metadata["flag"], _dest(f), is_flag=True, help=help_)
    name = option_name(f.name)
    if bound.integer:
        return click.option(name, f.name, type=click.IntRange(bound.lo, bound.hi), default=f.default,
                            show_default=True, help=help_)
    if f.metadata.get("multiple"):
        return click.option(name, f.name, type=float, multiple=True, callback=_bound_callback(name, bound),
                            help=help_)
    return click.option(name, f.name, type=float, default=f.default, show_default=f.default is not None,
                        callback=_bound_callback(name, bound), help=help_)


def trace_options(f):
    """Options of every traced branch (trace, diagram, sweep): the TraceOptions fields, the old name
    ``--max-defect`` of ``--max-error`` and ``--store-every`` (a recorder's, not a trace's, setting)."""
    max_error = next(x for x in fields(TraceOptions) if x.name == "max_error")
    opts = [_option(x) for x in _shared_fields()] + [
        click.option("--max-defect", type=float, default=None, hidden=True, help="old name of --max-error",
                     callback=_bound_callback("--max-defect", max_error.metadata["bound"])),
        click.option("--store-every", type=click.IntRange(1, 10**6), default=1, show_default=True,
                     help="keep the solution of every M-th point (and of special points and the last), in the file and "
                          "in memory: smaller files, less memory on long traces"),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def trace_kwargs(a) -> dict:
    """The TraceOptions fields set by the trace options of the command's parameters ``a`` (and its
    ``store_every``); their relations checked (:func:`rodcont.settings.trace_relations`)."""
    values = {x.name: getattr(a, _dest(x)) for x in _shared_fields()}
    values["adapt"] = not a.uniform
    values["forced"] = tuple(values["forced"])
    if a.max_defect is not None:
        values["max_error"] = a.max_defect
    ctx = click.get_current_context()
    if values["ds"] > values["ds_max"] and ctx.get_parameter_source("ds") == click.core.ParameterSource.DEFAULT:
        values["ds"] = values["ds_max"]  # only --ds-max was given: start at it
    try:
        trace_relations(values, option_name)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    values["store_every"] = a.store_every
    return values


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
OPTION_SOURCES = {**{x.name: (_dest(x),) for x in _shared_fields()}, "max_error": ("max_error", "max_defect"),
                  "p_range": ("prange",), "store_every": ("store_every",)}


def given_options(kw) -> dict:
    """The trace options given on the command line or in --config (the rest a restart takes from its file)."""
    return {name: kw[name] for name, sources in OPTION_SOURCES.items() if name in kw and explicit(*sources)}
