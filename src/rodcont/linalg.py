"""Sparse linear algebra of the solvers: LU with determinant, bordered systems, Newton.

Knows nothing of rods or of collocation. Three pieces:

* :class:`LU`: a sparse LU (SuperLU, natural column order: the matrices here
  come banded) that also gives the sign and log-magnitude of the determinant
  and solves with a rank-one change of its last row (Sherman-Morrison), so a
  factorisation of ``[[J, b], [c^T, d]]`` serves every border row ``c'``.
* :class:`BorderedPattern`: ``[[J, b], [c^T, d]]`` assembled straight from
  ``J``'s CSC arrays through insertion positions computed once per sparsity
  pattern.
* :class:`BorderedSolver`: the same bordered system solved by block elimination
  on the LU of ``J`` alone (memory and time linear in ``n`` where ``J`` is banded),
  checked by its backward error and refined; the tracker's default
  (:func:`bordered_solver`).
* :func:`newton_solve`: damped Newton returning a :class:`NewtonResult`
  (a failure is data, not an exception); :func:`chord_solve`, the same with the Jacobian frozen while
  the steps contract.

and :class:`HeapTrimmer`, which gives the factorisations' freed memory back to the system.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class HeapTrimmer:
    """Gives the C heap's free pages back to the system (glibc ``malloc_trim``): at most every ``interval``
    seconds, and only while the process holds more than ``above`` bytes.

    A trace factorises a matrix of a slightly different fill at every point; glibc keeps the freed blocks
    and the resident memory of a long trace grows by fragmentation, not by anything kept (a helix in a
    pipe at 4781 unknowns, 154 points: peak 413-467 MB untrimmed, 329-332 MB trimmed every 0.25 s, for
    about 0.7 s more system time in 10 s; benchmarks/bench.py). Small runs stay below ``above`` and never
    pay for it. ``interval = None``, or a C library without ``malloc_trim``: no-op.
    """

    def __init__(self, interval: float | None = 0.25, above: int = 256 * 2**20):
        self.interval, self.above = interval, above
        self.last = time.perf_counter()
        self._trim = _malloc_trim()

    def __call__(self) -> None:
        if self.interval is None or self._trim is None:
            return
        now = time.perf_counter()
        if now - self.last < self.interval:
            return
        self.last = now
        if resident_bytes() > self.above:
            self._trim(0)


def resident_bytes() -> int:
    """The process's resident memory (Linux ``/proc/self/statm``); 0 where that is not available."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, ValueError, IndexError):
        return 0


_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


_TRIM = []


def _malloc_trim():
    """glibc's ``malloc_trim`` from the running process's symbols (found once), or None."""
    if not _TRIM:
        try:
            import ctypes
            _TRIM.append(ctypes.CDLL(None).malloc_trim)
        except (OSError, AttributeError, TypeError):  # not glibc (macOS, musl, Windows)
            _TRIM.append(None)
    return _TRIM[0]


def max_norm(v: np.ndarray) -> float:
    return float(np.max(np.abs(v))) if v.size else 0.0


def canonical_csc(data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, n: int) -> sp.csc_matrix:
    """An ``n x n`` CSC matrix from arrays with sorted, unique row indices per column, its canonical
    format recorded: a template for :func:`csc_with_data`. Its index arrays are made read-only, as
    every matrix made from it shares them (an in-place change, such as ``eliminate_zeros``, raises
    instead of corrupting the others)."""
    A = sp.csc_matrix((data, indices, indptr), shape=(n, n))
    if not A.has_canonical_format:
        raise ValueError("the pattern has unsorted or duplicate row indices")
    A.indices.flags.writeable = False
    A.indptr.flags.writeable = False
    return A


def csc_with_data(template: sp.csc_matrix, data: np.ndarray) -> sp.csc_matrix:
    """``template``'s structure with new ``data``.

    A shallow copy sharing the template's read-only index arrays: scipy's
    validation of the structure (a sizeable part of the cost of a small matrix)
    and its canonical-format test are done once, for the template.
    """
    A = copy.copy(template)
    A.data = data
    return A


# --------------------------------------------------------------------------
# LU with determinant and border changes
# --------------------------------------------------------------------------
class SingularMatrix(ArithmeticError):
    """The factorisation met an exactly zero pivot."""


