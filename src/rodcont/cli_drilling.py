"""Moved to :mod:`rodcont.cli.drilling` (the CLI package); this name stays importable."""

from .cli.drilling import (DRILLING_KEYS, broomstick_command, drilling_options, register,  # noqa: F401
                           run_drilling_solve)
