"""Meshes that follow the solution: error estimates, equidistribution, refinement.

The error of a collocation solution is estimated by re-solving it in a richer
space: one more Gauss point per subinterval (or every subinterval halved).
The coarse spline space is contained in the richer one, so the solution is
carried over exactly and *one* Newton step there gives the change of the
solution to second order in it. The change of the quantities a user reads
(stretch, unstressed length, torque, the parameter, the centreline) is the
estimate: the richer solution is more accurate by a factor ``h^2`` (or
``2^(2k)``) at the mesh points and more in between, so the change is the
coarse error.

A new mesh (:func:`adapted_mesh`) equidistributes a per-subinterval indicator
(the residual between collocation points) with as many subintervals as the
estimate says are needed to bring the error to a target, assuming it falls
like ``h^(k+2)`` (conservative: the outputs converge at ``h^(2k)``, the
centreline between mesh points at ``h^(k+3)``).
"""

from __future__ import annotations

import math

import numpy as np


def halved(breakpoints: np.ndarray) -> np.ndarray:
    b = np.asarray(breakpoints, float)
    return np.sort(np.concatenate([b, 0.5 * (b[1:] + b[:-1])]))


def equidistribute(breakpoints: np.ndarray, indicator: np.ndarray, order: int, floor: float = 0.02,
                   ratio: float = 2.0, relax: float = 0.5, N: int | None = None) -> np.ndarray:
    """A mesh (``N`` subintervals, default as many as now) on which ``indicator`` would be equal.

    ``indicator[i]`` is an error estimate on subinterval ``i`` behaving like
    ``C_i h_i^order``; the new sizes follow the density ``C^(1/order)``
    (floored at ``floor`` of its maximum, neighbours within ``ratio``), and the
    new mesh is ``relax`` of the way from the old one to the equidistributed one
    (only when ``N`` is unchanged: a new count is equidistributed outright).
    """
    b = np.asarray(breakpoints, float)
    h = np.diff(b)
    d = np.maximum(np.asarray(indicator, float), 1e-300)
    rho = (d / h**order) ** (1.0 / order)
    rho = np.maximum(rho, floor * rho.max())
    for _ in range(len(rho)):  # limit the ratio of neighbouring densities
        before = rho.copy()
        rho[1:] = np.maximum(rho[1:], rho[:-1] / ratio)
        rho[:-1] = np.maximum(rho[:-1], rho[1:] / ratio)
        if np.array_equal(before, rho):
            break
    cum = np.concatenate([[0.0], np.cumsum(rho * h)])
    n_new = b.size - 1 if N is None else int(N)
    target = np.interp(np.linspace(0.0, cum[-1], n_new + 1), cum, b)
    if n_new == b.size - 1:
        target = (1 - relax) * b + relax * target
    target[0], target[-1] = b[0], b[-1]
    return target


def adapted_mesh(breakpoints: np.ndarray, indicator: np.ndarray, k: int, error: float, target: float,
                 N_min: int = 4, N_max: int = 1000, grow: float = 4.0) -> np.ndarray:
    """A new partition for an estimated ``error``, aiming at ``target``.

    The count scales by ``(error / target)^(1/(k+2))`` (at most ``grow`` times
    more, at least half as many, within ``[N_min, N_max]``) and the breakpoints
    equidistribute ``indicator`` (``~ h^k`` per subinterval).
    """
    b = np.asarray(breakpoints, float)
    N = b.size - 1
    factor = (max(error, 1e-300) / target) ** (1.0 / (k + 2))
    factor = min(max(factor, 0.5), grow)
    N_new = int(min(max(math.ceil(N * factor), N_min), N_max))
    return equidistribute(b, indicator, order=k, relax=1.0, N=N_new)


