"""A drill string in a surveyed well: sections, buoyancy, bit depth, and torque and drag with the stiff string.

Conventions (``/work/shared/DRILLING.md``): the well's reference curve is its survey by minimum curvature
(:class:`rodcont.curves.MinimumCurvatureWell`, axes ``e1, e2, e3`` = east, north, up; TVD ``= -z``), its
arclength ``S`` the measured depth MD, ``S = 0`` at the rig and ``S = L`` at the bit. The axial force is
positive in tension; the hook load is the axial force at the rig, the weight on bit a compression at the bit.

* :class:`DrillString`: sections from the bit up (bottom-hole assembly, heavy-weight pipe, drill pipe), each
  with its length, ``EI, GJ, EA``, weight per length (or outer and inner diameter and the steel's constants)
  and outer radius; buoyed in the mud (``w = w_air (1 - rho_mud / rho_steel)``, or a buoyancy factor).
  Read from TOML (:meth:`DrillString.from_toml`, ``examples/drill_string.toml``).
* :class:`Well`: the survey, the hole's diameter and the friction factor (numbers or MD stations: cased and
  open hole), the contact law's smoothing; read from TOML (``examples/well_s3d.toml``).
* :func:`torque_and_drag`: the equilibrium of the string with its bit at a measured depth, for an operation
  (:class:`rodcont.loads.Operation`), with Coulomb friction (:class:`rodcont.loads.Friction`), the rig's end
  conditions (:func:`rodcont.ends.rig_ends`), each section's clearance ``hole radius - its radius`` and the
  section boundaries as joins (:class:`rodcont.rod.Sections`); returns a :class:`TorqueDrag`.
* :func:`soft_string`: the soft-string (Johancsik) estimate on the same well path, the broomstick's second curve.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .blas import with_one_blas_thread
from .contact import Wall
from .loads import Operation

STEEL = dict(E=207e9, G=80e9, density=7850.0)
GRAVITY = 9.80665


class DrillingError(ValueError):
    """A string or well file, or a depth, that cannot be used (one line)."""


@dataclass(frozen=True)
class Section:
    """One section of the string: ``length`` (m, None: up to the rig), ``EI, GJ`` (N m^2), ``EA`` (N), weight per
    length in air ``w_air`` (N/m) and outer radius ``radius`` (m, where it touches the wall)."""

    name: str
    length: float | None
    EI: float
    GJ: float
    EA: float
    w_air: float
    radius: float


def _section(row: dict, steel: dict, where: str) -> Section:
    """A section from a TOML table: stiffnesses and weight given, or from ``od``/``id`` and the steel."""
    known = {"name", "length", "od", "id", "EI", "GJ", "EA", "w_air", "radius"}
    unknown = sorted(set(row) - known)
    if unknown:
        raise DrillingError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")
    for key, v in row.items():  # id = 0: a solid bar (the default), not a bore of no size refused
        if key != "name" and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                              or not (v >= 0 if key == "id" else v > 0)):
            what = "non-negative" if key == "id" else "positive"
            raise DrillingError(f"{where}: {key} must be a {what} number, got {v!r}")
    od, idia = row.get("od"), row.get("id", 0.0)
    if od is not None and not idia < od:
        raise DrillingError(f"{where}: id {idia!r} must be smaller than od {od!r}")
    derived = {}
    if od is not None:
        A = math.pi / 4 * (od**2 - idia**2)
        Ia = math.pi / 64 * (od**4 - idia**4)
        derived = dict(EI=steel["E"] * Ia, GJ=steel["G"] * 2 * Ia, EA=steel["E"] * A,
                       w_air=steel["density"] * GRAVITY * A, radius=od / 2)
    values = {key: float(row[key]) if key in row else derived.get(key) for key in ("EI", "GJ", "EA", "w_air", "radius")}
    missing = [key for key, v in values.items() if v is None]
    if missing:
        raise DrillingError(f"{where}: needs od (and id) or {', '.join(missing)}")
    length = row.get("length")
    return Section(str(row.get("name", where)), None if length is None else float(length), **values)


@dataclass(frozen=True)
class DrillString:
    """Sections from the bit up (the last may have ``length=None``: it runs to the rig) and the buoyancy factor
    ``1 - rho_mud / rho_steel`` (a string full of the same mud inside and out)."""

    sections: tuple
    buoyancy_factor: float = 1.0

    def __post_init__(self):
        if not self.sections:
            raise DrillingError("a drill string needs at least one section")
        if any(s.length is None for s in self.sections[:-1]):
            raise DrillingError("only the top section may run to the rig (no length)")
        if not 0 < self.buoyancy_factor <= 1:
            raise DrillingError(f"the buoyancy factor must lie in (0, 1], got {self.buoyancy_factor!r}")

    @classmethod
    def from_toml(cls, path: str, mud_density: float | None = None) -> DrillString:
        """``[string]`` (``mud_density`` kg/m^3 or ``buoyancy_factor``; ``E, G, density`` of the steel) and one
        ``[[section]]`` per section from the bit up; ``mud_density`` given here replaces the file's."""
        doc = _read_toml(path, "string file")
        _known_tables(doc, ("string", "section"), path)
        head = doc.get("string", {})
        unknown = sorted(set(head) - {"mud_density", "buoyancy_factor", "E", "G", "density"})
        if unknown or not isinstance(doc.get("section"), list):
            raise DrillingError(f"{path}: needs [string] (mud_density or buoyancy_factor, E, G, density) and "
                                f"[[section]] tables" + (f"; unknown key(s) {', '.join(unknown)}" if unknown else ""))
        for key in ("E", "G", "density", "buoyancy_factor"):
            _positive(head, key, path)
        if "mud_density" in head:
            _positive(head, "mud_density", path, zero=True)
        if "mud_density" in head and "buoyancy_factor" in head:
            raise DrillingError(f"{path}: give mud_density or buoyancy_factor in [string], not both")
        steel = {key: float(head.get(key, v)) for key, v in STEEL.items()}
        sections = tuple(_section(row, steel, f"{path}: section {i + 1}") for i, row in enumerate(doc["section"]))
        rho = mud_density if mud_density is not None else head.get("mud_density")
        bf = head.get("buoyancy_factor", 1.0) if rho is None else 1.0 - float(rho) / steel["density"]
        try:
            return cls(sections, float(bf))
        except DrillingError as exc:
            raise DrillingError(f"{path}: {exc}") from None

    def spans(self, depth: float) -> list:
        """``(top, bottom, section)`` in ``S`` from the rig down (the string cut at the rig), for the bit at
        ``depth``."""
        out, bottom = [], float(depth)
        for s in self.sections:
            top = 0.0 if s.length is None else max(bottom - s.length, 0.0)
            out.append((top, bottom, s))
            bottom = top
            if top <= 0.0:
                return out[::-1]
        raise DrillingError(f"the string ({depth - bottom:g} m) does not reach the rig from the bit at {depth:g} m: "
                            f"give the top section no length")


def _positive(table: dict, key: str, where: str, zero: bool = False) -> None:
    """``table[key]``, if there, a finite number > 0 (>= 0 with ``zero``), else a one-line :class:`DrillingError`
    (a text E or a density of 0 were an 'unexpected failure': test_a_bad_value_in_the_string_header_...)."""
    v = table.get(key)
    if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                          or not (v >= 0 if zero else v > 0)):
        raise DrillingError(f"{where}: {key} must be a {'non-negative' if zero else 'positive'} number, got {v!r}")


