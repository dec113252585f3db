"""Stability of rod equilibria: the number of unstable modes, counted two independent ways.

Controls are those of the system's own end conditions (:mod:`rodcont.ends`): by
default end rotation ``Phi`` imposed (``phi(L) = Phi``), axial force ``F . K3 = T``
imposed at ``S = L``, unstressed length ``l0`` free (self-feeding); under a prescribed
torque the end rotation is free (its row ``m(L) = M``, its unknown ``phi_L``), under a
prescribed unstressed length ``T`` is an unknown and ``l0`` an integral row. Those rows
carry no inertia, so the count follows the controls in force (tests/test_controls.py:
Maddocks' rule, the torque maximum under torque control, the Phi fold under rotation
control, on the Gamma = 1 branch). Two methods:

* :func:`unstable_modes` (method 1) counts the unstable eigenvalues of the
  linearised dynamics, a generalised eigenproblem ``J v = lambda B v`` of the
  collocation Jacobian on the point's own mesh;
* :func:`exchange_of_stability` (method 2) starts from a point of known
  stability and changes the count by one at each fold of ``Phi``, the
  direction read off the distinguished diagram (torque against ``Phi``,
  Maddocks 1987) or, for a problem that is not conservative, off the pencil's
  null vectors at the fold.

Method 1: linearised dynamics and the inertia operator ``B``
------------------------------------------------------------
``J`` is exactly the Jacobian of :meth:`Collocation.linearise` at fixed
parameters (``Phi`` and ``T`` imposed). Its rows are the equations multiplied
by ``s' = ds/dS``: force ``F' + f s'``, moment ``(M' + r' x F) . K_a``, torque
``m'/GJ``, then the boundary conditions. Newton's law for the material
reads ``F_s + f = rho A r_tt``: the force rows of the dynamic problem are
``R_F = rho A s' r_tt``, so ``R(x + v e^{sigma t}) ~ J v e^{sigma t} = sigma^2 B v
e^{sigma t}`` and the modes are the eigenpairs of ``J v = lambda B v`` with
``lambda = sigma^2``: ``lambda < 0`` oscillates (stable), ``lambda > 0``
grows (divergence), a complex ``lambda`` grows too (flutter). **An unstable
mode is an eigenvalue with Re lambda > 0**; the sign convention is that of the
residual rows (``+ inertia``), checked on the unloaded clamped beam, whose
eigenvalues are ``-beta^4 EI/(rho A L^4)``, ``beta = 4.730, 7.853, ...``
(-500.56, -3803.54, each double; the code gives them to 10 digits at
``w = T = Phi = 0``).

The inertia used (per collocation point, rows in frame components; with
``rho A = EI / L^4`` so that ``lambda`` is dimensionless)::

    row F.K1:  rho A s' dDelta1         row F.K2:  rho A s' dDelta2
    row F.K3: -rho A s' (Delta1' dDelta1 + Delta2' dDelta2)
    moment, torque and boundary rows: 0

It is the inertia of the kinetic energy ``1/2 int rho A s' |dDelta_t|^2 dS``:
transverse motion only. Why this is enough, and why the K3 row:

* Eulerian variables. Write the potential energy as ``V = int psi dS +
  (loads)`` with ``sigma = s'(S)`` the material density along the reference:
  ``psi = sigma (W(u, alpha) + w r.e3)``, ``u_perp = kappa_S / sigma``,
  ``u3 = (phi' + tau_q) / sigma``, ``alpha = |r'| / sigma``. ``sigma`` enters
  *pointwise* (no derivative): material flowing along the fixed centreline
  (the self-feeding degree of freedom, with ``l0 = int sigma``) is an
  algebraic variable. ``psi`` is strictly convex in ``(sigma, phi')`` jointly
  (``a^2 / sigma`` is convex for ``sigma > 0`` and ``EA sigma (|r'|/sigma -
  1)^2 / 2`` is strictly convex), and ``phi`` is pinned at both ends, so the
  Hessian block of the inertia-free variables ``(sigma, phi)`` is positive
  definite. By Haynsworth's inertia additivity the Morse index of the whole
  second variation is the index of its Schur complement on ``Delta``, and by
  Sylvester's law that is the number of positive ``lambda`` for *any*
  positive mass on ``Delta``: rotary (torsional) and axial inertia do not
  change the count (:func:`spectrum` takes ``torsional_inertia`` to check it:
  the counts are identical on the test branches).
* The rows are not the variational derivatives themselves: with ``F_perp``
  the constraint (shear) force, the derivative with respect to ``Delta`` at
  fixed material is the K1, K2 force rows (plus the adjoint of the twist-rate
  map applied to the torque row), and the derivative with respect to sliding
  is ``R_F . r' + m' (phi' + tau_q)``. With no kinetic energy for sliding the
  inertia force must do no work on it: ``R_F . r' = 0`` in the torque-free
  rows, which fixes the K3 entry ``-rho A s' Delta' . dDelta`` (the inertia
  force is normal to the tangent). Dropping it ("translational inertia in the
  transverse force rows" only) gives other eigenvalues but the same counts on
  every point tested.

Numerics. ``B = U W`` has rank ``2 n_pts`` (``n_pts = N k`` collocation
points); with a shift ``s0`` the finite eigenvalues are ``lambda = s0 +
1/nu`` for the nonzero eigenvalues ``nu`` of the small matrix ``C = W (J -
s0 B)^{-1} U`` (``2 n_pts`` square: 150 at ``N = 15, k = 5``). ``dense``
computes all of them (LAPACK); ``arnoldi`` (the default) the ``k = 8``
nearest the shift by ARPACK (shift-invert: one sparse LU, one solve per
Arnoldi step), doubling ``k`` until they fill a disc of radius ``reach`` about
the shift, ``reach`` an a-priori bound on the unstable eigenvalues from the
loads (:func:`_cap`; at most 1/35 of it is used by any unstable eigenvalue
met in the tests): every unstable eigenvalue is then inside the disc, and the
two solvers give the same counts at every point of the test branches. A
nearest-``k`` rule without that bound is not safe: in the loop at the end of
Gamma = 0 a dozen soft modes crowd the origin and the unstable eigenvalue
(33) lies beyond the 8 nearest. ``s0 = -0.618`` rather than 0: at a fold
``J`` is singular and a zero shift pollutes the other eigenvalues (a spurious
complex pair appears); if an eigenvalue falls within 1e-6 |s0| of the shift
another shift is used. Eigenvalues beyond ``cap = min((pi L/h_min)^4, 100
reach)`` are modes the mesh cannot resolve or rounding artefacts (a few near
1e13-1e17) and are not counted. ``J - s0 B`` is factorised in the problem's
own units (:func:`_equilibrated`: the unknowns divided by their scales, each
row by its largest entry). Cost at ``N = 15`` on the project machine: about
0.6 ms for the Jacobian and 2-5 ms for the rest (``dense``: 6 ms).

Units. Every number above is in the problem's own scales, so that the counts
and the eigenvalues are the same in any consistent units (lengths x a,
forces x b: tests/test_units.py, test_counts_do_not_depend_on_the_units):
eigenvalues (``tol``, ``s0``, ``cap``, ``reach``, the flutter test) in units
of ``EI / (rho A L^4)``, i.e. pure numbers with ``rho A = EI / L^4``;
lengths (the mesh size in the cap, the deflection unknowns) by the span
``L``; curvatures by ``1/L``; forces (the force unknowns, the reach's
``|F|``, the tension step of :func:`reciprocity_ratio`) by ``EI / L^2``;
torques by ``EI / L``. (The mesh cap was once ``(pi/h_min)^4``, in
1/length^4: with lengths x 10 it fell below the unstable eigenvalues and the
seed branch of Gamma = 1 read 0 unstable modes instead of 4.)

Zero eigenvalues. ``|lambda| <= tol`` (default ``1e-4`` EI/(rho A L^4), against ``-500.6``
for the first mode of the unloaded beam) is *null* and not counted as
unstable: at a located fold (``|lambda| ~ 1e-7``) the count is the smaller of
the two sides, i.e. the strictly unstable modes (a fold bracketed but not
located may fall on either side). The weightless straight rod at a critical
twist has a double null eigenvalue (the circle of helical modes of the O(2)
symmetry, ``|lambda| ~ 1e-6`` at the tabulated twists); just above it two
eigenvalues are positive (``2e-3`` at ``Phi_c (1 + 1e-6)``). A complex pair
with ``Re lambda > tol`` counts twice.

Method 2: exchange of stability at folds
----------------------------------------
For a conservative problem ``V(q; Phi)`` with ``mu = dV/dPhi`` the torque
(``V`` depends on ``Phi`` through ``phi(L) = Phi`` only, so ``dV/dPhi = m(L)``,
the constant axial moment ``torque``). Along a branch ``(q(s), Phi(s))``,
``H q' + V_qPhi Phi' = 0`` and ``mu' = V_Phiq q' + V_PhiPhi Phi'``, hence::

    q'^T H q' = -Phi' mu' + V_PhiPhi Phi'^2.

At a fold ``Phi' = 0``, ``q'`` is the null vector and ``mu' != 0`` (the fold
is non-degenerate), so near it the critical eigenvalue has the sign of the
Rayleigh quotient, ``-Phi' mu' = -Phi'^2 dmu/dPhi``:

    **Rule.** Of the two arcs meeting at a fold of ``Phi``, the one on which
    the torque increases with ``Phi`` (``dm/dPhi -> +inf`` next to the
    vertical tangent of the ``(Phi, m)`` curve) has one more unstable mode
    than the one on which ``dm/dPhi -> -inf``. Traversing the fold, the count
    changes by ``sign(Phi'_after * m')``, i.e. by +1 where the ``(Phi, m)``
    curve turns counter-clockwise, -1 where it turns clockwise.

At the Gamma = 1 fold (maximum of ``Phi``, torque already decreasing) the
count goes 0 -> 1. Branch points change the count too, by an amount the
diagram does not give (the O(2) critical twists of the weightless rod: by 2);
:func:`exchange_of_stability` refuses a branch with branch points unless told
the change.

``rule="pencil"`` reads the direction off the pencil at each fold instead:
with ``J phi = 0``, ``psi^T J = 0``, ``x' = c phi``, differentiating
``(J - lambda B) v = 0`` and twice the branch ``F(x(s), Phi(s)) = 0``::

    lambda' = psi^T J' phi / psi^T B phi = -Phi'' psi^T F_Phi / (c psi^T B phi).

It needs only the null vectors at the folds, not the spectrum elsewhere; for
a conservative problem it coincides with the torque rule.

Finding: the canonical self-feeding problem is not conservative
---------------------------------------------------------------
``V = int psi dS + G(T) l0`` (material drawn from a straight, untwisted
reservoir under a dead axial load ``T``, ``G(T) = T + T^2/(2 EA)``) has, as
natural condition for the pointwise ``sigma``, ``H = G(T)`` where ``H = M.u
+ alpha F3 - W - w r.e3`` is the rod's conserved energy-momentum (constant
along ``S`` on every computed solution, to the discretisation error). At
``S = L`` this reads ``G(F3) + EI |u_perp|^2 / 2 + GJ u3^2 / 2 = G(T)``: the
axial force in the span differs from the reservoir's by the Eshelby-like
(configurational) force of the clamp that straightens and untwists the
entering rod. The canonical problem imposes ``F3(L) = T`` instead, which is
the stationarity condition of no potential: Maxwell's reciprocity
``(dm/dT)_Phi = G'(T) (dl0/dPhi)_T`` holds to 6 digits at every point of the
conservative variant (:func:`sleeve_system`), but for the canonical problem
the ratio (:func:`reciprocity_ratio`) runs from 236 to 1.08 along Gamma = 1
and from 92 to 0.04 along Gamma = 0. And its linearisation is not
self-adjoint: complex eigenvalue pairs (``-1563 +- 173i`` at Gamma = 1,
``Phi = 12.747``; ``-44.4 +- 11.2i`` at Gamma = 0, ``Phi = 5.972``; converged
in ``N`` to 7 digits) appear where two stable modes meet, while the
conservative variant has a real spectrum everywhere. ``T`` is then a force
held at the clamp by a servo, the feed is slaved to it (quasi-statically, as
in method 1), the torque is not the conjugate of ``Phi`` and the torque rule
has no theorem behind it. ``unstable_modes`` counts divergence (``Re lambda >
0``) only: its changes happen where ``J`` is singular, whatever the inertia;
the complex pairs (growing oscillations of the undamped dynamics, their
existence depends on the assumed inertia and feed law) are reported apart
(``Spectrum.flutter``). Observed: method 1 and both rules agree at every
point of Gamma = 1 (0 -> 1 at the fold, ``Phi = 13.09999``) and of Gamma = 0
up to its second fold (0 -> 1 at ``Phi = 10.77692``); past the second fold
(``Phi = 5.87188``, a minimum with the torque decreasing) method 1 and the
pencil rule give 2, the torque rule 0. On the conservative variant the three
agree everywhere.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .rod import Jet

NULL_TOL = 1e-4          # |lambda| below this (units EI / (rho A L^4)) is a null eigenvalue
SHIFT = -0.6180339887    # default shift of the reduced eigenproblem (units EI / (rho A L^4))
DENSE_MIN = 60           # 'auto' uses the dense reduced problem up to this size (2 n_pts), ARPACK above


# --------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------
@dataclass
class Spectrum:
    """Eigenvalues of ``J v = lambda B v`` near the origin and the counts read from them.

    ``eigenvalues``: the computed finite eigenvalues with ``|lambda| <= cap``,
    sorted by decreasing real part (all of them for ``dense``, those within
    ``radius`` of the shift for ``arnoldi``). ``unstable``: the number with
    ``Re lambda > tol`` (divergence; what :func:`unstable_modes` returns);
    ``null``: the number with ``|lambda| <= tol``; ``flutter``: the number of
    the others off the real axis (``|Im lambda| > 1e-6 |lambda| + tol``): each
    is a growing oscillation of the undamped dynamics (they come in conjugate
    pairs; none can exist for a conservative problem); ``cap``: the largest
    modulus counted (module docstring); ``shift``, ``method``, ``radius``
    (``arnoldi``: every eigenvalue closer than this to the shift was found),
    ``k`` (``arnoldi``: how many eigenvalues that took; a good ``k`` for the next point of a branch).
    """

    eigenvalues: np.ndarray
    unstable: int
    null: int
    flutter: int
    cap: float
    shift: float
    method: str
    radius: float = math.inf
    tol: float = NULL_TOL
    k: int = 0  # arnoldi: the number of eigenvalues asked of ARPACK in the round that covered the reach

    @property
    def nearest(self) -> np.ndarray:
        """Eigenvalues sorted by modulus."""
        return self.eigenvalues[np.argsort(np.abs(self.eigenvalues))]


# --------------------------------------------------------------------------
# The inertia operator B = U W
# --------------------------------------------------------------------------
_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _static_parts(disc):
    """Per-discretisation pieces of ``B``: rows of the jet matrix and the row ranks (cached)."""
    c = _CACHE.get(disc)
    if c is None:
        npts = disc.npts
        E = disc.E.tocsr()

        def rows(j):
            return E[j * npts:(j + 1) * npts]

        rank = np.empty(disc.size, int)
        rank[disc.row_order] = np.arange(disc.size)
        q = np.arange(npts)
        c = dict(D1p=rows(Jet.D1[1]), D2p=rows(Jet.D2[1]), PHI=rows(Jet.PHI[0]),
                 W2=sp.vstack([rows(Jet.D1[0]), rows(Jet.D2[0])], format="csr"),
                 rank=rank, q=q, row=lambda i: rank[q * disc.problem.n_fields + i],
                 h_min=float(np.min(np.diff(disc.breakpoints))))
        _CACHE[disc] = c
    return c


def inertia_factors(system, x, p, torsional_inertia: float = 0.0, axial_row: bool = True):
    """``U`` (``size x r``) and ``W`` (``r x size``) with ``B = U W`` the inertia operator at ``x``.

    ``W`` maps the unknowns to the transverse displacements ``dDelta1, dDelta2``
    at the collocation points (and, with ``torsional_inertia = j2 > 0``, to the
    section rotation about ``d3``, ``dphi - p.(d3 x dd3)/(1 + p.d3)``, with
    rotary inertia ``rho J = j2 rho A L^2``); ``U`` puts the inertia forces in
    the equation rows (module docstring). ``rho A = EI / L^4``.
    ``axial_row=False`` leaves out the K3 entry (a diagnostic).
    """
    model, disc = system.model, system.disc
    c = _static_parts(disc)
    EI, GJ, EA = float(p[3]), float(p[4]), float(p[5])
    L = model.rod.L
    rhoA = EI / L**4
    z = disc.jets(x)
    npts, q = disc.npts, c["q"]
    D1p, D2p = z[Jet.D1[1]], z[Jet.D2[1]]
    n = np.sqrt(1.0 + D1p**2 + D2p**2)
    d3 = np.stack([D1p, D2p, np.ones_like(D1p)]) / n
    F = z[Jet.F]
    alpha = 1.0 + (F * d3).sum(axis=0) / EA
    mA = rhoA * n / alpha
    row = c["row"]
    R = [row(0), row(1)]
    C = [q, npts + q]
    V = [mA, mA]
    if axial_row:
        R += [row(2), row(2)]
        C += [q, npts + q]
        V += [-mA * D1p, -mA * D2p]
    ncol = 2 * npts
    W = c["W2"]
    if torsional_inertia > 0:
        mJ = torsional_inertia * L**2 * mA
        r2 = np.stack([z[Jet.D1[2]], z[Jet.D2[2]], np.zeros_like(D1p)])
        d3p = (r2 - d3 * (d3 * r2).sum(axis=0)) / n
        tau = -(d3[0] * d3p[1] - d3[1] * d3p[0]) / (1.0 + d3[2])
        twist = z[Jet.PHI[1]] + tau
        c1 = d3[1] / (n * (1.0 + d3[2]))
        c2 = -d3[0] / (n * (1.0 + d3[2]))
        theta = c["PHI"] + sp.diags(c1) @ c["D1p"] + sp.diags(c2) @ c["D2p"]
        W = sp.vstack([W, theta], format="csr")
        cc = 2 * npts + q
        R += [row(3), row(4), row(5)] + ([row(2)] if axial_row else [])
        C += [cc, cc, cc] + ([cc] if axial_row else [])
        V += [mJ * d3[0], mJ * d3[1], mJ / GJ] + ([-mJ * twist] if axial_row else [])
        ncol = 3 * npts
    U = sp.csr_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(C))), shape=(disc.size, ncol))
    return U, W


def _params(system, phi_L: float) -> np.ndarray:
    if getattr(system, "param", "phi_L") == "phi_L":
        return system.params(phi_L)
    p = system.base.copy()
    p[0] = phi_L
    return p


# --------------------------------------------------------------------------
# Method 1
# --------------------------------------------------------------------------
def spectrum(system, x, phi_L: float, *, tol: float = NULL_TOL, method: str = "auto", k: int = 8,
             shift: float = SHIFT, torsional_inertia: float = 0.0, axial_row: bool = True,
             J=None, params=None) -> Spectrum:
    """Eigenvalues of the linearised dynamics near the origin and the number of unstable modes.

    ``system``: a :class:`rodcont.system.RodSystem` (or anything with ``disc``,
    ``model`` and ``params``); ``x`` a solution on its mesh at end rotation
    ``phi_L``. ``method``: ``dense`` (every finite eigenvalue of the reduced
    problem), ``arnoldi`` (ARPACK, the ``k`` nearest the shift, ``k`` doubled
    until they cover every possible unstable eigenvalue; dense when that would
    take more than a third of them) or ``auto`` (``arnoldi``; ``dense`` for a
    reduced problem of at most 60). ``tol``: the null band. ``J``: the
    Jacobian at ``(x, phi_L)`` if already made (saves about a fifth of the
    cost). ``torsional_inertia``, ``axial_row``: see :func:`inertia_factors`
    (they change the eigenvalues, not the counts). ``params``: the whole parameter vector (default
    ``system``'s at ``phi_L``).

    The controls are those of ``system``'s end conditions: ``J`` is its Jacobian, so under a prescribed
    torque (:class:`rodcont.ends.Torque`) the end rotation is free (its row is ``m(L) = M``, its unknown
    ``phi_L``), under a prescribed unstressed length the tension is an unknown and ``l0`` a constraint
    (an integral row). Neither row carries inertia (``B`` has rows only at the collocation points' force
    equations); the count is then that of the system with those controls.
    """
    if method not in ("auto", "dense", "arnoldi"):
        raise ValueError(f"method must be auto, dense or arnoldi, got {method!r}")
    p = _params(system, phi_L) if params is None else np.asarray(params, float)
    disc = system.disc
    if J is None:
        _, J, _ = disc.linearise(np.asarray(x, float), p)
    U, W = inertia_factors(system, x, p, torsional_inertia, axial_row)
    r = W.shape[0]
    if method == "auto":
        method = "dense" if r <= DENSE_MIN else "arnoldi"
    cap, reach = _cap(system, x, p)
    B = (U @ W).tocsc()
    d = _unknown_scales(system, p)
    for _ in range(4):
        A, Ur, Wc = _equilibrated(J - shift * B, U, W, d)
        lu = spla.splu(A, permc_spec="NATURAL")
        radius = math.inf
        if method == "arnoldi":
            try:
                nu, radius = _arnoldi(lu, Ur, Wc, k, reach + abs(shift))
                k_used = 0 if nu is None else nu.size
            except spla.ArpackError:
                nu = None
            if nu is None:           # the disc had to hold most of the spectrum (or ARPACK failed): do them all
                method = "dense"
        if method == "dense":
            nu = np.linalg.eigvals(Wc @ lu.solve(Ur.toarray()))
            radius = math.inf
        lam = shift + 1.0 / nu[nu != 0]
        if np.all(np.abs(lam - shift) > 1e-6 * abs(shift)):
            break
        shift *= 2.3  # an eigenvalue sits on the shift: the others are polluted; move it
    lam = lam[np.abs(lam) <= cap]
    lam = lam[np.argsort(-lam.real)]
    unstable = lam.real > tol
    null = np.abs(lam) <= tol
    flutter = ~unstable & ~null & (np.abs(lam.imag) > 1e-6 * np.abs(lam) + tol)
    return Spectrum(eigenvalues=lam, unstable=int(unstable.sum()), null=int(null.sum()), flutter=int(flutter.sum()),
                    cap=cap, shift=shift, method=method, radius=radius, tol=tol,
                    k=k_used if method == "arnoldi" else 0)


def _unknown_scales(system, p) -> np.ndarray:
    """The problem's own unit of each unknown: ``L`` for ``Delta1, Delta2``, ``1`` for ``phi``,
    ``EI/L^2`` for ``F`` (and 1 for anything else), ``L`` the span and ``EI`` from ``p``."""
    disc, L = system.disc, float(system.model.rod.L)
    d = np.ones(disc.size)
    for field, unit in ((0, L), (1, L), (3, float(p[3]) / L**2), (4, float(p[3]) / L**2), (5, float(p[3]) / L**2)):
        d[disc.index[field]] = unit
    names = getattr(system.model, "param_names", ())
    for j, q in zip(disc.free_index, disc.problem.free):  # a freed T (length control) is a force
        if q < len(names) and names[q] == "T":
            d[j] = float(p[3]) / L**2
    return d


def _equilibrated(A, U, W, d):
    """``(R A D, R U, W D)``: the unknowns in the problem's units (``D = diag(d)``,
    :func:`_unknown_scales`), then each row divided by its largest entry (``R``), so that
    ``W D (R A D)^{-1} R U = W A^{-1} U``.

    Why: a change of units multiplies the rows and columns of ``A = J - s0 B`` by powers of the
    length and force units (force rows by b/a, the torque row by 1/a^2, the force unknowns by
    b, ...); a factorisation of ``A`` as it comes rounds its small eigenvalues differently in each
    (a null eigenvalue at a fold, 5e-10 in the paper's units, was 6e-5 with lengths x 1e-3 and forces
    x 1e-6; the stable -16.92 at the end of that branch moved by 5e-4 with lengths x 1e-3 and forces
    x 1e6; now both to about 1e-8 of their size). ``R A D`` is the same matrix in any units, to the
    rounding of its entries (tests/test_units.py)."""
    A = sp.csc_matrix(A, copy=True)
    A.data *= np.repeat(d, np.diff(A.indptr))                 # column j times d_j
    m = np.zeros(A.shape[0])
    np.maximum.at(m, A.indices, np.abs(A.data))
    r = 1.0 / np.where(m > 0, m, 1.0)
    A.data *= r[A.indices]                                    # row i over its largest entry
    U = sp.csr_matrix(U, copy=True)
    U.data *= np.repeat(r, np.diff(U.indptr))
    W = sp.csr_matrix(W, copy=True)
    W.data *= d[W.indices]
    return A, U, W


def _cap(system, x, p) -> tuple[float, float]:
    """``(cap, reach)``: the largest ``|lambda|`` counted and the bound on unstable eigenvalues.

    ``reach = (K L)^4`` with ``K = max|m|/EI + sqrt(max|F|/EI) + max|u_perp| +
    2 pi/L``: the bending stiffness ``EI k^4`` beats the torque ``|m| k^3``, the
    force ``|F| k^2`` and the curvature terms for wavenumbers above ``K``, so an
    unstable eigenvalue stays below ``(K L)^4`` (a pure twist gives at most
    ``27/256 (mL/EI)^4``, a pure compression ``(F L^2/EI)^2 / 4``; observed at
    most 1/35 of the bound on the branches of Gamma = 0, 1, 5, the twisted and
    the compressed straight rods). ``cap = min((pi L / h_min)^4, 100 reach)`` (``h_min`` the shortest
    subinterval; the bending eigenvalue ``(k L)^4`` of the shortest wave the mesh holds, ``k = pi/h_min``):
    beyond it are modes the mesh cannot resolve and the few spurious
    eigenvalues rounding puts near ``1e13-1e17``.
    """
    model, disc = system.model, system.disc
    z = disc.jets(x)
    m, alpha, n, _ = model._axial_quantities(disc.S, z, p)
    D1p, D2p, D1pp, D2pp = z[Jet.D1[1]], z[Jet.D2[1]], z[Jet.D1[2]], z[Jet.D2[2]]
    cross = np.stack([-D2pp, D1pp, D1p * D2pp - D2p * D1pp])  # r' x r'' with r' = (D1', D2', 1), r'' = (D1'', D2'', 0)
    kappa = alpha * np.sqrt((cross ** 2).sum(axis=0)) / n ** 3
    EI, L = float(p[3]), model.rod.L
    Fmax = float(np.sqrt((z[Jet.F] ** 2).sum(axis=0)).max())
    KL = float(np.abs(m).max()) * L / EI + math.sqrt(Fmax * L * L / EI) + float(kappa.max()) * L + 2 * math.pi
    reach = KL ** 4
    mesh_cap = (math.pi * L / _static_parts(disc)["h_min"]) ** 4
    return min(mesh_cap, 100.0 * reach), reach


def _arnoldi(lu, U, W, k, reach):
    """The ``k`` largest ``nu`` of ``C = W (J - s0 B)^{-1} U`` by ARPACK, ``k`` doubled until they
    hold every eigenvalue within ``reach`` of the shift; ``(None, radius)`` when that would take
    more than a third of them (the dense problem is then cheaper)."""
    r = W.shape[0]
    op = spla.LinearOperator((r, r), matvec=lambda v: W @ lu.solve(U @ v), dtype=float)
    k = min(k, r - 2)
    while True:
        nu = spla.eigs(op, k=k, which="LM", return_eigenvectors=False, tol=1e-12,
                       ncv=min(r, max(2 * k + 1, 20)), v0=np.ones(r))
        radius = 1.0 / float(np.min(np.abs(nu)))          # every eigenvalue with |lambda - s0| < radius is here
        if radius >= reach:
            return nu, radius
        if 2 * k > r // 3:
            return None, radius
        k *= 2


def unstable_modes(system, x, phi_L: float, **options) -> int:
    """Number of unstable modes of the equilibrium ``x`` at end rotation ``phi_L`` (method 1).

    The number of eigenvalues with ``Re lambda > tol`` of the linearised
    dynamics ``J v = lambda B v`` (see the module docstring: sign rule,
    inertia, null eigenvalues). ``options``: those of :func:`spectrum`.
    """
    return spectrum(system, x, phi_L, **options).unstable


# --------------------------------------------------------------------------
# Branches (a Branch in memory or a BranchData read from a file)
# --------------------------------------------------------------------------
class _View:
    """The columns method 2 reads, from a :class:`Branch` or a :class:`BranchData`."""

    def __init__(self, branch, T=None, make_system=None):
        self.b = branch
        self.make_system = make_system
        if hasattr(branch, "table"):   # Branch
            t = branch.table
            self.phi = np.asarray(t["phi_L"], float)
            self.torque = np.asarray(t["torque"], float)
            self.dphi = np.asarray(t["dphi_ds"], float)
            self.kind = [str(v) for v in t["kind"]]
            self.rod, self.k = branch.rod, int(branch.k)
            if T is None and make_system is None:
                T = getattr(branch, "tension", math.nan)  # a branch in memory or read from a file
                if not np.isfinite(T):
                    raise ValueError("a weightless branch does not carry its tension: give T")
        else:                          # a table-less view of a file
            t = branch.branch
            self.phi = np.asarray(t["phi_L"], float)
            self.torque = np.asarray(t["torque"], float)
            self.dphi = np.asarray(t["dphi_ds"], float)
            self.kind = [v.decode() if isinstance(v, bytes) else str(v) for v in t["kind"]]
            self.rod, self.k = branch.rod, int(branch.attrs["k"])
            if T is None and make_system is None:
                T = branch.tension
        self.T = float(T) if T is not None else math.nan
        self._systems = {}

    def __len__(self):
        return self.phi.size

    def point(self, i):
        if hasattr(self.b, "table"):
            x = np.asarray(self.b.coefficients[i], float)
            if x.size == 0:  # a branch traced with store_every > 1 keeps what its file keeps
                raise ValueError(f"point {i} of the branch has no stored solution (it was traced with "
                                 f"store_every > 1: every M-th point and the special ones are kept)")
            return x, np.asarray(self.b.meshes[i], float)
        pt = self.b.point(i)
        return pt["x"], pt["breakpoints"]

    def tangent(self, i):
        if hasattr(self.b, "table"):
            t = np.asarray(self.b.tangents[i], float)
            if t.size == 0:
                raise ValueError(f"point {i} of the branch has no stored tangent (it was traced with "
                                 f"store_every > 1: the special points keep theirs)")
            return t[:-1]
        return self.b.direction(i)[0]

    def system(self, breakpoints):
        from .system import RodSystem
        key = breakpoints.tobytes()
        if key not in self._systems:
            if self.make_system is not None:
                self._systems[key] = self.make_system(breakpoints)
            else:
                self._systems[key] = RodSystem(self.rod, T=self.T, N=breakpoints.size - 1, k=self.k,
                                               breakpoints=breakpoints, wall=getattr(self.b, "wall", None))
        return self._systems[key]


def branch_spectra(branch, T: float | None = None, make_system=None, **options) -> list[Spectrum]:
    """:func:`spectrum` at every point of a branch (each on its own mesh).

    ``branch``: a :class:`rodcont.branch.Branch` or a loaded
    :class:`rodcont.branchfile.BranchData`. ``make_system(breakpoints)``: the
    system a point lives on (default: the canonical :class:`RodSystem` of the
    branch's rod and tension on those breakpoints).
    """
    v = _View(branch, T, make_system)
    out = []
    for i in range(len(v)):
        x, b = v.point(i)
        out.append(spectrum(v.system(b), x, v.phi[i], **options))
    return out


def branch_unstable_modes(branch, T: float | None = None, make_system=None, **options) -> list[int]:
    """Method 1 at every point of a branch: the ``/branch/unstable_modes`` column.

    ``T`` is needed only for a weightless branch (whose ``gamma`` is NaN).
    """
    return [s.unstable for s in branch_spectra(branch, T, make_system, **options)]


# --------------------------------------------------------------------------
# Method 2
# --------------------------------------------------------------------------
def fold_indices(branch) -> list[int]:
    """Folds of ``Phi`` along the branch: the located ones (kind ``fold``) and any
    sign change of ``dPhi/ds`` between two points that the tracker did not locate
    (returned as the index of the point after it, marked negative)."""
    v = _View(branch, T=0.0)
    out = []
    for i in range(len(v)):
        if v.kind[i] == "fold":
            out.append(i)
        elif i > 0 and v.dphi[i - 1] * v.dphi[i] < 0 and v.kind[i - 1] != "fold":
            out.append(-i)
    return out


def exchange_of_stability(branch, start: int | None = None, rule: str = "torque", T: float | None = None,
                          branch_point_changes: dict | None = None, make_system=None) -> list[int]:
    """Method 2: the number of unstable modes at every point, by exchange of stability at folds.

    Starts from ``start`` unstable modes at point 0 (default: method 1 there)
    and changes the count at each fold of ``Phi`` by ``+-1``: ``rule="torque"``
    reads the direction off the distinguished diagram (module docstring:
    ``sign(Phi'_after * torque')``, the torque derivative by the central
    difference of the neighbours); ``rule="pencil"`` off the null vectors
    of ``J v = lambda B v`` at the fold point. At a fold point the count is the
    smaller of the two sides (its null mode is not counted, as in method 1).
    ``branch_point_changes``: ``{index: change}`` for branch points (the
    diagram does not give it); a branch point without one raises
    ``ValueError``, and so does a count that would become negative (the rule's
    hypotheses fail). ``T``, ``make_system``: as in :func:`branch_spectra`
    (used for the start count and the pencil rule only).
    """
    if rule not in ("torque", "pencil"):
        raise ValueError(f"rule must be torque or pencil, got {rule!r}")
    needs_system = start is None or rule == "pencil"
    v = _View(branch, T if needs_system else 0.0, make_system)
    n = len(v)
    if start is None:
        x, b = v.point(0)
        start = unstable_modes(v.system(b), x, v.phi[0])
    changes = {}
    for f in fold_indices(branch):
        i = abs(f)
        changes[i] = (_fold_change_torque(v, i) if rule == "torque" else _fold_change_pencil(v, i), f >= 0)
    bp = dict(branch_point_changes or {})
    for i in range(n):
        if v.kind[i] == "branch_point":
            if i not in bp:
                raise ValueError(f"point {i} is a branch point: the exchange rule does not say how the count "
                                 f"changes there (give branch_point_changes)")
            changes[i] = (int(bp[i]), True)
    counts = []
    c = int(start)
    for i in range(n):
        if i in changes:
            d, at_point = changes[i]
            after = c + d
            if after < 0:
                raise ValueError(f"the count would become negative at point {i}: the exchange rule does not hold "
                                 f"here (a non-conservative problem, or a degenerate fold)")
            if at_point:
                counts.append(min(c, after))
            else:
                counts.append(after)
            c = after
        else:
            counts.append(c)
    return counts


def _fold_change_torque(v: _View, i: int) -> int:
    n = len(v)
    if v.kind[i] == "fold":   # located: its neighbours lie on either side
        if i == 0 or i == n - 1:
            raise ValueError(f"the fold at point {i} is at an end of the branch: one of its sides is missing")
        dmu = v.torque[i + 1] - v.torque[i - 1]
        dphi_after = v.phi[i + 1] - v.phi[i]
    else:                     # a sign change of dPhi/ds between points i - 1 and i
        dmu = v.torque[i] - v.torque[i - 1]
        dphi_after = v.dphi[i]
    if dmu == 0 or dphi_after == 0:
        raise ValueError(f"degenerate fold at point {i}: the torque or Phi does not change across it")
    return 1 if dphi_after * dmu > 0 else -1


def _fold_change_pencil(v: _View, i: int) -> int:
    """``sign(lambda')`` across the fold from ``lambda' = -Phi'' psi^T F_Phi / (c psi^T B phi)``."""
    x, b = v.point(i)
    s = v.system(b)
    p = _params(s, v.phi[i])
    _, J, (FPhi,) = s.disc.linearise(x, p, [0])
    phi, psi = _null_vectors(J, _unknown_scales(s, p))
    U, W = inertia_factors(s, x, p)
    tx = v.tangent(i)
    c = float(tx @ phi) if tx.size == phi.size else 1.0
    if c == 0:
        c = 1.0
    phidd = np.sign(v.phi[min(i + 1, len(v) - 1)] - v.phi[i]) if v.kind[i] == "fold" else np.sign(v.dphi[i])
    lam_dot = -phidd * float(psi @ FPhi) / (c * float(psi @ (U @ (W @ phi))))
    return 1 if lam_dot > 0 else -1


def _null_vectors(J, d):
    """Right and left null vectors of a (nearly) singular sparse matrix by two steps of inverse
    iteration, on ``R J D`` (:func:`_equilibrated`: the same in any units)."""
    n = J.shape[0]
    A, R, _ = _equilibrated(J, sp.identity(n, format="csr"), sp.identity(n, format="csr"), d)
    try:
        lu = spla.splu(A, permc_spec="NATURAL")
    except RuntimeError:
        lu = spla.splu((A + 1e-12 * sp.identity(n, format="csc")).tocsc(), permc_spec="NATURAL")
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal(n), rng.standard_normal(n)
    for _ in range(2):
        a = lu.solve(a)
        a /= np.linalg.norm(a)
        b = lu.solve(b, trans="T")
        b /= np.linalg.norm(b)
    return d * a, R @ b


# --------------------------------------------------------------------------
# The conservative counterpart and the reciprocity check
# --------------------------------------------------------------------------
def sleeve_system(rod, T: float, N: int = 15, k: int = 5, breakpoints=None):
    """The conservative self-feeding problem: the canonical one with ``F3(L) = T`` replaced by

    ``G(F3) + alpha^2 (EI |Delta''|^2 + GJ phi'^2) / 2 = G(T)`` at ``S = L``, ``G(t) = t + t^2/(2 EA)``:

    the rod is drawn from a straight, untwisted reservoir (a keyed frictionless
    sleeve along ``e1`` beyond the clamp) pulled by a dead axial load ``T``;
    the condition is ``H = G(T)`` for the rod's conserved energy-momentum
    ``H``, the natural condition of ``V = int psi dS + G(T) l0``. Returns a
    :class:`RodSystem` whose discretisation carries this condition (for
    :func:`spectrum`, :func:`reciprocity_ratio` and the continuation tracker).
    """
    from .system import RodSystem
    base = RodSystem(rod, T=T, N=N, k=k, breakpoints=breakpoints)
    model = base.model

    def bc(za, zb, p):
        g = model.bc(za, zb, p)
        EI, GJ, EA, Tp = p[3], p[4], p[5], p[1]
        F3 = zb[Jet.F[2]]
        a = 1.0 + F3 / EA
        sleeve = (F3 + F3 * F3 / (2 * EA)) + 0.5 * a * a * (EI * (zb[Jet.D1[2]] ** 2 + zb[Jet.D2[2]] ** 2)
                                                             + GJ * zb[Jet.PHI[1]] ** 2) - (Tp + Tp * Tp / (2 * EA))
        return np.concatenate([g[:-1], np.asarray(sleeve)[None]])

    from .collocation import Collocation
    new = copy.copy(base)
    new.disc = Collocation(dataclasses.replace(model.problem, bc=bc, affine_bc=False), base.disc.breakpoints, k)
    return new


def reciprocity_ratio(system, x, phi_L: float, h: float = 1e-6) -> float:
    """``(dm/dT)_Phi / (dl0/dPhi)_T`` at a solution: ``G'(T) = 1 + T/EA`` at every point of a
    conservative problem with potential ``V + G(T) l0`` (Maxwell); anything else says no such
    potential exists. Central differences along the tangents, of step ``h`` in ``Phi`` and ``h EI/L^2``
    in ``T`` (the problem's force unit); the tangents solved on ``R J D`` (:func:`_equilibrated`)."""
    p = _params(system, phi_L)
    _, J, (FPhi, FT) = system.disc.linearise(x, p, [0, 1])
    d = _unknown_scales(system, p)
    A, R, _ = _equilibrated(J, sp.identity(J.shape[0], format="csr"), sp.identity(J.shape[0], format="csr"), d)
    lu = spla.splu(A, permc_spec="NATURAL")
    xP, xT = -d * lu.solve(R @ FPhi), -d * lu.solve(R @ FT)
    out = system.model.output_evaluator(system.disc)
    eP, eT = np.eye(p.size)[0], np.eye(p.size)[1]
    hT = h * float(p[3]) / float(system.model.rod.L) ** 2
    dm_dT = (out(x + hT * xT, p + hT * eT)["torque"] - out(x - hT * xT, p - hT * eT)["torque"]) / (2 * hT)
    dl_dP = (out(x + h * xP, p + h * eP)["l0"] - out(x - h * xP, p - h * eP)["l0"]) / (2 * h)
    return float(dm_dT / dl_dP) if dl_dP != 0 else math.nan  # at Phi = 0 both vanish (l0 is even in Phi)
