"""Unstable modes of rod equilibria (rodcont.stability), checked independent ways.

* Method 1 (eigenvalues of the linearised dynamics) against method 2 (exchange
  of stability at the folds from the planar sag, known stable) along the
  Gamma = 1 and Gamma = 0 primary branches; the dense and the ARPACK solvers
  and three choices of inertia give the same counts.
* Closed forms: the unloaded clamped beam (eigenvalues ``-beta^4``), the
  weightless straight rod under twist (stable below the first critical twist,
  two unstable modes above it, four above the second) and under compression
  (two unstable modes past the extensible Euler load).
* The torque rule of method 2 needs a conservative problem. The canonical
  self-feeding problem is not one (Maxwell's reciprocity fails, complex
  eigenvalues appear); its conservative counterpart (:func:`sleeve_system`)
  passes both checks and there the three counts agree everywhere.
"""

import math

import numpy as np
import pytest

from rodcont.branch import Branch
from rodcont.continuation import ContinuationSettings, Event, Tracker
from rodcont.drivers.trace import trace
from rodcont.rod import RodParameters
from rodcont.stability import (
    branch_spectra,
    branch_unstable_modes,
    exchange_of_stability,
    fold_indices,
    reciprocity_ratio,
    sleeve_system,
    spectrum,
    unstable_modes,
)
from rodcont.system import RodSystem

CRITICAL_TWISTS_T10 = (13.83443036, 21.69758836)  # weightless rod, T = 10, paper stiffnesses (double roots)


@pytest.fixture(scope="module")
def gamma1_file(tmp_path_factory):
    return str(tmp_path_factory.mktemp("stability") / "gamma1.h5")


@pytest.fixture(scope="module")
def gamma1(gamma1_file):
    return trace(1.0, N=15, out=gamma1_file)


@pytest.fixture(scope="module")
def gamma0():
    return trace(0.0, N=15)


@pytest.fixture(scope="module")
def spectra(gamma1, gamma0):
    return {1.0: branch_spectra(gamma1), 0.0: branch_spectra(gamma0)}


def _folds(br):
    f = fold_indices(br)
    assert all(i > 0 for i in f), "every fold of these branches is located"
    return f


# --------------------------------------------------------------------------
# The two methods on the primary branches
# --------------------------------------------------------------------------
def test_gamma1_both_methods_agree_at_every_point(gamma1, spectra):
    m1 = [s.unstable for s in spectra[1.0]]
    torque_rule = exchange_of_stability(gamma1, start=0)          # planar sag: stable (theory)
    pencil_rule = exchange_of_stability(gamma1, start=0, rule="pencil")
    assert m1 == torque_rule == pencil_rule
    (fold,) = _folds(gamma1)
    assert m1[:fold + 1] == [0] * (fold + 1)                      # stable up to the fold (null mode there)
    assert set(m1[fold + 1:]) == {1}                              # one unstable mode past it
    assert spectra[1.0][fold].null == 1
    assert exchange_of_stability(gamma1) == m1                     # start from method 1 instead of theory


def test_gamma0_methods_agree_up_to_the_second_fold(gamma0, spectra):
    m1 = [s.unstable for s in spectra[0.0]]
    pencil_rule = exchange_of_stability(gamma0, start=0, rule="pencil")
    torque_rule = exchange_of_stability(gamma0, start=0)
    f1, f2 = _folds(gamma0)
    assert m1 == pencil_rule
    assert m1 == [0] * (f1 + 1) + [1] * (f2 - f1) + [2] * (len(m1) - f2 - 1)
    assert [spectra[0.0][i].null for i in (f1, f2)] == [1, 1]
    # The torque rule agrees up to the second fold (a minimum of Phi with the torque
    # decreasing) and says -1 there, where the eigenvalues and the pencil say +1: the
    # canonical problem is not conservative (test_canonical_problem_is_not_conservative)
    # and the rule has no theorem behind it.
    assert torque_rule[:f2] == m1[:f2]
    assert set(torque_rule[f2:]) == {0}


