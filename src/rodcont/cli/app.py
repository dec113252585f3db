"""The ``rodcont`` click group and :func:`main`: one-line errors, exit status 2, clean interrupts."""

from __future__ import annotations

import os
import sys

import click

from .common import EXIT_USAGE, NUMPY_NOISE, PENDING, echo_err, flush_pending, show_warning


@click.group(context_settings=dict(help_option_names=["-h", "--help"]))
@click.version_option(package_name="rodcont", message="%(prog)s %(version)s")
@click.option("--debug", is_flag=True, help="show tracebacks of unexpected failures")
@click.pass_context
def main_group(ctx, debug):
    """Equilibrium branches, folds and bifurcations of the twisted heavy rod (Eulerian Cosserat rod)."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


def main(argv=None):
    """Entry point: click's parsing with one-line errors and exit status 2; the library's warnings said as
    ``rodcont: warning: ...`` lines once the command has ended (numpy's floating-point noise not)."""
    import warnings
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=NUMPY_NOISE, category=RuntimeWarning)
        warnings.showwarning = show_warning
        _main(argv)


def _main(argv):
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    PENDING.clear()
    try:
        rv = main_group.main(args=argv, prog_name="rodcont", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except SystemExit as exc:
        if exc.code in (0, None, 130, 143):  # an ending, not an error: what it read is said now
            flush_pending()
        # click turns a write to a closed pipe (`rodcont ... | head`) into exit 1: the reader went
        # away, not an error of ours
        if exc.code == 1 and type(sys.stdout).__name__.endswith("PacifyFlushWrapper"):  # click >= 8.2: _Pacify...
            _quiet_stdout()
            sys.exit(0)
        raise
    except click.ClickException as exc:
        msg = exc.format_message() if not isinstance(exc, click.UsageError) else _usage_message(exc)
        echo_err(f"rodcont: error: {' '.join(msg.split())}")
        sys.exit(EXIT_USAGE)
    except (click.exceptions.Abort, KeyboardInterrupt):
        echo_err("rodcont: interrupted")
        sys.exit(130)
    except BrokenPipeError:
        _quiet_stdout()
        sys.exit(0)
    except Exception as exc:  # a bug, or the machine (memory, disk): one line, and say which
        if debug:
            raise
        from ..branchfile import BranchFileError
        from ..safeio import InputFileError, OutputFileError
        if isinstance(exc, (BranchFileError, InputFileError, OutputFileError)):
            echo_err(f"rodcont: error: {exc}")
            sys.exit(EXIT_USAGE)
        from ..linalg import is_out_of_memory
        if is_out_of_memory(exc):  # the size asked for, not a bug: refused as bad input is
            echo_err("rodcont: error: out of memory" + (f" ({' '.join(str(exc).split())})" if str(exc) else "")
                     + ": ask for a smaller problem (--N, --N-max, a looser --max-error)")
            sys.exit(EXIT_USAGE)
        if isinstance(exc, OSError):
            echo_err(f"rodcont: error: {type(exc).__name__}: {' '.join(str(exc).split())}")
            sys.exit(1)
        echo_err(f"rodcont: error: unexpected failure ({type(exc).__name__}: {' '.join(str(exc).split())}); "
             f"please report it with the command line (--debug shows the traceback)")
        sys.exit(1)
    flush_pending()
    sys.exit(rv if isinstance(rv, int) else 0)


def _quiet_stdout() -> None:
    try:
        sys.stdout = open(os.devnull, "w")
    except OSError:
        pass


def _usage_message(exc: click.UsageError) -> str:
    msg = exc.format_message().replace("\n", " ")
    if exc.ctx is not None and exc.ctx.command_path:
        msg += f" (see '{exc.ctx.command_path} --help')"
    return msg
