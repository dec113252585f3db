"""Baseline: the twisted heavy beam by plain ``scipy.integrate.solve_bvp``.

What a user would write without rodcont: the classical Lagrangian (unstressed
arclength) Kirchhoff equations of the extensible rod, solved by collocation
with ``solve_bvp`` and followed in the imposed end rotation ``Phi`` by
*natural-parameter continuation* (each load step starts from the previous
solution).  Independent of ``rodcont`` (numpy and scipy only).

Problem (``shared/PROBLEM.md``): special Cosserat rod, unshearable,
extensible, isotropic; ``M = EI (u1 d1 + u2 d2) + GJ u3 d3``,
``F.d3 = EA (alpha - 1)``; weight ``-w e3`` per unit unstressed length;
clamps ``r(0) = 0``, ``r(l0) = L e1``, ``d3 = e1`` at both ends, the end
section turned by ``Phi`` about ``e1``; tension ``F.e1 = T = Gamma w L``;
unstressed length ``l0`` unknown.

Formulation
-----------
Independent variable ``t = s / l0 in [0, 1]``, unknown parameter ``l0``.
States (14), global components:

    r (3), q (4, quaternion of the directors), F (3), M (3), ell (1)

with ``d_k = R(q) e_k``, ``u = (M.d1/EI, M.d2/EI, M.d3/GJ)``,
``alpha = 1 + F.d3/EA`` and, with ``' = d/dt``,

    r' = l0 alpha d3,   q' = l0 q * (0, u) / 2,   F' = l0 w e3,
    M' = -l0 alpha d3 x F,   ell' = l0 alpha.

Boundary conditions (15 = 14 states + 1 parameter):
``r(0) = 0``, ``q(0) = (1, 1, 1, 1)/2`` (``d1 = e2, d2 = e3, d3 = e1``),
``ell(0) = 0``, ``F(0).e1 = T``, ``r(1) = L e1``,
``vec(conj(q_Phi) * q(1)) = 0`` with
``q_Phi = (cos Phi/2, sin Phi/2 e1) * q(0)``.
The quaternion equation conserves ``|q|`` (the collocation keeps it to the
tolerance); ``R(q)`` is the rotation of ``q/|q|``.  Since ``Phi`` is
increased continuously from 0 the end quaternion stays on the continuous
sheet (scalar part of ``conj(q_Phi) q(1)`` checked positive).

Outputs: ``stretch = (ell(1) - L)/L``, ``l0``, ``torque = M.d3`` (constant
for an isotropic rod; evaluated at ``t = 0`` where ``d3 = e1``).

Solver settings (the "typical user" baseline)
---------------------------------------------
* ``solve_bvp`` with its default *finite-difference* Jacobians (no
  ``fun_jac`` / ``bc_jac``): the right-hand side is vectorised over the mesh
  as ``solve_bvp`` requires, and that is all.
* ``tol`` (collocation residual) and ``bc_tol = tol``; ``max_nodes`` large.
* First step (``Phi = phis[0]``) from a crude guess: straight rod, the
  sagging beam's shear force ``F3 = w l0 (t - 1/2)`` and its bending moment,
  on ``nodes`` uniform nodes.  Every later step starts from the previous
  solution.  Two ways of passing it on (``mesh``):

  - ``"fixed"`` (default): the previous solution is evaluated on the initial
    uniform mesh (``res.sol(x0), res.p``), and ``solve_bvp`` refines that
    mesh again as it needs;
  - ``"previous"``: the previous mesh and values (``res.x, res.y, res.p``)
    are passed on.  This is pathological with ``solve_bvp``: on a load step
    of 0.5 its Newton solver (at most 4 Jacobians and 8 iterations per mesh)
    does not meet its termination test on the first mesh, the residual is
    then above ``tol`` on nearly every interval and nearly every interval is
    split; the mesh never coarsens, so it about doubles at every load step
    (``nodes = 41``, ``tol = 1e-8``: 481 nodes at Phi = 0, 53445 by
    Phi = 3.5, then ``max_nodes = 1e5`` stops some steps, which are halved,
    96169 at Phi = 13; ``nodes = 101``: 88495 by Phi = 4) and the Gamma = 1
    run takes minutes (500 to 780 s here, 73 calls of which 22 fail) instead
    of seconds (about 2.4 s with ``"fixed"``), for the same numbers.
    Kept only to document that trap.

* If a step fails, the increment in ``Phi`` is halved (up to ``max_halvings``
  times) from the last converged solution: what a user would do near the
  fold.  Every ``solve_bvp`` call is counted, failed ones included.

Measured (Gamma = 1, Phi = 0, 0.5, ..., 13, ``mesh="fixed"``, ``nodes = 101``,
one thread): 27 ``solve_bvp`` calls, none failed, no step halving.
Against the shooting reference (``tests/lagrangian_reference.py``,
``twisted_solution``) the stretch at Phi = 10 / 13 is off by 3e-14 / 2e-12
with ``tol = 1e-8`` (about 2.4 s, meshes of 401 to 1203 nodes); 5e-12 / 6e-11
with ``tol = 1e-6`` (0.5 s, at most 301 nodes); ``tol = 1e-9`` and ``1e-10``
take about 4.9 s and 20 s.  So ``tol = 1e-8`` is far more than the 1e-7 in
stretch needed for Figure 2.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/lagrangian_bvp.py`` for the
Gamma = 1 branch Phi = 0, 0.5, ..., 13 (just below the first fold at
Phi = 13.0999938).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_bvp

__all__ = ["natural_continuation"]

_Q0 = np.array([0.5, 0.5, 0.5, 0.5])      # d1 = e2, d2 = e3, d3 = e1


def _qmul(a, b):
    """Hamilton product (quaternions as arrays of shape (4, ...))."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0])


