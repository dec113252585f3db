"""Fold curves, branch switching and families on the rod."""

import os
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
import pytest

import rodcont
from conftest import assert_picture
from rodcont.cli import main
from rodcont.drivers.foldcurve import fold_curve
from rodcont.drivers.sweep import sweep
from rodcont.drivers.trace import trace


@pytest.fixture(scope="module")
def g1_n15(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("fc") / "g1.h5")
    trace(1.0, N=15, adapt=False, stretch_max=0.25, out=path)
    return path


def test_fold_curve_matches_one_parameter_traces(g1_n15, tmp_path):
    """Points of the fold locus in (Phi, Gamma) at Gamma = 0.5 and 1.5 agree to 1e-8 with the
    folds located by separate one-parameter traces at those Gamma (same mesh)."""
    d = rodcont.load_branch(g1_n15)
    out = str(tmp_path / "locus.h5")
    res = fold_curve(d, 0, "gamma", 0.5, 1.5, out=out, forced=(0.75,))
    by_gamma = {round(sp.value, 12): res.row_at(sp.index) for sp in res.special if sp.kind in ("bound", "forced")}
    for g in (0.5, 0.75, 1.5):
        q = by_gamma[g]
        ref = trace(g, N=15, adapt=False, stretch_max=q["stretch"] + 0.05).folds[0]
        for name in ("phi_L", "stretch", "torque", "l0"):
            assert q[name] == pytest.approx(ref[name], abs=1e-8), (g, name)
    # read back, the file is the same result
    back = rodcont.load_branch(out)
    assert back.table["gamma"] == pytest.approx(res.table["gamma"], abs=0) and back.status == res.status
    assert (back.message_first, back.message) == (res.message_first, res.message)
    # the file: branch-file conventions plus a dataset named after the parameter
    with h5py.File(out, "r") as f:
        assert f.attrs["param"] == "gamma"
        n = f["branch/phi_L"].shape[0]
        for name in ("phi_L", "stretch", "torque", "l0", "gamma"):
            assert f["branch"][name].shape == (n,)
        g = f["branch/gamma"][()][np.argsort(f["branch/arclength"][()])]  # rows as computed: down, then up
        assert np.all(np.diff(g) > 0) and g[0] == pytest.approx(0.5) and g[-1] == pytest.approx(1.5)


def test_fold_curve_in_a_stiffness(g1_n15):
    """Continuing in EI (T fixed): at the ends of the range the fold is where a one-parameter trace puts it."""
    d = rodcont.load_branch(g1_n15)
    res = fold_curve(d, 0, "EI", 0.9, 1.1)
    q = res.row_at(-1)
    assert q["kind"] == "bound" and q["EI"] == pytest.approx(1.1) and res.status == "bound"
    rod = rodcont.RodParameters(EI=1.1)
    ref = trace(1.0, rod, N=15, stretch_max=q["stretch"] + 0.05).folds[0]
    assert q["phi_L"] == pytest.approx(ref["phi_L"], abs=1e-8)


def test_fold_curve_cli_and_plot(g1_n15, tmp_path, capsys):
    out = str(tmp_path / "fc.h5")
    with pytest.raises(SystemExit) as exc:
        main(["fold-curve", f"{g1_n15}:0", "--param", "gamma", "--range", "0.8", "1.2", "--out", out, "--quiet"])
    assert exc.value.code == 0
    png = str(tmp_path / "fc.png")
    with pytest.raises(SystemExit) as exc:
        main(["plot", g1_n15, out, "-o", png])
    assert exc.value.code == 0
    assert_picture(png)
    for bad in ([f"{g1_n15}:3", "--range", "0.8", "1.2"], [f"{g1_n15}:x", "--range", "0.8", "1.2"],
                [f"{g1_n15}:0", "--range", "2", "3"], [f"{g1_n15}:0", "--range", "1.2", "0.8"],
                [f"{g1_n15}:0", "--param", "zz", "--range", "0.8", "1.2"]):
        with pytest.raises(SystemExit) as exc:
            main(["fold-curve", *bad, "--out", str(tmp_path / "x.h5")])
        assert exc.value.code == 2
    assert not (tmp_path / "x.h5").exists()
    with pytest.raises(SystemExit) as exc:  # a fold curve is not a branch to restart from
        main(["trace", "--start", f"{out}:0", "--out", str(tmp_path / "y.h5")])
    assert exc.value.code == 2
    assert not (tmp_path / "y.h5").exists()


def test_switch_needs_a_branch_point(g1_n15, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["trace", "--start", f"{g1_n15}:F1", "--switch", "--out", str(tmp_path / "s.h5")])
    assert exc.value.code == 2
    assert "branch point" in capsys.readouterr().err


def test_sweep_with_any_executor(tmp_path):
    """The family through the API with a plain ThreadPoolExecutor (any concurrent.futures executor fits);
    each branch equals a trace run on its own."""
    with ThreadPoolExecutor(max_workers=2) as ex:
        res = sweep([0.0, 1.0], str(tmp_path), executor=ex, stretch_max=0.2)
    assert [r["gamma"] for r in res["branches"]] == [0.0, 1.0]
    assert_picture(res["diagram"])
    for r in res["branches"]:
        d = rodcont.load_branch(r["path"])
        ref = trace(r["gamma"], stretch_max=0.2).folds[0]
        assert d.folds["phi_L"][0] == pytest.approx(ref["phi_L"], abs=1e-10)


def test_sweep_cli_processes(tmp_path, capsys):
    out = tmp_path / "fam"
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--gamma", "0", "1", "--jobs", "2", "--phi-max", "12", "--out", str(out), "--quiet"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "parameter bound p_max = 12" in text
    assert sorted(os.listdir(out)) == ["gamma_0.h5", "gamma_1.h5", "response_diagram.png"]
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--gamma", "1", "-50", "--out", str(tmp_path / "bad")])
    assert exc.value.code == 2
    assert not (tmp_path / "bad").exists()


def test_sweep_on_a_dask_cluster_with_process_workers(tmp_path):
    """The same sweep, on a real dask.distributed LocalCluster of two worker processes."""
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        res = sweep([0.0, 1.0], str(tmp_path), executor=client.get_executor(), stretch_max=0.2, plot=False)
    firsts = {r["gamma"]: r["first_fold"] for r in res["branches"]}
    assert firsts[1.0] == pytest.approx(13.0999938, abs=1e-6) and firsts[0.0] == pytest.approx(10.7769232, abs=1e-6)
    assert all(r["error"] is None for r in res["branches"])
