"""The Python API's edges (issue 22 item 16): a wrong type given to a public function is a ``TypeError`` or
``ValueError`` naming the argument, never an ``AttributeError`` (or ``OverflowError``) from inside.

Each case was found by calling the public API as a new user might; before these checks, ``critical_twists``,
``fold_curve``, ``bvp.solve``, ``continue_bvp`` (its problem, events, scales) and ``BVPResult.solution`` raised
``AttributeError``, ``bvp.solve`` took a string as a parameter's value and read ``N = "4"`` as a mesh,
``load_branch(None)`` failed in ``os.stat``, ``trace(start=branch)`` failed unpacking, and a helix reference of
radius 1e300 raised ``OverflowError: (34, 'Numerical result out of range')``.
"""

import numpy as np
import pytest

import rodcont
from conftest import run
from rodcont import bvp

BRATU = rodcont.BVProblem(orders=[2], residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),
                          bc=lambda za, zb, p: np.stack([za[0], zb[0]]), interval=(0.0, 1.0), params=["lam"],
                          names=["u"])


@pytest.fixture(scope="module")
def bratu_start():
    return bvp.solve(BRATU, {"lam": 0.0}, N=4, max_error=1e-6)


def test_solve_with_phi_names_phi_L_not_an_internal_function():
    with pytest.raises(TypeError, match=r"rodcont\.solve\(\) got unexpected keyword argument\(s\) 'phi' "
                                        r"\(the end rotation is phi_L\)") as exc:
        rodcont.solve(gamma=1.0, phi=5.0)
    assert "solve_equilibrium" not in str(exc.value)


@pytest.mark.parametrize("rod", [[1, 2], "rod", {"EI": 1.0}])
def test_critical_twists_refuses_a_rod_that_is_not_one(rod):
    with pytest.raises(TypeError, match="rod must be a RodParameters"):
        rodcont.critical_twists(rod)


@pytest.mark.parametrize("data", ["gamma_2.h5", None, 3, [1.0]])
def test_fold_curve_refuses_what_is_not_a_branch(data):
    with pytest.raises(TypeError, match=r"data must be a branch .*rodcont\.load_branch\(path\)"):
        rodcont.fold_curve(data, 0, "gamma", 0.0, 1.0)


@pytest.mark.parametrize("problem", ["bratu", None, {"orders": [2]}])
def test_bvp_entry_points_refuse_what_is_not_a_problem(problem, bratu_start):
    with pytest.raises(TypeError, match="problem must be a rodcont.BVProblem"):
        bvp.solve(problem, {"lam": 0.0})
    with pytest.raises(TypeError, match="problem must be a rodcont.BVProblem"):
        rodcont.continue_bvp(problem, "lam", bratu_start, (0.0, 1.0))


def test_bvp_solve_refuses_wrong_types_of_its_arguments():
    with pytest.raises(TypeError, match=r"params\['lam'\] must be a number, got '0'"):
        bvp.solve(BRATU, {"lam": "0"})
    with pytest.raises(TypeError, match=r"N \(subintervals\) must be an integer, got '4'"):
        bvp.solve(BRATU, {"lam": 0.0}, N="4")
    with pytest.raises(TypeError, match="outputs must be a dict name -> a function"):
        bvp.solve(BRATU, {"lam": 0.0}, outputs=[lambda sol: 0.0])
    with pytest.raises(TypeError, match="scales must be a dict name -> a number"):
        bvp.solve(BRATU, {"lam": 0.0}, scales=[1.0])


def test_continue_bvp_refuses_wrong_types_of_its_arguments(bratu_start):
    for kwargs, message in [(dict(events=[1]), "events must be a sequence of rodcont.Event"),
                            (dict(events="stop"), "events must be a sequence of rodcont.Event"),
                            (dict(scales=[1.0]), "scales must be a dict name -> a number"),
                            (dict(outputs={"u_mid": 0.5}), "outputs must be a dict name -> a function"),
                            (dict(callback=3), "callback must be a function of the point")]:
        with pytest.raises(TypeError, match=message):
            rodcont.continue_bvp(BRATU, "lam", bratu_start, (0.0, 1.0), **kwargs)


def test_a_result_solution_refuses_a_problem_that_is_not_one(bratu_start):
    res = rodcont.continue_bvp(BRATU, "lam", bratu_start, (0.0, 0.5), ds=0.1, ds_max=0.5, max_error=1e-6)
    assert res.solution(-1, BRATU).params["lam"] == pytest.approx(0.5)
    with pytest.raises(TypeError, match="problem must be a rodcont.BVProblem, got str"):
        res.solution(-1, "bratu")