def _end_quat(phi):
    """Quaternion of the end clamp: the start clamp turned by ``phi`` about e1."""
    return _qmul(np.array([np.cos(phi / 2), np.sin(phi / 2), 0.0, 0.0]), _Q0)


def _directors(q):
    """d1, d2, d3 (each (3, m)) of the rotation of q / |q|, q of shape (4, m)."""
    q0, q1, q2, q3 = q
    n = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    d1 = np.array([q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3,
                   2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)]) / n
    d2 = np.array([2 * (q1 * q2 - q0 * q3),
                   q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 + q0 * q1)]) / n
    d3 = np.array([2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1),
                   q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3]) / n
    return d1, d2, d3


def _make_problem(T, w, EI, GJ, EA, L, counter):
    """``fun(t, y, p)`` and ``bc(ya, yb, p, phi)`` for solve_bvp."""

    def fun(t, y, p):
        counter[0] += 1
        l0 = p[0]
        q, F, M = y[3:7], y[7:10], y[10:13]
        d1, d2, d3 = _directors(q)
        u1 = np.einsum("im,im->m", M, d1) / EI
        u2 = np.einsum("im,im->m", M, d2) / EI
        u3 = np.einsum("im,im->m", M, d3) / GJ
        alpha = 1.0 + np.einsum("im,im->m", F, d3) / EA
        q0, q1, q2, q3 = q
        dq = 0.5 * np.array([-(q1 * u1 + q2 * u2 + q3 * u3),
                             q0 * u1 + q2 * u3 - q3 * u2,
                             q0 * u2 + q3 * u1 - q1 * u3,
                             q0 * u3 + q1 * u2 - q2 * u1])
        dr = alpha * d3
        dF = np.zeros_like(F)
        dF[2] = w
        dM = -np.cross(dr, F, axis=0)
        return l0 * np.vstack([dr, dq, dF, dM, alpha])

    def bc(ya, yb, p, phi):
        e = _qmul(np.array([1.0, -1.0, -1.0, -1.0]) * _end_quat(phi), yb[3:7])
        return np.concatenate([ya[0:3], ya[3:7] - _Q0, ya[13:14], ya[7:8] - T,
                               yb[0:3] - np.array([L, 0.0, 0.0]), e[1:4]])

    return fun, bc


