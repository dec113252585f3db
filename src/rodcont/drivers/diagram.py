"""Whole response diagrams: every branch in a window of ``phi_L``, every fold, every new helical wave.

1. **Critical twists** (:func:`critical_twists`): the weightless straight rod
   under the same tension is an exact solution for every ``phi_L``, and the
   tangent operator along it is affine in ``phi_L`` (``J(Phi) = A + Phi B``:
   the twist enters only through the torque ``m = GJ alpha Phi / L``), so the
   twists where it is singular are the real eigenvalues of the pencil
   ``A + Phi B``: found on a coarse mesh by a dense generalised eigensolver,
   refined on a fine one by inverse iteration. Each is a double root (a
   circle of helical modes, O(2) symmetry) and is listed once.
2. **Seeds**: the primary branch from the planar sag at ``Phi = 0``, and one
   start per interval between consecutive critical twists, at its midpoint,
   reached from the exact weightless straight state by a homotopy in the
   weight (:func:`rodcont.drivers.trace.straight_seed`). The critical twists are
   computed beyond ``phi_max`` too, so the interval that straddles it is seeded
   (at its midpoint, or halfway between its lower end and ``phi_max`` when the
   midpoint lies outside the window): a branch that starts there may fold inside.
3. **Branches**: each seed traced both ways to its guards (the trace driver:
   adaptive mesh, validity and accuracy guards, located folds, the unstable-mode
   count checked and corrected), with a forced point at every seed's ``Phi``. Each
   branch is a :class:`rodcont.branch.Branch` whose ``status_first`` and ``status``
   say why its two ends end. A seed whose solution equals a point of an
   already traced branch at that ``Phi`` (compared on a common grid of ``S``)
   lies on it and is not traced again; two traced branches that share a
   solution are one, kept once.
4. **Deflation** (optional, :func:`deflate`): deflated Newton (Farrell,
   Birkisson & Funke 2015) at chosen ``Phi`` finds solutions that are none of
   the known ones; each new one is traced both ways like a seed.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..blas import with_one_blas_thread
from ..branch import Branch
from ..continuation import Kind, Point
from ..linalg import LU, SingularMatrix, max_norm
from ..result import Status, Table
from ..rod import RodParameters
from ..system import RodSystem, check_callable, check_mapping, check_number, check_numbers
from .solve import check_tension
from .trace import Recorder, TraceError, TraceOptions, _mesh_group, file_meta, run, straight_seed


# --------------------------------------------------------------------------
# Critical twists
# --------------------------------------------------------------------------
def critical_twists(rod: RodParameters | None = None, T: float = 10.0, phi_max: float = 40.0, phi_min: float = 0.0,
                    k: int = 5, N_fine: int = 60, *, l0: float | None = None) -> list[float]:
    """Twists ``Phi_n`` in ``(phi_min, phi_max]`` where the straight weightless rod under tension ``T`` buckles
    (or, with ``l0``, the rod of that unstressed length: under length control, ``T`` solved for).

    From the tangent operator of the discretised rod along the exact straight
    state (the rod's stiffnesses, its weight set to 0; its own end conditions: under length control the
    tension is an unknown and ``l0`` a constraint). Coarse roots: the real
    finite eigenvalues of the pencil ``(A, -B)`` on ``N = max(8, phi_max/4)``
    subintervals; each refined by inverse iteration with the shift at the
    coarse value on ``N_fine`` subintervals, to about 1e-12 relative.
    """
    from .trace import trace_ends
    rod = RodParameters() if rod is None else rod
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    ends = None
    if l0 is not None:
        l0 = check_number("l0", l0, positive=True)
        ends = trace_ends(l0=l0)
        T = rod.EA * (rod.L / l0 - 1.0)  # the straight rod's, alpha = L / l0
    T = check_number("T", T)
    phi_max, phi_min = check_number("phi_max", phi_max), check_number("phi_min", phi_min)
    if not phi_min < phi_max:
        raise ValueError("phi_min must be below phi_max")
    if max(abs(phi_max), abs(phi_min)) > 200.0:
        raise ValueError("critical twists are computed up to |phi| = 200 rad (a dense eigenproblem on a mesh "
                         "that resolves them); choose a smaller window")
    N_fine = check_number("N_fine", N_fine, integer=True)
    k = check_number("k", k, integer=True)
    if N_fine < 1:
        raise ValueError(f"N_fine (subintervals of the refining mesh) must be an integer >= 1, got {N_fine}")
    weightless = RodParameters(EI=rod.EI, GJ=rod.GJ, EA=rod.EA, w=0.0, L=rod.L,
                               weight_direction=rod.weight_direction)
    check_tension(weightless, T)
    if _none_below(weightless, T, max(abs(phi_max), abs(phi_min))):
        return []
    import scipy.linalg as sl
    N0 = max(8, int(math.ceil(max(abs(phi_max), abs(phi_min)) / 4)))
    coarse = _pencil(weightless, T, N0, k, ends)
    A, B = (M.toarray() for M in coarse)
    with np.errstate(all="ignore"):
        ev = sl.eigvals(A, -B)
    ev = ev[np.isfinite(ev)]
    # each root is double, and rounding splits a double root into a pair off the axis by the square root of its
    # error: at T L^2/EI = 1e9 the root 49.648 came as 49.648 +- 1.1e-4 i on one machine (dropped at 1e-6, not on
    # another); the pencil has no complex eigenvalue in the window there, and inverse iteration refines each
    ev = np.sort(ev[np.abs(ev.imag) <= 1e-3 * (1 + np.abs(ev))].real)
    ev = ev[(ev > phi_min - 1.0) & (ev < phi_max + 1.0)]
    roots = []
    for v in ev:  # O(2): each root twice; keep one per cluster
        if not roots or abs(v - roots[-1]) > 1e-5 * (1 + abs(v)):
            roots.append(v)
    Af, Bf = _pencil(weightless, T, max(N_fine, 2 * N0), k, ends)
    out = []
    for r in roots:
        phi = _refine(Af, Bf, float(r))
        if phi_min < phi <= phi_max:
            out.append(phi)
    return sorted(out)


#: the largest ratio |T| L^2 / EI of the tension's terms to the bending ones the pencil resolves: its roots lose
#: those digits to rounding (1e-12 off up to 1e9; at 1e10 a root was missed, at 1e11 they were 6 rad off)
MAX_TENSION_RATIO = 1e9


def _none_below(rod: RodParameters, T: float, phi: float) -> bool:
    """True where the straight rod has no critical twist up to ``phi`` (closed form, tests/closed_forms.py: roots
    need ``mu^2 > 4 tau``, ``mu = GJ Phi / EI``, ``tau = T L^2 / (EI alpha)``, ``alpha = 1 + T / EA``); a tension
    whose terms swamp the bending ones by more than :data:`MAX_TENSION_RATIO` is refused otherwise (``ValueError``):
    ``critical --T 1e20`` printed 24.99 where the closed form has none below 42.6."""
    tau = T * rod.L**2 / (rod.EI * (1.0 + T / rod.EA))
    if tau > 0 and rod.GJ * phi / rod.EI <= 2.0 * math.sqrt(tau):
        return True
    if abs(T) * rod.L**2 / rod.EI > MAX_TENSION_RATIO:
        raise ValueError(f"T = {T:.6g} is {abs(T) * rod.L**2 / rod.EI:.3g} times the bending stiffness EI/L^2: "
                         f"the critical twists lose their digits to rounding beyond {MAX_TENSION_RATIO:g} (they "
                         f"start at Phi = {2.0 * rod.EI * math.sqrt(max(tau, 0.0)) / rod.GJ:.6g})")
    return False


def _pencil(rod: RodParameters, T: float, N: int, k: int, ends=None, breakpoints=None):
    """``A, B`` with ``J(Phi) = A + Phi B`` along the straight state (exact: the residual is affine in Phi there),
    in the problem's own units: ``R A D, R B D`` with the unknowns by their scales (``D``: deflections by ``L``,
    forces by ``EI/L^2``) and each row by its largest entry (``R``). The pencil's eigenvalues are the same; its
    inverse iteration then converges alike in any units (on the raw pencil a critical twist came out 7e-8 off
    with lengths x 1e-3 and forces x 1e6: tests/test_units.py)."""
    from ..stability import _unknown_scales
    s = RodSystem(rod, T=T, N=N, k=k, ends=ends, breakpoints=breakpoints)
    J0 = s.disc.linearise(s.straight_state(0.0), s.params(0.0))[1]
    J1 = s.disc.linearise(s.straight_state(1.0), s.params(1.0))[1]
    D = sp.diags(_unknown_scales(s, s.params(0.0)))
    A, B = (J0 @ D).tocsr(), ((J1 - J0) @ D).tocsr()
    rows = np.maximum(abs(A).max(axis=1).toarray().ravel(), abs(B).max(axis=1).toarray().ravel())
    R = sp.diags(1.0 / np.where(rows > 0, rows, 1.0))
    return (R @ A).tocsc(), (R @ B).tocsc()


def _refine(A, B, phi: float, iterations: int = 8) -> float:
    """Inverse iteration on ``(A + sigma B)^{-1} B`` (eigenvalue ``1/(sigma - Phi)``), shift kept at ``phi``."""
    try:
        lu = LU((A + phi * B).tocsc())
    except SingularMatrix:
        return phi
    rng = np.random.default_rng(11)
    v = rng.standard_normal(A.shape[0])
    est = phi
    for _ in range(iterations):
        y = lu.solve(B @ v)
        mu = float(v @ y) / float(v @ v)
        if not math.isfinite(mu) or mu == 0:
            break
        new = phi - 1.0 / mu
        v = y / np.linalg.norm(y)
        if abs(new - est) <= 1e-13 * (1 + abs(new)):
            est = new
            break
        est = new
    return est


# --------------------------------------------------------------------------
# Comparing solutions on different meshes
# --------------------------------------------------------------------------
def shape_signature(system: RodSystem, x: np.ndarray, n: int = 200) -> np.ndarray:
    """``Delta1, Delta2`` and ``phi'`` on ``n`` points of ``[0, L]``: comparable across meshes."""
    S = np.linspace(*system.model.interval, n)
    d = system.disc
    return np.concatenate([d.evaluate(x, S, 0), d.evaluate(x, S, 1), d.evaluate(x, S, 2, 1) * system.rod.L / 10])


