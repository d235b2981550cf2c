"""Two-way hydro-mechanical coupling with moving grains (seed 004 §3.2, §4.2; issue 3).

Solver-side only: nothing here imports YADE. Grain positions, contact forces and gaps come
in as arrays (from :mod:`hmdem.dem` or any other DEM), pressure forces go out as arrays.
"""