@pytest.mark.parametrize("path", [None, 3, ["g1.h5"]])
def test_load_functions_refuse_what_is_not_a_file_name(path):
    for load in (rodcont.load_branch, rodcont.load_diagram):
        with pytest.raises(TypeError, match="path must be a file name"):
            load(path)


@pytest.mark.parametrize("start", ["g1.h5:-1", ("g1.h5", 0), {"x": [], "phi_L": 0.0}])
def test_trace_start_must_be_a_stored_point_and_says_how_to_get_one(start):
    with pytest.raises(TypeError, match=r"start must be a stored point \(x, value, direction\).*restart_from"):
        rodcont.trace(1.0, start=start)


def test_trace_refuses_a_callback_that_cannot_be_called():
    with pytest.raises(TypeError, match="callback must be a function of the point, got 3"):
        rodcont.trace(1.0, callback=3, max_steps=2)


@pytest.mark.parametrize("reference", ["helix:1e300,1", "helix:0.1,1e-300"])
def test_a_helix_too_large_to_represent_is_one_line(reference, capsys):
    with pytest.raises(ValueError, match="too large to represent"):
        rodcont.solve(gamma=1.0, phi_L=1.0, curve=reference)
    code, out, err = run(["solve", "--gamma", "1", "--phi", "1", "--reference", reference], capsys)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("rodcont: error: --reference ") and "too large to represent" in err
    assert "Errno" not in err and "(34," not in err


# --------------------------------------------------------------------------
# Found by calling every name of rodcont.__all__ with one wrong-typed argument at a time: each raised an
# AttributeError, a message naming no argument (``could not convert string to float: 'x'``) or nothing at all
# --------------------------------------------------------------------------
@pytest.mark.parametrize("gammas", ["1", 1.0, None, b"1", {"a": 1.0}])
def test_sweep_refuses_gammas_that_are_not_a_sequence_of_numbers(gammas, tmp_path):
    with pytest.raises(TypeError, match="gammas must be a sequence of Gamma values"):
        rodcont.sweep(gammas, out_dir=str(tmp_path / "s"), max_steps=2, plot=False, jobs=1)
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("kwargs,error,message", [
    (dict(out_dir=3), TypeError, "out_dir must be a directory name, got 3"),
    (dict(out_dir=None), TypeError, "out_dir must be a directory name"),
    (dict(N="abc"), TypeError, "N must be an integer"),
    (dict(N=0), ValueError, r"N \(number of subintervals\)"),
    (dict(k=[5]), TypeError, "k must be an integer"),
    (dict(executor="abc"), TypeError, "executor must be a concurrent.futures.Executor"),
])
def test_sweep_refuses_a_wrong_directory_mesh_or_executor_before_any_job(kwargs, error, message, tmp_path):
    kwargs = dict(dict(out_dir=str(tmp_path / "s")), **kwargs)
    with pytest.raises(error, match=message):
        rodcont.sweep([1.0], max_steps=2, plot=False, jobs=1, **kwargs)
    assert not (tmp_path / "s").exists()


def test_sweep_into_a_file_is_refused_in_one_sentence(tmp_path):
    f = tmp_path / "notes.txt"
    f.write_text("mine\n")
    with pytest.raises(ValueError, match="out_dir .*notes.txt exists and is not a directory"):
        rodcont.sweep([1.0], out_dir=str(f), max_steps=2, plot=False, jobs=1)
    assert f.read_text() == "mine\n"


@pytest.mark.parametrize("direction", ["x", "0,0,-1", {"x": 1}, object(), b"z"])
def test_a_weight_direction_that_is_not_a_vector_names_it(direction):
    with pytest.raises(TypeError, match=r"weight_direction must be a 3-vector of numbers \(X, Y, Z\)"):
        rodcont.RodParameters(weight_direction=direction)
    with pytest.raises(ValueError, match="weight_direction must be a non-zero 3-vector"):
        rodcont.RodParameters(weight_direction=(0, 1))
    assert rodcont.RodParameters(weight_direction=[0, 0, -2]).weight_direction == (0.0, 0.0, -1.0)


@pytest.mark.parametrize("breakpoints", ["abc", "0 0.5 1", {"a": 1}, b"x", object()])
def test_trace_breakpoints_that_are_not_numbers_are_named(breakpoints):
    with pytest.raises(TypeError, match=r"breakpoints must be a sequence of numbers \(the mesh's\)"):
        rodcont.trace(1.0, breakpoints=breakpoints, max_steps=2)


