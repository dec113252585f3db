"""``rodcont export`` / ``rodcont animate``: round trips, the Kirchhoff balance of the exported fields,
a VTK reader on the ``.vtp`` files, and the one-line errors of the command line."""

import csv
import io
import json
import os
import shutil
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import run
from rodcont.branchfile import FOLD_FIELDS, SCALARS, BranchWriter, load_branch, load_diagram
from rodcont.cli import main_group
from rodcont.cli.export import animate_cmd, export_cmd
from rodcont.export import ExportError, rod_fields, write_npz
from rodcont.system import point_system

for _cmd in (export_cmd, animate_cmd):
    if _cmd.name not in main_group.commands:
        main_group.add_command(_cmd)


def assert_one_line_error(code, out, err, *fragments):
    assert code == 2, (code, out, err)
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("rodcont: error:")
    assert "Traceback" not in err + out
    for f in fragments:
        assert f in lines[0], (f, lines[0])


# --------------------------------------------------------------------------
# Fixtures: a short primary branch through its first fold, a branch continued
# in EI, and a two-branch diagram file built from the first
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from rodcont.drivers.trace import trace
    d = tmp_path_factory.mktemp("export")
    path = str(d / "g1.h5")
    trace(1.0, N=15, stretch_max=0.2, out=path)
    data = load_branch(path)
    assert len(data.folds["index"]) == 1
    # continued in EI from point 20 (the file's root attribute keeps the EI it started from)
    pt = data.point(20)
    ei = str(d / "ei.h5")
    trace(rod=data.rod, T=data.tension, N=pt["breakpoints"].size - 1, k=int(data.attrs["k"]), param="EI",
          phi_L=float(pt["phi_L"]), start=(pt["x"], 1.0, None), breakpoints=pt["breakpoints"],
          p_range=(0.6, 1.0), direction=-1, max_steps=6, out=ei)
    diag = str(d / "diag.h5")
    _copy_as_diagram(data, diag)
    return dict(dir=d, branch=path, data=data, ei=ei, diagram=diag)


def _copy_as_diagram(data, path):
    """A diagram file of two branches: 0 = the whole branch, 1 = its points 5.. (so they differ)."""
    meta = {k: v for k, v in data.attrs.items() if k not in ("rodcont_version", "stop_reason")}
    meta["kind"] = "diagram"
    w = BranchWriter(path, meta)
    for j, first in enumerate((0, 5)):
        g = w.group(f"branches/{j}", attrs=dict(origin=f"copy from point {first}"))
        for i in range(first, len(data)):
            pt = data.point(i)
            row = {name: float(data.branch[name][i]) for name in SCALARS}
            row["helical_waves"] = int(data.branch["helical_waves"][i])
            w.add_point(g, row, str(data.branch["kind"][i]), True, pt["x"], data.branch["tangent"][i],
                        pt["breakpoints"])
        folds = [{n: data.folds[n][q] - (first if n == "index" else 0) for n in FOLD_FIELDS}
                 for q in range(len(data.folds["index"]))]
        g.set_special(folds, [])
    w.close("copied")


def _read_csv(path):
    with open(path) as fh:
        lines = fh.read().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    rest = [ln for ln in lines if not ln.startswith("#")]
    assert lines[:len(comments)] == comments, "comment lines come first"
    rows = list(csv.reader(io.StringIO("\n".join(rest))))
    header, body = rows[0], np.array(rows[1:], float)
    meta = dict(ln[2:].split(": ", 1) for ln in comments if ": " in ln)
    return header, body, meta


def _centreline_from_branch(data, label, S):
    i = data.resolve(label)
    system = point_system(data, i)
    return system.model.centreline(system.disc, data.point(i)["x"], S)


