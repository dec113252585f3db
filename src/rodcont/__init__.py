"""rodcont: equilibrium branches, folds and bifurcations of elastic rods.

Eulerian extensible Cosserat rod (Huynen, Detournay & Denoël), B-spline
collocation at Gauss points, Keller pseudo-arclength continuation.

    >>> import rodcont
    >>> eq = rodcont.solve(gamma=1.0, phi_L=10.0)        # one equilibrium
    >>> br = rodcont.trace(gamma=1.0, out="g1.h5")       # a branch, with its folds
    >>> data = rodcont.load_branch("g1.h5")              # read a branch file
"""

__version__ = "0.1.0"

from .rod import RodParameters, EulerianRod, StraightReference, ReferenceCurve  # noqa: E402
from .collocation import BVProblem, Collocation, NewtonResult  # noqa: E402
from .continuation import ContinuationSettings, Tracker, Point, Event, continuation  # noqa: E402
from .branch import solve_equilibrium as solve, trace, Branch, Equilibrium, RodSystem, ConvergenceError  # noqa: E402
from .branchfile import load_branch, BranchFileError  # noqa: E402

__all__ = [
    "RodParameters", "EulerianRod", "StraightReference", "ReferenceCurve", "BVProblem", "Collocation",
    "NewtonResult", "ContinuationSettings", "Tracker", "Point", "Event", "continuation", "solve", "trace",
    "Branch", "Equilibrium", "RodSystem", "ConvergenceError", "load_branch", "BranchFileError",
]
