"""A user's own boundary value problem (rodcont.bvp, issue 21 item 3), against the closed forms of
tests/bvp_reference.py: the three examples run as scripts, the points of their branches, the
located fold, restarts from files, branch points, the file and the command line, the README."""

import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import bvp_reference as ref
import rodcont
from conftest import assert_picture, run
from rodcont import bvp

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(ROOT, "examples")

BRATU = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                          bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"],
                          names=["u"])
OUTPUTS = {"u_mid": lambda sol: sol.evaluate(0.5, "u"), "slope_at_0": lambda sol: sol.evaluate(0.0, "u", 1)}


def run_example(name: str, cwd) -> dict:
    """Run ``examples/bvp_<name>.py`` as a user does (in ``cwd``); its ``name value`` lines."""
    r = subprocess.run([sys.executable, os.path.join(EXAMPLES, f"bvp_{name}.py")], cwd=cwd, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return dict(line.split(" ", 1) for line in r.stdout.splitlines() if " " in line)


@pytest.fixture(scope="module")
def examples(tmp_path_factory):
    """Each example run once: its printed values and its branch file read back."""
    d = tmp_path_factory.mktemp("examples")
    out = {}
    for name in ("bratu", "troesch", "elastica"):
        out[name] = (run_example(name, d), rodcont.load_branch(str(d / f"{name}.h5")))
    return out


# --------------------------------------------------------------------------
# The examples against the closed forms
# --------------------------------------------------------------------------
def test_bratu_example_fold(examples):
    printed, branch = examples["bratu"]
    fold = ref.bratu_fold()
    assert abs(float(printed["fold_lambda"]) - fold["lam"]) < 1e-9
    assert printed["fold_located"] == "True"
    assert abs(float(printed["fold_slope_at_0"]) - fold["slope"]) < 1e-8   # u'(0) = 4 at the fold
    assert abs(float(printed["fold_u_mid"]) - fold["u_max"]) < 1e-9
    assert printed["status"] == "event"
    # the file says the same: one fold, located, at the printed value
    assert [sp.label for sp in branch.special] == ["start", "F1", "u_mid"]
    assert float(branch.folds["lam"][0]) == float(printed["fold_lambda"])


def test_bratu_branch_points_on_the_closed_form(examples):
    """Every stored point, lower and upper branch: lam at the point's u(1/2) on the closed-form branch."""
    _, branch = examples["bratu"]
    lam, u_mid, slope = (np.asarray(branch.table[c]) for c in ("lam", "u_mid", "slope_at_0"))
    assert u_mid[-1] > 3.99 and np.sum(lam < 3.0) >= 4  # both branches are in it
    inside = lam > 0
    theta = np.array([ref.bratu_theta_from_max(u) for u in u_mid[inside]])
    assert np.max(np.abs(lam[inside] - ref.bratu_lambda(theta))) < 1e-8
    assert np.max(np.abs(slope[inside] - ref.bratu_slope(theta))) < 1e-8
    assert np.all(np.asarray(branch.table["error"]) <= 1e-10)


def test_bratu_fold_accuracy_comes_from_the_refined_mesh():
    """On the example's starting mesh held fixed the fold is more than 1e-9 off; adapted, within 1e-9."""
    lam = ref.bratu_fold()["lam"]
    start = bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1.0)
    fixed = rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), adapt=False, max_error=1.0, ds=0.1, ds_max=0.5,
                                 max_steps=20)
    assert abs(fixed.folds["lam"][0] - lam) > 1e-9
    adapted = rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), max_error=1e-10, fold_error=1e-11, ds=0.1,
                                   ds_max=0.5, max_steps=20)
    assert abs(adapted.folds["lam"][0] - lam) < 1e-9 and adapted.folds["located"][0]
    assert len(adapted.meshes[adapted.folds["index"][0]]) > 5  # the mesh did grow


