r"""Closed-form references for the "Your own problem" examples (issue 21, item 3).

An *independent* reference for the test-suite: numpy and scipy only, nothing
from ``rodcont``.  Three scalar boundary value problems with closed forms, each
cross-checked by shooting (``tests/test_bvp_reference_selfcheck.py``):

1. Bratu, ``u'' + lam e^u = 0``, ``u(0) = u(1) = 0`` (a fold in ``lam``);
2. Troesch, ``u'' = lam sinh(lam u)``, ``u(0) = 0``, ``u(1) = 1`` (a boundary
   layer at ``x = 1`` for large ``lam``);
3. the pinned planar elastica with an integral condition (the end shortening)
   and the load as a freed parameter (as AUTO's NINT).

Bratu
=====
``u = -2 ln[cosh((x - 1/2) theta/2) / cosh(theta/4)]`` gives
``u' = -theta tanh((x - 1/2) theta/2)`` and
``u'' = -(theta^2/2) sech^2((x - 1/2) theta/2) = -(theta^2 / (2 cosh^2(theta/4))) e^u``,
so it solves the problem iff ``lam = theta^2 / (2 cosh^2(theta/4))``, i.e.
``theta = sqrt(2 lam) cosh(theta/4)``, and ``u(0) = u(1) = 0`` holds by
symmetry.  ``theta`` parametrises the whole branch (``theta`` in (0, inf)):

* ``u'(0) = theta tanh(theta/4)`` and ``max u = u(1/2) = 2 ln cosh(theta/4)``,
  both increasing in ``theta`` (so either labels a point of a traced branch);
* ``d lam / d theta = 0`` where ``(theta/4) tanh(theta/4) = 1``: with
  ``y = theta*/4 = 1.19967864025773...`` (``y tanh y = 1``) and
  ``1/cosh^2 y = 1 - 1/y^2`` the fold is ``lam* = 8 (y^2 - 1) = 3.51383071912516121``
  (50-digit Newton in ``decimal``) and ``u'(0) = 4 y tanh y = 4`` exactly there;
  ``theta < theta*`` is the lower (stable) branch, ``theta > theta*`` the upper.

Troesch
=======
Multiplying by ``u'`` gives the first integral
``u'^2 = s^2 + 2 (cosh(lam u) - 1) = s^2 + 4 sinh^2(lam u / 2)``, ``s = u'(0)``,
hence ``x(u) = int_0^u du / sqrt(s^2 + 4 sinh^2(lam u/2))``.  With
``v = lam u/2``, ``t = sinh v`` and ``t = (s/2) y``:

    lam x(u) = int_0^Y dy / sqrt((1 + y^2)(1 + k'^2 y^2)),  Y = 2 sinh(lam u/2)/s,
    k'^2 = s^2/4.

Since ``d sc(w|m)/dw = dn/cn^2 = sqrt((1 + sc^2)(1 + (1 - m) sc^2))``, the
integral is ``sc^{-1}(Y | m)`` with the *parameter* ``m = k^2 = 1 - s^2/4``
(scipy's ``ellipj(u, m)`` convention), and ``u(1) = 1`` becomes the closed form
of the issue,

    sinh(lam/2) = (s/2) sc(lam | 1 - s^2/4),   lam < K(m) (sc finite).

Equivalently ``lam = F(phi | m)``, ``phi = arctan(2 sinh(lam/2)/s) = am(lam|m)``.
For large ``lam``, ``s ~ 8 e^{-lam}`` and ``1 - m = s^2/4`` is ~3e-8 at
``lam = 10``: ``m`` rounded in double precision loses ~1e-9 of ``K(m)``, so
``ellipj`` cannot give 1e-12 there (:func:`troesch_slope_ellipj` shows it).
:func:`troesch_slope` therefore evaluates ``F`` by Carlson's symmetric
integral with the complementary parameter kept exact,

    F(phi | m) = sin(phi) R_F(cos^2 phi, cos^2 phi + (s^2/4) sin^2 phi, 1),

with ``cos^2 phi = 1/(1 + Y^2)``, ``sin phi = Y / sqrt(1 + Y^2)`` (no
cancellation anywhere), and solves ``F/lam = 1`` for ``ln s`` by Brent's method.
``lam = 10``: ``u'(0) = 3.5833778463e-4`` (the literature's 3.58e-4).

Pinned elastica with an integral condition
=========================================
``theta'' + P sin(theta) = 0`` on ``s`` in [0, 1] (``EI = 1``, ``theta`` the
tangent angle, ``P`` the compressive end load), ``theta'(0) = theta'(1) = 0``
(pins: no end moment), ``int_0^1 cos(theta) ds = 1 - delta`` (``delta`` the
end shortening, the continued parameter), ``P`` free.

First integral: ``theta'^2 = 2P (cos theta - cos theta0) = 4P (k^2 - sin^2(theta/2))``,
``k = sin(theta0/2)``, ``theta0 = theta(0)``.  With ``sin(theta/2) = k sn(psi | m)``,
``m = k^2``: ``theta' = 2 k cn(psi) psi'`` and the right side is ``4 P k^2 cn^2``,
so ``psi' = -sqrt(P)``; ``theta'(0) = 0`` puts ``psi(0) = K(m)`` and the first
mode has ``theta'(1) = 0`` at ``psi(1) = -K``:

    sqrt(P) = 2 K(m),   P = (2 K(m))^2,   theta(s) = 2 arcsin(k sn(K (1 - 2s) | m)),

``theta(1) = -theta0`` (odd about ``s = 1/2``, so ``int sin(theta) = 0``: the
ends stay on the line of the load).  With ``cos theta = 1 - 2 k^2 sn^2 psi``
and ``int_0^K k^2 sn^2 = K - E``:

    int_0^1 cos(theta) ds = 2 E(m)/K(m) - 1 = 1 - delta,   delta = 2 - 2 E/K,

``E, K`` complete integrals of parameter ``m = k^2`` (scipy ``ellipe``,
``ellipk``).  The shape: ``x(s) = [2 (E(m) - E(am psi | m)) - (K - psi)] / (2K)``,
``y(s) = (k/K) cn(psi | m)``, so the mid-span deflection is ``k/K``.

* ``delta(m)`` increases from 0 to 2 on ``m`` in [0, 1).  Near ``delta = 0``:
  ``m = delta + O(delta^2)``, ``theta0 ~ 2 sqrt(delta)``,
  ``theta ~ theta0 cos(pi s)`` and ``P = pi^2 (1 + delta/2 + O(delta^2))``:
  the branch bifurcates (pitchfork, ``theta -> -theta``) from the straight state
  ``theta = 0`` at ``delta = 0``, ``P = pi^2`` (Euler's load); the straight
  state is a vertical line ``delta = 0``, every ``P``.
* ``delta = 1`` (``m = 0.8261..., theta0 = 130.7 deg``): the ends meet;
  past it ``1 - delta < 0``, the ends have passed through each other and the
  rod crosses itself (a loop; self-contact is not modelled).  As
  ``delta -> 2``, ``m -> 1``, ``P -> inf``: two nearly straight tails pointing
  back (``theta -> +-pi``) joined by a tight loop of size ``~ 1/sqrt(P)``.
* Mode ``n`` (``sqrt(P) = 2 n K``) has the same ``delta(m)``: ``P_n = n^2 P_1``.
* The reduced problem above (only the horizontal load) also admits the rigid
  rotation ``theta = arccos(1 - delta)``, ``P = 0``, which violates the
  ignored condition ``int sin(theta) = 0``: a continuation should start on
  the first mode (e.g. from the small-``delta`` form above), not from a
  constant ``theta``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipe, ellipj, ellipk, ellipkm1, elliprd, elliprf

__all__ = [
    "bratu_fold",
    "bratu_lambda",
    "bratu_max",
    "bratu_slope",
    "bratu_solution",
    "bratu_theta",
    "bratu_theta_from_max",
    "bratu_theta_from_slope",
    "elastica_delta",
    "elastica_load",
    "elastica_parameter",
    "elastica_shape",
    "elastica_theta",
    "elastica_theta0",
    "troesch_slope",
    "troesch_slope_ellipj",
    "troesch_solution",
]

_XTOL = 1e-15


# ----------------------------------------------------------------------------
# Bratu
# ----------------------------------------------------------------------------
def _fold_y():
    """Root of y tanh(y) = 1 (y = theta*/4)."""
    return brentq(lambda y: y * np.tanh(y) - 1.0, 1.0, 1.5, xtol=1e-16)


def bratu_lambda(theta):
    """lam on the branch at parameter theta: lam = theta^2 / (2 cosh^2(theta/4))."""
    theta = np.asarray(theta, dtype=float)
    return theta ** 2 / (2.0 * np.cosh(theta / 4.0) ** 2)


def bratu_slope(theta):
    """u'(0) = theta tanh(theta/4) (increasing in theta)."""
    theta = np.asarray(theta, dtype=float)
    return theta * np.tanh(theta / 4.0)