def test_trace_refuses_meta_settings_and_resume_of_the_wrong_type():
    for kwargs, message in [(dict(meta=3), "meta must be a dict, got 3"),
                            (dict(meta=[("a", 1)]), "meta must be a dict"),
                            (dict(settings={"ds": 0.1}), "settings must be a rodcont.ContinuationSettings"),
                            (dict(resume="g1.h5"), r"resume must be a rodcont.Branch .*rodcont.load_branch\(out\)")]:
        with pytest.raises(TypeError, match=message):
            rodcont.trace(1.0, max_steps=2, **kwargs)


@pytest.mark.parametrize("out", [3, ["g.h5"], 1.5])
def test_an_output_that_is_not_a_file_name_is_a_type_error(out, bratu_start):
    with pytest.raises(TypeError, match="out must be a file name"):
        rodcont.trace(1.0, max_steps=2, out=out)
    with pytest.raises(TypeError, match="out must be a file name"):
        rodcont.continue_bvp(BRATU, "lam", bratu_start, (0.0, 0.5), out=out)


def test_an_output_may_be_a_path(tmp_path):
    br = rodcont.trace(1.0, max_steps=2, out=tmp_path / "g.h5")
    assert len(rodcont.load_branch(str(tmp_path / "g.h5"))) == len(br) == 3


def test_diagram_refuses_wrong_types_of_its_arguments():
    for kwargs, error, message in [
            (dict(deflate_at=3.0), TypeError, "deflate_at must be a sequence of numbers, got 3.0"),
            (dict(deflate_at="12"), TypeError, "deflate_at must be a sequence of numbers"),
            (dict(deflate_at=[float("nan")]), ValueError, "deflate_at must be a finite number"),
            (dict(callback=3), TypeError, "callback must be a function of the point, got 3"),
            (dict(progress="print"), TypeError, "progress must be a function of a line of text"),
            (dict(meta=[1]), TypeError, "meta must be a dict"),
            (dict(resumed="D.h5"), TypeError, "resumed must be a sequence of DiagramBranch"),
            (dict(resumed=[1, 2]), TypeError, "resumed must be a sequence of DiagramBranch")]:
        with pytest.raises(error, match=message):
            rodcont.diagram(1.0, phi_max=12.0, max_steps=3, **kwargs)


@pytest.fixture(scope="module")
def fold_branch():
    return rodcont.trace(1.0, stretch_max=0.2)


def test_fold_curve_refuses_wrong_types_of_its_arguments(fold_branch):
    for kwargs, error, message in [
            (dict(forced=1.0), TypeError, "forced must be a sequence of numbers, got 1.0"),
            (dict(forced=None), TypeError, "forced must be a sequence of numbers"),
            (dict(callback="x"), TypeError, "callback must be a function of the point"),
            (dict(min_alignment="abc"), TypeError, "min_alignment must be a number"),
            (dict(min_alignment=float("nan")), ValueError, "min_alignment must be a finite number"),
            (dict(min_alignment=2.0), ValueError, r"min_alignment must be in \[0, 1\)")]:
        with pytest.raises(error, match=message):
            rodcont.fold_curve(fold_branch, 0, "gamma", 0.95, 1.05, max_steps=2, **kwargs)


@pytest.mark.parametrize("direction", ["up", None, [1], 0, 2, 0.5, True, float("nan")])
def test_continue_bvp_direction_is_plus_or_minus_one(direction, bratu_start):
    with pytest.raises(ValueError, match=r"direction must be \+1 or -1, got"):
        rodcont.continue_bvp(BRATU, "lam", bratu_start, (0.0, 0.5), direction=direction)


def test_rod_system_refuses_a_rod_or_loads_that_are_not_numbers():
    for kwargs, message in [(dict(rod="rod", gamma=1.0), "rod must be a RodParameters, got 'rod'"),
                            (dict(rod=None, gamma=1.0), "rod must be a RodParameters"),
                            (dict(gamma="1"), "gamma must be a number, got '1'"),
                            (dict(gamma=1.0, phi_L=[2.0]), r"phi_L must be a number, got \[2.0\]"),
                            (dict(T=b"10"), "T must be a number")]:
        kwargs = dict(dict(rod=rodcont.RodParameters()), **kwargs)
        with pytest.raises(TypeError, match=message):
            rodcont.RodSystem(**kwargs)


def test_a_straight_reference_names_what_is_wrong_in_one_line():
    for kwargs, error, message in [(dict(length="abc"), TypeError, "reference length L must be a number"),
                                   (dict(K1="abc"), TypeError, "K1 must be a 3-vector of numbers"),
                                   (dict(K1=(1,)), ValueError, "K1 must be a 3-vector of finite numbers"),
                                   (dict(K2=(0, 0, float("inf"))), ValueError, "K2 must be a 3-vector of finite"),
                                   (dict(origin={"x": 0}), TypeError, "origin must be a 3-vector of numbers")]:
        with pytest.raises(error, match=message) as exc:
            rodcont.StraightReference(**kwargs)
        assert "\n" not in str(exc.value)


