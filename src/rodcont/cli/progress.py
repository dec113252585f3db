"""Interrupts taken between two points of a trace, and the progress line on stderr."""

from __future__ import annotations

import signal
import sys
import time

import click


class Interrupts:
    """While active, SIGINT and SIGTERM set a flag that the point callback turns into
    ``KeyboardInterrupt`` (after the point is stored); a second one interrupts at once."""

    def __init__(self):
        self.signum = None

    def __enter__(self):
        self.previous = {s: signal.signal(s, self._handler) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _handler(self, signum, frame):
        if self.signum is not None:
            raise KeyboardInterrupt
        self.signum = signum

    def check(self):
        if self.signum is not None:
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        for s, h in self.previous.items():
            signal.signal(s, h)
        return False

    @property
    def exit_code(self) -> int:
        return 143 if self.signum == signal.SIGTERM else 130


class Progress:
    """One status line on a terminal (rewritten in place), a line every few seconds otherwise."""

    def __init__(self, quiet: bool, interrupts: Interrupts | None = None, param: str = "phi_L"):
        self.quiet = quiet
        self.name = "Phi" if param == "phi_L" else param  # the continued parameter, by its name
        self.tty = sys.stderr.isatty()
        self.last = 0.0
        self.n = 0
        self.t0 = time.perf_counter()
        self.folds = 0
        self.interrupts = interrupts

    def __call__(self, pt):
        self.n += 1
        if str(pt.kind) == "fold":
            self.folds += 1
        if not self.quiet:
            now = time.perf_counter()
            d = pt.data
            lead = "" if self.name == "Phi" else f"{self.name} {pt.p:9.5g}  "
            msg = (f"point {self.n:5d}  {lead}Phi {d['phi_L']:9.5f}  stretch {d['stretch']:10.6f}  "
                   f"waves {d['helical_waves']}  min d3.K3 {d['min_alignment']:.3f}  folds {self.folds}  "
                   f"{now - self.t0:6.1f} s")
            if str(pt.kind) not in ("regular", "start"):
                at = f"Phi = {d['phi_L']:.10f}" if self.name == "Phi" else f"{self.name} = {pt.p:.10g}"
                click.echo(("\r" if self.tty else "") + f"  {str(pt.kind)[:60]:<14s} at {at}, "
                           f"stretch = {d['stretch']:.10f}" + " " * 20, err=True)
            if self.tty:
                click.echo("\r" + msg, nl=False, err=True)
            elif now - self.last > 5.0:
                click.echo(msg, err=True)
                self.last = now
        if self.interrupts is not None:
            self.interrupts.check()

    def idle(self):
        """Called while worker processes trace (no point to show): an interrupt is taken at once."""
        if self.interrupts is not None:
            self.interrupts.check()

    def done(self):
        if self.tty and not self.quiet:
            click.echo("", err=True)
