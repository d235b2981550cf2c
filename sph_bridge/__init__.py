"""sph_bridge: companion package for flow in fractures (PF-SPH, Richards coupling, FHP lattice gas).

PF-SPH (issue 5, seed 000): the kernel, cell lists, particle sums (density, pressure, viscous and
pairwise forces), wall treatment and the Verlet time loop; surface tension measured on a free
slab (``tension``), sessile drops and their Young-Laplace reference shapes (``droplet``,
``young_laplace``), the calibration of the pairwise strengths (``calibrate``, stored results in
``calibrations``). ``python -m sph_bridge {droplet,poiseuille,hydrostatic,calibrate}`` runs them
into run directories. ``sph_bridge.lga`` (issue 6, seed 003): the FHP-II lattice gas for the
permeability of self-affine rough fractures (``python -m sph_bridge lga ...``); ``surfaces``: the
self-affine profile generator.
"""