# --------------------------------------------------------------------------
# Round trips: CSV, VTK, npz against the branch file's centreline
# --------------------------------------------------------------------------
def test_csv_round_trip(files, capsys):
    out = files["dir"] / "f1.csv"
    code, stdout, err = run(["export", files["branch"], "--point", "F1", "--samples", "301", "-o", out], capsys)
    assert code == 0, err
    header, body, meta = _read_csv(out)
    assert header[:5] == ["S", "s", "x", "y", "z"]
    for name in ("d1_x", "d3_z", "u1", "u2", "u3", "F_x", "N1", "N2", "N", "M_z", "M1", "M2", "M3", "alpha"):
        assert name in header
    assert len(meta["unit"].split(",")) == len(header)
    assert body.shape == (301, len(header))
    data = files["data"]
    i = data.resolve("F1")
    assert int(meta["point"]) == i and meta["kind"] == "fold"
    assert float(meta["phi_L"]) == data.branch["phi_L"][i]
    col = {n: body[:, j] for j, n in enumerate(header)}
    S = col["S"]
    np.testing.assert_array_equal(S, np.linspace(0.0, data.rod.L, 301))
    r = _centreline_from_branch(data, "F1", S)
    err_r = np.abs(np.stack([col["x"], col["y"], col["z"]]) - r).max()
    print(f"CSV centreline round trip: max |r_csv - r_branch| = {err_r:.1e}")
    assert err_r <= 1e-15 * data.rod.L  # 17 significant digits: exact


def test_vtp_read_by_vtk(files, capsys):
    pytest.importorskip("vtkmodules.vtkIOXML")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
    out = files["dir"] / "f1.vtp"
    code, _, err = run(["export", files["branch"], "--point", "F1", "--format", "vtk", "-o", out], capsys)
    assert code == 0, err
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(out))
    reader.Update()
    poly = reader.GetOutput()
    assert poly.GetNumberOfPoints() == 200
    assert poly.GetNumberOfLines() == 1 and poly.GetNumberOfCells() == 1
    np.testing.assert_array_equal(vtk_to_numpy(poly.GetLines().GetConnectivityArray()), np.arange(200))
    P = vtk_to_numpy(poly.GetPoints().GetData())
    data = files["data"]
    fields = rod_fields(data, "F1", 200)
    r = _centreline_from_branch(data, "F1", fields["S"])
    err_r = np.abs(P.T - r).max()
    print(f"VTK centreline round trip: max |r_vtp - r_branch| = {err_r:.1e}")
    assert err_r <= 1e-15 * data.rod.L
    pd = poly.GetPointData()
    names = {pd.GetArrayName(j) for j in range(pd.GetNumberOfArrays())}
    assert {"S", "s", "d1", "d2", "d3", "u1", "u2", "u3", "F", "N", "M", "M3", "alpha"} <= names
    for name in ("s", "d1", "F", "M", "u1", "u3", "alpha"):
        np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray(name)), fields[name])
    fd = poly.GetFieldData()
    assert vtk_to_numpy(fd.GetArray("phi_L"))[0] == data.branch["phi_L"][data.resolve("F1")]


def test_vtp_is_well_formed_polydata(files):
    """The XML itself (runs without a VTK reader): one polyline, arrays of the right sizes."""
    from rodcont.export import write_vtp
    data = files["data"]
    f = rod_fields(data, 7, 25)
    out = files["dir"] / "p7.vtp"
    write_vtp(f, str(out), {"phi_L": 1.5, "source": "x--y<&>"})
    root = ET.parse(out).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "PolyData"
    piece = root.find("PolyData/Piece")
    assert piece.get("NumberOfPoints") == "25" and piece.get("NumberOfLines") == "1"
    pts = np.array(piece.find("Points/DataArray").text.split(), float).reshape(-1, 3)
    np.testing.assert_array_equal(pts, np.column_stack([f["x"], f["y"], f["z"]]))
    for arr in piece.find("PointData"):
        ncomp = int(arr.get("NumberOfComponents", "1"))
        assert len(arr.text.split()) == 25 * ncomp, arr.get("Name")


