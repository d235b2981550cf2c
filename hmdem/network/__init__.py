"""Geometry: disc packings to pore networks (no YADE here)."""

from .apertures import uniform_apertures
from .boundaries import central_injection_boundaries, linear_flow_boundaries
from .contact_graph import boundary_domains, build_contact_network, find_contacts
from .lattice import square_lattice_network
from .network import OUTSIDE, Network

__all__ = [
    "Network", "OUTSIDE", "build_contact_network", "find_contacts", "boundary_domains",
    "square_lattice_network", "uniform_apertures", "linear_flow_boundaries", "central_injection_boundaries",
]
