"""Thin entry: ``python cli.py ...`` does what the ``rodcont`` console script does."""
import signal
import sys


def _early(signum, frame):  # an interrupt before the command line is read: one line, no traceback
    sys.stderr.write("rodcont: interrupted\n")
    sys.exit(143 if signum == signal.SIGTERM else 130)


signal.signal(signal.SIGINT, _early)
signal.signal(signal.SIGTERM, _early)

import os  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "src"))

from rodcont._entry import main  # noqa: E402

if __name__ == "__main__":
    main()