def test_npz_round_trip(files, capsys):
    out = files["dir"] / "p3.npz"
    code, _, err = run(["export", files["branch"] + ":3", "-o", out], capsys)  # FILE:POINT of a single branch
    assert code == 0, err
    data = files["data"]
    ref = rod_fields(data, 3, 200)
    with np.load(out) as z:
        for name, value in ref.items():
            np.testing.assert_array_equal(z[name], value)
        meta = json.loads(str(z["meta"]))
    assert meta["point"] == 3 and meta["EI"] == data.rod.EI
    r = _centreline_from_branch(data, 3, ref["S"])
    assert np.abs(np.stack([ref["x"], ref["y"], ref["z"]]) - r).max() == 0.0


# --------------------------------------------------------------------------
# Physics: Kirchhoff balance, constitutive law, kinematics
# --------------------------------------------------------------------------
def _kirchhoff_errors(f, p, g, L, defect):
    """Re-integrate dF/ds = -f, dM/ds = -r_s x F from s = 0 with the exported F(0), M(0).

    Returns the errors and their tolerances: the collocation residual (relative
    to its scale, at most ``defect`` between collocation points) integrated over
    the span, plus the trapezoid error of the moment integral estimated from the
    integrand's second differences (sum h^3 |g''| / 12).
    """
    w, EI = p[2], p[3]
    s, F, M = f["s"], f["F"], f["M"]
    Fmax = np.abs(F).max()
    F_int = F[0] - w * np.asarray(g)[None, :] * s[:, None]          # exact integral of -w g
    err_F = np.abs(F_int - F).max()
    tol_F = 2 * defect * max(w, Fmax / L, EI / L**3) * L + 1e-12 * Fmax
    G = -np.cross(f["alpha"][:, None] * f["d3"], F)                  # dM/ds = -(dr/ds) x F
    h = np.diff(s)
    M_int = M[0] + np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (G[1:] + G[:-1]) * h[:, None], axis=0)])
    err_M = np.abs(M_int - M).max()
    g2 = np.abs(np.diff(G, 2, axis=0)) / (0.5 * (h[1:] + h[:-1]))[:, None] ** 2
    trap = float((h[1:, None] ** 3 * g2).sum(axis=0).max() / 12.0)
    tol_M = 2 * defect * max(Fmax, EI / L**2) * L + 2 * trap
    return err_F, tol_F, err_M, tol_M


@pytest.mark.parametrize("which,label", [("branch", "F1"), ("branch", 10), ("ei", -1)])
def test_kirchhoff_balance(files, which, label):
    from rodcont.export import point_parameters
    data = load_branch(files[which])
    i = data.resolve(label)
    p = point_parameters(data, i)
    f = rod_fields(data, label, 4001)
    defect = float(data.branch["defect"][i])
    err_F, tol_F, err_M, tol_M = _kirchhoff_errors(f, p, data.rod.weight_direction, data.rod.L, defect)
    print(f"Kirchhoff {which}:{label}: |F - F_int| = {err_F:.2e} (tol {tol_F:.1e}, |F|max "
          f"{np.abs(f['F']).max():.3g}), |M - M_int| = {err_M:.2e} (tol {tol_M:.1e}, |M|max {np.abs(f['M']).max():.3g})")
    assert err_F <= tol_F
    assert err_M <= tol_M
    # the tension boundary condition F(L).K3 = T (K3 = e1): the point's parameters were used
    assert abs(f["F"][-1, 0] - p[1]) <= 1e-9 * abs(p[1])
    # the tolerance is far below what a wrong law would give (a sign of u1, a missing alpha, a wrong EI)
    assert tol_M < 1e-2 * np.abs(f["M"]).max()
    if which == "ei":
        assert p[3] == data.branch["EI"][i] != data.rod.EI  # the point's EI, not the file's starting one
        bad = dict(f, M=f["M"] + (data.rod.EI - p[3]) * (f["u1"][:, None] * f["d1"] + f["u2"][:, None] * f["d2"]))
        assert _kirchhoff_errors(bad, p, data.rod.weight_direction, data.rod.L, defect)[2] > 100 * tol_M


