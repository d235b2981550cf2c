"""Fill-reducing ordering of the pressure unknowns by geometric nested dissection.

The network is planar, so cutting it at the median coordinate (alternating to the longer
side) leaves separators of ~sqrt(n) unknowns; numbering each half first and the separator
last keeps the Cholesky/LU fill at O(n log n) (George 1973). On the Lenormand packings this
factorises 1.3x (1,188 grains) to 1.5x (20,000 grains) faster than COLAMD, whose cost per
unknown grows with n (BENCHMARKS.md).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

LEAF_SIZE = 16  # pieces this small are numbered as they come


def nested_dissection(adjacency: sp.csr_matrix, xy: np.ndarray, leaf_size: int = LEAF_SIZE) -> np.ndarray:
    """Permutation (new position -> unknown) for a symmetric sparsity pattern with unknowns at xy."""
    adjacency = sp.csr_matrix(adjacency, dtype=float)
    n = adjacency.shape[0]
    order: list[np.ndarray] = []
    # explicit stack; a piece is split into (left, right, separator), the separator emitted last
    stack: list[tuple[np.ndarray, bool]] = [(np.arange(n), False)]
    right_side = np.zeros(n)
    while stack:
        piece, is_separator = stack.pop()
        if is_separator or len(piece) <= leaf_size:
            order.append(piece)
            continue
        pts = xy[piece]
        axis = int(np.ptp(pts[:, 0]) < np.ptp(pts[:, 1]))
        left = pts[:, axis] < np.median(pts[:, axis])
        if left.all() or not left.any():
            order.append(piece)
            continue
        right_side[piece[~left]] = 1.0
        separator = left & (adjacency[piece] @ right_side > 0)  # left unknowns touching the right half
        right_side[piece[~left]] = 0.0
        # popped in reverse: left half, right half, then the separator
        stack.append((piece[separator], True))
        stack.append((piece[~left], False))
        stack.append((piece[left & ~separator], False))
    perm = np.concatenate(order) if order else np.zeros(0, int)
    return perm