def bratu_max(theta):
    """max u = u(1/2) = 2 ln cosh(theta/4) (increasing in theta)."""
    theta = np.asarray(theta, dtype=float)
    return 2.0 * np.log(np.cosh(theta / 4.0))


def bratu_fold():
    """The fold of the Bratu branch.

    Returns dict ``lam`` (8 (y^2 - 1) = 3.513830719125161...), ``theta``
    (4 y, y tanh y = 1), ``slope`` (u'(0)) and ``u_max`` there.
    """
    th = 4.0 * _fold_y()
    # lam(theta) is stationary at the fold: evaluating it at the rounded theta
    # gives lam* to 1 ulp, where 8 (y^2 - 1) would carry 16 y times y's error.
    return {"lam": float(bratu_lambda(th)), "theta": th, "slope": float(bratu_slope(th)),
                "u_max": float(bratu_max(th))}


def bratu_theta(lam, branch="lower"):
    """theta of the solution at ``lam`` (0 < lam <= lam*).

    ``branch``: ``"lower"`` (theta <= theta*, the stable branch, u -> 0 as
    lam -> 0) or ``"upper"`` (theta >= theta*, u -> inf as lam -> 0).  Root of
    theta / cosh(theta/4) = sqrt(2 lam) by Brent's method.
    """
    lam = float(lam)
    fold = bratu_fold()
    if not 0.0 < lam <= fold["lam"] * (1 + 1e-15):
        raise ValueError(f"lam = {lam} outside (0, lam*]")
    ths = fold["theta"]
    g = lambda th: th / np.cosh(th / 4.0) - np.sqrt(2.0 * lam)
    if g(ths) <= 0.0:             # at the fold to rounding
        return ths
    if branch == "lower":
        return brentq(g, 0.0, ths, xtol=_XTOL)
    if branch == "upper":
        hi = 2.0 * ths
        while g(hi) > 0.0:
            hi *= 2.0
        return brentq(g, ths, hi, xtol=_XTOL)
    raise ValueError(f"branch must be 'lower' or 'upper', not {branch!r}")


