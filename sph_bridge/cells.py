"""Cell lists for neighbour search: a fixed grid over the domain box, particles binned by a
counting sort each step, and a per-cell table of neighbour cells (digest seed 000 §6: cell-linked
lists with a prefix-sum layout).

Cells are at least ``cell_size`` wide; pairs within ``reach`` cell widths are found through the
table. The table lists the 3^3 cells of the inner shell first, so a search over r < cell_size
(the SPH kernel support h) stops after :attr:`CellGrid.inner` columns, while one over
r < reach x cell_size (the pairwise force, 2h) uses them all. The first column is the cell
itself, and :attr:`CellGrid.forward` marks the half of the others whose offset is
lexicographically positive: a sum that takes each pair once (Newton's third law) visits the
cell itself (partners later in it) and the forward columns only. Periodic axes wrap, with the image
shift stored per table entry; along other axes particles outside the box go to the edge cells
(only the search's efficiency suffers). Memory is linear in the number of cells and particles.
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit


class CellGrid:
    """Grid over the box [lo, hi) with cells of at least ``cell_size``; ``periodic`` per axis."""

    def __init__(self, lo, hi, periodic, cell_size: float, reach: int = 2):
        self.lo = np.asarray(lo, float)
        self.length = np.asarray(hi, float) - self.lo
        self.periodic = np.asarray(periodic, bool)
        if np.any(self.length <= 0.0) or cell_size <= 0.0:
            raise ValueError("the box needs hi > lo on every axis and a positive cell size")
        self.dims = np.maximum(1, np.floor(self.length / cell_size)).astype(np.int64)
        short = self.periodic & (self.dims < 2 * reach + 1)
        if short.any():
            raise ValueError(f"periodic box length {self.length[short].min():.4g} m is below {2 * reach + 1} "
                             f"interaction cells ({(2 * reach + 1) * cell_size:.4g} m): a particle would meet "
                             "its own image")
        self.cell_width = self.length / self.dims
        self.reach = reach
        offsets = sorted(itertools.product(range(-reach, reach + 1), repeat=3), key=lambda o: max(map(abs, o)))
        self.inner = 27 if reach >= 1 else 1
        # offset o pairs with -o: the forward half holds one of each (the cell itself comes first)
        self.forward = np.array([o > (0, 0, 0) for o in offsets], bool)
        self.neighbours, self.shifts = self._table(np.array(offsets, np.int64))

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.dims))

    def _table(self, offsets: np.ndarray):
        """(n_cells, K) neighbour cell ids (-1: outside a non-periodic box) and (n_cells, K, 3)
        image shifts: a particle j found through entry k is at pos_j + shift."""
        coords = np.stack(np.unravel_index(np.arange(self.n_cells), tuple(self.dims)), axis=1)
        target = coords[:, None, :] + offsets[None, :, :]
        wraps = np.floor_divide(target, self.dims)
        outside = np.any((wraps != 0) & ~self.periodic, axis=2)
        target = target - wraps * self.dims
        ids = np.ravel_multi_index(tuple(np.moveaxis(target, 2, 0)), tuple(self.dims))
        ids = np.where(outside, -1, ids)
        shifts = wraps * self.length
        return ids.astype(np.int64), shifts.astype(float)

    def bin(self, pos: np.ndarray):
        """(cell id per particle, particle order sorted by cell, start offset per cell + end)."""
        return bin_particles(pos, self.lo, self.cell_width, self.dims, self.periodic, self.length)


@njit(cache=True)
def bin_particles(pos, lo, width, dims, periodic, length):
    n = pos.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, np.int64)
    for i in range(n):
        c = 0
        for a in range(3):
            x = pos[i, a] - lo[a]
            if periodic[a]:
                x = x % length[a]
            k = int(np.floor(x / width[a]))
            k = min(max(k, 0), dims[a] - 1)
            c = c * dims[a] + k
        cell[i] = c
    start = np.zeros(n_cells + 1, np.int64)
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return cell, order, start


@njit(inline="always")
def separation(pos, i, j, shift):
    """r_i - (r_j + shift) and its squared length: particle j seen from i through a neighbour
    table entry whose periodic image shift is ``shift`` (:meth:`CellGrid._table`)."""
    dx = pos[i, 0] - pos[j, 0] - shift[0]
    dy = pos[i, 1] - pos[j, 1] - shift[1]
    dz = pos[i, 2] - pos[j, 2] - shift[2]
    return dx, dy, dz, dx * dx + dy * dy + dz * dz
