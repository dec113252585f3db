"""Export stored equilibria: fields along the rod (CSV, VTK XML PolyData, NumPy ``.npz``) and animations.

:func:`rod_fields` samples one stored point of a branch at ``samples`` points
uniform in the reference coordinate ``S`` (or, with ``grid="s"``, uniform in
the unstressed arclength ``s``). Everything is evaluated from the stored
B-spline coefficients with the model's own kinematics
(:class:`rodcont.rod.EulerianRod`):

=============  ======================================================================
``S``          reference coordinate in ``[0, L]``
``s``          unstressed arclength, ``int_0^S n / alpha dS`` (``n = |r'|``), by a
               Gauss rule of 8 points on every piece between samples and breakpoints
``x, y, z``    centreline ``r`` (global components)
``d1, d2, d3`` directors, ``(samples, 3)`` each (global components)
``u1, u2``     bending curvatures (director components of ``u_perp = d3 x d3_s``,
               per unit unstressed length)
``u3``         twist, ``m / GJ``
``kappa``      ``sqrt(u1^2 + u2^2)``
``F``          internal force, ``(samples, 3)`` global; ``N1, N2, N`` its director
               components (``N = F.d3`` the axial force)
``M``          internal moment ``EI (u1 d1 + u2 d2) + GJ u3 d3``, ``(samples, 3)``
               global; ``M1, M2, M3`` its director components (``M3`` the torque)
``alpha``      stretch factor ``1 + N / EA`` (``dr/ds = alpha d3``)
=============  ======================================================================

In a conduit (a branch file that holds contact data) also, as
:meth:`rodcont.rod.EulerianRod.contact` defines them:

===============  ====================================================================
``axial_force``  ``F.d3`` (tension positive; the drill string's axial force)
``torque``       ``m``, the torque about ``d3`` (``M3``)
``pressure``     the wall's force per unit ``S`` (the contact law)
``gap``          ``c - |Delta|``, the clearance left (negative: inside the wall)
``in_contact``   1 where the pressure reaches the contact level the zones are found
                 with (``contact_level P``), else 0
===============  ====================================================================

A drill string's file (a trip in bit depth, ``rodcont trace --param depth``, ``solve --string --out``, or a trace
in the force at the bit, :func:`rodcont.drilling.trace_bit_force`) holds the drilling record
(:func:`rodcont.drilling.drilling_record`): each point is rebuilt with the string placed at its own depth (a trace
in ``T``: the file's depth, the point's ``T``; :func:`drill_point`), ``S`` is the measured depth from the rig
(``S = depth`` at the bit), ``x, y, z`` are east, north, up in m (true vertical depth ``-z``), forces in N, and the
contact columns are
the drilling ones of :class:`rodcont.drilling.TorqueDrag`'s profile: ``axial_force`` (at ``S = 0`` the hook
load), ``torque`` ``M = -m`` (at ``S = 0`` the surface torque), ``pressure``, ``gap``, and ``in_contact`` 1 where
the gap is below 1 % of the clearance. ``grid="mesh"`` samples the solution's own contact grid, on which a
point contact (a pipe's end on the wall) is seen (the stored side force is the collocation rule's, which a
sampling of a contact narrower than a mesh interval approaches only as the grid refines).

With ``f = w g`` per unit unstressed length the exported fields satisfy the
Kirchhoff balance laws ``dF/ds + f = 0`` and ``dM/ds + (dr/ds) x F = 0``
(to the accuracy of the collocation solution; ``tests/test_export.py``
re-integrates them).

Units: those of the branch file (lengths in the unit of ``L``, forces in the
unit of ``EA``, so ``w`` is force per length, ``EI`` force x length^2).

Writers (:func:`write_csv`, :func:`write_vtp`, :func:`write_npz`,
:func:`write_pvd`, and :func:`animate`) publish atomically (:mod:`rodcont.safeio`: a
synced temporary file beside the target, renamed over it): the file appears whole or not
at all, and an existing one stays whole when the disk fills. They replace an existing file
(the command line refuses one unless ``--overwrite``); a series is replaced as a whole
(:func:`export_branch`). :func:`animate` draws the rod along a branch beside its response
diagram with matplotlib's object interface (no pyplot, backend untouched).
"""

from __future__ import annotations

import contextvars
import json
import os

import numpy as np

