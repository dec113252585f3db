r"""References for the rod's other controls (issue 21, item 5).

An *independent* reference for the test-suite: it imports nothing from
``rodcont``, only numpy, scipy and the two independent references already in
``tests/`` (``closed_forms.py``: the clamped twisted rod under tension, closed
form; ``lagrangian_reference.py``: the Lagrangian Kirchhoff equations solved
by shooting).  Checked in ``tests/test_twisted_reference_selfcheck.py``.

Rod (``shared/PROBLEM.md``): special Cosserat rod, unshearable, extensible
(``EA``; ``EA = inf`` is the inextensible Kirchhoff rod), isotropic (``EI``,
``GJ``), clamped at both ends of the span ``L`` along ``e1``, end section
turned by ``Phi`` about the axis, ``l0`` the unstressed length, ``T`` the
axial force (tension > 0).

A. Straight weightless rod under length control (``l0`` prescribed)
===================================================================
The straight state ``r = alpha s e1``, ``d3 = e1``, ``F = T e1``, uniform
twist ``Phi / l0``: ``alpha = L / l0``, ``T = EA (L/l0 - 1)``,
torque ``m = GJ Phi / l0`` (:func:`straight_length_control`).

Why the critical twists are those under tension control at ``T(l0)``.
Perturb the straight state by a transverse tilt ``theta`` of ``d3`` and a
transverse force ``f`` (first order ``eps``).  The end-to-end condition is
``L = int_0^l0 alpha (d3 . e1) ds`` with ``d3 . e1 = 1 - |theta|^2/2 + O(eps^3)``
and ``alpha = 1 + F . d3 / EA``, ``F . d3 = T + dT + f . theta + O(eps^3)``,
where ``f . theta`` is second order.  Hence, at first order,
``L = l0 (1 + (T + dT)/EA)`` with ``l0`` fixed: ``dT = 0``.  Likewise, under
tension control (``dT = 0``) the first-order change of ``l0`` vanishes.  The
torque's perturbation is a constant ``GJ d(u3)`` with ``int d(u3) ds = 0``
(the end rotation is held), so it vanishes too.  The transverse linearised
equations (``EI w'' - i m w' - alpha T w = -alpha c``, closed_forms.py) are
therefore the same under both controls with ``T = T(l0)``: the straight rod
under length control buckles at ``Phi_n = EI mu_n(tau) / GJ``,
``tau = T L^2 / (EI alpha)`` (:func:`critical_twist_length_control`).  The
*post-buckling* path differs (the tension drops at second order, so length
control stabilises).  Checked numerically: the 2-dimensional kernel of the
tension-control shooting Jacobian at ``Phi_1`` has zero ``l0`` (and torque)
component, and the length-control shooting Jacobian
(:func:`length_control_jacobian`) is singular at the same ``Phi_1``.

Untwisted (Euler) limit: ``tau = -4 pi^2``, i.e. with ``p = 4 pi^2 EI / L^2``,
``T_E = -p / (1 + p/EA)`` and ``l0_E = L / (1 + T_E/EA) = L (1 + p / EA)``
(:func:`euler_length_control`); for ``l0 > l0_E`` the straight rod is already
unstable at ``Phi = 0``.

B. Localized helical buckling of a long twisted rod
===================================================
(Love; Coyne 1990; van der Heijden & Thompson, Nonlinear Dynamics 21, 2000,
"Helical and localised buckling in twisted rods: a unified analysis of the
symmetric case"; van der Heijden, Champneys & Thompson 2002/2003 for clamped
finite rods; the analytic curve of PyElastica's
``examples/HelicalBucklingCase``.)  Inextensible isotropic Kirchhoff rod,
infinite, axis ``e_z``, force ``T e_z`` (tension), twisting moment ``M``,
``mu = M / (2 sqrt(EI T))`` with ``0 < mu < 1`` (``M^2 < 4 EI T``).

Derivation.  Euler angles ``(psi, theta, phi)``, directors
``R = Rz(psi) Ry(theta) Rz(phi)``, ``d3 = (sin th cos psi, sin th sin psi, cos th)``.
The twisting moment ``m = GJ u3 = GJ (phi' + psi' cos theta)`` is constant;
the moment about the force axis ``M_z = EI psi' sin^2 theta + m cos theta`` is
constant, and equal to ``m = M`` for a solution straight at infinity; the
Hamiltonian ``EI/2 (theta'^2 + psi'^2 sin^2 theta) + T cos theta`` is
constant, ``= T``.  So ``psi' = M / (EI (1 + cos theta))`` and, with
``v = 1 - cos theta``,

    v'^2 = c^2 v^2 (1 - v/a),   a = 2 (1 - mu^2),   c = 2 sqrt(T/EI) sqrt(1 - mu^2),

whose homoclinic solution is ``v = a sech^2(c s / 2)``:

    sin(theta/2) = sqrt(1 - mu^2) sech(c s / 2),     theta_max = 2 arccos(mu).

Integrating ``psi'`` and ``phi' = M/GJ - psi' cos theta`` (``beta = sqrt(1 - mu^2)/mu``,
``k = M / (2 EI)``):

    psi = k s + arctan(beta tanh(c s/2)),
    phi = (M/GJ) s - psi + 2 arctan(beta tanh(c s/2)),

and the centreline (``x + i y = rho``, ``rho' = sin(theta) e^{i psi}``,
``z' = cos theta``), centred at ``s = 0``:

    rho = -i A sech(c s/2) e^{i k s},   z = s - A tanh(c s/2),
    A = 2 a / c = 2 sqrt(EI/T) sqrt(1 - mu^2)

(so the lateral envelope is ``|rho| = A sech(c s/2)``, the helix turns at the
rate ``k = M / (2 EI)``).  Internal force ``T e_z``, moment
``M e_z - r x T e_z``; at the centre ``r = (0, -A, 0)``, moment
``(A T, 0, M)``, ``d3 = (sin theta_max, 0, cos theta_max)``.  (Checked by
integrating the Kirchhoff equations from the centre, to 1e-9.)
``GJ`` enters only the twist ``phi``.

End shortening and end rotation (what length control prescribes).  Over the
whole rod (unstressed length ``l``, exponentially small terms dropped):

    D = l - (span) = int (1 - cos theta) ds = 4 sqrt(EI/T) sqrt(1 - mu^2),
    Phi = M l / GJ + 4 arccos(mu)

(``Phi`` = ``(phi + psi)(+inf) - (phi + psi)(-inf)`` + twist: the localized
loop adds ``4 arccos mu``, independent of the stiffnesses).  These are
eqs 14-15 of van der Heijden et al. used by PyElastica, written there with
``m = M l/EI``, ``t = T l^2/EI``: ``D/l = sqrt(16/t (1 - m^2/(4t)))``,
``Phi = m EI/GJ + 4 arccos(m/(2 sqrt t))``.  Given ``(D, Phi, l)`` the loads
follow from one equation in ``mu`` (:func:`localized_helix_loads`):
``T = 16 EI (1 - mu^2) / D^2``, ``M = 8 EI mu sqrt(1 - mu^2) / D``,
``Phi = 8 EI l mu sqrt(1 - mu^2) / (GJ D) + 4 arccos mu``; it has two roots,
the larger ``mu`` (``theta_max < 90 deg`` when ``mu > 1/sqrt 2``) is the one
an Eulerian description (``d3 . e1 > 0``) can reach.

A finite clamped rod is not the infinite one: its tails must vanish at the
clamps.  :func:`clamped_helix` solves the finite clamped rod itself (multiple
shooting of the Lagrangian equations, length control): the reference to
compare a clamped rodcont run with.  At the ``(D, Phi)`` of given ``(T, M)``
its tension approaches ``T`` like ``exp(-c l / 2)`` (measured: 1.8e-3 at
``l = 40``, 1.3e-8 at ``l = 100`` for PyElastica's loads), its torque faster,
its envelope near the centre to ~4e-6 at ``l = 100``.

PyElastica's case (``examples/HelicalBucklingCase``): ``l = 100``, slack
``D = 3``, ``Phi = 27 turns = 54 pi``, ``EI = 1.345``, ``GJ = 0.789``; their
hard-coded ``m = 98.541496171190744``, ``t = 2900.993205792131`` are
reproduced by :func:`localized_helix_loads` (``T = 0.390183586179``,
``M = 1.325383123503``, ``mu = 0.914778187417``, ``theta_max = 47.6515073 deg``,
``A = 1.5``).  The clamped rod (span 97, inextensible):
``T = 0.390183591345``, torque ``1.325383123342``, ``max |r - axis| = 1.50000539``,
``theta_max = 47.6515638 deg``.  Two properties of the weightless clamped
problem matter to any solver (:func:`clamped_helix` docstring): buckled
states come in circles (rotation about the axis), so a Jacobian without a
phase condition is singular; and on a rod this long the buckle's position is
neutral to ~1e-11.

C. Maddocks' rule on the Gamma = 1 primary branch
=================================================
Under torque control the primary branch from ``Phi = 0`` loses stability at
its torque maximum (``d torque / ds = 0``), before the ``Phi`` fold at
``Phi = 13.0999938`` where rotation control loses it.
:func:`primary_torque_maximum` follows the branch with
``lagrangian_reference``'s shooting and pseudo-arclength, brackets the sign
change of the torque component of the tangent, and finds the zero of
``d torque / d Phi`` (or of ``d torque / d stretch``) by Brent's method, the
derivative exact by implicit differentiation of the shooting system.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

import closed_forms as cf
import lagrangian_reference as lag

__all__ = [
    "clamped_helix",
    "critical_twist_length_control",
    "euler_length_control",
    "length_control_jacobian",
    "localized_helix",
    "localized_helix_axial",
    "localized_helix_centre",
    "localized_helix_controls",
    "localized_helix_loads",
    "primary_state",
    "primary_torque_maximum",
    "straight_length_control",
]

_H = 1e-20                                   # complex step
_Q_START = np.array([0.5, 0.5, 0.5, 0.5])    # d1 = e2, d2 = e3, d3 = e1
_ZERO_G = np.zeros(3)


# ----------------------------------------------------------------------------
# A. Straight weightless rod under length control
# ----------------------------------------------------------------------------
def straight_length_control(l0, EA, L=1.0):
    """Straight weightless state at unstressed length ``l0``: dict alpha, T."""
    alpha = L / l0
    return {"alpha": alpha, "T": EA * (alpha - 1.0)}


def euler_length_control(EI=1.0, EA=255.0, L=1.0):
    """Untwisted buckling under length control: dict ``T`` (< 0) and ``l0``.

    ``T L^2 / (EI (1 + T/EA)) = -4 pi^2``: ``T = -p / (1 + p/EA)``,
    ``l0 = L (1 + p/EA)``, ``p = 4 pi^2 EI / L^2``.
    """
    p = 4.0 * np.pi ** 2 * EI / L ** 2
    return {"T": -p / (1.0 + p / EA), "l0": L * (1.0 + p / EA)}


def critical_twist_length_control(l0, EI=1.0, GJ=0.75, EA=255.0, L=1.0, n=1):
    """``n``-th critical end rotation of the straight rod of unstressed length ``l0``.

    The tension-control value (closed_forms.critical_twists) at
    ``T = EA (L/l0 - 1)`` (module docstring, A).  Requires ``l0 < l0_E``
    (:func:`euler_length_control`), where the untwisted rod is stable.
    """
    T = straight_length_control(l0, EA, L)["T"]
    if not cf.effective_tension(T, EI=EI, EA=EA, L=L) > -4.0 * np.pi ** 2:
        raise ValueError("l0 past the Euler length: the straight rod is unstable at Phi = 0")
    phi_max = 40.0
    while True:
        phis = cf.critical_twists(T, EI=EI, GJ=GJ, EA=EA, L=L, phi_max=phi_max)
        if phis.size >= n:
            return float(phis[n - 1])
        phi_max *= 2.0


def _end_residual(yend, phi, L):
    """r - L e1 (3) and vec(conj(q_Phi) q) (3) for end states (14, k); also the scalar part."""
    e = lag._qmul(lag._qconj(lag.clamp_quaternion(phi)), yend[3:7])
    return np.concatenate([yend[0:3] - np.array([L, 0.0, 0.0])[:, None], e[1:4]]), e[0]


def length_control_jacobian(l0, phi, F0, M0, EI=1.0, GJ=0.75, EA=255.0, L=1.0, rtol=1e-12):
    """Shooting map of the weightless rod under length control and its exact Jacobian.

    Unknowns ``x = (F0, M0)`` (global components at ``s = 0``, clamp
    ``d1 = e2, d2 = e3, d3 = e1``); ``l0`` and ``phi`` are held.  Returns
    ``(G, J)``: the six end-clamp residuals (``r(l0) - L e1``,
    ``vec(conj(q_Phi) q(l0))``) and their 6 x 6 Jacobian (complex step, the
    six columns integrated together with the same steps, at most ``l0/64``).
    """
    y0 = np.zeros((14, 6), dtype=complex)
    y0[3:7] = _Q_START[:, None]
    y0[7:10] = np.asarray(F0, dtype=float)[:, None]
    y0[10:13] = np.asarray(M0, dtype=float)[:, None]
    for j in range(6):
        y0[7 + j, j] += 1j * _H
    f = lambda s, y: lag.kirchhoff_rhs(y.reshape(14, 6), 0.0, EI, GJ, EA).ravel()
    # max_step: the steps follow the real trajectory, which for the untwisted
    # straight rod is exactly linear (one giant step would miss the perturbations)
    sol = solve_ivp(f, (0.0, l0), y0.ravel(), method="DOP853", rtol=rtol, atol=0.1 * rtol,
                    max_step=l0 / 64)
    ye = sol.y[:, -1].reshape(14, 6)
    res, _ = _end_residual(ye, np.full(6, float(phi)), L)
    return res[:, 0].real.copy(), res.imag / _H


# ----------------------------------------------------------------------------
# B. Localized helix (infinite inextensible rod), closed form
# ----------------------------------------------------------------------------
def _helix_constants(T, M, EI):
    if not T > 0.0:
        raise ValueError("the localized helix needs a tension T > 0")
    mu = M / (2.0 * np.sqrt(EI * T))
    if not 0.0 < mu < 1.0:
        raise ValueError(f"need 0 < M < 2 sqrt(EI T) (mu = {mu})")
    sq = np.sqrt(1.0 - mu * mu)
    c = 2.0 * np.sqrt(T / EI) * sq
    return mu, sq, c, 2.0 * np.sqrt(EI / T) * sq


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.array([[c, -s, z], [s, c, z], [z, z, o]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.array([[c, z, s], [z, o, z], [-s, z, c]])


def localized_helix(s, T, M, EI=1.0, GJ=0.75):
    """Homoclinic (localized helical) solution of the infinite Kirchhoff rod, centred at s = 0.

    Axis ``e_z``, force ``T e_z``, twisting moment ``M`` (``M^2 < 4 EI T``).
    Returns dict of arrays over ``s`` (formulas in the module docstring, B):

    * ``theta``: angle of the tangent from the axis, ``2 arcsin(sqrt(1-mu^2) sech(c s/2))``;
    * ``envelope``: lateral displacement ``|rho| = A sech(c s/2)``;
    * ``psi``, ``phi``: the other Euler angles (``R = Rz(psi) Ry(theta) Rz(phi)``);
    * ``r`` (3, n): centreline ``(Re rho, Im rho, s - A tanh(c s/2))``;
    * ``directors`` (3, 3, n): columns ``d1, d2, d3``;
    * ``moment`` (3, n): internal moment ``M e_z - r x T e_z``;
    * constants ``mu``, ``c`` (decay rate of ``sin(theta/2)`` is ``c/2``),
      ``A`` (envelope at the centre), ``theta_max``, ``k`` (helix turning rate).
    """
    mu, sq, c, A = _helix_constants(T, M, EI)
    s = np.atleast_1d(np.asarray(s, dtype=float))
    beta = sq / mu
    h = c * s / 2.0
    sech, tanh = 1.0 / np.cosh(h), np.tanh(h)
    k = M / (2.0 * EI)
    theta = 2.0 * np.arcsin(sq * sech)
    at = np.arctan(beta * tanh)
    psi = k * s + at
    phi = (M / GJ) * s - psi + 2.0 * at
    rho = -1j * A * sech * np.exp(1j * k * s)
    r = np.array([rho.real, rho.imag, s - A * tanh])
    D = np.einsum("ijn,jkn,kln->iln", _rz(psi), _ry(theta), _rz(phi))
    mom = np.array([-T * r[1], T * r[0], np.full_like(s, M)])   # M e_z - r x T e_z
    return {"theta": theta, "envelope": A * sech, "psi": psi, "phi": phi, "r": r, "directors": D,
                "moment": mom, "mu": mu, "c": c, "A": A, "theta_max": 2.0 * np.arccos(mu), "k": k}


def localized_helix_centre(T, M, EI=1.0, GJ=0.75):
    """State at the centre: dict r0, D0, F0, M0 (for integrating Kirchhoff's equations)."""
    h = localized_helix(0.0, T, M, EI, GJ)
    return {"r0": h["r"][:, 0], "D0": h["directors"][:, :, 0], "F0": np.array([0.0, 0.0, T]),
                "M0": h["moment"][:, 0]}


def localized_helix_axial(z, T, M, EI=1.0, GJ=0.75):
    """theta and the envelope as functions of the axial coordinate ``z`` (from the centre).

    An Eulerian description parametrises the rod by its projection on the
    axis; ``z(s) = s - A tanh(c s/2)`` is increasing while ``theta < 90 deg``
    (``mu > 1/sqrt 2``), inverted by Newton (``z' = cos theta``).  Returns
    dict ``s``, ``theta``, ``envelope``.
    """
    z = np.atleast_1d(np.asarray(z, dtype=float))
    mu, _sq, c, A = _helix_constants(T, M, EI)
    if mu * mu <= 0.5:
        raise ValueError("theta_max >= 90 deg: z(s) is not monotone")
    s = z.copy()
    for _ in range(100):
        h = c * s / 2.0
        ds = (s - A * np.tanh(h) - z) / (1.0 - 2.0 * (1 - mu * mu) / np.cosh(h) ** 2)
        s -= ds
        if np.max(np.abs(ds)) < 1e-15 * (1.0 + np.max(np.abs(z))):
            break
    out = localized_helix(s, T, M, EI, GJ)
    return {"s": s, "theta": out["theta"], "envelope": out["envelope"]}


def localized_helix_controls(T, M, l, EI=1.0, GJ=0.75):
    """End shortening ``D`` and end rotation ``Phi`` of the localized helix on a length ``l``.

    ``D = 4 sqrt(EI/T) sqrt(1 - mu^2)``, ``Phi = M l/GJ + 4 arccos(mu)``
    (infinite-rod values; exponentially small corrections dropped).
    """
    mu, sq, _, _ = _helix_constants(T, M, EI)
    return {"D": 4.0 * np.sqrt(EI / T) * sq, "Phi": M * l / GJ + 4.0 * np.arccos(mu), "mu": mu}


def localized_helix_loads(D, Phi, l, EI=1.0, GJ=0.75, branch="upper"):
    """(T, M) of the localized helix with end shortening ``D`` and end rotation ``Phi``.

    Root in ``mu`` of ``Phi = 8 EI l mu sqrt(1-mu^2) / (GJ D) + 4 arccos mu``
    (Brent to 1e-15); ``branch = "upper"`` takes the root with the larger
    ``mu`` (smaller ``theta_max``), ``"lower"`` the other.  Returns dict
    ``T``, ``M``, ``mu``, ``theta_max``.
    """
    g = lambda mu: 8.0 * EI * l * mu * np.sqrt(1.0 - mu * mu) / (GJ * D) + 4.0 * np.arccos(mu) - Phi
    grid = np.linspace(0.0, 1.0, 20001)
    vals = g(grid)
    top = int(np.argmax(vals))
    if vals[top] <= 0.0:
        raise ValueError("no localized helix with this (D, Phi, l): Phi too large")
    if branch == "upper":
        mu = brentq(g, grid[top], 1.0, xtol=1e-15)
    elif branch == "lower":
        if vals[0] >= 0.0:
            raise ValueError("no lower root: Phi <= 2 pi")
        mu = brentq(g, 0.0, grid[top], xtol=1e-15)
    else:
        raise ValueError("branch must be 'upper' or 'lower'")
    T = 16.0 * EI * (1.0 - mu * mu) / D ** 2
    return {"T": T, "M": 2.0 * mu * np.sqrt(EI * T), "mu": mu, "theta_max": 2.0 * np.arccos(mu)}


# ----------------------------------------------------------------------------
# B'. The finite clamped rod with a localized helix (multiple shooting)
# ----------------------------------------------------------------------------
_P = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])   # e_z -> e1, e_x -> e2, e_y -> e3