def test_dense_and_arnoldi_agree(gamma1, gamma0, spectra):
    for g, br in ((1.0, gamma1), (0.0, gamma0)):
        small = [i for i in range(len(br)) if br.meshes[i].size <= 41]  # dense is O(n^3): meshes up to N = 40
        dense = branch_spectra(_subset(br, small), method="dense")
        for j, i in enumerate(small):
            a, d = spectra[g][i], dense[j]
            assert (a.unstable, a.null) == (d.unstable, d.null), (g, i)
            near = a.nearest[:4]
            # rtol 1e-6: on the Gamma = 0 branch a close pair near -1520 moves by 5e-8 (dense) and 4e-7 (Arnoldi)
            # of its size when the Jacobian changes by rounding only (complex-step against analytic dG/dz)
            assert np.allclose(near, d.nearest[:4], rtol=1e-6, atol=1e-7), (g, i)


def test_count_does_not_depend_on_the_inertia(gamma1, gamma0, spectra):
    """Sylvester: any positive mass on the transverse motion gives the same count; rotary inertia
    about d3 and the axial entry of the inertia force change the eigenvalues, not the count
    (every point on the uniform N = 15 mesh: both folds of Gamma = 0 and the one of Gamma = 1)."""
    for g, br in ((1.0, gamma1), (0.0, gamma0)):
        idx = [i for i in range(len(br)) if br.meshes[i].size == 16]
        assert len(idx) > 30
        sub = _subset(br, idx)
        m1 = [spectra[g][i].unstable for i in idx]
        assert branch_unstable_modes(sub, torsional_inertia=0.02) == m1
        assert branch_unstable_modes(sub, axial_row=False) == m1


def test_branch_file_gives_the_same_column(gamma1_file, gamma1, spectra):
    from rodcont.branchfile import load_branch
    data = load_branch(gamma1_file)
    assert branch_unstable_modes(data) == [s.unstable for s in spectra[1.0]]
    assert exchange_of_stability(data, start=0) == exchange_of_stability(gamma1, start=0)
    assert exchange_of_stability(data, start=0, rule="pencil") == exchange_of_stability(gamma1, start=0)


# --------------------------------------------------------------------------
# Closed forms
# --------------------------------------------------------------------------
def test_unloaded_clamped_beam_eigenvalues():
    """Sign convention and scale: lambda = -beta^4 EI/(rho A L^4), each double (two planes)."""
    s = RodSystem(RodParameters(w=0.0), T=0.0, N=15)
    x = s.straight_state(0.0)
    beta = np.array([4.730040744862704, 7.853204624095838, 10.995607838001671])
    for method in ("dense", "arnoldi"):
        sp = spectrum(s, x, 0.0, method=method)
        lam = np.sort(sp.eigenvalues.real)[::-1][:6]
        assert np.allclose(lam, np.repeat(-beta**4, 2), rtol=1e-9)
        assert sp.unstable == sp.null == sp.flutter == 0


def test_weightless_straight_rod_loses_stability_at_the_critical_twists():
    s = RodSystem(RodParameters(w=0.0), T=10.0, N=15)
    c1, c2 = CRITICAL_TWISTS_T10
    cases = [(0.0, 0), (5.0, 0), (13.8, 0), (c1 * (1 - 1e-6), 0), (c1 * (1 + 1e-6), 2), (13.9, 2), (18.0, 2),
             (c2 * (1 - 1e-6), 2), (c2 * (1 + 1e-6), 4), (25.0, 4)]
    for phi, expected in cases:
        x = s.straight_state(phi)
        assert np.abs(s.residual(x, phi)).max() < 1e-7
        for method in ("dense", "arnoldi"):
            assert unstable_modes(s, x, phi, method=method) == expected, (phi, method)
    for c, below in ((c1, 0), (c2, 2)):
        sp = spectrum(s, s.straight_state(c), c)
        assert (sp.unstable, sp.null) == (below, 2)               # O(2): a double null eigenvalue


def test_weightless_straight_rod_under_compression():
    """Untwisted straight rod: two unstable modes (both planes) past the extensible Euler load."""
    rod = RodParameters(w=0.0)
    Tc = -4 * math.pi**2 * rod.EI / rod.L**2 / (1 + 4 * math.pi**2 * rod.EI / (rod.EA * rod.L**2))
    for factor, expected in ((0.9, 0), (0.999, 0), (1.001, 2), (1.1, 2)):
        s = RodSystem(rod, T=factor * Tc, N=15)
        assert unstable_modes(s, s.straight_state(0.0), 0.0) == expected, factor