# Column layout shared by the writers: (name in ``fields``, column names, unit).
LAYOUT = (
    ("S", ("S",), "length"),
    ("s", ("s",), "length"),
    ("x", ("x",), "length"),
    ("y", ("y",), "length"),
    ("z", ("z",), "length"),
    ("d1", ("d1_x", "d1_y", "d1_z"), "1"),
    ("d2", ("d2_x", "d2_y", "d2_z"), "1"),
    ("d3", ("d3_x", "d3_y", "d3_z"), "1"),
    ("u1", ("u1",), "1/length"),
    ("u2", ("u2",), "1/length"),
    ("u3", ("u3",), "1/length"),
    ("kappa", ("kappa",), "1/length"),
    ("F", ("F_x", "F_y", "F_z"), "force"),
    ("N1", ("N1",), "force"),
    ("N2", ("N2",), "force"),
    ("N", ("N",), "force"),
    ("M", ("M_x", "M_y", "M_z"), "force*length"),
    ("M1", ("M1",), "force*length"),
    ("M2", ("M2",), "force*length"),
    ("M3", ("M3",), "force*length"),
    ("alpha", ("alpha",), "1"),
    ("axial_force", ("axial_force",), "force"),
    ("torque", ("torque",), "force*length"),
    ("pressure", ("pressure",), "force/length"),
    ("gap", ("gap",), "length"),
    ("in_contact", ("in_contact",), "1"),
)
CONTACT_FIELDS = ("axial_force", "torque", "pressure", "gap", "in_contact")
FIELD_NAMES = tuple(name for name, _, _ in LAYOUT)
MAX_SAMPLES = 1_000_000
_QUAD = 8  # Gauss points per piece for the unstressed arclength
_CHUNK = 8192  # points evaluated at once


class ExportError(ValueError):
    """An export that cannot be done as asked (one-line message)."""


# --------------------------------------------------------------------------
# The fields
# --------------------------------------------------------------------------
def point_parameters(data, i: int) -> np.ndarray:
    """The parameter vector ``(phi_L, T, w, EI, GJ, EA)`` of stored point ``i``.

    The root attributes hold the rod the branch started from; a branch
    continued in a rod parameter (or a fold curve) stores that parameter's
    value per point in a column of its own, which wins.
    """
    from .rod import PARAMS
    rod = data.rod
    p = np.array([float(data.branch["phi_L"][i]), data.tension, rod.w, rod.EI, rod.GJ, rod.EA])
    param = data.param
    if param != "phi_L" and param in data.branch:
        v = float(data.branch[param][i])
        if param == "gamma":
            p[1] = v * p[2] * rod.L
        elif param in PARAMS:
            p[PARAMS.index(param)] = v
    return p


def _model_at(data, p):
    from .rod import EulerianRod
    from .system import rod_at
    return EulerianRod(rod_at(data.rod, p), data.curve, data.wall)


def _jets(disc, x, S):
    from .rod import Jet
    return (disc.jet_matrix(S) @ x).reshape(Jet.SIZE, np.size(S))


def _chunks(n: int):
    """Slices of at most ``_CHUNK`` points: memory stays bounded for any number of samples."""
    return [slice(a, min(a + _CHUNK, n)) for a in range(0, n, _CHUNK)]


def _integrand(model, disc, x, p, S):
    """``ds/dS = n / alpha`` at ``S``."""
    S = np.asarray(S, float)
    out = np.empty(S.size)
    for c in _chunks(S.size):
        _, alpha, n, _ = model._axial_quantities(S[c], _jets(disc, x, S[c]), p)
        out[c] = n / alpha
    return out


def unstressed_arclength(model, disc, x, p, S) -> np.ndarray:
    """``s(S) = int_0^S n/alpha dS`` at the increasing points ``S`` (Gauss rule per piece).

    The integrand is smooth inside each mesh subinterval but only continuous
    across breakpoints, so the pieces are cut at both the samples and the
    breakpoints; 8 Gauss points per piece integrate it to rounding.
    """
    S = np.asarray(S, float)
    b = disc.breakpoints
    knots = np.union1d(np.clip(S, b[0], b[-1]), b)
    h = np.diff(knots)
    xi, wi = np.polynomial.legendre.leggauss(_QUAD)
    Q = (knots[:-1, None] + 0.5 * h[:, None] * (xi[None, :] + 1.0)).ravel()
    W = (0.5 * h[:, None] * wi[None, :]).ravel()
    pieces = (W * _integrand(model, disc, x, p, Q)).reshape(-1, _QUAD).sum(axis=1)
    cum = np.concatenate([[0.0], np.cumsum(pieces)])
    return cum[np.searchsorted(knots, np.clip(S, b[0], b[-1]))]


def _grid_in_s(model, disc, x, p, samples):
    """Points ``S`` at which ``s`` is uniform on ``[0, s(L)]`` (table, then Newton to rounding)."""
    L = float(disc.breakpoints[-1])
    Sf = np.union1d(np.linspace(0.0, L, 4 * samples + 1), disc.breakpoints)
    sf = unstressed_arclength(model, disc, x, p, Sf)
    target = np.linspace(0.0, sf[-1], samples)
    S = np.interp(target, sf, Sf)
    for _ in range(8):
        err = unstressed_arclength(model, disc, x, p, S) - target
        S = np.clip(S - err / _integrand(model, disc, x, p, S), 0.0, L)
        S = np.maximum.accumulate(S)
        if np.max(np.abs(err)) <= 1e-15 * sf[-1]:
            break
    S[0], S[-1] = 0.0, L
    return S