def _helix_guess(nodes, l0, L, T, M, EI, GJ):
    """Closed-form states (14, n) at ``nodes``: centred at l0/2, axis e1, d1(0) ~ e2."""
    fine = np.union1d(np.linspace(0.0, l0, int(40 * l0) + 2), nodes)
    h = localized_helix(fine - 0.5 * l0, T, M, EI, GJ)
    chi = h["psi"][0] + h["phi"][0]            # the frame's turn at s = 0: undo it
    Rc = _P @ _rz(np.array(-chi))
    r = np.einsum("ij,jn->in", Rc, h["r"])
    r -= r[:, :1]
    Dg = np.einsum("ij,jkn->ikn", Rc, h["directors"])
    q = np.array([lag.directors_to_quat(Dg[:, :, i]) for i in range(fine.size)]).T
    for i in range(1, fine.size):              # continuous sign
        if q[:, i] @ q[:, i - 1] < 0:
            q[:, i] *= -1
    if q[:, 0] @ _Q_START < 0:
        q *= -1
    Mg = np.einsum("ij,jn->in", Rc, h["moment"])
    F = np.repeat((Rc @ np.array([0.0, 0.0, T]))[:, None], fine.size, axis=1)
    y = np.vstack([r, q, F, Mg, fine[None, :]])
    idx = np.searchsorted(fine, nodes)
    return y[:, idx]


