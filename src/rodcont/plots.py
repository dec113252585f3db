"""Figures from branch and diagram files: the response diagram (paper Figure 2) and 3D shapes.

Figures are drawn with matplotlib's object interface on an Agg canvas: no
pyplot, so the caller's backend and global state are left alone.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def save_figure(fig: Figure, path: str, dpi: int = 130) -> None:
    """Write ``fig`` to ``path`` atomically (:func:`rodcont.safeio.publish`: rendered in memory, written to a
    temporary file beside it, synced, renamed over it): a full disk or a kill leaves an existing image whole.
    The format is the suffix's when matplotlib writes it, else PNG."""
    from .safeio import publish
    publish(path, rendered(fig, path, dpi))


def rendered(fig: Figure, path: str, dpi: int = 130) -> bytes:
    """``fig`` rendered in memory in the format of ``path``'s suffix where matplotlib writes it, else PNG."""
    import io
    import os
    fmt = os.path.splitext(path)[1][1:].lower()
    if fmt not in fig.canvas.get_supported_filetypes():
        fmt = "png"
    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format=fmt)
    return buf.getvalue()


def _figure(w, h):
    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    return fig


def _cmap(name):
    import matplotlib
    return matplotlib.colormaps[name]


PLOT_VARIABLES = ("phi_L", "stretch", "torque", "l0", "helical_waves", "min_alignment")
LABELS = {"phi_L": "end rotation  Φ = φ(L)  [rad]", "stretch": "stretch  (ℓ − L) / L", "torque": "torque  M·d3",
          "l0": "unstressed length ℓ0", "helical_waves": "helical waves", "min_alignment": "min d3·K3",
          "gamma": "Γ = T / (w L)", "T": "tension T", "w": "weight w", "EI": "EI", "GJ": "GJ", "EA": "EA",
          "side_force": "side force  ∫ p dS", "min_gap": "min gap  min (c − |Δ|)", "contact_zones": "contact zones"}
#: a drill string's columns (a trip, a trace in the bit's force): SI units
DRILL_LABELS = {"depth": "bit measured depth  [m]", "hook_load": "hook load  [N]",
                "surface_torque": "surface torque  [N m]", "T": "axial force at the bit  T = −WOB  [N]",
                "side_force": "side force  ∫ p dS  [N]", "min_gap": "min gap  min (c − |Δ|)  [m]",
                "max_joint_side_force": "largest side force on a joint  [N]",
                "buckling_ratio": "largest buckling ratio  −F / F_s", "contact_zones": "contact zones"}
#: the columns a drill string's plot may use beside the rod's
DRILL_COLUMNS = ("depth", "hook_load", "surface_torque", "max_joint_side_force", "buckling_ratio")


def is_drill_string(attrs) -> bool:
    """The root attributes of a drill string's file (a trip in depth, solve --string --out, a trace in the bit's
    force): its plots default to the hook load against depth (or T), in SI units."""
    return attrs.get("param") == "depth" or "drilling" in attrs or "join_unknowns" in attrs


def default_axes(attrs) -> tuple:
    """``(x, y)`` a file is drawn with when ``--x``/``--y`` are not given: its continued parameter (the stretch for
    a trace in Φ) and ``phi_L``; a user's problem (rodcont.bvp) names its own ``y``, a drill string's is its hook
    load."""
    param = attrs.get("param", "phi_L")
    return (param if param != "phi_L" else "stretch",
            "hook_load" if is_drill_string(attrs) else attrs.get("plot_y", "phi_L"))


def _label(name, drill: bool) -> str:
    return DRILL_LABELS.get(name, LABELS.get(name, name)) if drill else LABELS.get(name, name)


