"""Regenerate ``tests/data/differential.json``: what the code before the continuation engine computed.

Usage (from the repository root, with the code before the change checked out at ``/work/old``)::

    PYTHONPATH=/work/old/src python tests/data/make_differential.py [--only NAME ...]

Each case is run through the public API or the command line of that code (``rodcont.trace``,
``rodcont.diagram``, ``fold_curve``, ``rodcont trace --conduit``), and what a user reads from it is
kept: the folds (Phi, stretch, the estimated error stored with each), the number of folds and
branch points, the stop sentence, the special points and the number of points. ``tests/test_differential.py`` runs the same cases on the code under test and
compares (folds to 1e-10 in Phi, the stop statuses mapped from these sentences).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
OUT = os.path.join(ROOT, "tests", "data", "differential.json")

TRACE_GAMMAS = (0.0, 0.5, 1.0, 2.0, 5.0, 10.0)
DIAGRAM_GAMMAS = (1.0, 3.0)
# the documented conduit examples at a window that keeps each trace short
CONDUITS = {"straight": 20.0, "arc": 20.0, "bump": 10.0, "helix": 6.0, "taper": 20.0}
# a trace in T from point START_POINT of the Gamma = 1 branch (stretch_max 0.3), over T_RANGE
START_POINT, T_RANGE = 40, (1.0, 60.0)
FOLD_CURVE_RANGE, FOLD_CURVE_FORCED = (0.8, 1.4), (1.2,)


def cli(args) -> int:
    from rodcont.cli import main
    try:
        main([str(a) for a in args])
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


def case_names():
    return ([f"trace_{g:g}" for g in TRACE_GAMMAS] + [f"diagram_{g:g}" for g in DIAGRAM_GAMMAS]
            + [f"conduit_{c}" for c in CONDUITS] + ["trace_T", "fold_curve"])


def _file_summary(path):
    """Folds, branch points and the stop sentence of a branch file (the old reader's dict of arrays)."""
    import rodcont
    d = rodcont.load_branch(path)
    idx = [int(i) for i in d.folds.get("index", [])]
    return dict(folds=[float(v) for v in d.folds.get("phi_L", [])],
                fold_stretch=[float(v) for v in d.folds.get("stretch", [])],
                fold_error=[float(d.branch["error"][i]) for i in idx],
                branch_points=len(d.branch_points.get("index", [])), stop_reason=str(d.attrs["stop_reason"]),
                points=len(d), special=_special(d.branch["kind"], d.branch["phi_L"]))


def _special(kinds, phis):
    """(kind, Phi) of every point that is not regular (events as the old kind, ``event:<sentence>``)."""
    return [[str(k), float(p)] for k, p in zip(kinds, phis) if str(k) != "regular"]


def run_case(name: str, tmp: str) -> dict:
    import rodcont
    if name.startswith("trace_") and name != "trace_T":
        br = rodcont.trace(float(name.split("_")[1]))
        return dict(folds=[f["phi_L"] for f in br.folds], fold_stretch=[f["stretch"] for f in br.folds],
                    fold_error=[f["error"] for f in br.folds], branch_points=len(br.branch_points), stop_reason=br.stop_reason, points=len(br),
                    special=_special(br.table["kind"], br.table["phi_L"]))
    if name.startswith("diagram_"):
        dg = rodcont.diagram(float(name.split("_")[1]))
        return dict(folds=[f["phi_L"] for f in dg.folds], fold_stretch=[f["stretch"] for f in dg.folds],
                    branches=[dict(folds=[f["phi_L"] for f in db.branch.folds], ends=list(db.ends),
                                   fold_error=[f["error"] for f in db.branch.folds],
                                   branch_points=len(db.branch.branch_points), points=len(db.branch))
                              for db in dg.branches])
    if name.startswith("conduit_"):
        kind = name.split("_", 1)[1]
        out = os.path.join(tmp, f"{name}.h5")
        code = cli(["trace", "--gamma", "1", "--conduit", os.path.join(ROOT, "examples", f"conduit_{kind}.toml"),
                    "--phi-max", CONDUITS[kind], "--out", out, "--quiet", "--overwrite"])
        assert code == 0, (name, code)
        return _file_summary(out)
    g1 = os.path.join(tmp, "g1.h5")
    if not os.path.exists(g1):
        rodcont.trace(1.0, stretch_max=0.3, out=g1)
    if name == "trace_T":
        out = os.path.join(tmp, "T.h5")
        code = cli(["trace", "--start", f"{g1}:{START_POINT}", "--param", "T", "--range", *T_RANGE, "--out", out,
                    "--quiet", "--overwrite"])
        assert code == 0, (name, code)
        return _file_summary(out)
    if name == "fold_curve":
        from rodcont.drivers.foldcurve import fold_curve
        res = fold_curve(rodcont.load_branch(g1), 0, "gamma", *FOLD_CURVE_RANGE, forced=FOLD_CURVE_FORCED)
        at = [dict(kind=str(q.kind), gamma=float(q.p), phi_L=float(q.data["phi_L"]),
                   stretch=float(q.data["stretch"])) for q in res["points"] if str(q.kind) in ("bound", "forced")]
        return dict(at=at, stop_reasons=list(res["stop_reasons"]), points=len(res["points"]))
    raise KeyError(name)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="*", default=None)
    args = ap.parse_args()
    import rodcont
    data = json.load(open(OUT)) if os.path.exists(OUT) else {}
    data["description"] = ("Results of the code before the continuation engine (rodcont "
                           f"{rodcont.__version__}, {rodcont.__file__}), by tests/data/make_differential.py")
    cases = data.setdefault("cases", {})
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or case_names():
            t0 = time.perf_counter()
            cases[name] = run_case(name, tmp)
            cases[name]["seconds"] = round(time.perf_counter() - t0, 1)
            print(f"{name}: {cases[name]['seconds']} s", file=sys.stderr, flush=True)
            with open(OUT, "w") as fh:
                json.dump(data, fh, indent=1)


if __name__ == "__main__":
    main()