def _flow(y0, s0, s1, EI, GJ, EA, rtol, dense=False):
    """Flow of the weightless Kirchhoff equations from s0 to s1 (DOP853 solution object)."""
    return solve_ivp(lambda s, y: lag.kirchhoff_rhs(y, 0.0, EI, GJ, EA, _ZERO_G), (s0, s1), y0,
                     method="DOP853", rtol=rtol, atol=0.1 * rtol, dense_output=dense)


def _flow_jacobian(y0, s0, s1, EI, GJ, EA, rtol):
    """14 x 14 Jacobian of the flow map (complex step, 14 columns integrated together).

    Newton only needs it to a few digits: it is integrated at a looser
    tolerance than the residual (the converged state is set by the residual).
    """
    Y = np.repeat(y0.astype(complex)[:, None], 14, axis=1)
    Y[np.arange(14), np.arange(14)] += 1j * _H
    f = lambda s, y: lag.kirchhoff_rhs(y.reshape(14, 14), 0.0, EI, GJ, EA, _ZERO_G).ravel()
    sol = solve_ivp(f, (s0, s1), Y.ravel(), method="DOP853", rtol=rtol, atol=0.1 * rtol)
    return sol.y[:, -1].reshape(14, 14).imag / _H


def clamped_helix(l0, L, Phi, EI=1.0, GJ=0.75, EA=np.inf, segments=24, rtol=1e-12,
                  guess=None, tol=1e-11, gtol=1e-12, maxit=20, rcond=1e-9,
                  jac_rtol=1e-8):
    """Clamped weightless rod of unstressed length ``l0`` on the span ``L``, end rotation ``Phi``.

    Length control (``l0`` and ``Phi`` prescribed; tension and torque are
    unknowns), solved by multiple shooting of ``lagrangian_reference``'s
    Kirchhoff equations on ``segments`` equal pieces (each short enough that
    its flow map is well conditioned), Newton with the exact Jacobian
    (complex step).  Clamps: ``r(0) = 0``, ``d1, d2, d3 = e2, e3, e1`` at
    ``s = 0``, ``r(l0) = L e1``, the end frame turned by ``Phi`` about ``e1``
    (the quaternion condition sees ``Phi`` mod 2 pi: the branch is selected
    by the initial guess, by default the localized helix of
    :func:`localized_helix_loads` with ``D = l0 - L``, centred at ``l0/2``; the
    scalar part of ``conj(q_Phi) q(l0)`` must come out positive, which fixes
    ``Phi`` mod 4 pi, and the torque close to the guess's fixes the turns).

    The Jacobian is singular, for two reasons.  (i) Exactly: rotating the
    whole buckled rod about ``e1`` and turning every section back by the same
    angle about its ``d3`` maps clamps (``d3 = e1`` there) onto themselves and
    an isotropic rod's equilibria onto equilibria, so weightless buckled
    states come in circles (one zero singular value, ~1e-12 here, set by the
    Jacobian's accuracy).  (ii) Nearly: on a long rod the position of the
    localized buckle along the rod costs only ~``exp(-c l0 / 2)`` (its tails
    meeting the clamps): ``sigma / sigma_max`` = 8e-5 at ``l0 = 30``, 1.3e-7 at
    60, 1.7e-9 at 80 for PyElastica's loads.  Newton steps are least-squares
    steps with singular values below ``rcond * sigma_max`` dropped; the guess
    is centred (symmetric) and its phase is kept, and neither dropped
    direction changes ``T`` or the torque.  Converged when the residual is
    below ``gtol`` or the step below ``tol``.

    Returns dict ``T`` (``F . e1``), ``torque`` (``M . d3``, at ``s = 0``),
    ``F0``, ``M0``, ``length`` (deformed), ``theta_max`` (max angle of ``d3``
    from ``e1``), ``envelope_max`` (max distance from the axis), ``guess``
    (the closed-form loads), ``iterations``, ``residual`` (clamp and
    continuity equations at the returned state), ``conditioning``, ``nodes``, ``Y``
    (states at the nodes) and ``profile(s)`` (states (14, n) at any ``s``).
    """
    nodes = np.linspace(0.0, l0, segments + 1)
    if guess is None:
        guess = localized_helix_loads(l0 - L, Phi, l0, EI, GJ)
    Y = _helix_guess(nodes[:-1], l0, L, guess["T"], guess["M"], EI, GJ)   # (14, segments)
    n = 14 * segments
    for it in range(1, maxit + 1):  # noqa: B007 (the count is returned)
        G = np.zeros(n)
        J = np.zeros((n, n))
        G[0:3] = Y[0:3, 0]
        G[3:7] = Y[3:7, 0] - _Q_START
        G[7] = Y[13, 0]
        J[0:7, 0:7] = np.eye(7)
        J[7, 13] = 1.0
        row = 8
        for i in range(segments):
            ye = _flow(Y[:, i], nodes[i], nodes[i + 1], EI, GJ, EA, rtol).y[:, -1]
            Ji = _flow_jacobian(Y[:, i], nodes[i], nodes[i + 1], EI, GJ, EA, jac_rtol)
            c = 14 * i
            if i < segments - 1:
                G[row:row + 14] = ye - Y[:, i + 1]
                J[row:row + 14, c:c + 14] = Ji
                J[row:row + 14, c + 14:c + 28] = -np.eye(14)
                row += 14
            else:
                cols = ye[:, None] + 1j * _H * Ji            # (14, 14) perturbed end states
                res, sc = _end_residual(np.column_stack([ye, cols]), np.full(15, Phi), L)
                G[row:row + 6] = res[:, 0].real
                J[row:row + 6, c:c + 14] = res[:, 1:].imag / _H
        U, sv, Vt = np.linalg.svd(J)
        if np.max(np.abs(G)) < gtol:
            break
        keep = sv > rcond * sv[0]                 # drop the near-neutral shift (see docstring)
        dY = -(Vt[keep].T @ ((U[:, keep].T @ G) / sv[keep]))
        Y = Y + dY.reshape(segments, 14).T
        if np.max(np.abs(dY)) < tol:
            break
    else:
        raise RuntimeError("clamped_helix: Newton did not converge")
    sols = [_flow(Y[:, i], nodes[i], nodes[i + 1], EI, GJ, EA, rtol, dense=True)
            for i in range(segments)]
    yend = sols[-1].y[:, -1]
    res, sc = _end_residual(yend[:, None], np.array([Phi]), L)
    gaps = [np.max(np.abs(sols[i].y[:, -1] - Y[:, i + 1])) for i in range(segments - 1)]
    residual = max(np.max(np.abs(res)), *gaps, np.max(np.abs(Y[3:7, 0] - _Q_START)))
    if sc[0] <= 0.0:
        raise RuntimeError("clamped_helix: end clamp on the other quaternion sheet")

    def profile(s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        k = np.clip(np.searchsorted(nodes, s, side="right") - 1, 0, segments - 1)
        out = np.empty((14, s.size))
        for i in np.unique(k):
            out[:, k == i] = sols[i].sol(s[k == i])
        return out

    def theta(s):
        d3 = lag.quat_to_directors(profile(s)[3:7])[:, 2]
        return np.arctan2(np.hypot(d3[1], d3[2]), d3[0])

    def dist(s):
        y = profile(s)
        return np.hypot(y[1], y[2])

    def peak(f):                     # sampled, then refined by Brent between neighbours
        sg = np.linspace(0.0, l0, int(50 * l0) + 1)
        k = int(np.argmax(f(sg)))
        lo, hi = sg[max(k - 1, 0)], sg[min(k + 1, sg.size - 1)]
        r = minimize_scalar(lambda x: -f(x)[0], bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-10})
        return float(max(-r.fun, f(sg[k])[0]))
    torque = float(Y[10, 0])                  # M . d3 with d3 = e1 at s = 0
    return {"T": float(Y[7, 0]), "torque": torque, "F0": Y[7:10, 0].copy(), "M0": Y[10:13, 0].copy(),
                "length": float(yend[13]), "theta_max": peak(theta), "envelope_max": peak(dist),
                "guess": guess, "iterations": it,
                "residual": float(residual), "conditioning": float(sv[-1] / sv[0]),
                "nodes": nodes, "Y": Y, "profile": profile}


