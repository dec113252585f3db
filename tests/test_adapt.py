"""Moving breakpoints (--adapt): the mesh follows the localising shape, and what it computes is the rod."""

import os
import subprocess
import sys

import numpy as np
import pytest

import rodcont
from rodcont.collocation import BVProblem, Collocation
from rodcont.drivers.trace import trace
from rodcont.mesh import equidistribute
from rodcont.system import point_system
from test_rod import clamp_miss

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_equidistribute_moves_points_to_the_error():
    b = np.linspace(0, 1, 21)
    h = np.diff(b)
    C = np.where(np.abs(0.5 * (b[1:] + b[:-1]) - 0.5) < 0.1, 1e4, 1.0)  # error constant peaked mid-span
    new = equidistribute(b, C * h**6, order=6, relax=1.0)
    assert new[0] == 0 and new[-1] == 1 and np.all(np.diff(new) > 0)
    hn = np.diff(new)
    dist = np.abs(0.5 * (new[1:] + new[:-1]) - 0.5)
    # finer where the error is; in between, neighbouring sizes change by at most the ratio 2
    assert hn[dist < 0.08].max() < 0.5 * hn[dist > 0.25].min()
    assert np.all(hn[1:] / hn[:-1] <= 2.0 + 1e-9) and np.all(hn[:-1] / hn[1:] <= 2.0 + 1e-9)
    assert hn.max() / hn.min() <= (1 / 0.02) + 1e-9  # density floor bounds the grading
    # an equidistributed indicator gives the mesh back
    assert np.allclose(equidistribute(b, np.ones(20) * h**6, order=6), b)


def test_transfer_is_exact_for_the_spline_space_and_accurate_otherwise():
    pb = BVProblem(orders=[3, 1], residual=lambda S, z, p: np.stack([z[3], z[5]]),
                   bc=lambda za, zb, p: np.stack([za[0], za[1], za[2], za[4]]), interval=(0.0, 1.0))
    a = Collocation(pb, np.linspace(0, 1, 9), 4)
    b = Collocation(pb, equidistribute(a.breakpoints, np.linspace(1, 50, 8), order=5), 4)
    poly = a.project([lambda S: 1 + S - 2 * S**3 + S**5, lambda S: np.cos(S)])
    y = b.transfer(poly, a)
    S = np.linspace(0, 1, 301)
    for nu in range(4):  # a degree-5 polynomial lives in both spaces (degree k + 3 - 1 = 6)
        assert np.max(np.abs(b.evaluate(y, S, 0, nu) - a.evaluate(poly, S, 0, nu))) < 1e-9 * 10**nu
    assert np.max(np.abs(b.evaluate(y, S, 1) - np.cos(S))) < 1e-6


@pytest.mark.slow
def test_adaptive_trace_goes_further_and_stays_a_rod_solution(tmp_path):
    """Gamma = 1, N = 30: the fixed mesh stops at the accuracy guard (estimated error 1e-6); the
    adaptive mesh goes further past the fold, to the validity guard, and the points it adds satisfy
    the Kirchhoff equations in the Lagrangian coordinate (independent re-integration lands on the
    clamp to 1e-6)."""
    uni = trace(1.0, N=30, adapt=False)
    assert uni.stop_reason.startswith("accuracy guard")
    out = str(tmp_path / "ad.h5")
    ad = trace(1.0, N=30, adapt=True, out=out)
    assert ad.stop_reason.startswith("validity guard")
    assert ad.folds[0]["phi_L"] == pytest.approx(uni.folds[0]["phi_L"], abs=1e-10)  # before any remesh
    s_uni, s_ad = uni.table["stretch"][-1], ad.table["stretch"][-1]
    assert s_ad > s_uni + 0.1
    d = rodcont.load_branch(out)
    meshes = {d.branch["breakpoints"][i].tobytes() for i in range(len(d))}
    assert len(meshes) >= 3
    beyond = [i for i in range(len(d)) if d.branch["stretch"][i] > s_uni]
    assert len(beyond) >= 3
    for i in beyond[::2] + [beyond[-1]]:
        sysm = point_system(d, i)
        x, ph = d.point(i)["x"], d.branch["phi_L"][i]
        # a solution of the discrete equations to the tolerance: Newton there moves it by rounding only
        # (its residual can read 1e-7 where the loop makes the equations stiff)
        exact = sysm.disc.newton(x, sysm.params(ph), tol=1e-12).x
        assert np.max(np.abs(exact - x)) < 1e-8 * (1 + np.max(np.abs(x)))
        assert max(clamp_miss(rodcont.Equilibrium(sysm.outputs(x, ph), x, sysm, None))) < 1e-6, i
    # a restart from an adapted point uses that point's mesh
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src"), OPENBLAS_NUM_THREADS="1")
    i = beyond[0]
    r = subprocess.run([sys.executable, os.path.join(ROOT, "cli.py"), "trace", "--start", f"{out}:{i}",
                        "--max-steps", "3", "--out", str(tmp_path / "re.h5"), "--quiet"],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    re = rodcont.load_branch(str(tmp_path / "re.h5"))
    assert re.branch["phi_L"][0] == pytest.approx(d.branch["phi_L"][i], abs=1e-9)
    assert np.array_equal(re.point(0)["breakpoints"], d.point(i)["breakpoints"])


def test_the_error_estimate_factorises_its_bordered_system_in_a_fill_reducing_order(monkeypatch):
    """In natural column order the estimate's bordered system of a heavy rod pressed on a stiff wall (rows
    of J up to 2.5e12; benchmarks/chen_cheatham.py at 21 035 unknowns) filled 146 times J's nonzeros, about
    2 GB and 5-10 s per estimate, and the trace's resident memory peaked at 7.7 GB; COLAMD filled twice J's
    in 0.27 s for the same estimate to the last digit. Checked here on a rod in a pipe: the estimate asks for
    COLAMD, and gives what the natural order gives."""
    import rodcont.linalg as la
    from rodcont.contact import Wall
    from rodcont.mesh import ErrorEstimator
    from rodcont.rod import RodParameters
    b = trace(rod=RodParameters(), T=10.0, wall=Wall(0.01, eps=1e-4), phi_max=12.0, N=20, adapt=False,
              max_error=1.0)
    from rodcont.system import RodSystem
    s = RodSystem(b.rod, T=10.0, breakpoints=b.meshes[-1], wall=Wall(0.01, eps=1e-4))
    x, phi, t = b.coefficients[-1], float(b.column("phi_L")[-1]), b.tangents[-1]
    orders = []
    original = la.LU.__init__

    def spy(self, A, ordering="NATURAL"):
        orders.append(ordering)
        original(self, A, ordering)

    monkeypatch.setattr(la.LU, "__init__", spy)
    est = ErrorEstimator(s)
    e_colamd = est.estimate(x, phi, (t[:-1], t[-1]))
    assert orders == ["COLAMD"]
    monkeypatch.setattr(la.LU, "__init__", lambda self, A, ordering="NATURAL": original(self, A, "NATURAL"))
    e_natural = est.estimate(x, phi, (t[:-1], t[-1]))
    assert 0 < e_colamd < 1e-3 and e_colamd == pytest.approx(e_natural, rel=1e-6)