class ErrorEstimator:
    """Estimated error of a collocation solution on its mesh (knows nothing of rods).

    The solution is re-solved in a richer space: one more Gauss point per subinterval
    (``refine="k"``, the default; the B-splines of order ``k + m`` with knots of multiplicity
    ``k`` span a subspace of those of order ``k + 1 + m`` with multiplicity ``k + 1``), or every
    subinterval halved (``refine="halve"``); the richer discretisation is built once per mesh.
    The estimate is the largest change, in the problem's own scales, of what a user reads:

    * ``problem.error_quantities(x, p) -> (values, scales)``: named scalars of the solution
      (1-D arrays); the change of each is divided by its scale at the richer solution;
    * the parameter: its change divided by ``max(|p|, up)``, ``up`` its unit (``unit_scale``; 1 without one; the
      change itself is kept as ``parameter_change``: at a fold, how far the fold moves);
    * ``problem.error_fields() -> [(field, scale), ...]``: fields whose values on ``samples``
      points per subinterval are compared (max change over the points, divided by the scale).

    The problem is a meshed problem (:mod:`rodcont.adaptive`) with ``disc`` (its
    :class:`rodcont.collocation.Collocation`), ``with_mesh(breakpoints, k)`` and
    ``linearise(x, p)``; optionally ``fixed_parameters`` (copied to the richer problem at each
    estimate, for a problem whose other parameters move, as a fold curve's do) and
    ``watched_quantities(x, p) -> {name: (value, scale)}``: with ``watch=True`` each estimate also
    sets ``watched[name]``, the change of each relative to its scale, kept apart from the estimate
    (a quantity whose own accuracy is not the guard's business, such as a contact force).

    With ``converge=True`` the richer problem at fixed parameter is solved to convergence (damped Newton from the
    one step, :func:`rodcont.linalg.newton_solve`; the one step where it does not converge): on a stiff contact
    law the one step overstates the error of a friction torque 13 times (``test_a_rotating_strings_error_is_its_
    converged_richer_solutions``), and the mesh refined to its cap for an error it did not have;
    :meth:`converged_estimate` converges the last one-step estimate after the fact.
    """

    def __init__(self, system, samples: int = 8, refine: str = "k", watch: bool = False, converge: bool = False):
        self.system = system
        self.watch, self.watched, self.converge = watch, {}, converge
        self.parameter_change = math.nan  # the last estimate's change of the parameter itself (how far a fold moves)
        if refine == "halve" or system.disc.k >= 7:
            self.fine = system.with_mesh(halved(system.disc.breakpoints))
        else:  # one more Gauss point per subinterval: the same knots, a richer space
            self.fine = system.with_mesh(system.disc.breakpoints, k=system.disc.k + 1)
        b = system.disc.breakpoints
        t = np.linspace(0.0, 1.0, samples + 1)[:-1]
        self.S = np.concatenate([(b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), [b[-1]]])
        coarse, fine = system.disc, self.fine.disc
        # the coarse space lies in the fine one: carry coefficients over by collocating at the fine Gauss points
        self._to_fine = _embedding(coarse, fine)
        fields = list(system.error_fields())
        self._fields = [(coarse.evaluation_matrix(self.S, i), fine.evaluation_matrix(self.S, i), float(scale))
                        for i, scale in fields]

    def _border_weights(self, n: int):
        """The border ``0.5 / n / ux^2``, ``0.5 / up^2`` in the problem's own units (``unit_scale``, else
        ``arclength_scale``; 1 without either): the hyperplane the richer problem is solved on is then the same in
        any units (with the raw ``0.5 / n`` the first estimate of Gamma = 1 read 4.690e-7 or 4.717e-7 with
        lengths x 10, and the meshes parted)."""
        scale = getattr(self.fine, "unit_scale", None) or getattr(self.fine, "arclength_scale", None)
        if scale is None:
            return 0.5 / n, 0.5
        sx, sp = scale()
        return 0.5 / n / np.asarray(sx, float) ** 2, 0.5 / float(sp) ** 2

    @property
    def _parameter_unit(self) -> float:
        """The parameter's own unit (``unit_scale``, else its arclength scale; 1 without either): the floor of
        ``|p|`` in the relative change of the parameter (an absolute 1 read a trace in T differently in other force
        units)."""
        scale = getattr(self.system, "unit_scale", None) or getattr(self.system, "arclength_scale", None)
        return float(scale()[1]) if scale is not None else 1.0

    def estimate(self, x: np.ndarray, value: float, tangent: tuple | None = None) -> float:
        """Estimated error of the solution ``x`` at parameter ``value``.

        With ``tangent = (tx, tp)`` (the branch tangent) the richer problem is
        solved on the hyperplane through the point normal to the tangent, as the
        tracker's corrector does, so the estimate stays finite at a fold (where
        the Jacobian at fixed parameter is singular) and includes the change of
        the parameter itself (how far the fold moves).
        """
        from .linalg import LU, SingularMatrix, bordered
        sysc, sysf = self.system, self.fine
        if hasattr(sysc, "fixed_parameters"):
            sysf.fixed_parameters = sysc.fixed_parameters
        xf = self._to_fine(x)
        F, J, Fp = sysf.linearise(xf, value)
        try:
            if tangent is None:
                dx, dp = LU(J).solve(-F), 0.0
            else:
                tx = self._to_fine(np.asarray(tangent[0], float))
                wx, wp = self._border_weights(tx.size)
                A = bordered(J, Fp, wx * tx, wp * float(tangent[1]))
                # a fill-reducing column order: in natural order a heavy rod pressed on a stiff wall
                # (rows of J up to 2.5e12) drew the dense border row into the pivots again and again, and
                # this factorisation at 21 035 unknowns filled 146 times J's nonzeros (about 2 GB and 10 s
                # each; resident memory peaked at 7.7 GB); COLAMD: twice, in 0.07 s
                d = LU(A, ordering="COLAMD").solve(-np.append(F, 0.0))
                dx, dp = d[:-1], float(d[-1])
        except SingularMatrix:
            return math.inf
        self.parameter_change = dp
        self._step = (x, value, xf + dx, value + dp)
        if self.converge and tangent is None:
            return self.converged_estimate()
        return self._measure(*self._step)

    def converged_estimate(self) -> float:
        """The last estimate at fixed parameter again, with the richer problem solved to convergence from its one
        step (damped Newton, :func:`rodcont.linalg.newton_solve`; the one step where it does not converge): for a
        caller that converges only the estimates above its guard, the ones that refine the mesh."""
        x, value, xf2, pf = self._step
        return self._measure(x, value, self._converged(xf2, value), pf)

    def _measure(self, x, value, xf2, pf) -> float:
        """The largest change, coarse ``x`` to richer ``xf2``, of the error quantities, the parameter and the
        fields, each relative to its scale (and the watched quantities' changes in ``watched``)."""
        sysc, sysf, dp = self.system, self.fine, pf - value
        qc, _ = sysc.error_quantities(x, value)
        qf, scales = sysf.error_quantities(xf2, pf)
        errs = list(np.abs(np.asarray(qf, float) - np.asarray(qc, float)) / np.asarray(scales, float))
        errs.append(abs(dp) / max(abs(value), self._parameter_unit))
        for Ec, Ef, scale in self._fields:
            errs.append(float(np.max(np.abs(Ef @ xf2 - Ec @ x))) / scale)
        if self.watch and hasattr(sysc, "watched_quantities"):
            wc, wf = sysc.watched_quantities(x, value), sysf.watched_quantities(xf2, pf)
            self.watched = {name: abs(wf[name][0] - wc[name][0]) / wf[name][1] for name in wc}
        e = max(errs)
        return e if math.isfinite(e) else math.inf

    def _converged(self, x: np.ndarray, value: float) -> np.ndarray:
        """The richer problem's solution at ``value`` by Newton from ``x``, or ``x`` where Newton fails."""
        from .linalg import newton_solve
        fine = self.fine
        r = newton_solve(lambda y: fine.linearise(y, value)[:2], lambda y: fine.residual(y, value), x)
        return r.x if r.converged else x