#: the sample grids: uniform in S, uniform in s, or the solution's own contact grid
GRIDS = ("S", "s", "mesh")
#: points per mesh subinterval of ``grid="mesh"`` (:meth:`rodcont.rod.EulerianRod.contact`'s default grid)
MESH_POINTS = 16


def _samples(model, disc, x, p, samples: int, grid: str) -> np.ndarray:
    """The points ``S``: ``samples`` uniform in ``S`` or in ``s``; ``grid="mesh"``: :data:`MESH_POINTS` equal
    pieces of every mesh subinterval and the end (``samples`` unused), the grid on which a solve computes its side
    force, gap and contact zones: a point contact (a pipe's end on the wall, a peak of a millimetre) falls on
    it, where a uniform grid of any practical size steps over it."""
    if grid == "mesh":
        b = disc.breakpoints
        t = np.linspace(0.0, 1.0, MESH_POINTS + 1)[:-1]
        return np.concatenate([(b[:-1, None] + np.diff(b)[:, None] * t[None, :]).ravel(), [b[-1]]])
    L = float(disc.breakpoints[-1])
    return np.linspace(0.0, L, samples) if grid == "S" else _grid_in_s(model, disc, x, p, samples)


def rod_fields(data, label, samples: int = 200, grid: str = "S") -> dict:
    """The fields along the rod at stored point ``label`` of ``data`` (a :class:`BranchData`).

    ``label``: point index (from 0, negative from the end), ``F<j>`` or
    ``BP<j>``. ``samples`` points uniform in ``S`` over ``[0, L]``
    (``grid="S"``) or uniform in ``s`` over ``[0, l0]`` (``grid="s"``), or the
    solution's contact grid (``grid="mesh"``, :func:`_samples`).
    Returns a dict of arrays (see the module docstring for names and meaning).
    """
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 2 <= samples <= MAX_SAMPLES:
        raise ExportError(f"samples must be an integer in 2..{MAX_SAMPLES}, got {samples!r}")
    if grid not in GRIDS:
        raise ExportError(f"grid must be 'S', 's' or 'mesh', got {grid!r}")
    i = data.resolve(label)
    if is_drill_string(data):
        return _drill_fields(data, i, int(samples), grid)
    pt = data.point(i)
    p = point_parameters(data, i)
    model = _model_at(data, p)
    disc = model.discretise(breakpoints=pt["breakpoints"], k=int(data.attrs["k"]))
    x = pt["x"]
    S = _samples(model, disc, x, p, int(samples), grid)
    parts = [_pointwise(model, disc, x, p, S[c]) for c in _chunks(S.size)]
    if model.wall is not None:
        parts = [dict(q, **_contact_fields(model, disc, x, p, q["S"])) for q in parts]
    out = {key: np.concatenate([q[key] for q in parts]) for key in parts[0]}
    out["s"] = unstressed_arclength(model, disc, x, p, S)
    return {key: out[key] for key in FIELD_NAMES if key in out}


def _contact_fields(model, disc, x, p, S) -> dict:
    """:data:`CONTACT_FIELDS` at the points ``S`` (:meth:`rodcont.rod.EulerianRod.contact`)."""
    c = model.contact(disc, x, p, S=S)
    level = model.wall.contact_level * model.contact_scale
    return dict(axial_force=c["axial_force"], torque=c["torque"], pressure=c["pressure"], gap=c["gap"],
                in_contact=(c["pressure"] >= level).astype(float))


def _pointwise(model, disc, x, p, S) -> dict:
    """Every field but ``s`` at the points ``S`` (the model's centreline, directors, force, torque)."""
    from .rod import Jet
    _, EI, GJ, EA = model._stiffness(S, p)  # a drill string's sections: each its own stiffness
    r = model.centreline(disc, x, S)
    D = model.directors(disc, x, S)
    d1, d2, d3 = D[0], D[1], D[2]
    F = model.force(disc, x, S)
    z = _jets(disc, x, S)
    m = model._axial_quantities(S, z, p)[0]  # the torque GJ u3, as the model defines it
    # r', r'' in global components from the reference curve (whatever its frame)
    _, r1, r2, _ = model.curve.centreline_jets(S, z[list(Jet.D1)], z[list(Jet.D2)])
    n = np.sqrt((r1 * r1).sum(axis=0))
    alpha = 1.0 + (F * d3).sum(axis=0) / EA
    uperp = alpha * np.cross(r1, r2, axis=0) / n**3  # d3 x d3_s
    u1, u2 = (uperp * d1).sum(axis=0), (uperp * d2).sum(axis=0)
    M = EI * (u1 * d1 + u2 * d2) + m * d3
    return dict(
        S=S, x=r[0].copy(), y=r[1].copy(), z=r[2].copy(),
        d1=d1.T.copy(), d2=d2.T.copy(), d3=d3.T.copy(),
        u1=u1, u2=u2, u3=m / GJ, kappa=np.hypot(u1, u2),
        F=F.T.copy(), N1=(F * d1).sum(axis=0), N2=(F * d2).sum(axis=0), N=(F * d3).sum(axis=0),
        M=M.T.copy(), M1=EI * u1, M2=EI * u2, M3=m,
        alpha=alpha,
    )


