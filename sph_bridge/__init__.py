"""sph_bridge: companion package for flow in fractures (PF-SPH, Richards coupling, FHP lattice gas).

Issue 5 (PF-SPH, seed 000) is in progress: the kernel, cell lists, particle sums (density,
pressure, viscous and pairwise forces), wall treatment and the Verlet time loop exist and are
tested (tests/test_sph_pfsph.py). ``python -m sph_bridge {hydrostatic,poiseuille}`` runs the two
validation cases between walls (a closed hydrostatic column and body-force Poiseuille flow) into
run directories. The free-surface column, the sessile droplet and the calibration routine (and
their commands) do not exist yet. Issue 6 (lattice gas) is not started.
"""
