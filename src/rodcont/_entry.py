"""The console script's entry: interrupts are clean from the first instant.

Until the command line is parsed, Ctrl-C or SIGTERM end the process with one
line and status 130/143 (no traceback from inside an import); then the
command's own handling takes over (a trace stops between two points).
"""

import signal
import sys


def _early(signum, frame):
    sys.stderr.write("rodcont: interrupted\n")
    sys.exit(143 if signum == signal.SIGTERM else 130)


def main(argv=None):
    signal.signal(signal.SIGINT, _early)
    signal.signal(signal.SIGTERM, _early)
    from .cli import main as cli_main
    signal.signal(signal.SIGINT, signal.default_int_handler)
    cli_main(argv)
