"""welleng 0.30's soft-string model against the independent reference (evidence, not a test).

    python benchmarks/welleng_compare.py [--skip-welleng]

Prints, with the reference of tests/softstring_reference.py (no rodcont code):

A. The build-and-hold well of examples/ with the README's string (1 km drill pipe, w = 235 N/m, contact
   radius 0.0635 m, mu = 0.25, no buoyancy): welleng on the survey stations and resampled every 30, 10 and
   1 m, against the reference with the cable equation's sign and with welleng's sign of the weight's
   normal component.  Hook loads pick-up / slack-off / rotating, drags, rotating torque.
B. The same with 100 kN at the bit (welleng's ``overpull``, its pick-up column only): the issue's
   "drag of 48 kN" is pick-up minus rotating with 100 kN at the bit, in welleng's sign.
C. The wall force per length in the middle of the build (MD 450), term by term.
D. The 3.5 km benchmark survey with the 3-section string: welleng's torque with several sections
   (its radius array in the wrong order) and after reordering it.
E. The benchmark table (hook loads and surface torque at 1000 ... 3500 m), the soft-string
   broomstick's run time (3 operations x 100 depths x 3 friction factors), buckling and lock-up
   estimates of 5" drill pipe in 8.5" hole.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
import softstring_reference as ss

BUILD_HOLD = os.path.join(HERE, "..", "examples", "well_build_and_hold.csv")
S3D = "/work/shared/data/well_s3d.csv"
W, R, MU = 235.0, 0.0635, 0.25


def kn(x):
    return f"{x / 1e3:10.3f}"


def reference_row(sv, bit_force, sign):
    string = [ss.Section(None, W, R)]
    p = [ss.soft_string(sv, string, 1000, op, MU, step=1, weight_normal_sign=sign)
         for op in (ss.pick_up(bit_force), ss.slack_off(bit_force), ss.rotating(bit_force))]
    return [q.hook_load for q in p] + [p[2].surface_torque]


def part_a(md, inc, azi, sv, with_welleng):
    print("A. build-and-hold, 1 km, w = 235 N/m, r = 0.0635 m, mu = 0.25, nothing at the bit (kN, N m)")
    print(f"{'model':34s}{'pick-up':>10s}{'slack-off':>10s}{'rotating':>10s}{'PU-ROT':>10s}{'ROT-SO':>10s}"
          f"{'torque':>10s}")
    rows = []
    if with_welleng:
        for spacing in (None, 30.0, 10.0, 1.0):
            td = ss.welleng_model(md, inc, azi, 1000.0, [(None, W, 2 * R)], MU, spacing=spacing)
            rows.append((f"welleng, {'stations' if spacing is None else f'every {spacing:g} m'}",
                         [td.tension[k][0] for k in ("pickup", "slackoff", "rotating")]
                         + [td.torque["rotating"][0]]))
    rows.append(("reference, cable equation (+1)", reference_row(sv, 0.0, 1.0)))
    rows.append(("reference, welleng's sign (-1)", reference_row(sv, 0.0, -1.0)))
    for name, (pu, so, ro, tq) in rows:
        print(f"{name:34s}{kn(pu)}{kn(so)}{kn(ro)}{kn(pu - ro)}{kn(ro - so)}{tq:10.1f}")
    return rows


def part_b(md, inc, azi, sv, with_welleng):
    print("\nB. 100 kN tension at the bit (pick-up), rotating hook load with 100 kN at the bit")
    ro = ss.soft_string(sv, [ss.Section(None, W, R)], 1000, ss.rotating(1e5), MU, step=1)
    for sign, name in ((1.0, "cable equation"), (-1.0, "welleng's sign")):
        pu = ss.soft_string(sv, [ss.Section(None, W, R)], 1000, ss.pick_up(1e5), MU, step=1,
                            weight_normal_sign=sign)
        drag = pu.hook_load - ro.hook_load
        print(f"  reference, {name:15s} pick-up {kn(pu.hook_load)} kN   drag PU-ROT {kn(drag)} kN")
    if with_welleng:
        td = ss.welleng_model(md, inc, azi, 1000.0, [(None, W, 2 * R)], MU, spacing=1.0, overpull=1e5)
        op, rot = td.tension["overpull"][0], td.tension["rotating"][0]
        print(f"  welleng every 1 m, overpull    pick-up {kn(op)} kN   drag PU-ROT-100 kN {kn(op - rot - 1e5)} kN"
              " (its rotating column starts from 0 at the bit)")


def part_c(sv):
    print("\nC. wall force per length at MD 450 (build 3 deg/30 m, I = 15 deg), pick-up, nothing at the bit")
    for sign, name in ((1.0, "cable"), (-1.0, "welleng's sign")):
        p = ss.soft_string(sv, [ss.Section(None, W, R)], 1000, ss.pick_up(), MU, step=1, weight_normal_sign=sign)
        k = int(np.argmin(abs(p.md - 450)))
        inc, dinc, *_ = sv.inclination_rates(p.md[k])
        F = p.axial_force[k]
        print(f"  {name:15s} F = {F / 1e3:8.3f} kN  F kappa = {F * dinc[0]:7.2f}  w sin I = {W * math.sin(inc[0]):6.2f}"
              f"  |N| = {p.normal_force[k]:7.2f} N/m  (F kappa {'-' if sign > 0 else '+'} w sin I)")
    print("  force balance: tension pulls to the high side of a build, weight to the low side: they subtract")


def part_d(with_welleng):
    if not with_welleng or not os.path.exists(S3D):
        return
    print("\nD. well_s3d, 3-section string, mud 1.2 SG, mu = 0.25, resampled every 1 m: rotating torque (N m)")
    d = np.loadtxt(S3D, delimiter=",", comments="#")
    sv = ss.Survey(d[:, 0], d[:, 1], d[:, 2])
    secs = [(200, 2189.0, 0.2032), (150, 624.0, 0.127), (None, 285.0, 0.127)]
    print(f"{'bit MD':>8s}{'welleng':>12s}{'welleng, radius':>17s}{'reference -1':>14s}{'reference +1':>14s}"
          f"{'PU welleng':>12s}{'PU ref -1':>12s}")
    for depth in (2000.0, 3500.0):
        raw = ss.welleng_model(d[:, 0], d[:, 1], d[:, 2], depth, secs, MU, mud_sg=1.2, spacing=1.0)
        fix = ss.welleng_model(d[:, 0], d[:, 1], d[:, 2], depth, secs, MU, mud_sg=1.2, spacing=1.0, fix_radius=True)
        ref = {g: (ss.soft_string(sv, ss.benchmark_string(), depth, ss.rotating(), MU, weight_normal_sign=g),
                   ss.soft_string(sv, ss.benchmark_string(), depth, ss.pick_up(), MU, weight_normal_sign=g))
               for g in (1.0, -1.0)}
        print(f"{depth:8.0f}{raw.torque['rotating'][0]:12.1f}{fix.torque['rotating'][0]:17.1f}"
              f"{ref[-1.0][0].surface_torque:14.1f}{ref[1.0][0].surface_torque:14.1f}"
              f"{raw.tension['pickup'][0] / 1e3:12.2f}{ref[-1.0][1].hook_load / 1e3:12.2f}")
    print("  welleng zips the bit-to-surface intervals with its radius array in surface-to-bit order")


def part_e():
    if not os.path.exists(S3D):
        return
    print("\nE. well_s3d, benchmark_string(), mu = 0.25, off bottom: hook loads (kN), surface torque (N m)")
    sv = ss.Survey.from_csv(S3D)
    string = ss.benchmark_string()
    print(f"{'bit MD':>8s}{'pick-up':>10s}{'slack-off':>10s}{'rotating':>10s}{'torque':>10s}")
    for depth in (1000, 2000, 3000, 3500):
        hl, tq = ss.hook_loads(sv, string, depth, [(op, MU) for op in ss.STANDARD_OPERATIONS])
        print(f"{depth:8d}{kn(hl[0])}{kn(hl[1])}{kn(hl[2])}{tq[2]:10.1f}")
    depths = np.linspace(35.0, 3500.0, 100)
    t0 = time.perf_counter()
    ss.broomstick(sv, string, depths, (0.15, 0.25, 0.35))
    print(f"soft-string broomstick, 3 operations x 100 depths x 3 friction factors: "
          f"{time.perf_counter() - t0:.2f} s (one process, step 10 m)")
    EI, w = ss.DRILL_PIPE_5IN["EI"], ss.DRILL_PIPE_5IN["w_air"] * ss.buoyancy_factor(1200)
    rc = (ss.HOLE_8_5IN - ss.DRILL_PIPE_5IN["od"]) / 2
    print(f"\n5in drill pipe in 8.5in hole (EI {EI:.3g}, w {w:.1f} N/m, r_c {rc:.5f} m), horizontal:")
    print(f"  Dawson-Paslay sinusoidal {ss.sinusoidal_buckling_load(EI, w, 90, rc) / 1e3:.1f} kN, helical: "
          f"Chen {ss.helical_buckling_load(EI, w, 90, rc) / 1e3:.1f} kN, "
          f"Wu {ss.helical_buckling_load(EI, w, 90, rc, 'wu') / 1e3:.1f} kN")
    for mu in (0.15, 0.25, 0.35):
        print(f"  mu {mu}: lock-up length (no WOB) {ss.lockup_length(EI, w, rc, mu):7.0f} m, "
              f"with 50 kN WOB {ss.lockup_length(EI, w, rc, mu, 5e4):7.0f} m; "
              f"most force delivered through 2000 m {ss.max_transmitted_force(EI, w, rc, mu, 2000) / 1e3:.1f} kN")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-welleng", action="store_true")
    args = ap.parse_args()
    with_welleng = not args.skip_welleng
    if with_welleng:
        try:
            import welleng  # noqa: F401
        except ImportError:
            print("welleng not installed: reference only")
            with_welleng = False
    md, inc, azi = np.loadtxt(BUILD_HOLD, delimiter=",", comments="#").T
    sv = ss.Survey(md, inc, azi)
    part_a(md, inc, azi, sv, with_welleng)
    part_b(md, inc, azi, sv, with_welleng)
    part_c(sv)
    part_d(with_welleng)
    part_e()


if __name__ == "__main__":
    main()
