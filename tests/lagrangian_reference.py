"""Independent Lagrangian reference solutions for the twisted heavy beam.

This module is a *reference implementation* used by the tests to check the
Eulerian (collocation) code of the project.  It shares no code with it: it
solves the same physical problem in the classical Lagrangian description,
with the unstressed arclength ``s`` as independent variable, using only numpy
and scipy.

Rod model (special Cosserat rod, unshearable, extensible, isotropic; seed
paper eqs 2-6, ``shared/PROBLEM.md``)
--------------------------------------------------------------------------
* directors ``d1, d2, d3 = d1 x d2``, ``ds d_k = u x d_k``, ``ds r = alpha d3``;
* ``M = EI (u1 d1 + u2 d2) + GJ u3 d3``, ``F = F1 d1 + F2 d2 + EA (alpha - 1) d3``;
* balance ``ds F + f = 0``, ``ds M + ds r x F = 0``, ``f = w g`` per unit
  *unstressed* length (``g = -e3``, gravity down, by default).

Inverting the constitutive law: with ``F_k = F . d_k`` and ``M_k = M . d_k``,
``u = (M_1/EI, M_2/EI, M_3/GJ)`` (director components) and
``alpha = 1 + F_3/EA``.  The state integrated along ``s`` is

    y = (r [3], q [4], F [3], M [3], ell [1])

with ``q`` a quaternion for the directors (``d_k = R(q) e_k``),
``F, M`` in *global* components and ``ell`` the running deformed length
``int alpha ds``.  The Kirchhoff equations read

    r' = alpha d3,  q' = q * (0, u) / 2,  F' = -w g,
    M' = -alpha d3 x F,  ell' = alpha.

``R(q)`` is evaluated as the rotation matrix of ``q / |q|`` (the formula
divided by ``q . q``), so the directors are orthonormal to rounding whatever
``|q|``; the quaternion equation conserves ``|q|`` exactly and the integrator
keeps it to ~1e-13, so no re-orthonormalisation is done (none is needed).
All right-hand sides are written with analytic operations only, so that the
complex-step derivative ``Im f(x + i h) / h`` is exact to rounding; they are
vectorised over trailing axes (mesh points for ``solve_bvp``, perturbation
columns for the shooting Jacobian).

Canonical problem (``shared/PROBLEM.md``)
-----------------------------------------
Clamps at ``r(0) = 0`` and ``r(l0) = L e1`` with ``d3 = e1`` at both ends,
``d1(0) = e2, d2(0) = e3`` (quaternion ``(1, 1, 1, 1)/2``) and the end
section turned by ``Phi`` about ``e1``: ``q(l0) = +- q_Phi`` with
``q_Phi = (cos Phi/2, sin Phi/2 e1) * (1, 1, 1, 1)/2``.  The condition is
imposed as ``vec(conj(q_Phi) * q(l0)) = 0`` (three equations); because the
branch is followed continuously from ``Phi = 0`` with ``Phi`` itself as the
continuous unknown, the twist is the continuous one (the scalar part of
``conj(q_Phi) * q(l0)`` is checked to stay positive, i.e. the quaternion is
tracked modulo 4 pi, never reduced).  The tension ``F . e1 = T = Gamma w L``
is constant for a vertical weight; the unstressed length ``l0`` is an
unknown.  Outputs: ``stretch = (l - L)/L`` with ``l = ell(l0)``, ``l0``,
``torque = M . d3`` (constant; evaluated at ``s = 0`` where ``d3 = e1``).

Methods
-------
* :func:`planar_sag` (``Phi = 0``): the planar extensible elastica in the
  ``(e1, e3)`` plane, solved by ``scipy.integrate.solve_bvp`` on
  ``t = s / l0 in [0, 1]`` with ``l0`` an unknown parameter.
* :func:`kirchhoff_integrate`: initial value problem (DOP853) of the
  equations above from given ``r, directors, F, M`` at ``s = 0``.
* Twisted (3D) solutions: *shooting*.  Unknowns
  ``z = (F2(0), F3(0), M1(0), M2(0), M3(0), l0, Phi)``
  (``F1(0) = T``), six equations (``r(l0) = L e1``, end clamp orientation).
  The Jacobian of the shooting map is exact: the five initial-value unknowns
  are perturbed by complex steps in five columns integrated together (same
  adaptive steps, so it is the exact derivative of the discrete map), the
  ``l0`` column is ``y'(l0)``, the ``Phi`` column is the complex-step
  derivative of the boundary residual.  The rod is short compared with its
  decay lengths (growth of the shooting map ~ 1e2 at the folds), so shooting
  with ``rtol = 1e-12`` gives ~1e-11 accuracy.
  The branch is followed from the planar solution by pseudo-arclength
  continuation in ``z`` (tangent predictor, bordered Newton corrector,
  step halving on failure, tangent-angle check).  The first fold is bracketed
  by the sign change of the ``Phi`` component of the tangent, then located
  with the stretch ``sigma`` as the prescribed (monotone) parameter: the
  extended Newton system ``[G(z); stretch(z) - sigma] = 0`` yields
  ``dPhi/dsigma`` exactly by implicit differentiation
  (``dz/dsigma = A^-1 e_7`` with ``A`` its Jacobian), and Brent's method finds
  the root of ``dPhi/dsigma`` (the maximum of ``Phi(sigma)``) to ``1e-13``.
* :func:`twisted_bvp` re-solves a 3D state by collocation (``solve_bvp``,
  complex-step Jacobian), an independent discretisation used to check the
  shooting results.

Verified numbers (paper values ``L=1, w=10, EI=1, GJ=0.75, EA=255``)
---------------------------------------------------------------------
* ``Gamma = 1, Phi = 0``: stretch 9.2449753e-4, l0 0.96282043.
* ``Gamma = 1, Phi = 10``: stretch 3.1059074e-3.
* first folds (phi_L, stretch, torque, l0):
  ``Gamma = 0``: 10.776923236, 0.0791552686, 7.200286795, 1.0763748568;
  ``Gamma = 1``: 13.099993823, 0.1454479447, 8.313547463, 1.1043872242;
  ``Gamma = 2``: 15.628416122, 0.4323993164, 7.353472144, 1.3531647984.
  ``min d3 . e1`` there: 0.889, 0.815, 0.392.
* Checks: changing ``rtol`` from 1e-10 to 1e-13 moves the fold numbers by
  < 1e-9 (1e-12 to 1e-13: < 3e-11); the collocation re-solution
  (:func:`twisted_bvp`, tol 1e-9) agrees in ``Phi`` at the fold stretch to
  5e-12 and, fitting ``Phi(stretch)`` from it, puts the fold stretch within
  3e-9; :func:`kirchhoff_integrate` from the fold's ``F0, M0`` lands on the
  end clamp to 1e-15; the straight weightless rod gives ``torque = GJ Phi/L``
  and the Greenhill loss of uniqueness (min singular value of the shooting
  Jacobian) is found at ``torque L/EI = 8.98682`` (``T = 0``) and 10.42886
  (``T L^2/EI = 10``, EA = 1e9); along the Gamma = 1 branch past the fold,
  ``min d3 . e1`` reaches 0 at ``Phi = 12.220``, stretch 0.859.

Secondary branches (added later, same independence from ``src/``)
------------------------------------------------------------------
* :func:`critical_twists`: the straight weightless rod under tension ``T``
  (exact for every ``Phi``, :func:`straight_weightless_state`) loses
  uniqueness where ``2 (cosh b - cos a) = tau sinh(b)/b``,
  ``a = GJ Phi/(2 EI)``, ``tau = T L^2/(alpha EI)``, ``b^2 = tau - a^2``
  (derivation in :func:`critical_condition`; Greenhill ``tan a = a`` for
  ``T = 0``); each root is a double zero of the shooting Jacobian.
  Gamma = 1: ``Phi_n = 13.83443036, 21.69758836, 29.85840987, 38.11622360,
  46.41777461``.
* :func:`secondary_fold`: from the straight weightless state at a ``Phi``
  between ``Phi_n`` and ``Phi_{n+1}``, continuation in the weight ``w``
  (0 -> 10) at fixed ``T`` and ``Phi`` (:func:`heavy_seed`, shooting with
  ``w`` as an extra unknown, :func:`_shoot_ext`), then in ``Phi`` upwards to
  the first fold, located by Brent on ``dPhi/dsigma`` with
  ``sigma = c . x`` (``c`` the tangent without its ``Phi`` component); the
  branch is abandoned where ``min d3 . e1`` reaches 0 (the exit point is
  then located and returned).  :func:`primary_fold` applies the same
  tracer to the branch from ``Phi = 0`` (agrees with
  :func:`twisted_branch_fold` to < 4e-13).
* Gamma = 1 secondary folds (phi_L, stretch, torque, l0, min d3.e1):
  n = 1: 21.0227971207, 0.0605983945, 14.959167916, 1.0209468126, 0.887;
  n = 2: 29.2419861763, 0.0363425617, 21.563917829, 0.9971766278, 0.922;
  n = 3: 37.5449542056, 0.0253206159, 28.151763486, 0.9864131611, 0.941.
  Changing ``rtol`` 1e-12 -> 1e-10 moves them by < 5e-10; seeds at 1/4
  instead of 1/2 of the interval give the same folds to < 1e-13; the
  collocation re-solution (:func:`twisted_bvp`) gives the same ``Phi`` at
  the fold stretch to < 2e-12.  All numbers, other Gamma, and the
  accuracies: ``tests/data/lagrangian_folds.json``
  (``tests/data/make_lagrangian_folds.py``).
"""

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp
from scipy.optimize import brentq, minimize_scalar

