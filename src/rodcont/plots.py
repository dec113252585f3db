"""Figures from branch files: the response diagram (paper Figure 2) and 3D shapes."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .branchfile import BranchData  # noqa: E402


def response_diagram(branches: list[BranchData], path: str, title: str | None = None) -> None:
    """``phi_L`` (vertical) against ``stretch``, one curve per branch labelled by Gamma, folds marked.

    A fold-curve file (``param`` attribute other than ``phi_L``) is drawn as
    ``phi_L`` at the fold against the continued parameter, on its own axes.
    """
    ordinary = [b for b in branches if b.attrs.get("param", "phi_L") == "phi_L"]
    loci = [b for b in branches if b.attrs.get("param", "phi_L") != "phi_L"]
    ncols = (1 if ordinary else 0) + (1 if loci else 0)
    fig, axes = plt.subplots(1, ncols, figsize=(6.5 * ncols, 5.5), squeeze=False)
    col = 0
    if ordinary:
        ax = axes[0, col]
        col += 1
        cmap = plt.get_cmap("viridis")
        gammas = sorted({b.gamma for b in ordinary})
        for b in sorted(ordinary, key=lambda b: b.gamma):
            c = cmap(gammas.index(b.gamma) / max(len(gammas) - 1, 1))
            ax.plot(b.branch["stretch"], b.branch["phi_L"], "-", color=c, lw=1.4, label=f"Γ = {b.gamma:g}")
            f = b.folds
            if f and len(f.get("index", [])):
                ax.plot(f["stretch"], f["phi_L"], "o", ms=5, mfc="white", mec=c, mew=1.5)
            ax.plot(b.branch["stretch"][-1:], b.branch["phi_L"][-1:], "x", color=c, ms=6)
        smin = min(float(np.min(b.branch["stretch"])) for b in ordinary)
        if smin > 0:
            ax.set_xscale("log")  # the stretch spans decades: from the sag to the loop
        else:
            ax.set_xscale("symlog", linthresh=1e-5, linscale=0.3)
        ax.set_xlabel("stretch  (ℓ − L) / L")
        ax.set_ylabel("end rotation  Φ = φ(L)  [rad]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="lower right", fontsize=9, title="○ fold   × end of trace", title_fontsize=8)
        ax.set_title(title or "Response diagram: twisted heavy clamped rod")
    if loci:
        ax = axes[0, col]
        for b in loci:
            param = b.attrs["param"]
            ax.plot(b.branch[param], b.branch["phi_L"], "-", lw=1.4, label=f"fold locus in {param}")
            ax.set_xlabel(param)
        ax.set_ylabel("Φ at the fold  [rad]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=9)
        ax.set_title("Fold curves")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def shape_figure(curves: list[tuple[np.ndarray, str]], path: str, title: str = "") -> None:
    """3D centrelines ``r(S)`` (each ``(3, n)``) with equal axis scales."""
    fig = plt.figure(figsize=(8, 5))
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
    plt.close(fig)
