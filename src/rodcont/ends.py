"""End conditions of the rod, as objects chosen per end.

Each end ``S = 0`` and ``S = L`` (the end of the reference curve) carries one
condition of each kind it needs:

* position: :class:`Clamp` (``Delta = Delta' = 0``: on the reference curve, tangent to it);
* twist: :class:`Rotation` (``phi = 0`` at ``S = 0``, the datum; ``phi = phi_L - beta`` at ``S = L``,
  ``beta`` the turn of the reference frame between the ends) or, at ``S = L``, :class:`Torque`
  (``m(L) = M``, the parameter ``torque``; ``phi_L`` becomes an unknown, solved for and read from
  the solution, with ``phi(L) = phi_L - beta`` defining it);
* axial, at one end: :class:`Tension` (``F . K3 = T`` there, the parameter ``T``) or, at ``S = L``,
  :class:`UnstressedLength` (``int n / alpha dS = l0``, the parameter ``l0``: ``T`` becomes an unknown,
  still defined as ``F . K3(L)``; an integral condition of the collocation core);
* optionally :class:`Phase` (not an end condition: a phase condition that fixes the turn of a weightless rod
  about its straight axis, freeing the weight as an unfolding parameter).

:class:`RodEnds` holds the two ends, checks that the conditions close the
problem (8 position, 2 twist, 1 axial condition, plus one per freed parameter
less one per integral condition) and assembles ``bc``: the rows grouped by kind
(positions, twists, axial), start before end: for the default ends exactly the
canonical problem's conditions in its order. ``affine`` only when every
condition is affine in the end jets and the parameters.

A new condition (a torque at the bit, a force at a free end) is one subclass:
``kind``; an affine one lists its rows ``z[j] - (p[q] + offset)`` as ``terms``
(evaluated for all such rows at once), any other sets ``affine = False`` and
writes ``rows(model, z, p, end)`` (analytic in the jet ``z``, which may carry a
trailing batch axis); and the parameter it adds (``param``, with its value) or
frees (``frees``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class EndCondition:
    """One condition at one end (module docstring)."""

    kind = ""           # "position", "twist" or "axial"
    affine = True       # affine in the end jet and the parameters
    param: str | None = None   # a parameter it adds to the model's parameter vector (its value: ``value``)
    frees: str | None = None   # a parameter it makes an unknown
    ends = (0, 1)       # the ends it may sit at

    @property
    def value(self) -> float:
        return 0.0

    def terms(self, model, end: int) -> list:
        """The rows of an affine condition as ``(jet index, parameter index or None, offset)``: the row is
        ``z[jet] - (p[parameter] + offset)`` (``z[jet] - offset`` without a parameter)."""
        raise NotImplementedError

    def rows(self, model, z, p, end: int) -> list:
        """The condition's rows at the end jet ``z``."""
        return [z[j] - ((p[q] if q is not None else 0.0) + off) for j, q, off in self.terms(model, end)]

    def integrand(self, model, S, z, p):
        """``q(S)`` of an integral condition ``int q dS = 0``, or None."""
        return None


@dataclass(frozen=True)
class Clamp(EndCondition):
    """``Delta1 = Delta1' = Delta2 = Delta2' = 0``: the end on the reference curve, tangent to it."""

    kind = "position"

    def terms(self, model, end):
        from .rod import Jet
        return [(Jet.D1[0], None, 0.0), (Jet.D1[1], None, 0.0), (Jet.D2[0], None, 0.0), (Jet.D2[1], None, 0.0)]


@dataclass(frozen=True)
class Rotation(EndCondition):
    """The section's rotation prescribed: ``phi(0) = 0`` (the datum), ``phi(L) = phi_L - beta``."""

    kind = "twist"

    def terms(self, model, end):
        from .rod import Jet
        if end == 0:
            return [(Jet.PHI[0], None, 0.0)]
        return [(Jet.PHI[0], 0, -model.twist_offset)]


@dataclass(frozen=True)
class Torque(EndCondition):
    """The end torque prescribed, ``m(L) = M`` (parameter ``torque``, value ``M``); the end rotation ``phi_L``
    is an unknown (``phi(L) = phi_L - beta``), read from the solution."""

    M: float = 0.0
    kind = "twist"
    affine = False
    param = "torque"
    frees = "phi_L"
    ends = (1,)

    @property
    def value(self) -> float:
        return float(self.M)

    def terms(self, model, end):
        return Rotation().terms(model, end)

    def rows(self, model, z, p, end):
        m = model.end_torque(z, p, end)
        return super().rows(model, z, p, end) + [m - p[model.param_names.index("torque")]]


@dataclass(frozen=True)
class Tension(EndCondition):
    """The axial force prescribed at the end: ``F . K3 = T`` (parameter ``T``)."""

    kind = "axial"

    def terms(self, model, end):
        from .rod import Jet
        return [(Jet.F[2], 1, 0.0)]


