"""The ``rodcont`` command line: solve, trace, critical, diagram, folds, plot, shape, fold-curve, sweep, export,
animate, broomstick.

Every error a user can cause (bad numbers, missing, foreign or damaged files,
an output that exists or is an input, no convergence) ends in one line on
stderr and exit status 2; no traceback (``--debug`` shows one), no half-written
output file, no input changed. Ctrl-C and SIGTERM end a trace between two
points with every point on disk (exit 130 / 143). Only what a command needs is
imported: ``rodcont --version`` costs no numpy.

One module per command family (:mod:`.solve`, :mod:`.trace`, :mod:`.diagram`, :mod:`.plots`, :mod:`.export`,
:mod:`.sweep`, :mod:`.drilling`: ``solve --string`` and ``broomstick``); :mod:`.app` holds the group and
:func:`main`; :mod:`.common`, :mod:`.options`, :mod:`.trace_options`, :mod:`.config`, :mod:`.progress` and
:mod:`.tables` what they share.
"""

from . import diagram, plots, solve, sweep, trace  # noqa: F401 - each registers its commands on main_group
from .app import main, main_group
from .common import UserError
from .drilling import register as _register_drilling
from .export import animate_cmd, export_cmd

main_group.add_command(export_cmd)
main_group.add_command(animate_cmd)
_register_drilling(main_group)

__all__ = ["UserError", "main", "main_group"]
