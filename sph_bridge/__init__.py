"""sph_bridge: companion package for flow in fractures (PF-SPH, Richards coupling, FHP lattice gas).

Issue 5 (PF-SPH, seed 000) is in progress: the kernel, cell lists, particle sums (density,
pressure, viscous and pairwise forces), wall treatment and the Verlet time loop exist and are
tested (tests/test_sph_pfsph.py), including a closed hydrostatic column and body-force
Poiseuille flow between two walls; the free-surface column, the sessile droplet, the
calibration routine and the ``python -m sph_bridge`` command do not exist yet. Issue 6 (lattice
gas) is not started.
"""