def _legend(d) -> str:
    """A drill string's file in a legend: its operation and friction factor (the drilling record's)."""
    import json
    mu = ""
    try:
        m = json.loads(str(d.attrs["drilling"]))["mu"]
        mu = f", μ = {m:g}" if isinstance(m, (int, float)) else ", μ by MD"
    except (KeyError, ValueError, TypeError):
        pass
    return f"{d.attrs.get('operation', 'drill string')}{mu}"


def _segments(x, y, unstable):
    """Split a curve where its stability changes: ``[(x, y, stable)]`` (no gaps)."""
    if unstable is None:
        return [(x, y, True)]
    stable = np.asarray(unstable) <= 0  # -1: not counted, drawn solid
    out, start = [], 0
    for i in range(1, len(x) + 1):
        if i == len(x) or stable[i] != stable[start]:
            j = min(i + 1, len(x))
            out.append((x[start:j], y[start:j], bool(stable[start])))
            start = i
    return out


def response_diagram(files, path: str, title: str | None = None, x: str | None = None, y: str | None = None,
                     labels=None, xscale: str | None = None) -> Figure:
    """Branches of every file, ``y`` (default ``phi_L``) against ``x`` (default ``stretch``).

    ``files``: :class:`rodcont.branchfile.DiagramData` (a trace file is a
    diagram of one branch). One colour per file (every branch of a diagram in
    the file's colour); stable parts solid and unstable parts dashed where the
    file stores ``unstable_modes``; folds marked (○) and, in diagrams,
    labelled with the helical waves on their two sides (``1→2``); × marks
    where a branch ends. A fold-curve file defaults to ``phi_L`` at the fold
    against its parameter. ``xscale``: ``log``, ``linear`` or None (log when
    ``x`` is the stretch and positive). The legend sits outside the axes.
    Returns the figure (saved to ``path``) for callers that want to adjust or inspect it.
    """
    fig = _figure(8.2, 5.8)
    ax = fig.add_subplot(1, 1, 1)
    colours = _cmap("tab10")
    xs_all = []
    kinds = {d.attrs.get("kind", "branch") for d in files}
    for n, d in enumerate(files):
        c = colours(n % 10)
        param = d.attrs.get("param", "phi_L")
        dx, dy = default_axes(d.attrs)
        xv, yv = x or dx, y or dy
        label = labels[n] if labels and n < len(labels) else _file_label(d, param)
        is_diagram = d.attrs.get("kind") == "diagram"
        for j, b in enumerate(d.branches):
            br = b.branch
            for name in (xv, yv):
                if name not in br:
                    columns = ", ".join(sorted(k for k in br if br[k].ndim == 1))
                    raise ValueError(f"{d.path} has no column {name!r} (it has: {columns})")
            order = np.argsort(br["arclength"]) if d.attrs.get("kind") == "fold_curve" else np.arange(len(br[xv]))
            X, Y = np.asarray(br[xv], float)[order], np.asarray(br[yv], float)[order]
            unstable = br.get("unstable_modes")
            unstable = None if unstable is None else np.asarray(unstable)[order]
            for k_, (sx, sy, stable) in enumerate(_segments(X, Y, unstable)):
                ax.plot(sx, sy, "-" if stable else "--", color=c, lw=1.4,
                        label=label if (j == 0 and k_ == 0) else None)
            xs_all.append(X)
            f = b.folds
            if f and len(f.get("index", [])) and d.attrs.get("kind") != "fold_curve":
                idx = np.asarray(f["index"], int)
                ax.plot(np.asarray(br[xv])[idx], np.asarray(br[yv])[idx], "o", ms=5, mfc="white", mec=c, mew=1.5)
                if is_diagram:
                    for i, wb, wa in zip(idx, f["waves_before"], f["waves_after"]):
                        ax.annotate(f"{wb}→{wa}", (br[xv][i], br[yv][i]), textcoords="offset points", xytext=(4, 4),
                                    fontsize=7, color=c)
            ax.plot(X[-1:], Y[-1:], "x", color=c, ms=6)
            if is_diagram:
                ax.plot(X[:1], Y[:1], "x", color=c, ms=6)
    allx = np.concatenate(xs_all) if xs_all else np.zeros(1)
    drill = all(is_drill_string(d.attrs) for d in files)
    # the first file's axes, as its curve is drawn (a trace in T or depth is not against the stretch)
    xname, yname = x or default_axes(files[0].attrs)[0], y or default_axes(files[0].attrs)[1]
    if xscale is None:
        xscale = "log" if xname == "stretch" and np.all(allx > 0) and allx.max() > 30 * allx.min() else "linear"
    ax.set_xscale(xscale)
    ax.set_xlabel(_label(xname, drill))
    ax.set_ylabel(_label(yname, drill))
    ax.grid(True, alpha=0.3)
    extra = "   -- unstable" if any("unstable_modes" in b.branch for d in files for b in d.branches) else ""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0,
              title=f"○ fold (waves)   × end{extra}", title_fontsize=7)
    ax.set_title(title or (f"Branches of {files[0].attrs['problem']}" if kinds == {"bvp"}
                           else "Torque and drag: a drill string in its well" if drill
                           else "Response diagram: twisted heavy clamped rod"))
    fig.tight_layout()
    save_figure(fig, path)
    return fig


