"""Domain volumes of a fixed network topology on moving grains (seed 004 §3.3, digest §2.5).

A domain is a union of triangles of the initial Delaunay triangulation of the grain centres
(digest §15.2). The topology is fixed (digest §0.2: fracturing does not merge domains), so as
the grains move each domain's volume is the sum of the signed areas of its triangles with the
current vertex positions: exactly the shoelace area of its centre polygon, x 1 m of depth.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..network.network import OUTSIDE, Network


def signed_triangle_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Counter-clockwise-positive areas of triangles (t, 3) over points (n, 2)."""
    a, b, c = points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def contact_gaps(points: np.ndarray, radii: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """d - r1 - r2 of grain pairs (k, 2): negative when they overlap (Eq. 14's gap)."""
    return np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1) - radii[pairs].sum(axis=1)


class DomainGeometry:
    """Volumes and centroids of a network's domains for any grain positions."""

    def __init__(self, net: Network):
        if net.triangles is None or net.points is None:
            raise ValueError("the network has no triangulation: moving-grain geometry needs a contact network")
        self.n_domains = net.n_domains
        inside = net.triangle_domain != OUTSIDE
        self.triangles = net.triangles[inside]
        self.triangle_domain = net.triangle_domain[inside]
        # orientation of each triangle as built, so that areas stay positive as grains move
        self.orientation = np.sign(signed_triangle_areas(net.points, self.triangles))
        # hull edges: contact pipes with a domain on one side only, directed with the domain on the left
        hull = (net.pipe_domains == OUTSIDE).sum(axis=1) == 1
        g = net.pipe_grains[hull]
        domain_on_left = net.pipe_domains[hull, 0] != OUTSIDE
        self.hull_edges = np.where(domain_on_left[:, None], g, g[:, ::-1])

    def volumes(self, points: np.ndarray) -> np.ndarray:
        """Domain volumes [m^3 per m] at grain positions ``points`` (n_grains, 2)."""
        area = self.orientation * signed_triangle_areas(points, self.triangles)
        return np.bincount(self.triangle_domain, weights=area, minlength=self.n_domains)

    def volume_gradient(self, points: np.ndarray) -> sp.csr_matrix:
        """dV/dx: the sparse (n_domains, 2 n_grains) derivative of :meth:`volumes` with respect to
        the grain centres, columns (x, y) of grain 0, grain 1, ... A triangle's area changes at
        vertex a by half the perpendicular of the opposite edge, (y_b - y_c, x_c - x_b) / 2."""
        t = self.triangles
        rows, cols, values = [], [], []
        for corner in range(3):
            b, c = points[t[:, (corner + 1) % 3]], points[t[:, (corner + 2) % 3]]
            grad = 0.5 * self.orientation[:, None] * np.c_[b[:, 1] - c[:, 1], c[:, 0] - b[:, 0]]
            for k in (0, 1):
                rows.append(self.triangle_domain)
                cols.append(2 * t[:, corner] + k)
                values.append(grad[:, k])
        shape = (self.n_domains, 2 * len(points))
        return sp.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=shape)

    def centroids(self, points: np.ndarray) -> np.ndarray:
        area = self.orientation * signed_triangle_areas(points, self.triangles)
        centre = points[self.triangles].mean(axis=1)
        volume = np.bincount(self.triangle_domain, weights=area, minlength=self.n_domains)
        return np.stack(
            [np.bincount(self.triangle_domain, weights=area * centre[:, k], minlength=self.n_domains) for k in (0, 1)],
            axis=1,
        ) / volume[:, None]

    def enclosed_area(self, points: np.ndarray) -> float:
        """Area enclosed by the hull contacts (the outer boundary of the domain tiling).

        Shoelace over the hull edges, each directed with its domain on the left; the outer face
        glued into the tiling through non-contact edges lies outside it. Equal to the sum of the
        domain volumes for any positions (digest §15.2 step 6, issue 3 volume conservation).
        """
        x0, x1 = points[self.hull_edges[:, 0]], points[self.hull_edges[:, 1]]
        return 0.5 * float(np.sum(x0[:, 0] * x1[:, 1] - x1[:, 0] * x0[:, 1]))
