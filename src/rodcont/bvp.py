"""Your own boundary value problem: solve it, continue it, find its folds, write its branch (knows nothing of rods).

A user's problem is a :class:`rodcont.collocation.BVProblem`: fields ``u_i`` of orders ``m_i`` on
``[a, b]``, a pointwise residual ``residual(S, z, p) = 0`` on the jets ``z``, boundary conditions
``bc(za, zb, p) = 0``, optional integral conditions ``int_a^b q(S, z, p) dS = 0`` (``integrals``),
parameters ``params`` (names) of which ``free`` are unknowns. On it this module gives the rod's
machinery:

* :func:`solve`: damped Newton at fixed parameters on a mesh that adapts until the estimated error
  meets ``max_error``; returns a :class:`Solution` (``x``, ``mesh``, ``params``, ``error``,
  ``outputs``, ``evaluate(S, field, derivative)``);
* :func:`continue_bvp`: pseudo-arclength continuation in one named parameter on a mesh that adapts
  under the accuracy guard (the engine of :mod:`rodcont.adaptive`), folds and branch points
  located, returning a :class:`BVPResult` (a :class:`rodcont.result.ContinuationResult`), and
  written as it goes to a branch file (``kind = "bvp"``) that :func:`rodcont.load_branch`,
  ``rodcont folds`` and ``rodcont plot`` read.

The error estimate (:class:`rodcont.mesh.ErrorEstimator`: one Newton step in the space with one more
Gauss point per subinterval) compares, each relative to its scale ``max(|value|, floor)``:

* every field on 8 points per subinterval (``|u_fine - u|`` in the max norm over the points, divided
  by ``max(max |u|, floor)``);
* every free parameter, and every user output (``outputs``: named functions of a :class:`Solution`,
  which also become columns of the result);
* the continued parameter (relative to ``max(|p|, 1)``; at a fold, how far the fold moves).

``scales`` gives the floors by name (fields, free parameters, outputs; default 1): an error is
relative to the quantity's size where it is larger than its floor, absolute below. The default
suits quantities of order one; give a field's typical size when it is far from one.

Restarts. A file cannot store Python code: it stores the problem's name, its fields, orders,
parameters and interval, and each point's coefficients, mesh and tangent. A restart passes the
problem object again with a stored point: ``continue_bvp(problem, "lam", load_branch(path).point("F1"))``;
the structure is checked against the file (a point of another problem is refused), the outputs and
scales are given again (default: none, resp. the file's scales).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import fields

import numpy as np

from .adaptive import AdaptiveContinuation, AdaptiveSettings, ResultRecorder
from .blas import with_one_blas_thread
from .bspline import gauss_legendre
from .collocation import BVProblem, Collocation
from .continuation import ContinuationSettings, Event, Point
from .linalg import full_bordered_lu
from .mesh import ErrorEstimator, adapted_mesh, halved
from .result import ContinuationResult, Status, _Rows

__all__ = ["BVPError", "BVPResult", "BVPSystem", "Solution", "continue_bvp", "read_file", "solve"]

#: points per subinterval on which the error estimate compares the fields
FIELD_SAMPLES = 8
#: the branch file's ``kind``
FILE_KIND = "bvp"


class BVPError(RuntimeError):
    """A problem that could not be solved to the accuracy asked (the message says why, in one line)."""


# --------------------------------------------------------------------------
# The meshed problem
# --------------------------------------------------------------------------
class BVPSystem:
    """A user's :class:`BVProblem` on a mesh, as ``F(x, p) = 0`` in one parameter (the meshed problem
    protocol of :mod:`rodcont.adaptive`).

    ``param``: the continued parameter's name (None: every parameter held, as in :func:`solve`);
    ``values``: the full parameter vector (the free entries are initial values, then read from ``x``);
    ``outputs``: ``{name: f(solution) -> float}``; ``scales``: ``{name: floor}`` (module docstring).
    """

    #: the LU of the whole bordered matrix: a collocation matrix's border does not fill it (as the rod's;
    #: the three examples' CPU times are the same with block elimination)
    bordered_solver = staticmethod(full_bordered_lu)

    def __init__(self, problem: BVProblem, param: str | None, values, breakpoints, k: int = 5,
                 outputs: Mapping[str, Callable] | None = None, scales: Mapping[str, float] | None = None,
                 name: str = "problem"):
        self.problem, self.name = problem, str(name)
        self.fields = field_names(problem)
        self.free_names = [problem.params[j] for j in problem.free]
        self.param = param
        self.index = None if param is None else problem.param_index(param)
        self.base = np.array(values, float)
        self.output_functions = dict(outputs or {})
        self.scales = {k_: float(v) for k_, v in (scales or {}).items()}
        self.disc = Collocation(problem, breakpoints, k)
        self._checks = None

    # ---- parameters and the tracker's protocol --------------------------------------
    def params(self, value) -> np.ndarray:
        p = self.base.copy()
        if self.index is not None:
            p[self.index] = value
        return p

    def residual(self, x, value):
        return self.disc.residual(x, self.params(value))

    def linearise(self, x, value):
        if self.index is None:
            F, J, _ = self.disc.linearise(x, self.params(value))
            return F, J, np.zeros(F.size)
        F, J, (Fp,) = self.disc.linearise(x, self.params(value), [self.index])
        return F, J, Fp

    def tangent(self, x, value):
        return self.linearise(x, value)[1:]

    def floor(self, name: str) -> float:
        return self.scales.get(name, 1.0)

    def arclength_scale(self):
        """The fields' and free parameters' floors on their coefficients, the parameter's floor on it."""
        sx = np.ones(self.disc.size)
        for i, f in enumerate(self.fields):
            sx[self.disc.index[i]] = self.floor(f)
        for j, f in enumerate(self.free_names):
            sx[self.disc.free_index[j]] = self.floor(f)
        return sx, (self.floor(self.param) if self.param is not None else 1.0)

    # ---- the meshed problem ----------------------------------------------------------
    @property
    def breakpoints(self) -> np.ndarray:
        return self.disc.breakpoints

    @property
    def k(self) -> int:
        return self.disc.k

    def with_mesh(self, breakpoints, k: int | None = None) -> BVPSystem:
        new = BVPSystem.__new__(BVPSystem)
        new.__dict__.update(self.__dict__)
        new.base = self.base.copy()
        new.disc = Collocation(self.problem, np.asarray(breakpoints, float), self.disc.k if k is None else k)
        new._checks = None
        return new

    def transfer(self, x, source: BVPSystem) -> np.ndarray:
        return self.disc.transfer(x, source.disc)

    @property
    def fixed_parameters(self) -> np.ndarray:
        return self.base.copy()

    @fixed_parameters.setter
    def fixed_parameters(self, base) -> None:
        self.base = np.array(base, float)

    def conform(self, breakpoints) -> np.ndarray:
        """The mesh with every join of the problem a breakpoint (the nearest one moved onto it, or it added)."""
        b = np.array(breakpoints, float)
        for s in np.unique(np.asarray(self.problem.joins, float)):
            i = int(np.argmin(np.abs(b - s)))
            h = min(np.diff(b)[max(i - 1, 0):i + 1])
            if 0 < i < b.size - 1 and abs(b[i] - s) <= 0.25 * h:
                b[i] = s
            else:
                b = np.sort(np.append(b, s))
        return b

    # ---- outputs, defect, error ------------------------------------------------------------
    def solution(self, x, value=None) -> Solution:
        return Solution(self, x, value)

    def outputs(self, x, value) -> dict:
        """The result's columns: the parameter, the free parameters, the L2 norm of each field
        (``norm_<field>``, Gauss rule), the user's outputs, and the ``defect``."""
        pf = self.disc.full_params(x, self.params(value))
        out = {} if self.param is None else {self.param: float(value)}
        out.update({f: float(pf[j]) for f, j in zip(self.free_names, self.problem.free)})
        for i, f in enumerate(self.fields):
            u = self.disc.jets(x)[self.disc.jet_rows[i]]
            out[f"norm_{f}"] = math.sqrt(max(self.disc.integrate(u * u), 0.0))
        out.update(self.user_outputs(x, value))
        out["defect"] = float(np.max(self.interval_defect(x, value)))
        return out

    def user_outputs(self, x, value) -> dict:
        if not self.output_functions:
            return {}
        sol = self.solution(x, value)
        return {name: float(f(sol)) for name, f in self.output_functions.items()}

    def _check_points(self):
        """Jets at the midpoints between the Gauss points and the ends of each subinterval (built once)."""
        if self._checks is None:
            b = self.breakpoints
            nodes = np.concatenate([[-1.0], gauss_legendre(self.k)[0], [1.0]])
            mids = 0.5 * (nodes[1:] + nodes[:-1])
            S = (b[:-1, None] + 0.5 * np.diff(b)[:, None] * (mids[None, :] + 1.0)).ravel()
            self._checks = (S, self.disc.jet_matrix(S))
        return self._checks

    def interval_defect(self, x, value) -> np.ndarray:
        """The residual between collocation points, equation ``i`` relative to
        ``max(max |u_i^(m_i)|, floor_i)``, its maximum on each subinterval (``~ h^k``: where to refine)."""
        S, E = self._check_points()
        pf = self.disc.full_params(x, self.params(value))
        z = (E @ x).reshape(self.problem.jet_size, S.size)
        G = np.abs(np.asarray(self.problem.residual(S, z, pf), float).reshape(-1, S.size))
        top = self.disc.jet_rows[1:] - 1  # the highest derivative of each field
        scale = np.maximum(np.max(np.abs(z[top]), axis=1), [self.floor(f) for f in self.fields])
        G = np.minimum(np.nan_to_num(G / scale[:, None], nan=1e100), 1e100)  # an overflow: refine there most
        return G.max(axis=0).reshape(self.disc.N, -1).max(axis=1)

    def error_quantities(self, x, value):
        """The free parameters and the user's outputs, each with its scale ``max(|value|, floor)``."""
        pf = self.disc.full_params(x, self.params(value))
        vals = [float(pf[j]) for j in self.problem.free] + list(self.user_outputs(x, value).values())
        names = self.free_names + list(self.output_functions)
        return (np.asarray(vals, float), np.array([max(abs(v), self.floor(n)) for v, n in zip(vals, names)]))

    def error_fields(self):
        return [(i, 1.0) for i in range(len(self.fields))]  # scales set per solution (_Estimator)

    def error_estimator(self) -> _Estimator:
        return _Estimator(self)