def is_out_of_memory(exc: BaseException) -> bool:
    """SuperLU's ways of saying an allocation failed: "SUPERLU_MALLOC fails ..." as a RuntimeError, or, when a
    work array could not be had, a SystemError "gstrf was called with invalid arguments"
    (test_an_lu_that_cannot_get_its_memory_is_a_memory_error)."""
    text = str(exc)
    return (isinstance(exc, MemoryError) or "MALLOC" in text.upper()
            or (isinstance(exc, SystemError) and "gstrf" in text))


def superlu(A, ordering: str = "NATURAL"):
    """SuperLU's factorisation of ``A`` (``scipy.sparse.linalg.splu``) with its failures read: out of memory a
    ``MemoryError`` naming the size, anything else (``Factor is exactly singular``) a :class:`SingularMatrix`."""
    try:
        return spla.splu(A, permc_spec=ordering)
    except (RuntimeError, SystemError) as exc:
        if is_out_of_memory(exc):
            n = A.shape[0]
            raise MemoryError(f"the sparse LU of a {n} x {n} matrix did not fit in memory") from None
        raise SingularMatrix(str(exc)) from None


class LU:
    """Sparse LU of a square CSC matrix ``A`` (``Pr A Pc = L U``; natural column order by default).

    ``solve(b)`` solves ``A x = b``; ``solve(b, trans=True)`` solves ``A^T x = b``.
    ``det()`` returns ``(sign, log|det|)``. For a bordered matrix whose last
    row is ``r``, ``with_last_row(r_new)`` returns a solver for the matrix
    with that row replaced (one extra solve, once).
    """

    def __init__(self, A: sp.csc_matrix, ordering: str = "NATURAL", row_scale: np.ndarray | None = None):
        """``ordering``: SuperLU's column order. ``NATURAL`` suits the banded Jacobians of the
        collocation; ``COLAMD`` bounds the fill where a dense border row meets a badly scaled band
        (:class:`rodcont.mesh.ErrorEstimator`). ``row_scale``: factorise ``R A`` (``R = diag(row_scale)``,
        powers of two, :func:`powers_of_two`: formed exactly, the pattern kept) and answer for ``A``. Partial
        pivoting compares the rows of a column as they are scaled: equations in units of their own (a force
        balance in N/m next to a torque equation in 1/m^2) pivot as their dimensionless forms do."""
        self._r = None
        if row_scale is not None:
            A = A if sp.issparse(A) and A.format == "csc" else sp.csc_matrix(A)
            self._r = np.asarray(row_scale, float)
            A = csc_with_data(A, A.data * self._r[A.indices])
        self._lu = superlu(A, ordering)
        self.n = A.shape[0]
        self._det = None

    def solve(self, b: np.ndarray, trans: bool = False) -> np.ndarray:
        b = np.asarray(b, float)
        if self._r is None:
            return self._lu.solve(b, trans="T" if trans else "N")
        if trans:  # A^T x = b is (R A)^T (R^-1 x) = b
            return self._r * self._lu.solve(b, trans="T")
        return self._lu.solve(self._r * b)

    def det(self) -> tuple[int, float]:
        """Sign and log-magnitude of ``det A`` (from the diagonal of ``U`` and the row permutation)."""
        if self._det is None:
            u = self._lu.U.diagonal()
            sign = int(np.prod(np.sign(u))) * permutation_sign(self._lu.perm_r) * permutation_sign(self._lu.perm_c)
            with np.errstate(divide="ignore"):
                log = float(np.sum(np.log(np.abs(u))))
            if self._r is not None:  # det A = det(R A) / det R, det R > 0
                log -= float(np.sum(np.log(self._r)))
            self._det = (sign, log)
        return self._det

    def with_last_row(self, old_row: np.ndarray, new_row: np.ndarray, u: np.ndarray | None = None) -> RowUpdatedLU:
        """``u``: ``A^{-1} e_n`` if already solved for (a tangent solve)."""
        return RowUpdatedLU(self, old_row, new_row, u)


