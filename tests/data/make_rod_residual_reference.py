"""Regenerate ``tests/data/rod_residual_reference.npz``: the rod's residual as the code wrote it before the
loads and end conditions became objects (commit 0ee0293, weight and wall written into each residual).

Usage, from the repository root, with the code of that commit first on the path (any later code gives the
file it is checked against, which proves nothing)::

    PYTHONPATH=/path/to/0ee0293/src python tests/data/make_rod_residual_reference.py

For each case of :func:`cases` (straight and curved references, with and without a wall, a tapered wall, a
well with joins): the pointwise residual at random jets, and on a small mesh the discrete residual, the
Jacobian times a random vector and the derivatives in ``phi_L, T, w`` at a random unknown vector.
``tests/test_rod.py::test_the_residual_is_the_one_before_loads_became_objects`` recomputes them.
"""

import os

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "rod_residual_reference.npz")


def cases():
    """``name -> (model factory, jet scale)``; every factory uses the API both versions share."""
    from rodcont.contact import Wall
    from rodcont.curves import parse_reference
    from rodcont.rod import EulerianRod, RodParameters

    def well():
        path = os.path.join(ROOT, "examples", "well_build_and_hold.csv")
        curve = parse_reference(f"well:{path}", 973.077121578337)
        rod = RodParameters(EI=1.25e6, GJ=9.6e5, EA=7.15e8, w=235.0, L=curve.span)
        return EulerianRod(rod, curve, Wall(0.05))

    return {
        "straight": (lambda: EulerianRod(RodParameters()), 0.3),
        "straight_tilted_weight": (lambda: EulerianRod(RodParameters(weight_direction=(0.3, -0.5, -1.0),
                                                                     EA=37.0)), 0.3),
        "straight_wall": (lambda: EulerianRod(RodParameters(), wall=Wall(0.01, eps=1e-4)), 0.01),
        "straight_taper": (lambda: EulerianRod(RodParameters(), wall=Wall(((0.0, 0.002), (1.0, 0.004)))), 0.003),
        "arc": (lambda: EulerianRod(RodParameters(), parse_reference("arc:0.6", 1.0)), 0.3),
        "helix_wall": (lambda: EulerianRod(RodParameters(), parse_reference("helix:0.05,1", 1.0),
                                           Wall(0.01, force_scale=7.0)), 0.01),
        "well_wall": (well, 0.05),
    }


def evaluate(model, scale, seed):
    """The reference quantities of one model at jets and unknowns drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    a, b = model.interval
    npts = 40
    S = rng.uniform(a, b, npts)
    z = rng.uniform(-scale, scale, (17, npts))
    z[[11, 13, 15]] = rng.uniform(-30, 30, (3, npts)) * max(1.0, model.rod.w * model.rod.L / 10)
    z[[12, 14, 16]] = rng.uniform(-10, 10, (3, npts)) * max(1.0, model.rod.w / 10)
    p = model.params(rng.uniform(-5, 5), T=rng.uniform(1, 20) * max(1.0, model.rod.w * model.rod.L / 10))
    disc = model.discretise(6, 3)
    x = rng.standard_normal(disc.size) * scale
    v = rng.standard_normal(disc.size)
    F, J, Fp = disc.linearise(x, p, [0, 1, 2])
    return dict(G=model.residual(S, z, p), F=disc.residual(x, p), Fl=F, Jv=J @ v, Fp=np.array(Fp))


def main():
    out = {}
    for i, (name, (make, scale)) in enumerate(cases().items()):
        with np.errstate(all="ignore"):
            for key, val in evaluate(make(), scale, seed=100 + i).items():
                out[f"{name}/{key}"] = val
    np.savez_compressed(OUT, **out)
    print(f"wrote {OUT}: {len(out)} arrays")


if __name__ == "__main__":
    main()
