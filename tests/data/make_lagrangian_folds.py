"""Regenerate ``tests/data/lagrangian_folds.json`` from the Lagrangian reference.

Usage (from the repository root; ~15-18 minutes with 2 worker processes)::

    python tests/data/make_lagrangian_folds.py [--procs 2]

Everything comes from ``tests/lagrangian_reference.py`` (independent of
``src/``; numpy and scipy only), paper values ``w = 10, EI = 1, GJ = 0.75,
EA = 255, L = 1``:

* ``critical_twists``: the first 5 critical twists of the straight weightless
  rod (closed form of :func:`lagrangian_reference.critical_condition`), each
  with the two smallest singular values of the 6x6 shooting Jacobian at that
  straight state (a double zero, independent confirmation of the root).
* ``primary_folds``: first fold of the branch from ``Phi = 0``
  (:func:`primary_fold`) for Gamma in {0, 0.5, 1, 2, 5, 10}.
* ``secondary_folds``: first fold (maximum of Phi) of the branch seeded
  between critical twists ``n`` and ``n + 1`` (:func:`secondary_fold`), for
  Gamma in {0.5, 1, 2, 5} and n = 1, 2, 3; when the rod reaches
  ``min d3 . e1 = 0`` before the fold the entry has ``status = "left_domain"``
  with the exit point, plus the fold found by continuing outside the domain.

Accuracy of each entry:

* ``accuracy``: absolute change of every field when the DOP853 tolerance
  goes from ``rtol = 1e-12`` (stored values) to ``1e-10`` (an upper bound of
  the integration error of the stored values, which is ~100 times smaller);
* ``route_check``: absolute change with a second route to the same point
  (primary: :func:`twisted_branch_fold`, stretch as the fold parameter and
  its own continuation; secondary: seed at a quarter instead of half of the
  interval between the critical twists);
* ``collocation_dphi``: ``Phi`` of the collocation re-solution
  (:func:`twisted_bvp`, ``solve_bvp`` tol 1e-9, stretch prescribed) minus the
  stored ``phi_L``.
"""

import argparse
import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from multiprocessing import Pool  # noqa: E402

import numpy as np  # noqa: E402

import lagrangian_reference as lag  # noqa: E402

PAPER = dict(w=10., EI=1., GJ=0.75, EA=255., L=1.)
PRIMARY_GAMMAS = [0.0, 0.5, 1.0, 2.0, 5.0, 10.0]
CRITICAL_GAMMAS = PRIMARY_GAMMAS
SECONDARY_GAMMAS = [0.5, 1.0, 2.0, 5.0]
SECONDARY_N = [1, 2, 3]
FIELDS = ["phi_L", "stretch", "torque", "l0", "min_d3_e1", "slope_turns"]
OUT = os.path.join(HERE, "lagrangian_folds.json")


def _clean(d):
    """Fields of a result dict that go to JSON (no arrays of the branch)."""
    keep = FIELDS + ["left_domain", "dphi_dsigma", "residual", "x"]
    return {k: d[k] for k in keep if k in d}


def _diff(a, b, fields=FIELDS):
    return {k: abs(a[k] - b[k]) for k in fields if k in a and k in b}


def _collocation(gamma, res):
    """Phi of the solve_bvp re-solution at the stored stretch, minus phi_L."""
    try:
        r = lag.twisted_bvp(gamma, np.array(res["x"][:7]), stretch=res["stretch"], tol=1e-9)
        return r["phi_L"] - res["phi_L"]
    except Exception as e:                            # recorded, not fatal
        return "failed: %r" % (e,)


def task(job):
    """One unit of work (run in a worker process)."""
    kind, gamma, n, variant = job
    t0 = time.time()
    if kind == "primary":
        if variant == "main":
            r = lag.primary_fold(gamma, rtol=1e-12)
            out = _clean(r)
            out["collocation_dphi"] = _collocation(gamma, out)
            out["branch_steps"] = r["branch_steps"]
        elif variant == "rtol":
            out = _clean(lag.primary_fold(gamma, rtol=1e-10))
        else:                                         # second route
            r = lag.twisted_branch_fold(gamma, rtol=1e-12)
            out = {k: r[k] for k in ["phi_L", "stretch", "torque", "l0", "min_d3_e1"]}
    else:
        if variant == "main":
            r = lag.secondary_fold(gamma, n, rtol=1e-12)
            out = _clean(r)
            out["seed"] = r["seed"]
            out["critical"] = r["critical"]
            out["weight_steps"] = r["weight_steps"]
            out["branch_steps"] = r["branch_steps"]
            out["collocation_dphi"] = _collocation(gamma, out)
            if r["left_domain"]:                      # follow on to the fold outside
                r2 = lag.secondary_fold(gamma, n, rtol=1e-12, stop_at_exit=False)
                out["fold_outside_domain"] = _clean(r2)
        elif variant == "rtol":
            r = lag.secondary_fold(gamma, n, rtol=1e-10)
            out = _clean(r)
            out["seed"] = r["seed"]
        else:
            out = _clean(lag.secondary_fold(gamma, n, rtol=1e-12, seed_fraction=0.25))
    out["seconds"] = time.time() - t0
    return job, out


