"""Particle placement on the dx lattice (seed 000 §2.11): fluid blocks and wall slabs.

A wall's nominal surface lies dx/2 in front of its outermost particle layer; three layers sit
at 0.5, 1.5 and 2.5 dx behind it (digest §2.9a). A fluid block [lo, hi] holds particles at
lo + (i + 1/2) dx, so a block resting on a wall surface starts dx/2 above it, like the wall's
first layer dx/2 below: the lattice continues across the surface.
"""

from __future__ import annotations

import numpy as np

WALL_LAYERS = 3


def lattice_block(lo, hi, dx: float) -> np.ndarray:
    """Centres lo + (i + 1/2) dx of the cubic lattice cells inside the box [lo, hi] (n, 3)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    counts = np.floor((hi - lo) / dx + 1e-9).astype(int)
    if np.any(counts < 1):
        raise ValueError(f"block {lo} .. {hi} is thinner than one particle spacing {dx:g} m")
    axes = [lo[a] + (np.arange(counts[a]) + 0.5) * dx for a in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def wall_slab(axis: int, surface: float, facing: int, lo, hi, dx: float, layers: int = WALL_LAYERS) -> np.ndarray:
    """Wall particles behind the plane x_axis = ``surface`` whose fluid side is ``facing`` (+1:
    fluid at larger x_axis, -1: smaller), spanning [lo, hi] along the two other axes."""
    if facing not in (1, -1):
        raise ValueError("facing must be +1 or -1")
    lo, hi = np.array(lo, float), np.array(hi, float)
    lo[axis] = surface - facing * layers * dx if facing == 1 else surface
    hi[axis] = surface if facing == 1 else surface + layers * dx
    return lattice_block(lo, hi, dx)