@dataclass(frozen=True)
class Phase(EndCondition):
    """A phase condition for a weightless rod on the straight reference, which can turn about its axis as a whole:
    its buckled equilibria come in circles and the Jacobian is singular on them. ``int_0^L Delta . g dS = 0``
    (``g`` the weight direction, across the axis) fixes the turn, and the weight ``w`` along ``g`` becomes an
    unknown (an unfolding parameter): 0 on every equilibrium of the symmetric rod (the discrete equations keep
    the symmetry: to rounding), so the equilibria are those of the weightless rod, each once. Regular where
    the weight's moment about the axis on the equilibrium, ``int Delta . (g x K3) dS``, is not 0 (on the
    straight rod and on a helix of non-zero mean offset); a bifurcation from the straight rod (a circle of
    helical modes) becomes a simple branch point, located and switched like any other. Not an end condition:
    it sits at ``S = L`` for the bookkeeping only (one integral condition, one freed parameter)."""

    kind = "phase"
    frees = "w"
    ends = (1,)
    #: the jet rows its integrand reads besides those of the residual: the deflections themselves
    integral_jets = "deflection"

    def terms(self, model, end):
        return []

    def integrand(self, model, S, z, p):
        from .rod import Jet
        g = np.asarray(model.gK, float)
        return z[Jet.D1[0]] * g[0] + z[Jet.D2[0]] * g[1]


@dataclass(frozen=True)
class UnstressedLength(EndCondition):
    """The rod's unstressed length fixed, ``int_0^L n / alpha dS = l0`` (parameter ``l0``); the tension
    ``T = F . K3(L)`` is an unknown, read from the solution."""

    l0: float = 1.0
    kind = "axial"
    param = "l0"
    frees = "T"
    ends = (1,)

    @property
    def value(self) -> float:
        return float(self.l0)

    def terms(self, model, end):
        return Tension().terms(model, end)

    def integrand(self, model, S, z, p):
        _, alpha, n, _ = model._axial_quantities(S, z, p)
        a, b = model.interval
        return n / alpha - p[model.param_names.index("l0")] / (b - a)


@dataclass(frozen=True)
class OnAxis(EndCondition):
    """The end on the reference curve and free to tilt (a pin: the bit on the hole axis):
    ``Delta1 = Delta2 = 0`` and no bending moment, ``u . K1 = u . K2 = 0`` (``u = alpha (r' x r'')/|r'|^3``, the
    curvature of the rod: ``EI u`` is its moment)."""

    kind = "position"
    affine = False

    def rows(self, model, z, p, end):
        from .rod import Jet
        zz = z.reshape(z.shape[0], -1)
        S = np.full(zz.shape[1], model.interval[end])
        if model.constant_frame:
            k = np.zeros((3, 3, zz.shape[1]))
        else:
            k = model._curve_data(S)[0]
        factors = None if model.sections is None else model.sections.factors(S)
        q = model._joint_quantities(k, zz, p, factors)
        shape = z.shape[1:]
        return [z[Jet.D1[0]], z[Jet.D2[0]], q[2].reshape(shape), q[3].reshape(shape)]


def _check_condition(c, end):
    if not isinstance(c, EndCondition):
        raise TypeError(f"an end condition must be a rodcont.ends.EndCondition (Clamp(), OnAxis(), Rotation(), "
                        f"Torque(M), Tension(), UnstressedLength(l0), Phase()), got {c!r}")
    if end not in c.ends:
        raise ValueError(f"{type(c).__name__} is available at S = L only (the rotation datum phi = 0 and the "
                         f"clamp are at S = 0)")
    for name in ("M", "l0"):
        v = getattr(c, name, None)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating))
                              or not np.isfinite(v)):
            raise TypeError(f"{type(c).__name__}.{name} must be a finite number, got {v!r}")
    if isinstance(c, UnstressedLength) and not c.l0 > 0:
        raise ValueError(f"the unstressed length l0 must be positive, got {c.l0!r}")