def test_troesch_example(examples):
    printed, branch = examples["troesch"]
    assert float(printed["lam"]) == 10.0 and printed["status"] == "bound"
    assert abs(float(printed["slope_at_0"]) / ref.troesch_slope(10.0) - 1) < 1e-8
    assert int(printed["N"]) == len(branch.meshes[-1]) - 1
    # the points of the branch
    lam, slope = np.asarray(branch.table["lam"]), np.asarray(branch.table["slope_at_0"])
    assert lam.size >= 5
    assert max(abs(s / ref.troesch_slope(v) - 1) for v, s in zip(lam, slope)) < 1e-8
    # the boundary layer at lam = 10: u and u' against the closed form, and the mesh graded into it
    sol = branch.solution(-1, troesch_problem())
    x = np.array([0.1, 0.5, 0.9, 0.99, 0.999])
    u, du = ref.troesch_solution(x, 10.0)
    assert np.max(np.abs(sol.evaluate(x, "u") - u)) < 1e-8
    assert np.max(np.abs(sol.evaluate(x, "u", 1) / du - 1)) < 1e-7
    h = np.diff(sol.mesh)
    assert h[-1] < h[0] / 10


def troesch_problem():
    return rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] - p[0] * np.sinh(p[0] * z[0]),
                             bc=lambda za, zb, p: np.stack([za[0], zb[0] - 1.0]), interval=(0.0, 1.0),
                             params=["lam"], names=["u"])


def readme_section() -> str:
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    start = text.index("### Your own problem")
    return text[start:text.index("\n## ", start)]


def test_troesch_uniform_mesh_claim(examples):
    """The README's uniform mesh for Troesch at lam = 10: u'(0) to 1e-8 relative with it, not with 10 % fewer."""
    n = int(re.search(r"a uniform mesh needs (\d+) subintervals", readme_section()).group(1))
    _, branch = examples["troesch"]
    adaptive = branch.solution(-1, troesch_problem())

    def error(N):
        sol = bvp.solve(adaptive.problem, {"lam": 10.0}, guess=adaptive, mesh=np.linspace(0, 1, N + 1),
                        max_error=1e30)
        return abs(sol.evaluate(0.0, "u", 1) / ref.troesch_slope(10.0) - 1)

    assert error(n) <= 1e-8 < error(int(0.9 * n))


def test_elastica_example(examples):
    printed, branch = examples["elastica"]
    assert float(printed["delta"]) == 1.0
    assert abs(float(printed["load_at_delta_1"]) - ref.elastica_load(1.0)) < 1e-9
    assert abs(float(printed["theta_0_at_delta_1"]) - ref.elastica_theta0(1.0)) < 1e-9
    assert [sp.label for sp in branch.special] == ["start", "P1", "bound"]
    delta, P, th0 = (np.asarray(branch.table[c]) for c in ("delta", "P", "theta_0"))
    assert delta[-1] == 1.5 and delta.size >= 6
    assert max(abs(p / ref.elastica_load(d) - 1) for d, p in zip(delta, P)) < 1e-10
    assert max(abs(t - ref.elastica_theta0(d)) for d, t in zip(delta, th0)) < 1e-8
    # the shape at delta = 1 (a point of the file, the problem given again)
    sol = branch.solution("P1", elastica_problem())
    s = np.linspace(0, 1, 9)
    assert np.max(np.abs(sol.evaluate(s, "theta") - ref.elastica_theta(s, 1.0)[0])) < 1e-9


def elastica_problem():
    return rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.sin(z[0]),
                             bc=lambda za, zb, p: np.stack([za[1], zb[1]]),
                             integrals=lambda S, z, p: (np.cos(z[0]) - (1.0 - p[1]))[None, :], interval=(0.0, 1.0),
                             params=["P", "delta"], free=[0], names=["theta"])


# --------------------------------------------------------------------------
# Restarts, the file, the result type
# --------------------------------------------------------------------------
def test_restart_from_a_stored_fold(examples):
    """From F1 of the file, back down the lower branch (direction -1) and on up the upper one (+1)."""
    _, branch = examples["bratu"]
    pt = branch.point("F1")
    assert pt["problem"] == "bratu" and pt["params"] == {"lam": pt["lam"]}
    for direction, side in ((-1, "lower"), (1, "upper")):
        r = rodcont.continue_bvp(BRATU, "lam", pt, (3.0, 4.0), direction=direction, outputs=OUTPUTS, max_error=1e-10)
        assert r.status == "bound" and r.table["lam"][-1] == 3.0
        assert abs(r.table["lam"][0] - ref.bratu_fold()["lam"]) < 1e-11  # the start is the fold, re-converged
        u_ref = ref.bratu_max(ref.bratu_theta(3.0, side))
        assert abs(r.table["u_mid"][-1] - u_ref) < 1e-9


