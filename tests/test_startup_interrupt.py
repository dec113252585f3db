"""An interrupt during start-up ends rodcont quietly (exit 130, one line or none), however early it comes.

The interrupt is sent by the process to itself when it begins to import a given module (a
``sitecustomize`` import hook on ``PYTHONPATH``, installed before the main module runs): an event, not a
moment on the clock, so the test means the same on a loaded machine. The three ways in are the console
script (its generated wrapper, written here as pip writes it), ``python -m rodcont`` and ``python cli.py``.
Before any line of rodcont runs (the interpreter's own start, ``site``) the interrupt is Python's.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

from sigint_hook import HOOK

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "src")

# what pip writes for the console script ``rodcont = "rodcont._entry:main"``
CONSOLE_SCRIPT = '''# -*- coding: utf-8 -*-
import re
import sys
from rodcont._entry import main
if __name__ == '__main__':
    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])
    sys.exit(main())
'''

ARGS = ["trace", "--gamma", "1", "--N", "60", "--uniform", "--max-error", "1", "--out", "o.h5", "--quiet"]

# from the first module rodcont's own code imports to the first a command imports (the handler restored)
EVENTS = ["rodcont._entry", "click", "numpy", "scipy", "rodcont.cli.app", "h5py", "rodcont.drivers.trace"]


def _entries(tmp_path):
    script = tmp_path / "rodcont"
    script.write_text(CONSOLE_SCRIPT)
    return {"console script": [sys.executable, str(script)], "python -m rodcont": [sys.executable, "-m", "rodcont"],
            "cli.py": [sys.executable, os.path.join(ROOT, "cli.py")]}


@pytest.mark.parametrize("event", EVENTS)
def test_an_interrupt_at_any_import_of_start_up_ends_quietly(tmp_path, event):
    """SIGINT as each import of start-up begins, through each entry: exit 130, at most one line, no traceback
    (on the code before, at the import of rodcont._entry, before the handler of _entry.main, the interpreter
    printed a KeyboardInterrupt traceback: rodcont/__init__ now installs it when it starts a command)."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(HOOK)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(hook), SRC]), RODCONT_SIGINT_AT=event)
    for how, cmd in _entries(tmp_path).items():
        work = tmp_path / how.replace(" ", "_")
        work.mkdir()
        r = subprocess.run(cmd + ARGS, cwd=work, env=env, capture_output=True, text=True, timeout=300)
        assert r.returncode == 130, (how, event, r.returncode, r.stderr)
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) <= 1, (how, event, r.stderr)


def test_the_hook_interrupts_where_it_says_and_the_library_keeps_pythons_handler():
    """The hook itself: with no handler, the interrupt at an import is a KeyboardInterrupt there (a module no
    start-up can have imported already: fractions was, once, in the full suite's environment)."""
    # a parent that ignores SIGINT (as the full suite may, by then) passes SIG_IGN on: restore Python's handler
    code = (HOOK + "\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "try:\n    import _rodcont_no_such_module\nexcept KeyboardInterrupt:\n    sys.exit(7)\n")
    env = dict(os.environ, RODCONT_SIGINT_AT="_rodcont_no_such_module")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 7, r.stderr
    code = "import signal, rodcont\nassert signal.getsignal(signal.SIGINT) is signal.default_int_handler"
    r = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=SRC), capture_output=True,
                       text=True, timeout=60, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert r.returncode == 0, r.stderr
