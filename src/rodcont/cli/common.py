"""What every command shares: the one-line user error, the rod, reference curve, conduit and tension of the
options, branch files read (an unverified one said so), outputs checked against the inputs, warnings said once
the command has ended."""

from __future__ import annotations

import math
import os

import click

EXIT_USAGE = 2


class UserError(click.ClickException):
    exit_code = EXIT_USAGE


def make_rod(w, EI, GJ, EA, L):
    from ..rod import RodParameters
    wd = click.get_current_context().meta.get("rodcont.weight_direction", (0.0, 0.0, -1.0))
    try:
        return RodParameters(EI=EI, GJ=GJ, EA=EA, w=w, L=L, weight_direction=wd)
    except (ValueError, TypeError) as exc:
        raise UserError(str(exc)) from None


def reference_curve(rod, straight_only: str | None = None, source: str | None = None):
    """The --reference curve for ``rod`` (None for the straight span); ``straight_only`` names a
    command that needs the straight reference. ``source``: where the specification comes from when
    it is not ``--reference`` (a conduit file's ``reference`` key), the label of its errors."""
    spec = click.get_current_context().meta.get("rodcont.reference", "straight")
    label = source or f"--reference {spec}"
    if spec is None or not spec.strip():
        raise UserError(f"{source}: needs KIND[:ARGS] (straight, bump:H,THETA, ...)" if source else
                        "--reference needs KIND[:ARGS] (straight, bump:H,THETA, ...)")
    if spec.strip() == "straight":
        return None
    if straight_only:
        raise UserError(f"{straight_only} needs the straight reference (the straight rod state lives there); "
                        f"got {label}")
    from ..curves import parse_reference
    try:
        with np_errstate():
            curve = parse_reference(spec, rod.L)
    except (ValueError, ArithmeticError) as exc:
        msg = str(exc)
        if source:  # parse_reference words its errors for --reference: say where the specification is
            from ..contact import unworded_reference_error
            raise UserError(f"{source}: {unworded_reference_error(msg, spec)}") from None
        raise UserError(f"--reference {spec}: {msg}" if not msg.startswith("--reference") else msg) from None
    if abs(curve.span - rod.L) > 1e-9 * rod.L:
        raise UserError(f"{label}: its span {curve.span:.15g} differs from --L {rod.L:.15g}; "
                        f"give --L {curve.span:.15g}")
    return curve


def conduit_of(path, rod):
    """``(curve, wall)`` of a ``--conduit FILE`` (:func:`rodcont.contact.load_conduit`); ``(None, None)`` without
    one. Without a ``reference`` in the file the axis is ``--reference``."""
    if path is None:
        return reference_curve(rod), None
    from ..contact import ConduitError, load_conduit
    ctx = click.get_current_context()
    given = ctx.meta.get("rodcont.reference", "straight")
    try:
        curve, wall = load_conduit(path, rod.L, reference=given)
    except ConduitError as exc:
        raise UserError(f"--conduit {exc}") from None
    # a file without an axis (or naming "straight", which then is --reference's too) leaves --reference's
    return (reference_curve(rod) if curve is None else curve), wall


def np_errstate():
    import numpy as np
    return np.errstate(all="ignore")


def tension_of(gamma, rod):
    """``(gamma, T)``: exactly one of --gamma and --T; Gamma needs a weight."""
    T = click.get_current_context().meta.get("rodcont.T")
    if T is not None and gamma is not None:
        raise UserError("give --gamma or --T, not both")
    if T is None and gamma is None:
        raise UserError("--gamma (T = gamma w L) or --T is required")
    if T is None:
        if rod.w == 0:
            raise UserError("--gamma needs a weight (--w > 0): give the tension with --T")
        T = rod.tension(gamma)
        if not math.isfinite(T):
            raise UserError(f"--gamma {gamma:g} gives a tension that is not finite")
    return gamma, T


