"""Sparse assembly with a precomputed pattern, and the linear solve chosen by size.

The pattern (where each COO entry lands in CSR storage) is built once per topology, so each
assembly is one ``np.bincount`` (DESIGN: "COO to CSR with precomputed index patterns").
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

DIRECT_MAX_UNKNOWNS = 60_000  # above this, pyamg-preconditioned CG


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


def solve_spd(A: sp.csr_matrix, b: np.ndarray, x0: np.ndarray | None = None, rtol: float = 1e-12) -> np.ndarray:
    """Solve the symmetric positive definite system A x = b and check the true residual.

    Direct (SuperLU) up to ``DIRECT_MAX_UNKNOWNS`` unknowns, with one step of iterative
    refinement; above that, CG preconditioned by smoothed-aggregation AMG on the symmetrically
    diagonal-scaled matrix (conductances span many decades, digest §15.4).
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros(0)
    scale = 1.0 / np.sqrt(A.diagonal())
    D = sp.diags(scale)
    As = (D @ A @ D).tocsr()
    bs = b * scale
    bnorm = np.linalg.norm(bs)
    if bnorm == 0.0:
        return np.zeros(n)
    if n <= DIRECT_MAX_UNKNOWNS:
        lu = spla.splu(As.tocsc(), permc_spec="MMD_AT_PLUS_A")
        y = lu.solve(bs)
        for _ in range(3):  # iterative refinement
            r = bs - As @ y
            if np.linalg.norm(r) <= 1e-15 * bnorm:
                break
            y = y + lu.solve(r)
    else:
        import pyamg

        ml = pyamg.smoothed_aggregation_solver(As, symmetry="symmetric")
        y0 = None if x0 is None else x0 / scale
        y, _ = spla.cg(As, bs, x0=y0, rtol=rtol, maxiter=500, M=ml.aspreconditioner())
    res = np.linalg.norm(bs - As @ y) / bnorm
    # a failed solve, not round-off: near-singular held systems (Eq. 19) reach ~1e-7
    if not np.isfinite(res) or res > 1e-5:
        raise LinearSolveError(f"pressure solve residual {res:.2e} (n = {n})")
    return y * scale