# --------------------------------------------------------------------------
# rodcont.continuation: the module and the function re-exported under its name were two objects, which one
# ``rodcont.continuation`` (and ``import rodcont.continuation as m``) gave depending on what was imported first
# --------------------------------------------------------------------------
_ORDERS = ["import rodcont; f = rodcont.continuation; import rodcont.continuation as m",
           "import rodcont.continuation as m; import rodcont; f = rodcont.continuation",
           "import rodcont; rodcont.trace; rodcont.Tracker; import rodcont.continuation as m; f = rodcont.continuation",
           "from rodcont import continuation as f; import rodcont.continuation as m"]
_CHECK = """
import types, numpy as np, scipy.sparse as sp, rodcont
from rodcont.continuation import continuation as function
class Line:  # x = p
    def residual(self, x, p): return x - p
    def tangent(self, x, p): return sp.identity(1, format="csc"), np.array([-1.0])
assert m is f is rodcont.continuation and isinstance(m, types.ModuleType), (m, f)
assert m.Tracker is rodcont.Tracker and callable(function) and not isinstance(function, types.ModuleType)
res = f(Line(), np.array([0.0]), 0.0, m.ContinuationSettings(ds=0.1, ds_max=0.1, max_steps=4))
assert str(res.status) == "max_steps" and abs(res.table["p"][-1] - 0.4) < 1e-12, res.table["p"]
"""


@pytest.mark.parametrize("order", _ORDERS)
def test_rodcont_continuation_is_the_module_and_calls_the_function_whatever_came_first(order):
    import os
    import subprocess
    import sys
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    r = subprocess.run([sys.executable, "-c", order + "\n" + _CHECK], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=src))
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("name", ["newton_tol", "fold_tol", "locate_tol", "newton_max_iter", "chord_max_iter",
                                  "locate_max_iter"])
def test_continuation_settings_name_the_tolerance_or_limit_that_is_wrong(name):
    with pytest.raises(ValueError, match=name):
        rodcont.ContinuationSettings(**{name: -1})


def test_loads_must_be_a_list_of_loads():
    from rodcont.loads import Weight
    for loads in (3, Weight()):
        with pytest.raises(TypeError, match="loads must be a list of rodcont.loads.DistributedLoad"):
            rodcont.EulerianRod(loads=loads)
    with pytest.raises(TypeError, match="a load must be a rodcont.loads.DistributedLoad, got 'w'"):
        rodcont.EulerianRod(loads="w")
    assert len(rodcont.EulerianRod(loads=[Weight()]).loads) == 1


@pytest.mark.parametrize("k", ["abc", "5", 5.0, 0, 8, True])
def test_a_rod_system_names_a_wrong_number_of_gauss_points(k):
    with pytest.raises(ValueError, match=r"k \(Gauss points per subinterval\) must be an integer in 1..7"):
        rodcont.RodSystem(rodcont.RodParameters(), gamma=1.0, k=k)


@pytest.mark.parametrize("branch", [[1, 2], 1.5, True])
def test_load_branch_names_a_branch_index_of_the_wrong_type(tmp_path, branch):
    # was BranchFileError "has no branch [1, 2]": a wrong type is the caller's error, named as such; a name
    # of the right type the file does not hold stays the file's error (the CLI's --branch '' or -1: exit 2)
    path = str(tmp_path / "g.h5")
    rodcont.trace(1.0, phi_max=2.0, out=path)
    with pytest.raises(TypeError, match=r"branch must be a branch index \(an int >= 0\), got "):
        rodcont.load_branch(path, branch=branch)
    for name in ("", "-1", -1, "branches"):
        with pytest.raises(rodcont.branchfile.BranchFileError, match="not a diagram: no branch"):
            rodcont.load_branch(path, branch=name)


@pytest.mark.parametrize("label", [1.5, [1], None, True])
def test_a_point_label_of_the_wrong_type_is_a_type_error(tmp_path, label):
    # was BranchFileError "point label '1.5'" (a file's error for an in-memory object); int and str read
    br = rodcont.trace(1.0, phi_max=2.0)
    assert br.point(np.int64(1))["phi_L"] == br.point("1")["phi_L"]
    with pytest.raises(TypeError, match="a point label is an int or a str"):
        br.point(label)
