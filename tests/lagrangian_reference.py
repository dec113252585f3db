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
"""

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp
from scipy.optimize import brentq

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
