"""FHP-II lattice gas with multi-spin coding (seed 003 §2; digest §1).

The lattice is triangular with horizontal rows: node (i, j) sits at x = i + (j mod 2)/2,
y = j sqrt(3)/2. Channel k = 1..6 moves along c_k = (cos(pi(k-1)/3), sin(pi(k-1)/3)); channel 0
is the rest particle. A state is seven bit-planes, ``state[k, j, w]``: bit b of word w of row j
is node i = 64 w + b. Collisions are boolean expressions on whole words (64 nodes at a time),
propagation is shifts with the triangular row offset, and each step is one pass over the rows,
parallel with numba.

One step: collide (fluid nodes) -> force (a fraction g of fluid nodes) -> propagate -> wall rules.
The stored state between steps is the one after forcing; :func:`advance` fuses
"propagate, wall rules, collide" into one pass and :func:`apply_forcing` follows it.

Walls (digest §1.4): at a ``solid`` node every particle reverses (bounce-back, no-slip); at a
``mirror`` node channels 2<->6 and 3<->5 swap (specular reflection, a symmetry plane). Neither
collides. x is periodic for any row length; y is periodic only when asked (an even number of
rows keeps the row parity), otherwise rows outside the lattice are empty.

Momentum bookkeeping is in half units (h = 2 p_x, an integer): channel k carries H_UNITS[k].
A bounce-back of a particle in channel k loses 2 H_UNITS[k]; forcing rule (a) gains 4 and rules
(b), (c) gain 2 each. Collisions, propagation and the mirror conserve p_x exactly, so
P_x(t+1) - P_x(t) = forcing - wall loss every step (digest §1.6, claim C5).
"""

from __future__ import annotations

import math
import types

import numpy as np
from numba import njit, prange

CHANNELS = 7
H_UNITS = np.array([0, 2, 1, -1, -2, -1, 1], dtype=np.int64)  # 2 c_kx: half units of x-momentum
Y_UNITS = np.array([0, 0, 1, 1, 0, -1, -1], dtype=np.int64)  # c_ky / (sqrt(3)/2)
OPPOSITE = np.array([0, 4, 5, 6, 1, 2, 3])
MIRRORED = np.array([0, 1, 6, 5, 4, 3, 2])  # y-reflection

_ONE = np.uint64(1)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)
_S1, _S63 = np.uint64(1), np.uint64(63)


def words_per_row(nx: int) -> int:
    return (nx + 63) // 64


def pack(sites: np.ndarray) -> np.ndarray:
    """Boolean ``(..., ny, nx)`` -> ``(..., ny, words)`` uint64 bit-planes (node i at bit i % 64 of
    word i // 64)."""
    sites = np.asarray(sites, dtype=bool)
    nx = sites.shape[-1]
    padded = np.zeros(sites.shape[:-1] + (words_per_row(nx) * 64,), dtype=bool)
    padded[..., :nx] = sites
    bytes_ = np.packbits(padded.reshape(sites.shape[:-1] + (-1, 8)), axis=-1, bitorder="little")
    return np.ascontiguousarray(bytes_.reshape(sites.shape[:-1] + (-1,))).view("<u8").copy()


def unpack(words: np.ndarray, nx: int) -> np.ndarray:
    """Inverse of :func:`pack`: ``(..., ny, words)`` -> boolean ``(..., ny, nx)``."""
    bytes_ = np.ascontiguousarray(words).astype("<u8").view(np.uint8)
    return np.unpackbits(bytes_, axis=-1, bitorder="little")[..., :nx].astype(bool)


@njit(cache=True, inline="always")
def _splitmix(z):
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _popcount(x):
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return np.int64((x * np.uint64(0x0101010101010101)) >> np.uint64(56))


@njit(cache=True, inline="always")
def _from_left(row, w, nx, last_mask):
    """Word w of the row moved one node towards +x (new node i = old node i - 1, periodic)."""
    nw = row.shape[0]
    if w > 0:
        carry = row[w - 1] >> _S63
    else:
        carry = (row[nw - 1] >> np.uint64((nx - 1) % 64)) & _ONE
    out = (row[w] << _S1) | carry
    if w == nw - 1:
        out &= last_mask
    return out


