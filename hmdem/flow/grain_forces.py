"""Fluid pressure forces on grains (seed 004 Eq. 8, digest §8).

The pressure p of a domain acts on the arc of each corner grain exposed to it; integrated, the
force is 2 p r sin(beta) along the corner bisector, pushing the grain away from the domain,
with no moment (it passes through the grain centre). Written per pipe: each boundary edge of a
domain adds p r n to both of its end grains, n being the edge's unit normal pointing out of the
domain; at a corner the two normals add to 2 sin(beta) along the outward bisector. Per metre of
depth (x 1 m). The outer face (``OUTSIDE``) carries no pressure.
"""

from __future__ import annotations

import numpy as np

from ..network.network import OUTSIDE, Network


def grain_pressure_forces(net: Network, radii: np.ndarray, pressure: np.ndarray,
                          positions: np.ndarray | None = None) -> np.ndarray:
    """Force (n_grains, 2) [N per m of depth] on every grain from the domain pressures (Eq. 8).

    ``positions``: current grain centres (n_grains, 2) when grains have moved since the network
    was built (the topology, and so which domains touch which corner, is fixed).
    """
    points = net.points if positions is None else positions
    g0, g1 = net.pipe_grains[:, 0], net.pipe_grains[:, 1]
    u = points[g1] - points[g0]
    u /= np.linalg.norm(u, axis=1)[:, None]
    right = np.c_[u[:, 1], -u[:, 0]]  # J(u): out of the left domain, into the right one
    left, right_dom = net.pipe_domains[:, 0], net.pipe_domains[:, 1]
    p_left = np.where(left != OUTSIDE, pressure[np.maximum(left, 0)], 0.0)
    p_right = np.where(right_dom != OUTSIDE, pressure[np.maximum(right_dom, 0)], 0.0)
    push = (p_left - p_right)[:, None] * right  # p n summed over the two faces of the edge
    n = len(net.points)
    force = np.zeros((n, 2))
    for ends in (g0, g1):
        for k in (0, 1):
            force[:, k] += np.bincount(ends, weights=radii[ends] * push[:, k], minlength=n)
    return force
