"""A plain FHP-II automaton, one byte per node, to cross-check the bit-parallel kernel (decisions #58).

Deliberately the other way round from :mod:`sph_bridge.lga.automaton`, sharing none of its code:
bit 0 of a node's byte is the rest particle, bit k = 1..6 the particle moving along
c_k = (cos(pi(k-1)/3), sin(pi(k-1)/3)); a collision is a look-up in a 2 x 128 table built from the
rules R1-R4 written as sets (:func:`sph_bridge.lga.rules.reference_outcomes`, digest §1.2), the
row picked by one random chirality bit per node; propagation pulls each particle from the
neighbour it comes from, found by explicit index arithmetic on the triangular lattice
(node (i, j) at x = i + (j mod 2)/2, y = j sqrt(3)/2). The lattice is periodic both ways and has
no walls or forcing: it exists to measure the automaton's own viscosity with an independent
implementation (:func:`sph_bridge.lga.shear_wave.shear_wave_viscosity`, ``implementation="reference"``).
It is 30-40x slower than the kernel and not used by any run. The shear wave's start and its
checks repeat :func:`sph_bridge.lga.shear_wave.decay`'s on purpose: no kernel code may run here.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .rules import STATES, reference_outcomes

# (row step, column step from an even row, column step from an odd row) of the neighbour along c_k
NEIGHBOUR = np.array([(0, 0, 0), (0, 1, 1), (1, 0, 1), (1, -1, 0), (0, -1, -1), (-1, -1, 0), (-1, 0, 1)],
                     dtype=np.int64)
HALF_PX = np.array([0, 2, 1, -1, -2, -1, 1], dtype=np.int64)  # 2 c_kx of bit k


def collision_table() -> np.ndarray:
    """``table[chirality, state]``: the outcome of R1-R4; the two chiral outcomes of a head-on
    pair go to chirality 0 and 1, every other state has one outcome (in both rows)."""
    table = np.empty((2, STATES), dtype=np.uint8)
    for state in range(STATES):
        outcomes = sorted(reference_outcomes(state))
        table[0, state] = outcomes[0]
        table[1, state] = outcomes[-1]
    return table


@njit(cache=True)
def _seed(seed):
    np.random.seed(seed)


@njit(cache=True)
def _step(nodes, new, table):
    """One step: propagate (pull from the upstream neighbour of each channel), then collide."""
    ny, nx = nodes.shape
    for j in range(ny):
        for i in range(nx):
            state = nodes[j, i] & 1  # the rest particle stays
            for k in range(1, 7):
                # the particle arriving along c_k left the neighbour along -c_k, channel k
                back = (k + 2) % 6 + 1
                dj = NEIGHBOUR[back, 0]
                di = NEIGHBOUR[back, 1] if j % 2 == 0 else NEIGHBOUR[back, 2]
                source = nodes[(j + dj) % ny, (i + di) % nx]
                state |= source & (1 << k)
            new[j, i] = table[1 if np.random.random() < 0.5 else 0, state]


@njit(cache=True)
def _row_momentum(nodes, out):
    """x-momentum of each row in half units."""
    ny, nx = nodes.shape
    for j in range(ny):
        total = 0
        for i in range(nx):
            for k in range(1, 7):
                if nodes[j, i] >> k & 1:
                    total += HALF_PX[k]
        out[j] = total


def decay(rows: int, length: int, density: float, velocity: float, steps: int, seed: int) -> tuple[np.ndarray, float]:
    """The sin(k y) mode of j_x (half units per row) at steps 0..steps, and k, for a shear wave
    started as in :func:`sph_bridge.lga.shear_wave.decay`: moving channel k occupied with
    probability d + e c_kx sin(k y), e = velocity density / 3, the rest channel with d."""
    if rows % 2:
        raise ValueError(f"rows must be even (the lattice is periodic in y), got {rows}")
    d = density / 7.0
    e = velocity * density / 3.0
    if not (velocity > 0.0 and 0.0 < d - e and d + e < 1.0):
        raise ValueError(f"velocity must be > 0 and keep the channel occupations inside (0, 1) at density "
                         f"{density}, got {velocity}")
    k = 2.0 * np.pi / (rows * np.sqrt(3.0) / 2.0)
    sines = np.sin(k * np.arange(rows) * np.sqrt(3.0) / 2.0)
    rng = np.random.default_rng(seed + 104729)
    nodes = (rng.random((rows, length)) < d).astype(np.uint8)
    for bit in range(1, 7):
        occupation = d + e * HALF_PX[bit] / 2.0 * sines[:, None]
        nodes |= ((rng.random((rows, length)) < occupation).astype(np.uint8) << bit)
    _seed(seed)
    table = collision_table()
    spare = np.empty_like(nodes)
    momentum = np.empty(rows, dtype=np.int64)
    amplitude = np.empty(steps + 1)
    for t in range(steps + 1):
        if t:
            _step(nodes, spare, table)
            nodes, spare = spare, nodes
        _row_momentum(nodes, momentum)
        amplitude[t] = 2.0 * float(momentum @ sines) / rows
    return amplitude, k