# --------------------------------------------------------------------------
# Units
# --------------------------------------------------------------------------
UNITS = [(10.0, 1.0), (1e-3, 1.0), (1e3, 1e6), (1e-3, 1e-6), (1e-3, 1e6), (1e3, 1e-6), (0.37, 2.9e4)]


@pytest.fixture(scope="module")
def seed_branch():
    """Issue 22's case: the Gamma = 1 branch from the near-straight rod at Phi = 25.778 (4 unstable modes,
    a fold, 5)."""
    import rodcont
    return rodcont.trace(1.0, from_straight=25.778)


def test_counts_do_not_depend_on_the_units(seed_branch):
    """Lengths x a and forces x b (the solution mapped exactly, test_units.in_units): the same eigenvalues
    (lambda is in units of EI/(rho A L^4)) and the same counts. Before, at and after the seed branch's fold,
    at its last point (its finest mesh) and on the weightless straight rod at Phi = 40 (8 unstable modes).
    The code before counted 0 instead of 4 with lengths x 10 (its mesh cap (pi/h)^4 was in 1/length^4) and
    moved eigenvalues by up to 2e-3 of their size in other units (J - s0 B factorised as it came)."""
    from test_units import in_units
    br = seed_branch
    (fold,) = [i for i, k in enumerate(br.table["kind"]) if k == "fold"]
    cases = []
    for i, expected in ((fold - 2, (4, 0)), (fold, (4, 1)), (fold + 2, (5, 0)), (len(br) - 1, (5, 0))):
        cases.append((RodSystem(br.rod, gamma=1.0, breakpoints=br.meshes[i]), br.coefficients[i],
                       float(br.table["phi_L"][i]), expected))
    straight = RodSystem(RodParameters(w=0.0), T=10.0, N=30)
    cases.append((straight, straight.straight_state(40.0), 40.0, (8, 0)))
    assert cases[-2][0].disc.N > 100
    for s, x, phi, expected in cases:
        ref = spectrum(s, x, phi)
        assert (ref.unstable, ref.null) == expected
        near = ref.nearest[:6]
        for a, b in UNITS:
            s2, y = in_units(s, x, a, b)
            sp = spectrum(s2, y, phi)
            assert (sp.unstable, sp.null) == expected, (phi, a, b)
            assert np.allclose(sp.nearest[:6], near, rtol=1e-6, atol=1e-6), (phi, a, b)


# --------------------------------------------------------------------------
# Conservative or not
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sleeve_branch():
    """The conservative counterpart of Gamma = 1 (rod drawn from a straight untwisted reservoir
    under a dead load T), traced on a fixed mesh while it is well resolved."""
    rod = RodParameters()
    T = rod.tension(1.0)
    s = sleeve_system(rod, T, N=30)
    x0 = s.disc.newton(s.model.initial_guess(s.disc, T), s.params(0.0)).x
    resolved = Event("resolved", lambda pt: 1e-4 - pt.data["defect"], stop=True)
    pts = list(Tracker(s, x0, 0.0, ContinuationSettings(ds=0.1, ds_max=0.3, max_steps=200, p_min=-1.0),
                       monitor=s.outputs, events=[resolved]))
    br = Branch(gamma=1.0, rod=rod, N=30, k=5)
    for pt in pts:
        br.add(pt, s.disc.breakpoints)
    return s, br


def test_conservative_variant_all_three_agree(sleeve_branch):
    s, br = sleeve_branch
    make = lambda b: s  # noqa: E731 - one fixed mesh
    spectra = branch_spectra(br, make_system=make, method="dense")
    m1 = [sp.unstable for sp in spectra]
    assert len(_folds(br)) == 1 and max(m1) == 1 and m1[0] == 0
    assert m1 == exchange_of_stability(br, start=0) == exchange_of_stability(br, start=0, rule="pencil",
                                                                             make_system=make)
    for sp in spectra:                      # self-adjoint: a real spectrum
        assert sp.flutter == 0
        assert np.abs(sp.eigenvalues.imag).max(initial=0.0) <= 1e-8 * np.abs(sp.eigenvalues).max()