def bratu_theta_from_slope(slope):
    """theta with theta tanh(theta/4) = slope (slope = u'(0) > 0)."""
    slope = float(slope)
    hi = max(2.0, 2.0 * slope)
    return brentq(lambda th: bratu_slope(th) - slope, 0.0, hi, xtol=_XTOL)


def bratu_theta_from_max(u_max):
    """theta with 2 ln cosh(theta/4) = u_max (u_max >= 0)."""
    return 4.0 * np.arccosh(np.exp(0.5 * float(u_max)))


def bratu_solution(x, lam, branch="lower"):
    """u(x) and u'(x) on ``branch`` at ``lam`` (see :func:`bratu_theta`)."""
    th = bratu_theta(lam, branch)
    x = np.asarray(x, dtype=float)
    a = (x - 0.5) * th / 2.0
    u = -2.0 * (np.log(np.cosh(a)) - np.log(np.cosh(th / 4.0)))
    return u, -th * np.tanh(a)


# ----------------------------------------------------------------------------
# Troesch
# ----------------------------------------------------------------------------
def _troesch_F(Y, s):
    """F(arctan Y | 1 - s^2/4) by Carlson's R_F, complementary parameter exact."""
    c2 = 1.0 / (1.0 + Y * Y)
    sn = Y * np.sqrt(c2)
    return sn * elliprf(c2, c2 + 0.25 * s * s * sn * sn, 1.0)


