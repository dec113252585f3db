"""The console script's entry: interrupts are clean from the first instant.

Until the command line is parsed, Ctrl-C or SIGTERM end the process with one
line and status 130/143 (no traceback from inside an import); then the
command's own handling takes over (a trace stops between two points).
"""

import signal
import sys

from . import _interrupted as _early  # noqa: F401  (the handler rodcont/__init__ installs for a command)


def main(argv=None):
    signal.signal(signal.SIGINT, _early)
    signal.signal(signal.SIGTERM, _early)
    try:
        from .cli import main as cli_main
        signal.signal(signal.SIGINT, signal.default_int_handler)
        cli_main(argv)
    except KeyboardInterrupt:  # before the command's own handling began, or after it ended
        sys.stderr.write("rodcont: interrupted\n")
        sys.exit(130)