def same_solution(a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> bool:
    return max_norm(a - b) <= tol * (1.0 + max(max_norm(a), max_norm(b)))


# --------------------------------------------------------------------------
# Deflation
# --------------------------------------------------------------------------
def deflate(system: RodSystem, phi_L: float, known: Sequence[np.ndarray], guesses: Sequence[np.ndarray],
            power: float = 2.0, shift: float = 1.0, tol: float = 1e-10, max_iter: int = 80,
            max_new: int = 10) -> list[np.ndarray]:
    """Further solutions of ``F(x, phi_L) = 0`` on ``system``'s mesh, none of them in ``known``.

    Deflated Newton (Farrell, Birkisson & Funke, SIAM J. Sci. Comput. 37, 2015):
    Newton on ``G(x) = M(x) F(x)``, ``M(x) = prod_i (1 / |x - r_i|^power + shift)``
    (``|.|`` the root-mean-square of the unknowns in the problem's own scales,
    ``arclength_scale``), whose Jacobian is ``M (J + F g^T)`` with
    ``g = grad log M``: the step is ``-J^{-1} F / (1 + g . J^{-1} F)`` (one LU
    per iteration, as Newton's), damped by halving while ``|G|`` does not
    fall. Each guess is tried against every known root and every root found
    so far; the new roots (converged with plain Newton at the end) are returned.
    """
    roots = [np.asarray(r, float) for r in known]
    found: list[np.ndarray] = []
    p = system.params(phi_L) if system.param == "phi_L" else system.base
    n = system.disc.size
    scale = getattr(system, "arclength_scale", None)
    sx = np.asarray(scale()[0], float) if scale is not None else np.ones(n)
    w = 1.0 / (n * sx**2)
    rng = np.random.default_rng(2015)

    def log_m_and_grad(x):
        logm, g = 0.0, np.zeros(n)
        for r in roots:
            d = x - r
            nd2 = max(float((w * d) @ d), 1e-300)
            m = nd2 ** (-power / 2) + shift
            logm += math.log(m)
            g += -power * nd2 ** (-power / 2 - 1) * (w * d) / m
        return logm, g

    def merit(x):
        F = system.disc.residual(x, p)
        if not np.all(np.isfinite(F)):
            return math.inf
        return math.log(max(float(np.linalg.norm(F)), 1e-300)) + log_m_and_grad(x)[0]

    for guess in guesses:
        if len(found) >= max_new:
            break
        x = np.asarray(guess, float).copy()
        # a guess on a known root is where deflation is infinite: start beside it
        if any(max_norm(x - r) <= 1e-8 * (1 + max_norm(r)) for r in roots):
            x = x + 1e-2 * sx * rng.standard_normal(n)
        x = _deflated_newton(system, p, x, log_m_and_grad, merit, tol, max_iter)
        if x is None:
            continue
        r = system.disc.newton(x, p, tol=tol)
        if not r.converged:
            continue
        if any(max_norm(r.x - q) <= 1e-6 * (1 + max_norm(q)) for q in roots):
            continue
        roots.append(r.x)
        found.append(r.x)
    return found


def _deflated_newton(system, p, x, log_m_and_grad, merit, tol: float, max_iter: int):
    """Damped deflated Newton from ``x`` (see :func:`deflate`): the point it converges to, or None."""
    for _ in range(max_iter):
        F, J, _ = system.disc.linearise(x, p)
        if not np.all(np.isfinite(F)):
            return None
        try:
            dx0 = LU(J).solve(-F)
        except SingularMatrix:
            return None
        _, g = log_m_and_grad(x)
        denom = 1.0 - float(g @ dx0)  # 1 + g . J^{-1} F with J^{-1} F = -dx0
        if not math.isfinite(denom) or abs(denom) < 1e-14:
            return None
        dx = dx0 / denom
        if max_norm(dx0) <= tol * (1 + max_norm(x)):
            return x
        m0, lam = merit(x), 1.0
        while lam >= 1.0 / 64 and not merit(x + lam * dx) < m0:
            lam *= 0.5
        if lam < 1.0 / 64:
            return None
        x = x + lam * dx
    return None


# --------------------------------------------------------------------------
# The diagram
# --------------------------------------------------------------------------
@dataclass
class DiagramBranch:
    branch: Branch
    origin: str
    ends: tuple = ("", "")        # why it ends at its first and at its last point
    seed_phi: float = math.nan
    time: float = 0.0

    @property
    def statuses(self) -> tuple:
        """The :class:`rodcont.result.Status` of its first and its last end."""
        return (self.branch.status_first, self.branch.status)


@dataclass
class Diagram:
    gamma: float
    T: float
    rod: RodParameters
    critical: list
    branches: list = field(default_factory=list)
    skipped: list = field(default_factory=list)   # (origin, reason) of seeds not traced
    elapsed: float = 0.0
    status: Status = Status.RUNNING               # COMPLETE, or INTERRUPTED
    attrs: dict = field(default_factory=dict)     # the root attributes of its file
    resumed: list = field(default_factory=list)   # complete branches of an interrupted run, not traced again
    tracing: tuple | None = None                  # (j, branch) being traced: an interrupt marks it in the file
    ends: object = None                           # the end conditions (rodcont.ends.RodEnds) other than Phi, T

    @property
    def folds(self) -> Table:
        """Every fold of every branch, sorted by phi_L, with its branch number (rows, or columns by name)."""
        out = []
        for j, db in enumerate(self.branches):
            for f in db.branch.folds:
                out.append(dict(f, branch=j))
        return Table(sorted(out, key=lambda f: f["phi_L"]), columns=("branch", "phi_L", "stretch", "torque", "l0",
                                                                      "waves_before", "waves_after", "index"))


@with_one_blas_thread
def diagram(gamma: float | None = None, rod: RodParameters | None = None, N: int = 15, k: int = 5, *,
            T: float | None = None, l0: float | None = None, out: str | None = None, overwrite: bool = False,
            deflate_at: Sequence[float] = (), callback: Callable[[Point], None] | None = None,
            progress: Callable[[str], None] | None = None, meta: dict | None = None, store_every: int = 1,
            resumed: Sequence[DiagramBranch] = (), **options) -> Diagram:
    """The whole response diagram of the twisted heavy rod at ``gamma`` (or tension ``T``, or under length control
    at the unstressed length ``l0``, the tension solved for at each point) in ``[phi_min, phi_max]``.

    ``options``: the fields of :class:`rodcont.drivers.trace.TraceOptions`,
    applied to every branch. ``deflate_at``: values of ``phi_L`` where
    deflated Newton looks for solutions the seeds missed. ``progress`` gets one
    line per branch as it is done. ``resumed``: the complete branches of an interrupted run of this very
    diagram, in their order (:func:`rodcont.restart.resume_diagram`): each is kept where the run reaches its
    seed again, not traced. An interrupted run marks its file and the branch it was tracing ``interrupted``.

    The branches are traced at once, each seed's two directions as two jobs, on a process pool of ``jobs``
    workers (the default None: the usable cores, :func:`usable_cores`; the pool :mod:`rodcont.drivers.sweep`
    uses) or on ``executor=`` (any ``concurrent.futures`` one, e.g. a Dask ``client.get_executor()``): the same
    branches, in the same order, as ``jobs=1``, which traces them one after the other (as does a resumed run,
    and a diagram inside a worker process). A ``callback`` sees each branch's points as the serial run's
    does, once its jobs are done; its ``idle()``, if it has one, is called while the workers trace (a
    KeyboardInterrupt from either ends the run as between two points:
    test_an_interrupted_diagram_is_marked_and_resume_finishes_it).
    """
    from .trace import _options
    executor, jobs = options.pop("executor", None), options.pop("jobs", None)
    opts = _options(options, "diagram()")
    rod, T = _rod_and_tension(gamma, rod, T, l0)
    ends = None
    if l0 is not None:
        from .trace import trace_ends
        ends = trace_ends(l0=l0)
    N, k, deflate_at, resumed, store_every = _checked(N, k, deflate_at, callback, progress, meta, resumed, ends,
                                                      store_every)
    t_start = time.perf_counter()
    beyond = critical_twists(rod, T, phi_max=_beyond(opts.phi_max), phi_min=0.0, k=k, l0=l0)
    crit = [c for c in beyond if c <= opts.phi_max]
    seeds = seed_twists(beyond, opts.phi_min, opts.phi_max)
    bopts = TraceOptions(**dict(opts.as_dict(), forced=tuple(sorted(set(opts.forced) | set(seeds) | set(deflate_at)))))
    dg = Diagram(gamma=rod.gamma(T) if rod.w > 0 else math.nan, T=T, rod=rod, critical=crit, resumed=list(resumed))
    dg.ends = ends
    dg.attrs = file_meta(rod, T, N, k, "phi_L", opts, RodSystem(rod, T=T, N=N, k=k, ends=ends),
                         dict(kind="diagram", critical_twists=np.asarray(crit), seeds=np.asarray(seeds),
                              deflate_at=np.asarray(deflate_at), **(meta or {})))
    writer = None if out is None else _open_diagram(out, overwrite, dg, store_every, RodSystem(rod, T=T, N=N, k=k))
    note = progress or (lambda msg: None)
    try:
        if dg.resumed or not _parallel(jobs, executor, len(seeds) + 1):
            _trace_seeds(dg, rod, T, N, k, seeds, beyond, bopts, writer, callback, note, ends)
        else:
            _trace_seeds_parallel(dg, rod, T, N, k, seeds, beyond, bopts, writer, callback, note, ends, executor,
                                  jobs)
        for phi in deflate_at:
            _trace_deflated(dg, rod, T, phi, N, k, opts, bopts, writer, callback, note)
        _drop_duplicates(dg, writer)
        dg.status = Status.COMPLETE
    finally:
        dg.elapsed = time.perf_counter() - t_start
        if dg.status != Status.COMPLETE:
            dg.status = Status.INTERRUPTED
        if writer is not None:
            if dg.status == Status.INTERRUPTED:
                _mark_interrupted(writer, dg)
            _write_folds(writer, dg)
            writer.close(f"{len(dg.branches)} branches" if dg.status == Status.COMPLETE else
                         f"interrupted ({len(dg.branches)} branches complete)", dg.status)
    return dg


def _checked(N, k, deflate_at, callback, progress, meta, resumed, ends, store_every) -> tuple:
    """:func:`diagram`'s arguments checked (one line each): ``(N, k, deflate_at, resumed, store_every)``."""
    N = check_number("N", N, integer=True)
    k = check_number("k", k, integer=True)
    deflate_at = check_numbers("deflate_at", deflate_at)
    check_callable("callback", callback, "a function of the point")
    check_callable("progress", progress, "a function of a line of text")
    check_mapping("meta", meta)
    given = resumed
    resumed = list(resumed) if hasattr(resumed, "__iter__") and not isinstance(resumed, (str, bytes)) else [None]
    if not all(isinstance(db, DiagramBranch) for db in resumed):
        raise TypeError(f"resumed must be a sequence of DiagramBranch (the complete branches of the interrupted "
                        f"run), got {given!r}")
    if deflate_at and ends is not None:
        raise ValueError("deflation (--deflate) works with the tension imposed, not under length control (--l0)")
    store_every = check_number("store_every", store_every, integer=True)
    if store_every < 1:
        raise ValueError(f"store_every must be >= 1, got {store_every}")
    return N, k, deflate_at, resumed, store_every


def _open_diagram(out: str, overwrite: bool, dg: Diagram, store_every: int, system: RodSystem):
    """The diagram's file writer (its mesh group that of ``system``); a resumed file is replaced only once it holds
    its complete branches again."""
    from ..branchfile import BranchWriter, check_output
    out = check_output(out, overwrite=overwrite)
    writer = BranchWriter(out, dg.attrs, store_every=store_every,
                          min_points=sum(len(db.branch) for db in dg.resumed) or 1)
    _mesh_group(writer, system)
    return writer


def _mark_interrupted(writer, dg: Diagram) -> None:
    """The branch an interrupt stopped: marked ``interrupted`` in its group (``folds`` and the resume read
    it), or dropped when it holds no point yet."""
    if dg.tracing is None:
        return
    j, branch = dg.tracing
    where = f"branches/{j}"
    group = writer.groups.get(where)
    if group is None:
        return
    group.drain()
    if group.n == 0:
        del writer.f[where]
        writer.groups.pop(where)
        return
    branch.status, branch.message = Status.INTERRUPTED, "interrupted"
    _branch_attrs(writer, j, branch)


def _resumed_branch(dg: Diagram, origin: str, writer) -> DiagramBranch | None:
    """The next complete branch of the run being resumed, if it is the one from ``origin``: copied into the
    file as branch ``len(dg.branches)``."""
    if not dg.resumed or dg.resumed[0].origin != origin:
        return None
    db = dg.resumed.pop(0)
    if writer is not None:
        j, b = len(dg.branches), db.branch
        group = writer.group(f"branches/{j}", attrs=dict(origin=origin))
        rec = Recorder(Branch(dg.gamma, dg.rod, b.N, b.k, attrs=b.attrs), writer, group)
        for i in range(len(b)):
            rec.copy(b, i)
        _branch_attrs(writer, j, b)
        rec.sync()
    return db


def _rod_and_tension(gamma, rod, T, l0=None):
    rod = rod or RodParameters()
    if not isinstance(rod, RodParameters):
        raise TypeError(f"rod must be a RodParameters, got {rod!r}")
    if l0 is not None:  # under length control: the straight rod's tension, a first guess
        if gamma is not None or T is not None:
            raise ValueError("give one of gamma, T and l0 (the tension, or the unstressed length that sets it)")
        T = rod.EA * (rod.L / check_number("l0", l0, positive=True) - 1.0)
        check_tension(rod, T, "the straight rod of this unstressed length has a tension that")
        return rod, T
    if T is None:
        if gamma is None:
            raise ValueError("give gamma (T = gamma w L) or T")
        gamma = check_number("gamma", gamma)
        if rod.w == 0:
            raise ValueError("gamma = T / (w L) is undefined for a weightless rod: give T")
        T = rod.tension(gamma)
    T = check_number("T", T)
    check_tension(rod, T)
    return rod, T


def _beyond(phi_max: float) -> float:
    """How far past ``phi_max`` critical twists are computed: far enough for the next one (they are about 8
    apart on the paper's rod; more with compression), within the 200 rad the eigenproblem allows."""
    return min(max(phi_max + max(20.0, 0.5 * abs(phi_max)), phi_max), 200.0)


def seed_twists(critical: Sequence[float], phi_min: float, phi_max: float) -> list[float]:
    """One seed per interval between consecutive critical twists, at its midpoint, inside ``(phi_min,
    phi_max)``; the interval that straddles ``phi_max`` too (``critical`` reaches beyond it), seeded halfway
    between its lower end and ``phi_max`` when its midpoint lies outside the window."""
    out = []
    for a, b in zip(critical[:-1], critical[1:]):
        if a >= phi_max:
            break
        m = 0.5 * (a + b)
        if m >= phi_max:
            m = 0.5 * (a + phi_max)
        if phi_min < m < phi_max:
            out.append(m)
    return out


def _trace_seeds(dg: Diagram, rod, T, N, k, seeds, crit, bopts, writer, callback, note, ends=None) -> None:
    """The primary branch from the planar sag, then one branch per seed not on a known branch."""
    t0 = time.perf_counter()
    system = RodSystem(rod, T=T, N=N, k=k, ends=ends)
    x0 = system.model.initial_guess(system.disc, system.base[1])
    db = _trace_both(system, x0, 0.0, bopts, _origin(None, crit), writer, dg, callback, both=False)
    db.time = time.perf_counter() - t0
    _keep(dg, db, note)
    for phi in seeds:
        origin = _origin(phi, crit)
        t0 = time.perf_counter()
        try:
            sysw, xs = straight_seed(rod, T, phi, N, k, ends=ends)
        except TraceError as exc:
            dg.skipped.append((origin, str(exc)))
            note(f"  skipped {origin}: {exc}")
            continue
        system = RodSystem(rod, T=T, N=N, k=k, breakpoints=sysw.disc.breakpoints, ends=ends)
        on = _on_known_branch(dg, system, xs, phi)
        if on is not None:
            dg.skipped.append((origin, f"lies on branch {on}"))
            note(f"  {origin}: lies on branch {on}, not traced again")
            continue
        db = _trace_both(system, xs, phi, bopts, origin, writer, dg, callback)
        db.seed_phi, db.time = phi, time.perf_counter() - t0
        _keep(dg, db, note)


def usable_cores() -> int:
    """The cores this process may run on (its affinity mask where the system has one, else every core): a
    pool's default size."""
    import os
    try:
        return len(os.sched_getaffinity(0)) or 1
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _parallel(jobs, executor, n_jobs: int) -> bool:
    """Whether the branches go to an executor: one was given, or more than one job and core, outside a worker
    process (a sweep of diagrams is already parallel over Gamma)."""
    import multiprocessing
    if executor is not None:
        return True
    if jobs is not None:
        jobs = check_number("jobs", jobs, integer=True)
        if jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {jobs}")
    workers = jobs or usable_cores()
    return n_jobs > 1 and workers > 1 and multiprocessing.parent_process() is None


@with_one_blas_thread
def _branch_job(rod, T, N, k, phi, bopts, ends, gamma, attrs, direction: int = 1) -> dict:
    """One direction of one branch of a diagram, traced without a file (a worker's job): the primary branch
    (``phi`` None) from the planar sag, or the seed at ``phi`` traced ``direction`` (-1 down, 1 up) as
    :func:`_trace_both` traces it; the run, its seed's solution and mesh (for the test against the branches
    kept before it), its time and the warnings it raised."""
    import warnings
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if phi is None:
            system = RodSystem(rod, T=T, N=N, k=k, ends=ends)
            x0, phi0 = system.model.initial_guess(system.disc, system.base[1]), 0.0
        else:
            try:
                sysw, x0 = straight_seed(rod, T, phi, N, k, ends=ends)
            except TraceError as exc:
                return dict(error=str(exc), warnings=[])
            system, phi0 = RodSystem(rod, T=T, N=N, k=k, breakpoints=sysw.disc.breakpoints, ends=ends), phi
        dg = Diagram(gamma=gamma, T=T, rod=rod, critical=[], attrs=attrs)
        b = _trace_direction(system, x0, phi0, bopts, dg, direction)
    return dict(error=None, run=b, N=system.disc.N, x=x0, breakpoints=system.disc.breakpoints,
                time=time.perf_counter() - t0, warnings=[(str(w.message), w.category) for w in caught])


def _trace_seeds_parallel(dg: Diagram, rod, T, N, k, seeds, crit, bopts, writer, callback, note, ends, executor,
                          jobs) -> None:
    """:func:`_trace_seeds` with every branch traced at once on ``executor`` (default a process pool), a
    seed's two directions as two jobs (nine jobs of 0.1 to 2.7 s for the five branches of Gamma = 1: two
    workers end within 0.2 s of each other, where five whole branches of 1 to 5 s left one idle); each branch
    is kept or skipped in the serial order, by the same tests, and written to the file when it is kept."""
    own = executor is None
    if own:
        from concurrent.futures import ProcessPoolExecutor

        from .sweep import _worker_init
        executor = ProcessPoolExecutor(max_workers=min(jobs or usable_cores(), 2 * len(seeds) + 1),
                                       initializer=_worker_init)
    from .sweep import _stop_workers
    finished, futures = False, []
    try:
        args = (rod, T, N, k)
        futures = [(None, None, executor.submit(_branch_job, *args, None, bopts, ends, dg.gamma, dg.attrs, 1))]
        futures += [(phi, executor.submit(_branch_job, *args, phi, bopts, ends, dg.gamma, dg.attrs, -1),
                     executor.submit(_branch_job, *args, phi, bopts, ends, dg.gamma, dg.attrs, 1)) for phi in seeds]
        for phi, down, up in futures:
            _keep_traced(dg, rod, T, k, phi, crit, _result(down, callback), _result(up, callback), writer,
                         callback, note, ends)
        finished = True
    finally:
        if own:
            if not finished:  # an interrupt or an error: the jobs still running are not waited for
                _stop_workers(executor)
            executor.shutdown(wait=True, cancel_futures=True)
        elif not finished:
            for future in (f for job in futures for f in job[1:] if f is not None):
                future.cancel()


def _result(future, callback):
    """A job's result (None for no job); the callback's ``idle()`` called before it is awaited and every 0.2 s
    while it runs (where a serial run would have called the callback at its points)."""
    if future is None:
        return None
    from concurrent.futures import TimeoutError as Pending
    idle = getattr(callback, "idle", None)
    while idle is not None:
        idle()
        try:
            return future.result(timeout=0.2)
        except Pending:
            pass
    return future.result()


def _keep_traced(dg: Diagram, rod, T, k, phi, crit, down, up, writer, callback, note, ends) -> None:
    """A branch traced by the workers (``down`` None for the primary branch), kept or skipped as
    :func:`_trace_seeds` keeps or skips it; its jobs' warnings raised here, in the serial order."""
    import warnings
    origin = _origin(phi, crit)
    for r in (down, up):
        for message, category in (r["warnings"] if r is not None else ()):
            warnings.warn(message, category, stacklevel=5)  # the caller's line, past with_one_blas_thread
    if up["error"] is not None:
        dg.skipped.append((origin, up["error"]))
        note(f"  skipped {origin}: {up['error']}")
        return
    if phi is not None:
        system = RodSystem(rod, T=T, N=up["N"], k=k, breakpoints=up["breakpoints"], ends=ends)
        on = _on_known_branch(dg, system, up["x"], phi)
        if on is not None:
            dg.skipped.append((origin, f"lies on branch {on}"))
            note(f"  {origin}: lies on branch {on}, not traced again")
            return
    branch, rec = _open_branch(dg, rod, up["N"], k, origin, writer, None if down is None else down["run"])
    _copy_run(branch, rec, up["run"], callback)
    db = _close_branch(dg, branch, rec, writer, origin)
    db.seed_phi, db.time = math.nan if phi is None else phi, up["time"] + (down["time"] if down else 0.0)
    _keep(dg, db, note)


def _origin(phi, crit) -> str:
    """How a branch was started: the primary branch (``phi`` None), or the seed at ``phi`` between two
    critical twists."""
    if phi is None:
        return "primary branch from the planar sag at phi_L = 0"
    lo, hi = max(c for c in crit if c < phi), min(c for c in crit if c > phi)
    return f"seed at phi_L = {phi:.6g}, between the critical twists {lo:.6g} and {hi:.6g}"


def _copy_run(branch: Branch, rec: Recorder, up: Branch, callback) -> None:
    """The upward run ``up`` traced elsewhere, appended to ``branch`` as :func:`run` appends it there: its
    points (``callback`` sees each once it is stored), its end, its notes and counts."""
    rec.deferred = True  # published once, when the branch is complete (or interrupted)
    try:
        for i in range(len(up)):
            rec.copy(up, i)
            if callback is not None:
                callback(_stored_point(branch, len(branch) - 1))
    except KeyboardInterrupt:  # as the engine ends an interrupted run
        branch.set_status(Status.INTERRUPTED, "interrupted")
        rec.sync()
        raise
    finally:
        rec.deferred = False
    branch.set_status(up.status, up.message)
    branch.unlocated += up.unlocated
    branch.missed_crossings += up.missed_crossings
    branch.settings.update(up.settings)
    branch.steps, branch.newton_iterations = branch.steps + up.steps, branch.newton_iterations + up.newton_iterations
    branch.remeshes, branch.elapsed = branch.remeshes + up.remeshes, branch.elapsed + up.elapsed


def _stored_point(b: Branch, i: int) -> Point:
    """Point ``i`` of a branch as the tracker handed it over (what a callback reads)."""
    row = b.row_at(i)
    t = np.asarray(b.tangents[i], float)
    return Point(x=b.coefficients[i], p=float(row["phi_L"]), tx=t[:-1], tp=float(t[-1]) if t.size else 0.0,
                 kind=row["kind"], located=bool(row["located"]), data=row, message=b.messages.get(i, ""))


def _trace_deflated(dg: Diagram, rod, T, phi, N, k, opts, bopts, writer, callback, note) -> None:
    t0 = time.perf_counter()
    for system, x in _deflated_starts(dg, rod, T, phi, N, k, opts):
        origin = f"deflated Newton at phi_L = {phi:.6g}"
        if _on_known_branch(dg, system, x, phi) is not None:
            continue
        try:
            db = _trace_both(system, x, phi, bopts, origin, writer, dg, callback)
        except TraceError as exc:
            dg.skipped.append((origin, str(exc)))
            continue
        db.seed_phi, db.time = phi, time.perf_counter() - t0
        _keep(dg, db, note)


def _keep(dg: Diagram, db: DiagramBranch, note) -> None:
    dg.branches.append(db)
    note(_line(len(dg.branches) - 1, db))


def _line(j: int, db: DiagramBranch) -> str:
    b = db.branch
    return (f"  branch {j}: {len(b)} points, {len(b.folds)} fold(s), {db.time:.2f} s  ({db.origin}); "
            f"ends: {db.ends[0] or '-'} | {db.ends[1] or '-'}")


def _trace_both(system: RodSystem, x0, phi0: float, opts: TraceOptions, origin: str, writer, dg: Diagram,
                callback, both: bool = True) -> DiagramBranch:
    """Trace from a seed down, then up; the branch runs from its lower end through the seed."""
    done = _resumed_branch(dg, origin, writer)
    if done is not None:
        return done
    down = _trace_direction(system, x0, phi0, opts, dg, -1) if both else None
    branch, rec = _open_branch(dg, system.rod, system.disc.N, system.disc.k, origin, writer, down)
    run(system, x0, phi0, TraceOptions(**dict(opts.as_dict(), direction=1)), branch=branch, recorder=rec,
        callback=callback)
    return _close_branch(dg, branch, rec, writer, origin)


def _trace_direction(system: RodSystem, x0, phi0: float, opts: TraceOptions, dg: Diagram, direction: int) -> Branch:
    """One run from the seed (``direction`` -1: down, 1: up), into a branch of its own."""
    b = Branch(dg.gamma, system.rod, system.disc.N, system.disc.k, attrs=dg.attrs)
    return run(system, x0, phi0, TraceOptions(**dict(opts.as_dict(), direction=direction)), branch=b)


def _open_branch(dg: Diagram, rod, N: int, k: int, origin: str, writer, down: Branch | None):
    """Branch ``len(dg.branches)`` begun, in memory and in the file (``dg.tracing``: an interrupt marks it):
    the downward run ``down`` reversed without the seed (the upward run starts there again), or for the
    primary branch (``down`` None) nothing. Returns ``(branch, recorder)``."""
    j = len(dg.branches)
    branch = Branch(dg.gamma, rod, N, k, attrs=dg.attrs)
    dg.tracing = (j, branch)
    group = writer.group(f"branches/{j}", attrs=dict(origin=origin), extra_columns=_extra_columns(dg)) \
        if writer is not None else None
    rec = Recorder(branch, writer, group)
    if down is None:
        branch.status_first, branch.message_first = Status.START, "start of the trace at phi_L = 0"
        return branch, rec
    rev = down.reversed()
    rec.deferred = True  # published with the upward run's first special point
    for i in range(len(rev) - 1):
        rec.copy(rev, i, kind=Kind.REGULAR if rev.table["kind"][i] == Kind.START else None)
    rec.deferred = False
    branch.status_first, branch.message_first = down.status, down.message
    # folds and branch points detected but not located, eigenvalue crossings missed: on either side
    branch.unlocated += down.unlocated
    branch.missed_crossings += down.missed_crossings
    return branch, rec


def _close_branch(dg: Diagram, branch: Branch, rec: Recorder, writer, origin: str) -> DiagramBranch:
    """The branch being traced, complete: its ends and notes written to its group."""
    if writer is not None:
        _branch_attrs(writer, dg.tracing[0], branch)
        rec.sync()
        writer.flush()
    dg.tracing = None  # complete: an interrupt from here on leaves it as it is
    return DiagramBranch(branch, origin, (branch.message_first, branch.message))


def _extra_columns(dg: Diagram) -> tuple:
    """A branch group's columns beyond the rod's: under length control the tension solved for at each point."""
    return ("T",) if getattr(dg, "ends", None) is not None and "T" in dg.ends.frees else ()


def _branch_attrs(writer, j: int, branch: Branch) -> None:
    """A diagram branch's ends (reasons and statuses) and its notes, as attributes of its group."""
    where = f"branches/{j}"
    writer.set_attr("stop_reason_first", branch.message_first, where)
    writer.set_attr("stop_reason", branch.message, where)
    writer.set_attr("status_first", str(branch.status_first), where)
    writer.set_attr("status", str(branch.status), where)
    for name in ("unlocated", "missed_crossings"):
        if getattr(branch, name):
            writer.set_attr(name, json.dumps(getattr(branch, name)), where)


def _signature_at(db: DiagramBranch, phi: float, rod, T, k):
    """Signatures of the branch's points at exactly ``phi`` (its forced points)."""
    b = db.branch
    out = []
    for i, (p, _kind) in enumerate(zip(b.table["phi_L"], b.table["kind"])):
        if abs(p - phi) <= 1e-9 * (1 + abs(phi)):
            s = RodSystem(rod, T=T, N=b.meshes[i].size - 1, k=k, breakpoints=b.meshes[i])
            out.append(shape_signature(s, b.coefficients[i]))
    return out


def _on_known_branch(dg: Diagram, system: RodSystem, x, phi: float):
    sig = shape_signature(system, x)
    for j, db in enumerate(dg.branches):
        for other in _signature_at(db, phi, dg.rod, dg.T, system.disc.k):
            if same_solution(sig, other):
                return j
    return None


def _drop_duplicates(dg: Diagram, writer) -> None:
    """Two branches that share a solution at a forced ``phi_L`` are one: keep the longer."""
    forced = sorted({p for db in dg.branches for p, kd in zip(db.branch.table["phi_L"], db.branch.table["kind"])
                     if kd == Kind.FORCED})
    drop = set()
    k = dg.branches[0].branch.k if dg.branches else 5
    for i in range(len(dg.branches)):
        for j in range(i + 1, len(dg.branches)):
            if i in drop or j in drop:
                continue
            for phi in forced:
                a = _signature_at(dg.branches[i], phi, dg.rod, dg.T, k)
                b = _signature_at(dg.branches[j], phi, dg.rod, dg.T, k)
                if any(same_solution(u, v) for u in a for v in b):
                    drop.add(j if len(dg.branches[j].branch) <= len(dg.branches[i].branch) else i)
                    break
    if drop:
        keep = [db for q, db in enumerate(dg.branches) if q not in drop]
        for q in sorted(drop):
            dg.skipped.append((dg.branches[q].origin, "the same branch as another one (dropped)"))
        dg.branches = keep
        if writer is not None:
            _rewrite_groups(writer, dg)


def _rewrite_groups(writer, dg: Diagram) -> None:
    """Renumber the branch groups after dropping duplicates (the file is rebuilt in memory)."""
    if "branches" in writer.f:
        del writer.f["branches"]
    writer.groups = {k_: v for k_, v in writer.groups.items() if not k_.startswith("branches/")}
    for j, db in enumerate(dg.branches):
        group = writer.group(f"branches/{j}", attrs=dict(origin=db.origin), extra_columns=_extra_columns(dg))
        b = db.branch
        rec = Recorder(Branch(dg.gamma, dg.rod, b.N, b.k, attrs=b.attrs), writer, group)
        for i in range(len(b)):
            rec.copy(b, i)
        _branch_attrs(writer, j, b)
        rec.sync()


def _write_folds(writer, dg: Diagram) -> None:
    if writer.points == 0:
        return
    if "folds" in writer.f:
        del writer.f["folds"]
    fo = writer.f.create_group("folds")
    folds = dg.folds
    cols = ("branch", "phi_L", "stretch", "torque", "l0", "waves_before", "waves_after", "index", "located",
            "unstable_before", "unstable_after")
    for name in cols:
        dt = "f8" if name in ("phi_L", "stretch", "torque", "l0") else "i8"
        fo.create_dataset(name, data=np.array([f[name] for f in folds], dtype=dt).reshape(-1))
    writer.set_attr("skipped", json.dumps([list(s) for s in dg.skipped]))
    missed = [[j] + list(m) for j, db in enumerate(dg.branches) for m in db.branch.missed_crossings]
    if missed:  # [branch, value before, value after, count before, count after]
        writer.set_attr("missed_crossings", json.dumps(missed))


def _deflated_starts(dg: Diagram, rod, T, phi: float, N: int, k: int, opts: TraceOptions):
    """New solutions at ``phi`` by deflation from the known ones (on a uniform mesh of max(2N, 30)).

    Guesses: the known solutions (started beside), the straight twisted state, the untwisted
    sag, and helical shapes of 1 to 4 waves of amplitude 0.05 L and 0.15 L."""
    Nd = max(2 * N, 30)
    system = RodSystem(rod, T=T, N=Nd, k=k)
    known = []
    for db in dg.branches:
        b = db.branch
        for i, p in enumerate(b.table["phi_L"]):
            if abs(p - phi) <= 1e-9 * (1 + abs(phi)):
                src = RodSystem(rod, T=T, N=b.meshes[i].size - 1, k=k, breakpoints=b.meshes[i])
                known.append(system.disc.transfer(b.coefficients[i], src.disc))
    guesses = list(known)
    guesses.append(system.straight_state(phi))
    guesses.append(system.model.initial_guess(system.disc, T))
    # helical shapes of 1 to 4 waves, small and moderate, on the straight twisted state
    L = rod.L
    for waves in (1, 2, 3, 4):
        for amp in (0.05 * L, 0.15 * L):
            shape = [lambda S, n=waves, a=amp: a * np.sin(np.pi * S / L) ** 2 * np.cos(2 * np.pi * n * S / L),
                     lambda S, n=waves, a=amp: a * np.sin(np.pi * S / L) ** 2 * np.sin(2 * np.pi * n * S / L),
                     lambda S: phi * S / L, lambda S: 0 * S, lambda S: 0 * S, lambda S: 0 * S + T]
            guesses.append(system.disc.project(shape))
    with np.errstate(all="ignore"):
        found = deflate(system, phi, known, guesses)
    out = []
    for x in found:
        o = system.outputs(x, phi)
        if o["min_alignment"] > opts.min_alignment and o.get("alpha_min", 1.0) > 0:
            out.append((system, x))
    return out