# --------------------------------------------------------------------------
# A drill string's file (a trip in bit depth, or solve --string --out)
# --------------------------------------------------------------------------
def is_drill_string(data) -> bool:
    """A file of a drill string in its well (a trip, ``solve --string --out``, a trace in the bit's force)."""
    a = data.attrs
    return data.param == "depth" or "drilling" in a or "join_unknowns" in a or "trip" in a


def drill_point(data, i: int):
    """Stored point ``i`` of a drill string's file rebuilt (:func:`rodcont.drilling.rebuild`): the string placed at
    the point's depth (a trace in the bit's force, :func:`rodcont.drilling.trace_bit_force`: at the file's depth,
    with the point's ``T``), its system on the stored mesh and contact law; a one-line :class:`ExportError` for a
    file written before the drilling record (rodcont before its version 1)."""
    from .drilling import DrillingError, read_record, rebuild
    trip = data.param == "depth"
    if "drilling" not in data.attrs or not (trip and "force_scale" in data.branch
                                            or data.param == "T" and "depth" in data.attrs):
        what = "trip file" if trip else "drill string's file (a trace in the bit's force)"
        raise ExportError(f"{data.label}: this {what} predates the drilling record export rebuilds a point from "
                          f"(the well, the string and the operation): re-run the "
                          f"{'trip' if trip else 'trace (rodcont.drilling.trace_bit_force)'}")
    try:
        record = read_record(str(data.attrs["drilling"]))
        if trip:
            return rebuild(record, float(data.branch["depth"][i]), data.meshes[i], data.coefficients[i],
                           float(data.branch["force_scale"][i]))
        # a trace in T keeps one law (its force scale in the wall's spec) at the depth it was solved at
        return rebuild(record, float(data.attrs["depth"]), data.meshes[i], data.coefficients[i],
                       float(data.wall.force_scale), T=float(data.branch["T"][i]))
    except DrillingError as exc:
        raise ExportError(f"{data.label}: point {i}: {exc}") from None


def _drill_fields(data, i: int, samples: int, grid: str) -> dict:
    """:func:`rod_fields` of a drill string's point: ``S`` the measured depth (0 at the rig, the depth at the bit),
    ``x, y, z`` east, north, up (m; true vertical depth ``-z``), forces in N. Its contact columns as
    :class:`rodcont.drilling.TorqueDrag`'s profile has them: ``axial_force`` ``F.d3`` and ``torque`` ``M = -m``
    (:func:`rodcont.ends.axial_force_and_torque`: at ``S = 0`` the hook load and the surface torque),
    ``pressure`` the wall force per unit MD, ``gap``, ``in_contact`` 1 where the gap is below 1 % of the
    clearance."""
    from .ends import axial_force_and_torque
    td = drill_point(data, i)
    sysm, x = td.system, td.x
    model, disc, p = sysm.model, sysm.disc, td.params
    S = _samples(model, disc, x, p, samples, grid)
    parts = []
    for c in _chunks(S.size):
        q = _pointwise(model, disc, x, p, S[c])
        con = model.contact(disc, x, p, S=S[c])
        F, M = axial_force_and_torque(model, disc, x, p, S[c])
        q.update(axial_force=F, torque=M, pressure=con["pressure"], gap=con["gap"],
                 in_contact=(con["gap"] <= 0.01 * model.wall.clearance_at(S[c])).astype(float))
        parts.append(q)
    out = {key: np.concatenate([q[key] for q in parts]) for key in parts[0]}
    out["s"] = unstressed_arclength(model, disc, x, p, S)
    return {key: out[key] for key in FIELD_NAMES if key in out}


def _drill_meta(data, i: int, label, samples: int, grid: str) -> dict:
    from . import __version__
    b = data.branch
    meta = dict(rodcont_version=__version__, source=os.path.abspath(data.path), point=int(i), label=str(label),
                kind=str(b["kind"][i]), param=str(data.param),
                depth=float(b["depth"][i] if data.param == "depth" else data.attrs["depth"]),
                operation=str(data.attrs.get("operation", "")),
                S="measured depth from the rig (m)", axes="x east, y north, z up (m; true vertical depth = -z)",
                units="SI: m, N, N m", samples=int(samples), grid=grid)
    for name in ("T", "hook_load", "surface_torque", "side_force", "min_gap", "force_scale", "error"):
        if name in b:
            meta[name] = float(b[name][i])
    return meta