class _Estimator(ErrorEstimator):
    """:class:`rodcont.mesh.ErrorEstimator` with each field compared relative to ``max(max |u_i|, floor_i)``
    of the solution estimated (the generic estimator's field scales are fixed per mesh)."""

    def __init__(self, system: BVPSystem):
        super().__init__(system, samples=FIELD_SAMPLES)
        self.floors = [system.floor(f) for f in system.fields]

    def estimate(self, x, value, tangent=None) -> float:
        self._fields = [(Ec, Ef, max(float(np.max(np.abs(Ec @ x))), floor))
                        for (Ec, Ef, _), floor in zip(self._fields, self.floors)]
        return super().estimate(x, value, tangent)


def field_names(problem: BVProblem) -> list[str]:
    names = list(problem.names) if problem.names is not None else (
        ["u"] if problem.n_fields == 1 else [f"u{i}" for i in range(problem.n_fields)])
    if len(names) != problem.n_fields or len(set(names)) != len(names):
        raise ValueError(f"names must name each of the {problem.n_fields} fields once, got {names!r}")
    return [str(n) for n in names]


# --------------------------------------------------------------------------
# Solutions
# --------------------------------------------------------------------------
class Solution:
    """A solution of a user's problem: ``x`` (coefficients, then free parameters), ``mesh``, ``k``,
    ``params`` (every parameter by name, the free ones solved for), ``error`` (the estimate),
    ``outputs`` (the result's columns), ``evaluate(S, field, derivative)``."""

    def __init__(self, system: BVPSystem, x, value=None, error: float = math.nan, iterations: int = 0):
        self.system, self.x = system, np.asarray(x, float)
        self.value = value
        self.error, self.iterations = error, iterations

    @property
    def problem(self) -> BVProblem:
        return self.system.problem

    @property
    def mesh(self) -> np.ndarray:
        return self.system.breakpoints

    @property
    def N(self) -> int:
        return self.system.disc.N

    @property
    def k(self) -> int:
        return self.system.k

    @property
    def params(self) -> dict:
        p = self.system.disc.full_params(self.x, self.system.params(self.value))
        return dict(zip(self.problem.params, (float(v) for v in p)))

    @property
    def outputs(self) -> dict:
        return self.system.outputs(self.x, self.value)

    def evaluate(self, S, field: int | str = 0, derivative: int = 0):
        """The ``derivative``-th derivative of ``field`` (its index or name) at ``S`` (a number or an array)."""
        i = field if isinstance(field, (int, np.integer)) else self.system.fields.index(field) \
            if field in self.system.fields else None
        if i is None or not 0 <= int(i) < len(self.system.fields):
            raise KeyError(f"no field {field!r}; fields: {', '.join(self.system.fields)}")
        m = self.problem.orders[int(i)]
        if not 0 <= int(derivative) <= m + self.k - 1:
            raise ValueError(f"derivative must be in 0..{m + self.k - 1}, got {derivative!r}")
        out = self.system.disc.evaluate(self.x, np.asarray(S, float), int(i), int(derivative))
        return float(out) if np.ndim(S) == 0 else out

    def __repr__(self) -> str:
        return f"Solution({self.system.name}, N = {self.N}, k = {self.k}, error = {self.error:.2g}, {self.params})"