def _file_label(d, param) -> str:
    """A file's legend entry: a user's problem, a drill string's operation, else its Γ (or T)."""
    if "problem" in d.attrs:
        return str(d.attrs.get("problem"))
    if is_drill_string(d.attrs):
        return _legend(d)
    g = d.attrs.get("gamma")
    return ((f"Γ = {g:g}" if isinstance(g, float) and math.isfinite(g) else f"T = {d.attrs.get('T', 0):g}")
            + {"diagram": " (diagram)", "fold_curve": f" (fold locus in {param})"}.get(d.attrs.get("kind"), ""))


def shape_figure(curves: list[tuple[np.ndarray, str]], path: str, title: str = "", reference=None,
                 tube=None, contacts=(), axes=("e1", "e2", "e3")) -> Figure:
    """3D centrelines ``r(S)`` (each ``(3, n)``) with equal axis scales; returns the figure (saved to ``path``).

    ``reference``: the reference curve's points ``(3, n)`` (default: the straight
    span along e1); ``tube``: the conduit's wall as three ``(n_S, n_theta)``
    arrays, drawn translucent; ``contacts``: points ``(3, m)`` of each curve in
    contact with the wall, drawn as red dots; ``axes``: the axes' labels.
    """
    fig = _figure(8, 5)
    ax = fig.add_subplot(projection="3d")
    allpts = np.concatenate([r for r, _ in curves], axis=1)
    for r, label in curves:
        ax.plot(r[0], r[1], r[2], lw=2, label=label)
    if reference is None:
        ax.plot([allpts[0].min(), allpts[0].max()], [0, 0], [0, 0], "k--", lw=0.8, label="reference curve")
    else:
        ax.plot(reference[0], reference[1], reference[2], "k--", lw=0.8, label="reference curve")
        allpts = np.concatenate([allpts, reference], axis=1)
    if tube is not None:
        ax.plot_surface(*tube, color="tab:gray", alpha=0.15, linewidth=0, shade=False)
        allpts = np.concatenate([allpts, np.stack([t.ravel() for t in tube])], axis=1)
    for i, pts in enumerate(contacts):
        if pts.size:
            ax.plot(pts[0], pts[1], pts[2], "o", color="tab:red", ms=2.5,
                    label="in contact with the wall" if i == 0 else None)
    centre = 0.5 * (allpts.max(axis=1) + allpts.min(axis=1))
    half = 0.5 * float(np.max(allpts.max(axis=1) - allpts.min(axis=1)))
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_xlabel(axes[0])
    ax.set_ylabel(axes[1])
    ax.set_zlabel(axes[2])
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    save_figure(fig, path)
    return fig