def point_meta(data, label, samples: int, grid: str = "S") -> dict:
    """What a reader of an exported file needs to know about its point (scalars and short strings)."""
    from . import __version__
    i = data.resolve(label)
    if is_drill_string(data):
        return _drill_meta(data, i, label, samples, grid)
    p = point_parameters(data, i)
    rod = data.rod
    meta = dict(rodcont_version=__version__, source=os.path.abspath(data.path))
    if data.name:
        meta["branch"] = data.name
    meta.update(point=int(i), label=str(label), kind=str(data.branch["kind"][i]),
                phi_L=float(p[0]), T=float(p[1]), w=float(p[2]), EI=float(p[3]), GJ=float(p[4]), EA=float(p[5]),
                L=float(rod.L), gamma=float(p[1] / (p[2] * rod.L)) if p[2] > 0 else float("nan"),
                weight_direction=" ".join(repr(float(c)) for c in rod.weight_direction),
                samples=int(samples), grid=grid, param=data.param)
    for name in ("stretch", "torque", "l0", "helical_waves", "min_alignment", "error"):
        if name in data.branch:
            v = data.branch[name][i]
            meta[name] = int(v) if name == "helical_waves" else float(v)
    return meta


def stack_fields(series: list[dict]) -> dict:
    """Fields of several points with a leading point axis (for ``.npz`` of a whole branch)."""
    return {name: np.stack([f[name] for f in series]) for name in series[0]}


# --------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------
_STAGE = contextvars.ContextVar("rodcont_export_stage", default=None)


def _publish(path: str, payload) -> None:
    """Write ``payload`` (bytes, or an iterable of str pieces) atomically (:func:`rodcont.safeio.publish`:
    a synced temporary file beside ``path`` renamed over it): the file appears whole or not at all, and an
    old one stays whole if the disk fills. Inside :func:`export_branch`'s series the file is only staged."""
    from .safeio import OutputFileError, publish
    stage = _STAGE.get()
    try:
        if stage is not None:
            stage.add(path, payload)
        else:
            publish(path, payload)
    except OutputFileError as exc:
        raise ExportError(str(exc)) from None


def _columns(fields: dict):
    """``(column names, units, 2-D array)`` in :data:`LAYOUT` order (unknown extra fields appended)."""
    names, units, cols = [], [], []
    known = set()
    for key, cnames, unit in LAYOUT:
        if key not in fields:
            continue
        known.add(key)
        a = np.asarray(fields[key], float)
        a = a.reshape(a.shape[0], -1)
        names += list(cnames)
        units += [unit] * len(cnames)
        cols.append(a)
    for key in fields:
        if key not in known:
            a = np.asarray(fields[key], float)
            a = a.reshape(a.shape[0], -1)
            names += [key] if a.shape[1] == 1 else [f"{key}_{c}" for c in "xyz"[:a.shape[1]]]
            units += ["?"] * a.shape[1]
            cols.append(a)
    return names, units, np.hstack(cols)


def _meta_value(v) -> str:
    return " ".join(str(v).split())


def write_csv(fields: dict, path: str, meta: dict | None = None) -> None:
    """CSV: ``#`` comment lines (the point, the rod, the units), one header row, one row per sample.

    Read it with ``pandas.read_csv(path, comment="#")``, or with
    ``csv``/``numpy`` after skipping the lines that start with ``#``.
    Values are written with 17 significant digits (exact round trip).
    """
    names, units, table = _columns(fields)
    lines = ["# rodcont export: fields along the rod, sampled uniformly in "
             f"{(meta or {}).get('grid', 'S')}"]
    for key, val in (meta or {}).items():
        lines.append(f"# {key}: {_meta_value(val)}")
    if "units" not in (meta or {}):  # a drill string's meta states its SI units itself
        lines.append("# units: lengths in the unit of L, forces in the unit of EA; per column:")
    lines.append("# unit: " + ",".join(units))
    lines.append(",".join(names))

    def pieces():
        yield "\n".join(lines) + "\n"
        for a in range(0, table.shape[0], 4096):
            yield "".join(",".join(map(repr, row)) + "\n" for row in table[a:a + 4096].tolist())
    _publish(path, pieces())


def _vtk_array(name: str | None, a: np.ndarray, indent: str, vtype: str = "Float64") -> str:
    a = np.asarray(a)
    ncomp = 1 if a.ndim == 1 else a.shape[1]
    attrs = f'type="{vtype}"' + (f' Name="{name}"' if name else "")
    if ncomp > 1:
        attrs += f' NumberOfComponents="{ncomp}"'
    fmt = repr if vtype.startswith("Float") else (lambda v: str(int(v)))
    text = " ".join(fmt(float(v)) if vtype.startswith("Float") else fmt(v) for v in a.ravel().tolist())
    return f'{indent}<DataArray {attrs} format="ascii">{text}</DataArray>\n'


