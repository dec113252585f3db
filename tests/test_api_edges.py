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
from conftest import run

import rodcont
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