def _initial_guess(T, w, EI, L, nodes):
    """Straight rod with the shear force and bending moment of a heavy beam."""
    t = np.linspace(0.0, 1.0, nodes)
    y = np.zeros((14, nodes))
    y[0] = L * t
    y[3:7] = _Q0[:, None]
    y[7] = T
    y[9] = w * L * (t - 0.5)                         # F3: shear of the sagging beam
    y[11] = -w * L**2 * (t * t / 2 - t / 2 + 1 / 12)  # M2: moment of a clamped heavy beam (rough)
    y[13] = L * t
    return t, y, np.array([L])


def natural_continuation(gamma, phis, w=10., EI=1., GJ=0.75, EA=255., L=1., tol=1e-8,
                         nodes=101, mesh="fixed", max_nodes=100000, max_halvings=6, verbose=False):
    """Follow the twisted heavy beam branch by natural continuation in ``Phi``.

    Parameters
    ----------
    gamma : dimensionless tension ``T / (w L)``.
    phis : increasing end rotations (radians); the first is solved from a
        crude straight-rod guess, each next one from the previous solution.
    w, EI, GJ, EA, L : weight per unstressed length, stiffnesses, span.
    tol : ``solve_bvp`` tolerance (``bc_tol = tol``).
    nodes : uniform nodes of the initial mesh (``solve_bvp`` refines it).
    mesh : ``"fixed"`` (previous solution interpolated on the initial mesh,
        default) or ``"previous"`` (previous mesh reused; see module doc).
    max_nodes : passed to ``solve_bvp``.
    max_halvings : on a failed step, halve the increment in ``Phi`` at most
        this many times before giving up (``RuntimeError``).
    verbose : print one line per load step.

    Returns
    -------
    dict with arrays (one entry per ``phis``) ``phi_L``, ``stretch``,
    ``torque``, ``l0``, ``nodes`` (mesh size of each converged solution),
    ``quat_norm_error`` (max ``| |q| - 1 |`` on the mesh); scalars
    ``n_solve_bvp`` (all ``solve_bvp`` calls, including failed ones and
    halved sub-steps), ``n_failed`` (failed calls), ``n_fun_evals`` (calls of
    the vectorised right-hand side, finite-difference Jacobians included),
    ``max_nodes_used``, ``total_nodes`` (sum of the mesh sizes over all
    ``solve_bvp`` calls), ``elapsed`` (seconds), ``tol``, ``jacobian``
    (``'finite-difference'``), ``initial_nodes`` and ``bvp`` (last
    ``solve_bvp`` result).
    """
    if mesh not in ("fixed", "previous"):
        raise ValueError("mesh must be 'fixed' or 'previous'")
    phis = np.asarray(phis, dtype=float)
    T = gamma * w * L
    counter = [0]
    fun, bc = _make_problem(T, w, EI, GJ, EA, L, counter)
    out = {k: [] for k in ("phi_L", "stretch", "torque", "l0", "nodes", "quat_norm_error")}
    n_calls = n_failed = total_nodes = 0
    t0 = time.perf_counter()

    def solve(x, y, p, phi):
        nonlocal n_calls, n_failed, total_nodes
        n_calls += 1
        res = solve_bvp(fun, lambda ya, yb, pp: bc(ya, yb, pp, phi), x, y, p=p,
                        tol=tol, bc_tol=tol, max_nodes=max_nodes)
        total_nodes += res.x.size
        ok = res.status == 0 and res.p[0] > 0
        if ok:   # stay on the continuous sheet of the end quaternion
            ok = _qmul(np.array([1.0, -1.0, -1.0, -1.0]) * _end_quat(phi), res.y[3:7, -1])[0] > 0
        if not ok:
            n_failed += 1
        return res, ok

    x, y, p = _initial_guess(T, w, EI, L, nodes)
    x_fixed = x

    def _next_guess(res):
        if mesh == "fixed":
            return x_fixed, res.sol(x_fixed), res.p
        return res.x, res.y, res.p

    res = None
    phi_done = None
    for phi_target in phis:
        if phi_done is None:
            res, ok = solve(x, y, p, phi_target)
            if not ok:
                raise RuntimeError("first step (Phi = %g) failed: %s" % (phi_target, res.message))
        else:
            dphi = phi_target - phi_done
            phi_cur, halvings = phi_done, 0
            while phi_cur < phi_target:
                phi_try = min(phi_cur + dphi, phi_target)
                trial, ok = solve(x, y, p, phi_try)
                if ok:
                    res, phi_cur = trial, phi_try
                    x, y, p = _next_guess(res)
                else:
                    halvings += 1
                    if halvings > max_halvings:
                        raise RuntimeError("natural continuation failed at Phi = %g (from %g): %s"
                                           % (phi_try, phi_cur, trial.message))
                    dphi /= 2
        x, y, p = _next_guess(res)
        phi_done = phi_target
        out["phi_L"].append(phi_target)
        out["stretch"].append((res.y[13, -1] - L) / L)
        out["torque"].append(res.y[10, 0])
        out["l0"].append(res.p[0])
        out["nodes"].append(res.x.size)
        out["quat_norm_error"].append(np.max(np.abs(np.linalg.norm(res.y[3:7], axis=0) - 1)))
        if verbose:
            print("Phi = %6.3f  stretch = %.10e  torque = %.8f  l0 = %.9f  nodes = %d"
                  % (phi_target, out["stretch"][-1], out["torque"][-1], out["l0"][-1], res.x.size))
    result = {k: np.array(v) for k, v in out.items()}
    result.update(n_solve_bvp=n_calls, n_failed=n_failed, n_fun_evals=counter[0],
                  max_nodes_used=int(result["nodes"].max()) if len(phis) else 0,
                  total_nodes=total_nodes, elapsed=time.perf_counter() - t0, tol=tol,
                  jacobian="finite-difference", initial_nodes=nodes, bvp=res)
    return result