def test_canonical_problem_is_not_conservative(gamma1, gamma0, spectra, sleeve_branch):
    """Maxwell: (dm/dT)_Phi = G'(T) (dl0/dPhi)_T, G'(T) = 1 + T/EA, for a potential V + G(T) l0."""
    s, br = sleeve_branch
    g1 = 1.0 + s.base[1] / s.rod.EA
    for i in range(1, len(br), 4):
        if br.table["kind"][i] != "fold":
            assert reciprocity_ratio(s, br.coefficients[i], br.table["phi_L"][i]) == pytest.approx(g1, rel=1e-5)
    for g, b in ((1.0, gamma1), (0.0, gamma0)):
        ratios = [reciprocity_ratio(RodSystem(b.rod, gamma=g, N=b.meshes[i].size - 1, breakpoints=b.meshes[i]),
                                    b.coefficients[i], b.table["phi_L"][i])
                  for i in range(1, len(b), 3) if b.table["kind"][i] != "fold"]
        assert max(ratios) > 50 * min(ratios)        # no constant: no potential of that form
        # ... and a non-self-adjoint linearisation: complex eigenvalues (flutter of the undamped dynamics)
        assert any(sp.flutter > 0 for sp in spectra[g])
        assert all(sp.flutter % 2 == 0 for sp in spectra[g])


def test_exchange_rule_refuses_what_it_cannot_know(gamma1):
    br = _subset(gamma1, range(len(gamma1)))
    i = len(br) // 3
    br.table["kind"][i] = "branch_point"
    with pytest.raises(ValueError, match="branch point"):
        exchange_of_stability(br, start=0)
    counts = exchange_of_stability(br, start=0, branch_point_changes={i: 2})
    assert counts[i] == 0 and counts[i + 1] == 2
    with pytest.raises(ValueError, match="negative"):
        exchange_of_stability(gamma1.reversed(), start=0)         # the end arc is unstable: 0 is wrong there


def _subset(br, idx):
    out = Branch(br.gamma, br.rod, br.N, br.k, br.param)
    idx = list(idx)
    for name, col in br.table.items():
        out.table[name] = [col[i] for i in idx]
    out.coefficients = [br.coefficients[i] for i in idx]
    out.tangents = [br.tangents[i] for i in idx]
    out.meshes = [br.meshes[i] for i in idx]
    return out


def test_traces_store_the_counts_of_method_one(tmp_path):
    """The trace stores method 1's count at every point (computed where it can change, carried
    between): it equals method 1 recomputed at every point of the stored Gamma = 1 branch, and the
    fold table says which side is stable."""
    import rodcont
    from rodcont.stability import unstable_modes
    from rodcont.system import point_system
    path = str(tmp_path / "g1.h5")
    rodcont.trace(1.0, out=path)
    d = rodcont.load_branch(path)
    for i in range(len(d)):
        s = point_system(d, i)
        assert d.branch["unstable_modes"][i] == unstable_modes(s, d.point(i)["x"], d.branch["phi_L"][i]), i
    assert d.folds["unstable_before"][0] == 0 and d.folds["unstable_after"][0] == 1


def test_first_unstable_tension_finds_the_euler_load_of_the_straight_weightless_rod():
    """rodcont.drivers.solve.first_unstable_tension against the closed form: the straight, weightless,
    clamped rod loses stability at the Euler load (extensible, self-feeding: euler_tension). A tension end
    with no unstable mode gives nan; a 'stable' waypoint past the load is refused."""
    from rodcont.drivers.solve import euler_tension, first_unstable_tension
    rod = RodParameters(w=0.0)
    TE = euler_tension(rod)
    T, n = first_unstable_tension(rod, (10.0, 0.5 * TE), 1.5 * TE, N=15, tol=1e-6 * abs(TE))
    assert n >= 1 and T == pytest.approx(TE, rel=1e-5)
    assert first_unstable_tension(rod, (10.0,), 5.0)[1] == 0
    with pytest.raises(ValueError, match="already has an unstable mode"):
        first_unstable_tension(rod, (10.0, 1.2 * TE), 1.5 * TE)