__all__ = [
    "kirchhoff_rhs",
    "kirchhoff_integrate",
    "planar_sag",
    "twisted_solution",
    "twisted_branch_fold",
    "twisted_bvp",
    "quat_to_directors",
    "directors_to_quat",
    "clamp_quaternion",
    "straight_weightless_state",
    "critical_condition",
    "critical_twists",
    "slope_turns",
    "primary_fold",
    "heavy_seed",
    "secondary_fold",
]

# Complex step used for exact derivatives (any tiny value works).
_H = 1e-20
# Quaternion of the start clamp: d1 = e2, d2 = e3, d3 = e1 (a 120 degree turn
# about (1, 1, 1)).
_Q_START = np.array([0.5, 0.5, 0.5, 0.5])
# Gravity of the canonical problem.
_G_DOWN = np.array([0.0, 0.0, -1.0])


# ----------------------------------------------------------------------------
# Quaternions
# ----------------------------------------------------------------------------
def _qmul(a, b):
    """Hamilton product of quaternions ``a`` and ``b`` (shape (4, ...))."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array([
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    ])


def _qconj(a):
    """Quaternion conjugate (vector part negated; no complex conjugation)."""
    return np.array([a[0], -a[1], -a[2], -a[3]])


def quat_to_directors(q):
    """Director matrix ``D`` (columns d1, d2, d3) of the quaternion ``q``.

    ``q`` has shape (4, ...); ``D`` has shape (3, 3, ...) with
    ``D[i, k] = (d_k) . e_i``.  The rotation of ``q / |q|`` is returned (the
    quadratic formula is divided by ``q . q``), so ``D`` is orthonormal for
    any nonzero ``q``.  Analytic in ``q`` (complex-step safe).
    """
    q0, q1, q2, q3 = q
    n = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    D = np.array([
        [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
        [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
    ])
    return D / n


def directors_to_quat(D):
    """Unit quaternion (q0 >= 0) of a 3x3 rotation matrix ``D`` (columns d_k).

    Shepperd's method (pivot on the largest of the four candidate squares).
    """
    D = np.asarray(D, dtype=float)
    tr = np.trace(D)
    cand = np.array([tr, D[0, 0], D[1, 1], D[2, 2]])
    k = int(np.argmax(cand))
    if k == 0:
        q0 = 0.5 * np.sqrt(1 + tr)
        q = [q0, (D[2, 1] - D[1, 2]) / (4 * q0), (D[0, 2] - D[2, 0]) / (4 * q0),
             (D[1, 0] - D[0, 1]) / (4 * q0)]
    elif k == 1:
        q1 = 0.5 * np.sqrt(1 + 2 * D[0, 0] - tr)
        q = [(D[2, 1] - D[1, 2]) / (4 * q1), q1, (D[0, 1] + D[1, 0]) / (4 * q1),
             (D[0, 2] + D[2, 0]) / (4 * q1)]
    elif k == 2:
        q2 = 0.5 * np.sqrt(1 + 2 * D[1, 1] - tr)
        q = [(D[0, 2] - D[2, 0]) / (4 * q2), (D[0, 1] + D[1, 0]) / (4 * q2), q2,
             (D[1, 2] + D[2, 1]) / (4 * q2)]
    else:
        q3 = 0.5 * np.sqrt(1 + 2 * D[2, 2] - tr)
        q = [(D[1, 0] - D[0, 1]) / (4 * q3), (D[0, 2] + D[2, 0]) / (4 * q3),
             (D[1, 2] + D[2, 1]) / (4 * q3), q3]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def clamp_quaternion(phi):
    """Quaternion of the end clamp turned by ``phi`` about ``e1``.

    ``(cos phi/2, sin phi/2 e1) * q_start``: ``d1 = cos(phi) e2 + sin(phi) e3``,
    ``d2 = -sin(phi) e2 + cos(phi) e3``, ``d3 = e1``.  ``phi`` may be an array
    (result shape (4, n)) and complex (complex step).  As a function of the
    continuous ``phi`` it distinguishes ``phi`` modulo 4 pi.
    """
    phi = np.asarray(phi)
    c, s = np.cos(phi / 2), np.sin(phi / 2)
    z = np.zeros_like(c)
    start = _Q_START.reshape((4,) + (1,) * phi.ndim) * np.ones_like(c)
    return _qmul(np.array([c, s, z, z]), start)


# ----------------------------------------------------------------------------
# Kirchhoff equations
# ----------------------------------------------------------------------------
def kirchhoff_rhs(y, w, EI, GJ, EA, g=_G_DOWN):
    """``d y / ds`` of the Lagrangian rod equations.

    ``y`` has shape (14, ...): ``r`` (0:3), quaternion ``q`` (3:7), internal
    force ``F`` (7:10) and moment ``M`` (10:13) in global components, running
    deformed length ``ell`` (13).  Any trailing shape is allowed (mesh points,
    complex-step columns).  Constitutive law inverted in the director basis:
    ``u_k = M.d_k / (EI, EI, GJ)``, ``alpha = 1 + F.d3 / EA``.
    """
    q, F, M = y[3:7], y[7:10], y[10:13]
    D = quat_to_directors(q)                      # D[i, k] = (d_k)_i
    Fb = np.einsum("ik...,i...->k...", D, F)      # F . d_k
    Mb = np.einsum("ik...,i...->k...", D, M)      # M . d_k
    u1, u2, u3 = Mb[0] / EI, Mb[1] / EI, Mb[2] / GJ
    alpha = 1 + Fb[2] / EA
    q0, q1, q2, q3 = q
    dq = 0.5 * np.array([                         # q * (0, u) / 2
        -(q1 * u1 + q2 * u2 + q3 * u3),
        q0 * u1 + q2 * u3 - q3 * u2,
        q0 * u2 + q3 * u1 - q1 * u3,
        q0 * u3 + q1 * u2 - q2 * u1,
    ])
    dr = alpha * D[:, 2]
    g = np.asarray(g, dtype=float).reshape((3,) + (1,) * (y.ndim - 1))
    dF = -w * np.broadcast_to(g, F.shape)
    dM = -np.cross(dr, F, axis=0)
    return np.concatenate([dr, dq, dF, dM, alpha[None]], axis=0)


def kirchhoff_integrate(r0, D0, F0, M0, l0, w=10., EI=1., GJ=0.75, EA=255.,
                        g=(0., 0., -1.), rtol=1e-12, atol=1e-13):
    """Integrate the Kirchhoff rod equations from ``s = 0`` to ``s = l0``.

    Parameters
    ----------
    r0 : (3,) position at ``s = 0``.
    D0 : (3, 3) director matrix at ``s = 0`` (columns d1, d2, d3); converted to
        a unit quaternion (so it is projected on the rotations if slightly off).
    F0, M0 : (3,) internal force and moment at ``s = 0``, global components.
    l0 : unstressed length to integrate over.
    w, EI, GJ, EA : weight per unstressed length and stiffnesses.
    g : direction of gravity (body force ``f = w g``).
    rtol, atol : DOP853 tolerances.

    Returns
    -------
    dict with ``r`` (3,) and ``D`` (3, 3) at ``s = l0``, ``F`` and ``M`` at
    ``s = l0``, ``length`` (deformed length ``int alpha ds``), ``sol``
    (callable ``s -> r(s)``, shape (3,) or (3, n)), ``directors`` (callable
    ``s -> D(s)``), ``state`` (callable ``s -> y(s)``, the 14-component state
    of :func:`kirchhoff_rhs`) and ``quat_norm_drift`` (max ``| |q| - 1 |`` at
    the integrator steps).  Directors come from the quaternion normalised at
    evaluation, so they are orthonormal to rounding; no re-orthonormalisation
    is performed.
    """
    y0 = np.zeros(14)
    y0[0:3] = r0
    y0[3:7] = directors_to_quat(D0)
    y0[7:10] = F0
    y0[10:13] = M0
    g = np.asarray(g, dtype=float)
    sol = solve_ivp(lambda s, y: kirchhoff_rhs(y, w, EI, GJ, EA, g), (0.0, l0), y0,
                    method="DOP853", rtol=rtol, atol=atol, dense_output=True)
    if not sol.success:
        raise RuntimeError("kirchhoff_integrate: " + sol.message)
    ye = sol.y[:, -1]

    def position(s):
        return sol.sol(s)[0:3]

    def directors(s):
        return quat_to_directors(sol.sol(s)[3:7])

    return dict(r=ye[0:3], D=quat_to_directors(ye[3:7]), F=ye[7:10], M=ye[10:13],
                length=ye[13], sol=position, directors=directors, state=sol.sol,
                quat_norm_drift=np.max(np.abs(np.linalg.norm(sol.y[3:7], axis=0) - 1)))


# ----------------------------------------------------------------------------
# Planar sag (Phi = 0)
# ----------------------------------------------------------------------------
def planar_sag(gamma, w=10., EI=1., EA=255., L=1., tol=1e-10):
    """Planar heavy clamped-clamped extensible elastica under tension.

    In the ``(e1, e3)`` plane, ``d3 = (cos th, 0, sin th)``, ``F = (T, 0, Fz)``;
    with ``t = s / l0`` the states ``(x, z, th, m = EI th_s, Fz, ell)`` obey

        x' = l0 alpha cos th,  z' = l0 alpha sin th,  th' = l0 m / EI,
        m' = l0 alpha (T sin th - Fz cos th),  Fz' = l0 w,  ell' = l0 alpha,

    ``alpha = 1 + (T cos th + Fz sin th) / EA``, with ``x = z = th = ell = 0``
    at ``t = 0``, ``x = L, z = th = 0`` at ``t = 1``; ``l0`` is a parameter.
    (The moment is ``M = -m e2``.)  Solved by ``solve_bvp`` with tolerance
    ``tol``.

    Returns
    -------
    dict with ``stretch`` ((l - L)/L), ``l0``, ``torque`` (0),
    ``deflection`` (callable ``x1 -> x3``, vectorised, x1 in [0, L]),
    ``max_sag`` (``-min x3 > 0``), ``x_max_sag`` (where it occurs),
    ``F0``, ``M0`` (global internal force and moment at ``s = 0``) and
    ``bvp`` (the ``solve_bvp`` result, states as above, ``t`` in [0, 1]).
    """
    T = gamma * w * L

    def fun(t, y, p):
        l0 = p[0]
        _, _, th, m, Fz, _ = y
        c, s = np.cos(th), np.sin(th)
        a = 1 + (T * c + Fz * s) / EA
        return l0 * np.vstack([a * c, a * s, m / EI, a * (s * T - c * Fz),
                               w * np.ones_like(t), a])

    def bc(ya, yb, p):
        return np.array([ya[0], ya[1], ya[2], ya[5], yb[0] - L, yb[1], yb[2]])

    t = np.linspace(0.0, 1.0, 41)
    y = np.zeros((6, t.size))
    y[0] = L * t
    y[4] = w * L * (t - 0.5)
    y[5] = L * t
    res = solve_bvp(fun, bc, t, y, p=[L], tol=tol, bc_tol=1e-2 * tol, max_nodes=200000)
    if res.status != 0:
        raise RuntimeError("planar_sag: solve_bvp failed: " + res.message)
    l0 = res.p[0]
    sol = res.sol

    def t_of_x(x1):
        """Invert x(t) = x1 by Newton's method (x is increasing in t)."""
        x1 = np.asarray(x1, dtype=float)
        tt = np.clip(x1 / L, 0.0, 1.0)
        for _ in range(50):
            yy = sol(tt)
            dt = (yy[0] - x1) / fun(tt, yy, res.p)[0]
            tt = np.clip(tt - dt, 0.0, 1.0)
            if np.max(np.abs(dt)) < 1e-14:
                break
        return tt

    def deflection(x1):
        return sol(t_of_x(x1))[1]

    # lowest point: the interior zero of th (th < 0 before, > 0 after)
    tg = np.linspace(0.0, 1.0, 2001)[1:-1]
    th = sol(tg)[2]
    k = np.nonzero((th[:-1] < 0) & (th[1:] >= 0))[0]
    if k.size:
        ts = brentq(lambda tt: sol(tt)[2], tg[k[0]], tg[k[0] + 1], xtol=1e-15)
    else:                                   # no sag (e.g. w = 0)
        ts = 0.5
    ys = sol(ts)
    return dict(stretch=(res.y[5, -1] - L) / L, l0=l0, torque=0.0,
                deflection=deflection, max_sag=-ys[1], x_max_sag=ys[0],
                F0=np.array([T, 0.0, res.y[4, 0]]), M0=np.array([0.0, -res.y[3, 0], 0.0]),
                bvp=res)