def test_restart_from_the_last_point_goes_on(examples):
    _, branch = examples["bratu"]
    r = rodcont.continue_bvp(BRATU, "lam", branch.point(-1), (0.5, 4.0), outputs=OUTPUTS, max_error=1e-10)
    assert r.status == "bound" and r.table["lam"][-1] == 0.5
    assert r.table["u_mid"][-1] > r.table["u_mid"][0] > 3.99  # on up the upper branch, away from the fold
    assert abs(r.table["u_mid"][-1] - ref.bratu_max(ref.bratu_theta(0.5, "upper"))) < 1e-8


def test_restart_of_another_problem_refused(examples):
    _, branch = examples["bratu"]
    with pytest.raises(ValueError, match="params"):
        rodcont.continue_bvp(elastica_problem(), "delta", branch.point(-1), (0.0, 1.0))
    with pytest.raises(ValueError, match="not 'troesch'"):
        rodcont.continue_bvp(BRATU, "lam", branch.point(-1), (0.0, 1.0), name="troesch")


def test_file_reads_back_as_the_result_in_memory(tmp_path):
    """Code written against the result in memory works on the one read from its file."""
    path = str(tmp_path / "b.h5")
    start = bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1e-8, outputs=OUTPUTS, name="bratu")
    mem = rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), max_error=1e-8, ds=0.2, ds_max=0.5, max_steps=15,
                               out=path)
    disk = rodcont.load_branch(path)
    assert type(disk) is type(mem) and disk.status == mem.status and disk.message == mem.message
    assert list(disk.table) == list(mem.table)
    for name in mem.table:
        assert list(disk.table[name]) == list(mem.table[name]), name
    assert [(s.label, s.index, s.value) for s in disk.special] == [(s.label, s.index, s.value) for s in mem.special]
    for label in ("F1", -1):
        a, b = mem.point(label), disk.point(label)
        assert np.array_equal(a["x"], b["x"]) and np.array_equal(a["breakpoints"], b["breakpoints"])
        assert a["params"] == b["params"] and a["k"] == b["k"]
    assert mem.solution("F1").evaluate(0.5) == disk.solution("F1", BRATU).evaluate(0.5)
    with pytest.raises(ValueError, match="give the problem"):
        disk.solution("F1")


def test_file_is_published_as_the_run_goes_and_an_interrupt_keeps_it(tmp_path):
    path = str(tmp_path / "b.h5")
    seen = []

    def callback(pt):
        if str(pt.kind) == "fold":
            seen.append(len(rodcont.load_branch(path).folds))  # published at the fold, complete
        if seen and len(seen) == 1 and str(pt.kind) == "regular":
            seen.append("interrupt")
            raise KeyboardInterrupt

    start = bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1e-8)
    with pytest.raises(KeyboardInterrupt):
        rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), max_error=1e-8, ds=0.2, out=path, callback=callback)
    assert seen == [1, "interrupt"]
    b = rodcont.load_branch(path)
    assert b.status == "interrupted" and b.folds["label"][0] == "F1"
    r = rodcont.continue_bvp(BRATU, "lam", b.point(-1), (1.0, 3.6), max_error=1e-8)  # on along the upper branch
    assert r.status == "bound" and r.table["lam"][-1] == 1.0 and r.table["norm_u"][-1] > r.table["norm_u"][0]


def test_existing_file_and_failed_start(tmp_path):
    path = tmp_path / "b.h5"
    path.write_bytes(b"mine")
    start = bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1e-8)
    with pytest.raises(rodcont.BranchFileError, match="exists"):
        rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), out=str(path))
    assert path.read_bytes() == b"mine"
    other = tmp_path / "c.h5"
    with pytest.raises(ValueError, match="outside the bounds"):
        rodcont.continue_bvp(BRATU, "lam", start, (1.0, 3.6), out=str(other))
    assert not other.exists() and os.listdir(tmp_path) == ["b.h5"]  # no file, no lock left behind


