"""prototype"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .rod import Jet


def inertia_factors(system, x, p, rhoA=None, rhoJ=None, consistent=True):
    model, disc = system.model, system.disc
    rod = model.rod
    EI, GJ, EA, L = p[3], p[4], p[5], rod.L
    if rhoA is None:
        rhoA = EI / L**4
    if rhoJ is None:
        rhoJ = rhoA * 2.0 * EI / EA
    z = disc.jets(x)
    npts = disc.npts
    r1, r2, _ = model._frame_jets(z)
    n = np.sqrt((r1 * r1).sum(0))
    d3 = r1 / n
    F = z[Jet.F]
    alpha = 1.0 + (F * d3).sum(0) / EA
    sp_ = n / alpha
    d3p = (r2 - d3 * (d3 * r2).sum(0)) / n
    tau = -(d3[0] * d3p[1] - d3[1] * d3p[0]) / (1.0 + d3[2])
    twist = z[Jet.PHI[1]] + tau
    E = disc.E
    rows = lambda j: E[j * npts:(j + 1) * npts]  # noqa: E731
    q = np.arange(npts)
    if consistent:
        c1 = d3[1] / (n * (1.0 + d3[2]))
        c2 = -d3[0] / (n * (1.0 + d3[2]))
        th = rows(Jet.PHI[0]) + sp.diags(c1) @ rows(Jet.D1[1]) + sp.diags(c2) @ rows(Jet.D2[1])
    else:
        th = rows(Jet.PHI[0])
    W = sp.vstack([rows(Jet.D1[0]), rows(Jet.D2[0]), th], format="csr")
    # U: natural rows q*6+i, columns a=q, b=npts+q, c=2npts+q
    mA, mJ = rhoA * sp_, rhoJ * sp_
    if consistent:
        R = [q * 6 + 0, q * 6 + 1, q * 6 + 2, q * 6 + 2, q * 6 + 2, q * 6 + 3, q * 6 + 4, q * 6 + 5]
        C = [q, npts + q, q, npts + q, 2 * npts + q, 2 * npts + q, 2 * npts + q, 2 * npts + q]
        V = [mA, mA, -mA * z[Jet.D1[1]], -mA * z[Jet.D2[1]], -mJ * twist, mJ * d3[0], mJ * d3[1], mJ / GJ]
    else:
        R = [q * 6 + 0, q * 6 + 1, q * 6 + 5]
        C = [q, npts + q, 2 * npts + q]
        V = [mA, mA, mJ / GJ]
    rank = np.empty(disc.size, int)
    rank[disc.row_order] = np.arange(disc.size)
    U = sp.csr_matrix((np.concatenate(V), (rank[np.concatenate(R)], np.concatenate(C))), shape=(disc.size, 3 * npts))
    return U, W


def spectrum(system, x, phi_L, consistent=True, shift=0.0, **kw):
    p = system.params(phi_L) if system.param == "phi_L" else system.base.copy()
    p[0] = phi_L
    _, J, _ = system.disc.linearise(x, p)
    U, W = inertia_factors(system, x, p, consistent=consistent, **kw)
    A = (J - shift * (U @ W)).tocsc() if shift else J
    lu = spla.splu(A, permc_spec="NATURAL")
    Y = lu.solve(U.toarray())
    C = W @ Y
    mu = np.linalg.eigvals(C)
    mu = mu[np.abs(mu) > 1e-14 * np.abs(mu).max()]
    return shift + 1.0 / mu