# ----------------------------------------------------------------------------
# Twisted beam: shooting, continuation, fold
# ----------------------------------------------------------------------------
def _initial_state(z, T, ncol=None):
    """State at s = 0 for unknowns z = (F2, F3, M1, M2, M3, l0, Phi)."""
    y0 = np.zeros(14) if ncol is None else np.zeros((14, ncol), dtype=complex)
    y0[3:7] = _Q_START if ncol is None else _Q_START[:, None]
    y0[7:10] = np.array([T, z[0], z[1]]) if ncol is None else np.array([T, z[0], z[1]])[:, None]
    y0[10:13] = z[2:5] if ncol is None else z[2:5, None]
    return y0


def _end_residual(yend, phi, L):
    """Boundary residual at s = l0 for states ``yend`` (14, k) and angles (k,).

    Rows: r - L e1 (3), vec(conj(q_Phi) q) (3), ell / L - 1 (the stretch).
    Also returns the scalar part of ``conj(q_Phi) q`` (positive on the
    continuous branch).
    """
    e = _qmul(_qconj(clamp_quaternion(phi)), yend[3:7])
    res = np.concatenate([yend[0:3] - np.array([L, 0.0, 0.0])[:, None], e[1:4],
                          yend[13:14] / L - 1.0], axis=0)
    return res, e[0]


