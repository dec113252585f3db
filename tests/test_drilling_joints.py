"""The wall's force over a stretch of the string (rodcont.drilling.collocated_integral, the side force per joint)
at a point contact, against the exact contact problem solved independently (tests/contact_reference.py: Lagrangian
shooting of the free spans glued to the wall)."""

import numpy as np
import pytest

import rodcont
from contact_reference import heavy_rod_on_flat_wall
from rodcont.contact import Wall
from rodcont.drilling import collocated_integral
from rodcont.rod import RodParameters
from rodcont.system import RodSystem

C = 0.012   # the Gamma = 1 rod in a straight pipe touches it at midspan only (0.00744 < c < 0.0195)


@pytest.fixture(scope="module")
def point_contact():
    """The heavy clamped rod (Gamma = 1, Phi = 0) sagging onto the floor of a straight pipe at one point, the
    law's smoothing eps = 1e-6 (a zone a few micrometres wide, narrower than its mesh interval)."""
    wall = Wall(C, eps=1e-6, force_scale=10.0)
    b = rodcont.trace(1.0, wall=wall, phi_max=1e-3)
    sysm = RodSystem(RodParameters(), gamma=1.0, breakpoints=b.meshes[0], wall=wall)
    return sysm, b.coefficients[0], sysm.params(0.0)


def _sampled_law(sysm, x, p, n=16):
    """The law integrated on the spline by Gauss-Legendre with ``n`` points per mesh interval (the rule before)."""
    b = sysm.disc.breakpoints
    g, wg = np.polynomial.legendre.leggauss(n)
    mid, half = 0.5 * (b[1:] + b[:-1]), 0.5 * np.diff(b)
    S = (mid[:, None] + half[:, None] * g[None, :]).ravel()
    return float(np.sum(half * (sysm.model.contact(sysm.disc, x, p, S=S)["pressure"].reshape(mid.size, n) @ wg)))


def test_a_point_contacts_force_is_the_exact_reaction(point_contact):
    """The midspan point contact: the wall's force over the rod, integrated as the collocation equations carry
    it, is the shooting solution's reaction for the wall where the smoothed rod reaches it (clearance c plus the
    rod's penetration) to 1e-5 (measured 1.2e-6), and the reaction for the clearance c to 2e-4 (measured 7.1e-5,
    the penetration's share); the law sampled on the spline by 16 Gauss points per interval misreads the narrow
    peak by more than 1e-3 (measured 3.5e-3 low; a trapezoid rule on 16 points per interval 3.3e-3)."""
    sysm, x, p = point_contact
    whole = collocated_integral(sysm, x, p, [0.0, 1.0])[0]
    near = np.linspace(0.49, 0.51, 20001)
    penetration = -sysm.model.contact(sysm.disc, x, p, S=near)["gap"].min()
    assert 0 < penetration < 1e-3 * C
    exact = heavy_rod_on_flat_wall(C + penetration, 10.0)
    assert exact["regime"] == "point"
    assert whole == pytest.approx(exact["total_side_force"], rel=1e-5)
    assert whole == pytest.approx(heavy_rod_on_flat_wall(C, 10.0)["total_side_force"], rel=2e-4)
    assert abs(_sampled_law(sysm, x, p) / exact["total_side_force"] - 1) > 1e-3


def test_the_pieces_tile_the_collocation_rule(point_contact):
    """Over any cut of the rod the pieces sum to the Gauss rule of the collocation points (the load the discrete
    force balance carries) to 1e-12; the cut around midspan carries all but the law's small force off the wall,
    and a cut inside one mesh interval splits it, each piece non-negative."""
    sysm, x, p = point_contact
    rule = float(sysm.model.contact(sysm.disc, x, p, S=sysm.disc.S)["pressure"] @ sysm.disc.weights)
    edges = [0.0, 0.3, 0.5, 0.50001, 0.77, 1.0]
    parts = collocated_integral(sysm, x, p, edges)
    assert parts.size == 5 and np.all(parts >= 0)
    assert parts.sum() == pytest.approx(rule, rel=1e-12)
    assert parts[1] + parts[2] + parts[3] > 0.999 * rule
    assert parts[0] == pytest.approx(collocated_integral(sysm, x, p, [0.0, 0.1, 0.3]).sum(), rel=1e-12)


