"""The fold and branch-point tables printed by trace, diagram and folds, and the warnings beside them."""

from __future__ import annotations

import math

import click


def fold_warnings(data) -> None:
    """A fold only bracketed, or located above --fold-error, is said in the summary (the table marks it too); so is
    where a trace in a conduit went deeper than the penetration guard."""
    import json
    f = data.folds
    index = list(f.get("index", []))
    located = list(f.get("located", [1] * len(index)))
    fold_error = (data.settings.get("adaptive") or {}).get("fold_error")
    deep = json.loads(data.attrs.get("penetration_guard", "[]") or "[]")  # a contact law too soft for the loads
    if deep:
        click.echo(f"warning      the rod sits deeper than 1e-3 of the clearance inside the wall from {data.param} "
                   f"between {deep[0]:.10g} and {deep[1]:.10g} ({deep[2]:.2g} there): the contact law is too soft "
                   f"for these loads (a larger force_scale in the conduit file)")
    for j, i in enumerate(index):
        phi = f["phi_L"][j]
        if not located[j]:
            click.echo(f"warning      fold F{j + 1} at phi_L = {phi:.10g} is bracketed, not located: its location did "
                       f"not converge (the values are those of the nearest converged point); a smaller --ds-max "
                       f"or a larger --N-max may locate it")
        err = float(data.table["error"][int(i)]) if "error" in data.table else math.nan
        if fold_error and err > float(fold_error):
            click.echo(f"warning      fold F{j + 1} at phi_L = {phi:.10g} has an estimated error {err:.2g} above "
                       f"--fold-error {float(fold_error):g} (its mesh could not be refined enough: --N-max)")


def fold_table(data):
    f = data.folds
    if not len(f.get("index", [])):
        click.echo("no folds")
        return
    # a branch traced in another parameter folds in that parameter: its value leads the row
    param = data.param if data.param != "phi_L" else None
    head = f" {param:>18}" if param else ""
    click.echo(f"{'fold':>4} {'index':>6}{head} {'phi_L':>18} {'stretch':>18} {'torque':>16} {'l0':>16} "
               f"waves before->after")
    located = f.get("located", [1] * len(f["index"]))
    for j in range(len(f["index"])):
        mark = "  (+1 wave)" if f["waves_after"][j] > f["waves_before"][j] else ""
        mark += stable_side(f, j)
        mark += "" if located[j] else "  (bracketed, not located)"
        value = f" {float(data.point(int(f['index'][j]))[param]):18.12g}" if param else ""
        click.echo(f"F{j + 1:<3d} {f['index'][j]:6d}{value} {f['phi_L'][j]:18.12f} {f['stretch'][j]:18.12f} "
                   f"{f['torque'][j]:16.10f} {f['l0'][j]:16.10f} {f['waves_before'][j]:d} -> {f['waves_after'][j]:d}"
                   f"{mark}")


def stable_side(f, j) -> str:
    ub = f.get("unstable_before", [-1] * (j + 1))[j]
    ua = f.get("unstable_after", [-1] * (j + 1))[j]
    if ub < 0 or ua < 0:
        return ""
    side = {(True, False): "before", (False, True): "after", (True, True): "both", (False, False): "neither"}
    return f"  stable: {side[(ub == 0, ua == 0)]} ({ub} | {ua} unstable)"


def diagram_folds(folds):
    if not folds:
        click.echo("no folds")
        return
    click.echo(f"{'branch':>6} {'phi_L':>18} {'stretch':>16} {'torque':>14} {'l0':>14} waves")
    for f in folds:
        mark = "  <- +1 wave" if f["waves_after"] > f["waves_before"] else ""
        mark += stable_side({k: [v] for k, v in f.items()}, 0)
        click.echo(f"{f['branch']:6d} {f['phi_L']:18.12f} {f['stretch']:16.10f} {f['torque']:14.8f} "
                   f"{f['l0']:14.10f} {f['waves_before']} -> {f['waves_after']}{mark}")


def user_folds(data) -> None:
    """The folds and branch points of a user's problem (``kind = "bvp"``, rodcont.bvp): every number column."""
    from ..bvp import describe
    click.echo(describe(data))
    skip = ("arclength", "kind", "located", "defect", "dp_ds")
    cols = [data.param] + [c for c in data.table if c not in skip and c != data.param]
    for what, table in (("fold", data.folds), ("branch point", data.branch_points)):
        if not len(table):
            click.echo(f"no {what}s")
            continue
        click.echo(f"{'label':<6} {'index':>6} " + " ".join(f"{c:>22}" for c in cols))
        for row in table:
            i = int(row["index"])
            mark = "" if data.table["located"][i] else "  (bracketed, not located)"
            click.echo(f"{row['label']:<6} {i:6d} " + " ".join(f"{float(data.table[c][i]):22.15g}" for c in cols)
                       + mark)


def diagram_unfinished(file, d) -> str:
    """What the header of an interrupted diagram adds: which branch is unfinished, and how to finish it."""
    if d.attrs.get("status") not in ("interrupted", "running"):
        return ""
    open_ = [b.name for b in d.branches if str(b.status) in ("interrupted", "running")]
    part = f"; branch {', '.join(open_)} unfinished, its folds not listed" if open_ else ""
    return f" (INTERRUPTED{part}: finish it with rodcont diagram --resume {file})"


def diagram_branches(dg) -> None:
    """One line per branch of a diagram, its ends, and what was detected but not located along it."""
    for j, db in enumerate(dg.branches):
        click.echo(f"  {j}: {len(db.branch):4d} points {len(db.branch.folds):2d} folds {db.time:6.2f} s  "
                   f"{db.origin}")
        if db.ends[0] == db.ends[1]:  # both directions stopped by the same guard: say it once
            click.echo(f"       both ends: {db.ends[0]}")
        else:
            click.echo(f"       ends: {db.ends[0]}")
            click.echo(f"             {db.ends[1]}")
        for kind, a, b in db.branch.unlocated:
            click.echo(f"       warning: a {kind.replace('_', ' ')} between phi_L = {a:.10g} and {b:.10g} was "
                       f"detected but could not be located; it is not in the tables")
        for a, b, n0, n1 in db.branch.missed_crossings:
            click.echo(f"       warning: unstable modes {n0} -> {n1} between phi_L = {a:.10g} and {b:.10g}: more "
                       f"eigenvalues crossed zero than the located folds and branch points account for (unseen "
                       f"bifurcations; the counts between are corrected)")
    for origin, why in dg.skipped:
        click.echo(f"  not traced: {origin}: {why}")