def _shoot(z, T, par, rtol):
    """Shooting map and its exact Jacobian.

    ``z = (F2, F3, M1, M2, M3, l0, Phi)``.  Returns ``G`` (7,): six clamp
    residuals and the stretch, ``J`` (7, 7) = dG/dz, and the scalar part of
    ``conj(q_Phi) q(l0)``.  Columns 0-4 of ``J`` by complex-step perturbation
    of the initial state, integrated together (identical adaptive steps);
    column 5 (``l0``) from ``y'(l0)``; column 6 (``Phi``) by complex step on
    the residual.
    """
    w, EI, GJ, EA, L = par
    y0 = _initial_state(z, T, ncol=5)
    for j in range(5):
        y0[8 + j, j] += 1j * _H
    f = lambda s, y: kirchhoff_rhs(y.reshape(14, 5), w, EI, GJ, EA).ravel()
    sol = solve_ivp(f, (0.0, z[5]), y0.ravel(), method="DOP853", rtol=rtol, atol=0.1 * rtol)
    if not sol.success or not np.all(np.isfinite(sol.y[:, -1])):
        raise RuntimeError("shooting integration failed")
    ye = sol.y[:, -1].reshape(14, 5)
    base = ye[:, 0].real
    cols = np.empty((14, 7), dtype=complex)
    cols[:, :5] = ye
    cols[:, 5] = base + 1j * _H * kirchhoff_rhs(base, w, EI, GJ, EA)
    cols[:, 6] = base
    phi = np.full(7, z[6], dtype=complex)
    phi[6] += 1j * _H
    res, sc = _end_residual(cols, phi, L)
    return res[:, 0].real.copy(), res.imag / _H, sc[0].real


def _newton(z, T, par, rtol, mode, target=None, tau=None, z_prev=None, ds=None,
            tol=1e-12, maxit=15):
    """Newton corrector on the six clamp equations plus one extra equation.

    ``mode``: ``'arclength'`` (``tau . (z - z_prev) = ds``), ``'phi'``
    (``Phi = target``) or ``'stretch'`` (``stretch = target``).  Returns the
    converged ``z``, ``G``, ``J`` (of the last evaluation at the converged
    point), the orientation scalar and the iteration count.
    """
    z = np.array(z, dtype=float)
    for it in range(1, maxit + 1):
        G, J, sc = _shoot(z, T, par, rtol)
        if mode == "arclength":
            row, e = tau, tau @ (z - z_prev) - ds
        elif mode == "phi":
            row, e = np.eye(7)[6], z[6] - target
        elif mode == "stretch":
            row, e = J[6], G[6] - target
        else:
            raise ValueError(mode)
        dz = np.linalg.solve(np.vstack([J[:6], row]), -np.append(G[:6], e))
        if not np.all(np.isfinite(dz)):
            break
        z += dz
        if z[5] <= 0:
            break
        if np.max(np.abs(dz)) < tol:
            G, J, sc = _shoot(z, T, par, rtol)
            if sc <= 0:
                raise RuntimeError("end clamp quaternion jumped to the other sheet")
            return z, G, J, sc, it
    raise RuntimeError("Newton did not converge")


def _tangent(J, t_prev):
    """Unit null vector of J[:6] (7 unknowns), oriented along ``t_prev``."""
    t = np.linalg.solve(np.vstack([J[:6], t_prev]), np.eye(7)[6])
    return t / np.linalg.norm(t)


def _start_point(gamma, par, rtol):
    """Planar solution (Phi = 0) polished by the shooting Newton."""
    w, EI, GJ, EA, L = par
    p = planar_sag(gamma, w=w, EI=EI, EA=EA, L=L)
    z = np.array([0.0, p["F0"][2], 0.0, p["M0"][1], 0.0, p["l0"], 0.0])
    return _newton(z, gamma * w * L, par, rtol, "phi", target=0.0)


def _branch(gamma, par, rtol, ds0=0.3, ds_max=1.0, max_angle=0.35, max_steps=2000):
    """Pseudo-arclength continuation of the branch from the planar solution.

    Generator of ``(z, G, J, tau)`` at each accepted point, starting with the
    planar point and following the direction of increasing ``Phi``.
    Step control: halve on Newton failure or when successive tangents turn
    by more than ``max_angle`` radians; grow by 1.5 after an easy step.
    """
    T = gamma * par[0] * par[4]
    z, G, J, _, _ = _start_point(gamma, par, rtol)
    tau = _tangent(J, np.eye(7)[6])
    yield z, G, J, tau
    ds = ds0
    for _ in range(max_steps):
        if ds < 1e-8:
            raise RuntimeError("continuation step collapsed near Phi = %g" % z[6])
        try:
            zn, Gn, Jn, _, it = _newton(z + ds * tau, T, par, rtol, "arclength",
                                        tau=tau, z_prev=z, ds=ds, tol=1e-10)
        except RuntimeError:
            ds /= 2
            continue
        taun = _tangent(Jn, tau)
        if np.arccos(np.clip(tau @ taun, -1, 1)) > max_angle:
            ds /= 2
            continue
        z, G, J, tau = zn, Gn, Jn, taun
        yield z, G, J, tau
        if it <= 3:
            ds = min(1.5 * ds, ds_max)
    raise RuntimeError("continuation: too many steps")


def _min_d3_e1(z, T, par, rtol):
    """Minimum over s of d3 . e1 for the solution with unknowns z."""
    w, EI, GJ, EA, L = par
    y0 = _initial_state(z, T)
    sol = solve_ivp(lambda s, y: kirchhoff_rhs(y, w, EI, GJ, EA), (0.0, z[5]), y0,
                    method="DOP853", rtol=rtol, atol=0.1 * rtol, dense_output=True)
    s = np.linspace(0.0, z[5], 2001)
    c = quat_to_directors(sol.sol(s)[3:7])[0, 2]
    k = int(np.argmin(c))
    if 0 < k < s.size - 1:     # parabola through the three lowest samples
        c0, c1, c2 = c[k - 1], c[k], c[k + 1]
        den = c0 - 2 * c1 + c2
        if den > 0:
            h = 0.5 * (c0 - c2) / den * (s[1] - s[0])
            return float(quat_to_directors(sol.sol(s[k] + h)[3:7])[0, 2])
    return float(c[k])


def _pack(z, G, T, par, rtol, **extra):
    """Output dictionary for a converged shooting solution."""
    out = dict(phi_L=float(z[6]), stretch=float(G[6]), torque=float(z[2]), l0=float(z[5]),
               F0=np.array([T, z[0], z[1]]), M0=z[2:5].copy(),
               min_d3_e1=_min_d3_e1(z, T, par, rtol), residual=float(np.max(np.abs(G[:6]))),
               z=z.copy())
    out.update(extra)
    return out


def twisted_solution(gamma, phi_L, w=10., EI=1., GJ=0.75, EA=255., L=1., rtol=1e-12):
    """Solution of the twisted heavy beam at end rotation ``phi_L``.

    The branch is followed (pseudo-arclength, shooting) from the planar
    solution with increasing ``Phi`` up to ``phi_L``, which must lie on the
    rising part (before the first fold, else ``ValueError``); the point is
    then solved at ``Phi = phi_L`` exactly.

    Returns
    -------
    dict with ``phi_L``, ``stretch``, ``l0``, ``torque``, ``F0``, ``M0``
    (global internal force and moment at ``s = 0``, for
    :func:`kirchhoff_integrate` with ``D0 = [e2, e3, e1]``), ``min_d3_e1``,
    ``residual`` (clamp residual) and ``z`` (shooting unknowns).
    """
    par = (w, EI, GJ, EA, L)
    T = gamma * w * L
    prev = None
    for z, G, J, tau in _branch(gamma, par, rtol):
        if prev is not None and prev[3][6] > 0 and tau[6] < 0:
            raise ValueError("phi_L = %g lies beyond the first fold (Phi_max ~ %g)"
                             % (phi_L, max(prev[0][6], z[6])))
        if z[6] >= phi_L:
            if prev is None:            # phi_L <= 0
                zg = z
            else:
                lam = (phi_L - prev[0][6]) / (z[6] - prev[0][6])
                zg = (1 - lam) * prev[0] + lam * z
            zs, Gs, _, _, _ = _newton(zg, T, par, rtol, "phi", target=phi_L)
            return _pack(zs, Gs, T, par, rtol)
        prev = (z, G, J, tau)


