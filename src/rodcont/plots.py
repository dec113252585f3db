"""Figures from branch and diagram files: the response diagram (paper Figure 2) and 3D shapes.

Figures are drawn with matplotlib's object interface on an Agg canvas: no
pyplot, so the caller's backend and global state are left alone.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def _figure(w, h):
    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    return fig


def _cmap(name):
    import matplotlib
    return matplotlib.colormaps[name]


def response_diagram(files, path: str, title: str | None = None) -> None:
    """``phi_L`` (vertical) against ``stretch``: every branch of every file, one colour per Gamma.

    ``files``: :class:`rodcont.branchfile.DiagramData` (a trace file is a
    diagram of one branch). Folds are marked (○) and, in diagrams, labelled
    with the helical waves on their two sides (``1→2``); × marks where a
    branch ends. A fold-curve file is drawn as ``phi_L`` at the fold against
    its parameter, on its own axes.
    """
    ordinary = [d for d in files if d.attrs.get("kind", "branch") != "fold_curve"
                and d.attrs.get("param", "phi_L") == "phi_L"]
    loci = [d for d in files if d not in ordinary]
    ncols = (1 if ordinary else 0) + (1 if loci else 0)
    fig = _figure(7.0 * ncols, 5.8)
    axes = [fig.add_subplot(1, ncols, i + 1) for i in range(ncols)]
    col = 0
    if ordinary:
        ax = axes[col]
        col += 1
        cmap = _cmap("viridis")
        gammas = sorted({float(d.attrs.get("gamma", 0.0)) for d in ordinary})
        smin = np.inf
        for d in sorted(ordinary, key=lambda d: float(d.attrs.get("gamma", 0.0))):
            g = float(d.attrs.get("gamma", 0.0))
            c = cmap(0.9 * gammas.index(g) / max(len(gammas) - 1, 1))
            is_diagram = d.attrs.get("kind") == "diagram"
            for j, b in enumerate(d.branches):
                s, p = b.branch["stretch"], b.branch["phi_L"]
                smin = min(smin, float(np.min(s)))
                label = f"Γ = {g:g}" + (" (diagram)" if is_diagram else "") if j == 0 else None
                ax.plot(s, p, "-", color=c, lw=1.4, label=label)
                f = b.folds
                if f and len(f.get("index", [])):
                    ax.plot(f["stretch"], f["phi_L"], "o", ms=5, mfc="white", mec=c, mew=1.5)
                    if is_diagram:
                        for fs, fp, wb, wa in zip(f["stretch"], f["phi_L"], f["waves_before"], f["waves_after"]):
                            ax.annotate(f"{wb}→{wa}", (fs, fp), textcoords="offset points", xytext=(4, 4),
                                        fontsize=7, color=c)
                ax.plot(s[-1:], p[-1:], "x", color=c, ms=6)
                if is_diagram:
                    ax.plot(s[:1], p[:1], "x", color=c, ms=6)
        if smin > 0:
            ax.set_xscale("log")  # the stretch spans decades: from the sag to the loop
        else:
            ax.set_xscale("symlog", linthresh=1e-5, linscale=0.3)
        ax.set_xlabel("stretch  (ℓ − L) / L")
        ax.set_ylabel("end rotation  Φ = φ(L)  [rad]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=9, title="○ fold (waves before→after)   × end", title_fontsize=8)
        ax.set_title(title or "Response diagram: twisted heavy clamped rod")
    if loci:
        ax = axes[col]
        for d in loci:
            for b in d.branches:
                param = d.attrs.get("param")
                order = np.argsort(b.branch["arclength"])
                ax.plot(b.branch[param][order], b.branch["phi_L"][order], "-", lw=1.4,
                        label=f"fold locus in {param}")
                ax.set_xlabel(param)
        ax.set_ylabel("Φ at the fold  [rad]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=9)
        ax.set_title("Fold curves")
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def shape_figure(curves: list[tuple[np.ndarray, str]], path: str, title: str = "") -> None:
    """3D centrelines ``r(S)`` (each ``(3, n)``) with equal axis scales."""
    fig = _figure(8, 5)
    ax = fig.add_subplot(projection="3d")
    allpts = np.concatenate([r for r, _ in curves], axis=1)
    for r, label in curves:
        ax.plot(r[0], r[1], r[2], lw=2, label=label)
    ax.plot([allpts[0].min(), allpts[0].max()], [0, 0], [0, 0], "k--", lw=0.8, label="reference curve")
    centre = 0.5 * (allpts.max(axis=1) + allpts.min(axis=1))
    half = 0.5 * float(np.max(allpts.max(axis=1) - allpts.min(axis=1)))
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)
    ax.set_xlabel("e1")
    ax.set_ylabel("e2")
    ax.set_zlabel("e3")
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