def test_store_every_keeps_special_points_and_the_last(tmp_path):
    path = str(tmp_path / "b.h5")
    start = bvp.solve(BRATU, {"lam": 1.0}, N=4, max_error=1e-8)
    mem = rodcont.continue_bvp(BRATU, "lam", start, (1.0, 3.6), max_error=1e-8, ds=0.1, ds_max=0.2, store_every=4,
                               out=path)
    assert mem.status == "bound" and len(mem) > 12
    disk = rodcont.load_branch(path)
    for r in (mem, disk):
        kept = [i for i in range(len(r)) if np.size(r.coefficients[i])]
        assert kept == sorted({0, r.folds["index"][0], len(r) - 1} | set(range(0, len(r), 4)))
        assert r.point("F1")["direction"][0].size == r.point("F1")["x"].size


# --------------------------------------------------------------------------
# Solve, branch points, the API's checks
# --------------------------------------------------------------------------
def test_solve_to_the_accuracy_asked():
    x = np.linspace(0, 1, 21)
    for max_error in (1e-6, 1e-10):
        sol = bvp.solve(BRATU, {"lam": 1.0}, N=2, max_error=max_error)
        assert sol.error <= max_error
        u, du = ref.bratu_solution(x, 1.0)
        assert np.max(np.abs(sol.evaluate(x, "u") - u)) < max_error
        assert np.max(np.abs(sol.evaluate(x, 0, 1) - du)) < 10 * max_error
    # every kind of guess reaches the same solution (the lower one); a solution as a guess, the upper one
    for guess in (0.0, [0.0], lambda S: 0 * S, {"u": lambda S: S * (1 - S)}):
        assert abs(bvp.solve(BRATU, {"lam": 1.0}, guess=guess).evaluate(0.5) - sol.evaluate(0.5)) < 1e-9
    upper = bvp.solve(BRATU, {"lam": 1.0}, guess=lambda S: 20 * S * (1 - S), max_error=1e-9)
    assert abs(upper.evaluate(0.5) - ref.bratu_max(ref.bratu_theta(1.0, "upper"))) < 1e-8
    again = bvp.solve(BRATU, {"lam": 1.0}, guess=upper, N=3)
    assert abs(again.evaluate(0.5) - upper.evaluate(0.5)) < 1e-9


def test_solve_refuses_what_it_cannot_do():
    with pytest.raises(ValueError, match="missing: lam"):
        bvp.solve(BRATU, {})
    with pytest.raises(ValueError, match="unknown: mu"):
        bvp.solve(BRATU, {"lam": 1.0, "mu": 2.0})
    with pytest.raises(bvp.BVPError, match="did not converge"):
        bvp.solve(BRATU, {"lam": 4.0})  # beyond the fold: no solution
    with pytest.raises(bvp.BVPError, match="accuracy not reached.*N_max"):
        bvp.solve(BRATU, {"lam": 1.0}, N=2, max_error=1e-14, N_max=4)
    sol = bvp.solve(BRATU, {"lam": 1.0})
    with pytest.raises(KeyError, match="no field 'v'"):
        sol.evaluate(0.5, "v")
    with pytest.raises(TypeError, match="unknown options ds_mx"):
        rodcont.continue_bvp(BRATU, "lam", sol, (0, 1), ds_mx=0.1)
    with pytest.raises(ValueError, match="unknown parameter 'mu'"):
        rodcont.continue_bvp(BRATU, "mu", sol, (0, 1))
    with pytest.raises(ValueError, match="free parameter"):
        rodcont.continue_bvp(elastica_problem(), "P", sol, (0, 1))


def test_branch_points_of_the_straight_elastica_located():
    """Under a load P the straight pinned rod theta = 0 buckles at P = (n pi)^2: branch points, located."""
    euler = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.sin(z[0]),
                              bc=lambda za, zb, p: np.stack([za[1], zb[1]]), interval=(0.0, 1.0), params=["P"])
    sol = bvp.solve(euler, {"P": 5.0})
    r = rodcont.continue_bvp(euler, "P", sol, (5.0, 45.0), ds=0.5, ds_max=2.0, max_error=1e-10)
    assert r.status == "bound"
    assert list(r.branch_points["label"]) == ["BP1", "BP2"] and all(r.branch_points["located"])
    assert np.max(np.abs(r.branch_points["P"] - np.pi**2 * np.array([1.0, 4.0]))) < 1e-9