def twisted_branch_fold(gamma, w=10., EI=1., GJ=0.75, EA=255., L=1., rtol=1e-12,
                        xtol=1e-13, return_branch=False):
    """First fold (first maximum of Phi) of the twisted heavy beam branch.

    The branch is followed from ``Phi = 0`` with increasing ``Phi`` until the
    ``Phi`` component of the tangent changes sign; between the two points the
    stretch ``sigma`` is prescribed and ``Phi`` is an unknown, and the root of
    ``dPhi/dsigma`` (exact, by implicit differentiation of the extended
    shooting system) is found by Brent's method to ``xtol`` in ``sigma``.

    Returns
    -------
    dict with ``phi_L``, ``stretch``, ``torque``, ``l0`` at the fold, plus
    ``F0``, ``M0``, ``min_d3_e1``, ``residual``, ``dphi_dstretch`` (value at
    the returned point, ~0), ``z`` and, if ``return_branch``, ``branch``: an
    array of the computed ``(phi_L, stretch)`` points up to the fold.
    """
    par = (w, EI, GJ, EA, L)
    T = gamma * w * L
    pts = []
    prev = None
    for z, G, J, tau in _branch(gamma, par, rtol):
        pts.append((z[6], G[6]))
        if prev is not None and prev[3][6] > 0 and tau[6] < 0:
            break
        prev = (z, G, J, tau)
    za, sa, zb, sb = prev[0], prev[1][6], z, G[6]
    if not sb > sa:
        raise RuntimeError("stretch is not increasing across the fold bracket")
    state = {}

    def dphi_dsigma(sigma):
        lam = (sigma - sa) / (sb - sa)
        zg = state.get("z", (1 - lam) * za + lam * zb)
        zs, Gs, Js, _, _ = _newton(zg, T, par, rtol, "stretch", target=sigma)
        state.update(z=zs, G=Gs)
        return np.linalg.solve(Js, np.eye(7)[6])[6]     # (dz/dsigma)[Phi]

    fa, fb = dphi_dsigma(sa), dphi_dsigma(sb)
    if not (fa > 0 > fb):
        raise RuntimeError("fold bracket without a sign change of dPhi/dstretch")
    sigma = brentq(dphi_dsigma, sa, sb, xtol=xtol, rtol=4 * np.finfo(float).eps)
    d = dphi_dsigma(sigma)
    extra = dict(dphi_dstretch=float(d))
    if return_branch:
        extra["branch"] = np.array(pts)
    return _pack(state["z"], state["G"], T, par, rtol, **extra)


# ----------------------------------------------------------------------------
# Independent check by collocation
# ----------------------------------------------------------------------------
def twisted_bvp(gamma, z, stretch=None, w=10., EI=1., GJ=0.75, EA=255., L=1.,
                tol=1e-9, nodes=101):
    """Re-solve a 3D state by collocation (``solve_bvp``), for cross-checks.

    The 14 states of :func:`kirchhoff_rhs` on ``t = s / l0 in [0, 1]``,
    parameter ``l0``; boundary conditions ``r(0) = 0``, ``q(0) = q_start``,
    ``ell(0) = 0``, ``F1(0) = T``, ``r(1) = L e1``, ``vec(conj(q_Phi) q(1)) = 0``.
    If ``stretch`` is None, ``Phi = z[6]`` is imposed; otherwise ``Phi`` is a
    second parameter and ``ell(1) = L (1 + stretch)`` is added.  The initial
    guess is the shooting solution with unknowns ``z`` (any nearby point).
    Jacobians by complex step.  Returns dict with ``phi_L``, ``stretch``,
    ``l0``, ``torque`` and ``bvp`` (the ``solve_bvp`` result).
    """
    T = gamma * w * L
    z = np.asarray(z, dtype=float)
    sol0 = solve_ivp(lambda s, y: kirchhoff_rhs(y, w, EI, GJ, EA), (0.0, z[5]),
                     _initial_state(z, T), method="DOP853", rtol=1e-12, atol=1e-13,
                     dense_output=True)
    t = np.linspace(0.0, 1.0, nodes)
    y = sol0.sol(t * z[5])
    free_phi = stretch is not None

    def fun(t, y, p):
        return p[0] * kirchhoff_rhs(y, w, EI, GJ, EA)

    def jac(t, y, p):
        m = y.shape[1]
        dfy = np.empty((14, 14, m))
        for j in range(14):
            yc = y.astype(complex)
            yc[j] += 1j * _H
            dfy[:, j] = fun(t, yc, p).imag / _H
        dfp = np.zeros((14, p.size, m))
        dfp[:, 0] = kirchhoff_rhs(y, w, EI, GJ, EA)
        return dfy, dfp

    def bc(ya, yb, p):
        phi = p[1] if free_phi else z[6]
        res, _ = _end_residual(yb[:, None], np.array([phi]), L)
        out = [ya[0:3], ya[3:7] - _Q_START, ya[13:14], ya[7:8] - T, res[0:6, 0]]
        if free_phi:
            out.append([yb[13] - L * (1 + stretch)])
        return np.concatenate(out)

    p0 = [z[5], z[6]] if free_phi else [z[5]]
    res = solve_bvp(fun, bc, t, y, p=p0, fun_jac=jac, tol=tol, bc_tol=1e-12,
                    max_nodes=200000)
    if res.status != 0:
        raise RuntimeError("twisted_bvp: solve_bvp failed: " + res.message)
    return dict(phi_L=float(res.p[1] if free_phi else z[6]),
                stretch=float(res.y[13, -1] / L - 1), l0=float(res.p[0]),
                torque=float(res.y[10, 0]), bvp=res)


# ----------------------------------------------------------------------------
# Straight weightless rod, its critical twists, and the secondary branches
# ----------------------------------------------------------------------------
def straight_weightless_state(gamma, phi_L, w=10., GJ=0.75, EA=255., L=1.):
    """Exact straight twisted state of the *weightless* rod (shooting unknowns).

    With ``w = 0`` and ``F . e1 = T = gamma * w * L`` (``w`` is only used to
    build ``T``: it is the weight the branch will eventually carry), the
    straight rod ``r = alpha s e1``, ``d3 = e1``, ``F = T e1``,
    ``M = M_t e1`` solves the Kirchhoff equations for every ``phi_L``:
    ``alpha = 1 + T/EA``, ``l0 = L/alpha``, ``u3 = phi_L/l0`` (uniform twist,
    the directors turn by ``phi_L`` about ``e1``), ``M_t = GJ phi_L/l0``.

    Returns the 8 unknowns ``x = (F2, F3, M1, M2, M3, l0, Phi, w)`` of
    :func:`_shoot_ext` (global components at ``s = 0``; ``F1 = T``) with the
    weight set to 0.
    """
    T = gamma * w * L
    alpha = 1 + T / EA
    l0 = L / alpha
    return np.array([0.0, 0.0, GJ * phi_L / l0, 0.0, 0.0, l0, float(phi_L), 0.0])


def critical_condition(a, tau):
    """Loss of uniqueness of the straight weightless twisted rod (clamped).

    Derivation (Lagrangian, linearised about the straight state of
    :func:`straight_weightless_state`).  Write the transverse part of ``d3`` as
    the complex slope ``zeta = d3.e2 + i d3.e3`` (small), and the transverse
    displacement ``rho = r.e2 + i r.e3``.  Since ``e1 x (a e2 + b e3)``
    is multiplication by ``i``, to first order ``rho' = alpha zeta``,
    the transverse moment is ``EI d3 x d3' + M_t d3 -> i EI zeta' + M_t zeta``
    (isotropic rod, ``M . d3 = M_t`` constant), the force is ``T e1 + V``
    with ``V`` a constant transverse force (``w = 0``), and the transverse
    part of ``M' + alpha d3 x F = 0`` reads

        EI zeta'' - i M_t zeta' - alpha T zeta = -alpha V,     s in [0, l0],

    with ``zeta(0) = zeta(l0) = 0`` (clamps ``d3 = e1``) and
    ``int_0^l0 zeta ds = 0`` (``rho(l0) = 0``); ``alpha = 1 + T/EA`` and the
    twist rate ``M_t/GJ = Phi/l0`` are unperturbed at first order.  With
    ``lambda_{1,2} = i k/2 +- beta`` (``k = M_t/EI``,
    ``beta^2 = alpha T/EI - k^2/4``) the solution is
    ``zeta = V/T + A e^{lambda_1 s} + B e^{lambda_2 s}``; the 3x3 determinant
    of the three conditions is, up to the factor
    ``4 beta EI e^{i k l0/2} / (alpha T)``,

        h(a, tau) = 2 (cosh b - cos a) - tau sinh(b)/b = 0,

    ``a = M_t l0/(2 EI) = GJ Phi/(2 EI)``, ``tau = alpha T l0^2/EI = T L^2/(alpha EI)``,
    ``b = beta l0 = sqrt(tau - a^2)`` (``h`` is even in ``b``, hence real
    for ``a^2 > tau`` too: ``cosh b -> cos g``, ``sinh(b)/b -> sin(g)/g``,
    ``g = sqrt(a^2 - tau)``).  The same equation follows in the deformed
    coordinate ``x = alpha s`` from ``alpha EI rho'''' - i M_t rho''' - T rho'' = 0``
    on ``[0, L]``: extensibility only rescales the bending stiffness.
    For ``tau -> 0`` (``T = 0``) ``h = O(tau^2)`` with leading coefficient
    proportional to ``sin a - a cos a``: the Greenhill condition
    ``tan a = a`` (``M_t L/EI = 2 a = 8.9868``), used for ``tau == 0``.
    Each root is a *double* eigenvalue of the real problem (``zeta`` and
    ``i zeta``: the rotational symmetry about ``e1``).

    ``a`` may be an array; ``tau`` a scalar >= 0.  Returns ``h`` (or
    ``sin a - a cos a`` if ``tau == 0``).
    """
    a = np.asarray(a, dtype=float)
    if tau == 0:
        return np.sin(a) - a * np.cos(a)
    b2 = tau - a * a
    b = np.sqrt(b2.astype(complex))
    small = np.abs(b) < 1e-8
    bs = np.where(small, 1.0, b)
    sinhc = np.where(small, 1.0 + b2 / 6, np.sinh(bs) / bs)
    return (2 * (np.cosh(b) - np.cos(a)) - tau * sinhc).real


