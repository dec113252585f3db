"""The knobs of a trace, each named once: its default, its help text and its declared constraint.

:class:`TraceOptions` is what every trace runs with; the command line builds its trace options
(``--phi-max``, ``--ds``, ...: name, default, help and check) from these fields, so a default or a check
is written here and nowhere else. No numpy at import: ``rodcont --version`` and ``--help`` do not load it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields

__all__ = ["Bound", "TraceOptions", "knob", "trace_relations"]


@dataclass(frozen=True)
class Bound:
    """A number knob's constraint: finite; ``> 0`` with ``positive``; in ``[lo, hi]`` (``[lo, hi)`` with
    ``open_hi``; ``>= lo`` without ``hi``); a whole number with ``integer``."""

    positive: bool = False
    integer: bool = False
    lo: float | None = None
    hi: float | None = None
    open_hi: bool = False

    def problem(self, v: float) -> str | None:
        """What is wrong with the number ``v``, worded to follow its name (None: nothing)."""
        if not math.isfinite(v):
            return f"must be a finite number, got {v}"
        if self.positive and not v > 0:
            return f"must be positive, got {v:g}"
        lo, hi = self.lo, self.hi
        if hi is None:
            return None if lo is None or v >= lo else f"must be >= {lo:g}, got {v:g}"
        if (lo is not None and not v >= lo) or not (v < hi if self.open_hi else v <= hi):
            return f"must be in [{lo:g}, {hi:g}{')' if self.open_hi else ']'}, got {v:g}"
        return None

    def check(self, name: str, value):
        """``value`` as a float (an int with ``integer``); a TypeError or ValueError naming ``name``."""
        from .system import check_number  # the API's type checks (numpy scalars accepted)
        v = check_number(name, value, integer=self.integer)
        said = self.problem(v)
        if said:
            raise ValueError(f"{name} {said}")
        return v


def knob(default, help: str | None = None, bound: Bound | None = None, *, option: bool = True,
         flag: str | None = None, multiple: bool = False):
    """A field of a settings dataclass with what the command line needs: its ``help``, its ``bound``,
    whether it is a shared option (``option``), the switch that turns it off (``flag``, e.g.
    ``--uniform`` for ``adapt``) and whether it is a list of numbers (``multiple``)."""
    return field(default=default, metadata=dict(help=help, bound=bound, option=option, flag=flag,
                                                multiple=multiple))


def trace_relations(values: dict, label: Callable[[str], str] = str) -> None:
    """The relations between the knobs (each one's own constraint is its :class:`Bound`):
    ``phi_min < phi_max`` and ``ds_min <= ds <= ds_max``; a ValueError names them by ``label(name)``."""
    ds_min, ds, ds_max = values["ds_min"], values["ds"], values["ds_max"]
    if not ds_min <= ds <= ds_max:
        raise ValueError(f"need {label('ds_min')} <= {label('ds')} <= {label('ds_max')}, got {ds_min:g}, {ds:g}, "
                         f"{ds_max:g}")
    if not values["phi_min"] < values["phi_max"]:
        raise ValueError(f"{label('phi_min')} must be below {label('phi_max')}")


@dataclass
class TraceOptions:
    """Every knob of a trace, named once, with its default; checked when made.

    ``max_error``: the accuracy guard, on the estimated error of the stored
    outputs and centreline (relative; :class:`rodcont.mesh.ErrorEstimator`).
    ``adapt``: rebuild the mesh when the error passes ``max_error / 100``
    (up to ``N_max`` subintervals); ``False`` keeps the first mesh.
    ``p_range``: bounds of the continued parameter when it is not ``phi_L``.
    ``fold_error``: a fold whose estimated error is larger is located again on
    a mesh refined for it (with ``adapt``).
    """

    phi_max: float = knob(40.0, None, Bound())
    phi_min: float = knob(-1.0, None, Bound())
    stretch_max: float | None = knob(None, "stop when the stretch reaches this value", Bound())
    max_steps: int = knob(2000, None, Bound(integer=True, lo=1, hi=10**7))
    ds: float = knob(0.1, "first pseudo-arclength step", Bound(positive=True))
    ds_max: float = knob(0.5, None, Bound(positive=True))
    ds_min: float = knob(1e-6, "the trace stops when the step must shrink below this", Bound(positive=True))
    min_alignment: float = knob(0.05, "validity guard: stop where min d3.K3 falls to this (in [0, 1))",
                                Bound(lo=0.0, hi=1.0, open_hi=True))
    max_error: float = knob(1e-6, "accuracy guard: the estimated error of the outputs and centreline (relative)",
                            Bound(positive=True))
    fold_error: float = knob(1e-9, "a fold with a larger estimated error is located again on a refined mesh",
                             Bound(positive=True))
    forced: Sequence[float] = knob((), "a Phi value that gets a point of its own (repeatable)", Bound(),
                                   multiple=True)
    adapt: bool = knob(True, "keep the first mesh (no adaptation)", flag="--uniform")
    N_max: int = knob(400, "largest number of subintervals the adaptive mesh may use",
                      Bound(integer=True, lo=1, hi=20000))
    p_range: tuple | None = knob(None, option=False)
    direction: int = knob(1, option=False)

    def __post_init__(self):
        import numpy as np
        for f in fields(self):
            bound, v = f.metadata.get("bound"), getattr(self, f.name)
            if bound is None or v is None:
                continue
            if f.metadata.get("multiple"):
                if not isinstance(v, (list, tuple, np.ndarray)):
                    raise TypeError(f"{f.name} must be a sequence of numbers, got {v!r}")
                setattr(self, f.name, tuple(bound.check(f.name, u) for u in v))
            else:
                setattr(self, f.name, bound.check(f.name, v))
        from .system import check_number
        self.direction = check_number("direction", self.direction, integer=True)
        if self.direction not in (1, -1):
            raise ValueError("direction must be +1 or -1")
        if not isinstance(self.adapt, (bool, np.bool_)):
            raise TypeError(f"adapt must be True or False, got {self.adapt!r}")
        if self.p_range is not None:
            if not isinstance(self.p_range, (list, tuple)) or len(self.p_range) != 2:
                raise TypeError(f"p_range must be a pair (lo, hi), got {self.p_range!r}")
            lo, hi = (check_number("range", v) for v in self.p_range)
            if not lo < hi:
                raise ValueError(f"the range must be given as A B with A < B, got {lo:g} {hi:g}")
            self.p_range = (lo, hi)
        trace_relations(asdict(self))

    def as_dict(self) -> dict:
        return asdict(self)

    def continuation_settings(self, param: str):
        """The tracker's settings: steps, the parameter's bounds (``phi_min, phi_max`` or ``p_range``)."""
        from .continuation import ContinuationSettings
        if param == "phi_L":
            p_min, p_max = self.phi_min, self.phi_max
        elif self.p_range is not None:
            p_min, p_max = self.p_range
        else:
            from .drivers.trace import TraceError
            raise TraceError(f"a trace in {param} needs its range (p_range / --range A B)")
        return ContinuationSettings(ds=self.ds, ds_min=self.ds_min, ds_max=self.ds_max, p_min=p_min, p_max=p_max,
                                    max_steps=self.max_steps, direction=self.direction, forced=tuple(self.forced))

    def adaptive_settings(self):
        """The adaptive loop's settings (its other limits at their defaults)."""
        from .adaptive import AdaptiveSettings
        return AdaptiveSettings(max_error=self.max_error, fold_error=self.fold_error, adapt=self.adapt,
                                N_max=self.N_max)

    def events(self) -> list:
        """The rod's guards: validity (the Eulerian description ends), a stretch factor through 0, and
        ``stretch_max``; each stops the trace with its status."""
        from .continuation import Event
        from .result import Status
        o = self
        events = [Event(f"validity guard: min d3.K3 reached min_alignment = {o.min_alignment:g} (the rod is about "
                        f"to fold back over the reference curve: the Eulerian description ends)",
                        lambda q: q.data["min_alignment"] - o.min_alignment, stop=True, tol=1e-6,
                        label="validity_guard", status=Status.VALIDITY_GUARD),
                  Event("the stretch factor reached 0 (compressed through zero length: not physical)",
                        lambda q: q.data["alpha_min"], stop=True, tol=1e-6, label="stretch_factor_zero",
                        status=Status.VALIDITY_GUARD)]
        if o.stretch_max is not None:
            events.append(Event(f"stretch_max = {o.stretch_max:g} reached",
                                lambda q: o.stretch_max - q.data["stretch"], stop=True, label="stretch_max"))
        return events