def stretch_warning(rod, T) -> None:
    """Warn of a tension beyond half of EA: the model is right for any stretch, a real rod is not, and this
    is nearly always a forgotten --EA. Said once the command has ended: a command the library then refuses
    (T = 1e30 'is not a usable number') gives its one-line error alone (the fuzz's numeric probes)."""
    from ..drivers.solve import euler_tension
    # (below the Euler load, or not finite, the tension is refused anyway)
    if math.isfinite(T) and abs(T) > 0.5 * rod.EA and T > euler_tension(rod):
        warn_later(f"T = {T:g} stretches the rod by T/EA = {T / rod.EA:.3g} (EA = {rod.EA:g}"
                    f"{', the paper default' if rod.EA == 255.0 else ''}): give the rod's --EA if it is not meant")


def file_meta():
    return {"config": click.get_current_context().meta.get("rodcont.config", "")}


# warnings printed once the command has ended (on an error its one line stands alone)
PENDING: list = []


def warn_later(message: str) -> None:
    if message not in PENDING:
        PENDING.append(message)


def flush_pending() -> None:
    while PENDING:
        echo_err(f"rodcont: warning: {PENDING.pop(0)}")


# numpy's floating-point noise (an overflow in a rejected trial step, ...), not something the library says
NUMPY_NOISE = r"(overflow|underflow|invalid value|divide by zero) encountered"


def worded(message: str) -> str:
    """A library message in one line, in the words of the parameter this command continues (its ``T = 5``
    for the engine's ``p = 5``: :func:`rodcont.result.in_terms_of`)."""
    ctx = click.get_current_context(silent=True)
    param = ctx.meta.get("rodcont.param") if ctx is not None else None
    text = " ".join(str(message).split())
    if param in (None, "phi_L"):
        return text
    from ..result import in_terms_of
    return in_terms_of(text, param)


def show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` while a command runs: what the library warns of is said once the command has
    ended, one line each (``rodcont: warning: ...``)."""
    warn_later(worded(str(message)))


def _read(loader, *args):
    """A branch or diagram file read by ``loader``; a file without rodcont's checksum is read and said so."""
    import warnings

    from ..branchfile import BranchFileError, UnverifiedFileWarning
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", UnverifiedFileWarning)
            data = loader(*args)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    for w in said:
        if issubclass(w.category, UnverifiedFileWarning):
            warn_later(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return data


def load_branch_file(path, branch=None):
    from ..branchfile import load_branch
    return _read(load_branch, path, branch)


def load_any_file(path):
    from ..branchfile import load_diagram
    return _read(load_diagram, path)


def point_spec(spec, what="--start"):
    from ..branchfile import BranchFileError, split_spec
    try:
        path, branch, label = split_spec(spec, what)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    data = load_branch_file(path, branch)
    try:
        pt = data.point(label)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None
    return data, pt, label


def explicit(*names):
    ctx = click.get_current_context()
    return [n for n in names if ctx.get_parameter_source(n) not in (click.core.ParameterSource.DEFAULT, None)]


def input_files(loaded=(), files=()) -> list:
    """Every file this command reads (:func:`rodcont.safeio.command_inputs`): its --config file, the survey of
    --reference well:FILE, its --conduit file and that file's survey, the branch files ``files`` and the
    ``loaded`` branches or diagrams (with the surveys of their reference curves)."""
    from ..safeio import command_inputs
    ctx = click.get_current_context()
    return command_inputs(config=ctx.meta.get("rodcont.config_file"), reference=ctx.meta.get("rodcont.reference"),
                          conduit=ctx.params.get("conduit"), branch_files=files, loaded=loaded)


def check_out(out, inputs=(), overwrite=False, what="--out", loaded=()):
    """An output that is none of the command's inputs (any name), kept if it exists unless ``overwrite``."""
    from ..branchfile import BranchFileError, check_output
    try:
        return check_output(out, list(inputs) + input_files(loaded), overwrite, what)
    except BranchFileError as exc:
        raise UserError(str(exc)) from None


def image_out(path, inputs=(), overwrite=False, loaded=()):
    """A PNG/GIF/MP4 output path: a writable name that is not an input, an existing file only with
    --overwrite (the suffix is checked by each command)."""
    return check_out(path, inputs, overwrite, "-o", loaded)


def file_identity(path):
    """What tells one published version of ``path`` from another (a publication renames a new file over it)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_dev, st.st_mtime_ns, st.st_size


def echo_err(msg: str) -> None:
    try:
        click.echo(msg, err=True)
    except OSError:
        pass