def critical_twists(gamma, count=5, w=10., EI=1., GJ=0.75, EA=255., L=1.):
    """First ``count`` critical twists ``Phi_n`` of the straight weightless rod.

    Roots ``a_n`` of :func:`critical_condition` (sign changes on a fine grid
    of ``a``, then Brent to 1e-15) with ``tau = T L^2/(alpha EI)``,
    ``T = gamma * w * L``, ``alpha = 1 + T/EA``; ``Phi_n = 2 a_n EI/GJ``,
    torque ``M_t = 2 a_n EI/l0``.  For ``T L^2/EI = 10``, ``EA -> inf`` the
    first root gives ``M_t L/EI = 10.42886`` and for ``T = 0`` 8.98682
    (Greenhill).

    Returns dict with ``phi_L`` (array), ``torque`` (array), ``tau``.
    """
    T = gamma * w * L
    alpha = 1 + T / EA
    l0 = L / alpha
    tau = T * L ** 2 / (alpha * EI)
    roots = []
    a_hi = 8.0
    while len(roots) < count:
        grid = np.linspace(1e-3, a_hi, int(400 * a_hi))
        v = critical_condition(grid, tau)
        idx = np.nonzero(np.sign(v[:-1]) * np.sign(v[1:]) < 0)[0]
        roots = [brentq(lambda a: float(critical_condition(a, tau)), grid[i], grid[i + 1],
                        xtol=1e-15, rtol=4 * np.finfo(float).eps) for i in idx]
        a_hi *= 2
    a = np.array(roots[:count])
    return dict(phi_L=2 * a * EI / GJ, torque=2 * a * EI / l0, tau=tau)


def _shoot_ext(x, T, par, rtol):
    """Shooting map with the weight as an extra unknown, and its exact Jacobian.

    ``x = (F2, F3, M1, M2, M3, l0, Phi, w)`` (global components of ``F`` and
    ``M`` at ``s = 0``, ``F1 = T``), ``par = (EI, GJ, EA, L)``.  Same
    equations as :func:`_shoot`; the ``w`` column of the Jacobian is a sixth
    complex-step column integrated with the five initial-value columns (its
    body force ``-(w + i h) g``).  Returns ``G`` (7,): six clamp residuals and
    the stretch; ``J`` (7, 8) = dG/dx; the scalar part of
    ``conj(q_Phi) q(l0)`` (> 0 on the continuous sheet).
    """
    EI, GJ, EA, L = par
    y0 = _initial_state(x[:7], T, ncol=6)
    for j in range(5):
        y0[8 + j, j] += 1j * _H
    wcol = np.full(6, x[7], dtype=complex)
    wcol[5] += 1j * _H
    f = lambda s, y: kirchhoff_rhs(y.reshape(14, 6), wcol, EI, GJ, EA).ravel()
    sol = solve_ivp(f, (0.0, x[5]), y0.ravel(), method="DOP853", rtol=rtol, atol=0.1 * rtol)
    if not sol.success or not np.all(np.isfinite(sol.y[:, -1])):
        raise RuntimeError("shooting integration failed")
    ye = sol.y[:, -1].reshape(14, 6)
    base = ye[:, 0].real
    cols = np.empty((14, 8), dtype=complex)
    cols[:, :5] = ye[:, :5]
    cols[:, 5] = base + 1j * _H * kirchhoff_rhs(base, x[7], EI, GJ, EA)
    cols[:, 6] = base
    cols[:, 7] = ye[:, 5]
    phi = np.full(8, x[6], dtype=complex)
    phi[6] += 1j * _H
    res, sc = _end_residual(cols, phi, L)
    return res[:, 0].real.copy(), res.imag / _H, sc[0].real


def _newton_ext(x, T, par, rtol, active, row_fn, tol=1e-11, maxit=15):
    """Newton on the six clamp equations plus one scalar equation.

    ``active``: indices (7) of ``x`` that are unknowns (the eighth is held).
    ``row_fn(xa, G, Ja) -> (row, e)`` gives the extra equation ``e = 0`` and
    its gradient with respect to the active unknowns.  Returns ``x``, ``G``,
    ``Ja`` (7 x 7: clamp rows and the stretch row, active columns), the
    orientation scalar and the iteration count.
    """
    x = np.array(x, dtype=float)
    for it in range(1, maxit + 1):
        G, J, sc = _shoot_ext(x, T, par, rtol)
        Ja = J[:, active]
        row, e = row_fn(x[active], G, Ja)
        dx = np.linalg.solve(np.vstack([Ja[:6], row]), -np.append(G[:6], e))
        if not np.all(np.isfinite(dx)):
            break
        x[active] += dx
        if x[5] <= 0:
            break
        if np.max(np.abs(dx)) < tol:
            G, J, sc = _shoot_ext(x, T, par, rtol)
            if sc <= 0:
                raise RuntimeError("end clamp quaternion jumped to the other sheet")
            return x, G, J[:, active], sc, it
    raise RuntimeError("Newton did not converge")


def _continue_ext(x0, T, par, rtol, active, k_dir, ds0=0.2, ds_max=1.0, max_angle=0.3,
                  max_steps=4000):
    """Pseudo-arclength continuation in the 7 active unknowns of ``x``.

    Starts from the converged ``x0``, initial tangent oriented so that its
    component ``k_dir`` (index into ``active``) is positive.  Yields
    ``(x, G, Ja, tau)`` at the start and at every accepted point.  Predictor
    ``x + ds tau``; corrector: Newton on ``[G_clamp(x) = 0,
    tau . (x - x_prev) = ds]``; step halved on Newton failure or when the
    tangent turns by more than ``max_angle``; grown by 1.5 after easy steps.
    """
    act = np.asarray(active)

    def tangent(Ja, t_prev):
        t = np.linalg.solve(np.vstack([Ja[:6], t_prev]), np.eye(7)[6])
        return t / np.linalg.norm(t)

    x = np.array(x0, dtype=float)
    G, J, _ = _shoot_ext(x, T, par, rtol)
    Ja = J[:, act]
    tau = tangent(Ja, np.eye(7)[k_dir])
    yield x, G, Ja, tau
    ds = ds0
    for _ in range(max_steps):
        if ds < 1e-9:
            raise RuntimeError("continuation step collapsed at x = %s" % x)
        xp = x.copy()
        xp[act] += ds * tau
        xa_prev = x[act].copy()
        try:
            xn, Gn, Jn, _, it = _newton_ext(
                xp, T, par, rtol, act,
                lambda xa, G, Ja: (tau, tau @ (xa - xa_prev) - ds))  # noqa: B023 (called in this iteration)
        except RuntimeError:
            ds /= 2
            continue
        taun = tangent(Jn, tau)
        if np.arccos(np.clip(tau @ taun, -1, 1)) > max_angle:
            ds /= 2
            continue
        x, G, Ja, tau = xn, Gn, Jn, taun
        yield x, G, Ja, tau
        if it <= 3:
            ds = min(1.5 * ds, ds_max)
    raise RuntimeError("continuation: too many steps")


