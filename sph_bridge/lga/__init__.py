"""sph_bridge.lga: FHP-II lattice-gas flow through self-affine rough fractures (seed 003)."""
