"""A ``sitecustomize`` that sends SIGINT to its process as the import of module ``$RODCONT_SIGINT_AT``
begins (once): an interrupt at an event, not a moment on the clock. Used by tests/test_startup_interrupt.py and
benchmarks/fuzz_cli.py (signal:startup-event probes)."""

HOOK = '''import os, signal, sys
_AT = os.environ.get("RODCONT_SIGINT_AT")


class _InterruptAt:
    """Sends SIGINT to this process as the import of module _AT begins (once)."""

    def find_spec(self, name, path=None, target=None):
        global _AT
        if _AT and name == _AT:
            _AT = None
            os.kill(os.getpid(), signal.SIGINT)
        return None


sys.meta_path.insert(0, _InterruptAt())
'''
