"""Moved to :mod:`rodcont.cli.drilling` (the CLI package); this name stays importable."""

from .cli.drilling import (
                           DRILLING_KEYS,
                           broomstick_command,
                           drilling_options,
                           register,
                           run_drilling_solve,
                           run_drilling_trace,
)

__all__ = ["DRILLING_KEYS", "broomstick_command", "drilling_options", "register", "run_drilling_solve",
           "run_drilling_trace"]
