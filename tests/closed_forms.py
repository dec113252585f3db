r"""Closed-form reference: critical twists of a clamped, pulled, self-fed rod.

This module is an *independent* reference for the test-suite.  It does not
import anything from ``rodcont``; it only uses numpy and scipy.

Problem
=======
A straight, weightless, extensible, unshearable, isotropic Cosserat rod
(bending stiffness EI, torsional stiffness GJ, axial stiffness EA) is clamped
at both ends of a fixed span L::

    r(0) = 0,  r(l0) = L e1,  d3(0) = d3(l0) = e1,

the end section being rotated by the angle Phi about e1.  The axial tension T
is prescribed (T > 0 pulls; T <= 0 is compression) and the unstressed length
l0 is *not* prescribed: the rod is fed through the ends until the tension is
T.  With s the unstressed arclength, s in [0, l0]::

    F_s = 0,   M_s + r_s x F = 0,   r_s = alpha d3,
    M = EI (u1 d1 + u2 d2) + GJ u3 d3,   F.d3 = EA (alpha - 1),

where u is the Darboux vector (d_i' = u x d_i) per unit *unstressed* length.

Straight state
--------------
F = T e1, d3 = e1, stretch alpha = 1 + T/EA (we need alpha > 0, i.e.
T > -EA), so the unstressed length is l0 = L/alpha, the twist is
u3 = Phi/l0 and the twisting moment is

    m = GJ u3 = GJ Phi / l0 = GJ alpha Phi / L.

Linearisation
=============
Because M.d3_s = 0 and (r_s x F).d3 = 0, the d3-component of the moment
balance gives (GJ u3)_s = 0 exactly, so the twisting moment is a constant m.
For an unshearable rod u1 d1 + u2 d2 = d3 x d3_s, hence

    M = EI d3 x d3_s + m d3,     M_s = EI d3 x d3_ss + m d3_s.

Perturb: d3 = e1 + theta, F = T e1 + f, with theta, f transverse (first
order; the axial perturbations of F and l0 only move the rod along e1 and
decouple).  The perturbation of the twist is a constant delta u3 = psi_1'
(psi = linearised rotation vector) and psi_1(0) = psi_1(l0) = 0 because the
end rotation is held at Phi, so delta u3 = 0 and m is unchanged at first
order.  The perturbation of alpha multiplies e1 x T e1 = 0.  Hence

    EI e1 x theta'' + m theta' + alpha e1 x f - alpha T e1 x theta = 0.

Complex notation.  Identify a transverse vector a e2 + b e3 with a + i b;
then e1 x (.) is multiplication by i.  With w = theta_2 + i theta_3 (the
complex tangent tilt), c = f_2 + i f_3, and dividing by i:

    EI w'' - i m w' - alpha T w = -alpha c,                     (1)

and the complex transverse displacement Y = r_2 + i r_3 obeys Y' = alpha w.
Clamping gives w(0) = w(l0) = 0 and Y(0) = Y(l0) = 0, i.e. int_0^l0 w ds = 0.
Eliminating the constant shear force c, the displacement obeys the
4th-order equation

    EI Y'''' - i m Y''' - alpha T Y'' = 0,  Y = Y' = 0 at s = 0, l0.   (2)

How extensibility enters
------------------------
Change to the *physical* coordinate x = alpha s in [0, L] (d/ds = alpha d/dx)
and divide (1) by alpha:

    (EI alpha) w_xx - i m w_x - T w = -c.

So the extensible problem is the inextensible one with

  * effective bending stiffness  EI_eff = alpha EI  (alpha = 1 + T/EA),
  * the rod living on the deformed length L (not l0 = L/alpha),
  * twisting moment m = GJ alpha Phi / L (m grows with alpha at fixed Phi).

With xi = x/L in [0, 1] the dimensionless torque and tension are

    mu  = m L / EI_eff = GJ Phi / EI          (alpha cancels!)
    tau = T L^2 / EI_eff = T L^2 / (EI (1 + T/EA)),

and the displacement y(xi) satisfies y'''' - i mu y''' - tau y'' = 0 with
y = y' = 0 at xi = 0, 1.  Extensibility therefore only renormalises the
tension: Phi_n = EI mu_n(tau) / GJ, with mu_n(tau) the critical torques of
Greenhill's clamped problem.  The (extensible, clamped) Euler load tau = -4 pi^2
corresponds to T_E = -(4 pi^2 EI/L^2) / (1 + 4 pi^2 EI/(EA L^2)).

Characteristic roots
--------------------
Y = exp(lambda xi) gives lambda^2 (lambda^2 - i mu lambda - tau) = 0:

    lambda = 0 (double),   lambda_pm = i mu/2 pm q,   q = sqrt(4 tau - mu^2)/2.

Write a = mu/2, so tau = q^2 + a^2.

Clamped determinant
-------------------
With the basis {1, xi, exp(lambda_+ xi), exp(lambda_- xi)} the four
clamped conditions give

            | 1  0  1                1                |
    Det4 =  | 0  1  lambda_+         lambda_-         |
            | 1  1  E_+              E_-              |     E_pm = exp(lambda_pm)
            | 0  1  lambda_+ E_+     lambda_- E_-     |

which evaluates (checked symbolically) to

    Det4 = 2 q exp(i mu/2) G(mu, tau),
    G    = 2 (cosh q - cos(mu/2)) - tau sinh(q)/q.

The complex phase exp(i mu/2) never vanishes and G is REAL (it is even in
q, i.e. a function of q^2 = tau - mu^2/4).  The factor 2q and a factor
tau^2 inside G are artefacts of the basis degenerating (lambda_+ = lambda_-
at q = 0, lambda_- -> 0 as tau -> 0); the properly normalised (confluent
Vandermonde) determinant is the entire real function

    H(mu, tau) = G(mu, tau) / tau^2,

and the critical torques are the positive roots mu_n of H(mu, tau) = 0.  Since
the linear problem is C-linear (rotating a mode, Y -> exp(i beta) Y, gives a
mode), every root is a real two-dimensional kernel (a circle of helical
modes): it is listed once.  H is even in mu (Phi -> -Phi).

Cases of D = 4 tau - mu^2
-------------------------
* D > 0 (only possible for tau > 0), q real:
      H = [2 (cosh q - cos a) - tau sinh(q)/q] / tau^2.
  There are NO roots here: using 2 cos a >= 2 - a^2 and tau = q^2 + a^2,
  tau^2 H <= 2 cosh q - 2 - q sinh q + a^2 (1 - sinh(q)/q) < 0 for q > 0.
* D = 0 (q = 0):  H = [2 (1 - cos a) - tau] / tau^2 = [2 (1 - cos a) - a^2]/a^4 < 0.
  So for tau > 0 every critical torque exceeds the helical (infinite-rod)
  value mu = 2 sqrt(tau), i.e. m^2 > 4 EI_eff T.
* D < 0 (always for tau <= 0), q = i kappa, kappa = sqrt(mu^2/4 - tau) > 0:
      tau^2 H = G = 2 (cos kappa - cos a) - tau sin(kappa)/kappa.
  This suffers catastrophic cancellation as tau -> 0 (G = O(tau^2)).  An
  exact cancellation-free form follows from the half-sum/difference
      sigma = (a + kappa)/2,  h = (a - kappa)/2 = tau / (2 (a + kappa)),
  (so a = sigma + h, kappa = sigma - h, a^2 - kappa^2 = 4 sigma h = tau):
      cos kappa - cos a = 2 sin sigma sin h,
      G = (4 h^2 / kappa) R,   i.e.   H = R / (kappa (a + kappa)^2),
      R(mu, tau) = sinc(h) (sigma cos sigma - sin sigma) + sigma sin(sigma) psi(h),
      sinc(h) = sin(h)/h,   psi(h) = (sin h - h cos h)/h^2  (= h/3 - h^3/30 + ...).
  Since kappa (a + kappa)^2 > 0, the roots for D < 0 are exactly the roots of

      R(mu, tau) = 0.                                               (*)

  tau < 0 (compression) is covered by this same formula (kappa > a, h < 0).
* tau = 0 (T = 0): h = 0, sigma = a, so R = a cos a - sin a and (*) is
  Greenhill's  tan(mu/2) = mu/2, i.e. mu_1 = 2 x 4.493409... = 8.986818...
  (mu_1 is the first positive root of tan(x/2) = x/2, equivalently twice the
  first positive root of tan x = x).
* At the clamped Euler loads (tau = -4 pi^2, tau = -80.763...), mu = 0 is a
  root: the straight rod buckles without twist.  For -4 pi^2 < tau the
  critical twists are the stability thresholds; below the Euler load the
  roots of H still mark loss of uniqueness of the straight state, but the
  straight state is already unstable at Phi = 0.

Numerics: H is sampled on a fine grid in mu (starting at 2 sqrt(tau) for
tau > 0, where there are provably no roots below), sign changes are bracketed
and refined with scipy.optimize.brentq to ~1e-14 absolute in mu.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

__all__ = [
    "effective_tension",
    "characteristic_function",
    "critical_torques",
    "greenhill_torque",
    "critical_twists",
    "extensible_euler_load",
]

_EULER_TAU = -4.0 * np.pi ** 2


def effective_tension(T, EI=1.0, EA=255.0, L=1.0):
    """Dimensionless tension tau = T L^2 / (EI alpha), alpha = 1 + T/EA."""
    alpha = 1.0 + T / EA
    if not alpha > 0.0:
        raise ValueError(f"stretch alpha = 1 + T/EA = {alpha} must be positive")
    return T * L ** 2 / (EI * alpha)


def extensible_euler_load(EI=1.0, EA=255.0, L=1.0):
    """Tension T (< 0) at which tau = -4 pi^2 (clamped-clamped Euler load)."""
    p = 4.0 * np.pi ** 2 * EI / L ** 2
    return -p / (1.0 + p / EA)


def _psi(h):
    """(sin h - h cos h)/h^2, accurate for small |h| (vectorised)."""
    h = np.asarray(h, dtype=float)
    out = np.empty_like(h)
    small = np.abs(h) < 0.1
    hs = h[small]
    h2 = hs * hs
    out[small] = hs * (1.0 / 3.0 + h2 * (-1.0 / 30.0 + h2 * (1.0 / 840.0
                       + h2 * (-1.0 / 45360.0 + h2 / 3991680.0))))
    hb = h[~small]
    out[~small] = (np.sin(hb) - hb * np.cos(hb)) / (hb * hb)
    return out


def characteristic_function(mu, tau):
    """Normalised clamped determinant H(mu, tau) = G / tau^2 (real, entire).

    ``mu`` may be an array (mu >= 0), ``tau`` a scalar.  The critical
    dimensionless torques are the positive roots of H.  See the module
    docstring for the derivation and the three cases of D = 4 tau - mu^2.
    """
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    tau = float(tau)
    a = 0.5 * np.abs(mu)
    D = 4.0 * tau - mu * mu
    H = np.empty_like(mu)

    # D > 0: q real (tau > 0 necessarily).
    pos = D > 0
    if np.any(pos):
        q = 0.5 * np.sqrt(D[pos])
        H[pos] = (2.0 * (np.cosh(q) - np.cos(a[pos]))
                  - tau * np.sinh(q) / q) / tau ** 2

    # D == 0: q -> 0 limit.
    zero = D == 0
    if np.any(zero):
        if tau == 0.0:          # mu = tau = 0: limit of -(sin a - a cos a)/(4 a^3)
            H[zero] = -1.0 / 12.0
        else:
            H[zero] = (2.0 * (1.0 - np.cos(a[zero])) - tau) / tau ** 2

    # D < 0: q = i kappa.
    neg = D < 0
    if np.any(neg):
        an = a[neg]
        kap = np.sqrt(an * an - tau)
        Hn = np.empty_like(an)
        # kappa small compared with a (only when tau > 3 a^2 / 4 > 0): the
        # plain cosine form has no tau -> 0 cancellation there, whereas
        # R / kappa would lose digits as kappa -> 0.
        near = kap < 0.5 * an
        if np.any(near):
            k, aa = kap[near], an[near]
            G = (-4.0 * np.sin(0.5 * (k + aa)) * np.sin(0.5 * (k - aa))
                 - tau * np.sinc(k / np.pi))
            Hn[near] = G / tau ** 2
        far = ~near
        if np.any(far):
            k, aa = kap[far], an[far]
            sig = 0.5 * (aa + k)
            h = tau / (2.0 * (aa + k))
            R = (np.sinc(h / np.pi) * (sig * np.cos(sig) - np.sin(sig))
                 + sig * np.sin(sig) * _psi(h))
            Hn[far] = R / (k * (aa + k) ** 2)
        H[neg] = Hn
    return H


def critical_torques(tau, mu_max, dmu=0.005, xtol=1e-14):
    """Sorted positive roots mu_n < mu_max of H(mu, tau) = 0 (see module doc)."""
    tau = float(tau)
    mu_lo = 2.0 * np.sqrt(tau) if tau > 0 else 0.0
    if mu_max <= mu_lo:
        return np.empty(0)
    n = max(int(np.ceil((mu_max - mu_lo) / dmu)), 2)
    grid = np.linspace(mu_lo, mu_max, n + 1)
    vals = characteristic_function(grid, tau)
    f = lambda x: float(characteristic_function(x, tau)[0])
    roots = []
    for i in range(n):
        v0, v1 = vals[i], vals[i + 1]
        if v0 == 0.0:
            if grid[i] > 0.0:
                roots.append(grid[i])
            continue
        if v0 * v1 < 0.0:
            roots.append(brentq(f, grid[i], grid[i + 1], xtol=xtol,
                                rtol=4 * np.finfo(float).eps, maxiter=200))
    if vals[-1] == 0.0 and grid[-1] > 0.0:
        roots.append(grid[-1])
    return np.array(sorted(r for r in roots if 0.0 < r < mu_max))


def greenhill_torque(tau):
    """Smallest critical dimensionless torque mu = m L / EI_eff at tension tau.

    tau = T L^2 / EI_eff (EI_eff = EI for an inextensible rod).  tau = 0 gives
    Greenhill's 8.98681892... (first positive root of tan(mu/2) = mu/2).
    Requires tau > -4 pi^2 (below the clamped Euler load in magnitude).
    """
    tau = float(tau)
    if not tau > _EULER_TAU:
        raise ValueError("tau must exceed the clamped Euler load -4 pi^2")
    mu_max = 2.0 * np.sqrt(max(tau, 0.0)) + 20.0
    while True:
        r = critical_torques(tau, mu_max)
        if r.size:
            return float(r[0])
        mu_max *= 2.0


def critical_twists(T, EI=1.0, GJ=0.75, EA=255.0, L=1.0, phi_max=40.0):
    """Sorted positive critical end rotations Phi_n < phi_max (each listed once).

    T is the prescribed axial tension (T < 0: compression; need T > -EA).
    With alpha = 1 + T/EA, tau = T L^2 / (EI alpha) and mu = GJ Phi / EI, the
    Phi_n = EI mu_n / GJ where mu_n are the positive roots of the real
    equation H(mu, tau) = 0, i.e. for D = 4 tau - mu^2 < 0 (the only case
    with roots):

        sinc(h) (sigma cos sigma - sin sigma) + sigma sin(sigma) psi(h) = 0,
        kappa = sqrt(mu^2/4 - tau), sigma = (mu/2 + kappa)/2,
        h = tau / (mu + 2 kappa),  psi(h) = (sin h - h cos h)/h^2,

    equivalently (tau != 0)  2 (cos kappa - cos(mu/2)) = tau sin(kappa)/kappa.
    """
    tau = effective_tension(T, EI=EI, EA=EA, L=L)
    mu = critical_torques(tau, GJ * phi_max / EI)
    phi = EI * mu / GJ
    return phi[(phi > 0.0) & (phi < phi_max)]