def _read_toml(path: str, what: str) -> dict:
    import tomllib

    from .safeio import InputFileError, read_input
    try:
        return tomllib.loads(read_input(path, "toml", what=what).decode("utf-8"))
    except InputFileError as exc:
        raise DrillingError(str(exc)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DrillingError(f"{path}: not a TOML file ({' '.join(str(exc).split())})") from None


def _known_tables(doc: dict, known: tuple, path: str) -> None:
    """A :class:`DrillingError` for a table or key outside ``known`` (a ``[casing]`` table was read as nothing)."""
    unknown = sorted(set(doc) - set(known))
    if unknown:
        raise DrillingError(f"{path}: unknown table(s) or key(s) {', '.join(unknown)} (known: "
                            f"{', '.join('[' + k + ']' for k in known)})")


def _table(value, what: str, where: str):
    """A number or MD stations ``[[MD, value], ...]`` (piecewise constant from each MD on), as given."""
    from .loads import _stations
    try:
        _, values = _stations(value, what)
    except ValueError as exc:
        raise DrillingError(f"{where}: {exc}") from None
    if not np.all(np.isfinite(values)) or np.any(values < 0):  # friction = nan solved to 'residual not finite'
        raise DrillingError(f"{where}: {what} must be finite and non-negative, got {value!r}")
    return float(value) if isinstance(value, (int, float)) else tuple((float(a), float(b)) for a, b in value)


@dataclass(frozen=True)
class Well:
    """Survey stations ``(MD, inclination, azimuth)`` (degrees), the hole diameter (m; a number or MD
    stations ``((MD, d), ...)``: casing to its shoe, open hole below), the friction factor (number or MD
    stations) and the contact law's smoothing ``eps`` (:class:`rodcont.contact.Wall`)."""

    stations: np.ndarray
    hole_diameter: float | tuple = 0.2159
    friction: float | tuple = 0.25
    eps: float = 1e-5
    survey: str | None = None  # the survey file it was read from (an input: outputs may not replace it)

    @classmethod
    def from_toml(cls, path: str) -> Well:
        """``[well]``: ``survey`` (a CSV of MD, INC, AZI, relative to the file), ``hole_diameter``, ``friction``,
        ``eps``."""
        from .curves import MinimumCurvatureWell
        doc = _read_toml(path, "well file")
        _known_tables(doc, ("well",), path)
        sec = doc.get("well")
        if not isinstance(sec, dict) or "survey" not in sec:
            raise DrillingError(f"{path}: needs a [well] section with survey = FILE.csv")
        unknown = sorted(set(sec) - {"survey", "hole_diameter", "friction", "eps"})
        if unknown:
            raise DrillingError(f"{path}: unknown key(s) {', '.join(unknown)} in [well] (known: survey, "
                                f"hole_diameter, friction, eps)")
        survey = os.path.join(os.path.dirname(os.path.abspath(path)), str(sec["survey"]))
        try:
            stations = MinimumCurvatureWell.from_file(survey).stations
        except (ValueError, OSError) as exc:
            raise DrillingError(f"{path}: survey {sec['survey']}: {exc}") from None
        if stations[0][0] != 0.0:  # --depth is MD from the rig: from a later first station it read the wrong MD
            raise DrillingError(f"{path}: survey {sec['survey']} starts at MD {stations[0][0]:g} m: a well's survey "
                                f"starts at the rig, MD 0 (add a first station 0, 0, 0 above a vertical top hole)")
        eps = sec.get("eps", 1e-5)
        if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not 1e-12 <= eps <= 0.1:
            raise DrillingError(f"{path}: eps must be a number in 1e-12 .. 0.1, got {eps!r}")
        return cls(np.asarray(stations, float), _table(sec.get("hole_diameter", 0.2159), "hole_diameter", path),
                   _table(sec.get("friction", 0.25), "friction", path), float(eps), survey)

    @property
    def total_depth(self) -> float:
        return float(self.stations[-1, 0] - self.stations[0, 0])

    def check_depth(self, depth: float) -> float:
        """``depth`` (m, bit MD from the rig), checked: inside the survey and deeper than the hole is wide at the
        rig. A shorter string is no rod in its hole: at 1e-300 m the survey cut to it had one station, at 1 cm
        the homotopy met an exactly singular Jacobian (test_a_bit_depth_within_the_holes_diameter_is_refused)."""
        depth = float(depth)
        if not 0 < depth <= self.total_depth * (1 + 1e-12):
            raise DrillingError(f"the bit depth {depth:g} m lies outside the survey (0 .. {self.total_depth:g} m)")
        hole = float(_value_at(self.hole_diameter, np.asarray(0.0)))
        if depth <= hole:
            raise DrillingError(f"the bit depth {depth:g} m is within the hole's diameter ({hole:g} m) of the rig: "
                                f"a string that short is no rod in its hole; give a depth above {hole:g} m")
        return depth

    def curve(self, depth: float):
        """The well path from the rig to the bit at MD ``depth`` (the survey cut there on its arc)."""
        from .curves import MinimumCurvatureWell
        st = self.stations
        md = st[0, 0] + self.check_depth(depth)
        keep = st[st[:, 0] < md - 1e-9 * max(1.0, md)]
        if keep.shape[0] == 0 or abs(st[keep.shape[0], 0] - md) <= 1e-9 * max(1.0, md):
            return MinimumCurvatureWell(np.vstack([keep, st[keep.shape[0]]]))
        return MinimumCurvatureWell(np.vstack([keep, _station_on_arc(st[keep.shape[0] - 1], st[keep.shape[0]], md)]))


def _station_on_arc(a, b, md):
    """The survey station at MD ``md`` on the minimum-curvature arc from station ``a`` to ``b``."""
    def tangent(inc, azi):
        i, z = math.radians(inc), math.radians(azi)
        return np.array([math.sin(i) * math.sin(z), math.sin(i) * math.cos(z), -math.cos(i)])
    t1, t2 = tangent(a[1], a[2]), tangent(b[1], b[2])
    x = (md - a[0]) / (b[0] - a[0])
    beta = 2.0 * math.asin(min(1.0, 0.5 * float(np.linalg.norm(t2 - t1))))
    t = t1 if beta < 1e-14 else (math.sin((1 - x) * beta) * t1 + math.sin(x * beta) * t2) / math.sin(beta)
    inc = math.degrees(math.acos(max(-1.0, min(1.0, -t[2]))))
    azi = math.degrees(math.atan2(t[0], t[1])) % 360.0 if math.hypot(t[0], t[1]) > 1e-12 else float(a[2])
    return np.array([md, inc, azi])


# --------------------------------------------------------------------------
# The string in the well: the rod's data
# --------------------------------------------------------------------------
def _value_at(table, S):
    """A number, or MD stations (piecewise constant, the first value before them), at ``S``."""
    if isinstance(table, float):
        return np.full(np.shape(S), table)
    at = np.array([a for a, _ in table])
    v = np.array([b for _, b in table])
    return v[np.clip(np.searchsorted(at, S, side="right") - 1, 0, v.size - 1)]


@dataclass
class StringInWell:
    """What the rod model needs for the string with its bit at ``depth``: the curve, the rod's reference values
    (the section at the rig), the sections' factors, the outer radius and the clearance at MD stations."""

    curve: object
    rod: object
    sections: object
    spans: list
    radius: tuple       # ((S_from, r), ...)
    clearance: object   # c, or steps ((S, c), ...) (SteppedWall)
    weights: tuple      # ((S_from, buoyed w), ...)

    @property
    def w_max(self) -> float:
        return max(w for _, w in self.weights)


def place_string(well: Well, string: DrillString, depth: float) -> StringInWell:
    """The string with its bit at MD ``depth``: sections as :class:`rodcont.rod.Sections` (factors over the
    section at the rig), clearance ``hole radius - outer radius`` section by section."""
    from .rod import RodParameters, Sections
    curve = well.curve(depth)
    L = curve.length
    spans = string.spans(L)
    bf = string.buoyancy_factor
    top = spans[0][2]
    rod = RodParameters(EI=top.EI, GJ=top.GJ, EA=top.EA, w=top.w_air * bf, L=curve.span)
    table = [(s.w_air / top.w_air, s.EI / top.EI, s.GJ / top.GJ, s.EA / top.EA) for _, _, s in spans]
    bounds = [a for a, _, _ in spans[1:]]
    sections = Sections(bounds, table) if bounds else None
    radius = tuple((a, s.radius) for a, _, s in spans)
    weights = tuple((a, s.w_air * bf) for a, _, s in spans)
    return StringInWell(curve, rod, sections, spans, radius, _clearance(well, radius, L), weights)


def _clearance(well: Well, radius: tuple, L: float):
    """``c = hole radius - outer radius``: a number, or steps ``((S, c), ...)`` (each from its ``S`` on, the first at
    0) where a section's radius or the hole changes (:class:`SteppedWall`)."""
    steps = sorted({0.0} | {a for a, _ in radius if 0 < a < L}
                   | ({a for a, _ in well.hole_diameter if 0 < a < L} if isinstance(well.hole_diameter, tuple)
                      else set()))
    rows = []
    for a in steps:
        c = float(_value_at(well.hole_diameter, np.asarray(a)) / 2 - _value_at(radius, np.asarray(a)))
        if not c > 0:
            raise DrillingError(f"the string does not fit in the hole at MD {a:g} m (clearance {c:g} m)")
        if not rows or c != rows[-1][1]:
            rows.append((a, c))
    return rows[0][1] if len(rows) == 1 else tuple(rows + [(L, rows[-1][1])])


@dataclass(frozen=True)
class SteppedWall(Wall):
    """A hole whose clearance is piecewise constant: ``clearance = ((S0, c0), (S1, c1), ..., (L, c_last))``, each
    ``c_i`` from ``S_i`` to the next station (the last row closes the table), steps where a section's outer radius
    or the hole's diameter changes. The steps are the wall's stations (mesh breakpoints: the collocation points
    never sit on one), no cone between them: the contact law sees each pipe's own clearance right up to its end
    (a taper would wedge the stiffer pipe across it)."""

    def clearance_at(self, S):
        t = np.asarray(self.clearance, float)
        i = np.clip(np.searchsorted(t[:, 0], np.real(np.asarray(S, float)), side="right") - 1, 0, t.shape[0] - 2)
        return t[i, 1]

    def slope_at(self, S):
        return np.zeros(np.shape(S))

    @property
    def spec(self) -> str:
        """The wall's line (:attr:`rodcont.contact.Wall.spec`) marked ``steps=1``: read back as a SteppedWall."""
        return super().spec + ",steps=1"


# --------------------------------------------------------------------------
# Torque and drag: one equilibrium
# --------------------------------------------------------------------------
@dataclass
class TorqueDrag:
    """One equilibrium of the string: ``hook_load`` (N, the axial force at the rig), ``surface_torque`` (N m),
    profiles against MD on a fine grid (``profile``: ``S``, ``axial_force``, ``torque``, ``pressure`` the wall force
    per length, ``gap``, ``in_contact``), ``side_force`` (the wall's total), the contact ``zones``, the error
    estimate and the mesh size ``N``; ``system``, ``x``: the solved rod (:class:`rodcont.system.RodSystem`);
    ``well``, ``string``: what it was solved for (a file's drilling record, :func:`drilling_record`)."""

    depth: float
    operation: Operation
    mu: float | tuple
    wob: float
    bit_torque: float
    hook_load: float
    surface_torque: float
    profile: dict
    side_force: float
    zones: list
    error: float
    N: int
    system: object = field(repr=False)
    x: np.ndarray = field(repr=False)
    placed: StringInWell = field(repr=False)
    well: Well | None = field(default=None, repr=False)
    string: DrillString | None = field(default=None, repr=False)

    @property
    def params(self) -> np.ndarray:
        return self.system.disc.full_params(self.x, self.system.base)


def _force_scale(placed: StringInWell, T_bit: float) -> float:
    """The contact law's ``P``: the heaviest section's weight, and the string's whole weight pulled round the
    sharpest dogleg (:func:`rodcont.contact.default_force_scale` with that tension)."""
    from .contact import default_force_scale
    W = sum(w * (b - a) for (a, w), (_, b, _) in zip(placed.weights, placed.spans))
    return max(placed.w_max, default_force_scale(placed.rod, abs(T_bit) + W, placed.curve))


def build_system(placed: StringInWell, friction, T_bit: float, bit_torque: float, eps: float, N: int, k: int = 5,
                 bit: str = "on-axis", force_scale: float | None = None, breakpoints=None):
    """The :class:`rodcont.system.RodSystem` of the placed string: weight, wall (clearance table, smoothing
    ``eps``, force scale :func:`_force_scale` or ``force_scale``), the friction load, the rig's ends, the sections
    as joins; on ``N`` subintervals or on ``breakpoints`` (conformed to the stations)."""
    from .ends import rig_ends
    from .loads import WallContact, Weight
    from .system import RodSystem
    kind = Wall if isinstance(placed.clearance, float) else SteppedWall
    wall = kind(placed.clearance, eps=eps, force_scale=force_scale or _force_scale(placed, T_bit))
    loads = [Weight(), WallContact(wall)] + ([friction] if friction is not None else [])
    sysm = RodSystem(placed.rod, T=T_bit, N=N, k=k, curve=placed.curve, wall=wall, param="T",
                     ends=rig_ends(bit_torque, bit), loads=loads, sections=placed.sections)
    return sysm if breakpoints is None else sysm.with_mesh(sysm.conform(breakpoints))


def carried_guess(sysm, prev: TorqueDrag):
    """The solution ``prev`` moved with the bit onto ``sysm`` (the string at a depth ``h`` deeper, on ``prev``'s
    mesh shifted by ``h``): the fields at ``S`` are ``prev``'s at ``S - h`` (the sections move with the bit; at
    ``S < h`` the rig's values), fitted by :meth:`rodcont.collocation.Collocation.transfer`."""
    import copy
    h = float(sysm.disc.breakpoints[-1] - prev.system.disc.breakpoints[-1])
    src, moved = copy.copy(prev.system.disc), {}
    src.breakpoints = src.breakpoints + h

    def shift(space):
        if id(space) not in moved:
            moved[id(space)] = copy.copy(space)
            moved[id(space)].breakpoints, moved[id(space)].knots = space.breakpoints + h, space.knots + h
        return moved[id(space)]
    src.spaces = [shift(sp) for sp in src.spaces]
    return sysm.disc.transfer(prev.x, src)


def settle(sysm, x, tol: float = 1e-10, **options):
    """The equilibrium inside the hole from a guess that may cross its wall: the contact law's smoothing from
    0.1 down to the wall's own by factors of 10, Newton at each (a factor 100 stalls on a slack string);
    ``options`` go to :func:`rodcont.drivers.solve.settle_in_conduit`."""
    from .drivers.solve import settle_in_conduit
    return settle_in_conduit(sysm, x, sysm.base, tol, factor=10.0, **options)


def _estimate(sysm, x, max_error: float = 1e-6, max_side_force_error: float = 1e-3) -> tuple:
    """``(error, side force's error)`` of a solution (:class:`rodcont.mesh.ErrorEstimator`, the richer problem
    solved to convergence where its one step puts either estimate above its guard)."""
    from .mesh import ErrorEstimator
    est = ErrorEstimator(sysm, watch=True)
    err = est.estimate(x, sysm.value())
    if _ratio(err, est.watched.get("side_force", math.nan), max_error, max_side_force_error) > 1.0:
        err = est.converged_estimate()
    return err, est.watched.get("side_force", math.nan)


def _penetration(sysm, x) -> float:
    """How deep the string sits inside the wall, over the clearance (:func:`rodcont.contact.penetration`), but not
    at a clearance's step: there the law is not collocated, the larger pipe's end carries a point contact and the
    spline's value at the breakpoint leans into the wall while the law holds on each side; refining, not a stiffer
    law, resolves it."""
    con = sysm.model.contact(sysm.disc, x, sysm.base)
    S, wall = con["S"], sysm.model.wall
    keep = np.ones(S.size, bool)
    if isinstance(wall, SteppedWall):
        steps = np.array([a for a, _ in wall.clearance[1:-1]])
        keep = np.min(np.abs(S[:, None] - steps[None, :]), axis=1) > 1e-9 * S[-1]
    return float(np.max(-con["gap"][keep] / wall.clearance_at(S[keep])))


def _ratio(err, sf, max_error, max_side_force_error) -> float:
    """The larger estimate relative to its guard (a side force's NaN where there is no wall)."""
    return max(err / max_error, 0.0 if math.isnan(sf) else sf / max_side_force_error)


def adapt(sysm, x, max_error: float = 1e-6, max_side_force_error: float = 1e-3, N_max: int = 4000,
          tol: float = 1e-10):
    """Refine the mesh (and stiffen the contact law past :data:`rodcont.contact.MAX_PENETRATION`) until the
    estimates meet their guards, at most eight rounds: ``(system, x, error, side force's error)``."""
    from .contact import MAX_PENETRATION
    from .drivers.solve import stiffen_contact
    from .mesh import adapted_mesh
    for _ in range(8):
        pen = _penetration(sysm, x)  # first: an estimate of a law about to be stiffened is thrown away (1.8 s)
        if pen > MAX_PENETRATION:
            x = stiffen_contact(sysm, x, sysm.base, sysm.model.contact_scale * pen / (MAX_PENETRATION / 10), tol)
            continue
        err, sf = _estimate(sysm, x, max_error, max_side_force_error)
        ratio = _ratio(err, sf, max_error, max_side_force_error)
        if ratio <= 1.0 or sysm.disc.N >= N_max:
            return _said(sysm, x, err, sf, ratio, max_error, max_side_force_error)
        b = adapted_mesh(sysm.disc.breakpoints, sysm.interval_defect(x, sysm.value()), sysm.disc.k,
                         ratio * max_error, max_error / 4, N_max=N_max)
        sysm, x = _remeshed(sysm, x, b, tol)
    err, sf = _estimate(sysm, x, max_error, max_side_force_error)
    ratio = _ratio(err, sf, max_error, max_side_force_error)
    return _said(sysm, x, err, sf, ratio, max_error, max_side_force_error)


def _remeshed(sysm, x, b, tol):
    """``(system, x)`` on the breakpoints ``b`` (conformed), Newton from ``x`` carried over, else settled afresh."""
    new = sysm.with_mesh(sysm.conform(b))
    r = new.disc.newton(new.disc.transfer(x, sysm.disc), new.base, tol=tol)
    return new, (r.x if r.converged else settle(new, new.model.initial_guess(new.disc, new.value()), tol))


def _said(sysm, x, err, sf, ratio, max_error, max_side_force_error) -> tuple:
    """``(system, x, error, side force's error)``, with a ``RuntimeWarning`` where an estimate is above its guard
    (the mesh at its cap ``N_max`` or out of rounds)."""
    if ratio > 1.0:
        warnings.warn(f"the equilibrium at N = {sysm.disc.N} is above its guard: estimated error {err:.2g} "
                      f"(max_error {max_error:g}), side force's {sf:.2g} (max {max_side_force_error:g}); "
                      f"raise N_max", RuntimeWarning, stacklevel=3)
    return sysm, x, err, sf


def first_mesh(placed: StringInWell, T_bit: float, N_max: int = 4000) -> int:
    """Two subintervals per length over which the lightest pipe lifts off its wall, ``(EI c / w)^(1/4)``, and
    per sag length ``(EI / w)^(1/3)`` (:func:`rodcont.drivers.solve.first_mesh` with the string's clearance)."""
    from .drivers.solve import first_mesh as rod_mesh
    kind = Wall if isinstance(placed.clearance, float) else SteppedWall
    return rod_mesh(placed.rod, T_bit, placed.curve, kind(placed.clearance), N_max)


@with_one_blas_thread
def torque_and_drag(well: Well, string: DrillString, depth: float, operation: Operation | str = "static", *,
                    mu=None, wob: float = 0.0, bit_torque: float = 0.0, trip_speed: float | None = None,
                    rpm: float | None = None, bit: str = "on-axis", N: int | None = None, k: int = 5,
                    max_error: float = 1e-6, max_side_force_error: float = 1e-3, N_max: int = 4000,
                    tol: float = 1e-10, force_scale: float | None = None,
                    start: TorqueDrag | None = None) -> TorqueDrag:
    """The stiff string's equilibrium with the bit at MD ``depth`` for ``operation`` (a name of
    :data:`rodcont.loads.OPERATIONS` or an :class:`rodcont.loads.Operation`; ``trip_speed``/``rpm`` combine the
    motion), friction factor ``mu`` (default the well's: number or MD stations), ``wob`` (N, a compression at
    the bit; only on bottom, ``drill``) and ``bit_torque`` (N m). The mesh adapts until the estimated error
    is below ``max_error`` and the side force's below ``max_side_force_error``. ``force_scale``: the contact
    law's (default :func:`_force_scale`); ``start``: an equilibrium at a nearby depth to start from (its mesh and
    law carried down with the bit, :func:`carried_guess`; a cold start where Newton does not converge from it)."""
    from .ends import bit_force
    from .loads import Friction
    from .system import check_number
    wob, bit_torque = check_number("wob", wob, nonnegative=True), check_number("bit_torque", bit_torque)
    op = operation if isinstance(operation, Operation) else Operation.named(operation, trip_speed, rpm)
    if op.name != "drill" and (wob or bit_torque):
        raise DrillingError(f"weight and torque on bit are for drilling (the bit on bottom), not {op.name}")
    placed = place_string(well, string, depth)
    mu = well.friction if mu is None else mu
    friction = Friction(mu, placed.radius, op)
    T = bit_force(wob)
    N, N_max = _mesh_size(N, N_max, placed, T)
    with np.errstate(all="ignore"):
        sysm, x = _warm(placed, friction, T, bit_torque, well.eps, k, start, tol) if start is not None else (None, None)
        if x is None:
            sysm, x = _cold_start(placed, friction, T, bit_torque, well.eps, N, k, force_scale, tol)
        sysm, x, err, sf = adapt(sysm, x, max_error, max_side_force_error, N_max, tol)
    alpha = sysm.model.stretch_factor_min(sysm.disc, x, sysm.base)
    if not alpha > 0:  # 1 + F.d3/EA <= 0: a pipe shortened past zero length (seen: --wob 1e9, alpha -0.42)
        raise DrillingError(f"the string is compressed past zero length (stretch 1 + F/EA = {alpha:.3g} <= 0): "
                            f"an axial load beyond its pipe's EA" + (f" (weight on bit {wob:g} N)" if wob else ""))
    return _result(sysm, x, placed, op, mu, wob, bit_torque, err, well, string)


def _cold_start(placed, friction, T, bit_torque, eps, N, k, force_scale, tol) -> tuple:
    """``(system, x)`` from the straight guess: settled (:func:`settle`), else with the load raised gradually
    (:func:`_loaded_gradually`), else settled by the homotopy on the mesh itself, which a failure of the softest
    law on the coarse mesh skipped (settle_in_conduit's softest_is_verdict)."""
    from .drivers.solve import ConvergenceError
    sysm = build_system(placed, friction, T, bit_torque, eps, N, k, force_scale=force_scale)
    guess = sysm.model.initial_guess(sysm.disc, T)
    try:
        return sysm, settle(sysm, guess, tol, softest_is_verdict=True)
    except ConvergenceError as exc:
        at = getattr(exc, "at", None)
        skipped = at is not None and at[0] is not sysm
    try:
        return _loaded_gradually(sysm, friction, tol)
    except ConvergenceError:
        if not skipped:
            raise
    return sysm, settle(sysm, guess, tol, coarsen=1)


def _mesh_size(N, N_max, placed: StringInWell, T: float) -> tuple:
    """``(N, N_max)``: the first mesh (default :func:`first_mesh`) checked against the cap, as
    :func:`rodcont.drivers.solve.solve_equilibrium` checks it (a first mesh above ``N_max`` makes the cap none),
    and a ``RuntimeWarning`` where it is below :func:`first_mesh`'s rule: at 500 m in examples/well_s3d.toml
    N = 200 put 35.1 kN on the wall in no contact zone with an estimate of 1.4e-10, N = 300-1680 10.01-10.02 kN
    in 4-5 zones (test_a_mesh_below_the_first_mesh_rule_is_said)."""
    from .system import check_number
    N_max = int(check_number("N_max", N_max, integer=True))
    if N_max < 1:
        raise DrillingError(f"N_max must be an integer >= 1, got {N_max}")
    need = first_mesh(placed, T, 2**62)
    N = min(need, N_max) if N is None else int(check_number("N", N, integer=True))
    if not 1 <= N <= N_max:
        raise DrillingError(f"N = {N} must lie in 1 .. N_max = {N_max} (raise N_max for a larger mesh)")
    if N < need:  # the estimates compare richer spaces on the same mesh: an unresolved contact is not seen
        warnings.warn(f"N = {N} is below the N = {need} this string's own lengths need (two subintervals per "
                      f"lift-off length (EI c/w)^(1/4) and sag length (EI/w)^(1/3) of its lightest pipe): a contact "
                      f"may be unresolved, which the error estimate cannot see; raise N_max (or N)", RuntimeWarning,
                      stacklevel=4)
    return N, N_max


#: the contact law's smoothing the load is raised under (the wall's own where stiffer): under eps = 1e-5 each step
#: of the 2875 m slack-off took ~27 Newton iterations damped to 1/8-1/32 (the tension's step, ~3e4 N, moves the
#: contacts across the stiff law), under 1e-3 five; the law is then stiffened at the full load by factors of 10
RAMP_EPS = 1e-3


def _loaded_gradually(sysm, friction, tol, step: float = 0.25) -> tuple:
    """``(sysm, x)`` with the system's friction factor and the bit's force and torque raised together from 0 to
    theirs, Newton from the previous step's solution, the step halved where Newton fails (down to 1/64): a string
    compressed by its friction or its WOB near its buckling load is not reached from the straight guess on the axis
    (a column far past its Euler load), a string without either is (it hangs in tension). The load is raised under
    the softer law :data:`RAMP_EPS` on the coarse rung of the homotopy's ladder, then the law stiffened to the
    wall's own up the ladder (:func:`rodcont.drivers.solve.climb`); where that fails, the load is raised under the
    wall's own law on the mesh itself. Every step scales the one system in place (:class:`_LoadScale`): a system
    built a step made the 3000 m slack-off discretise 19 times, not 7, and cost 9.96 s of CPU, not 8.09."""
    from .drivers.solve import ConvergenceError, _coarse_system, _ladder, climb
    eps = sysm.model.wall.eps
    soft = max(eps, RAMP_EPS)
    if soft == eps:
        return sysm, _raise_load(sysm, friction, eps, tol, step)
    try:
        coarse = _coarse_system(sysm, None)  # the load raised on it, the law stiffened up the ladder (_ladder)
        start = sysm if coarse is None else coarse
        x = _raise_load(start, friction, soft, tol, step)
        rungs = _ladder(sysm, None, _stiffening(soft, eps), coarse)
        return sysm, climb(rungs, x, start, sysm.base, tol, True)
    except ConvergenceError:  # the softer law's path is no verdict: the wall's own is
        return sysm, _raise_load(sysm, friction, eps, tol, step)


def _stiffening(soft: float, eps: float) -> list:
    """The smoothings from ``soft`` down to ``eps`` by factors of 10 (:func:`settle`'s), ``soft`` excluded."""
    stages, e = [], soft / 10
    while e > eps * (1 + 1e-9):
        stages.append(e)
        e /= 10
    return stages + [eps]  # the last stage the wall's own exactly


class _LoadScale:
    """The friction factor (of ``friction``, a load of ``sysm``'s model) and the bit's force ``T`` and torque (in
    ``sysm.base``) at ``lam`` times the system's own, set in place; ``restore()`` sets them back. The systems on
    other meshes of the same model (``with_mesh``) share its friction, not its ``base``."""

    def __init__(self, sysm, friction):
        self.sysm, self.friction = sysm, friction
        self.mu = None if friction is None else friction.mu_table
        names = sysm.model.param_names
        self.at = [names.index(q) for q in ("T", "torque") if q in names]
        self.full = sysm.base[self.at].copy()

    def __call__(self, lam: float) -> None:
        if self.friction is not None:
            self.friction.mu_table = (self.mu[0], lam * self.mu[1])
        self.sysm.base[self.at] = lam * self.full

    def restore(self) -> None:
        if self.friction is not None:
            self.friction.mu_table = self.mu
        self.sysm.base[self.at] = self.full


def _raise_load(sysm, friction, eps: float, tol: float, step: float) -> np.ndarray:
    """``x``: ``sysm``'s load raised from 0 in steps of ``step`` under the law ``eps`` (:func:`_loaded_gradually`),
    on ``sysm``'s mesh; its load and law are its own again on return."""
    from .drivers.solve import ConvergenceError
    model, wall = sysm.model, sysm.model.wall
    scale = _LoadScale(sysm, friction)
    try:
        model.wall = dataclasses.replace(wall, eps=eps)
        scale(0.0)
        x, lam = settle(sysm, sysm.model.initial_guess(sysm.disc, sysm.value()), tol), 0.0
        while lam < 1.0:
            nxt = min(1.0, lam + step)
            scale(nxt)
            r = sysm.disc.newton(x, sysm.base, tol=tol, max_iter=40)
            if r.converged:
                x, lam = r.x, nxt
            elif step > 1 / 64:
                step /= 2
            else:
                raise ConvergenceError(f"no equilibrium found with the friction and the bit's load raised from 0 "
                                       f"past {lam:g} of theirs: {r.message}")
        return x
    finally:
        scale.restore()
        model.wall = wall


def _warm(placed, friction, T, bit_torque, eps, k, start, tol):
    """``(system, x)`` from the equilibrium ``start`` carried down with the bit (its law, its mesh shifted), or
    ``(None, None)`` where Newton does not converge from it."""
    L = placed.curve.length
    moved = start.system.disc.breakpoints[1:-1] + (L - start.depth)
    b = np.concatenate([[0.0], moved[(moved > 1e-6 * L) & (moved < L * (1 - 1e-9))], [L]])
    sysm = build_system(placed, friction, T, bit_torque, eps, b.size - 1, k,
                        force_scale=start.system.model.contact_scale, breakpoints=b)
    r = sysm.disc.newton(carried_guess(sysm, start), sysm.base, tol=tol, max_iter=40)
    return (sysm, r.x) if r.converged else (None, None)


def _result(sysm, x, placed, op, mu, wob, bit_torque, err, well=None, string=None) -> TorqueDrag:
    from .ends import axial_force_and_torque
    model, disc = sysm.model, sysm.disc
    p = disc.full_params(x, sysm.base)
    con = model.contact(disc, x, p)
    F, M = axial_force_and_torque(model, disc, x, p, con["S"])
    # on the wall where the gap is below 1 % of the clearance (the law's standoff is eps c P / p; a free span's
    # gap is of the order of c): a pressure level would miss a light pipe's contact under a large force scale
    profile = dict(S=con["S"], axial_force=F, torque=M, pressure=con["pressure"], gap=con["gap"],
                   in_contact=con["gap"] <= 0.01 * model.wall.clearance_at(con["S"]))
    return TorqueDrag(float(placed.curve.length), op, mu, float(wob), float(bit_torque), float(F[0]), float(M[0]),
                      profile, con["side_force"], con["zones"], float(err), disc.N, sysm, x, placed, well, string)


def law_error(td: TorqueDrag, h: float = 1e-3) -> dict:
    """How far the contact law's smoothing moves ``hook_load`` (N) and ``surface_torque`` (N m) from exact contact:
    the first-order change ``q(0) - q(eps) = -eps dq/d(eps)`` at the law's force scale. Both the standoff inside
    the wall (``eps c p / P``) and the pressure on a free span (``eps c P / gap``, whose friction the hook load and
    the torque carry) are linear in ``eps``. ``dx/d(eps)`` solves the linearised equations at the solution (one LU),
    ``dF/d(eps)`` by central differences of step ``h eps``. At 1000 m rotating on examples/well_s3d.toml (mu 0.25):
    -8.0 N m of the surface torque's 7749.5, and Newton on its mesh at eps / 2 and eps / 10 moves it by 0.50 and
    0.91 of that (test_the_laws_error_estimate_is_the_change_a_smoother_law_makes)."""
    from .ends import axial_force_and_torque
    from .linalg import LU
    sysm, x = td.system, td.x
    disc, model, wall = sysm.disc, sysm.model, sysm.model.wall

    def residual(eps):
        model.wall = dataclasses.replace(wall, eps=eps)
        try:
            return disc.residual(x, sysm.base)
        finally:
            model.wall = wall

    dF = (residual(wall.eps * (1 + h)) - residual(wall.eps * (1 - h))) / (2 * h)   # eps dF/d(eps)
    _, J = disc.linearise(x, sysm.base)[:2]
    dx = LU(J.tocsc()).solve(dF)   # -eps dx/d(eps): the move to eps = 0, to first order

    def ends(y):
        F, M = axial_force_and_torque(model, disc, y, sysm.base, [0.0])
        return np.array([F[0], M[0]])

    s = 1e-2
    dq = (ends(x + s * dx) - ends(x - s * dx)) / (2 * s)
    return dict(hook_load=float(dq[0]), surface_torque=float(dq[1]))


# --------------------------------------------------------------------------
# Side force per joint
# --------------------------------------------------------------------------
#: a joint of drill pipe, m (30 ft, range 2)
JOINT_LENGTH = 9.14


#: the most joints a string's table may have (a joint length of 1e-4 m at 600 m asked 6 million and ran out of
#: memory after the solve, advising a smaller mesh: test_a_joint_length_giving_too_many_joints_is_refused_first)
MAX_JOINTS = 100_000


#: the options of torque_and_drag a broomstick or a trip passes on (and keeps in its file): counts, positive
#: numbers, and the motion and bit loads (finite numbers, checked again by the solve)
COUNT_OPTIONS, NUMBER_OPTIONS = ("N", "k", "N_max"), ("max_error", "max_side_force_error", "tol", "force_scale")
MOTION_OPTIONS = ("wob", "bit_torque", "trip_speed", "rpm")


def check_solve_options(options: dict) -> None:
    """Each option one of :data:`COUNT_OPTIONS` (None or a positive integer), :data:`NUMBER_OPTIONS` (None or a
    positive finite number) or :data:`MOTION_OPTIONS` (None or a finite number), else a :class:`DrillingError`
    before any solve (a damaged broomstick file's options had made every cell a failure and the file complete:
    test_a_damaged_broomstick_file_is_refused_before_it_is_touched)."""
    known = COUNT_OPTIONS + NUMBER_OPTIONS + MOTION_OPTIONS
    for key, v in options.items():
        if key not in known:
            raise DrillingError(f"unknown option {key!r} of the solves (known: {', '.join(known)})")
        number = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        if v is None or (key in MOTION_OPTIONS and number and math.isfinite(v)):
            continue
        if key in COUNT_OPTIONS and not (isinstance(v, (int, np.integer)) and number and v >= 1):
            raise DrillingError(f"the option {key} must be a positive integer, got {v!r}")
        if key not in COUNT_OPTIONS and not (number and math.isfinite(v) and (key in MOTION_OPTIONS or v > 0)):
            raise DrillingError(f"the option {key} must be a {'finite' if key in MOTION_OPTIONS else 'positive'} "
                                f"number, got {v!r}")


def check_joints(depth: float, joint_length: float) -> None:
    """A :class:`DrillingError` (one line) unless ``joint_length`` is a positive number giving at most
    :data:`MAX_JOINTS` joints over ``depth``."""
    if not (math.isfinite(joint_length) and joint_length > 0):
        raise DrillingError(f"the joint length must be a positive number, got {joint_length!r}")
    if depth / joint_length > MAX_JOINTS:
        raise DrillingError(f"a joint length of {joint_length:g} m makes {depth / joint_length:.3g} joints over "
                            f"{depth:g} m: at most {MAX_JOINTS} (a longer --joint-length)")


def joint_edges(depth: float, joint_length: float = JOINT_LENGTH) -> np.ndarray:
    """The joints' ends in MD from the rig down, ``0, ..., L - 2 l_j, L - l_j, L``: joints counted from the bit up
    (the string is made up from the bit), the top one cut at the rig (shorter than ``l_j``)."""
    check_joints(depth, joint_length)
    L = float(depth)
    n = math.ceil(L / joint_length * (1 - 1e-12))
    # rounded to the nanometre: the ends print as the decimals a user gave (15.58, not 15.579999999999984)
    return np.concatenate([[0.0], np.round(L - joint_length * np.arange(n - 1, 0, -1), 9), [L]])


def collocated_integral(sysm, x, p, edges) -> np.ndarray:
    """The wall's force ``integral of p dS`` between successive ``edges`` (increasing, in ``[0, L]``) as the collocation
    equations see it (:meth:`rodcont.collocation.Collocation.integrate_between` of the pressure at the collocation
    points, where alone the equations load the rod); a fine sampling of the law on the spline instead misreads a
    point contact narrower than an interval (a straight rod's midspan contact at eps = 1e-6: 3.5e-3 below the
    exact reaction, this 1.2e-6; tests/test_drilling_joints.py)."""
    disc = sysm.disc
    return disc.integrate_between(sysm.model.contact(disc, x, p, S=disc.S)["pressure"], edges)


def joint_side_forces(td: TorqueDrag, joint_length: float = JOINT_LENGTH) -> dict:
    """The wall's force on each joint, ``integral of p dS`` over it (``p`` the wall force per unit MD, the contact
    law's pressure) as the collocation equations carry it (:func:`collocated_integral`: a point contact such as a
    collar's end on the wall gets the force the rod's balance has there). Arrays from the rig down: ``top``,
    ``bottom`` (MD, m), ``side_force`` (N), ``max_pressure`` (N/m, the largest ``p`` in the joint, located:
    :func:`_located_maxima` from the largest of 16 Gauss points of every piece between the mesh's breakpoints and
    the joints' ends and the profile's grid) and ``max_pressure_md`` (where it is); their sum is the Gauss rule of
    the collocation points over the string."""
    sysm, x = td.system, td.x
    edges = joint_edges(td.depth, joint_length)
    force = collocated_integral(sysm, x, td.params, edges)
    cuts = np.union1d(sysm.disc.breakpoints, edges)
    g = np.polynomial.legendre.leggauss(16)[0]
    mid, half = 0.5 * (cuts[1:] + cuts[:-1]), 0.5 * np.diff(cuts)
    gauss = (mid[:, None] + half[:, None] * g[None, :]).ravel()
    # the profile's grid too: solve prints its largest p, which must be a row's (it was 7e-5 above them all)
    S = np.unique(np.concatenate([gauss, td.profile["S"], edges]))
    S_max, P_max = _located_maxima(td, edges, S, _pressure_at(td, S))
    return dict(top=edges[:-1], bottom=edges[1:], side_force=force, max_pressure=P_max, max_pressure_md=S_max)


def _pressure_at(td: TorqueDrag, S) -> np.ndarray:
    """The contact law's ``p`` at MD ``S`` on the solution's spline (:meth:`rodcont.rod.EulerianRod.pressure_at`)."""
    return td.system.model.pressure_at(td.system.disc, td.x, S)


def _located_maxima(td: TorqueDrag, edges, S, P, iterations: int = 48) -> tuple:
    """``(S_max, p_max)`` per joint (between successive ``edges``) from samples ``(S, P)``, ``S`` increasing: the
    largest sample, then a golden-section search for the maximum of ``p`` between its two neighbours (within the
    joint), all joints at once; kept where it found more. A point contact's peak is narrower than a sampling's
    spacing: at 505 m the bit joint's 16 Gauss points per piece read 48.1 kN/m, the profile's grid 53.3 kN/m
    (test_a_joints_largest_force_per_length_is_located)."""
    joint = np.clip(np.searchsorted(edges, S, side="right") - 1, 0, edges.size - 2)   # the joint each sample is in
    order = np.lexsort((-P, joint))   # by joint, the largest p first
    best = order[np.concatenate([[0], np.flatnonzero(np.diff(joint[order])) + 1])]
    top, bottom = edges[joint[best]], edges[joint[best] + 1]
    a = np.maximum(S[np.maximum(best - 1, 0)], top)
    b = np.minimum(S[np.minimum(best + 1, S.size - 1)], bottom)
    r = 0.5 * (math.sqrt(5.0) - 1.0)
    c, d = b - r * (b - a), a + r * (b - a)
    fc, fd = _pressure_at(td, c), _pressure_at(td, d)
    for _ in range(iterations):   # 48 steps shrink a bracket by 1e-10
        left = fc > fd            # the maximum lies in [a, d], c becomes its upper point; else in [c, b]
        kept, f_kept = np.where(left, c, d), np.where(left, fc, fd)
        a, b = np.where(left, a, c), np.where(left, d, b)
        new = np.where(left, b - r * (b - a), a + r * (b - a))
        f_new = _pressure_at(td, new)
        c, fc = np.where(left, new, kept), np.where(left, f_new, f_kept)
        d, fd = np.where(left, kept, new), np.where(left, f_kept, f_new)
    S_found, P_found = np.where(fc > fd, c, d), np.maximum(fc, fd)
    more = P_found > P[best]
    return np.where(more, S_found, S[best]), np.where(more, P_found, P[best])


# --------------------------------------------------------------------------
# The soft-string estimate (Johancsik) on the same well path
# --------------------------------------------------------------------------
def soft_string(well: Well, string: DrillString, depth: float, operation: Operation | str = "static", *, mu=None,
                wob: float = 0.0, bit_torque: float = 0.0, step: float = 1.0) -> tuple:
    """``(hook_load, surface_torque)`` of the soft string (a cable on the wall of the well path): from the bit
    up, classical Runge-Kutta in steps of at most ``step`` between the survey stations, section boundaries
    and friction stations, with ``t = K3`` and ``kappa n = K3'`` of the minimum-curvature path (``g = -e3``)::

        dF/dS = -w (g . t) - s_a mu |N|,   dM/dS = -s_r mu |N| r,   N = F kappa n + w (g - (g . t) t).

    (The broomstick's estimate beside the stiff string; the tests check the stiff string against the
    independent implementation in ``tests/softstring_reference.py``. Where ``N`` passes through zero on an arc in a
    vertical plane, ``|N|`` has a kink these steps do not split: first order there, 5e-5 of the hook load and 1e-4
    of the torque at the default step on the benchmark well.)"""
    op = Operation.named(operation) if isinstance(operation, str) else operation
    placed = place_string(well, string, depth)
    curve, L = placed.curve, placed.curve.length
    mu = well.friction if mu is None else mu
    cuts = {0.0, L} | {float(b) for b in curve.breakpoints if 0 < b < L} | {a for a, _ in placed.radius if 0 < a < L}
    if not isinstance(mu, (int, float)):
        cuts |= {float(a) for a, _ in mu if 0 < a < L}
    edges = np.array(sorted(cuts))
    g = np.array([0.0, 0.0, -1.0])
    y = np.array([-float(wob), float(bit_torque)])

    def rhs(t, kn, y, w, r, m, s_a, s_r):
        gt = float(g @ t)
        N = float(np.linalg.norm(y[0] * kn + w * (g - gt * t)))
        return np.array([-w * gt - s_a * m * N, -s_r * m * N * r])
    for a, b in zip(edges[::-1][1:], edges[::-1][:-1]):
        mid = 0.5 * (a + b)
        w, r = float(_value_at(placed.weights, mid)), float(_value_at(placed.radius, mid))
        m = float(_value_at(mu if not isinstance(mu, (int, float)) else float(mu), mid))
        s_a, s_r = op.split(r)
        n = max(1, math.ceil((b - a) / step))
        h = (b - a) / n
        S = np.array([b - i * h for i in range(n)])  # upward: S decreases by h
        t, kn = _path_vectors(curve, np.concatenate([S, S - h / 2, S - h]))  # one jet for the interval's steps
        for i in range(n):
            k1 = rhs(t[:, i], kn[:, i], y, w, r, m, s_a, s_r)
            k2 = rhs(t[:, n + i], kn[:, n + i], y - h / 2 * k1, w, r, m, s_a, s_r)
            k3 = rhs(t[:, n + i], kn[:, n + i], y - h / 2 * k2, w, r, m, s_a, s_r)
            k4 = rhs(t[:, 2 * n + i], kn[:, 2 * n + i], y - h * k3, w, r, m, s_a, s_r)
            y = y - h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return float(y[0]), float(y[1])


def _path_vectors(curve, S) -> tuple:
    """``(t, kappa n)`` of ``curve`` at the arclengths ``S``, arrays ``(3, S.size)``."""
    j = curve.jet(np.asarray(S, float))
    return j.K[2], j.k[0, 0] * j.K[0] + j.k[1, 0] * j.K[1]


# --------------------------------------------------------------------------
# A trace of the string at a fixed depth (its branch file stores the hook load and the surface torque)
# --------------------------------------------------------------------------
@with_one_blas_thread
def trace_bit_force(td: TorqueDrag, T_range: tuple, out: str | None = None, *, overwrite: bool = False,
                    ds: float = 0.1, ds_max: float = 0.5, N_max: int = 4000, max_error: float = 1e-6):
    """Trace the solved string ``td`` in the axial force at the bit ``T`` (``-WOB``) over ``T_range`` (from the
    solution's ``T`` towards the other end) with :func:`rodcont.drivers.trace.run`; ``out``: its branch file
    (columns ``hook_load`` and ``surface_torque`` per point; the wall's steps kept; the drilling record of ``td``'s
    well and string, so ``rodcont export`` rebuilds each point in drilling terms). Returns the
    :class:`rodcont.branch.Branch`."""
    if td.well is None or td.string is None:
        raise DrillingError("trace_bit_force needs the equilibrium of torque_and_drag (it knows its well and string)")
    from .branch import Branch
    from .drivers.trace import TraceOptions, _close_output, _open_output, file_meta, run
    sysm, x = td.system, td.x
    T0 = float(sysm.value())
    lo, hi = (float(v) for v in T_range)
    opts = TraceOptions(p_range=(lo, hi), direction=1 if hi - T0 >= T0 - lo else -1, ds=ds, ds_max=ds_max,
                        N_max=N_max, max_error=max_error)
    attrs = file_meta(sysm.rod, T0, sysm.disc.N, sysm.disc.k, "T", opts, sysm,
                      dict(depth=td.depth, operation=td.operation.name, join_unknowns=_join_unknowns(sysm),
                           drilling=drilling_record(td.well, td.string, td)))
    branch = Branch(math.nan, sysm.rod, sysm.disc.N, sysm.disc.k, "T", attrs=attrs, curve=sysm.curve, wall=sysm.wall)
    writer, recorder = _open_output(out, overwrite, attrs, 1, branch, sysm)
    try:
        with np.errstate(all="ignore"):
            run(sysm, x, T0, opts, branch=branch, recorder=recorder)
    finally:
        if writer is not None:
            _close_output(writer, branch, recorder.contact)
    return branch


def _join_unknowns(sysm) -> int:
    """The unknowns of a solution beyond ``6 N k + 11``: the joins' (survey stations and section boundaries)."""
    return int(sysm.disc.size - sysm.disc.n_free - 6 * sysm.disc.N * sysm.disc.k - 11)


# --------------------------------------------------------------------------
# Buckling of the compressed string (the criteria a torque-and-drag check applies along the string)
# --------------------------------------------------------------------------
#: the helical onset over the sinusoidal one (Chen, Lin and Cheatham 1990: 2 sqrt(2) against Dawson-Paslay's 2)
HELICAL_FACTOR = math.sqrt(2.0)


def buckling_ratio(td: TorqueDrag) -> np.ndarray:
    """The compression over the sinusoidal buckling load along the string's profile, ``-F / F_s`` (0 in tension),
    with ``F_s = max(2 sqrt(EI w sin I / c), 1.94 (EI w^2)^(1/3))``: Dawson and Paslay's load of the local section
    (``EI``, buoyed ``w``), inclination ``I`` and clearance ``c``, and where that vanishes (a vertical stretch)
    Lubinski's load of a vertical pipe buckling under its own weight. Above 1: sinusoidally buckled; above
    :data:`HELICAL_FACTOR`: helically (Chen, Lin and Cheatham)."""
    P = td.placed
    S, F = td.profile["S"], td.profile["axial_force"]
    t = P.curve.jet(S).K[2]
    sin_i = np.hypot(t[0], t[1])
    EI = _value_at(tuple((a, s.EI) for a, _, s in P.spans), S)
    w = _value_at(P.weights, S)
    c = td.system.model.wall.clearance_at(S)
    Fs = np.maximum(2.0 * np.sqrt(EI * w * sin_i / c), 1.94 * np.cbrt(EI * w * w))
    return np.where(F < 0, -F / Fs, 0.0)


# --------------------------------------------------------------------------
# The drilling record of a file: what rebuilds each stored point's system
# --------------------------------------------------------------------------
#: the version of the record a drill string's file keeps in its ``drilling`` attribute (JSON)
RECORD_VERSION = 1


def _plain_table(v):
    """A number or MD stations as JSON (a list of pairs), and back (:func:`_table_back`)."""
    return float(v) if isinstance(v, (int, float)) else [[float(a), float(b)] for a, b in v]


def _table_back(v):
    return float(v) if isinstance(v, (int, float)) else tuple((float(a), float(b)) for a, b in v)


def drilling_record(well: Well, string: DrillString, td: TorqueDrag) -> str:
    """The JSON a drill string's file stores (attribute ``drilling``, :data:`RECORD_VERSION`): the well (survey
    stations, hole diameter, friction, ``eps``), the string (sections, buoyancy factor), the operation, the
    friction factor used, WOB, bit torque and ``k``. With a point's depth, mesh, coefficients and contact law's
    force scale it rebuilds that point's system (:func:`rebuild`)."""
    import json
    op = td.operation
    return json.dumps(dict(
        version=RECORD_VERSION, **well_and_string_record(well, string),
        operation=dict(name=op.name, trip_speed=float(op.trip_speed), rpm=float(op.rpm)),
        mu=_plain_table(td.mu), wob=float(td.wob), bit_torque=float(td.bit_torque), k=int(td.system.disc.k)))


def well_and_string_record(well: Well, string: DrillString) -> dict:
    """``{"well": ..., "string": ...}`` as plain JSON values: the well's survey stations, hole diameter, friction
    and ``eps`` (and the survey's path, for the record), the string's sections and buoyancy factor; read back by
    :func:`well_and_string_back`."""
    import dataclasses
    return dict(
        well=dict(stations=np.asarray(well.stations, float).tolist(), hole_diameter=_plain_table(well.hole_diameter),
                  friction=_plain_table(well.friction), eps=float(well.eps), survey=well.survey),
        string=dict(buoyancy_factor=float(string.buoyancy_factor),
                    sections=[dataclasses.asdict(s) for s in string.sections]))


def well_and_string_back(d: dict) -> tuple:
    """``(Well, DrillString)`` of :func:`well_and_string_record`'s ``d`` (KeyError, ValueError, TypeError where
    it is damaged)."""
    w, s = d["well"], d["string"]
    well = Well(np.asarray(w["stations"], float), _table_back(w["hole_diameter"]), _table_back(w["friction"]),
                float(w["eps"]), w.get("survey"))
    return well, DrillString(tuple(Section(**row) for row in s["sections"]), float(s["buoyancy_factor"]))


def read_record(text: str) -> dict:
    """The record of :func:`drilling_record` as objects: ``well``, ``string``, ``operation``, ``mu``, ``wob``,
    ``bit_torque``, ``k``; a :class:`DrillingError` (one line) for a newer or damaged one."""
    import json
    try:
        d = json.loads(text)
        if int(d.get("version", 0)) > RECORD_VERSION:
            raise DrillingError(f"its drilling record is version {d['version']}, newer than this rodcont's "
                                f"({RECORD_VERSION}): update rodcont")
        well, string = well_and_string_back(d)
        op = Operation(str(d["operation"]["name"]), float(d["operation"]["trip_speed"]),
                       float(d["operation"]["rpm"]))
        return dict(well=well, string=string, operation=op, mu=_table_back(d["mu"]), wob=float(d["wob"]),
                    bit_torque=float(d["bit_torque"]), k=int(d["k"]))
    except DrillingError:
        raise
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise DrillingError(f"damaged drilling record ({type(exc).__name__}: {exc})") from None


def rebuild(record: dict, depth: float, breakpoints, coefficients, force_scale: float,
            T: float | None = None) -> TorqueDrag:
    """The stored equilibrium with its bit at ``depth``: the string placed there (:func:`place_string`), its
    system built as the solve built it (:func:`build_system`, on the stored ``breakpoints`` with the contact
    law's ``force_scale``) and the stored ``coefficients`` expanded; a :class:`TorqueDrag` (``error`` NaN:
    not re-estimated). ``T``: the point's axial force at the bit (a trace in it, :func:`trace_bit_force`; WOB
    ``-T``), default the record's WOB."""
    from .ends import bit_force
    from .loads import Friction
    placed = place_string(record["well"], record["string"], float(depth))
    op, mu = record["operation"], record["mu"]
    T = bit_force(record["wob"]) if T is None else float(T)
    b = np.asarray(breakpoints, float)
    sysm = build_system(placed, Friction(mu, placed.radius, op), T, record["bit_torque"],
                        record["well"].eps, b.size - 1, record["k"], force_scale=float(force_scale), breakpoints=b)
    if sysm.disc.breakpoints.size != b.size or not np.allclose(sysm.disc.breakpoints, b, rtol=0, atol=1e-9 * b[-1]):
        raise DrillingError(f"the stored mesh at depth {depth:g} m does not fit the string placed there")
    x = sysm.expanded(np.asarray(coefficients, float))
    if x.size != sysm.disc.size:
        raise DrillingError(f"the stored solution at depth {depth:g} m does not fit the string placed there")
    return _result(sysm, x, placed, op, mu, -T if T else 0.0, record["bit_torque"], math.nan, record["well"],
                   record["string"])
