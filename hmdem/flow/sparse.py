"""Sparse assembly with a precomputed pattern, and the linear solve chosen by size.

The pattern (where each COO entry lands in CSR storage) is built once per topology, so each
assembly is one ``np.bincount`` (DESIGN: "COO to CSR with precomputed index patterns").
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

DIRECT_MAX_UNKNOWNS = 60_000  # above this, pyamg-preconditioned CG
MAX_REFINEMENTS = 6  # iterative-refinement passes after the first solve
REFINED = 1e-17  # stop refining at this residual relative to the terms of b


# a failed solve, not round-off: near-singular held systems (Eq. 19) reach ~1e-7 unpivoted
FAILED = 1e-5
ROUND_OFF = 64 * np.finfo(float).eps  # a row residual this small against its terms is round-off
# the rows' summed residual is formed in extended precision, and pipe fluxes cancel in it exactly
MASS_ROUND_OFF = 64 * np.finfo(np.longdouble).eps


def refine(correction, b: np.ndarray, residual, size: float, mass_defect=None) -> tuple[np.ndarray, float, np.ndarray]:
    """x from ``correction(b)`` refined in extended precision against ``residual(x)``; returns
    x, its residual relative to ``size``, and the residual itself.

    ``mass_defect(r)``, if given, is the rows' summed residual relative to their terms: the
    step's mass defect (digest U8). Pipe fluxes enter two rows with opposite signs, so their
    round-off cancels in that sum but not in the norm. With huge conductances (a nearly inviscid
    grounded fluid) the norm can sit at that floor while the sum is 1e-5 Q dt off (decisions #79);
    a correction that lowers such a sum is then taken even if it does not lower the norm, and
    refinement stops once a correction lowers neither.
    """
    def defect(r):
        return 0.0 if mass_defect is None else mass_defect(r)

    y = correction(b).astype(np.longdouble)
    r = residual(y)
    lowest = np.linalg.norm(r)
    for _ in range(MAX_REFINEMENTS):
        rnorm, off = np.linalg.norm(r), defect(r)
        unbalanced = off > MASS_ROUND_OFF
        if rnorm <= REFINED * size and not unbalanced:
            break
        step = correction(r.astype(float))
        r_next = residual(y + step)
        next_norm = np.linalg.norm(r_next)
        rebalances = unbalanced and next_norm <= 2.0 * lowest and defect(r_next) < off
        if next_norm < rnorm or rebalances:
            y, r = y + step, r_next
            lowest = min(lowest, next_norm)
        if next_norm >= 0.5 * rnorm and not rebalances:  # at the round-off floor of both
            break
    return y, float(np.linalg.norm(r) / size), r


class LinearSolveError(RuntimeError):
    """The linear solver did not reach the requested true residual."""


class CsrPattern:
    """Maps COO entries (rows, cols) to positions in a fixed CSR structure."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, n: int):
        keys = rows.astype(np.int64) * n + cols
        unique_keys, self.slot = np.unique(keys, return_inverse=True)
        self.n = n
        self.indices = (unique_keys % n).astype(np.int32)
        self.indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(unique_keys // n, minlength=n), out=self.indptr[1:])
        self.nnz = len(unique_keys)

    def matrix(self, values: np.ndarray) -> sp.csr_matrix:
        data = np.bincount(self.slot, weights=values, minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


class SpdSolver:
    """Solves A x = b for symmetric positive definite matrices sharing one CSR pattern.

    Rows and columns are scaled to a unit diagonal (conductances span many decades, digest
    §15.4). Up to ``DIRECT_MAX_UNKNOWNS`` unknowns: SuperLU with a fill-reducing ordering fixed
    once (the one given, e.g. nested dissection, else COLAMD on the first matrix) and no
    pivoting, which is stable for SPD matrices and ~3x cheaper than ordering every
    factorisation. Above that size: CG preconditioned by
    smoothed-aggregation AMG (pyamg). Either way the answer is refined against the caller's
    residual and checked.
    """

    def __init__(self, ordering: np.ndarray | None = None):
        self._fill_reducing = ordering  # new position -> unknown; None: COLAMD on the first matrix
        self._order = None  # (permutation q, permuted CSC indices, indptr, data map)
        self._last_factor = None  # (scaled CSR values, their LU)

    def __getstate__(self):  # SuperLU objects do not pickle (checkpoints); the next solve refactors
        return {**self.__dict__, "_last_factor": None}

    def __setstate__(self, state):
        self.__dict__.update({"_last_factor": None, **state})

    def _ordering(self, A: sp.csr_matrix):
        if self._order is None:
            q = self._fill_reducing
            if q is None:
                q = np.argsort(spla.splu(A.tocsc(), permc_spec="COLAMD").perm_c)
            marker = sp.csr_matrix((np.arange(1, A.nnz + 1, dtype=float), A.indices, A.indptr), shape=A.shape)
            permuted = marker[q][:, q].tocsc()
            self._order = (q, permuted.indices, permuted.indptr, permuted.data.astype(np.int64) - 1)
        return self._order

    def solve(self, A: sp.csr_matrix, b: np.ndarray, rtol: float = 1e-12, residual=None, b_size=None,
              storage=None, floating=None, offset=None) -> np.ndarray:
        """x with A x = b.

        ``residual(x)``, if given, returns b - A x computed more accurately than from the stored
        A and b (e.g. from the fluxes the solution implies); iterative refinement then converges
        to that more accurate solution instead of stalling at the round-off of forming b.
        ``b_size`` (>= |b| per row): the size of the terms b was summed from. Near a steady
        state b is a small difference of large terms, and the failure check compares the
        residual with those terms rather than with b itself.
        ``storage`` (the diagonal's storage part) and ``floating`` (per unknown: a component
        label, -1 where the component reaches a Dirichlet value) let a system whose floating
        components are singular in double precision be solved by :func:`floating_solve`.
        ``offset``: the values x is an increment of (p^n for a pressure increment); they set the
        round-off floor of an island's rows in :func:`floating_residual`.
        """
        n = A.shape[0]
        if n == 0:
            return np.zeros(0)
        scale = 1.0 / np.sqrt(A.diagonal())
        rows = np.repeat(np.arange(n), np.diff(A.indptr))
        As = sp.csr_matrix((A.data * scale[rows] * scale[A.indices], A.indices, A.indptr), shape=A.shape)
        bs = b * scale
        bnorm = np.linalg.norm(bs)
        if bnorm == 0.0:
            return np.zeros(n)
        if residual is None:
            residual = lambda x: b - A @ x  # noqa: E731

        def scaled_residual(y):
            return residual(y * scale) * scale

        size = bnorm if b_size is None else max(bnorm, np.linalg.norm(b_size * scale))
        islands = floating is not None and bool(np.any(floating >= 0))
        b_terms = np.abs(b) if b_size is None else b_size

        # the grounded rows' summed residual: a shut-in island's is settled on its own (settle_island_levels)
        grounded = slice(None) if floating is None else floating < 0
        terms = float(np.sum(b_terms[grounded]))

        def mass_defect(r):
            return abs(float(np.sum(r[grounded] / scale[grounded]))) / terms if terms > 0.0 else 0.0

        def settled(y, res, r):
            """An LU answer (residual ``r``) with each island at the level its mass balance fixes:
            a tiny non-zero pivot leaves that level wrong while the residual of the whole system
            looks small (Ca* 1e-9: 12 Q dt off, decisions #78); the island's balance is then checked."""
            if not islands or res > FAILED:
                return y, res
            y, r = settle_island_levels(y, r, scale, storage, floating)
            return y, max(float(np.linalg.norm(r) / size), island_defect(r, scale, floating, b_terms))

        try:
            correction = self._direct(As) if n <= DIRECT_MAX_UNKNOWNS else self._amg(As, rtol)
            y, res = settled(*refine(correction, bs, scaled_residual, size, mass_defect))
        except RuntimeError:  # SuperLU without pivoting met a zero pivot
            y, res = None, np.inf
        if (not np.isfinite(res) or res > FAILED) and islands:
            try:
                deflated = floating_solve(A, storage, floating)
                y, _, r = refine(lambda r: deflated(r / scale) / scale, bs, scaled_residual, size, mass_defect)
                level = np.zeros(n) if offset is None else offset / scale
                res = floating_residual(As, y, level, r, scale, size, floating, b_terms)
            except RuntimeError:
                y, res = None, np.inf
        if (not np.isfinite(res) or res > FAILED) and n <= DIRECT_MAX_UNKNOWNS:
            # near-singular without pivoting, e.g. an Eq. 19 held system whose invaded island of
            # a nearly inviscid, stiff fluid is tied to the rest only by its storage V/(K dt)
            # (~1e-15 of its conductances at Ca* = 1e-8, M = 1e-3): partial pivoting
            try:
                y, res = settled(*refine(self._pivoted(As), bs, scaled_residual, size, mass_defect))
            except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
                raise LinearSolveError(f"pressure solve: {exc} (n = {n})") from None
        if not np.isfinite(res) or res > FAILED:
            raise LinearSolveError(f"pressure solve residual {res:.2e} (n = {n})")
        return (y * scale).astype(float)

    @staticmethod
    def _pivoted(As: sp.csr_matrix):
        """Solve function of an LU factorisation with partial pivoting (SuperLU's default)."""
        lu = spla.splu(As.tocsc())
        return lu.solve

    def _direct(self, As: sp.csr_matrix):
        """Solve function of an LU factorisation in the stored fill-reducing ordering. The last
        factorisation is kept and reused while the matrix is the same to the bit: the P-V
        evaluations of a coupled step change only the right side (decisions #65)."""
        q, indices, indptr, data_map = self._ordering(As)
        last = self._last_factor
        if last is not None and np.array_equal(last[0], As.data):
            lu = last[1]
        else:
            permuted = sp.csc_matrix((As.data[data_map], indices, indptr), shape=As.shape)
            lu = spla.splu(permuted, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
            self._last_factor = As.data.copy(), lu

        def solve(r):
            y = np.empty(len(r))
            y[q] = lu.solve(r[q])
            return y

        return solve

    def _amg(self, As: sp.csr_matrix, rtol: float):
        """Solve function of CG preconditioned by smoothed-aggregation AMG (pyamg)."""
        import pyamg

        preconditioner = pyamg.smoothed_aggregation_solver(As, symmetry="symmetric").aspreconditioner()
        return lambda r: spla.cg(As, r, rtol=rtol, maxiter=500, M=preconditioner)[0]


def island_residual_sums(r, scale, floating):
    """(member mask, island label of each member, per island the sum of its rows' unscaled
    residuals): summed over an island the pipe terms cancel, leaving sum b - storage . x."""
    member = floating >= 0
    label = floating[member]
    return member, label, np.bincount(label, np.asarray(r, float)[member] / scale[member])


def settle_island_levels(y, r, scale, storage, floating):
    """``y`` (scaled unknowns, scaled residual ``r``) and its residual with each shut-in island
    shifted to the level its own mass balance fixes: summed over an island the pipe terms
    cancel, so its rows' residuals add up to sum b - storage . x, and the uniform shift
    sum(r) / sum(storage) zeroes that sum. The shift moves no pipe flux, so each row's residual
    changes by its storage times the shift exactly, with no new evaluation of the residual."""
    member, label, defect = island_residual_sums(r, scale, floating)
    total = np.bincount(label, storage[member], len(defect))
    shift = np.divide(defect, total, out=np.zeros_like(defect), where=total > 0.0)
    y, r = y.copy(), r.copy()
    y[member] += shift[label] / scale[member]
    r[member] -= storage[member] * shift[label] * scale[member]
    return y, r


def island_defect(r, scale, floating, b_size) -> float:
    """Largest mass defect of a shut-in island: |sum of its rows' residuals| (the pipe terms
    cancel, leaving sum b - storage . x) over the sum of its rows' term sizes ``b_size``.
    ``r`` is the residual of the scaled system (row i multiplied by ``scale[i]``)."""
    member, label, defect = island_residual_sums(r, scale, floating)
    terms = np.bincount(label, b_size[member])
    defect = np.abs(defect)
    return float(np.max(defect / np.maximum(terms, np.finfo(float).tiny), initial=0.0))


def floating_residual(As, y, level, r, scale, size, floating, b_size) -> float:
    """Relative residual of a solution with shut-in islands (scaled system As y = b S, residual
    r, y an increment of the scaled values ``level``, e.g. p^n): the rows that reach a Dirichlet
    value against ``size`` as usual, and each island's mass balance (:func:`island_defect`).
    Inside an island a row residual at the round-off of the row's terms, |A| (|level| + |y|), is
    accepted: the island sits at a pressure so far above its internal pressure differences (~b/G)
    that double precision resolves them only to ~eps pressure/difference, and no solve can do
    better. The pressure counts whole, not only its increment: an island at rest (y ~ 0) at 43 Pa
    holds its differences only to ~eps 43 Pa once p^n + y is stored (Ca* = 1e-9, decisions #78).
    A larger residual fails the solution (inf)."""
    r = np.asarray(r, float)
    member = floating >= 0
    grounded = np.linalg.norm(r[~member]) / size
    floor = ROUND_OFF * (abs(As) @ (np.abs(level) + np.abs(y)))[member]
    interior_at_round_off = bool(np.all(np.abs(r[member]) <= floor))
    if not interior_at_round_off:
        return np.inf
    return float(max(grounded, island_defect(r, scale, floating, b_size)))


def floating_solve(A: sp.csr_matrix, storage: np.ndarray, floating: np.ndarray):
    """Solve function for A = L + diag(storage) whose floating components (no path to a
    Dirichlet value; ``floating`` labels them, -1 elsewhere) are singular in double precision.

    A floating component's equations sum to storage . x = sum b (the pipe terms cancel), so with
    x = c + y and storage . y = 0 its level is c = sum b / sum storage exactly, and y solves the
    compatible system L y = b - c storage. That system is solved with one node of the component
    held at 0 (a grounded Laplacian, well conditioned) and y shifted to storage . y = 0. For an
    invaded island shut in by capillarity over a very long step (storage V/(K dt) ~1e-17 of its
    conductances) this is the uniform pressure rise Q dt / sum(V/K) the island must take; the
    residual left in the held node is ~storage/conductance and goes in the caller's refinement.
    """
    n = A.shape[0]
    member = np.flatnonzero(floating >= 0)
    label = floating[member]
    n_comp = int(label.max()) + 1
    total = np.bincount(label, storage[member], n_comp)
    if np.any(total[np.unique(label)] <= 0.0):
        raise LinearSolveError("floating component without storage (incompressible and shut in): singular")
    _, first = np.unique(label, return_index=True)
    keep = np.ones(n, bool)
    keep[member[first]] = False
    sub = A[keep][:, keep].tocsc()
    scale = 1.0 / np.sqrt(sub.diagonal())
    lu = spla.splu((sp.diags(scale) @ sub @ sp.diags(scale)).tocsc(), permc_spec="COLAMD")

    def solve(b):
        level = np.bincount(label, b[member], n_comp) / total
        rhs = b.copy()
        rhs[member] -= level[label] * storage[member]
        x = np.zeros(n)
        x[keep] = scale * lu.solve(scale * rhs[keep])
        shift = np.bincount(label, storage[member] * x[member], n_comp) / total
        x[member] += level[label] - shift[label]
        return x

    return solve
