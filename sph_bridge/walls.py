"""Wall particles of PF-SPH (seed 000 §2.9): the velocity and pressure the fluid sees in them
(Eq. 25, decisions #33) and the bounce-back of fluid particles that penetrate a wall (proximity ratio, Eqs. 18-24).

Walls are three layers of fixed particles on the fluid's dx lattice, at 0.5, 1.5 and 2.5 dx
behind the nominal surface (digest §2.9a).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .cells import separation
from .kernel import wendland, wendland_gradient_over_r

BOUNCE_BACK_BETA = 1.0  # seed 000 Eq. 24 ("affords the best results")


@njit(parallel=True, cache=True)
def wall_state(pos, vel, pressure, rho, fluid, gravity, h, cell, order, start, neighbours, shifts, inner):
    """What the fluid sees in the wall particles, from their fluid neighbours f (0 without any):

    - velocity -sum_f v_f W / sum_f W (seed 000 Eq. 25, Adami et al. 2012 with the wall at rest),
      so the viscous term imposes no slip (digest §2.9b);
    - pressure (sum_f P_f W + g . sum_f rho_f (r_w - r_f) W) / sum_f W, the same paper's
      extrapolation with the hydrostatic head (seed 000 gives walls no pressure rule, digest
      §2.9a; decisions #33).

    Returns copies of ``vel`` and ``pressure`` with the wall entries replaced."""
    n = pos.shape[0]
    vel_out, p_out = vel.copy(), pressure.copy()
    h2 = h * h
    # in cell order (sph_bridge.pfsph's docstring); i and j index these copies, vel_out and p_out do not
    pos, vel, pressure, rho, fluid = pos[order], vel[order], pressure[order], rho[order], fluid[order]
    for i in prange(n):
        if fluid[i]:
            continue
        c = cell[order[i]]
        wsum, vx, vy, vz, psum, head = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for k in range(inner):
            nc = neighbours[c, k]
            if nc < 0:
                continue
            for j in range(start[nc], start[nc + 1]):
                if not fluid[j]:
                    continue
                dx, dy, dz, r2 = separation(pos, i, j, shifts[c, k])
                if r2 < h2:
                    w = wendland(math.sqrt(r2), h)
                    wsum += w
                    vx += w * vel[j, 0]
                    vy += w * vel[j, 1]
                    vz += w * vel[j, 2]
                    psum += pressure[j] * w
                    head += rho[j] * (gravity[0] * dx + gravity[1] * dy + gravity[2] * dz) * w
        own = order[i]  # i in the caller's arrays
        if wsum > 0.0:
            vel_out[own, 0], vel_out[own, 1], vel_out[own, 2] = -vx / wsum, -vy / wsum, -vz / wsum
            p_out[own] = (psum + head) / wsum
        else:
            vel_out[own, 0], vel_out[own, 1], vel_out[own, 2] = 0.0, 0.0, 0.0
            p_out[own] = 0.0
    return vel_out, p_out


@njit(parallel=True, cache=True)
def proximity(pos, mass, fluid, h, bulk_number, cell, order, start, neighbours, shifts, inner):
    """Per fluid particle, the proximity ratio phi = 1 - n_wall / n_bulk (0.5 on the nominal wall
    surface, 1 from h into the fluid) and the unit normal -grad n_wall / |grad n_wall| pointing
    away from the wall; also the number density n = sum_j W_ij (fluid and wall). And, from the
    same neighbours, every particle's summation density rho = sum_j m_j W_ij (seed 000 Eq. 15),
    the same to the bit as :func:`sph_bridge.pfsph.density`'s: a step needs both at the same
    positions, and one pass over the neighbours costs less than two.

    Seed 000 Eqs. 18-23 take phi = n_fluid / n and the normal from the fluid colour gradient.
    Both equal these where the fluid fills the kernel (n_fluid + n_wall = n_bulk), but at a
    free surface or a contact line the missing fluid neighbours pull n_fluid / n below 0.5 on
    the first fluid layer, which then bounced every step and pinned the contact line (the
    truncation bias digest §2.9c mentions; decisions #35). Measuring the wall's share against
    the bulk lattice value keeps the paper's flat-wall values (Eq. 21) everywhere.

    Returns (rho, phi, normal, n)."""
    n = pos.shape[0]
    rho = np.empty(n)
    phi = np.ones(n)
    normal = np.zeros((n, 3))
    number = np.zeros(n)
    h2 = h * h
    # in cell order (sph_bridge.pfsph's docstring); i and j index these copies
    pos, mass, fluid = pos[order], mass[order], fluid[order]
    for i in prange(n):
        c = cell[order[i]]
        total, n_all, n_wall, gx, gy, gz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for k in range(inner):
            nc = neighbours[c, k]
            if nc < 0:
                continue
            for j in range(start[nc], start[nc + 1]):
                dx, dy, dz, r2 = separation(pos, i, j, shifts[c, k])
                if r2 >= h2:
                    continue
                r = math.sqrt(r2)
                w = wendland(r, h)
                total += mass[j] * w
                n_all += w
                if fluid[i] and not fluid[j]:
                    n_wall += w
                    # grad_i W_ij = r_ij (1/r) dW/dr points from i toward j: -grad n_wall points away
                    g = wendland_gradient_over_r(r, h)
                    gx -= g * dx
                    gy -= g * dy
                    gz -= g * dz
        own = order[i]  # i in the caller's arrays
        rho[own] = total
        if not fluid[i]:
            continue
        phi[own] = 1.0 - n_wall / bulk_number
        number[own] = n_all
        norm = math.sqrt(gx * gx + gy * gy + gz * gz)
        if norm > 0.0:
            normal[own, 0], normal[own, 1], normal[own, 2] = gx / norm, gy / norm, gz / norm
    return rho, phi, normal, number


def bounce_back(pos, vel_list, phi, normal, fluid, dx):
    """Move fluid particles with phi < 0.5 by beta dx (1 - phi/0.5) along the normal into the
    fluid and stop them (seed 000 Eq. 24); ``vel_list``: the velocity arrays to zero. Returns the
    indices of those that bounced."""
    inside = fluid & (phi < 0.5)
    if inside.any():
        pos[inside] += (BOUNCE_BACK_BETA * dx * (1.0 - phi[inside] / 0.5))[:, None] * normal[inside]
        for v in vel_list:
            v[inside] = 0.0
    return np.flatnonzero(inside)