def test_error_is_relative_to_the_scales():
    """A field of size 1e-4 is resolved relative to its size only when its floor says so."""
    small = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0] * 1e4) * 1e-4,
                              bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"],
                              names=["v"])  # v = u / 1e4: Bratu scaled
    x = np.linspace(0, 1, 11)
    u = ref.bratu_solution(x, 3.0)[0]
    loose = bvp.solve(small, {"lam": 3.0}, N=2, max_error=1e-6)
    tight = bvp.solve(small, {"lam": 3.0}, N=2, max_error=1e-6, scales={"v": 1e-4})
    assert tight.N > loose.N
    assert np.max(np.abs(tight.evaluate(x) * 1e4 - u)) / np.max(u) < 1e-6


# --------------------------------------------------------------------------
# The command line reads the files
# --------------------------------------------------------------------------
def test_cli_folds_and_plot(examples, tmp_path, capsys):
    printed, branch = examples["bratu"]
    path = branch.path
    code, out, err = run(["folds", path], capsys)
    assert code in (0, None), err
    lines = out.splitlines()
    assert lines[0].startswith(f"# bratu.h5: problem bratu, continued in lam, {len(branch)} points, status event")
    f1 = next(line for line in lines if line.startswith("F1"))
    assert abs(float(f1.split()[2]) - float(printed["fold_lambda"])) < 1e-13
    assert "no branch points" in lines
    png = tmp_path / "b.png"
    code, out, err = run(["plot", path, "--x", "lam", "--y", "u_mid", "-o", png], capsys)
    assert code in (0, None), err
    assert_picture(png)
    code, out, err = run(["plot", path, "--x", "lam", "--y", "stretch", "-o", tmp_path / "c.png"], capsys)
    assert code == 2 and err.count("\n") == 1 and "choose one of lam" in err
    assert not (tmp_path / "c.png").exists()


# --------------------------------------------------------------------------
# The README
# --------------------------------------------------------------------------
def test_readme_bratu_block_is_the_example():
    block = re.search(r"```python\n(.*?)```", readme_section(), re.DOTALL).group(1)
    code = open(os.path.join(EXAMPLES, "bvp_bratu.py"), encoding="utf-8").read()
    code = code[code.index('"""', 3) + 3:].lstrip("\n")
    assert block == code


def test_readme_numbers_are_what_the_examples_print(examples):
    """Every number the section quotes from an example equals its printed value (to 1e-12 relative; N exactly)."""
    text = readme_section()
    quoted = {}
    for name in ("fold_lambda", "fold_u_mid", "fold_slope_at_0", "fold_N", "slope_at_0", "N", "load_at_delta_1",
                 "theta_0_at_delta_1"):
        m = re.findall(rf"^{name} (\S+)$", text, re.MULTILINE)
        assert len(m) == 1, name
        quoted[name] = m[0]
    sources = {"fold_lambda": "bratu", "fold_u_mid": "bratu", "fold_slope_at_0": "bratu", "fold_N": "bratu",
               "slope_at_0": "troesch",
               "N": "troesch", "load_at_delta_1": "elastica", "theta_0_at_delta_1": "elastica"}
    for name, example in sources.items():
        value = examples[example][0][name]
        if name in ("N", "fold_N"):
            assert quoted[name] == value
        else:
            assert math.isclose(float(quoted[name]), float(value), rel_tol=1e-12), name
    # and the adaptive N quoted beside the uniform one is the example's
    assert re.search(rf"adaptive mesh of {examples['troesch'][0]['N']} subintervals", text)


def short(v: float) -> str:
    """An error as the README writes it: two digits, ``9.9e-14``, ``4.8e-9``."""
    m, e = f"{v:.1e}".split("e")
    return f"{m}e{int(e)}"


def stated(flat: str, phrase: str) -> list:
    """The errors the README states where ``phrase`` reads NUMBER (``to NUMBER``: ``to 9.9e-14``), in order."""
    m = re.search(re.escape(" ".join(phrase.split())).replace("NUMBER", r"(\d\.\de-\d+)"), flat)
    assert m, phrase
    return [float(v) for v in m.groups()]