def _param_vector(problem: BVProblem, params) -> np.ndarray:
    names = list(problem.params)
    if isinstance(params, Mapping):
        unknown = [k for k in params if k not in names]
        missing = [n for n in names if n not in params]
        if unknown or missing:
            raise ValueError(f"params: give every parameter of the problem ({', '.join(names)}; the free ones "
                             f"as initial guesses)" + (f"; unknown: {', '.join(map(str, unknown))}" if unknown else "")
                             + (f"; missing: {', '.join(missing)}" if missing else ""))
        params = [params[n] for n in names]
    p = np.array(params, float).ravel()
    if p.size != max(len(names), 1) or not np.all(np.isfinite(p)):
        raise ValueError(f"params must be {len(names)} finite numbers ({', '.join(names)}), got {params!r}")
    return p


def _initial(system: BVPSystem, guess) -> np.ndarray:
    """Coefficients from a guess: a :class:`Solution`, a constant, a callable (one field), or one of
    those per field (a sequence in field order, or a dict by field name)."""
    if isinstance(guess, Solution):
        _check_same(system.problem, guess.problem, "guess")
        return system.transfer(guess.x, guess.system)
    n = len(system.fields)
    if isinstance(guess, Mapping):
        unknown = [g for g in guess if g not in system.fields]
        if unknown:
            raise ValueError(f"guess names unknown fields {unknown}; fields: {', '.join(system.fields)}")
        guess = [guess.get(f, 0.0) for f in system.fields]
    elif callable(guess) or np.ndim(guess) == 0:
        guess = [guess] * n if np.ndim(guess) == 0 and not callable(guess) else [guess]
    guess = list(guess)
    if len(guess) != n:
        raise ValueError(f"guess: one callable or constant per field ({n}), got {len(guess)}")

    def as_function(g):
        if callable(g):
            return lambda S: np.broadcast_to(np.asarray(g(S), float), np.shape(S))
        return lambda S, c=float(g): np.full(np.shape(S), c)

    free = system.base[list(system.problem.free)]
    return system.disc.project([as_function(g) for g in guess], free)