def _log_slope_bracket(fun, lam):
    """[a, b] in ln s with fun(a) > 0 > fun(b) (fun decreasing in ln s)."""
    hi = 0.0                       # s = 1: u'(0) < 1 since u is convex
    lo = min(-1.0, np.log(8.0) - lam - 5.0)
    while fun(lo) <= 0.0:
        lo -= 5.0
    if fun(hi) >= 0.0:
        raise RuntimeError("Troesch: no sign change at s = 1")
    return lo, hi


def troesch_slope(lam):
    """u'(0) of Troesch's problem at ``lam`` >= 0, to ~1e-14 relative.

    Solves ``F(arctan(2 sinh(lam/2)/s) | 1 - s^2/4) = lam`` (the closed form
    ``sinh(lam/2) = (s/2) sc(lam | 1 - s^2/4)``, see the module docstring) for
    ``ln s`` with Carlson's ``R_F``.  ``lam = 0`` gives 1 (u = x).
    """
    lam = float(lam)
    if lam < 0.0:
        raise ValueError("lam must be >= 0")
    if lam == 0.0:
        return 1.0
    sh = np.sinh(0.5 * lam)

    def fun(ls):
        s = np.exp(ls)
        return _troesch_F(2.0 * sh / s, s) / lam - 1.0

    lo, hi = _log_slope_bracket(fun, lam)
    return float(np.exp(brentq(fun, lo, hi, xtol=1e-15, rtol=1e-15)))


def troesch_slope_ellipj(lam):
    """u'(0) from the literal form sinh(lam/2) = (s/2) sc(lam | 1 - s^2/4).

    Uses ``scipy.special.ellipj`` with the parameter ``m = 1 - s^2/4``: a
    check of the closed form's conventions.  Accurate to ~1e-14 for
    moderate ``lam``; for large ``lam`` (``m`` near 1) the rounding of ``m``
    limits it (about 1e-9 relative at ``lam = 10``, see module docstring).
    """
    lam = float(lam)
    sh = np.sinh(0.5 * lam)

    def fun(ls):
        s = np.exp(ls)
        m = 1.0 - 0.25 * s * s
        if lam >= ellipk(m):                # at or past the pole of sc(. | m)
            return -1.0
        sn, cn, _, _ = ellipj(lam, m)
        return 1.0 - 0.5 * s * sn / (cn * sh)

    lo, hi = _log_slope_bracket(fun, lam)
    return float(np.exp(brentq(fun, lo, hi, xtol=1e-15, rtol=1e-15)))


def troesch_solution(x, lam):
    """u(x) of Troesch's problem (array x in [0, 1]), with u'(x).

    Inverts ``lam x = F(arctan(2 sinh(lam u/2)/s) | 1 - s^2/4)`` for ``u`` at
    each ``x`` (Brent, 1e-15), ``u' = sqrt(s^2 + 4 sinh^2(lam u/2))``.
    """
    lam = float(lam)
    s = troesch_slope(lam)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    if lam == 0.0:
        return x.copy(), np.ones_like(x)
    u = np.empty_like(x)
    for i, xi in enumerate(x):
        if xi <= 0.0:
            u[i] = 0.0
            continue
        f = lambda v, xi=xi: _troesch_F(2.0 * np.sinh(0.5 * lam * v) / s, s) - lam * xi
        u[i] = 1.0 if xi >= 1.0 else brentq(f, 0.0, 1.0, xtol=1e-16)
    return u, np.sqrt(s * s + 4.0 * np.sinh(0.5 * lam * u) ** 2)


# ----------------------------------------------------------------------------
# Pinned elastica, end shortening delta prescribed, load P free
# ----------------------------------------------------------------------------
def elastica_delta(m):
    """End shortening delta = 2 - 2 E(m)/K(m) of the first mode, m = k^2."""
    m = np.asarray(m, dtype=float)
    return 2.0 - 2.0 * ellipe(m) / ellipk(m)