def test_the_total_side_force_and_its_zones_are_the_collocation_rules(point_contact):
    """The total side force a solve prints, a file stores and the adaptive mesh watches (rod.contact's
    ``side_force``) is the collocation rule's, whatever the sample points: at the midspan point contact the
    shooting solution's reaction to 1e-5 (the trapezoid rule on 16 samples per interval it was before: 3.3e-3
    low), the rule over the whole span to 1e-12; the one zone's force is all of it."""
    sysm, x, p = point_contact
    c = sysm.model.contact(sysm.disc, x, p)
    near = np.linspace(0.49, 0.51, 20001)
    at_near = sysm.model.contact(sysm.disc, x, p, S=near)
    exact = heavy_rod_on_flat_wall(C - at_near["gap"].min(), 10.0)["total_side_force"]
    assert c["side_force"] == pytest.approx(exact, rel=1e-5)
    assert c["side_force"] == pytest.approx(collocated_integral(sysm, x, p, [0.0, 1.0])[0], rel=1e-12)
    assert at_near["side_force"] == c["side_force"]
    assert len(c["zones"]) == 1 and c["zones"][0][2] == pytest.approx(c["side_force"], rel=1e-12)


def test_a_collars_contact_on_its_joint_is_the_refined_meshs():
    """Slack-off with the bit at 300 m in the short build-and-hold well (tests/test_drilling_export.py's: a 50 m
    collar under drill pipe): the joint from 281.72 to 290.86 m carries a contact zone under a metre wide on an
    adapted mesh of about 200 intervals. Its side force (rodcont.drilling.joint_side_forces) equals, to 1e-3
    (measured 1e-4), the same joint's on the solution with the mesh halved three times (8 times as many
    intervals, Newton from the transferred solution), as does the sum over the joints (1e-4, measured 1.2e-5); the
    law sampled on the spline by 16 Gauss points per piece was 10.8 % off on that joint at the adapted mesh and
    1.6 % on the sum. The joints sum to the total side force (1e-12), as its rule is theirs."""
    from rodcont.drilling import DrillString, Well, joint_edges, joint_side_forces, torque_and_drag
    from test_drilling_export import COLLAR, HOLE, PIPE, STATIONS
    td = torque_and_drag(Well(STATIONS, hole_diameter=HOLE, friction=0.25), DrillString((COLLAR, PIPE), 0.847),
                         300.0, "slack-off")
    j = joint_side_forces(td)
    edges = joint_edges(300.0)
    k = int(np.searchsorted(edges, 285.0)) - 1
    assert (j["top"][k], j["bottom"][k]) == pytest.approx((281.72, 290.86))
    sysm, x = td.system, td.x
    for _ in range(3):
        b = sysm.disc.breakpoints
        fine = sysm.with_mesh(sysm.conform(np.sort(np.concatenate([b, 0.5 * (b[1:] + b[:-1])]))))
        r = fine.disc.newton(fine.disc.transfer(x, sysm.disc), fine.base, tol=1e-10)
        assert r.converged
        sysm, x = fine, r.x
    ref = collocated_integral(sysm, x, sysm.base, edges)
    assert j["side_force"][k] > 0.1 * j["side_force"].max()
    assert j["side_force"][k] == pytest.approx(ref[k], rel=1e-3)
    assert j["side_force"].sum() == pytest.approx(ref.sum(), rel=1e-4)
    assert j["side_force"].sum() == pytest.approx(td.side_force, rel=1e-12)   # the joints tile the total


