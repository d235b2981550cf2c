"""hmdem: hydro-mechanical pore-network models for fluids in granular media, on top of YADE.

Layers (see README): ``hmdem.network`` (geometry, no YADE), ``hmdem.flow`` (solvers, no YADE),
``hmdem.dem`` (the only package that imports YADE), cases and CLIs (``hmdem.hele_shaw``).
"""

__version__ = "0.1.0"
