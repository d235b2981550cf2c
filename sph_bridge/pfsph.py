"""PF-SPH particle sums (seed 000 §2.3-2.9): density, pressure, and the accelerations from the
pressure, viscous and pairwise interaction forces, summed over a cell list.

The sums loop in parallel (numba ``prange``) over particles, or over runs of them, and over the
neighbour cells of :class:`sph_bridge.cells.CellGrid`; no pair list is stored, so memory stays
linear in N.
The loops read copies of the particle arrays in cell order (``a[order]``), so that a cell's
particles are adjacent in memory: as a drop stirs, the particles' own order loses all relation
to their place, and gathering through ``order`` cost the force sum 1.75x its time on the 2e-4 m
puddle. The density is gathered per particle; the forces are evaluated once per pair
(:func:`accelerations`).
Particles are fluid (``fluid`` True) or fixed wall particles. Pair terms are antisymmetric in
(i, j), so with fluid only they conserve momentum to round-off (digest §7 #4).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .cells import separation
from .kernel import INTERACTION_RANGE, interaction_shape, wendland, wendland_gradient_over_r


@njit(inline="always")
def summed_density(i, c, pos, mass, h, start, neighbours, shifts, inner):
    """sum_j m_j W(r_ij, h) for particle i (cell-ordered arrays) in cell c."""
    total = 0.0
    h2 = h * h
    for k in range(inner):
        nc = neighbours[c, k]
        if nc < 0:
            continue
        for j in range(start[nc], start[nc + 1]):
            _, _, _, r2 = separation(pos, i, j, shifts[c, k])
            if r2 < h2:
                total += mass[j] * wendland(math.sqrt(r2), h)
    return total


@njit(parallel=True, cache=True)
def density(pos, mass, h, cell, order, start, neighbours, shifts, inner):
    """rho_i = sum_j m_j W(r_ij, h) over every particle, itself and walls included (seed 000
    Eq. 15; digest §2.3: the sum runs over all N particles)."""
    n = pos.shape[0]
    rho = np.empty(n)
    pos, mass = pos[order], mass[order]  # in cell order (module docstring); i and j index these copies
    for i in prange(n):
        rho[order[i]] = summed_density(i, cell[order[i]], pos, mass, h, start, neighbours, shifts, inner)
    return rho


@njit(parallel=True, cache=True)
def refresh_density(rho, dirty, pos, mass, h, cell, order, start, neighbours, shifts, inner):
    """:func:`density` again, in place, for the particles in the cells marked ``dirty`` only: after a
    few particles moved (a bounce-back), the cells within h of where they were and are now. The
    others' sums hold none of them, so the result is the full sum's to the bit."""
    pos, mass = pos[order], mass[order]  # in cell order (module docstring)
    for i in prange(pos.shape[0]):
        c = cell[order[i]]
        if dirty[c]:
            rho[order[i]] = summed_density(i, c, pos, mass, h, start, neighbours, shifts, inner)


def pressure(rho: np.ndarray, rho0: np.ndarray, c0: float, p0: float = 0.0) -> np.ndarray:
    """Tait equation of state P = c0^2 rho0 / 7 ((rho/rho0)^7 - 1) + P0 (seed 000 Eq. 13; P0 is
    not given in the paper, 0 by default: digest §2.4)."""
    return c0 * c0 * rho0 / 7.0 * ((rho / rho0) ** 7 - 1.0) + p0


def density_from_pressure(p: np.ndarray, rho0: np.ndarray, c0: float, p0: float = 0.0) -> np.ndarray:
    """The inverse of :func:`pressure` (Eq. 13), clipped at a tension that would empty the particle."""
    return rho0 * np.maximum(1.0 + 7.0 * (p - p0) / (c0 * c0 * rho0), 1e-6) ** (1.0 / 7.0)


@njit(inline="always")
def pair_force_over_r(i, j, r, h, mass, rho, pressure, fluid, s_ff, s_sf):
    """The non-viscous part of the force on fluid particle i from j, divided by r_ij [N/m] (a
    vector along r_i - r_j): the pairwise force of Eq. 27, s [8 f(2r/h) - f(r/h)] / r with s = s_ff
    between fluid particles and s_sf with a wall, and the pressure force of Eq. 16 with its
    sign restored, -m_i m_j (P_i/rho_i^2 + P_j/rho_j^2) (1/r) dW/dr. A wall's extrapolated
    pressure is taken as max(P_j, 0): the wall's own term only pushes (decisions #35). The fluid
    particle's own term keeps its sign, as against a fluid neighbour: the wall's mass is in its
    summation density, and the force must follow that density both ways or it stops being the
    gradient of the EOS energy; clamping it drove a ~0.1 m/s circulation along the wall
    (decisions #37)."""
    s = s_ff if fluid[j] else s_sf
    f = s * interaction_shape(r, h) / r if s != 0.0 else 0.0
    if r < h:
        p_i, p_j = pressure[i], pressure[j]
        if not fluid[j]:
            p_j = max(p_j, 0.0)
        f -= mass[i] * mass[j] * (p_i / (rho[i] * rho[i]) + p_j / (rho[j] * rho[j])) * wendland_gradient_over_r(r, h)
    return f


FORCE_CHUNKS = 8  # runs of particles the force sum splits into: a fixed number, so its result is thread-free


def work_chunks(fluid, n_chunks):
    """Bounds of ``n_chunks`` runs of consecutive particles (in cell order) with about equal work
    for :func:`accelerations`: a fluid particle scans its forward cells and evaluates its pairs,
    a wall particle only scans them for fluid partners (counted as a quarter of the work)."""
    weight = np.where(fluid, 1.0, 0.25).cumsum()
    bounds = np.searchsorted(weight, weight[-1] * np.arange(1, n_chunks) / n_chunks) if len(weight) else []
    return np.concatenate([[0], np.asarray(bounds, np.int64), [len(fluid)]]).astype(np.int64)


def accelerations(pos, vel, mass, rho, pressure, viscosity, fluid, s_ff, s_sf, h, gravity,
                  cell, order, start, neighbours, shifts, forward):
    """dv_i/dt of every fluid particle (0 for walls), seed 000 Eq. 11:

    - pressure, Eq. 16 with the sign restored (digest §2.5): -sum_j m_j (P_i/rho_i^2 + P_j/rho_j^2) grad_i W_ij;
    - viscosity, Morris et al. (1997), Eq. 17: sum_j m_j (mu_i + mu_j)/(rho_i rho_j) v_ij (1/r) dW/dr;
    - pairwise interaction, Eq. 27: s [8 f(2r/h) - f(r/h)] e_ij / m_i with s = s_ff between fluid
      particles and s_sf with a wall particle (range 2h);
    - gravity.

    ``vel`` is the velocity the forces see: the extrapolated v-bar of the Verlet scheme for fluid
    particles and the Eq. 25 extrapolation for walls (digest §2.10, §2.9b).

    Each pair with a fluid particle in it is evaluated once and its force given to both (Newton's
    third law; the pair terms are antisymmetric), which halves the work of a gather over both
    particles' neighbourhoods. Particles are split into :data:`FORCE_CHUNKS` :func:`work_chunks`,
    each summing into its own force array (24 B per particle each); the arrays are added in a
    fixed order, so the result is the same to the bit on any number of threads, and a checkpoint
    resumes alike on another machine. More threads than chunks would idle in this sum.
    """
    order = np.asarray(order)
    bounds = work_chunks(np.asarray(fluid)[order], FORCE_CHUNKS)
    force = np.zeros((FORCE_CHUNKS, len(order), 3))
    pair_forces(pos, vel, mass, rho, pressure, viscosity, fluid, s_ff, s_sf, h, cell, order, start, neighbours,
                shifts, forward, bounds, force)
    acc = np.zeros((len(order), 3))
    acc[order] = force.sum(axis=0) / np.asarray(mass)[order, None]
    acc[fluid] += gravity
    acc[~np.asarray(fluid, bool)] = 0.0
    return acc


@njit(parallel=True, cache=True)
def pair_forces(pos, vel, mass, rho, pressure, viscosity, fluid, s_ff, s_sf, h, cell, order, start, neighbours,
                shifts, forward, bounds, force):
    """Add the pressure, viscous and pairwise forces of every pair with a fluid particle in it to
    ``force[chunk]`` (in cell order), each pair once: from the particle whose chunk, in
    :func:`accelerations`' split ``bounds``, holds the one that finds the other in a forward
    column (or later in its own cell)."""
    cutoff2 = (INTERACTION_RANGE * h) ** 2
    h2 = h * h
    # in cell order (module docstring); i and j below index these copies
    pos, vel, mass, rho = pos[order], vel[order], mass[order], rho[order]
    pressure, viscosity, fluid = pressure[order], viscosity[order], fluid[order]
    for chunk in prange(len(bounds) - 1):
        out = force[chunk]
        for i in range(bounds[chunk], bounds[chunk + 1]):
            c = cell[order[i]]
            for k in range(neighbours.shape[1]):
                nc = neighbours[c, k]
                if nc < 0 or not (k == 0 or forward[k]):
                    continue
                first = i + 1 if k == 0 else start[nc]  # column 0 is the cell itself: later partners only
                for j in range(first, start[nc + 1]):
                    if not (fluid[i] or fluid[j]):
                        continue
                    dx, dy, dz, r2 = separation(pos, i, j, shifts[c, k])
                    if r2 >= cutoff2 or r2 == 0.0:
                        continue
                    r = math.sqrt(r2)
                    # the force on the fluid one of the pair, seen from it; along r_i - r_j on i
                    f = pair_force_over_r(i, j, r, h, mass, rho, pressure, fluid, s_ff, s_sf) if fluid[i] else \
                        pair_force_over_r(j, i, r, h, mass, rho, pressure, fluid, s_ff, s_sf)
                    fx, fy, fz = f * dx, f * dy, f * dz
                    if r2 < h2:
                        grad = wendland_gradient_over_r(r, h)  # grad_i W_ij = (dx, dy, dz) * grad
                        visc = mass[i] * mass[j] * (viscosity[i] + viscosity[j]) / (rho[i] * rho[j]) * grad
                        fx += visc * (vel[i, 0] - vel[j, 0])
                        fy += visc * (vel[i, 1] - vel[j, 1])
                        fz += visc * (vel[i, 2] - vel[j, 2])
                    out[i, 0] += fx
                    out[i, 1] += fy
                    out[i, 2] += fz
                    out[j, 0] -= fx
                    out[j, 1] -= fy
                    out[j, 2] -= fz