def _check_same(a: BVProblem, b: BVProblem, what: str) -> None:
    if a is b:
        return
    if list(a.orders) != list(b.orders) or list(a.params) != list(b.params) or list(a.free) != list(b.free) \
            or tuple(a.interval) != tuple(b.interval):
        raise ValueError(f"{what} is a solution of another problem (orders, parameters or interval differ)")


# --------------------------------------------------------------------------
# Solve at fixed parameters
# --------------------------------------------------------------------------
@with_one_blas_thread
def solve(problem: BVProblem, params, *, guess=0.0, N: int = 10, k: int = 5, mesh=None, max_error: float = 1e-8,
          N_max: int = 2000, outputs: Mapping[str, Callable] | None = None, scales: Mapping[str, float] | None = None,
          name: str = "problem", tol: float = 1e-11, max_refinements: int = 12) -> Solution:
    """Solve ``problem`` at the parameters ``params`` (a dict by name, or a sequence; the free ones are
    initial guesses) to the estimated error ``max_error``.

    Damped Newton (:func:`rodcont.linalg.newton_solve`) on ``N`` uniform subintervals (or ``mesh``, the
    breakpoints) with ``k`` Gauss points each, from ``guess``: a constant, a callable ``u(S)`` (one field),
    one of those per field (a list, or a dict by field name), or a previous :class:`Solution`. While the
    error estimate (module docstring) is above ``max_error`` the mesh is rebuilt where the residual
    between collocation points is large, with as many subintervals as the estimate says (up to
    ``N_max``); a mesh on which Newton fails is replaced by the last one halved. Raises
    :class:`BVPError` when Newton does not converge or the accuracy is not reached.
    """
    _check_api(problem, params=params, outputs=outputs, scales=scales)
    if mesh is None and (isinstance(N, bool) or not isinstance(N, (int, np.integer))):
        raise TypeError(f"N (subintervals) must be an integer, got {N!r}")
    _check_positive("max_error", max_error)
    base = _param_vector(problem, params)
    system = BVPSystem(problem, None, base, N if mesh is None else mesh, k, outputs, scales, name)
    x = _initial(system, guess)
    last = None
    for _ in range(max_refinements + 1):
        r = system.disc.newton(x, base, tol=tol, max_iter=50, min_damping=1.0 / 256)
        if not r.converged:
            if last is None or 2 * last.N > N_max:
                raise BVPError(f"Newton did not converge on N = {system.disc.N} ({r.message}): a better guess or "
                               f"another N")
            system = last.system.with_mesh(last.system.conform(halved(last.mesh)))
            x, last = system.transfer(last.x, last.system), None
            continue
        error = _Estimator(system).estimate(r.x, 0.0)
        last = Solution(system, r.x, None, error, r.iterations)
        if error <= max_error:
            return last
        if system.disc.N >= N_max:
            break
        b = adapted_mesh(system.breakpoints, system.interval_defect(r.x, None), system.k, error, 0.1 * max_error,
                         N_max=N_max)
        new = system.with_mesh(system.conform(b))
        x, system = new.transfer(r.x, system), new
    raise BVPError(f"accuracy not reached: estimated error {last.error:.2g} > max_error = {max_error:g} with "
                   f"N = {last.N}" + (" (N_max reached)" if last.N >= N_max else ""))


def _check_api(problem, *, params=None, outputs=None, scales=None, events=(), callback=None) -> None:
    """The API's arguments are what they must be (a ``TypeError`` naming the argument, not an
    ``AttributeError`` from inside)."""
    if not isinstance(problem, BVProblem):
        raise TypeError(f"problem must be a rodcont.BVProblem, got {type(problem).__name__}")
    if isinstance(params, Mapping):
        for key, value in params.items():
            if isinstance(value, (str, bytes, bool)) or np.ndim(value) != 0:
                raise TypeError(f"params[{key!r}] must be a number, got {value!r}")
    for what, given, ok in (("outputs", outputs, callable), ("scales", scales, _is_number)):
        if given is not None and not (isinstance(given, Mapping)
                                      and all(isinstance(n, str) and ok(v) for n, v in given.items())):
            kind = "a function of the solution" if what == "outputs" else "a number (the floor)"
            raise TypeError(f"{what} must be a dict name -> {kind}, got {given!r}")
    if isinstance(events, (str, bytes)) or not isinstance(events, Sequence) \
            or not all(isinstance(e, Event) for e in events):
        raise TypeError(f"events must be a sequence of rodcont.Event, got {events!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be a function of the point, got {callback!r}")