@dataclass(frozen=True)
class RodEnds:
    """The conditions at ``S = 0`` (``start``) and ``S = L`` (``end``); default: the canonical problem (both
    ends clamped, ``phi(0) = 0``, ``phi(L) = phi_L``, ``F . K3(L) = T``)."""

    start: tuple = (Clamp(), Rotation())
    end: tuple = (Clamp(), Rotation(), Tension())

    def __post_init__(self):
        for name in ("start", "end"):
            v = getattr(self, name)
            if isinstance(v, EndCondition):
                v = (v,)
            if not isinstance(v, (tuple, list)):
                raise TypeError(f"RodEnds.{name} must be a tuple of end conditions, got {v!r}")
            object.__setattr__(self, name, tuple(v))
        for end, conds in enumerate((self.start, self.end)):
            kinds = []
            for c in conds:
                _check_condition(c, end)
                kinds.append(c.kind)
            for kind in set(kinds):
                if kinds.count(kind) > 1:
                    raise ValueError(f"two {kind} conditions at S = {'0' if end == 0 else 'L'}")
            if "position" not in kinds:
                raise ValueError(f"the end S = {'0' if end == 0 else 'L'} needs a position condition (Clamp())")
            if "twist" not in kinds:
                raise ValueError(f"the end S = {'0' if end == 0 else 'L'} needs a twist condition "
                                 f"(Rotation(){' or Torque(M)' if end else ''})")
        axial = [c for c in self.start + self.end if c.kind == "axial"]
        if len(axial) != 1:
            raise ValueError(f"one axial condition (Tension() or UnstressedLength(l0)) at one end, got {len(axial)}")

    @property
    def conditions(self) -> list:
        """``(end, condition)`` in the order of the rows: positions, twists, axial; start before end."""
        order = ("position", "twist", "axial", "phase")
        return [(end, c) for kind in order for end, conds in enumerate((self.start, self.end))
                for c in conds if c.kind == kind]

    @property
    def affine(self) -> bool:
        return all(c.affine for _, c in self.conditions)

    @property
    def params(self) -> tuple:
        """``(name, value)`` of the parameters the conditions add (after ``phi_L, T, w, EI, GJ, EA``)."""
        return tuple((c.param, c.value) for _, c in self.conditions if c.param is not None)

    @property
    def frees(self) -> tuple:
        """The parameters the conditions make unknowns."""
        return tuple(c.frees for _, c in self.conditions if c.frees is not None)

    @property
    def has_integrals(self) -> bool:
        return any(type(c).integrand is not EndCondition.integrand for _, c in self.conditions)

    def find(self, cls):
        """The condition of class ``cls`` (at either end), or None."""
        return next((c for _, c in self.conditions if isinstance(c, cls)), None)

    @property
    def is_default(self) -> bool:
        return self == RodEnds()


# --------------------------------------------------------------------------
# The ends as a rig sees them (a drill string in a well: S = 0 at the rig, S = L at the bit)
# --------------------------------------------------------------------------
def rig_ends(bit_torque: float = 0.0, bit: str = "on-axis") -> RodEnds:
    """A drill string's ends: at the rig (``S = 0``) the clamp and the rotation datum ``phi(0) = 0``; at the bit
    (``S = L``) the bit on the hole axis (:class:`OnAxis`, free to tilt; ``bit="clamp"``: :class:`Clamp`), the
    bit torque ``M`` (the rock resists the clockwise turn: the internal torque ``m(L) = -M``, :class:`Torque`;
    the string's wind-up ``phi_L`` is solved for) and the axial force at the bit ``F . K3(L) = T``
    (:class:`Tension`: ``T = -WOB`` on bottom, 0 off bottom, :func:`bit_force`)."""
    position = {"on-axis": OnAxis(), "clamp": Clamp()}.get(bit)
    if position is None:
        raise ValueError(f"bit must be 'on-axis' or 'clamp', got {bit!r}")
    return RodEnds(start=(Clamp(), Rotation()), end=(position, Torque(-float(bit_torque)), Tension()))


def bit_force(wob: float = 0.0) -> float:
    """The axial force at the bit, ``T = -WOB`` (weight on bit a compression; 0 off bottom)."""
    if not (np.isfinite(wob) and wob >= 0):
        raise ValueError(f"the weight on bit must be a non-negative number, got {wob!r}")
    return -float(wob)


def axial_force_and_torque(model, disc, x, p, S) -> tuple:
    """The axial force ``F . d3`` (tension positive) and the torque the string above ``S`` turns the string
    below with, ``M = -m`` (positive for a clockwise drive seen from above), at the points ``S``."""
    from .rod import Jet, _dot
    S = np.atleast_1d(np.asarray(S, float))
    p = disc.full_params(x, p)
    z = (disc.jet_matrix(S) @ x).reshape(model.problem.jet_size, S.size)
    m, _, _, d3 = model._axial_quantities(S, z, p)
    return _dot(z[Jet.F], d3), 0.0 - m  # not -m: a string at rest has m = 0, and -0.0 printed as a torque misleads


def hook_load(model, disc, x, p) -> float:
    """The axial force at the rig, ``F . d3(0)`` (the travelling block's own weight excluded)."""
    return float(axial_force_and_torque(model, disc, x, p, [model.interval[0]])[0][0])


def surface_torque(model, disc, x, p) -> float:
    """The torque at the rig, ``M(0) = -m(0)``."""
    return float(axial_force_and_torque(model, disc, x, p, [model.interval[0]])[1][0])
