"""Thin entry: ``python cli.py ...`` does what the ``rodcont`` console script does."""
try:  # from the first line: an interrupt before the command line is read is one line, no traceback
    import signal
    import sys

    def _early(signum, frame):
        sys.stderr.write("rodcont: interrupted\n")
        sys.exit(143 if signum == signal.SIGTERM else 130)

    signal.signal(signal.SIGINT, _early)
    signal.signal(signal.SIGTERM, _early)

    import os

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "src"))

    from rodcont._entry import main
except KeyboardInterrupt:  # before the handler above was installed (during the import of signal)
    import sys
    sys.stderr.write("rodcont: interrupted\n")
    sys.exit(130)

if __name__ == "__main__":
    main()