@njit(cache=True, inline="always")
def _from_right(row, w, nx):
    """Word w of the row moved one node towards -x (new node i = old node i + 1, periodic)."""
    nw = row.shape[0]
    if w < nw - 1:
        return (row[w] >> _S1) | (row[w + 1] << _S63)
    return (row[w] >> _S1) | ((row[0] & _ONE) << np.uint64((nx - 1) % 64))


@njit(cache=True, inline="always")
def collide(n0, n1, n2, n3, n4, n5, n6, chirality):
    """FHP-II collision of 64 nodes (digest §1.2, rules R1-R4); ``chirality`` picks the rotation
    sense of head-on pairs node by node. Returns the seven new words. States with four or more
    particles, a head-on pair with a moving spectator, a triple with a rest particle and every
    other state not listed stay unchanged."""
    r, nr = chirality, ~chirality
    # R1 + R2: a head-on pair and nothing else moving (a rest particle may sit by)
    p1 = n1 & n4 & ~(n2 | n3 | n5 | n6)
    p2 = n2 & n5 & ~(n1 | n3 | n4 | n6)
    p3 = n3 & n6 & ~(n1 | n2 | n4 | n5)
    # R3: symmetric triples, no rest particle
    t = ((n1 & n3 & n5 & ~(n2 | n4 | n6)) | (n2 & n4 & n6 & ~(n1 | n3 | n5))) & ~n0
    # R4: rest + one moving (k) <-> two moving at 120 degrees (k-1, k+1), nothing else
    u1 = (n0 & n1 & ~(n2 | n3 | n4 | n5 | n6)) | (~n0 & n6 & n2 & ~(n1 | n3 | n4 | n5))
    u2 = (n0 & n2 & ~(n1 | n3 | n4 | n5 | n6)) | (~n0 & n1 & n3 & ~(n2 | n4 | n5 | n6))
    u3 = (n0 & n3 & ~(n1 | n2 | n4 | n5 | n6)) | (~n0 & n2 & n4 & ~(n1 | n3 | n5 | n6))
    u4 = (n0 & n4 & ~(n1 | n2 | n3 | n5 | n6)) | (~n0 & n3 & n5 & ~(n1 | n2 | n4 | n6))
    u5 = (n0 & n5 & ~(n1 | n2 | n3 | n4 | n6)) | (~n0 & n4 & n6 & ~(n1 | n2 | n3 | n5))
    u6 = (n0 & n6 & ~(n1 | n2 | n3 | n4 | n5)) | (~n0 & n5 & n1 & ~(n2 | n3 | n4 | n6))
    # pair k -> (k+1, k+4) with chirality, (k-1, k+2) without
    f1 = p1 | (p2 & nr) | (p3 & r) | t | u6 | u1 | u2
    f2 = p2 | (p1 & r) | (p3 & nr) | t | u1 | u2 | u3
    f3 = p3 | (p2 & r) | (p1 & nr) | t | u2 | u3 | u4
    f4 = p1 | (p3 & r) | (p2 & nr) | t | u3 | u4 | u5
    f5 = p2 | (p1 & r) | (p3 & nr) | t | u4 | u5 | u6
    f6 = p3 | (p2 & r) | (p1 & nr) | t | u5 | u6 | u1
    f0 = u1 | u2 | u3 | u4 | u5 | u6
    return n0 ^ f0, n1 ^ f1, n2 ^ f2, n3 ^ f3, n4 ^ f4, n5 ^ f5, n6 ^ f6


def advance(state, spare, solid, mirror, fluid, nx, periodic_y, seed, step0, g, fluid_nodes, gains, losses):
    """Run ``len(gains)`` steps from step number ``step0``; the result is left in ``state``.

    Each step propagates into ``spare``, applies the wall rules, collides the fluid nodes (one
    pass, parallel over rows), swaps the two arrays and forces (:func:`apply_forcing`).
    ``gains[t]`` and ``losses[t]`` receive step t's x-momentum added by forcing and lost to
    bounce-back (half units). Chirality bits come from a counter-based hash of (seed, step,
    row, word), so a run is the same on any number of threads."""
    ny = state.shape[1]
    rem = nx % 64
    last_mask = _ALL if rem == 0 else (_ONE << np.uint64(rem)) - _ONE
    row_loss = np.zeros(ny, dtype=np.int64)
    old, new = state, spare
    for t in range(gains.shape[0]):
        base = _splitmix(np.uint64(seed)) ^ (np.uint64(step0 + t) * np.uint64(0xD1B54A32D192ED03))
        for j in prange(ny):
            row_loss[j] = _advance_row(old, new, solid, mirror, fluid, nx, periodic_y, base, j, last_mask)
        losses[t] = row_loss.sum()
        old, new = new, old
        gains[t] = apply_forcing(old, fluid_nodes, nx, g) if g > 0 else 0
    if gains.shape[0] % 2 == 1:
        state[:] = spare