if __name__ == "__main__":
    import os
    phis = np.arange(0.0, 13.0 + 1e-9, 0.5)
    print("# plain scipy solve_bvp, Lagrangian, natural continuation in Phi; Gamma = 1, paper values")
    print("# OPENBLAS_NUM_THREADS=%s" % os.environ.get("OPENBLAS_NUM_THREADS", "unset"))
    t = time.perf_counter()
    r = natural_continuation(1.0, phis, verbose=True)
    elapsed = time.perf_counter() - t
    print("time: %.3f s for %d load steps (Phi = 0 .. %g), %d solve_bvp calls (%d failed), "
          "%d rhs evaluations, Jacobians: %s, tol = %g"
          % (elapsed, phis.size, phis[-1], r["n_solve_bvp"], r["n_failed"], r["n_fun_evals"],
             r["jacobian"], r["tol"]))
    print("nodes: initial %d, final %d, max %d, summed over calls %d"
          % (r["initial_nodes"], r["nodes"][-1], r["max_nodes_used"], r["total_nodes"]))
    for phi in (0.0, 10.0, 13.0):
        k = int(np.argmin(np.abs(r["phi_L"] - phi)))
        print("Phi = %5.2f: stretch = %.10e  torque = %.10f  l0 = %.10f"
              % (r["phi_L"][k], r["stretch"][k], r["torque"][k], r["l0"][k]))
    print("reference (PROBLEM.md): Phi = 0: stretch 9.2449753e-4, l0 0.96282043; "
          "Phi = 10: stretch 3.1059074e-3")
    print("reference (shooting, tests/lagrangian_reference.py, twisted_solution(1.0, 13.0)): "
          "Phi = 13: stretch 6.2398373230e-02, torque 9.2541995380, l0 1.0225808255")