def test_constitutive_law_and_kinematics(files):
    from rodcont.export import point_parameters
    data = files["data"]
    i = data.resolve("F1")
    p = point_parameters(data, i)
    EI, GJ, EA = p[3], p[4], p[5]
    f = rod_fields(data, "F1", 4001)
    d1, d2, d3 = f["d1"], f["d2"], f["d3"]
    scale = np.abs(f["M"]).max()
    M = EI * (f["u1"][:, None] * d1 + f["u2"][:, None] * d2) + GJ * f["u3"][:, None] * d3
    assert np.abs(M - f["M"]).max() <= 1e-13 * scale
    for k, dk in enumerate((d1, d2, d3), 1):
        assert np.abs((f["M"] * dk).sum(axis=1) - f[f"M{k}"]).max() <= 1e-13 * scale
    assert np.abs(np.cross(d1, d2) - d3).max() < 1e-14
    assert np.abs(f["alpha"] - 1 - f["N"] / EA).max() < 1e-14
    np.testing.assert_allclose(f["N"], (f["F"] * d3).sum(axis=1), rtol=0, atol=1e-13 * np.abs(f["F"]).max())
    # torque constant and equal to the stored one; s(L) = l0 (both Gauss rules of the mesh)
    assert np.ptp(f["M3"]) <= 1e-6 * abs(data.branch["torque"][i])
    assert abs(f["M3"].mean() - data.branch["torque"][i]) <= 1e-6 * abs(data.branch["torque"][i])
    assert abs(f["s"][-1] - data.branch["l0"][i]) <= 1e-11
    # the polyline's length is l: the stored stretch (l - L)/L (chords short by h^2 kappa^2 / 24)
    r = np.column_stack([f["x"], f["y"], f["z"]])
    lpoly = np.linalg.norm(np.diff(r, axis=0), axis=1).sum()
    assert abs((lpoly - data.rod.L) / data.rod.L - data.branch["stretch"][i]) < 1e-6
    # finite differences in the exported s: dr/ds = alpha d3 and the Darboux vector
    # u1 = d2_s.d3, u2 = d3_s.d1, u3 = d1_s.d2 (central differences, error O(h^2) ~ 1e-5 here)
    h = np.diff(f["s"])[:, None]
    mid = lambda a: 0.5 * (a[1:] + a[:-1])  # noqa: E731
    drds = np.diff(r, axis=0) / h
    assert np.abs(drds - mid(f["alpha"][:, None] * d3)).max() < 1e-5
    umax = max(np.abs(f[n]).max() for n in ("u1", "u2", "u3"))
    for name, (a, b) in dict(u1=(d2, d3), u2=(d3, d1), u3=(d1, d2)).items():
        fd = (np.diff(a, axis=0) / h * mid(b)).sum(axis=1)
        assert np.abs(fd - mid(f[name])).max() < 1e-5 * umax, name


def test_grid_uniform_in_s(files):
    data = files["data"]
    f = rod_fields(data, "F1", 101, grid="s")
    i = data.resolve("F1")
    assert f["S"][0] == 0.0 and f["S"][-1] == data.rod.L
    np.testing.assert_allclose(np.diff(f["s"]), data.branch["l0"][i] / 100, rtol=1e-12)
    r = _centreline_from_branch(data, "F1", f["S"])
    assert np.abs(np.stack([f["x"], f["y"], f["z"]]) - r).max() == 0.0


def test_rod_fields_rejects_bad_arguments(files):
    data = files["data"]
    for bad in (1, 0, 10**7, 2.5, True):
        with pytest.raises(ExportError):
            rod_fields(data, 0, bad)
    with pytest.raises(ExportError):
        rod_fields(data, 0, 10, grid="t")