def _named_copy(func, name: str):
    """``func`` under another name. Numba's on-disk cache files a function by module, name and
    line, and keys its entries by signature, not by jit options (numba issue #6845): compiled
    from one function, the serial and the parallel kernel would share one cache entry and
    whichever was compiled first would serve both."""
    copy = types.FunctionType(func.__code__, func.__globals__, name, func.__defaults__, func.__closure__)
    copy.__qualname__ = name
    copy.__doc__ = func.__doc__
    return copy


advance_parallel = njit(cache=True, parallel=True)(_named_copy(advance, "advance_parallel"))
advance_serial = njit(cache=True)(_named_copy(advance, "advance_serial"))
PARALLEL_WORDS = 16_000  # ~1e6 nodes: below this one thread beats the cost of a parallel region per step


@njit(cache=True, inline="always")
def _advance_row(old, new, solid, mirror, fluid, nx, periodic_y, base, j, last_mask):
    """Row j of one step: pull-propagate, wall rules, collision. Returns the row's bounce-back
    loss of x-momentum (half units)."""
    ny, nw = old.shape[1], old.shape[2]
    odd = (j & 1) == 1
    below, above = j - 1, j + 1
    if periodic_y:
        below, above = below % ny, above % ny
    loss = np.int64(0)
    for w in range(nw):
        a0 = old[0, j, w]
        a1 = _from_left(old[1, j], w, nx, last_mask)
        a4 = _from_right(old[4, j], w, nx)
        a2 = a3 = a5 = a6 = np.uint64(0)
        if below >= 0:
            if odd:
                a2 = old[2, below, w]
                a3 = _from_right(old[3, below], w, nx)
            else:
                a2 = _from_left(old[2, below], w, nx, last_mask)
                a3 = old[3, below, w]
        if above < ny:
            if odd:
                a5 = _from_right(old[5, above], w, nx)
                a6 = old[6, above, w]
            else:
                a5 = old[5, above, w]
                a6 = _from_left(old[6, above], w, nx, last_mask)
        s = solid[j, w]
        if s != 0:  # bounce-back: every moving particle reverses
            loss += 2 * (2 * _popcount(a1 & s) + _popcount(a2 & s) - _popcount(a3 & s)
                         - 2 * _popcount(a4 & s) - _popcount(a5 & s) + _popcount(a6 & s))
            ns = ~s
            a1, a4 = (a1 & ns) | (a4 & s), (a4 & ns) | (a1 & s)
            a2, a5 = (a2 & ns) | (a5 & s), (a5 & ns) | (a2 & s)
            a3, a6 = (a3 & ns) | (a6 & s), (a6 & ns) | (a3 & s)
        m = mirror[j, w]
        if m != 0:  # specular: 2 <-> 6, 3 <-> 5 (x-momentum unchanged)
            nm = ~m
            a2, a6 = (a2 & nm) | (a6 & m), (a6 & nm) | (a2 & m)
            a3, a5 = (a3 & nm) | (a5 & m), (a5 & nm) | (a3 & m)
        f = fluid[j, w]
        c0, c1, c2, c3, c4, c5, c6 = collide(a0, a1, a2, a3, a4, a5, a6, _splitmix(base ^ np.uint64(j * nw + w)))
        nf = ~f
        new[0, j, w] = (a0 & nf) | (c0 & f)
        new[1, j, w] = (a1 & nf) | (c1 & f)
        new[2, j, w] = (a2 & nf) | (c2 & f)
        new[3, j, w] = (a3 & nf) | (c3 & f)
        new[4, j, w] = (a4 & nf) | (c4 & f)
        new[5, j, w] = (a5 & nf) | (c5 & f)
        new[6, j, w] = (a6 & nf) | (c6 & f)
    return loss


