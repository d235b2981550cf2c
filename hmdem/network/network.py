"""The pore network: domains (pores) joined by pipes (throats), as named numpy arrays.

Topology (domains, pipes, their incidence) is fixed at construction; the geometry arrays
(``domain_volume``, ``pipe_aperture``) may be updated in place by a coupling. All 2D quantities
are per metre of out-of-plane depth (seed 004 uses 1 m thick discs): a domain "volume" is its
polygon area x 1 m, in m^3 per m.

A pipe whose ``pipe_domains`` holds ``OUTSIDE`` (-1) on one side borders the outer face of the
contact graph (a hull contact); it counts in the Euler relation but carries no flow (digest
seed 004 §3.1 [INTERP]: boundaries act through domain types, not through hull pipes). A pipe
with the same domain on both sides (a dangling contact) carries no flow either.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

OUTSIDE = -1


def pipes_touching(pipe_domains: np.ndarray, domains) -> np.ndarray:
    """Mask of the pipes with one of ``domains`` on either side (e.g. the injection port's)."""
    return np.isin(pipe_domains, domains).any(axis=1)


@dataclass
class Network:
    """Domains and pipes of a planar pore network (seed 004 §2.1, digest §3).

    Arrays (n domains, m pipes):
      domain_centroid (n, 2) m; domain_volume (n,) m^3 per m of depth;
      pipe_domains (m, 2) int, OUTSIDE for the outer face; pipe_length (m,) m;
      pipe_aperture (m,) m; pipe_grains (m, 2) int (grain ids: the lattice's sites too);
      inlet_domains, outlet_domains: int index arrays.
    Optional drawing data: ``triangles`` (t, 3) vertex ids into ``points`` with
    ``triangle_domain`` (t,), the domain each triangle belongs to (OUTSIDE for the outer face),
    and ``triangle_neighbors`` (t, 3), the triangle across the edge opposite each vertex (-1: none).
    """

    domain_centroid: np.ndarray
    domain_volume: np.ndarray
    pipe_domains: np.ndarray
    pipe_length: np.ndarray
    pipe_aperture: np.ndarray
    pipe_grains: np.ndarray
    inlet_domains: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    outlet_domains: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    points: np.ndarray | None = None
    triangles: np.ndarray | None = None
    triangle_domain: np.ndarray | None = None
    triangle_neighbors: np.ndarray | None = None
    n_vertices: int = 0
    extent: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)  # xmin, xmax, ymin, ymax

    @property
    def n_domains(self) -> int:
        return len(self.domain_volume)

    @property
    def n_pipes(self) -> int:
        return len(self.pipe_length)

    @property
    def flowing_pipes(self) -> np.ndarray:
        """Indices of pipes that join two distinct domains (the only ones that carry flow)."""
        a, b = self.pipe_domains[:, 0], self.pipe_domains[:, 1]
        return np.flatnonzero((a != OUTSIDE) & (b != OUTSIDE) & (a != b))

    def euler_characteristic(self) -> int:
        """V - E + F with F = domains + 1 (outer face). Equals 2 for a connected planar contact graph."""
        return self.n_vertices - self.n_pipes + self.n_domains + 1

    def check_euler(self) -> None:
        """Raise if the network is not the face set of a connected planar graph (digest U1)."""
        chi = self.euler_characteristic()
        if chi != 2:
            raise ValueError(
                f"network fails the Euler check: V - E + F = {self.n_vertices} - {self.n_pipes} + "
                f"{self.n_domains + 1} = {chi}, expected 2 (contact graph not connected or not planar)"
            )

    def arrays(self) -> dict[str, np.ndarray]:
        """The ``network.npz`` contract (issue 2) plus drawing data."""
        out = {
            "domain_centroid": self.domain_centroid,
            "domain_volume": self.domain_volume,
            "pipe_domains": self.pipe_domains,
            "pipe_aperture": self.pipe_aperture,
            "pipe_length": self.pipe_length,
            "pipe_grains": self.pipe_grains,
            "inlet_domains": self.inlet_domains,
            "outlet_domains": self.outlet_domains,
            "extent": np.asarray(self.extent, float),
        }
        if self.triangles is not None:
            out.update(points=self.points, triangles=self.triangles, triangle_domain=self.triangle_domain,
                       triangle_neighbors=self.triangle_neighbors)
        return out