def _is_number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))


def _check_positive(name, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (v > 0) \
            or not math.isfinite(v):
        raise ValueError(f"{name} must be a positive number, got {v!r}")
    return float(v)


# --------------------------------------------------------------------------
# The result, in memory and read from a file
# --------------------------------------------------------------------------
class BVPResult(ContinuationResult):
    """A branch of a user's problem: the generic result, with the problem's description (``attrs``:
    its name, fields, orders, parameters, interval, ``k``, the held parameter values) so that every point
    can be restarted from. ``point(label)`` adds ``params`` (every parameter at that point) and ``k``;
    ``solution(label, problem)`` is that point as a :class:`Solution` (the problem is needed for a
    result read from a file)."""

    SIGNED_COLUMNS = ("dp_ds",)

    def __init__(self, param: str = "p", attrs: dict | None = None, settings: dict | None = None):
        super().__init__(param, settings)
        self.attrs = dict(attrs or {})
        self.path = ""
        self.problem: BVProblem | None = None
        self.options: dict = {}  # outputs, scales, name: what a solution of this result carries

    def row(self, pt) -> dict:
        out = super().row(pt)
        out["dp_ds"] = float(pt.tp)
        return out

    @property
    def label(self) -> str:
        return self.path or "the branch"

    def point(self, label) -> dict:
        out = super().point(label)
        held = json.loads(self.attrs["held"]) if "held" in self.attrs else {}
        free = json.loads(self.attrs.get("free", "[]"))
        params = dict(held)
        params[self.param] = float(out[self.param])
        params.update({f: float(out[f]) for f in free if f in out})
        names = json.loads(self.attrs.get("params", "[]"))
        out.update(params={n: params[n] for n in names if n in params}, k=int(self.attrs["k"]),
                   problem=str(self.attrs.get("problem", "")), param=self.param, attrs=self.attrs,
                   scales=_stored_scales(self.attrs))
        return out

    def solution(self, label, problem: BVProblem | None = None) -> Solution:
        problem = problem or self.problem
        if problem is None:
            raise ValueError(f"{self.label}: give the problem (a file stores no code)")
        _check_api(problem)
        pt = self.point(label)
        _check_point(problem, pt, self.attrs, self.label)
        opts = dict(self.options)
        system = BVPSystem(problem, self.param, _param_vector(problem, pt["params"]), pt["breakpoints"], pt["k"],
                           opts.get("outputs"), opts.get("scales", _stored_scales(self.attrs)),
                           opts.get("name", pt["problem"] or "problem"))
        return Solution(system, pt["x"], float(pt[self.param]), float(pt.get("error", math.nan)))


def _stored_scales(attrs: dict) -> dict:
    try:
        return dict(json.loads(attrs.get("scales", "{}")))
    except (TypeError, ValueError):
        return {}


def _description(system: BVPSystem, param: str) -> dict:
    """What a file (and a result) records of the problem: enough to check a restart, none of its code."""
    pb = system.problem
    held = {n: float(v) for j, (n, v) in enumerate(zip(pb.params, system.base)) if j not in set(pb.free)
            and n != param}
    return {"kind": FILE_KIND, "problem": system.name, "param": param, "fields": json.dumps(system.fields),
            "orders": json.dumps([int(m) for m in pb.orders]), "params": json.dumps(list(pb.params)),
            "free": json.dumps(system.free_names), "held": json.dumps(held),
            "interval": json.dumps([float(v) for v in pb.interval]), "k": int(system.k),
            "N": int(system.disc.N), "n_integrals": int(system.disc.n_int),
            "outputs": json.dumps(list(system.output_functions)), "scales": json.dumps(system.scales),
            "plot_y": (list(system.output_functions) or [f"norm_{system.fields[0]}"])[0]}


def _check_point(problem: BVProblem, pt: dict, attrs: dict, where: str) -> None:
    """A stored point fits ``problem``: the same fields' orders, parameters, free ones and interval, and
    its coefficients the size of the problem's discretisation on its mesh."""
    want = dict(orders=[int(m) for m in problem.orders], params=list(problem.params),
                free=[problem.params[j] for j in problem.free], interval=[float(v) for v in problem.interval])
    for key, value in want.items():
        if key in attrs and json.loads(attrs[key]) != value:
            raise ValueError(f"{where} is a point of problem {attrs.get('problem', '?')!r} whose {key} "
                             f"{json.loads(attrs[key])} differ from the problem given ({value})")
    b = np.asarray(pt["breakpoints"], float)
    size = Collocation(problem, b, int(pt["k"])).size
    if np.size(pt["x"]) != size:
        raise ValueError(f"{where}: the stored point has {np.size(pt['x'])} unknowns, the problem given has "
                         f"{size} on that mesh (another problem?)")


# --------------------------------------------------------------------------
# Continuation
# --------------------------------------------------------------------------
_CONT = {f.name for f in fields(ContinuationSettings)}
_ADAPT = {f.name for f in fields(AdaptiveSettings)}


def _settings(p_range, direction, options: dict) -> tuple[ContinuationSettings, AdaptiveSettings]:
    """The tracker's and the loop's settings from one set of keywords (each a field of one of them)."""
    unknown = sorted(set(options) - _CONT - _ADAPT)
    if unknown:
        raise TypeError(f"continue_bvp() got unknown options {', '.join(unknown)} (the fields of "
                        f"ContinuationSettings and AdaptiveSettings are accepted)")
    cont = {k: v for k, v in options.items() if k in _CONT}
    adapt = dict(measure_every=1)  # a user's defect has no known ratio to the error: measure every point
    adapt.update({k: v for k, v in options.items() if k in _ADAPT})
    if p_range is not None:
        if not isinstance(p_range, (list, tuple)) or len(p_range) != 2:
            raise TypeError(f"p_range must be a pair (lo, hi), got {p_range!r}")
        cont.update(p_min=float(p_range[0]), p_max=float(p_range[1]))
    if not _is_number(direction) or direction not in (1, -1):  # 1.0 is 1; "1", True and 0.5 are not
        raise ValueError(f"direction must be +1 or -1, got {direction!r}")
    cont["direction"] = int(direction)
    return ContinuationSettings(**cont), AdaptiveSettings(**adapt)


def _start(problem: BVProblem, param: str, start, direction: int, outputs, scales, name):
    """``(system, x0, p0, tangent0)`` from a :class:`Solution` or a stored point (a dict of
    :meth:`BVPResult.point`)."""
    if isinstance(start, Solution):
        _check_same(problem, start.problem, "start")
        system = BVPSystem(problem, param, _param_vector(problem, start.params), start.mesh, start.k,
                           start.system.output_functions if outputs is None else outputs,
                           start.system.scales if scales is None else scales,
                           start.system.name if name is None else name)
        return system, start.x.copy(), float(start.params[param]), None
    if not isinstance(start, Mapping) or not {"x", "breakpoints", "params", "k"} <= set(start):
        raise TypeError("start must be a rodcont.bvp.Solution or a point of a BVPResult (result.point(label), "
                        "load_branch(path).point(label))")
    if name is not None and start.get("problem") and name != start["problem"]:
        raise ValueError(f"the start is a point of problem {start['problem']!r}, not {name!r}")
    _check_point(problem, start, start.get("attrs", {}), "the start")
    system = BVPSystem(problem, param, _param_vector(problem, start["params"]), start["breakpoints"], start["k"],
                       outputs, scales if scales is not None else start.get("scales", {}),
                       name or start.get("problem") or "problem")
    tangent0 = None
    tx, tp = start.get("direction", (None, None))
    if start.get("param") == param and tx is not None and np.size(tx) == np.size(start["x"]):
        tangent0 = (direction * np.asarray(tx, float), direction * float(tp))  # on along the stored branch
    return system, np.asarray(start["x"], float), float(start["params"][param]), tangent0


@with_one_blas_thread
def continue_bvp(problem: BVProblem, param: str, start, p_range: tuple | None = None, *, direction: int = 1,
                 outputs: Mapping[str, Callable] | None = None, scales: Mapping[str, float] | None = None,
                 name: str | None = None, out: str | None = None, overwrite: bool = False, store_every: int = 1,
                 events: Sequence = (), callback: Callable[[Point], None] | None = None, **options) -> BVPResult:
    """Continue ``problem`` in the parameter ``param`` from ``start`` over ``p_range = (lo, hi)``.

    ``start``: a :class:`Solution` (from :func:`solve`; it leaves along ``direction`` in ``param``) or
    a stored point (``result.point("F1")``, ``rodcont.load_branch(path).point(-1)``; it goes on along
    its stored tangent, ``direction = -1`` back). ``outputs`` and ``scales`` (module docstring): default
    the start's. ``options``: any field of :class:`rodcont.continuation.ContinuationSettings` (``ds``,
    ``ds_max``, ``max_steps``, ``forced``, ``detect_branch_points``, ...) or of
    :class:`rodcont.adaptive.AdaptiveSettings` (``max_error``, ``fold_error``, ``N_max``, ``adapt``,
    ...; ``measure_every`` defaults to 1 here: the error of every point is estimated). ``events``:
    :class:`rodcont.continuation.Event` objects on the points' columns. ``out``: a branch file written
    as the run goes (published whole at least every second and at every special point; an existing
    file only with ``overwrite``). Returns a :class:`BVPResult`; its ``status`` says why it ended.
    """
    _check_api(problem, outputs=outputs, scales=scales, events=events, callback=callback)
    if param not in list(problem.params):
        raise ValueError(f"unknown parameter {param!r}; the problem's: {', '.join(problem.params)}")
    if problem.param_index(param) in set(problem.free):
        raise ValueError(f"{param} is a free parameter (solved for): continue in one that is held")
    settings, adaptive = _settings(p_range, direction, options)
    system, x0, p0, tangent0 = _start(problem, param, start, settings.direction, outputs, scales, name)
    attrs = dict(_description(system, param), max_error=adaptive.max_error)
    result = BVPResult(param, attrs)
    result.problem, result.options = problem, dict(outputs=system.output_functions, scales=system.scales,
                                                   name=system.name)
    recorder = _Recorder(result, out, overwrite, attrs, store_every)
    try:
        engine = AdaptiveContinuation(system, x0, p0, settings, adaptive, tangent0=tangent0, events=events,
                                      recorder=recorder, callback=callback, param=param)
        result.attrs["settings"] = json.dumps(result.settings, default=float)
        with np.errstate(all="ignore"):
            engine.run()
    finally:
        recorder.close()
    return result


# --------------------------------------------------------------------------
# Branch files of kind "bvp"
# --------------------------------------------------------------------------
class _Recorder(ResultRecorder):
    """Adds each point to the result and, with ``out``, to a branch file (published as the rod's are:
    :class:`rodcont.branchfile.BranchWriter`)."""

    def __init__(self, result: BVPResult, out, overwrite, attrs, store_every: int):
        super().__init__(result)
        if isinstance(store_every, bool) or not isinstance(store_every, (int, np.integer)) or store_every < 1:
            raise ValueError(f"store_every must be an integer >= 1, got {store_every!r}")
        self.thin, self.writer, self.group = int(store_every), None, None
        if out is not None:
            from .branchfile import BranchWriter, check_output
            out = check_output(out, overwrite=overwrite, what="out")
            self.writer = BranchWriter(out, attrs, store_every=self.thin)
            self.group = self.writer.groups["/"] = _Group(self.writer.f, self.thin)
            result.path = out

    def add(self, pt: Point, problem) -> int:
        r = self.result
        if self.thin > 1 and len(r):
            r.thin(len(r) - 1, self.thin)
        i = r.add(pt, problem.breakpoints)
        if self.writer is not None:
            self.group.add(r.row_at(i), pt.x, np.append(pt.tx, pt.tp), problem.breakpoints)
            self.writer.points += 1
            if str(pt.kind) != "regular" or self.writer.due():
                self.sync()
                self.writer.flush()
        return i

    def sync(self) -> None:
        if self.writer is not None:
            self.writer.set_attr("settings", json.dumps(self.result.settings, default=float))
            self.writer.set_attr("columns", json.dumps(list(self.result.table)))
            self.group.set_special(self.result)

    def close(self) -> None:
        if self.writer is None:
            return
        r = self.result
        self.sync()
        if r.unlocated:
            self.writer.set_attr("unlocated", json.dumps(r.unlocated))
        running = r.status == Status.RUNNING
        self.writer.close("interrupted" if running else r.message, Status.INTERRUPTED if running else r.status)


class _Group:
    """The ``/branch`` group of a "bvp" file: one column per name of the result's table, the
    coefficients, meshes and tangents NaN-padded; points queued and written at each publication."""

    def __init__(self, root, store_every: int):
        self.root, self.store_every = root, store_every
        self.g = root.create_group("branch")
        self.n, self.queue, self.pending = 0, [], None

    def add(self, row: dict, x, tangent, breakpoints) -> None:
        from .branchfile import kept
        keep_x, keep_t = kept(self.n, row["kind"], self.store_every)
        self.queue.append((row, np.array(x, float) if keep_x else np.zeros(0),
                           np.array(tangent, float) if keep_t else np.zeros(0), np.array(breakpoints, float)))
        self.pending = None if keep_x else (self.n, np.array(x, float), np.array(tangent, float))
        self.n += 1
        if len(self.queue) == 1 and self.n == 1:
            self.root.require_group("mesh").create_dataset("breakpoints", data=np.array(breakpoints, float))

    def _column(self, name, sample):
        import h5py
        if name not in self.g:
            dtype = h5py.string_dtype() if isinstance(sample, str) else ("i1" if name == "located" else "f8")
            self.g.create_dataset(name, (self.n - len(self.queue),), maxshape=(None,), dtype=dtype, chunks=(256,),
                                  **({} if isinstance(sample, str) else {"fillvalue": np.nan if dtype == "f8" else 0}))
        return self.g[name]

    def _matrix(self, name, width, dtype):
        if name not in self.g:
            self.g.create_dataset(name, (0, max(width, 1)), maxshape=(None, None), dtype=dtype, fillvalue=np.nan,
                                  chunks=(16, max(min(width, 4096), 1)), compression="gzip", shuffle=True)
        ds = self.g[name]
        if ds.shape[1] < width:
            ds.resize(width, axis=1)
        return ds

    def drain(self) -> None:
        q, self.queue = self.queue, []
        if not q:
            return
        i0, m = self.n - len(q), len(q)
        for name in dict.fromkeys(k for row, *_ in q for k in row):
            ds = self._column(name, q[0][0].get(name, 0.0))
            ds.resize(i0 + m, axis=0)
            vals = [row.get(name, math.nan) for row, *_ in q]
            ds[i0:] = np.array(vals, dtype=object if isinstance(vals[0], str) else float)
        for j, (name, dtype) in enumerate((("coefficients", "f8"), ("tangent", "f4"), ("breakpoints", "f8")), 1):
            ds = self._matrix(name, max(r[j].size for r in q), dtype)
            ds.resize(i0 + m, axis=0)
            block = np.full((m, ds.shape[1]), np.nan)
            for a, r in enumerate(q):
                block[a, :r[j].size] = r[j]
            ds[i0:, :] = block.astype(dtype)

    def fill_pending(self) -> None:
        """The last point's solution, if it was thinned out: a file always ends on a restartable point."""
        self.drain()
        if self.pending is not None:
            i, x, t = self.pending
            self._matrix("coefficients", x.size, "f8")[i, :x.size] = x
            self._matrix("tangent", t.size, "f4")[i, :t.size] = t
            self.pending = None

    def set_special(self, result: BVPResult) -> None:
        """``/special_points``, ``/folds`` and ``/branch_points`` (for other readers; rodcont reads the kinds)."""
        import h5py
        for name in ("special_points", "folds", "branch_points"):
            if name in self.root:
                del self.root[name]
        sp, special = self.root.create_group("special_points"), result.special
        sp.create_dataset("index", data=np.array([p.index for p in special], dtype="i8"))
        sp.create_dataset("located", data=np.array([p.located for p in special], dtype="i1"))
        sp.create_dataset("value", data=np.array([p.value for p in special], dtype="f8"))
        for name in ("kind", "label", "message"):
            sp.create_dataset(name, data=np.array([getattr(p, name) for p in special], dtype=object),
                              dtype=h5py.string_dtype())
        for group, table in (("folds", result.folds), ("branch_points", result.branch_points)):
            g = self.root.create_group(group)
            for col in table.columns:
                values = [row.get(col, math.nan) for row in table]
                if not all(isinstance(v, str) for v in values) or not values:
                    g.create_dataset(col, data=np.array(values, dtype="i8" if col == "index" else "f8"))
                else:
                    g.create_dataset(col, data=np.array(values, dtype=object), dtype=h5py.string_dtype())


def read_file(path: str, f) -> BVPResult:
    """A "bvp" branch file (open, checked by :mod:`rodcont.branchfile`) as a :class:`BVPResult`."""
    from .branchfile import BranchFileError, _plain
    attrs = {k: _plain(v) for k, v in f.attrs.items()}
    for key in ("param", "k", "params", "orders", "fields"):
        if key not in attrs:
            raise BranchFileError(f"{path}: damaged branch file (attribute {key} missing)")
    param = str(attrs["param"])
    g = f.get("branch")
    if g is None or param not in g or "kind" not in g or "coefficients" not in g:
        raise BranchFileError(f"{path}: damaged branch file (/branch incomplete)")
    raw = {key: g[key][()] for key in g}
    n = min(len(v) for v in raw.values())
    out = BVPResult(param, attrs)
    out.path = path
    out.table = {}
    for key, v in raw.items():
        if np.ndim(v) == 1:
            v = v[:n]
            out.table[key] = ([_plain(s) for s in v] if v.dtype.kind in "OSU" else
                              [bool(u) for u in v] if key == "located" else v.tolist())
    order = [c for c in json.loads(attrs.get("columns", "[]")) if c in out.table]
    out.table = {c: out.table[c] for c in order + [c for c in out.table if c not in order]}
    out.coefficients, out.meshes = _Rows(raw["coefficients"][:n]), _Rows(raw["breakpoints"][:n])
    out.tangents = _Rows(raw["tangent"][:n]) if "tangent" in raw else [np.empty(0)] * n
    sp = f.get("special_points")
    if sp is not None and "message" in sp:
        out.messages = {int(i): _plain(m) for i, m in zip(sp["index"][()], sp["message"][()]) if _plain(m)}
    out.message = str(attrs.get("stop_reason", ""))
    try:
        out.status = Status(str(attrs.get("status", "running")))
    except ValueError:
        raise BranchFileError(f"{path}: damaged branch file (status = {attrs.get('status')!r})") from None
    try:
        out.settings = json.loads(attrs.get("settings", "{}"))
        out.unlocated = json.loads(attrs.get("unlocated", "[]"))
    except (TypeError, ValueError):
        raise BranchFileError(f"{path}: damaged branch file (settings)") from None
    out.options = dict(scales=_stored_scales(attrs), name=str(attrs.get("problem", "problem")))
    return out


def describe(result: BVPResult) -> str:
    """One line: the problem, the parameter, the points and why the run ended (``rodcont folds``)."""
    where = os.path.basename(result.path) if result.path else "branch"
    return (f"# {where}: problem {result.attrs.get('problem', '?')}, continued in {result.param}, {len(result)} "
            f"points, status {result.status}: {result.message}")