def test_a_zones_force_takes_in_the_light_contact_around_it():
    # the README's figures: at 1000 m rotating, the collars' top presses on 4 mm at 800 m (their clearance step);
    # its zone reaches half-way to the zones beside it and carries the collars lying on the low side below
    import os

    from rodcont import drilling
    examples = os.path.join(os.path.dirname(__file__), "..", "examples")
    well = drilling.Well.from_toml(os.path.join(examples, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(examples, "drill_string.toml"))
    td = drilling.torque_and_drag(well, string, 1000.0, "rotate", mu=0.25)
    zone = next(z for z in td.zones if abs(z[0] - 800.0) < 1e-6)
    assert zone[1] - zone[0] < 0.005 and round(zone[2] / 1e3, 1) == 179.6
    b = td.system.disc.breakpoints
    i = int(np.searchsorted(b, 800.0))
    assert b[i] == pytest.approx(800.0, abs=1e-9) and b[i + 1] > zone[1]   # the 4 mm lie in one interval
    own = collocated_integral(td.system, td.x, td.params, b[i:i + 2])[0]
    assert round(own / 1e3, 1) == 3.2
    assert sum(z[2] for z in td.zones) == pytest.approx(td.side_force, rel=1e-12)   # the zones tile the span
    # past that contact the torque profile rises toward the bit between collocation points (the spline whose
    # derivative interpolates mu r p at the Gauss points): the README's 8.4 N m, 1.1e-3 of the surface torque
    M, S = td.profile["torque"], td.profile["S"]
    rise, run, where = 0.0, 0.0, None
    for k, step in enumerate(np.diff(M) * np.sign(M[0] - M[-1])):
        run = run + step if step > 0 else 0.0
        if run > rise:
            rise, where = run, S[k + 1]
    assert round(rise, 1) == 8.4 and round(rise / abs(M[0]), 4) == 1.1e-3 and 800.0 < where < 800.05


def test_off_bottom_the_bit_holds_no_force_along_the_hole_not_the_tilted_string():
    # the README's figure: the bit condition puts no force along the hole's axis; the profile's axial force is
    # along the string's own tangent, tilted at the bit, and reads -15.1 N there at 500 m pick-up (3e-5)
    import os

    from rodcont import drilling
    examples = os.path.join(os.path.dirname(__file__), "..", "examples")
    well = drilling.Well.from_toml(os.path.join(examples, "well_s3d.toml"))
    string = drilling.DrillString.from_toml(os.path.join(examples, "drill_string.toml"))
    td = drilling.torque_and_drag(well, string, 500.0, "pick-up")
    assert td.profile["S"][-1] == 500.0 and round(float(td.profile["axial_force"][-1]), 1) == -15.1
    assert abs(td.profile["axial_force"][-1]) < 4e-5 * td.hook_load


def test_joint_ends_read_as_the_decimals_of_the_depth_and_the_joint_length():
    # before: 500 - 53 * 9.14 printed as 15.579999999999984 (in max_joint_side_force_md and --joints)
    from rodcont.drilling import joint_edges
    e = joint_edges(500.0)
    assert repr(float(e[2])) == "15.58" and e[0] == 0.0 and e[-1] == 500.0
    assert all(len(repr(float(v)).split(".")[1]) <= 2 for v in e)
    assert np.max(np.abs(e[1:-1] - (500.0 - 9.14 * np.arange(e.size - 2, 0, -1)))) < 1e-9


def test_a_joints_largest_force_per_length_is_located():
    # README: at 505 m (examples/well_s3d.toml, at rest, 10 m joints) the point contact 4 m above the bit peaks at
    # 54.1 kN/m; the profile's grid reads 53.3 kN/m there and the 16 Gauss points per piece 48.1 kN/m (the table's
    # figure before the maximum was located). The located peak against a brute-force search (2e5 points in its
    # joint, 2e4 in the others)
    import os

    from rodcont import drilling
    from rodcont.drilling import _pressure_at
    ex = os.path.join(os.path.dirname(__file__), "..", "examples")
    td = drilling.torque_and_drag(drilling.Well.from_toml(os.path.join(ex, "well_s3d.toml")),
                                  drilling.DrillString.from_toml(os.path.join(ex, "drill_string.toml")), 505.0)
    j = drilling.joint_side_forces(td, 10.0)
    i = int(np.argmax(j["max_pressure"]))
    assert j["max_pressure"][i] == pytest.approx(54.15e3, rel=1e-3)
    assert j["max_pressure"][i] > 1.01 * float(np.max(td.profile["pressure"])) > 1.01 * 53.25e3
    assert j["max_pressure_md"][i] == pytest.approx(500.94, abs=0.01) and j["top"][i] <= 500.94 <= j["bottom"][i]
    for k, (top, bottom, peak, where) in enumerate(zip(j["top"], j["bottom"], j["max_pressure"], j["max_pressure_md"])):
        S = np.linspace(top, bottom, 200001 if k == i else 20001)[1:-1]   # its ends: a clearance step's two sides
        P = _pressure_at(td, S)
        assert top <= where <= bottom and _pressure_at(td, [where])[0] == pytest.approx(peak, rel=1e-12)
        assert P.max() <= peak * (1 + 1e-12), (top, P.max(), peak)   # no point of the joint higher
        if k == i:   # the peak inside the joint: found, not just bounded
            assert P.max() >= peak * (1 - 1e-8)
    cuts = np.union1d(td.system.disc.breakpoints, [j["top"][i], j["bottom"][i]])
    cuts = cuts[(cuts >= j["top"][i]) & (cuts <= j["bottom"][i])]
    g = np.polynomial.legendre.leggauss(16)[0]
    S = (0.5 * (cuts[1:] + cuts[:-1])[:, None] + 0.5 * np.diff(cuts)[:, None] * g[None, :]).ravel()
    gauss = td.system.model.contact(td.system.disc, td.x, td.params, S=S)["pressure"].max()
    assert gauss == pytest.approx(48.09e3, rel=1e-3) and gauss < j["max_pressure"][i]