def _xml_attr(v) -> str:
    from xml.sax.saxutils import quoteattr
    return quoteattr(str(v))


def write_vtp(fields: dict, path: str, meta: dict | None = None) -> None:
    """VTK XML PolyData (``.vtp``): the centreline as one polyline, every field as point data.

    ASCII, 17 significant digits. Vector fields (``d1, d2, d3, F, M``) have
    three components (global x, y, z); the numbers of ``meta`` go into the
    field data (``TimeValue`` is the point index, for series), its strings
    into an XML comment.
    """
    pts = np.column_stack([fields["x"], fields["y"], fields["z"]])
    npts = pts.shape[0]
    meta = dict(meta or {})
    out = ['<?xml version="1.0"?>\n']
    notes = " ".join(f"{k}={_meta_value(v)}" for k, v in meta.items() if isinstance(v, str))
    if notes:
        out.append(f"<!-- rodcont export: {notes.replace('--', '- -')} -->\n")
    out.append('<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n')
    out.append("  <PolyData>\n")
    numeric = {k: v for k, v in meta.items() if isinstance(v, (int, float, np.integer, np.floating))
               and not isinstance(v, bool)}
    if "point" in numeric:
        numeric = {"TimeValue": numeric["point"], **numeric}
    if numeric:
        out.append("    <FieldData>\n")
        for k, v in numeric.items():
            out.append(_vtk_array(k, np.array([float(v)]), "      ").replace(
                "<DataArray ", '<DataArray NumberOfTuples="1" ', 1))
        out.append("    </FieldData>\n")
    out.append(f'    <Piece NumberOfPoints="{npts}" NumberOfVerts="0" NumberOfLines="1" '
               f'NumberOfStrips="0" NumberOfPolys="0">\n')
    out.append('      <PointData Scalars="alpha" Vectors="F">\n')
    for key in FIELD_NAMES:
        if key in ("x", "y", "z") or key not in fields:
            continue
        out.append(_vtk_array(key, fields[key], "        "))
    for key in fields:
        if key not in FIELD_NAMES:
            out.append(_vtk_array(key, fields[key], "        "))
    out.append("      </PointData>\n")
    out.append("      <Points>\n")
    out.append(_vtk_array("Points", pts, "        "))
    out.append("      </Points>\n")
    out.append("      <Lines>\n")
    out.append(_vtk_array("connectivity", np.arange(npts), "        ", "Int64"))
    out.append(_vtk_array("offsets", np.array([npts]), "        ", "Int64"))
    out.append("      </Lines>\n")
    out.append("    </Piece>\n  </PolyData>\n</VTKFile>\n")
    _publish(path, out)


