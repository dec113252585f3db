"""Joins: breakpoints where fields are only C^0 and interface conditions hold (collocation core, rod model).

A reference curve whose curvature jumps (a minimum-curvature well) makes its stations joins: the exact
Eulerian fields Delta', Delta'', phi' jump there. Evidence: a two-material bar solved exactly by the core;
the assembled Jacobian (interface rows included) against differences of the residual; and the physical
rod on an S-shaped well path against the same rod on the straight reference (it must not depend on the
reference curve).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rodcont.collocation import BVProblem, Collocation


# --------------------------------------------------------------------------
# The collocation core: a two-material bar
# --------------------------------------------------------------------------
def bar_problem(joins=(1.0,)):
    """``(a u')' = -1`` on ``[0, 2]``, ``a = 1`` left of 1, ``a = p0`` right of it, ``u(0) = u(2) = 0``: at the
    join ``u`` is C^0 and the flux is continuous, ``u'(1-) = p1 u'(1+)``, with ``p1`` a free parameter fixed
    by the boundary condition ``p1 = p0`` (so the interface rows read a free parameter)."""
    def residual(S, z, p):
        a = np.where(S < 1.0, 1.0, p[0])
        return (a * z[2] + 1.0)[None]

    def bc(za, zb, p):
        return np.stack([za[0], zb[0], p[1] - p[0] + 0 * za[0]])

    def interface(zl, zr, p, S):
        return (zl[1] - p[1] * zr[1])[None]

    return BVProblem(orders=(2,), residual=residual, bc=bc, interval=(0.0, 2.0), params=("a", "ratio"), free=(1,),
                     joins=joins, join_continuity=(0,) if joins else None, interface=interface if joins else None)


def bar_exact(S, a):
    """Flux ``a u' = C - S``, ``C = (a + 3) / (2 (a + 1))`` from ``u(2) = 0`` and continuity at 1."""
    C = (a + 3) / (2 * (a + 1))
    D = (C - 0.5) * (1 - 1 / a)
    return np.where(S < 1.0, C * S - S**2 / 2, (C * S - S**2 / 2) / a + D)


def dense_fd_jacobian(f, x, h=1e-6):
    """Central differences of ``f`` at ``x``, column by column."""
    cols = []
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=1)


def test_a_join_gives_the_kinked_solution_exactly():
    """Piecewise quadratic with a kink at the join: reproduced to rounding by C^0 joins (one interface row,
    one more unknown), on either side of the join and after transfer to a finer mesh; the C^1 space
    without the join misses it by O(h)."""
    a = 3.0
    p = np.array([a, 0.0])
    b = np.array([0.0, 0.3, 1.0, 1.4, 2.0])
    disc = Collocation(bar_problem(), b, k=3)
    plain = Collocation(bar_problem(joins=()), b, k=3)
    assert disc.size == plain.size + 1 and disc.n_interface == 1 and disc.n_bc == plain.n_bc == 3
    r = disc.newton(np.zeros(disc.size), p)
    assert r.converged
    S = np.linspace(0, 2, 201)
    assert np.max(np.abs(disc.evaluate(r.x, S, 0) - bar_exact(S, a))) < 1e-13
    assert r.x[disc.free_index[0]] == pytest.approx(a, abs=1e-13)
    # one-sided jets at the join (a point on a join belongs to the right subinterval)
    C = (a + 3) / (2 * (a + 1))
    left = (disc.jet_matrix(np.array([1.0]), interval=np.array([1])) @ r.x)
    right = (disc.jet_matrix(np.array([1.0])) @ r.x)
    assert left[1] == pytest.approx(C - 1, abs=1e-13) and right[1] == pytest.approx((C - 1) / a, abs=1e-13)
    assert left[0] == pytest.approx(right[0], abs=1e-14) and disc.evaluate(r.x, 1.0, 0, 1) == right[1]
    # transfer to a finer mesh with the same join: exact (the solution lies in both spaces)
    fine = Collocation(bar_problem(), np.union1d(b, [0.7, 1.2, 1.7]), k=4)
    xf = fine.transfer(r.x, disc)
    assert np.max(np.abs(fine.evaluate(xf, S, 0) - bar_exact(S, a))) < 1e-13
    assert np.max(np.abs(fine.residual(xf, p))) < 1e-12
    rp = plain.newton(np.zeros(plain.size), p)
    assert rp.converged and np.max(np.abs(plain.evaluate(rp.x, S, 0) - bar_exact(S, a))) > 1e-3


def test_a_join_must_be_a_breakpoint():
    with pytest.raises(ValueError, match="join must be an interior breakpoint"):
        Collocation(bar_problem(), np.array([0.0, 0.5, 1.5, 2.0]), k=3)
    with pytest.raises(ValueError, match="interface function"):
        Collocation(dataclasses.replace(bar_problem(), interface=None), np.array([0.0, 1.0, 2.0]), k=3)


def test_bar_jacobian_with_a_join_equals_differences():
    """Rows of the collocation, the boundary and the interface, the free parameter's column and a
    parameter derivative: against central differences."""
    disc = Collocation(bar_problem(), np.array([0.0, 0.4, 1.0, 2.0]), k=3)
    rng = np.random.default_rng(1)
    x, p = rng.normal(size=disc.size), np.array([2.5, 0.0])
    F, J, (Fa,) = disc.linearise(x, p, [0])
    assert np.allclose(F, disc.residual(x, p), atol=1e-14)
    assert np.max(np.abs(J.toarray() - dense_fd_jacobian(lambda y: disc.residual(y, p), x))) < 1e-7
    pa = lambda v: disc.residual(x, np.array([v, 0.0]))  # noqa: E731
    assert np.max(np.abs(Fa - (pa(2.5 + 1e-6) - pa(2.5 - 1e-6)) / 2e-6)) < 1e-7