# ----------------------------------------------------------------------------
# C. Maddocks: the torque maximum of the Gamma = 1 primary branch
# ----------------------------------------------------------------------------
def primary_state(gamma, phi_L, w=10.0, EI=1.0, GJ=0.75, EA=255.0, L=1.0, rtol=1e-12):
    """Point of the primary branch at ``phi_L`` (lagrangian_reference.twisted_solution)."""
    return lag.twisted_solution(gamma, phi_L, w=w, EI=EI, GJ=GJ, EA=EA, L=L, rtol=rtol)


@functools.lru_cache(maxsize=8)
def _torque_bracket(gamma, par, rtol):
    """Two accepted points of the primary branch around the sign change of the
    torque component of the tangent (``lagrangian_reference._branch``)."""
    prev = None
    for z, G, J, tau in lag._branch(gamma, par, rtol):
        if prev is not None and prev[3][6] > 0 and tau[6] < 0:
            raise RuntimeError("the Phi fold came before the torque maximum")
        if prev is not None and prev[3][2] > 0 and tau[2] < 0:
            return prev[0], prev[1], z, G
        prev = (z, G, J, tau)


def primary_torque_maximum(gamma=1.0, w=10.0, EI=1.0, GJ=0.75, EA=255.0, L=1.0, rtol=1e-12,
                           xtol=1e-13, route="phi"):
    """Maximum of the torque along the primary branch from ``Phi = 0``.

    The branch is followed by ``lagrangian_reference._branch`` (shooting,
    pseudo-arclength) until the torque component of its tangent turns
    negative (it must do so before the ``Phi`` component: the maximum lies
    before the fold).  Between the two points Brent's method finds the zero
    of ``d torque / d p`` with ``p = Phi`` (``route="phi"``: ``Phi``
    prescribed, ``dz/dPhi = [J_clamp; e_Phi]^-1 e_7``) or ``p = stretch``
    (``route="stretch"``: ``dz/dsigma = J^-1 e_7``), exact by implicit
    differentiation of the shooting system.

    Returns dict ``phi_L``, ``torque``, ``stretch``, ``l0``, ``dtorque``
    (the derivative at the returned point), ``z`` (shooting unknowns),
    ``route``.
    """
    par = (w, EI, GJ, EA, L)
    T = gamma * w * L
    za, Ga, zb, Gb = _torque_bracket(gamma, par, rtol)
    if route == "phi":
        pa, pb, mode = za[6], zb[6], "phi"
    elif route == "stretch":
        pa, pb, mode = Ga[6], Gb[6], "stretch"
    else:
        raise ValueError("route must be 'phi' or 'stretch'")
    state = {}

    def dtorque(p):
        lam = (p - pa) / (pb - pa)
        zg = state.get("z", (1 - lam) * za + lam * zb)
        zs, Gs, Js, _, _ = lag._newton(zg, T, par, rtol, mode, target=p)
        A = np.vstack([Js[:6], np.eye(7)[6]]) if mode == "phi" else Js
        state.update(z=zs, G=Gs)
        return np.linalg.solve(A, np.eye(7)[6])[2]

    fa, fb = dtorque(pa), dtorque(pb)
    if not (fa > 0 > fb):
        raise RuntimeError("torque bracket without a sign change")
    p = brentq(dtorque, pa, pb, xtol=xtol, rtol=4 * np.finfo(float).eps)
    d = dtorque(p)
    z, G = state["z"], state["G"]
    return {"phi_L": float(z[6]), "torque": float(z[2]), "stretch": float(G[6]), "l0": float(z[5]),
                "dtorque": float(d), "z": z.copy(), "route": route}