# --------------------------------------------------------------------------
# Whole branches, diagram branches
# --------------------------------------------------------------------------
def test_all_as_pvd_series(files, capsys):
    out = files["dir"] / "series.pvd"
    code, stdout, err = run(["export", files["branch"], "--all", "--samples", "20", "-o", out], capsys)
    assert code == 0, err
    data = files["data"]
    root = ET.parse(out).getroot()
    assert root.get("type") == "Collection"
    sets = root.findall("Collection/DataSet")
    assert len(sets) == len(data)
    steps = [float(s.get("timestep")) for s in sets]
    assert steps == sorted(steps) and len(set(steps)) == len(steps)
    for s in sets:
        assert os.path.isfile(files["dir"] / s.get("file"))
    last = ET.parse(files["dir"] / sets[-1].get("file")).getroot()
    pts = np.array(last.find("PolyData/Piece/Points/DataArray").text.split(), float).reshape(-1, 3)
    r = _centreline_from_branch(data, len(data) - 1, np.linspace(0, data.rod.L, 20))
    assert np.abs(pts.T - r).max() == 0.0


def test_all_as_npz(files, capsys):
    out = files["dir"] / "series.npz"
    code, _, err = run(["export", files["branch"], "--all", "--samples", "15", "-o", out], capsys)
    assert code == 0, err
    data = files["data"]
    with np.load(out) as z:
        assert z["x"].shape == (len(data), 15) and z["F"].shape == (len(data), 15, 3)
        np.testing.assert_array_equal(z["phi_L"], data.branch["phi_L"])
        np.testing.assert_array_equal(z["M"][12], rod_fields(data, 12, 15)["M"])


def test_diagram_branch(files, capsys):
    diag = files["diagram"]
    d1 = load_diagram(diag).branches[1]
    ref = rod_fields(d1, 2, 30)
    for args in ([diag + ":1", "--point", "2"], [diag, "--branch", "1", "--point", "2"], [diag + ":1:2"]):
        out = files["dir"] / "diag.npz"
        if out.exists():
            out.unlink()
        code, _, err = run(["export", *args, "--samples", "30", "-o", out], capsys)
        assert code == 0, (args, err)
        with np.load(out) as z:
            np.testing.assert_array_equal(z["x"], ref["x"])
            assert json.loads(str(z["meta"]))["branch"] == "1"
    # point 2 of branch 1 is point 7 of the branch it was copied from
    np.testing.assert_array_equal(ref["M"], rod_fields(files["data"], 7, 30)["M"])