class RowUpdatedLU:
    """Solver for ``A + e_n (r_new - r_old)^T`` from the LU of ``A`` (Sherman-Morrison).

    With ``u = A^{-1} e_n``: ``x = y - u (delta . y) / (1 + delta . u)``, ``y = A^{-1} b``.
    For a bordered matrix whose old last row gave ``r_old . u = 1`` (a tangent
    solve), the denominator is ``r_new . u``: far from zero while the new row is
    close to the tangent direction, as in a continuation step.
    """

    def __init__(self, lu: LU, old_row: np.ndarray, new_row: np.ndarray, u: np.ndarray | None = None):
        self.lu = lu
        self.delta = np.asarray(new_row, float) - np.asarray(old_row, float)
        if u is None:
            e = np.zeros(lu.n)
            e[-1] = 1.0
            u = lu.solve(e)
        self.u = u
        self.denominator = 1.0 + float(self.delta @ self.u)
        if not (math.isfinite(self.denominator) and abs(self.denominator) > 1e-12):
            raise SingularMatrix("the updated bordered matrix is singular")

    def solve(self, b: np.ndarray) -> np.ndarray:
        y = self.lu.solve(b)
        return y - self.u * (float(self.delta @ y) / self.denominator)


def powers_of_two(units: np.ndarray) -> np.ndarray:
    """The powers of two nearest ``1 / units`` (1 where a unit is 0 or not finite): a row scale that
    :class:`LU` applies without rounding."""
    u = np.abs(np.asarray(units, float))
    ok = np.isfinite(u) & (u > 0)
    return np.exp2(-np.round(np.log2(np.where(ok, u, 1.0))))


def permutation_sign(perm: np.ndarray) -> int:
    """Sign of a permutation: ``(-1)^(n - number of cycles)``.

    Cycles are counted by pointer doubling: every index learns the smallest
    index on its cycle in ``log2(n)`` vectorised rounds.
    """
    p = np.asarray(perm, dtype=np.int64)
    n = p.size
    label = np.arange(n)
    if np.array_equal(p, label):  # the column order of a natural-order LU
        return 1
    step = p.copy()
    for _ in range(max(1, int(np.ceil(np.log2(n))) + 1)):
        label = np.minimum(label, label[step])
        step = step[step]
    cycles = int(np.count_nonzero(label == np.arange(n)))
    return -1 if (n - cycles) % 2 else 1


# --------------------------------------------------------------------------
# Bordered matrices
# --------------------------------------------------------------------------
class BorderedPattern:
    """``[[J, b], [c^T, d]]`` for every ``J`` with one CSC sparsity pattern.

    The positions of ``J``'s entries, of the border column ``b`` and of the
    border row ``c`` in the bordered CSC data array are computed once; each
    assembly is then one array fill.
    """

    def __init__(self, indices: np.ndarray, indptr: np.ndarray, n: int):
        self.n = n
        counts = np.diff(indptr)
        # column j of the bordered matrix: J's column j, then the border-row entry
        new_indptr = np.concatenate([[0], np.cumsum(counts + 1)])
        new_indptr = np.append(new_indptr, new_indptr[-1] + n + 1)
        col_of = np.repeat(np.arange(n), counts)
        self.pos_J = np.arange(indices.size) + col_of
        self.pos_row = new_indptr[1:n + 1] - 1
        self.pos_col = np.arange(new_indptr[n], new_indptr[n + 1])
        new_indices = np.empty(new_indptr[-1], dtype=np.int32)
        new_indices[self.pos_J] = indices
        new_indices[self.pos_row] = n
        new_indices[self.pos_col] = np.arange(n + 1)
        self.indices, self.indptr = new_indices, new_indptr.astype(np.int32)
        self.source = (indices, indptr)
        self.template = canonical_csc(np.zeros(new_indices.size), self.indices, self.indptr, n + 1)

    def assemble(self, J_data: np.ndarray, b: np.ndarray, c: np.ndarray, d: float) -> sp.csc_matrix:
        data = np.empty(self.indices.size)
        data[self.pos_J] = J_data
        data[self.pos_row] = c
        data[self.pos_col[:-1]] = b
        data[self.pos_col[-1]] = d
        return csc_with_data(self.template, data)


_PATTERNS: dict = {}


