"""rodcont: equilibrium branches, folds and bifurcations of elastic rods.

Eulerian extensible Cosserat rod (Huynen, Detournay & Denoël), B-spline
collocation at Gauss points, Keller pseudo-arclength continuation.

    >>> import rodcont
    >>> eq = rodcont.solve(gamma=1.0, phi_L=10.0)        # one equilibrium
    >>> br = rodcont.trace(gamma=1.0, out="g1.h5")       # a branch, with its folds
    >>> data = rodcont.load_branch("g1.h5")              # read it back: the same type as br
    >>> br.status, br.stop_reason, br.folds[0]["phi_L"]  # why it ended; its first fold
    >>> sol = rodcont.bvp.solve(problem, {"lam": 0.0})       # your own BVProblem, solved
    >>> res = rodcont.continue_bvp(problem, "lam", sol, (0, 4))  # and continued, with its folds

``rodcont.continuation`` is the tracker's module (``rodcont.continuation.Tracker``) and, called, its
function ``continuation(problem, x0, p0, settings)``: one object, whatever is imported first.

Names are imported on first use, so ``import rodcont`` (and the command
line) costs only what is used.
"""

__version__ = "0.2.0"


def _interrupted(signum, frame):  # an interrupt before the command line is read: one line, no traceback
    import signal
    import sys
    sys.stderr.write("rodcont: interrupted\n")
    sys.exit(143 if signum == signal.SIGTERM else 130)


def _as_command() -> bool:
    """Whether this import starts the command line: the console script (``argv[0]`` is ``.../rodcont``) or
    ``python -m rodcont`` (``argv[0]`` is ``-m`` while the package is imported to find its ``__main__``)."""
    import os
    import sys
    argv0 = sys.argv[0] if sys.argv else ""
    return argv0 == "-m" or os.path.basename(argv0) in ("rodcont", "rodcont.exe", "rodcont-script.py")


if _as_command():  # the earliest line of rodcont a command runs: from here an interrupt is clean (_entry.main)
    import signal as _signal
    _signal.signal(_signal.SIGINT, _interrupted)
    _signal.signal(_signal.SIGTERM, _interrupted)
    del _signal
    from .blas import command_environment as _blas_env  # before numpy loads OpenBLAS: one thread, none spinning
    _blas_env()
    del _blas_env

_API = {
    "RodParameters": "rod", "EulerianRod": "rod", "StraightReference": "rod", "ReferenceCurve": "rod",
    "BVProblem": "collocation", "Collocation": "collocation", "NewtonResult": "linalg",
    "ContinuationSettings": "continuation", "Tracker": "continuation", "Point": "continuation",
    "Event": "continuation", "continuation": ("continuation", None),  # the module, callable as its function
    "ContinuationResult": "result", "Status": "result", "SpecialPoint": "result", "Table": "result",
    "AdaptiveContinuation": "adaptive", "AdaptiveSettings": "adaptive", "adaptive_continuation": "adaptive",
    "solve": ("drivers.solve", "solve_equilibrium"), "Equilibrium": "drivers.solve",
    "ConvergenceError": "drivers.solve",
    "trace": "drivers.trace", "TraceOptions": "drivers.trace", "Branch": "branch", "RodSystem": "system",
    "fold_curve": "drivers.foldcurve", "critical_twists": "drivers.diagram", "diagram": "drivers.diagram",
    "deflate": "drivers.diagram", "sweep": "drivers.sweep",
    "load_branch": "branchfile", "load_diagram": "branchfile", "BranchFileError": "branchfile",
    "bvp": ("bvp", None), "continue_bvp": "bvp", "BVPResult": "bvp",
}

__all__ = sorted(_API)


def __getattr__(name):
    target = _API.get(name)
    if target is None:
        raise AttributeError(f"module 'rodcont' has no attribute {name!r}")
    module, attr = target if isinstance(target, tuple) else (target, name)
    import importlib
    value = importlib.import_module(f".{module}", __name__)
    value = value if attr is None else getattr(value, attr)  # None: the module itself (rodcont.bvp)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + __all__)