def write_pvd(entries: list[tuple[float, str]], path: str) -> None:
    """A ParaView collection (``.pvd``): ``(timestep, file)`` pairs, files relative to the ``.pvd``."""
    out = ['<?xml version="1.0"?>\n',
           '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n', "  <Collection>\n"]
    for t, f in entries:
        out.append(f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={_xml_attr(f)}/>\n')
    out.append("  </Collection>\n</VTKFile>\n")
    _publish(path, "".join(out).encode())


def write_npz(fields: dict, path: str, meta: dict | None = None) -> None:
    """NumPy ``.npz``: one array per field (names as in :func:`rod_fields`), ``meta`` as a JSON string.

    ``np.load(path)["meta"]`` holds the JSON (no pickle needed).
    """
    import io
    arrays = {k: np.asarray(v) for k, v in fields.items()}
    arrays["meta"] = np.array(json.dumps(meta or {}, default=_json_default))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    _publish(path, buf.getvalue())


def _json_default(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return str(v)


WRITERS = {"csv": write_csv, "vtk": write_vtp, "npz": write_npz}


def export_point(data, label, path: str, fmt: str, samples: int = 200, grid: str = "S") -> dict:
    """Write one point's fields to ``path`` as ``fmt`` (csv, vtk, npz); returns the fields."""
    if fmt not in WRITERS:
        raise ExportError(f"unknown format {fmt!r} (csv, vtk or npz)")
    fields = rod_fields(data, label, samples, grid)
    WRITERS[fmt](fields, path, point_meta(data, label, int(np.size(fields["S"])), grid))
    return fields


def series_dir(pvd_path: str) -> str:
    """The directory that holds the ``.vtp`` files of a ``.pvd`` series: ``<name>_vtp`` beside it."""
    stem, _ = os.path.splitext(pvd_path)
    return stem + "_vtp"


def series_files(pvd_path: str, n: int) -> list[str]:
    """The ``.vtp`` files of a series of ``n`` points written with ``pvd_path`` (in :func:`series_dir`)."""
    d = series_dir(pvd_path)
    stem = os.path.basename(os.path.splitext(pvd_path)[0])
    return [os.path.join(d, f"{stem}_{i:06d}.vtp") for i in range(n)]


def _stale_series(pvd_path: str, n: int) -> list[str]:
    """Files of an earlier, longer series of the same name (``<stem>_<index>.vtp`` from index ``n`` on)."""
    import re
    d = series_dir(pvd_path)
    stem = os.path.basename(os.path.splitext(pvd_path)[0])
    pattern = re.compile(re.escape(stem) + r"_(\d{6})\.vtp$")
    try:
        names = os.listdir(d)
    except OSError:
        return []
    return [os.path.join(d, m) for m in names if (g := pattern.match(m)) and int(g.group(1)) >= n]


def export_branch(data, path: str, fmt: str, samples: int = 200, grid: str = "S", progress=None,
                  overwrite: bool = True) -> int:
    """Every point of a branch: ``vtk`` writes a ``.pvd`` collection (timestep = point index) and one
    ``.vtp`` per point in :func:`series_dir`; ``npz`` writes the fields stacked along a leading
    point axis (``phi_L``, ``stretch``, ``torque``, ``index`` per point as extra arrays).
    Returns the number of points. CSV is one table per point: refused here.

    A series is replaced as a whole: every file is written to a temporary file first and all are renamed
    once all are written (a full disk leaves the old series as it was), the ``.pvd`` last; the files of an
    earlier, longer series of the same name are then removed. ``overwrite=False``: an existing ``.pvd`` or
    series file is refused (:class:`ExportError`) before anything is computed."""
    n = len(data)
    if n == 0:
        raise ExportError(f"{data.label} holds no point")
    if fmt == "npz" and grid == "mesh":
        raise ExportError("--all --grid mesh: each point has its own mesh, so its arrays cannot be stacked in one "
                          ".npz: write a .pvd series (--format vtk) or sample uniformly (--grid S)")
    if fmt == "npz" and not overwrite and os.path.lexists(path):
        raise ExportError(f"{path} exists: choose another -o or add --overwrite to replace it")
    if fmt == "vtk":
        from .safeio import Staged
        d = series_dir(path)
        if os.path.lexists(d) and not os.path.isdir(d):
            raise ExportError(f"cannot write the series: {d} exists and is not a directory")
        targets = series_files(path, n)
        if not overwrite:
            there = [p for p in [path] + targets if os.path.lexists(p)]
            if there:
                raise ExportError(f"{there[0]} exists{f' (and {len(there) - 1} more of the series)' if len(there) > 1 else ''}: "
                                  f"choose another -o or add --overwrite to replace the series")
        os.makedirs(d, exist_ok=True)
        entries = []
        with Staged() as stage:
            token = _STAGE.set(stage)
            try:
                for i, target in enumerate(targets):
                    export_point(data, i, target, "vtk", samples, grid)
                    entries.append((i, f"{os.path.basename(d)}/{os.path.basename(target)}"))
                    if progress is not None:
                        progress(i + 1, n)
                write_pvd(entries, path)
            finally:
                _STAGE.reset(token)
            try:
                stage.commit()
            except OSError as exc:
                raise ExportError(str(exc)) from None
        for stale in _stale_series(path, n):
            try:
                os.unlink(stale)
            except OSError:
                pass
        return n
    if fmt == "npz":
        series = []
        for i in range(n):
            series.append(rod_fields(data, i, samples, grid))
            if progress is not None:
                progress(i + 1, n)
        fields = stack_fields(series)
        meta = point_meta(data, 0, samples, grid)
        for key in ("point", "label", "kind", "phi_L", "stretch", "torque", "l0", "helical_waves",
                    "min_alignment", "error"):
            meta.pop(key, None)
        meta["points"] = n
        fields["index"] = np.arange(n)
        for key in ("phi_L", "stretch", "torque", "l0"):
            fields[key] = np.asarray(data.branch[key], float)
        if data.param != "phi_L" and data.param in data.branch:
            fields[data.param] = np.asarray(data.branch[data.param], float)
        fields["kind"] = np.asarray(data.branch["kind"]).astype(str)
        write_npz(fields, path, meta)
        return n
    raise ExportError(f"--all writes a series as vtk (.pvd collection) or npz, not {fmt}: "
                      f"a CSV holds one point (export each with --point)")


# --------------------------------------------------------------------------
# Animation
# --------------------------------------------------------------------------
def ffmpeg_available() -> bool:
    from matplotlib.animation import FFMpegWriter
    return bool(FFMpegWriter.isAvailable())


def frame_indices(n: int, max_frames: int) -> np.ndarray:
    """At most ``max_frames`` point indices spread evenly over ``0..n-1`` (both ends included)."""
    if n <= max_frames:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_frames)).astype(int))


