"""Independent reference: heavy clamped-clamped rod resting on a flat wall.

A reference implementation for the tests (numpy + scipy only, no code shared
with ``rodcont``): the planar, twist-free heavy extensible elastica between
two clamps at the same height, with a rigid frictionless floor ``z >= -c``
(the bottom of a pipe whose axis is ``z = 0``).

Model and sign conventions
--------------------------
Plane ``(e1, e3)``, ``e3`` up; unstressed arclength ``s`` (``s0``) from the
clamp at ``x = 0``.  Tangent ``d3 = (cos th, sin th)``, ``th`` measured from
``e1``, positive upwards.  Unshearable, extensible: ``r' = alpha d3``,
``alpha = 1 + N/EA``, ``N = F . d3``.

* ``F = (Fx, Fz)`` is the internal force exerted *on the part* ``[0, s)``
  *by the part* ``(s, l0]`` (balance ``F' + f = 0``).  So ``N > 0`` is
  tension, the clamp at ``x = L`` exerts ``+F(l0)`` on the rod and the clamp
  at ``x = 0`` exerts ``-F(0)``.  ``f = (0, -w + p)``, ``p >= 0`` the wall
  reaction per unit unstressed length.  Hence ``Fx = T`` everywhere (the
  prescribed horizontal tension) and ``Fz' = w - p``.
* A positive ``th`` is a rotation about ``-e2`` (it turns ``e1`` towards
  ``e3``), so the moment vector is ``M = -m e2`` with the *scalar bending
  moment* ``m = EI th'`` (``m > 0``: sagging curvature, ``z`` convex; in the
  small-slope limit ``m = EI z_xx``).  The ``e2`` component of
  ``M' + r' x F = 0`` gives, with ``(a x b)_2 = a3 b1 - a1 b3``,

      m' = alpha (T sin th - Fz cos th) = -alpha Q,   Q = F . (-sin th, cos th),

  (``Q`` the shear).  Small slopes: ``m_x = T z_x - Fz``, ``Fz_x = w``, i.e.
  ``EI z'''' - T z'' = -w``.

State ``y = (x, z, th, m, Fz, ell)`` (``ell`` the deformed arclength):

    x' = alpha cos th,  z' = alpha sin th,  th' = m/EI,
    m' = alpha (T sin th - Fz cos th),  Fz' = w,  ell' = alpha,
    alpha = 1 + (T cos th + Fz sin th)/EA.

The clamp at ``x = 0`` gives ``x = z = th = ell = 0``; ``m(0) = M0`` and
``Fz(0) = V0`` are unknowns.  The unstressed length ``l0`` is unknown, ``T``
prescribed.

Equilibria (all symmetric about ``x = L/2``)
--------------------------------------------
* ``'free'``: no contact.  Shoot over the half rod, unknowns
  ``(s_h = l0/2, M0)`` with ``V0 = -w s_h`` (each clamp carries half the
  weight: its upward force on the rod is ``-V0 = w l0/2``); conditions
  ``th(s_h) = 0``, ``x(s_h) = L/2``.
* ``'point'``: contact at the single point ``x = L/2``, point reaction
  ``P >= 0`` there (``Fz`` jumps from ``P/2`` to ``-P/2``), curvature there
  ``m_mid >= 0``.  Unknowns ``(s_h, M0, V0)``, conditions ``th(s_h) = 0``,
  ``x(s_h) = L/2``, ``z(s_h) = -c``; ``P = 2 (V0 + w s_h)``.  This regime
  exists between the onset of contact ``c0`` (:func:`onset_clearance`,
  ``P = 0``) and ``c1`` (:func:`flat_onset_clearance`, ``m_mid = 0``).  The
  flat-contact solution cannot hold there: it would need ``a > L/2``
  (small-slope, ``T = 0``: ``c0 = w L^4/(384 EI)``, ``c1 = w L^4/(1152 EI)``).
* ``'flat'`` (``c < c1``): free span ``0 <= x <= a``, contact zone
  ``a <= x <= L - a`` (``z = -c, th = 0, m = 0, Fz = 0, N = T``, reaction
  ``p = w`` per unit unstressed length, i.e. ``w/alpha_T`` per unit ``x``,
  ``alpha_T = 1 + T/EA``), mirror span.  At the touchdown point moment
  continuity gives ``m = 0`` and ``Fz`` jumps by the point reaction
  ``R = Fz(s_a-) = V0 + w s_a >= 0``.  Unknowns ``(s_a, M0, V0)``,
  conditions ``z(s_a) = -c``, ``th(s_a) = 0``, ``m(s_a) = 0``.

:func:`heavy_rod_on_flat_wall` solves ``'free'``; if its lowest point is below
``-c`` it solves ``'point'``; if that has ``m_mid < 0`` (the rod would
penetrate beside the midpoint) it solves ``'flat'``.  Every accepted solution
is checked (``P, R >= 0``, ``m_mid >= 0``, ``a <= L/2``, ``z > -c`` inside the
free spans; violations raise ``RuntimeError``).

Numerics: ``solve_ivp`` (DOP853, ``rtol`` given, ``atol = 1e-14``) with the
variational equations for the exact Jacobian of the shooting map; damped
Newton to rounding.  Initial guesses: the small-slope tension beam (free,
flat) or the free solution (point); fallback: continuation in ``c``.
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["heavy_rod_on_flat_wall", "onset_clearance", "flat_onset_clearance",
           "integrate_span", "span_rhs", "linear_flat_contact"]

_ATOL = 1e-14


# ----------------------------------------------------------------------------
# ODEs
# ----------------------------------------------------------------------------
def span_rhs(s, y, T, w, EI, EA):
    """Right-hand side of the free-span equations for ``y = (x, z, th, m, Fz, ell)``."""
    _, _, th, m, Fz, _ = y[:6]
    c, sn = np.cos(th), np.sin(th)
    a = 1.0 + (T * c + Fz * sn) / EA
    return np.array([a * c, a * sn, m / EI, a * (T * sn - Fz * c), w + 0.0 * a, a])


def _rhs_var(s, Y, T, w, EI, EA):
    """State plus its derivatives w.r.t. ``(m(0), Fz(0))`` (6 x 2, row-major)."""
    x, z, th, m, Fz, ell = Y[:6]
    P = Y[6:].reshape(6, 2)
    c, sn = np.cos(th), np.sin(th)
    N = T * c + Fz * sn
    Q = -T * sn + Fz * c
    a = 1.0 + N / EA
    f = np.array([a * c, a * sn, m / EI, -a * Q, w, a])
    # partial derivatives w.r.t. th, m, Fz (x, z, ell do not enter)
    jth = np.array([Q * c / EA - a * sn, Q * sn / EA + a * c, 0.0,
                    -Q * Q / EA + a * N, 0.0, Q / EA])
    jm = np.array([0.0, 0.0, 1.0 / EI, 0.0, 0.0, 0.0])
    jF = np.array([sn * c / EA, sn * sn / EA, 0.0, -sn * Q / EA - a * c, 0.0, sn / EA])
    dP = np.outer(jth, P[2]) + np.outer(jm, P[3]) + np.outer(jF, P[4])
    return np.concatenate([f, dP.ravel()])


def integrate_span(M0, V0, s_end, T, w=10., EI=1., EA=255., rtol=1e-12, y0=None):
    """Integrate the span ODE from the clamp (or from ``y0``) over ``[0, s_end]``.

    Returns the ``solve_ivp`` result (``dense_output=True``; ``.sol(s)`` gives
    ``(x, z, th, m, Fz, ell)``).  Starts from ``(0, 0, 0, M0, V0, 0)`` unless
    ``y0`` is given.
    """
    if y0 is None:
        y0 = [0.0, 0.0, 0.0, M0, V0, 0.0]
    res = solve_ivp(span_rhs, (0.0, s_end), np.asarray(y0, float), method="DOP853",
                    rtol=rtol, atol=_ATOL, args=(T, w, EI, EA), dense_output=True)
    if res.status != 0:
        raise RuntimeError("integrate_span: " + res.message)
    return res


def _shoot(s_end, M0, V0, par, rtol):
    """End state ``y``, its s-derivative ``f`` and ``dy/d(M0, V0)`` at ``s_end``."""
    T, w, EI, EA = par
    if not (s_end > 0 and np.isfinite(s_end)):
        raise ValueError("non-positive span length")
    Y0 = np.zeros(18)
    Y0[3], Y0[4] = M0, V0
    Y0[6 + 2 * 3 + 0] = 1.0        # d m / d M0
    Y0[6 + 2 * 4 + 1] = 1.0        # d Fz / d V0
    res = solve_ivp(_rhs_var, (0.0, s_end), Y0, method="DOP853", rtol=rtol, atol=_ATOL,
                    args=par)
    if res.status != 0:
        raise ValueError(res.message)
    Ye = res.y[:, -1]
    ye = Ye[:6]
    return ye, span_rhs(s_end, ye, *par), Ye[6:].reshape(6, 2)


# ----------------------------------------------------------------------------
# Shooting systems (unknowns z, residual G, Jacobian J)
# ----------------------------------------------------------------------------
def _sys_free(zz, par, rtol, L):
    s_h, M0 = zz
    w = par[1]
    y, f, P = _shoot(s_h, M0, -w * s_h, par, rtol)
    rows = [2, 0]
    G = np.array([y[2], y[0] - 0.5 * L])
    J = np.column_stack([f[rows] - w * P[rows, 1], P[rows, 0]])
    return G, J


def _sys_mid(zz, par, rtol, L, third):
    """Point contact (``third = ('z', c)``) or the point->flat transition
    (``third = ('m', None)``): ``th = 0, x = L/2`` and ``z = -c`` or ``m = 0``."""
    s_h, M0, V0 = zz
    y, f, P = _shoot(s_h, M0, V0, par, rtol)
    k = 1 if third[0] == "z" else 3
    rows = [2, 0, k]
    G = np.array([y[2], y[0] - 0.5 * L, y[k] + (third[1] if k == 1 else 0.0)])
    J = np.column_stack([f[rows], P[rows]])
    return G, J


def _sys_flat(zz, par, rtol, c):
    s_a, M0, V0 = zz
    y, f, P = _shoot(s_a, M0, V0, par, rtol)
    rows = [1, 2, 3]
    G = np.array([y[1] + c, y[2], y[3]])
    J = np.column_stack([f[rows], P[rows]])
    return G, J


def _newton(sysfun, z0, maxit=60):
    """Damped Newton to rounding; raises RuntimeError on failure."""
    z = np.array(z0, float)
    G, J = sysfun(z)
    nG = np.max(np.abs(G))
    for _ in range(maxit):
        dz = np.linalg.solve(J, -G)
        lam = 1.0
        while True:
            zn = z + lam * dz
            try:
                Gn, Jn = sysfun(zn)
                nGn = np.max(np.abs(Gn))
            except (ValueError, np.linalg.LinAlgError):
                nGn = np.inf
            if np.isfinite(nGn) and (nGn < nG or nGn < 1e-12):
                break
            lam *= 0.5
            if lam < 1e-8:
                raise RuntimeError("Newton: no descent")
        z, G, J, nG = zn, Gn, Jn, nGn
        if np.max(np.abs(lam * dz)) <= 1e-14 * (1 + np.max(np.abs(z))) or nG < 1e-15:
            break
    if nG > 1e-10:
        raise RuntimeError("Newton did not converge (|G| = %g)" % nG)
    return z


def _continuation(make_sys, z_start, c_start, c_target, n=8):
    """Follow a solution from ``c_start`` to ``c_target`` (secant predictor)."""
    cs = np.linspace(c_start, c_target, n + 1)[1:]
    z_prev, c_prev_prev, c_prev, z = None, None, c_start, np.array(z_start, float)
    for ci in cs:
        guess = z if z_prev is None else z + (z - z_prev) * (ci - c_prev) / (c_prev - c_prev_prev)
        z_new = _newton(make_sys(ci), guess)
        z_prev, c_prev_prev, c_prev, z = z, c_prev, ci, z_new
    return z


# ----------------------------------------------------------------------------
# Small-slope guesses
# ----------------------------------------------------------------------------
def _linear_free_M0(T, w, EI, L):
    """Clamp moment of the small-slope tension beam (m'' - k^2 m = -w)."""
    k = np.sqrt(max(T, 0.0) / EI)
    if k * L < 1e-3:
        return -w * L ** 2 / 12.0
    return w / k ** 2 - 0.5 * w * L / (k * np.tanh(0.5 * k * L))


def linear_flat_contact(c, T, w, EI):
    """Small-slope, inextensible flat-contact span ``EI y'''' - T y'' = -w``,
    ``y(0) = y'(0) = 0``, ``y(a) = -c``, ``y'(a) = y''(a) = 0``.

    Returns ``(a, M0, V0, R)`` (same sign conventions as the module).
    ``T = 0``: ``a = (72 EI c/w)^(1/4)``, ``M0 = -w a^2/6``, ``V0 = -2 w a/3``,
    ``R = w a/3``.  Used as an initial guess only.
    """
    a0 = (72.0 * EI * c / w) ** 0.25
    k = np.sqrt(max(T, 0.0) / EI)
    if k * a0 < 1e-2:
        return a0, -w * a0 ** 2 / 6.0, -2.0 * w * a0 / 3.0, w * a0 / 3.0
    # xi = a - x; y = -c + b1 xi + b2 (cosh k xi - 1) + b3 sinh k xi + w xi^2/(2T)
    b2 = -w * EI / T ** 2

    def b3_of(a):
        return (-b2 * k * np.sinh(k * a) - w * a / T) / (k * (np.cosh(k * a) - 1.0))

    def y_at(a):
        b3 = b3_of(a)
        return (-c - k * b3 * a + b2 * (np.cosh(k * a) - 1.0) + b3 * np.sinh(k * a)
                + w * a * a / (2 * T))

    hi = a0
    while y_at(hi) < 0:
        hi *= 2.0
    a = brentq(y_at, 1e-6 * a0, hi, xtol=1e-15, rtol=1e-15)
    b3 = b3_of(a)
    M0 = EI * (b2 * k ** 2 * np.cosh(k * a) + b3 * k ** 2 * np.sinh(k * a) + w / T)
    V0 = EI * k ** 3 * (b2 * np.sinh(k * a) + b3 * np.cosh(k * a))
    R = EI * k ** 3 * b3
    return a, M0, V0, R


# ----------------------------------------------------------------------------
# Solvers of the three regimes
# ----------------------------------------------------------------------------
def _solve_free(T, par, rtol, L):
    w, EI, EA = par[1], par[2], par[3]
    aT = 1.0 + T / EA
    z0 = [0.5 * L / aT, _linear_free_M0(T, w, EI, L)]
    return _newton(lambda z: _sys_free(z, par, rtol, L), z0)


def _solve_transition(T, par, rtol, L, z_free):
    w = par[1]
    z0 = [z_free[0], 0.0, -w * z_free[0] + w * L / 6.0]   # guess: 2R = wL/3 (T = 0)
    try:
        return _newton(lambda z: _sys_mid(z, par, rtol, L, ("m", None)), z0)
    except RuntimeError:
        z0 = [z_free[0], z_free[1], -w * z_free[0]]
        return _newton(lambda z: _sys_mid(z, par, rtol, L, ("m", None)), z0)


def _span_min_z(sol, s_end, n=801):
    """Lowest point of a span (sampled, refined by the zero of th)."""
    s = np.linspace(0.0, s_end, n)
    y = sol(s)
    k = int(np.argmin(y[1]))
    zmin = y[1, k]
    if 0 < k < n - 1 and y[2, k - 1] < 0 < y[2, k + 1]:
        sm = brentq(lambda t: sol(t)[2], s[k - 1], s[k + 1], xtol=1e-15)
        zmin = min(zmin, sol(sm)[1])
    return zmin, y


def _inverse_x(sol, s_end, f_x, x1):
    """``s`` with ``x(s) = x1`` on a span (x increasing), by Newton."""
    x1 = np.asarray(x1, float)
    xe = sol(s_end)[0]
    s = np.clip(x1 / xe * s_end, 0.0, s_end)
    for _ in range(60):
        y = sol(s)
        ds = (y[0] - x1) / f_x(y)
        s = np.clip(s - ds, 0.0, s_end)
        if np.max(np.abs(ds), initial=0.0) < 1e-15:
            break
    return s


def heavy_rod_on_flat_wall(c, T, w=10., EI=1., EA=255., L=1., rtol=1e-12):
    """Symmetric equilibrium of the heavy clamped-clamped rod above the floor ``z = -c``.

    Parameters: clearance ``c > 0``, horizontal tension ``T >= 0`` (``F.e1``),
    weight ``w`` per unit unstressed length, ``EI``, ``EA``, clamp distance
    ``L``, integrator ``rtol``.

    Returns a dict:

    * ``contact`` (bool), ``regime``: ``'free'``, ``'point'`` (single contact
      point at ``x = L/2``) or ``'flat'`` (contact zone ``[a, L - a]``).
    * ``x_touchdown``: ``a`` (``L/2`` for ``'point'``, nan for ``'free'``).
    * ``s_touchdown``: unstressed length of one free span (``l0/2`` for
      ``'point'``, nan for ``'free'``).
    * ``R``: concentrated wall reaction (upward, >= 0) at each touchdown point;
      for ``'point'`` the two touchdown points coincide and ``R`` is *half*
      the midspan point reaction ``P`` (so ``R`` is continuous at the
      point -> flat transition); nan for ``'free'``.
    * ``M0``: bending moment ``m = EI dth/ds0`` at the clamp ``x = 0``
      (moment vector ``-M0 e2``; negative = hogging, the usual sign there).
    * ``V0``: ``F(0) . e3``, vertical internal force at ``x = 0`` (force of
      the rod part ``s > 0`` on ``s < 0``); the clamp pushes the rod upwards
      with ``clamp_reaction = -V0`` (``= w l0/2`` without contact).
    * ``l0`` total unstressed length, ``l`` total deformed length,
      ``stretch = (l - L)/L``.
    * ``min_z``: lowest point of the centreline (``-c`` with contact).
    * ``contact_force_per_x``: distributed reaction per unit ``x`` in the zone,
      ``w/alpha_T`` (``'flat'``; nan otherwise).
    * ``total_side_force``: all of the wall reaction, ``2 R + w l_zone0``
      (``l_zone0 = (L - 2a)/alpha_T``; ``0`` without contact).
    * ``M_mid``: bending moment at midspan (``0`` for ``'flat'``).
    * ``alpha_T = 1 + T/EA``, ``clamp_reaction = -V0``, ``c``, ``T``.
    * ``span``: dense solution (``span(s) -> (x, z, th, m, Fz, ell)``) of the
      free span from the clamp, ``s`` in ``[0, s_span]``; ``s_span``.
    * ``shape``: callable ``x -> z`` (arrays), the centreline height over
      ``[0, L]`` (``-c`` in the contact zone).
    """
    if not c > 0:
        raise ValueError("c must be positive")
    par = (float(T), float(w), float(EI), float(EA))
    aT = 1.0 + T / EA
    zf = _solve_free(T, par, rtol, L)
    sol_f = integrate_span(zf[1], -w * zf[0], zf[0], *par, rtol=rtol)
    zmin_f, _ = _span_min_z(sol_f.sol, zf[0])
    zmin_f = min(zmin_f, sol_f.y[1, -1])

    def f_x(y):
        return span_rhs(0.0, y, *par)[0]

    if zmin_f >= -c:
        regime, z, s_span = "free", zf, zf[0]
    else:
        # point contact at midspan
        c0 = -zmin_f
        mk_mid = lambda cc: (lambda zz: _sys_mid(zz, par, rtol, L, ("z", cc)))
        zp0 = np.array([zf[0], zf[1], -w * zf[0]])
        try:
            zp = _newton(mk_mid(c), zp0)
        except RuntimeError:
            zp = _continuation(mk_mid, zp0, c0, c)
        yp = integrate_span(zp[1], zp[2], zp[0], *par, rtol=rtol).y[:, -1]
        if yp[3] >= 0:
            regime, z, s_span = "point", zp, zp[0]
        else:
            mk_flat = lambda cc: (lambda zz: _sys_flat(zz, par, rtol, cc))
            a_lin, M_lin, V_lin, _ = linear_flat_contact(c, T, w, EI)
            try:
                if a_lin >= 0.5 * L:
                    raise RuntimeError("linear guess outside the span")
                z = _newton(mk_flat(c), [a_lin / aT, M_lin, V_lin])
            except RuntimeError:
                zt = _solve_transition(T, par, rtol, L, zf)
                c1 = -integrate_span(zt[1], zt[2], zt[0], *par, rtol=rtol).y[1, -1]
                z = _continuation(mk_flat, zt, c1, c, n=12)
            regime, s_span = "flat", z[0]

    s_span = float(s_span)
    M0 = float(z[1])
    V0 = float(-w * z[0]) if regime == "free" else float(z[2])
    res = integrate_span(M0, V0, s_span, *par, rtol=rtol)
    sol = res.sol
    ye = res.y[:, -1]
    zmin_span, ys = _span_min_z(sol, s_span)

    out = dict(contact=regime != "free", regime=regime, M0=M0, V0=V0, clamp_reaction=-V0,
               alpha_T=aT, c=float(c), T=float(T), span=sol, s_span=s_span)
    if regime == "free":
        out.update(x_touchdown=np.nan, s_touchdown=np.nan, R=np.nan, l0=2 * s_span,
                   l=2 * ye[5], min_z=min(zmin_span, ye[1]), contact_force_per_x=np.nan,
                   total_side_force=0.0, M_mid=float(ye[3]))
        a = 0.5 * L
    elif regime == "point":
        P = 2.0 * (V0 + w * s_span)
        out.update(x_touchdown=0.5 * L, s_touchdown=s_span, R=0.5 * P, l0=2 * s_span,
                   l=2 * ye[5], min_z=-float(c), contact_force_per_x=np.nan,
                   total_side_force=P, M_mid=float(ye[3]))
        a = 0.5 * L
    else:
        a = float(ye[0])
        R = V0 + w * s_span
        lz0 = (L - 2 * a) / aT
        out.update(x_touchdown=a, s_touchdown=s_span, R=R, l0=2 * s_span + lz0,
                   l=2 * ye[5] + (L - 2 * a), min_z=-float(c), contact_force_per_x=w / aT,
                   total_side_force=2 * R + w * lz0, M_mid=0.0)
    out["stretch"] = (out["l"] - L) / L

    # validity of the accepted solution
    if out["contact"]:
        inner = ys[1, 1:-1]
        if out["R"] < -1e-12 or out["M_mid"] < -1e-12 or a > 0.5 * L + 1e-12:
            raise RuntimeError("contact solution violates R >= 0, m_mid >= 0 or a <= L/2")
        if np.any(inner < -c - 1e-13):
            raise RuntimeError("free span penetrates the wall")

    def shape(x):
        x = np.asarray(x, float)
        xm = np.where(x <= 0.5 * L, x, L - x)          # symmetry
        zz = np.full(xm.shape, -float(c))
        on_span = xm <= a
        if np.any(on_span):
            s = _inverse_x(sol, s_span, f_x, np.minimum(xm[on_span], ye[0]))
            zz[on_span] = sol(s)[1]
        return zz

    out["shape"] = shape
    return out


def onset_clearance(T, w=10., EI=1., EA=255., L=1., rtol=1e-12):
    """Clearance ``c0`` at which contact begins: ``-min z`` of the free solution."""
    par = (float(T), float(w), float(EI), float(EA))
    zf = _solve_free(T, par, rtol, L)
    res = integrate_span(zf[1], -w * zf[0], zf[0], *par, rtol=rtol)
    zmin, _ = _span_min_z(res.sol, zf[0])
    return -min(zmin, res.y[1, -1])


def flat_onset_clearance(T, w=10., EI=1., EA=255., L=1., rtol=1e-12):
    """Clearance ``c1`` below which the contact is a flat zone: point contact
    at midspan with zero midspan moment (``a = L/2``).  Returns
    ``(c1, dict(s_half, M0, V0, R))`` (``R`` = half the midspan reaction)."""
    par = (float(T), float(w), float(EI), float(EA))
    zf = _solve_free(T, par, rtol, L)
    zt = _solve_transition(T, par, rtol, L, zf)
    y = integrate_span(zt[1], zt[2], zt[0], *par, rtol=rtol).y[:, -1]
    return -y[1], dict(s_half=zt[0], M0=zt[1], V0=zt[2], R=zt[2] + w * zt[0])