def bordered(J, b: np.ndarray, c: np.ndarray, d: float) -> sp.csc_matrix:
    """``[[J, b], [c^T, d]]`` as CSC (the insertion positions are cached per pattern)."""
    J = J.tocsc() if sp.issparse(J) else sp.csc_matrix(np.asarray(J))
    if not J.has_sorted_indices:
        J = J.sorted_indices()
    n = J.shape[0]
    # a discretisation hands out Jacobians of one pattern: keyed by shape and size, checked by value
    key = (n, J.indices.size)
    pat = _PATTERNS.get(key)
    # (a collocation's Jacobians share read-only index arrays: then the identity test settles it)
    frozen = not (J.indices.flags.writeable or J.indptr.flags.writeable)
    same = pat is not None and ((frozen and pat.source[0] is J.indices and pat.source[1] is J.indptr) or (
        np.array_equal(pat.source[0], J.indices) and np.array_equal(pat.source[1], J.indptr)))
    if same:
        pat.source = (J.indices, J.indptr)  # (equal arrays of another discretisation: identical next time)
    else:
        pat = BorderedPattern(J.indices, J.indptr, n)
        if len(_PATTERNS) > 16:
            _PATTERNS.clear()
        _PATTERNS[key] = pat
    return pat.assemble(J.data, np.asarray(b, float), np.asarray(c, float), float(d))