# --------------------------------------------------------------------------
# Errors: one line, exit 2, nothing written
# --------------------------------------------------------------------------
def _error_cases(files):
    b, d, diag = files["branch"], files["dir"], files["diagram"]
    other = str(d / "other.h5")
    shutil.copy(b, other)
    foreign = d / "foreign.h5"
    foreign.write_text("not hdf5\n")
    plain = str(d / "plain.h5")
    import h5py
    with h5py.File(plain, "w") as fh:
        fh["x"] = [1.0]
    link = d / "link.h5"
    if not link.exists():
        os.symlink(b, link)
    o = str(d / "e.csv")
    return [
        (["export", str(d / "missing.h5"), "--point", "0", "-o", o], "no such file"),
        (["export", str(foreign), "--point", "0", "-o", o], "foreign.h5"),
        (["export", plain, "--point", "0", "-o", o], "not a rodcont branch file"),
        (["export", b, "--point", "99", "-o", o], "out of range"),
        (["export", b, "--point", "F7", "-o", o], "fold"),
        (["export", b, "--point", "BP1", "-o", o], "branch point"),
        (["export", b, "--point", "middle", "-o", o], "point label"),
        (["export", b, "--point", "0", "--samples", "1", "-o", o], "--samples"),
        (["export", b, "--point", "0", "--samples", "1000001", "-o", o], "--samples"),
        (["export", b, "--point", "0", "--samples", "many", "-o", o], "--samples"),
        (["export", b, "--point", "0", "--format", "xls", "-o", o], "--format"),
        (["export", b, "--point", "0", "-o", str(d / "nowhere" / "e.csv")], "does not exist"),
        (["export", b, "--point", "0", "--format", "csv", "-o", b], "is the input file"),
        (["export", b, "--point", "0", "--format", "csv", "-o", str(link)], "is the input file"),
        (["export", b, "--point", "0", "--format", "csv", "-o", other], "will not overwrite"),
        (["export", b, "--point", "0", "-o", str(d)], "it is a directory"),
        (["export", b, "--all", "-o", o], "--all"),
        (["export", b, "--all", "--format", "csv", "-o", str(d / "e.txt")], "--all"),
        (["export", b, "-o", o], "--point"),
        (["export", b, "--point", "0", "--all", "-o", str(d / "e.npz")], "not both"),
        (["export", b, "--point", "0", "-o", str(d / "e.txt")], "cannot tell the format"),
        (["export", b, "--point", "0", "--format", "npz", "-o", str(d / "e.vtp")], "suffix"),
        (["export", b, "--point", "0", "-o", str(d / "e.pvd")], "--all"),
        (["export", b, "--all", "-o", str(d / "e.vtp")], ".pvd"),
        (["export", b + ":3", "--point", "4", "-o", o], "two points"),
        (["export", b, "--branch", "1", "--point", "0", "-o", o], "not a diagram"),
        (["export", diag, "--point", "0", "-o", o], "diagram of 2 branches"),
        (["export", diag + ":7", "--point", "0", "-o", o], "no branch 7"),
        (["export", diag + ":0", "--branch", "1", "--point", "0", "-o", o], "two branches"),
        (["animate", b, "-o", str(d / "a.png")], ".gif or .mp4"),
        (["animate", b + ":3", "-o", str(d / "a.gif")], "whole branch"),
        (["animate", str(d / "missing.h5"), "-o", str(d / "a.gif")], "no such file"),
        (["animate", b, "--fps", "0", "-o", str(d / "a.gif")], "--fps"),
        (["animate", b, "-o", str(d / "nowhere" / "a.gif")], "does not exist"),
        (["animate", diag, "-o", str(d / "a.gif")], "diagram of 2 branches"),
    ]


def test_cli_errors(files, capsys):
    d = files["dir"]
    for args, fragment in _error_cases(files):
        before = set(os.listdir(d))
        code, out, err = run(args, capsys)
        assert_one_line_error(code, out, err, fragment)
        assert set(os.listdir(d)) == before, args
    with open(files["branch"], "rb") as fh:
        assert fh.read(20).startswith(b"RODCONT")  # the input is untouched


def test_animate_mp4_needs_ffmpeg(files, capsys):
    from rodcont.export import ffmpeg_available
    if ffmpeg_available():
        pytest.skip("ffmpeg is installed here")
    out = files["dir"] / "a.mp4"
    code, stdout, err = run(["animate", files["branch"], "-o", out], capsys)
    assert_one_line_error(code, stdout, err, "ffmpeg")
    assert not out.exists()


def test_animate_gif(files, capsys):
    import matplotlib
    from PIL import Image
    backend = matplotlib.get_backend()
    had_pyplot = "matplotlib.pyplot" in sys.modules
    out = files["dir"] / "twist.gif"
    code, stdout, err = run(["animate", files["diagram"] + ":1", "-o", out, "--max-frames", "4", "--samples", "30",
                             "--fps", "5"], capsys)
    assert code == 0, err
    with Image.open(out) as im:
        assert im.n_frames == 4
        assert im.size[0] > im.size[1]  # the rod beside the diagram
    assert matplotlib.get_backend() == backend
    assert had_pyplot or "matplotlib.pyplot" not in sys.modules
    assert not [n for n in os.listdir(files["dir"]) if n.endswith(".tmp.gif")]


def test_write_npz_meta_is_json(tmp_path):
    write_npz({"S": np.linspace(0, 1, 3)}, str(tmp_path / "m.npz"), {"a": 1, "b": "two", "c": np.float64(0.5)})
    with np.load(tmp_path / "m.npz") as z:  # no pickle needed
        assert json.loads(str(z["meta"])) == {"a": 1, "b": "two", "c": 0.5}