def _elastica_mp(delta):
    """(m, p = 1 - m) at end shortening delta in (0, 2), each to full relative precision.

    For ``delta <= delta(1/2)`` Brent on ``m``; beyond, on ``ln p`` with
    ``K = ellipkm1(p)`` (``m`` near 1 is not representable well enough: ``P``
    and ``theta0`` would lose digits).  ``p`` down to 1e-300 (``delta`` up to
    1.994) is reachable.
    """
    delta = float(delta)
    if not 0.0 < delta < 2.0:
        raise ValueError("delta must lie in (0, 2)")
    if delta <= float(elastica_delta(0.5)):
        m = brentq(lambda m: float(elastica_delta(m)) - delta, 0.0, 0.5,
                   xtol=1e-300, rtol=1e-15)
        return m, 1.0 - m
    f = lambda lp: 2.0 - 2.0 * ellipe(-np.expm1(lp)) / ellipkm1(np.exp(lp)) - delta
    if f(-690.0) < 0.0:
        raise ValueError("delta too close to 2 for double precision")
    lp = brentq(f, -690.0, np.log(0.5), xtol=1e-15, rtol=1e-15)
    return -np.expm1(lp), np.exp(lp)


def elastica_parameter(delta):
    """m = k^2 = sin^2(theta0/2) of the first mode at end shortening delta in (0, 2)."""
    return _elastica_mp(delta)[0]


def elastica_load(delta):
    """Load P = (2 K(m))^2 on the first mode at end shortening delta (EI = 1, length 1)."""
    return float(4.0 * ellipkm1(_elastica_mp(delta)[1]) ** 2)


def elastica_theta0(delta):
    """End angle theta(0) = 2 arccos(sqrt(1 - m)) > 0 (theta(1) = -theta(0))."""
    return float(2.0 * np.arccos(np.sqrt(_elastica_mp(delta)[1])))


def elastica_theta(s, delta):
    """Tangent angle theta(s) = 2 arcsin(k sn(K (1 - 2 s) | m)) and theta'(s).

    ``theta' = -2 k sqrt(P) cn(psi) = -4 k K cn(psi)``, ``psi = K (1 - 2 s)``.
    ``ellipj`` takes ``m`` itself, so the relative accuracy is about
    ``1e-16 / (1 - m)``: 1e-13 for ``delta <= 1.5``.
    """
    m, p = _elastica_mp(delta)
    k, K = np.sqrt(m), ellipkm1(p)
    sn, cn, _, _ = ellipj(K * (1.0 - 2.0 * np.asarray(s, dtype=float)), m)
    return 2.0 * np.arcsin(k * sn), -4.0 * k * K * cn


def _ellipeinc(phi, m, p):
    """E(phi | m) for |phi| <= pi/2 by Carlson's R_F, R_D, with p = 1 - m exact.

    scipy's ``ellipeinc`` jumps at isolated points (scipy issue 19498; seen
    here: E(1.18724..., 0.098717...) = 1.549 instead of 1.166).
    """
    s, c = np.sin(phi), np.cos(phi)
    c2 = c * c
    y = c2 + p * s * s
    return s * elliprf(c2, y, 1.0) - (m / 3.0) * s ** 3 * elliprd(c2, y, 1.0)


def elastica_shape(s, delta):
    """Centreline (x(s), y(s)) from the pin at the origin, load along x.

    ``x = [2 (E(m) - E(am psi | m)) - (K - psi)] / (2K)``,
    ``y = (k/K) cn(psi | m)``, ``psi = K (1 - 2 s)``; ``x(1) = 1 - delta``,
    ``y(0) = y(1) = 0``, ``y(1/2) = k/K``.  Accuracy as :func:`elastica_theta`.
    """
    m, p = _elastica_mp(delta)
    k, K = np.sqrt(m), ellipkm1(p)
    psi = K * (1.0 - 2.0 * np.asarray(s, dtype=float))
    _, cn, _, ph = ellipj(psi, m)
    x = (2.0 * (ellipe(m) - _ellipeinc(ph, m, p)) - (K - psi)) / (2.0 * K)
    return x, (k / K) * cn
