"""Independent reference: soft-string (Johancsik) torque and drag in a surveyed well.

A reference implementation for the tests (numpy + scipy only, no code shared with
``rodcont``): the axial force ``F``, the torque ``M`` and the wall force per length ``N`` of a
string lying on the wall of a minimum-curvature well path, for the rig operations, integrated
from the bit to the surface; plus the buckling and lock-up estimates later tests compare the
stiff string with.  The equations are those of ``/work/shared/DRILLING.md``.

Axes and the well path
----------------------
Survey stations ``(MD, inclination, azimuth)`` (degrees in the files, radians inside).  This
module works in ``(x, y, z) = (north, east, TVD)``, ``z`` positive *down*; the unit tangent
pointing down-hole at a station is ``t = (sin I cos A, sin I sin A, cos I)``.  rodcont uses
``e1, e2, e3 = east, north, up``: a point ``(n, e, tvd)`` here is ``(e, n, -tvd)`` there
(:func:`to_rodcont_axes`).  Between stations the path is the minimum-curvature arc: the tangent
turns at a constant rate in the plane of ``t1, t2`` through the dogleg ``beta = 2 asin(|t2 - t1|/2)``,

    t(x) = [sin((1 - x) beta) t1 + sin(x beta) t2] / sin(beta),      x = (s - s1)/(s2 - s1),
    kappa n = dt/ds = beta/(s2 - s1) [cos(x beta) t2 - cos((1 - x) beta) t1] / sin(beta),
    r(x) = r1 + (s2 - s1)/(beta sin beta) [2 sin((2 - x) beta/2) sin(x beta/2) t1 + 2 sin^2(x beta/2) t2],

so ``r(1) - r1 = (s2 - s1)/2 RF (t1 + t2)``, ``RF = tan(beta/2)/(beta/2)``, the textbook formula
(the forms above have no cancellation for small doglegs).

The force balance of a cable (derivation of the equations)
----------------------------------------------------------
Arclength ``s`` = MD, increasing down-hole.  ``F`` is the axial force, tension positive: the part
below ``s`` pulls the part above with ``+F t``.  The element ``[s, s + ds]`` carries its buoyed
weight ``f_w = w e_d ds`` (``e_d = (0, 0, 1)`` down), the wall force ``N_vec ds`` (normal to ``t``)
and the friction ``f_mu ds``.  A soft string carries no shear and no bending moment, so

    d(F t)/ds + f_w + N_vec + f_mu = 0,        d(F t)/ds = F' t + F kappa n.

* Along ``t``:  ``F' = -w (e_d . t) - f_mu . t = -w cos(I) - f_mu . t``.
* Normal to ``t``: ``N_vec = -(F kappa n + w_perp)``, ``w_perp = w (e_d - (e_d . t) t)`` (the
  weight's part normal to the axis), so the wall force per length is

      |N| = |F kappa n + w_perp|.

Friction opposes the sliding velocity of the string's surface on the wall, whose axial part is
``V`` (``V > 0``: the string moves up, out of the hole) and circumferential part ``Omega r``; the
force ``mu |N|`` is split along ``(V, Omega r)`` (the velocity-vector method):

    s_a = V / sqrt(V^2 + (Omega r)^2),   s_r = Omega r / sqrt(V^2 + (Omega r)^2),
    dF/ds = -w cos(I) - s_a mu |N|,      dM/ds = -s_r mu |N| r,

with pick-up ``s_a = +1``, slack-off ``s_a = -1``, rotating off bottom or drilling ``s_a = 0, s_r = 1``
(moving up, the friction on the string points down-hole, ``+t``, and the force grows upward).

*Which sign the weight's normal component takes.*  Write ``t`` by its inclination ``I(s)`` and
azimuth ``A(s)``: ``dt/ds = I' e_I + A' sin(I) e_A`` with the unit vectors
``e_I = (cos I cos A, cos I sin A, -sin I)`` (in the vertical plane of ``t``, pointing to the
*high side*: its TVD component is ``-sin I``) and ``e_A = (-sin A, cos A, 0)`` (horizontal).  Then
``e_d . e_I = -sin I`` and ``e_d . e_A = 0``, so ``w_perp = -w sin(I) e_I`` and

    F kappa n + w_perp = (F I' - w sin I) e_I + F A' sin(I) e_A,
    |N| = sqrt((F I' - w sin I)^2 + (F A' sin I)^2)                   (Johancsik's form),

and for a planar well ``|N| = |F dI/ds - w sin I|``: in a build (``I' > 0``, inclination growing
down-hole) tension pulls the string to the high side of the hole and the weight to the low side,
so they *subtract*.  Johancsik, Friesen and Dawson (SPE 11380, 1984) write the lumped form
``Fn = [(Ft dA sin I)^2 + (Ft dI + W sin I)^2]^(1/2)``; its ``+`` is the cable equation's ``-`` only if
``dI`` is counted from the element's lower end to its upper end (upward, the direction of their
bit-to-surface recursion), where a build has ``dI < 0``.  welleng 0.30 (``torque_drag.force_normal``)
uses the ``+`` with ``inc_delta[i] = inc[i] - inc[i-1]``, counted *down-hole*: it adds the two in a build
and subtracts them in a drop, the opposite of the force balance (welleng's author made the same point
about another implementation: the order in which the points are taken sets the sign of the deltas,
github.com/pro-well-plan/torque_drag/issues/3).  ``weight_normal_sign=-1`` in :func:`soft_string`
reproduces welleng's sign for the comparison; the default ``+1`` is the cable equation.

welleng against this reference (``benchmarks/welleng_compare.py``, ``test_welleng_*``): on the
build-and-hold example (1 km, w = 235 N/m, r = 0.0635 m, mu = 0.25) welleng resampled every metre
equals the reference *with welleng's sign* to its first-order discretisation (hook loads to 14 N,
rotating torque 1981.8 against 1982.4 N m; on the bare stations 1914 N m); with the cable equation
the torque is 1409.6 N m and, with 100 kN at the bit, the pick-up drag over rotating 38.3 kN instead
of welleng's 48.2 kN (the issue's "48 kN and 1982 N m").  welleng's frictionless hook load on the bare
stations is 85 N high (its ``W cos`` of the average inclination instead of the TVD span).  With several
sections welleng's torque is also wrong for a second reason: ``get_forces_and_torsion`` zips the
bit-to-surface intervals with ``self.radius`` in surface-to-bit order (``welleng_model(fix_radius=True)``).

Integration
-----------
From the bit (``F = F_bit``: ``-WOB`` on bottom, 0 off bottom or an overpull; ``M = bit torque``) up to
the surface, classical Runge-Kutta (order 4) with steps no longer than ``step``, aligned with the
survey stations, the section boundaries and the friction stations (where the right-hand side
jumps).  ``|N|`` has a kink where ``F kappa n + w_perp`` vanishes, which can only happen on an arc in
a vertical plane (elsewhere the binormal component ``w (e_d . b)`` keeps it away from 0); there the
step is split at the zero (regula falsi on the Runge-Kutta step length), which keeps order 4
(test: ``test_order_of_convergence``).  :func:`planar_soft_string` solves the planar form with
scipy's DOP853 as a second, independently written integrator.

A published case with numbers
-----------------------------
None could be reproduced.  Searched (2026-11, this project's search tool, corpora pages, docs,
code, issues): Johancsik, Friesen and Dawson 1984 (SPE 11380; only the first page is stored,
scribd.com/document/484068991, no table of results); Sheppard, Wick and Burgess 1987 (first page,
de.scribd.com/document/215160784); McCormick, Frilot and Chiu 2011 (SPE 143623, first page); Wu,
Hareland and Fazaelizadeh 2011/2012 (MAS 5(6) and IOSRJEN 2(1), first pages); Fazaelizadeh 2013
(Calgary thesis, first page); Aadnoy and Andersen's analytical models (book excerpts without their
worked numbers); welleng's own tests (github jonnymaserati/welleng tests/test_torque_drag.py: no
reference values, only construction and the azimuth wrap); pro-well-plan/torque_drag
docs/source/calculations.rst (printed output of its own code on an unlisted trajectory file, not a
benchmark); Oliasoft's technical documentation (equations only).  One repository claiming "SPE 11380
Table 2" values (a 10 000 ft S-well, hook loads 164 and 129 klbf) says in its own comment that the
numbers are its model's calibrated output, not the paper's: not citable.  What the tests use
instead are closed forms: the capstan, the straight inclined hole, the frictionless hook load
(buoyed weight of the vertical projection), the rotating torque, and the heavy string on a
circular build, :func:`build_arc_closed_form` (the linear ODE solved exactly; the form of Aadnoy
and Andersen's analytical hoisting model for a build with the weight's normal component kept).

The benchmark survey (numbers for rodcont's broomstick)
-------------------------------------------------------
``/work/shared/data/well_s3d.csv`` with :func:`benchmark_string` (8" collars 200 m, 5" HWDP 150 m,
5" drill pipe to surface; mud 1200 kg/m^3, buoyancy factor 0.8471; mu = 0.25, one value for the whole
8.5" open hole), off bottom (no WOB, no bit torque); hook loads in kN, surface torque rotating off
bottom in N m (``test_benchmark_table``):

    bit MD (m)   pick-up   slack-off   rotating   surface torque
      1000        612.98     422.31     508.95        7985.4
      2000        930.10     456.78     642.16       17134.3
      3000       1491.23     651.88     965.66       26215.7
      3500       1695.87     709.64    1074.83       30795.8

Buckling and lock-up (for the slack-off tests)
----------------------------------------------
:func:`sinusoidal_buckling_load` (Dawson and Paslay 1984), :func:`helical_buckling_load` (Chen, Lin
and Cheatham 1990; Wu and Juvkam-Wold 1993), :func:`helical_contact_force` (Mitchell 1986) and
:func:`lockup_length` / :func:`max_transmitted_force` (derived here: the helix's wall force
``r_c P^2/(4 EI)`` turns the drag law into a Riccati equation solved in closed form).
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

STEEL_DENSITY = 7850.0   # kg/m^3 (DRILLING.md)
G = 9.80665

# DRILLING.md, "Typical data (SI)": OD, ID (m), w_air (N/m), EI (N m^2)
DRILL_PIPE_5IN = {"od": 0.127, "id": 0.1086, "w_air": 285.0, "w_air_body": 262.0, "EI": 1.23e6}
HWDP_5IN = {"od": 0.127, "id": 0.0762, "w_air": 624.0, "EI": 2.30e6}
COLLAR_8IN = {"od": 0.2032, "id": 0.0714, "w_air": 2189.0, "EI": 1.71e7}
HOLE_8_5IN = 0.2159


def benchmark_string(mud_density: float = 1200.0):
    """The 3-section string of the benchmark (DRILLING.md): 8" collars 200 m, 5" heavy-weight pipe
    150 m, 5" drill pipe (285 N/m in air with tool joints) to the surface; buoyed in ``mud_density``;
    contact radius the outer radius of each (the drill pipe's body, 0.0635 m)."""
    bf = buoyancy_factor(mud_density)
    return [Section(200.0, COLLAR_8IN["w_air"] * bf, COLLAR_8IN["od"] / 2, "8in collars"),
            Section(150.0, HWDP_5IN["w_air"] * bf, HWDP_5IN["od"] / 2, "5in HWDP"),
            Section(None, DRILL_PIPE_5IN["w_air"] * bf, DRILL_PIPE_5IN["od"] / 2, "5in drill pipe")]


def buoyancy_factor(mud_density: float, steel_density: float = STEEL_DENSITY) -> float:
    """``1 - rho_mud/rho_steel`` for a string full of the same mud inside and out."""
    return 1.0 - mud_density / steel_density


def to_rodcont_axes(points_net) -> np.ndarray:
    """``(north, east, TVD)`` rows to rodcont's ``(e1, e2, e3) = (east, north, up)``."""
    p = np.asarray(points_net, float)
    return np.stack([p[..., 1], p[..., 0], -p[..., 2]], axis=-1)


# --------------------------------------------------------------------------------------------
# Well path by minimum curvature
# --------------------------------------------------------------------------------------------
def _unit_tangent(inc, azi):
    return np.stack([np.sin(inc) * np.cos(azi), np.sin(inc) * np.sin(azi), np.cos(inc)], axis=-1)


class Survey:
    """Minimum-curvature well path through stations ``md`` (m), ``inc``, ``azi`` (degrees).

    Axes ``(north, east, TVD)``; the first station is at the origin.
    """

    def __init__(self, md, inc_deg, azi_deg):
        self.md = np.asarray(md, float)
        if self.md.ndim != 1 or self.md.size < 2 or np.any(np.diff(self.md) <= 0):
            raise ValueError("survey: need at least two stations with increasing MD")
        self.inc = np.radians(np.asarray(inc_deg, float))
        self.azi = np.radians(np.asarray(azi_deg, float))
        self.t = _unit_tangent(self.inc, self.azi)
        t1, t2 = self.t[:-1], self.t[1:]
        self.dogleg = 2.0 * np.arcsin(np.clip(np.linalg.norm(t2 - t1, axis=1) / 2.0, 0.0, 1.0))
        if np.any(self.dogleg > math.pi - 1e-6):
            raise ValueError("survey: a dogleg of 180 degrees between stations has no arc")
        self.dmd = np.diff(self.md)
        self.curved = self.dogleg > 1e-12
        steps = [self._arc_offset(j, 1.0) for j in range(self.md.size - 1)]
        self.stations = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])
        cross = np.cross(t1, t2)
        norm = np.linalg.norm(cross, axis=1)
        self.binormal = np.where(norm[:, None] > 0, cross / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
        # on an arc in a vertical plane |F kappa n + w_perp| can vanish (see the module docstring)
        self.vertical_plane = self.curved & (np.abs(self.binormal[:, 2]) < 1e-12)

    @classmethod
    def from_csv(cls, path):
        rows = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
        return cls(rows[:, 0], rows[:, 1], rows[:, 2])

    def interval(self, s) -> np.ndarray:
        """Index ``j`` of the interval ``[md[j], md[j+1]]`` holding each ``s``."""
        return np.clip(np.searchsorted(self.md, s, side="right") - 1, 0, self.md.size - 2)

    def _arc_offset(self, j, x):
        t1, t2, b, d = self.t[j], self.t[j + 1], self.dogleg[j], self.dmd[j]
        x = np.asarray(x, float)
        if b <= 1e-12:
            return d * x[..., None] * t1
        c1 = 2.0 * np.sin((2.0 - x) * b / 2.0) * np.sin(x * b / 2.0)
        c2 = 2.0 * np.sin(x * b / 2.0) ** 2
        return d / (b * np.sin(b)) * (c1[..., None] * t1 + c2[..., None] * t2)

    def geometry(self, j: int, s):
        """Tangent ``t`` and curvature vector ``kappa n = dt/ds`` at ``s`` (array) on interval ``j``."""
        s = np.asarray(s, float)
        t1, t2, b, d = self.t[j], self.t[j + 1], self.dogleg[j], self.dmd[j]
        x = (s - self.md[j]) / d
        if b <= 1e-12:
            return np.broadcast_to(t1, s.shape + (3,)).copy(), np.zeros(s.shape + (3,))
        sb = np.sin(b)
        t = (np.sin((1 - x) * b)[..., None] * t1 + np.sin(x * b)[..., None] * t2) / sb
        kn = (b / d) * (np.cos(x * b)[..., None] * t2 - np.cos((1 - x) * b)[..., None] * t1) / sb
        return t, kn

    def position(self, s) -> np.ndarray:
        """``(north, east, TVD)`` at measured depths ``s``."""
        s = np.atleast_1d(np.asarray(s, float))
        j = self.interval(s)
        out = np.empty(s.shape + (3,))
        for k in np.unique(j):
            m = j == k
            out[m] = self.stations[k] + self._arc_offset(k, (s[m] - self.md[k]) / self.dmd[k])
        return out

    def tvd(self, s) -> np.ndarray:
        return self.position(s)[..., 2]

    def inclination_rates(self, s):
        """Inclination, ``dI/ds`` and ``dA/ds`` from the exact tangent (for the Johancsik form)."""
        s = np.atleast_1d(np.asarray(s, float))
        j = self.interval(s)
        t = np.empty(s.shape + (3,))
        kn = np.empty_like(t)
        for k in np.unique(j):
            m = j == k
            t[m], kn[m] = self.geometry(k, s[m])
        inc = np.arccos(np.clip(t[..., 2], -1, 1))
        dinc = -kn[..., 2] / np.sin(inc)                 # d(cos I)/ds = t_z'
        dazi = (t[..., 0] * kn[..., 1] - t[..., 1] * kn[..., 0]) / np.sin(inc) ** 2
        return inc, dinc, dazi, t, kn


# --------------------------------------------------------------------------------------------
# The string, the friction factor and the operations
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """A string section: ``length`` (m; ``None``: up to the surface), buoyed weight per length ``w``
    (N/m), contact radius ``r`` (m: the outer radius that touches the wall)."""
    length: float | None
    w: float
    r: float
    name: str = ""


def section_spans(string, bit_depth):
    """``(top, bottom, section)`` from the bit up; the string is cut at the surface.

    The last section with ``length=None`` fills the rest; a string too short to reach the
    surface is an error.
    """
    spans, bottom = [], float(bit_depth)
    for k, sec in enumerate(string):
        top = 0.0 if sec.length is None else max(bottom - sec.length, 0.0)
        if sec.length is None and k != len(string) - 1:
            raise ValueError("only the top section may run to the surface (length=None)")
        spans.append((top, bottom, sec))
        bottom = top
        if top <= 0.0:
            return spans
    raise ValueError(f"the string ({bit_depth - bottom:g} m) does not reach the surface from {bit_depth:g} m")


def friction_at(mu, s):
    """Friction factor at MD ``s``: ``mu`` a number, or stations ``[(md_from, mu), ...]`` (piecewise
    constant, each value from its MD down to the next station's)."""
    if np.isscalar(mu):
        return float(mu)
    mds = [m for m, _ in mu]
    k = max(np.searchsorted(mds, s, side="right") - 1, 0)
    return float(mu[k][1])


def _friction_breaks(mu):
    return [] if np.isscalar(mu) else [float(m) for m, _ in mu]


@dataclass(frozen=True)
class Operation:
    """A rig operation: trip speed ``V`` (m/s, > 0 up), rotation rate ``omega`` (rad/s, >= 0), the axial
    force at the bit ``bit_force`` (tension positive: ``-WOB`` on bottom) and the ``bit_torque``.
    Pure pick-up/slack-off/rotation are the limits ``omega = 0`` or ``V = 0``."""
    trip_speed: float = 0.0
    omega: float = 0.0
    bit_force: float = 0.0
    bit_torque: float = 0.0
    name: str = ""

    def split(self, r: float):
        """``(s_a, s_r)``: the shares of ``mu |N|`` along the axis and around it (velocity vector)."""
        vr = self.omega * r
        speed = math.hypot(self.trip_speed, vr)
        if speed == 0.0:
            return 0.0, 0.0
        return self.trip_speed / speed, vr / speed


def pick_up(bit_force=0.0):
    return Operation(trip_speed=1.0, bit_force=bit_force, name="pick-up")


def slack_off(bit_force=0.0):
    return Operation(trip_speed=-1.0, bit_force=bit_force, name="slack-off")


def rotating(bit_force=0.0):
    return Operation(omega=1.0, bit_force=bit_force, name="rotating")


def drilling(wob, bit_torque):
    return Operation(omega=1.0, bit_force=-float(wob), bit_torque=float(bit_torque), name="drilling")


def combined(trip_speed, rpm, bit_force=0.0):
    return Operation(trip_speed=float(trip_speed), omega=2 * math.pi * rpm / 60.0, bit_force=bit_force,
                     name=f"V={trip_speed:g} m/s, {rpm:g} rpm")


STANDARD_OPERATIONS = (pick_up(), slack_off(), rotating())


# --------------------------------------------------------------------------------------------
# Integration
# --------------------------------------------------------------------------------------------
@dataclass
class Profile:
    """Soft-string profiles from the surface (index 0) to the bit: ``md``, ``axial_force`` (N, tension
    positive), ``torque`` (N m), ``normal_force`` (N/m, the wall force per length ``|N|``)."""
    md: np.ndarray
    axial_force: np.ndarray
    torque: np.ndarray
    normal_force: np.ndarray
    operation: Operation = field(default_factory=Operation)

    @property
    def hook_load(self) -> float:
        return float(self.axial_force[0])

    @property
    def surface_torque(self) -> float:
        return float(self.torque[0])


@dataclass
class _Piece:
    top: float
    bottom: float
    j: int          # survey interval
    w: float
    r: float
    mu: np.ndarray  # per case
    s_a: np.ndarray
    s_r: np.ndarray


def _pieces(survey, string, bit_depth, cases):
    """Smooth stretches of the right-hand side between stations, section ends and friction stations."""
    if not 0 < bit_depth <= survey.md[-1] + 1e-9:
        raise ValueError(f"bit depth {bit_depth:g} outside the survey (0 .. {survey.md[-1]:g})")
    spans = section_spans(string, bit_depth)
    breaks = {0.0, float(bit_depth)}
    breaks.update(float(m) for m in survey.md if 0.0 < m < bit_depth)
    breaks.update(top for top, _, _ in spans if 0.0 < top < bit_depth)
    for _, mu in cases:
        breaks.update(b for b in _friction_breaks(mu) if 0.0 < b < bit_depth)
    edges = sorted(breaks)
    pieces = []
    for a, b in itertools.pairwise(edges):
        mid = 0.5 * (a + b)
        sec = next(s for top, bot, s in spans if top <= mid <= bot)
        split = [op.split(sec.r) for op, _ in cases]
        pieces.append(_Piece(a, b, int(survey.interval(mid)), sec.w, sec.r,
                             np.array([friction_at(mu, mid) for _, mu in cases]),
                             np.array([sa for sa, _ in split]), np.array([sr for _, sr in split])))
    return pieces


def _normal_vector(F, t, kn, w, sign):
    """``F kappa n + sign w_perp`` for forces ``F`` (cases) at one point."""
    wperp = w * (np.array([0.0, 0.0, 1.0]) - t[2] * t)
    return F[:, None] * kn[None, :] + sign * wperp[None, :]


def _rhs(F, t, kn, pc, sign):
    N = np.linalg.norm(_normal_vector(F, t, kn, pc.w, sign), axis=1)
    fr = pc.mu * N
    return -pc.w * t[2] - pc.s_a * fr, -pc.s_r * fr * pc.r, N


def _rk4(F, M, s0, h, survey, pc, sign, geom=None):
    """One classical Runge-Kutta step from ``s0`` to ``s0 - h`` (upward)."""
    if geom is None:
        ts, kns = survey.geometry(pc.j, np.array([s0, s0 - h / 2, s0 - h]))
    else:
        ts, kns = geom
    k1f, k1m, _ = _rhs(F, ts[0], kns[0], pc, sign)
    k2f, k2m, _ = _rhs(F - h / 2 * k1f, ts[1], kns[1], pc, sign)
    k3f, k3m, _ = _rhs(F - h / 2 * k2f, ts[1], kns[1], pc, sign)
    k4f, k4m, _ = _rhs(F - h * k3f, ts[2], kns[2], pc, sign)
    return (F - h / 6 * (k1f + 2 * k2f + 2 * k3f + k4f),
            M - h / 6 * (k1m + 2 * k2m + 2 * k3m + k4m))


def _signed_normal(F, s, survey, pc, sign):
    """On a vertical-plane arc: ``(F kappa n + sign w_perp) . n`` (its only component)."""
    t, kn = survey.geometry(pc.j, np.array([s]))
    n = kn[0] / np.linalg.norm(kn[0])
    return _normal_vector(F, t[0], kn[0], pc.w, sign) @ n


def _kink_step(F, M, s0, h, survey, pc, sign):
    """A step over the zero of the signed wall force, split there (one case: arrays of length 1)."""
    q0 = _signed_normal(F, s0, survey, pc, sign)[0]

    def q_after(hh):
        Fh, _ = _rk4(F, M, s0, hh, survey, pc, sign)
        return _signed_normal(Fh, s0 - hh, survey, pc, sign)[0]

    lo, hi, qlo, qhi = 0.0, h, q0, q_after(h)
    side = 0
    for _ in range(60):        # regula falsi (Illinois)
        hm = (lo * qhi - hi * qlo) / (qhi - qlo)
        qm = q_after(hm)
        if qm == 0.0 or abs(hi - lo) < 1e-14 * h:
            break
        if np.sign(qm) == np.sign(qlo):
            lo, qlo = hm, qm
            if side == -1:
                qhi /= 2
            side = -1
        else:
            hi, qhi = hm, qm
            if side == 1:
                qlo /= 2
            side = 1
    F1, M1 = _rk4(F, M, s0, hm, survey, pc, sign)
    return _rk4(F1, M1, s0 - hm, h - hm, survey, pc, sign)


def _integrate(survey, string, bit_depth, cases, step, sign):
    """Integrate all ``cases`` (``(Operation, mu)``) from the bit up; arrays ``(n_points, n_cases)``."""
    pieces = _pieces(survey, string, bit_depth, cases)
    F = np.array([op.bit_force for op, _ in cases], float)
    M = np.array([op.bit_torque for op, _ in cases], float)
    rows = ([], [], [], [])

    def record(*values):
        for store, v in zip(rows, values):
            store.append(np.copy(v))
    for pc in reversed(pieces):
        n = max(1, math.ceil((pc.bottom - pc.top) / step - 1e-9))
        h = (pc.bottom - pc.top) / n
        s = pc.bottom - h * np.arange(n + 1)
        s[-1] = pc.top
        half = s[:-1] - h / 2
        ts, kns = survey.geometry(pc.j, s)
        th, knh = survey.geometry(pc.j, half)
        record(s[0], F, M, _rhs(F, ts[0], kns[0], pc, sign)[2])
        for k in range(n):
            geom = (np.array([ts[k], th[k], ts[k + 1]]), np.array([kns[k], knh[k], kns[k + 1]]))
            F1, M1 = _rk4(F, M, s[k], h, survey, pc, sign, geom)
            if survey.vertical_plane[pc.j]:
                q0 = _signed_normal(F, s[k], survey, pc, sign)
                q1 = _signed_normal(F1, s[k + 1], survey, pc, sign)
                for c in np.nonzero(q0 * q1 < 0)[0]:
                    one = _Piece(pc.top, pc.bottom, pc.j, pc.w, pc.r, pc.mu[c:c + 1],
                                 pc.s_a[c:c + 1], pc.s_r[c:c + 1])
                    F1[c], M1[c] = (v[0] for v in _kink_step(F[c:c + 1], M[c:c + 1], s[k], h, survey, one, sign))
            F, M = F1, M1
            if k < n - 1 or pc is pieces[0]:   # a piece's top is recorded as the next piece's bottom
                record(s[k + 1], F, M, _rhs(F, ts[k + 1], kns[k + 1], pc, sign)[2])
    return tuple(np.array(v)[::-1] for v in rows)


def soft_string(survey, string, bit_depth, operation=None, mu=0.25, *, step=10.0, weight_normal_sign=1.0):
    """Soft-string profiles for one operation with the bit at MD ``bit_depth``.

    ``string``: :class:`Section` s from the bit up; ``mu``: a number or MD stations (see
    :func:`friction_at`); ``step``: the longest Runge-Kutta step (m).  ``weight_normal_sign = -1``
    reproduces welleng 0.30's normal force (weight's normal component added to ``F kappa`` in a
    build; module docstring); ``+1`` is the cable equation.  Returns a :class:`Profile`.
    """
    operation = operation or pick_up()
    md, F, M, N = _integrate(survey, string, bit_depth, [(operation, mu)], step, weight_normal_sign)
    return Profile(md, F[:, 0], M[:, 0], N[:, 0], operation)


def hook_loads(survey, string, bit_depth, cases, *, step=10.0, weight_normal_sign=1.0):
    """Hook load and surface torque of several ``(Operation, mu)`` cases at one bit depth (integrated
    together): arrays ``(hook_load, surface_torque)`` of length ``len(cases)``."""
    _, F, M, _ = _integrate(survey, string, bit_depth, list(cases), step, weight_normal_sign)
    return F[0], M[0]


def broomstick(survey, string, depths, mus, operations=STANDARD_OPERATIONS, *, step=10.0):
    """Hook load and surface torque against bit depth: arrays ``(len(depths), len(operations), len(mus))``."""
    cases = [(op, mu) for op in operations for mu in mus]
    hl = np.empty((len(depths), len(operations), len(mus)))
    tq = np.empty_like(hl)
    for i, d in enumerate(depths):
        f, m = hook_loads(survey, string, d, cases, step=step)
        hl[i] = f.reshape(len(operations), len(mus))
        tq[i] = m.reshape(len(operations), len(mus))
    return hl, tq


# --------------------------------------------------------------------------------------------
# Second, planar formulation (independent integrator) and closed forms
# --------------------------------------------------------------------------------------------
def normal_force_vector(F, t, kn, w):
    """``|F kappa n + w_perp|`` (3D vector form), axes (north, east, TVD)."""
    t = np.asarray(t, float)
    wperp = w * (np.array([0.0, 0.0, 1.0]) - t[..., 2:3] * t)
    return np.linalg.norm(np.asarray(F)[..., None] * np.asarray(kn) + wperp, axis=-1)


def normal_force_angles(F, inc, dinc, dazi, w):
    """Johancsik's form ``sqrt((F I' - w sin I)^2 + (F A' sin I)^2)`` (module docstring)."""
    return np.hypot(F * dinc - w * np.sin(inc), F * dazi * np.sin(inc))


def planar_soft_string(md, inc_deg, w, r, mu, operation, bit_depth=None, rtol=1e-12):
    """The planar form on a planar well (one azimuth): ``dF/ds = -w cos I - s_a mu |F I' - w sin I|``,
    ``dM/ds = -s_r mu |F I' - w sin I| r``, ``I`` linear in MD between stations (minimum curvature in
    a vertical plane), one section; solved by scipy's DOP853.  Returns ``(hook_load, surface_torque)``."""
    from scipy.integrate import solve_ivp
    md = np.asarray(md, float)
    inc = np.radians(np.asarray(inc_deg, float))
    bit = md[-1] if bit_depth is None else float(bit_depth)
    s_a, s_r = operation.split(r)
    y = np.array([operation.bit_force, operation.bit_torque])
    knots = [m for m in md if 0 < m < bit][::-1]
    for a, b in zip([bit, *knots], [*knots, 0.0]):
        j = min(np.searchsorted(md, 0.5 * (a + b), side="right") - 1, md.size - 2)
        rate = (inc[j + 1] - inc[j]) / (md[j + 1] - md[j])

        def f(s, y, j=j, rate=rate):
            I = inc[j] + rate * (s - md[j])
            N = abs(y[0] * rate - w * math.sin(I))
            return [-w * math.cos(I) - s_a * mu * N, -s_r * mu * N * r]
        y = solve_ivp(f, (a, b), y, method="DOP853", rtol=rtol, atol=1e-9).y[:, -1]
    return float(y[0]), float(y[1])


def capstan_ratio(mu, beta):
    """``F_out / F_in = exp(mu beta)`` for a weightless string pulled around an arc of angle ``beta``."""
    return math.exp(mu * beta)


def straight_hole_force_change(w, length, inc_deg, mu, s_a):
    """``F_top - F_bottom = w L (cos I + s_a mu sin I)`` in a straight hole."""
    i = math.radians(inc_deg)
    return w * length * (math.cos(i) + s_a * mu * math.sin(i))


def straight_hole_rotating_torque(w, length, inc_deg, mu, r):
    """``M = mu w sin(I) r L`` in a straight inclined hole (rotating)."""
    return mu * w * math.sin(math.radians(inc_deg)) * r * length


def build_arc_closed_form(F_bottom, w, R, inc1_deg, inc2_deg, mu, s_a, weight_normal_sign=1.0):
    """Axial force at the top of a planar circular build of radius ``R`` (inclination ``I1`` at the top,
    ``I2 > I1`` at the bottom), the string pressed to the high side throughout (``F/R - g w sin I > 0``).

    With ``dI = ds/R`` the soft-string equation is the linear ODE
    ``dF/dI + k F = -w R cos I + g k w R sin I``, ``k = s_a mu``, ``g = weight_normal_sign`` (1: the cable
    equation, -1: welleng's sign).  Its particular solution ``F_p = A cos I + B sin I`` has
    ``A = -k w R (1 + g)/(1 + k^2)``, ``B = -w R (1 - g k^2)/(1 + k^2)``, and

        F(I1) = (F(I2) - F_p(I2)) exp(k (I2 - I1)) + F_p(I1).
    """
    k = s_a * mu
    g = weight_normal_sign
    a = -k * w * R * (1 + g) / (1 + k * k)
    b = -w * R * (1 - g * k * k) / (1 + k * k)
    i1, i2 = math.radians(inc1_deg), math.radians(inc2_deg)

    def fp(i):
        return a * math.cos(i) + b * math.sin(i)
    return (F_bottom - fp(i2)) * math.exp(k * (i2 - i1)) + fp(i1)


# --------------------------------------------------------------------------------------------
# Buckling and lock-up
# --------------------------------------------------------------------------------------------
def sinusoidal_buckling_load(EI, w, inc_deg, r_c):
    """Dawson and Paslay (1984, JPT 36(10) 1734, SPE 11167): ``F_s = 2 sqrt(EI w sin(I) / r_c)``,
    ``w`` the buoyed weight per length, ``r_c`` the radial clearance (hole radius minus pipe radius)."""
    return 2.0 * math.sqrt(EI * w * math.sin(math.radians(inc_deg)) / r_c)


def helical_buckling_load(EI, w, inc_deg, r_c, model="chen"):
    """Onset of helical buckling in an inclined or horizontal hole (loading):

    * ``"chen"``: Chen, Lin and Cheatham (1990, SPE Drilling Eng., "Tubing and casing buckling in
      horizontal wells"): ``2 sqrt(2) sqrt(EI w sin I / r_c) = sqrt(2) F_s``;
    * ``"wu"``: Wu and Juvkam-Wold (1993, SPE 25503, "Study of helical buckling of pipes in horizontal
      wells"; J. Energy Resour. Technol. 115(3) 190): ``2 (2 sqrt(2) - 1) sqrt(EI w sin I / r_c)``.  Their
      abstract (onepetro.org/SPEOKOG/proceedings-abstract/93POS/All-93POS/SPE-25503-MS/55658): "about
      1.8 times the critical buckling load that predicts the onset of sinusoidal buckling, and about 1.3
      times the so-called helical buckling load" (here 1.828 and 1.293; the README's "Wu and Juan").
    """
    q = math.sqrt(EI * w * math.sin(math.radians(inc_deg)) / r_c)
    if model == "chen":
        return 2.0 * math.sqrt(2.0) * q
    if model == "wu":
        return 2.0 * (2.0 * math.sqrt(2.0) - 1.0) * q
    raise ValueError(f"unknown model {model!r}")


def helical_contact_force(P, EI, r_c):
    """Wall force per length of a helically buckled string under compression ``P`` (Mitchell 1986,
    SPE 13064; Lubinski 1962): ``N_h = r_c P^2 / (4 EI)``."""
    return r_c * P * P / (4.0 * EI)


def _helix_scale(EI, w, r_c):
    # the Riccati scale a = 2 sqrt(EI w / r_c): in a horizontal hole the Dawson-Paslay load
    return 2.0 * math.sqrt(EI * w / r_c)


def lockup_length(EI, w, r_c, mu, toe_force=0.0, helical="chen"):
    """Length of horizontal section at which slack-off locks up (the push needed at the heel becomes
    infinite), for a required compression ``toe_force`` at the toe (the WOB; 0 off bottom).

    Model (soft string on the low side of a straight horizontal hole, compression ``P >= 0``, ``x``
    measured from the toe towards the heel, the string pushed in from the heel):

        dP/dx = mu w                       for P < P_h (the weight alone presses on the wall),
        dP/dx = mu (w + r_c P^2/(4 EI))    for P >= P_h (helix, Mitchell's contact force added),

    ``P_h`` the helical buckling load (:func:`helical_buckling_load`, ``sin I = 1``).  Sinusoidal
    buckling's extra contact force is neglected.  With ``a = 2 sqrt(EI w / r_c)`` the helical part is
    ``dP/dx = (mu w / a) (a^2 + P^2)/a``, so ``atan(P/a)`` grows linearly at rate ``mu w / a`` and ``P``
    is infinite after a finite length:

        L_lock = max(P_h - P_toe, 0)/(mu w) + (a/(mu w)) (pi/2 - atan(max(P_toe, P_h)/a)).

    With Chen's ``P_h = sqrt(2) a`` the helical stretch is ``0.6155 a/(mu w)``.  (Leaving the weight out
    of the helical wall force, ``dP/dx = mu r_c P^2/(4EI)``, gives ``a^2/(mu w P_h) = 0.7071 a/(mu w)``.)
    """
    a = _helix_scale(EI, w, r_c)
    ph = helical_buckling_load(EI, w, 90.0, r_c, helical)
    lin = max(ph - toe_force, 0.0) / (mu * w)
    return lin + a / (mu * w) * (math.pi / 2 - math.atan(max(toe_force, ph) / a))


def max_transmitted_force(EI, w, r_c, mu, length, heel_force=math.inf, helical="chen"):
    """Compression reaching the toe of a horizontal section of ``length`` pushed with ``heel_force`` at
    the heel (the model of :func:`lockup_length`); ``inf`` gives the most any push can deliver.
    Returns 0 when the push is used up before the toe (the string stalls there)."""
    a = _helix_scale(EI, w, r_c)
    ph = helical_buckling_load(EI, w, 90.0, r_c, helical)
    k = mu * w
    if heel_force > ph:
        ang = (math.pi / 2 if math.isinf(heel_force) else math.atan(heel_force / a))
        l_h = a / k * (ang - math.atan(ph / a))     # helical stretch from the heel down to P_h
        if length <= l_h:
            return a * math.tan(ang - k * length / a)
        length, heel_force = length - l_h, ph
    return max(heel_force - k * length, 0.0)


def compression_height(critical, w, inc_deg, mu, bit_force):
    """Soft string in slack-off in a straight inclined hole, ``F(h) = F_bit + w h (cos I - mu sin I)``
    at height ``h`` above the bit: the ``h`` where the compression ``-F`` reaches ``critical`` (e.g. the
    Dawson-Paslay load), ``inf`` if never (the compression does not grow upward), 0 if at the bit."""
    i = math.radians(inc_deg)
    grow = w * (mu * math.sin(i) - math.cos(i))     # d(-F)/dh
    need = critical - (-bit_force)
    if need <= 0:
        return 0.0
    return need / grow if grow > 0 else math.inf


# --------------------------------------------------------------------------------------------
# welleng 0.30, the second soft-string implementation (test extra; imported only here)
# --------------------------------------------------------------------------------------------
def welleng_model(md, inc_deg, azi_deg, bit_depth, sections, mu, *, mud_sg=0.0, spacing=None,
                  overpull=None, fix_radius=False):
    """welleng's ``TorqueDrag`` on the survey (resampled every ``spacing`` m by welleng's own minimum
    curvature when given), ``sections`` from the bit up as ``(length, w_air N/m, od m)`` (the last
    length ``None``: to the surface), buoyancy from ``mud_sg`` (0: the weights are already buoyed).

    ``fix_radius`` reverses welleng's radius array before recomputing: in 0.30
    ``get_forces_and_torsion`` zips the bit-to-surface intervals with ``self.radius`` in surface-to-bit
    order, so with several sections each interval's torque uses another section's radius.
    Returns the ``TorqueDrag`` (``tension``/``torque`` dicts, index 0 at the surface).
    """
    import warnings

    from welleng.architecture import BHA, WellBore
    from welleng.survey import Survey as WSurvey
    from welleng.torque_drag import TorqueDrag
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        survey = WSurvey(md=np.asarray(md, float), inc=np.asarray(inc_deg, float), azi=np.asarray(azi_deg, float))
        if spacing:
            survey = survey.interpolate_mds(np.arange(0.0, bit_depth + 1e-9, spacing))
        hole = WellBore("hole", top=0.0, bottom=float(bit_depth), method="top_down")
        hole.add_section(bottom=float(bit_depth), id=HOLE_8_5IN, coeff_friction_sliding=mu)
        string = BHA("string", top=0.0, bottom=float(bit_depth), method="bottom_up")
        left = float(bit_depth)
        for length, w_air, od in sections:
            length = left if length is None else min(length, left)
            string.add_section(length=length, od=od, unit_weight=w_air)
            left -= length
            if left <= 0:
                break
        td = TorqueDrag(survey, hole, string, fluid_density=mud_sg, overpull=overpull)
        if fix_radius:
            td.radius = td.radius[:td.index][::-1].copy()
            td.get_forces_and_torsion(overpull=overpull)
    return td
