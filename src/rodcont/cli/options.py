"""The options shared by the commands that build a rod: number checks, the rod, load and mesh options
(``--config`` among them), and the option taking several numbers (``sweep --gamma 0 0.5 1``)."""

from __future__ import annotations

import math

import click

from .config import echo_config, load_config


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
                     callback=load_config, expose_value=True,
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