def rounding_level(quoted: float, actual: float, tolerance: float, name: str) -> None:
    """An error at rounding level as the README quotes it (``9.9e-14``): the code's is below the tolerance the
    README states for it, and at most 10 times the quoted size (the last digits are the machine's: Bratu's fold was
    off by 6.7e-15 on one CPU against the 9.9e-14 quoted from another, so the quote bounds it, from above only)."""
    assert quoted <= tolerance, (name, quoted, tolerance)
    assert actual <= tolerance and actual <= 10 * quoted, (name, actual, quoted)


def test_readme_errors_are_the_examples_errors(examples):
    """The errors the section states, from the printed values and the closed forms: those at rounding level
    (the examples' against the closed forms) below the tolerance the README gives and of the size it quotes;
    the fixed-mesh fold's (a discretisation error) and the mesh's facts as printed."""
    text = readme_section()
    flat = " ".join(text.split())
    b, t, e = (examples[n][0] for n in ("bratu", "troesch", "elastica"))
    fold = ref.bratu_fold()
    start = bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1.0)
    fixed = rodcont.continue_bvp(BRATU, "lam", start, (0.0, 3.6), adapt=False, max_error=1.0, ds=0.1, ds_max=0.5,
                                 max_steps=20).folds["lam"][0]
    s = ref.troesch_slope(10.0)
    for phrase in ("held below `max_error = 1e-10` and the fold's below `fold_error = 1e-11`",
                   "(`examples/bvp_troesch.py`, `max_error = 1e-8`", "(1e-8 relative)"):
        assert " ".join(phrase.split()) in flat, phrase
    assert fold["lam"] == 3.513830719125161
    (q,) = stated(flat, "`λ* = 3.51383071912516` (closed form `λ* = 8 (y² − 1)`, `y tanh y = 1`) to NUMBER;")
    rounding_level(q, abs(float(b["fold_lambda"]) - fold["lam"]), 1e-11, "fold lambda")
    (q,) = stated(flat, "`u(1/2)` to NUMBER,")
    rounding_level(q, abs(float(b["fold_u_mid"]) - fold["u_max"]), 1e-11, "fold u(1/2)")
    (q,) = stated(flat, "`u'(0)` (4 exactly there) to NUMBER.")
    rounding_level(q, abs(float(b["fold_slope_at_0"]) - 4), 1e-11, "fold u'(0)")
    (q,) = stated(flat, "`u'(0)` at `λ = 10` to NUMBER relative")
    rounding_level(q, abs(float(t["slope_at_0"]) / s - 1), 1e-8, "Troesch u'(0), relative")
    q_load, q_rel, q_angle = stated(flat, "`δ = 2 − 2 E(m)/K(m)`: NUMBER (NUMBER relative) and NUMBER for the "
                                          "end angle")
    load = float(e["load_at_delta_1"])
    rounding_level(q_load, abs(load - ref.elastica_load(1.0)), 1e-10, "elastica load")
    rounding_level(q_rel, abs(load / ref.elastica_load(1.0) - 1), 1e-10, "elastica load, relative")
    rounding_level(q_angle, abs(float(e["theta_0_at_delta_1"]) - ref.elastica_theta0(1.0)), 1e-10, "end angle")
    exact = [f"on those 4 held fixed (`adapt=False`) the fold is {short(abs(fixed - fold['lam']))} off",
             "to 21 at the fold", f"graded from {t['h_max']} to {t['h_min']} into the layer"]
    assert b["fold_N"] == "21"
    for phrase in exact:
        assert " ".join(phrase.split()) in flat, phrase
    # the layer's facts: u'(1) = 148 at lam = 10, the singularity 1.4e-3 beyond x = 1 (x(u) = int du / u')
    from scipy.integrate import quad
    assert round(float(ref.troesch_solution(np.array([1.0]), 10.0)[1][0])) == 148 and "`u'(1) = 148`" in text
    with np.errstate(over="ignore"):
        beyond = quad(lambda u: 1 / math.sqrt(s * s + 4 * math.sinh(5 * u) ** 2), 1, 50)[0]
    assert f"singularity is {short(beyond)} beyond" in flat