def _embedding(coarse, fine):
    """``x_coarse -> x_fine`` for nested spline spaces: least squares at ``k + m`` Gauss points
    per fine subinterval (exact, the coarse function lies in the fine space), factorised once
    per field order (the fields of one order share their points and normal equations)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from .bspline import gauss_points
    per_order, solvers = {}, []
    for i, m in enumerate(coarse.problem.orders):
        key = (id(coarse.spaces[i]), id(fine.spaces[i]))  # fields that share both spaces share the factors
        if key not in per_order:
            pts = gauss_points(fine.breakpoints, fine.k + m)[0]
            A = fine.spaces[i].matrix(pts)
            vals, first = coarse.spaces[i].local(pts, 0)
            per_order[key] = (A.T, spla.splu((A.T @ A).tocsc()), vals[0].ravel(), first, pts.size)
        At, lu, bvals, first, npts = per_order[key]
        order = coarse.spaces[i].order
        # coarse.evaluation_matrix(pts, i), from the values shared by the fields of this order
        B = sp.csr_matrix((bvals, (np.repeat(np.arange(npts), order),
                                   coarse.index[i][first[:, None] + np.arange(order)[None, :]].ravel())),
                          shape=(npts, coarse.size))
        solvers.append((lu, (At @ B).tocsr(), fine.index[i]))

    def carry(x):
        out = np.zeros(fine.size)
        for lu, AtB, idx in solvers:
            out[idx] = lu.solve(AtB @ x)
        if fine.n_free:
            out[fine.free_index] = x[coarse.free_index]
        return out

    return carry
