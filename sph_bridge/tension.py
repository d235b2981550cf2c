"""Surface tension of the PF-SPH fluid, measured mechanically on a free liquid slab.

A slab of fluid, periodic along x and y and free above and below, relaxes at zero gravity. Its
surface tension is the anisotropy of the pair stress summed over the slab (Kirkwood and Buff's
mechanical route, Irving-Kirkwood pair virial):

    sigma = 1/(2A) sum_{i<j} [ z_ij F_ij,z - (x_ij F_ij,x + y_ij F_ij,y) / 2 ]

with A the slab's area (two interfaces) and F_ij the force on i from j. Both fluid-fluid forces
of PF-SPH are central pair forces: the pressure force of seed 000 Eq. 16 (the many-body part
sits in P_i and rho_i only) and the pairwise force of Eq. 27 (:func:`sph_bridge.pfsph.pair_force_over_r`,
the one the time step uses), so the sum is the model's own surface tension,
whatever share the equation-of-state tension of the surface particles and the pairwise
cohesion take (digest §2.7 asks for sigma to be measured, not computed from s alone). The
viscous force vanishes at rest; the kinetic term is isotropic and dropped.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .cells import separation
from .geometry import lattice_block
from .kernel import INTERACTION_RANGE
from .pfsph import pair_force_over_r
from .simulation import Simulation, SphParameters

SLAB_SIDE = 18  # periodic width in dx: 5 kernel supports (h = 3.42 dx), the pairwise force's 2h each side
JITTER = 0.1  # random displacement of the starting lattice sites, in dx
SLAB_LAYERS = 20  # thickness in dx: a bulk region beyond the pairwise range 2h of both surfaces


@njit(parallel=True, cache=True)
def stress_anisotropy(pos, mass, rho, pressure, fluid, s_ff, s_sf, h, cell, order, start, neighbours, shifts):
    """Per fluid particle, half of sum_j [z_ij F_ij,z - (x_ij F_ij,x + y_ij F_ij,y)/2] over its
    neighbours (each pair split between its two particles) [N m]."""
    n = pos.shape[0]
    out = np.zeros(n)
    cutoff2 = (INTERACTION_RANGE * h) ** 2
    for i in prange(n):
        if not fluid[i]:
            continue
        c = cell[i]
        total = 0.0
        for k in range(neighbours.shape[1]):
            nc = neighbours[c, k]
            if nc < 0:
                continue
            for idx in range(start[nc], start[nc + 1]):
                j = order[idx]
                if j == i:
                    continue
                dx, dy, dz, r2 = separation(pos, i, j, shifts[c, k])
                if r2 >= cutoff2 or r2 == 0.0:
                    continue
                f = pair_force_over_r(i, j, math.sqrt(r2), h, mass, rho, pressure, fluid, s_ff, s_sf)
                total += f * (dz * dz - 0.5 * (dx * dx + dy * dy))
        out[i] = 0.5 * total
    return out


def slab(params: SphParameters, side: int = SLAB_SIDE, layers: int = SLAB_LAYERS, jitter: float = JITTER,
         seed: int = 0) -> Simulation:
    """A free slab of ``layers`` dx, periodic ``side`` dx along x and y, with vacuum of 2h + 1 dx
    above and below inside the box (the box's z ends are not periodic). Sites are displaced by
    up to ``jitter`` dx at random (``seed``): the perfect cubic lattice is a metastable state
    whose surface rearranges after ~1,000 steps with a 35 % higher tension."""
    dx = params.dx
    length, height = side * dx, layers * dx
    fluid = lattice_block([0, 0, 0], [length, length, height], dx)
    fluid += np.random.default_rng(seed).uniform(-jitter * dx, jitter * dx, fluid.shape)
    gap = INTERACTION_RANGE * params.h + dx
    return Simulation(fluid, np.empty((0, 3)), params, [0, 0, -gap], [length, length, height + gap],
                      (True, True, False))


def surface_tension(sim: Simulation) -> float:
    """sigma of a relaxed free slab (module docstring) [N/m]."""
    p, g = sim.params, sim.grid
    virial = stress_anisotropy(sim.pos, sim.mass, sim.rho, sim.pressure, sim.fluid, p.s_ff, p.s_sf, sim.h,
                               *sim._lists())
    area = g.length[0] * g.length[1]
    return float(virial.sum() / (2.0 * area))


def bulk_density(sim: Simulation) -> float:
    """Mean density of the slab's particles farther than the pairwise range 2h from both surfaces."""
    z = sim.pos[sim.fluid, 2]
    reach = INTERACTION_RANGE * sim.h
    inner = (z > z.min() + reach) & (z < z.max() - reach)
    return float(sim.rho[sim.fluid][inner].mean())