@njit(cache=True)
def seed_forcing(seed):
    """Seed the generator that picks forcing sites (numba's own, separate from NumPy's)."""
    np.random.seed(seed)


@njit(cache=True)
def apply_forcing(state, fluid_nodes, nx, g):
    """Forcing rules (seed 003 Fig. 4, digest §1.5) at a fraction ``g`` of the fluid nodes,
    drawn at random this step: (a) c4 -> c1 (+2 p_x), (b) c3 -> c2 (+1), (c) c5 -> c6 (+1),
    each wherever its source is occupied and its target empty; all three at once where possible
    (they use disjoint channels). Each node is chosen with probability g, independently: the
    gaps between chosen nodes are geometric, so the cost is the number of chosen nodes.
    ``fluid_nodes`` lists the fluid nodes as j * nx + i.
    Returns the x-momentum added, in half units."""
    n = fluid_nodes.shape[0]
    log_miss = math.log1p(-g)
    gain = np.int64(0)
    k = -1
    while True:
        k += 1 + int(math.log(1.0 - np.random.random()) / log_miss)
        if k >= n:
            break
        j, i = divmod(np.int64(fluid_nodes[k]), nx)
        w, bit = i >> 6, _ONE << np.uint64(i & 63)
        for src, dst, h in ((4, 1, 4), (3, 2, 2), (5, 6, 2)):
            if (state[src, j, w] & bit) != 0 and (state[dst, j, w] & bit) == 0:
                state[src, j, w] ^= bit
                state[dst, j, w] ^= bit
                gain += h
    return gain


@njit(cache=True)
def row_sums(state, mask, counts, momentum_x):
    """Per row j over the nodes in ``mask``: particles (``counts[j]``) and x-momentum in half
    units (``momentum_x[j]``)."""
    ny, nw = state.shape[1], state.shape[2]
    for j in range(ny):
        c = np.int64(0)
        p = np.int64(0)
        for w in range(nw):
            m = mask[j, w]
            if m == 0:
                continue
            c1, c4 = _popcount(state[1, j, w] & m), _popcount(state[4, j, w] & m)
            c2, c3 = _popcount(state[2, j, w] & m), _popcount(state[3, j, w] & m)
            c5, c6 = _popcount(state[5, j, w] & m), _popcount(state[6, j, w] & m)
            c += _popcount(state[0, j, w] & m) + c1 + c2 + c3 + c4 + c5 + c6
            p += 2 * (c1 - c4) + c2 - c3 - c5 + c6
        counts[j] = c
        momentum_x[j] = p


@njit(cache=True)
def accumulate_fields(state, nx, density, momentum_x, momentum_y):
    """Add each node's particle number, x-momentum (half units) and y-momentum (units of
    sqrt(3)/2) to the ``(ny, nx)`` accumulators."""
    ny, nw = state.shape[1], state.shape[2]
    for j in range(ny):
        for w in range(nw):
            w0, w1, w2, w3 = state[0, j, w], state[1, j, w], state[2, j, w], state[3, j, w]
            w4, w5, w6 = state[4, j, w], state[5, j, w], state[6, j, w]
            if (w0 | w1 | w2 | w3 | w4 | w5 | w6) == 0:
                continue
            for b in range(min(64, nx - 64 * w)):
                sh = np.uint64(b)
                e0, e1, e2 = np.int64((w0 >> sh) & _ONE), np.int64((w1 >> sh) & _ONE), np.int64((w2 >> sh) & _ONE)
                e3, e4, e5 = np.int64((w3 >> sh) & _ONE), np.int64((w4 >> sh) & _ONE), np.int64((w5 >> sh) & _ONE)
                e6 = np.int64((w6 >> sh) & _ONE)
                i = 64 * w + b
                density[j, i] += e0 + e1 + e2 + e3 + e4 + e5 + e6
                momentum_x[j, i] += 2 * (e1 - e4) + e2 - e3 - e5 + e6
                momentum_y[j, i] += e2 + e3 - e5 - e6
