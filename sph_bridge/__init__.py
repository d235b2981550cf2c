"""sph_bridge: companion package for flow in fractures (PF-SPH, Richards coupling, FHP lattice gas).

Planned in issues 5 and 6; nothing is implemented yet, and nothing here claims to be.
"""