# --------------------------------------------------------------------------
# Newton
# --------------------------------------------------------------------------
@dataclass
class NewtonResult:
    """Outcome of a Newton solve. ``converged`` False is a result, not an error."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual_norm: float
    step_norm: float
    message: str
    lu: object = field(default=None, repr=False)
    corrections: list = field(default_factory=list, repr=False)  # the first two Newton steps
    factorisations: int = -1  # the LUs made (-1: not counted; newton_solve makes one per iteration)


def at_rounding(F: np.ndarray, J, x: np.ndarray, extra: np.ndarray | float = 0.0, factor: float = 1e3) -> bool:
    """Whether every row of the residual ``F`` is within ``factor`` times its rounding noise: machine epsilon
    times the size of its terms, ``|J| |x|`` (plus ``extra``, e.g. ``|F_p| |p|``, and the mean of those,
    for rows whose terms cancel). A residual there cannot fall further, whatever the steps do."""
    mag = abs(J) @ np.abs(x) + extra
    noise = np.finfo(float).eps * (mag + float(np.mean(mag)))
    return bool(np.all(np.abs(F) <= factor * noise))


def newton_solve(linearise: Callable, residual: Callable, x0: np.ndarray, tol: float = 1e-10,
                 max_iter: int = 30, min_damping: float = 1.0 / 64) -> NewtonResult:
    """Damped Newton for ``F(x) = 0`` given ``linearise(x) -> (F, J)`` (``J`` sparse).

    One assembly and one sparse LU per iteration. A full step is tried first;
    while the max-norm residual does not decrease the step is halved, down to
    ``min_damping``. Converged when a full step is below ``tol * (1 + |x|)``,
    or when quadratic convergence predicts the next one is
    (``|dx_k|^2 / |dx_{k-1}| <= tol * (1 + |x|)`` with ``|dx_k| < |dx_{k-1}| / 4``),
    which saves the last, confirming, iteration; the residual at the result
    must not exceed the one before the step (beyond rounding). A full step
    below ``sqrt(tol) * (1 + |x|)`` is taken without a line search as long as
    the residual stays within ten times its size (it is at its rounding level:
    a nearly converged start, such as a stored solution on a slightly
    different problem, would otherwise fail on noise). ``lu`` in the
    result is the factorisation of the last Jacobian used (one step before ``x``).
    """
    x = np.array(x0, dtype=float)
    F, J = linearise(x)
    fnorm, step, prev = max_norm(F), np.inf, np.inf
    # residual changes below this are rounding: the size of the terms, not of their sum
    floor = 1e-13 * (1.0 + (fnorm if np.isfinite(fnorm) else 0.0))
    corrections: list = []
    for it in range(1, max_iter + 1):
        if not np.all(np.isfinite(F)):
            return NewtonResult(x, False, it - 1, fnorm, step, "residual is not finite")
        stalled = it > 2 and step <= math.sqrt(tol) * (1 + max_norm(x)) and step > 0.25 * prev
        if stalled and at_rounding(F, J, x):
            # converged to rounding: the steps no longer contract and the residual is at its noise. On a stiff
            # problem (a contact law on a fine mesh) they stay above tol * (1 + |x|) from noise alone (a
            # conduit solve at N = 500 never met it in 30 iterations); while they contract, Newton goes on
            return NewtonResult(x, True, it - 1, fnorm, step, "converged (to rounding)", None, corrections)
        try:
            lu = LU(J)
        except SingularMatrix as exc:
            return NewtonResult(x, False, it - 1, fnorm, step, f"singular Jacobian ({exc})")
        dx = lu.solve(-F)
        if len(corrections) < 2:
            corrections.append(dx)
        prev, step = step, max_norm(dx)
        scale = tol * (1 + max_norm(x))
        if not np.isfinite(step):
            return NewtonResult(x, False, it, fnorm, step, "Newton step is not finite (singular Jacobian)")
        done = step <= scale or (np.isfinite(prev) and step < 0.25 * prev and step * step <= scale * prev)
        if done:
            fdone = max_norm(residual(x + dx))
            if np.isfinite(fdone) and fdone <= 10.0 * fnorm + floor:  # a tiny step only moves rounding
                return NewtonResult(x + dx, True, it, fdone, step, "converged", lu, corrections)
        Ft, Jt = linearise(x + dx)
        ft, lam = max_norm(Ft), 1.0
        # a full step this small only moves rounding (as at convergence above): the residual may not fall
        tiny = step <= math.sqrt(tol) * (1 + max_norm(x)) and np.isfinite(ft) and ft <= 10.0 * fnorm + floor
        while not (tiny or (np.isfinite(ft) and ft <= fnorm * (1 + 1e-6) + floor)):
            lam *= 0.5
            if lam < min_damping:
                return NewtonResult(x, False, it, fnorm, step, "line search failed: the residual does not decrease")
            Ft = residual(x + lam * dx)
            ft, Jt = max_norm(Ft), None
        x = x + lam * dx
        if Jt is None:
            Ft, Jt = linearise(x)
        F, J, fnorm = Ft, Jt, max_norm(Ft)
        if lam < 1.0:
            step = np.inf  # a damped step says nothing about the rate
    return NewtonResult(x, False, max_iter, fnorm, step, f"no convergence in {max_iter} iterations")


def chord_solve(linearise: Callable, residual: Callable, x0: np.ndarray, tol: float = 1e-10,
                max_iter: int = 60, max_contraction: float = 0.5, min_damping: float = 1.0 / 64) -> NewtonResult:
    """Newton with a frozen Jacobian (the chord method) for ``F(x) = 0``, safeguarded as :func:`newton_solve`.

    ``dx_k = -J(x_j)^-1 F(x_k)`` with the LU of the Jacobian at the last point ``x_j`` where it was taken. A chord
    step is kept while it is at most ``max_contraction`` times the previous step and the max-norm residual does
    not grow; otherwise the Jacobian is taken afresh at the current point. A step on a fresh Jacobian is a
    Newton step with :func:`newton_solve`'s line search (halved down to ``min_damping``; after a damped step the
    Jacobian is taken afresh again) and its test of convergence to rounding. Converged when a full step is
    below ``tol * (1 + |x|)``, or when the contraction ``q`` of the last two predicts the error left,
    ``q / (1 - q) |dx_k|``, is. ``iterations`` counts the steps, ``factorisations`` the LUs; ``lu`` is None.
    """
    x = np.array(x0, dtype=float)
    F, J = linearise(x)
    fnorm, prev = max_norm(F), np.inf
    floor = 1e-13 * (1.0 + (fnorm if np.isfinite(fnorm) else 0.0))
    lu, fresh, factorisations, steps = None, True, 0, 0

    def result(converged, message, step=prev):
        return NewtonResult(x, converged, steps, fnorm, step, message, factorisations=factorisations)

    for _ in range(2 * max_iter):  # a refresh is no step: at most one between two steps
        if steps >= max_iter:
            break
        if not np.all(np.isfinite(F)):
            return result(False, "residual is not finite")
        if lu is None:
            try:
                lu, factorisations = LU(J), factorisations + 1
            except SingularMatrix as exc:
                return result(False, f"singular Jacobian ({exc})")
        dx = lu.solve(-F)
        step = max_norm(dx)
        small = step <= math.sqrt(tol) * (1 + max_norm(x))
        if fresh and np.isfinite(prev) and small and step > 0.25 * prev and at_rounding(F, J, x):
            return result(True, "converged (to rounding)", step)
        Ft = residual(x + dx) if np.isfinite(step) and (fresh or step <= max_contraction * prev) else None
        ft = max_norm(Ft) if Ft is not None else np.inf
        ok = np.isfinite(ft) and (ft <= fnorm * (1 + 1e-6) + floor or (fresh and small and ft <= 10 * fnorm + floor))
        if not ok and not fresh:  # the chord stopped contracting: a fresh Jacobian at the current point
            F, J = linearise(x)
            lu, fresh = None, True
            continue
        if not np.isfinite(step):
            return result(False, "Newton step is not finite (singular Jacobian)", step)
        lam = 1.0
        while not ok:
            lam *= 0.5
            if lam < min_damping:
                return result(False, "line search failed: the residual does not decrease", step)
            Ft = residual(x + lam * dx)
            ft = max_norm(Ft)
            ok = np.isfinite(ft) and ft <= fnorm * (1 + 1e-6) + floor
        x, F, fnorm, steps = x + lam * dx, Ft, ft, steps + 1
        if lam < 1.0:  # a damped step says nothing about the rate: Newton again from there
            F, J = linearise(x)
            lu, fresh, prev = None, True, np.inf
            continue
        q = step / prev
        if step <= tol * (1 + max_norm(x)) or (0 < q < 1 and q / (1 - q) * step <= tol * (1 + max_norm(x))):
            return result(True, "converged", step)
        prev, fresh = step, False
    return result(False, f"no convergence in {max_iter} iterations")


def scaled_smallest_singular_value(A, iterations: int = 25) -> float:
    """The smallest singular value of ``A`` with its rows, then its columns, scaled to unit max-norm.

    Scaling is what a solver can undo; what is left is the matrix's own conditioning (its largest singular
    value is then between 1 and the square root of its size). Inverse iteration on ``B^T B``, ``B = R A C``,
    with one LU of ``A`` itself (``B^-1 = C^-1 A^-1 R^-1``): factorising the scaled matrix changes the
    pivots and, on a collocation matrix, filled 1.8 GB at N = 600. 0 where ``A`` is exactly singular.
    Below about 1e-14 a solve with ``A`` is noise.
    """
    A = sp.csc_matrix(A, dtype=float)
    rows = abs(A).max(axis=1).toarray().ravel()
    r = 1.0 / np.where(rows > 0, rows, 1.0)
    cols = abs(sp.diags(r) @ A).max(axis=0).toarray().ravel()
    c = 1.0 / np.where(cols > 0, cols, 1.0)
    try:
        lu = LU(A)
    except SingularMatrix:
        return 0.0
    v = np.random.default_rng(0).standard_normal(A.shape[0])
    v /= np.linalg.norm(v)
    growth = 0.0
    for _ in range(iterations):
        u = lu.solve(v / r) / c                  # B^-1 v
        v = lu.solve(u / c, trans=True) / r      # B^-T B^-1 v
        growth = float(np.linalg.norm(v))
        if not (math.isfinite(growth) and growth > 0):
            return 0.0
        v /= growth
    return 1.0 / math.sqrt(growth)


# --------------------------------------------------------------------------
# Bordered systems by block elimination
# --------------------------------------------------------------------------
#: backward error of a block-elimination solve (row by row, ``|f - M z| / (|f| + |M| 1 |z|_inf)``) at which it
#: is accepted. An LU of the whole matrix leaves 2e-14 .. 6e-12 on the Gamma = 1 rod's trace (461 .. 1511
#: unknowns) and elimination alone the same (accepted: at 1e-12 half the rod's solves were refined, 20 %
#: more time per step at N = 5000); one refinement step brings it to 1e-16, and at FD Bratu's located
#: fold, where elimination alone is wrong by 1e-1 of the solution (1e-4 backward), to the LU's accuracy
#: (tests/test_bordered.py)
BACKWARD_TOL = 1e-11
#: refinement steps before a solve falls back to the LU of the whole bordered matrix
MAX_REFINE = 2
#: the fallback LU scales the border row by 2^-BORDER_SHIFT (relative to J's columns), so that partial
#: pivoting takes it only where J's own pivot is that much smaller: its fill stays that of J's LU
#: (2^-20 still let FD Bratu at n = 20000 fill without bound; benchmarks/bordered_fd.py)
BORDER_SHIFT = 40


class BorderedSolver:
    """Solver for ``M = [[J, b], [c^T, d]]`` (``J`` sparse ``n x n``) by block elimination on the LU of ``J``.

    With ``w = J^-1 b`` and the Schur complement ``s = d - c.w``, ``M z = f`` is ``y = (f_n - c.J^-1 f') / s``,
    ``x = J^-1 f' - y w`` (Keller's BEC); ``det M = det J * s``. Near a fold ``J`` is nearly singular and
    this elimination alone loses digits along ``J``'s null vector (``1e-1`` of the solution at FD Bratu's
    located fold), though ``M`` itself is well conditioned; so each solve measures its backward error row
    by row, ``max_i |f - M z|_i / (|f_i| + sum_j |M_ij| |z|_inf)``, and applies up to ``MAX_REFINE`` steps of
    iterative refinement with the exact ``M`` (Govaerts' BEC+k; one step restores the accuracy of an LU of
    ``M``). If ``J`` has an exactly zero pivot, ``s`` vanishes, or refinement does not reach
    ``BACKWARD_TOL``, the solver falls back to an LU of ``M`` itself, its border row scaled by
    ``2^-BORDER_SHIFT`` (exact) so that partial pivoting takes it only where J's own pivot is that much
    smaller (its fill stays near J's), which raises :class:`SingularMatrix` where ``M`` is exactly singular,
    as the LU of ``M`` did before.

    Memory: the LU of ``J`` plus a few ``n``-vectors; never the dense border row in the factors (a natural
    LU of ``M`` pulled it into them: 50 to 500 times the nonzeros on FD Bratu). ``with_last_row`` gives the
    solver of ``M`` with another border row from the same LU of ``J`` (a new ``s``, no new factorisation);
    its ``lu`` is the solver it came from, as for :class:`RowUpdatedLU`.
    """

    def __init__(self, J, b: np.ndarray, c: np.ndarray, d: float, *, _shared=None):
        self.J = J = J if sp.issparse(J) and J.format == "csc" else sp.csc_matrix(J)
        self.b, self.c, self.d = np.asarray(b, float), np.asarray(c, float), float(d)
        self.n = J.shape[0] + 1
        self.lu = None  # the solver this one was derived from by with_last_row
        self._full = None
        self._rows = None  # sum_j |M_ij| per row, for the backward error
        self.fallbacks = 0  # solves answered by the LU of M
        if _shared is not None:
            self._luJ, self.w, self._rowsum = _shared
        else:
            self._rowsum = np.bincount(J.indices, weights=np.abs(J.data), minlength=J.shape[0])
            try:
                self._luJ = LU(J)
            except SingularMatrix:  # J exactly singular (a fold of the problem hit to the last bit)
                self._luJ, self.w = None, None
            else:
                self.w = self._luJ.solve(self.b)
        self.s = None if self._luJ is None else self.d - float(self.c @ self.w)
        if self.s is None or not (math.isfinite(self.s) and self.s != 0 and np.all(np.isfinite(self.w))):
            self._factorise_full()

    # ---- the fallback ----------------------------------------------------------------
    def _factorise_full(self) -> None:
        """LU of ``[[J, b], [sigma c^T, sigma d]]``, ``sigma = 2^-BORDER_SHIFT`` against J's column maxima."""
        if self._full is not None:
            return
        colmax = np.asarray(abs(self.J).max(axis=0).todense()).ravel()
        ratio = float(np.max(np.abs(self.c) / np.where(colmax > 0, colmax, 1.0))) if self.c.size else 0.0
        exponent = -BORDER_SHIFT - (math.ceil(math.log2(ratio)) if ratio > 0 and math.isfinite(ratio) else 0)
        self._sigma = math.ldexp(1.0, exponent)
        self._full = LU(bordered(self.J, self.b, self._sigma * self.c, self._sigma * self.d))

    def _full_solve(self, f: np.ndarray) -> np.ndarray:
        g = f.copy()
        g[-1] *= self._sigma
        return self._full.solve(g)

    # ---- solves -------------------------------------------------------------------------
    def _eliminate(self, f: np.ndarray) -> np.ndarray:
        z = np.empty(self.n)
        x = z[:-1]
        x[:] = self._luJ.solve(f[:-1])
        y = (f[-1] - float(self.c @ x)) / self.s
        x -= y * self.w
        z[-1] = y
        return z

    def _residual(self, z: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, bool]:
        """``r = f - M z`` and whether ``z`` is accepted: its backward error row by row (invariant to row
        scaling: the collocation rows differ by powers of the mesh width), ``|r_i| <= BACKWARD_TOL
        (|f_i| + sum_j |M_ij| |z|_inf)`` in every row (a NaN fails)."""
        x, y = z[:-1], z[-1]
        r = f.copy()
        r[:-1] -= self.J @ x
        r[:-1] -= y * self.b
        r[-1] -= float(self.c @ x) + self.d * y
        if self._rows is None:
            self._rows = np.append(self._rowsum + np.abs(self.b), float(np.sum(np.abs(self.c))) + abs(self.d))
        bound = np.abs(f)
        bound += max_norm(z) * self._rows
        return r, bool(np.all(np.abs(r) <= BACKWARD_TOL * bound))

    def solve(self, f: np.ndarray) -> np.ndarray:
        f = np.asarray(f, float)
        if self._full is not None:
            return self._solve_full_refined(f)
        z = self._eliminate(f)
        for _ in range(MAX_REFINE):
            r, ok = self._residual(z, f)
            if ok:
                return z
            z += self._eliminate(r)
        if self._residual(z, f)[1]:
            return z
        self.fallbacks += 1
        self._factorise_full()
        return self._solve_full_refined(f)

    def _solve_full_refined(self, f: np.ndarray) -> np.ndarray:
        z = self._full_solve(f)
        r, ok = self._residual(z, f)
        if not ok and np.all(np.isfinite(z)):
            z += self._full_solve(r)  # one step: the scaled row's growth is bounded by 2^BORDER_SHIFT
        return z

    def det(self) -> tuple[int, float]:
        """Sign and log-magnitude of ``det M = det J * s`` (or from the LU of ``M``)."""
        if self._full is not None:
            sign, log = self._full.det()
            return sign, log - math.log(self._sigma)
        sign, log = self._luJ.det()
        return sign * (1 if self.s > 0 else -1), log + math.log(abs(self.s))

    def with_last_row(self, old_row: np.ndarray, new_row: np.ndarray, u: np.ndarray | None = None):
        """The solver of ``M`` with its last row ``(c^T, d)`` replaced by ``new_row`` (``old_row`` and ``u``,
        the interface of :meth:`LU.with_last_row`, are not needed: ``s`` is recomputed from ``w``)."""
        new_row = np.asarray(new_row, float)
        if self._full is not None:  # this matrix needed the LU of M: update that (Sherman-Morrison)
            return RowUpdatedLU(self, old_row, new_row, u)
        out = BorderedSolver(self.J, self.b, new_row[:-1], new_row[-1],
                             _shared=(self._luJ, self.w, self._rowsum))
        out.lu = self
        return out

    def factor_nonzeros(self) -> int:
        """Nonzeros of the factors held (``L + U`` of ``J``, and of ``M`` after a fallback)."""
        total = 0
        for lu in (self._luJ, self._full):
            if lu is not None:
                total += lu._lu.L.nnz + lu._lu.U.nnz
        return total


def bordered_solver(J, b: np.ndarray, c: np.ndarray, d: float) -> BorderedSolver:
    """The tracker's default solver for ``[[J, b], [c^T, d]]`` (:class:`BorderedSolver`); a problem may
    provide its own ``bordered_solver(J, b, c, d)`` with ``solve``, ``det`` and ``with_last_row``."""
    return BorderedSolver(J, b, c, d)


def full_bordered_lu(J, b: np.ndarray, c: np.ndarray, d: float, row_scale: np.ndarray | None = None) -> LU:
    """A sparse LU of the assembled ``[[J, b], [c^T, d]]`` (natural order): the solver before
    :class:`BorderedSolver`, for a problem that wants it (``bordered_solver = full_bordered_lu``).
    ``row_scale``: powers of two for ``J``'s rows (:class:`LU`); the border row is left as it is. It must stay
    small against ``J``'s columns, or partial pivoting takes it and the fill has no bound: with ``J``'s rows
    equilibrated one by one (the stiffest, ~N^3, scaled down) the LU at 60 012 unknowns passed 6 GB, with the
    border row equilibrated too 22.9 GB, for 557 MB raw; scales by the equations' units keep it."""
    r = None if row_scale is None else np.append(np.asarray(row_scale, float), 1.0)
    return LU(bordered(J, b, c, d), row_scale=r)
