"""Boundary domain types: inflow (Neumann, rate) and outflow (Dirichlet, p = 0) domains."""

from __future__ import annotations

import numpy as np

from .contact_graph import boundary_domains
from .network import Network


class NoBoundaryDomains(ValueError):
    """A network with no domain along an edge that needs one: its grains do not make a cell."""


def linear_flow_boundaries(net: Network, band: float) -> tuple[np.ndarray, np.ndarray]:
    """Lenormand cell (seed 004 §4.1): edge domains within ``band`` of the left / right hull.

    The top and bottom sides are impervious. Returns (inlet_domains, outlet_domains).
    """
    edge = boundary_domains(net)
    x = net.domain_centroid[edge, 0]
    xs = net.points[:, 0]
    inlet = edge[x <= xs.min() + band]
    outlet = edge[x >= xs.max() - band]
    if len(inlet) == 0 or len(outlet) == 0:
        raise NoBoundaryDomains(f"its network has {len(inlet)} inflow and {len(outlet)} outflow domains "
                                f"({net.n_domains} domains in all): its discs must touch or nearly touch across the cell")
    return inlet, outlet


def central_injection_boundaries(net: Network) -> tuple[np.ndarray, np.ndarray]:
    """Radial injection (seed 004 App. D.2, §4.2): the domain holding the centre is the inlet,
    every domain touching the sample edge is an outlet."""
    centre = np.array([(net.extent[0] + net.extent[1]) / 2, (net.extent[2] + net.extent[3]) / 2])
    inlet = np.array([int(np.argmin(np.linalg.norm(net.domain_centroid - centre, axis=1)))])
    return inlet, boundary_domains(net)
