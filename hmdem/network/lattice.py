"""Square-lattice network of touching discs (Chen & Wilkinson case, seed 004 App. D.2)."""

from __future__ import annotations

import numpy as np

from .contact_graph import build_contact_network
from .network import Network


def square_lattice_network(n_side: int = 40, spacing: float = 0.5e-3) -> Network:
    """n_side x n_side discs of radius spacing/2 in contact: (n_side-1)^2 square domains and
    2 n_side (n_side - 1) pipes of length ``spacing`` (1521 and 3120 for n_side = 40, digest U2)."""
    ix, iy = np.meshgrid(np.arange(n_side), np.arange(n_side))
    centres = np.c_[ix.ravel(), iy.ravel()] * spacing
    radii = np.full(n_side * n_side, spacing / 2)
    k = np.arange(n_side * n_side).reshape(n_side, n_side)
    contacts = np.concatenate([np.c_[k[:, :-1].ravel(), k[:, 1:].ravel()], np.c_[k[:-1, :].ravel(), k[1:, :].ravel()]])
    return build_contact_network(centres, radii, contacts)
