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
import scipy.sparse as sp

from ..network.network import OUTSIDE, Network


def pressure_force_matrix(net: Network, radii: np.ndarray, positions: np.ndarray | None = None) -> sp.csr_matrix:
    """The linear map (Eq. 8) from domain pressures (n_domains,) to grain forces, as a sparse
    (2 n_grains, n_domains) matrix whose rows are (f_x, f_y) of grain 0, grain 1, ... [N per m
    per Pa]. ``positions``: current grain centres when grains have moved since the network was
    built (the topology, and so which domains touch which corner, is fixed)."""
    points = net.points if positions is None else positions
    g0, g1 = net.pipe_grains[:, 0], net.pipe_grains[:, 1]
    u = points[g1] - points[g0]
    u /= np.linalg.norm(u, axis=1)[:, None]
    right = np.c_[u[:, 1], -u[:, 0]]  # J(u): out of the left domain, into the right one
    rows, cols, values = [], [], []
    # each edge pushes both end grains by r n (p_left - p_right); the outer face has no pressure
    for domains, sign in ((net.pipe_domains[:, 0], 1.0), (net.pipe_domains[:, 1], -1.0)):
        inside = domains != OUTSIDE
        for ends in (g0, g1):
            for k in (0, 1):
                rows.append(2 * ends[inside] + k)
                cols.append(domains[inside])
                values.append(sign * radii[ends[inside]] * right[inside, k])
    shape = (2 * len(points), net.n_domains)
    return sp.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=shape)


def grain_pressure_forces(net: Network, radii: np.ndarray, pressure: np.ndarray,
                          positions: np.ndarray | None = None) -> np.ndarray:
    """Force (n_grains, 2) [N per m of depth] on every grain from the domain pressures (Eq. 8).

    ``positions``: as for :func:`pressure_force_matrix`.
    """
    return (pressure_force_matrix(net, radii, positions) @ pressure).reshape(-1, 2)