def animate(data, path: str, fps: int = 10, samples: int = 120, max_frames: int = 300, others=(),
            title: str | None = None, dpi: int = 90, progress=None) -> int:
    """The rod's shape along a branch (left, 3-D, with ticks of ``d1`` showing the twist) beside the
    response diagram (right: Phi against stretch, the current point marked); GIF or MP4 by suffix.

    ``others``: further :class:`BranchData` drawn in grey on the diagram (the rest of a diagram file).
    MP4 needs ffmpeg. Returns the number of frames. No pyplot: the caller's backend is untouched.
    """
    from matplotlib.animation import FFMpegWriter, PillowWriter
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ext = os.path.splitext(path)[1].lower()
    if ext not in (".gif", ".mp4"):
        raise ExportError(f"{path}: animations are written as .gif or .mp4")
    if ext == ".mp4" and not ffmpeg_available():
        raise ExportError("writing MP4 needs ffmpeg (not found on PATH): install it, or write a .gif")
    n = len(data)
    if n == 0:
        raise ExportError(f"{data.label} holds no point")
    idx = frame_indices(n, max_frames)
    shapes = []
    for i in idx:
        f = rod_fields(data, int(i), samples)
        shapes.append((np.stack([f["x"], f["y"], f["z"]]), f["d1"].T))
    allpts = np.concatenate([r for r, _ in shapes], axis=1)
    centre = 0.5 * (allpts.max(axis=1) + allpts.min(axis=1))
    half = 0.5 * float(np.max(allpts.max(axis=1) - allpts.min(axis=1))) * 1.05
    tick = 0.04 * float(data.rod.L)
    ticks_at = np.unique(np.linspace(0, samples - 1, min(samples, 25)).astype(int))

    fig = Figure(figsize=(11.0, 4.8))
    FigureCanvasAgg(fig)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    for setter, c in zip((ax3.set_xlim, ax3.set_ylim, ax3.set_zlim), centre):
        setter(c - half, c + half)
    ax3.set_xlabel("e1")
    ax3.set_ylabel("e2")
    ax3.set_zlabel("e3")
    ax3.plot([0, data.rod.L], [0, 0], [0, 0], "k--", lw=0.8)
    (rod_line,) = ax3.plot([], [], [], lw=2.2, color="tab:blue")
    (tick_line,) = ax3.plot([], [], [], lw=1.0, color="tab:red")

    st_all = [np.asarray(b.branch["stretch"], float) for b in (data, *others)]
    smin = min(float(np.min(s)) for s in st_all)
    for b in others:
        ax2.plot(b.branch["stretch"], b.branch["phi_L"], "-", color="0.75", lw=1.0)
    stretch, phi = np.asarray(data.branch["stretch"], float), np.asarray(data.branch["phi_L"], float)
    ax2.plot(stretch, phi, "-", color="tab:blue", lw=1.4)
    fo = data.folds.get("index", [])
    if len(fo):
        ax2.plot(stretch[fo], phi[fo], "o", ms=5, mfc="white", mec="tab:blue", mew=1.5)
    (marker,) = ax2.plot([], [], "o", color="tab:red", ms=8)
    if smin > 0:
        ax2.set_xscale("log")
    else:
        ax2.set_xscale("symlog", linthresh=1e-5, linscale=0.3)
    ax2.set_xlabel("stretch  (ℓ − L) / L")
    ax2.set_ylabel("end rotation  Φ  [rad]")
    ax2.grid(True, alpha=0.3)
    head = title or f"{os.path.basename(data.label)}  (Γ = {data.gamma:g})"
    ax2.set_title(head, fontsize=10)
    ax3.set_title("point 0: Φ = 0, stretch = 0", fontsize=10)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))

    from .safeio import OutputFileError, commit, discard, reason, side_file, synced
    writer = (PillowWriter if ext == ".gif" else FFMpegWriter)(fps=fps)
    tmp = side_file(path, "tmp", ext)  # the writers choose the format by the suffix
    try:
        with writer.saving(fig, tmp, dpi):
            for j, i in enumerate(idx):
                r, d1 = shapes[j]
                rod_line.set_data_3d(r[0], r[1], r[2])
                a = r[:, ticks_at]
                e = a + tick * d1[:, ticks_at]
                seg = np.full((3, 3 * ticks_at.size), np.nan)
                seg[:, 0::3], seg[:, 1::3] = a, e
                tick_line.set_data_3d(seg[0], seg[1], seg[2])
                marker.set_data([stretch[i]], [phi[i]])
                ax3.set_title(f"point {i}: Φ = {phi[i]:.4f}, stretch = {stretch[i]:.4g}", fontsize=10)
                writer.grab_frame()
                if progress is not None:
                    progress(j + 1, idx.size)
        synced(tmp)
        commit(tmp, path)  # atomic: an existing animation stays whole if anything above failed
    except OutputFileError as exc:
        raise ExportError(str(exc)) from None
    except OSError as exc:  # from the animation writer itself (PIL, ffmpeg) on the temporary file
        raise ExportError(f"cannot write {path}: {reason(exc)}") from None
    finally:
        discard(tmp)
    return int(idx.size)