def _profile(x, T, par, rtol, n=4001):
    """Dense solution for unknowns ``x``: returns (s grid, directors (3,3,n), sol)."""
    EI, GJ, EA, L = par
    sol = solve_ivp(lambda s, y: kirchhoff_rhs(y, x[7], EI, GJ, EA), (0.0, x[5]),
                    _initial_state(x[:7], T), method="DOP853", rtol=rtol, atol=0.1 * rtol,
                    dense_output=True)
    s = np.linspace(0.0, x[5], n)
    return s, quat_to_directors(sol.sol(s)[3:7]), sol


def _min_d3_e1_ext(x, T, par, rtol):
    """Minimum over ``s`` of ``d3 . e1``: sampled on 4001 points, then refined
    by a bounded Brent minimisation between the neighbours of the sampled
    minimum (``xatol`` 1e-11 in ``s``, so the value is exact to rounding)."""
    s, D, sol = _profile(x, T, par, rtol)
    c = D[0, 2]
    k = int(np.argmin(c))
    if 0 < k < s.size - 1:
        f = lambda t: float(quat_to_directors(sol.sol(t)[3:7])[0, 2])
        r = minimize_scalar(f, bounds=(s[k - 1], s[k + 1]), method="bounded",
                            options=dict(xatol=1e-11))
        return float(min(r.fun, c[k]))
    return float(c[k])


def slope_turns(x, T, par, rtol=1e-12):
    """Turns made by the transverse slope ``zeta = d3.e2 + i d3.e3`` along the rod.

    ``(arg zeta(l0-) - arg zeta(0+)) / (2 pi)`` with the argument followed
    continuously.  ``zeta`` vanishes at both clamps, where its direction has
    a limit: ``zeta ~ zeta'(0) s`` and ``zeta ~ -zeta'(l0) (l0 - s)``, with
    ``d3' = u x d3`` (``u = D (M.d1/EI, M.d2/EI, M.d3/GJ)``) evaluated from the
    end states, so the end directions are exact.  In between ``arg zeta`` is
    sampled on a grid clustered at the ends (``s = l0 (1 - cos(pi t))/2``,
    ``t`` in [1e-3, 1 - 1e-3]) and refined until no step of the argument
    exceeds 0.3 rad.  A float; ill defined only if ``zeta`` (or
    ``zeta'`` at an end) vanishes.
    """
    EI, GJ, EA, L = par
    sol = solve_ivp(lambda s, y: kirchhoff_rhs(y, x[7], EI, GJ, EA), (0.0, x[5]),
                    _initial_state(x[:7], T), method="DOP853", rtol=rtol, atol=0.1 * rtol,
                    dense_output=True)

    def dzeta(y):
        D = quat_to_directors(y[3:7])
        u = D @ ((D.T @ y[10:13]) / np.array([EI, EI, GJ]))
        d3p = np.cross(u, D[:, 2])
        return d3p[1] + 1j * d3p[2]

    a0 = np.angle(dzeta(sol.y[:, 0]))
    a1 = np.angle(-dzeta(sol.y[:, -1]))
    n = 2001
    while True:
        t = np.linspace(1e-3, 1 - 1e-3, n)
        s = x[5] * 0.5 * (1 - np.cos(np.pi * t))
        D = quat_to_directors(sol.sol(s)[3:7])
        ang = np.unwrap(np.concatenate([[a0], np.angle(D[1, 2] + 1j * D[2, 2]), [a1]]))
        if np.max(np.abs(np.diff(ang))) < 0.3 or n > 300000:
            return float((ang[-1] - ang[0]) / (2 * np.pi))
        n = 2 * n - 1


def _locate_fold_ext(pa, pb, T, par, rtol, active, k_phi, xtol=1e-13):
    """Fold of ``Phi`` between accepted continuation points ``pa``, ``pb``.

    ``p = (x, G, Ja, tau)`` with the ``Phi`` component of ``tau`` changing
    sign.  The branch is parametrised near the fold by ``sigma = c . x_act``,
    ``c`` the mean of the two tangents with its ``Phi`` component removed
    (``sigma`` is monotone across the fold).  At given ``sigma`` the
    extended system ``[G_clamp(x) = 0, c . x_act = sigma]`` is solved by
    Newton; ``dPhi/dsigma = (A^-1 e_7)_Phi`` (implicit differentiation, ``A``
    its Jacobian) and Brent finds its root to ``xtol`` in ``sigma``.
    Returns ``(x, G, dPhi/dsigma)`` at the fold.
    """
    act = np.asarray(active)
    c = pa[3] + pb[3]
    c[k_phi] = 0.0
    c /= np.linalg.norm(c)
    sa, sb = c @ pa[0][act], c @ pb[0][act]
    if not sb > sa:
        raise RuntimeError("fold bracket: sigma is not increasing")
    state = {}

    def dphi(sig):
        lam = (sig - sa) / (sb - sa)
        xg = state.get("x", (1 - lam) * pa[0] + lam * pb[0])
        xs, Gs, Js, _, _ = _newton_ext(xg, T, par, rtol, act,
                                       lambda xa, G, Ja: (c, c @ xa - sig), tol=1e-12)
        state.update(x=xs, G=Gs)
        return np.linalg.solve(np.vstack([Js[:6], c]), np.eye(7)[6])[k_phi]

    fa, fb = dphi(sa), dphi(sb)
    if not (fa > 0 > fb):
        raise RuntimeError("fold bracket without a sign change of dPhi/dsigma")
    sig = brentq(dphi, sa, sb, xtol=xtol, rtol=4 * np.finfo(float).eps)
    d = dphi(sig)
    return state["x"], state["G"], d


def _fold_fields(x, G, T, par, rtol):
    """Reported figures of a converged state ``x`` (8 unknowns) with output ``G``."""
    return dict(phi_L=float(x[6]), stretch=float(G[6]), torque=float(x[2]),
                l0=float(x[5]), min_d3_e1=_min_d3_e1_ext(x, T, par, rtol),
                slope_turns=slope_turns(x, T, par, rtol))


def _locate_exit_ext(pa, pb, T, par, rtol, active):
    """Point between accepted points ``pa`` (min d3.e1 > 0) and ``pb`` (<= 0)
    where ``min_s d3 . e1 = 0``.

    Points of the branch between them are parametrised by the arclength
    ``t = tau_a . (x - x_a)`` along ``pa``'s tangent (the same corrector as the
    continuation) and Brent finds the zero of ``min d3 . e1`` in ``t`` to
    1e-12.  Returns ``(x, G)`` there.
    """
    act = np.asarray(active)
    xa, tau = pa[0], pa[3]
    tb = tau @ (pb[0][act] - xa[act])

    def point(t):
        lam = t / tb
        xg = (1 - lam) * xa + lam * pb[0]
        xs, Gs, _, _, _ = _newton_ext(xg, T, par, rtol, act,
                                      lambda y, G, Ja: (tau, tau @ (y - xa[act]) - t))
        return xs, Gs

    t = brentq(lambda t: _min_d3_e1_ext(point(t)[0], T, par, rtol), 0.0, tb, xtol=1e-12)
    return point(t)