def critical_entry(gamma):
    """Critical twists and the shooting-Jacobian confirmation."""
    c = lag.critical_twists(gamma, 5, **PAPER)
    par = (PAPER["EI"], PAPER["GJ"], PAPER["EA"], PAPER["L"])
    sv = []
    for phi in c["phi_L"]:
        x = lag.straight_weightless_state(gamma, phi, w=PAPER["w"], GJ=PAPER["GJ"],
                                          EA=PAPER["EA"], L=PAPER["L"])
        _, J, _ = lag._shoot_ext(x, gamma * PAPER["w"] * PAPER["L"], par, 1e-12)
        s = np.linalg.svd(J[:6, :6], compute_uv=False)
        sv.append([float(s[-1]), float(s[-2]), float(s[-3])])
    return dict(gamma=gamma, phi_L=c["phi_L"].tolist(), torque=c["torque"].tolist(),
                tau=c["tau"], shooting_singular_values=sv,
                accuracy=("roots of the closed form to 1e-15 in a (Brent); the three "
                          "smallest singular values of the 6x6 shooting Jacobian at each "
                          "root show the double zero (~1e-14 against ~1e-2 for the third)"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--procs", type=int, default=2)
    args = ap.parse_args()
    t0 = time.time()
    jobs = [("primary", g, None, v) for g in PRIMARY_GAMMAS for v in ("main", "rtol", "route")]
    jobs += [("secondary", g, n, v) for g in SECONDARY_GAMMAS for n in SECONDARY_N
             for v in ("main", "rtol", "route")]
    jobs.sort(key=lambda j: (j[0] == "primary", j[1]), reverse=True)   # long ones first
    results = {}
    with Pool(args.procs) as pool:
        for job, out in pool.imap_unordered(task, jobs):
            results[job] = out
            print("%-9s gamma=%-4g n=%-4s %-5s %6.1f s  phi_L=%.10f %s" % (
                job[0], job[1], job[2], job[3], out["seconds"], out["phi_L"],
                "(left domain)" if out.get("left_domain") else ""), flush=True)

    primary = []
    for g in PRIMARY_GAMMAS:
        e = dict(gamma=g, status="left_domain" if results[("primary", g, None, "main")]
                 ["left_domain"] else "fold")
        e.update(results[("primary", g, None, "main")])
        e["accuracy"] = _diff(e, results[("primary", g, None, "rtol")])
        e["route_check"] = _diff(e, results[("primary", g, None, "route")])
        primary.append(e)
    secondary = []
    for g in SECONDARY_GAMMAS:
        for n in SECONDARY_N:
            m = results[("secondary", g, n, "main")]
            e = dict(gamma=g, n=n, status="left_domain" if m["left_domain"] else "fold")
            e.update(m)
            rt = results[("secondary", g, n, "rtol")]
            e["accuracy"] = _diff(e, rt)
            e["seed"]["accuracy"] = _diff(e["seed"], rt["seed"])
            e["route_check"] = _diff(e, results[("secondary", g, n, "route")])
            secondary.append(e)
    for lst in (primary, secondary):
        for e in lst:
            e.pop("seconds", None)

    data = dict(
        description=("Folds of the twisted heavy clamped-clamped extensible rod from the "
                     "independent Lagrangian reference tests/lagrangian_reference.py "
                     "(shooting, DOP853 rtol 1e-12, pseudo-arclength, folds located by "
                     "Brent on dPhi/dsigma to 1e-13). Regenerate with "
                     "tests/data/make_lagrangian_folds.py."),
        parameters=PAPER,
        fields=dict(
            phi_L="end rotation Phi (rad, continuous)",
            stretch="(l - L)/L",
            torque="M . d3 (constant)",
            l0="unstressed length",
            min_d3_e1="min over s of d3 . e1",
            slope_turns=("turns of zeta = d3.e2 + i d3.e3 along the rod, "
                         "(arg zeta(l0-) - arg zeta(0+))/(2 pi)"),
            x="shooting unknowns (F2, F3, M1, M2, M3, l0, Phi, w) at s = 0, global "
              "components, F1 = T = Gamma w L, start clamp d1 = e2, d2 = e3, d3 = e1",
            status="'fold' or 'left_domain' (min d3.e1 reached 0 before the first fold; "
                   "fields are then those of the exit point, and fold_outside_domain "
                   "gives the fold found by continuing outside the domain)",
            accuracy="|change| of each field for rtol 1e-12 -> 1e-10",
            route_check="|change| with a second route to the same point",
            collocation_dphi="solve_bvp re-solution Phi at the stored stretch minus phi_L"),
        critical_twists=[critical_entry(g) for g in CRITICAL_GAMMAS],
        primary_folds=primary,
        secondary_folds=secondary,
        seconds_to_generate=time.time() - t0,
        processes=args.procs,
    )
    with open(OUT, "w") as f:
        json.dump(data, f, indent=1)
    print("wrote %s in %.0f s" % (OUT, time.time() - t0))


if __name__ == "__main__":
    main()