def _trace_to_fold(x_start, T, par, rtol, xtol, record=False, stop_at_exit=True):
    """Follow the branch through ``x_start`` with increasing ``Phi`` to its first fold.

    Pseudo-arclength continuation (:func:`_continue_ext`) in
    ``(F2, F3, M1, M2, M3, l0, Phi)`` at the weight ``x_start[7]``; at every
    accepted point ``min d3 . e1`` is computed.  Stops at the first sign
    change (+ to -) of the ``Phi`` component of the tangent, then locates the
    fold (:func:`_locate_fold_ext`); or, if ``min d3 . e1 <= 0`` first (the
    rod leaves the Eulerian domain ``d3 . e1 > 0`` before any fold), locates
    the exit point (:func:`_locate_exit_ext`) and returns its fields with
    ``left_domain = True``.  With ``stop_at_exit=False`` the exit point is
    stored in ``out['exit']`` and the branch is followed (outside the
    Eulerian domain: the Lagrangian equations do not need it) to its fold.
    Returns ``(out, steps)``; with ``record`` the accepted points
    ``(phi_L, stretch, min d3.e1)`` are in ``out['branch']``.
    """
    active = [0, 1, 2, 3, 4, 5, 6]
    prev = None
    steps = 0
    pts = []
    exit_ = None
    for x, G, Ja, tau in _continue_ext(x_start, T, par, rtol, active, 6, ds0=0.2,
                                       ds_max=1.0):
        steps += 1
        m = _min_d3_e1_ext(x, T, par, rtol)
        pts.append((float(x[6]), float(G[6]), m))
        if m <= 0 and exit_ is None:
            xe, Ge = _locate_exit_ext(prev, (x, G, Ja, tau), T, par, rtol, active)
            exit_ = _fold_fields(xe, Ge, T, par, rtol)
            exit_.update(residual=float(np.max(np.abs(Ge[:6]))), x=xe.tolist())
            if stop_at_exit:
                out = dict(exit_, left_domain=True)
                break
        if prev is not None and prev[3][6] > 0 and tau[6] < 0:
            xf, Gf, d = _locate_fold_ext(prev, (x, G, Ja, tau), T, par, rtol, active, 6,
                                         xtol=xtol)
            out = _fold_fields(xf, Gf, T, par, rtol)
            out.update(left_domain=exit_ is not None, dphi_dsigma=float(d),
                       residual=float(np.max(np.abs(Gf[:6]))), x=xf.tolist())
            if exit_ is not None:
                out["exit"] = exit_
            break
        prev = (x, G, Ja, tau, m)
    if record:
        out["branch"] = np.array(pts)
    return out, steps


def primary_fold(gamma, w=10., EI=1., GJ=0.75, EA=255., L=1., rtol=1e-12, xtol=1e-13,
                 record=False, stop_at_exit=True):
    """First fold of the primary branch (from the planar sag ``Phi = 0``).

    Same start as :func:`twisted_branch_fold` (the planar solution of
    :func:`planar_sag` polished by shooting) but followed by
    :func:`_trace_to_fold`: arclength steps in the raw unknowns, a check of
    ``min d3 . e1 > 0`` at every point, and the fold located with the
    parameter ``sigma = c . x`` (not the stretch) -- a second route to the
    same fold.  Returns the dict of :func:`_trace_to_fold` (fields
    ``phi_L, stretch, torque, l0, min_d3_e1, slope_turns, left_domain,
    dphi_dsigma, residual, x``) plus ``branch_steps``.
    """
    par = (EI, GJ, EA, L)
    T = gamma * w * L
    z, _, _, _, _ = _start_point(gamma, (w, EI, GJ, EA, L), rtol)
    x0 = np.append(z, w)
    out, steps = _trace_to_fold(x0, T, par, rtol, xtol, record, stop_at_exit)
    out.update(branch_steps=steps, gamma=gamma)
    return out


def heavy_seed(gamma, phi_seed, w=10., EI=1., GJ=0.75, EA=255., L=1., rtol=1e-12):
    """Near-straight heavy solution reached from the straight weightless rod.

    Start: :func:`straight_weightless_state` at ``Phi = phi_seed`` (exact,
    residual 0 to rounding; isolated when ``phi_seed`` is not a critical
    twist).  Then pseudo-arclength continuation in
    ``(F2, F3, M1, M2, M3, l0, w)`` at fixed ``Phi = phi_seed`` and fixed
    ``T = gamma * w * L`` (``w`` here is the *final* weight) from weight 0 up
    to ``w``, the last point solved at weight ``w`` exactly.

    Returns ``(x, G, steps)``: unknowns ``x`` (8, last = weight), shooting
    output ``G`` and the number of continuation points.
    """
    par = (EI, GJ, EA, L)
    T = gamma * w * L
    active = [0, 1, 2, 3, 4, 5, 7]
    x0 = straight_weightless_state(gamma, phi_seed, w=w, GJ=GJ, EA=EA, L=L)
    prev = None
    for k, (x, _G, _Ja, tau) in enumerate(_continue_ext(x0, T, par, rtol, active, 6,
                                                      ds0=0.5, ds_max=2.0)):
        if x[7] >= w:
            lam = (w - prev[7]) / (x[7] - prev[7])
            xg = (1 - lam) * prev + lam * x
            xg[7] = w
            xs, Gs, _, _, _ = _newton_ext(xg, T, par, rtol, active,
                                          lambda xa, G, Ja: (np.eye(7)[6], xa[6] - w))
            return xs, Gs, k + 1
        if prev is not None and tau[6] <= 0:
            raise RuntimeError("weight continuation turned back at w = %g" % x[7])
        prev = x


def secondary_fold(gamma, n, w=10., EI=1., GJ=0.75, EA=255., L=1., rtol=1e-12,
                   seed_fraction=0.5, xtol=1e-13, record=False, stop_at_exit=True):
    """First fold (maximum of ``Phi``) of the secondary branch number ``n``.

    1. ``Phi_n < Phi_{n+1}``: critical twists of the straight weightless rod
       (:func:`critical_twists`); seed twist
       ``Phi_s = Phi_n + seed_fraction (Phi_{n+1} - Phi_n)``.
    2. :func:`heavy_seed`: exact weightless straight state at ``Phi_s``,
       continued in the weight to ``w`` at fixed ``T = gamma w L``, ``Phi_s``.
    3. Pseudo-arclength continuation in ``(F2, F3, M1, M2, M3, l0, Phi)`` at
       the full weight, from the seed with increasing ``Phi``, until the
       ``Phi`` component of the tangent changes sign (fold bracket) or the rod
       leaves the Eulerian domain (``min d3 . e1 <= 0``, checked at every
       accepted point).
    4. The fold is located by :func:`_locate_fold_ext` (Brent on
       ``dPhi/dsigma``, exact by implicit differentiation).

    Seeds from different ``seed_fraction`` lie on the same branch (checked
    for ``gamma = 1, 5``: the folds agree to 1e-14).

    Returns dict: ``phi_L``, ``stretch``, ``torque`` (``M . d3``, evaluated
    at ``s = 0`` where ``d3 = e1``), ``l0``, ``min_d3_e1``, ``slope_turns``
    (:func:`slope_turns`) at the fold, ``left_domain`` (False), and
    ``dphi_dsigma`` (~0), ``residual``, ``x`` (the 8 shooting unknowns).  If
    the rod reaches ``min d3 . e1 = 0`` first, the same fields are those of
    the exit point and ``left_domain`` is True (or, with
    ``stop_at_exit=False``, those of the fold outside the domain with the
    exit point in ``exit``).  Also ``seed`` (the same fields at the seed, and
    its ``x``), ``critical`` (``[Phi_n, Phi_{n+1}]``), ``n``, ``gamma`` and
    the step counts ``weight_steps``, ``branch_steps``.
    """
    par = (EI, GJ, EA, L)
    T = gamma * w * L
    crit = critical_twists(gamma, n + 1, w=w, EI=EI, GJ=GJ, EA=EA, L=L)["phi_L"]
    phi_s = crit[n - 1] + seed_fraction * (crit[n] - crit[n - 1])
    xs, Gs, wsteps = heavy_seed(gamma, phi_s, w=w, EI=EI, GJ=GJ, EA=EA, L=L, rtol=rtol)

    seed = _fold_fields(xs, Gs, T, par, rtol)
    seed["x"] = xs.tolist()
    out, steps = _trace_to_fold(xs, T, par, rtol, xtol, record, stop_at_exit)
    out.update(seed=seed, critical=[float(crit[n - 1]), float(crit[n])],
               weight_steps=wsteps, branch_steps=steps, n=n,
               gamma=gamma)
    return out
