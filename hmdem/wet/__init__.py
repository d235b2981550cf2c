"""Wet granular media, pendular state (seed 002 §3.2; digest §4): liquid bridges between spheres.

- :mod:`hmdem.wet.bridges`: the bridge force (Eq. 4) and rupture distance (Eq. 5).
- :mod:`hmdem.wet.young_laplace`: the bridge's Young–Laplace profile (Eq. 3) and a table of its
  suction and force against volume and gap (§4.1).
- :mod:`hmdem.wet.liquid`: where the liquid is (bridges and grain films), and how it moves when
  bridges form and rupture (§4.4, §4.5), conserving its volume exactly.
- :mod:`hmdem.wet.pendular`: one pendular step for a set of spheres (§4.7).

numpy, scipy and numba only; YADE enters through :mod:`hmdem.dem.spheres`, which only the
``bridge`` command imports. Film flow, the funicular clusters and the plane-shear run are still
to come (docs/roadmap.md, Draft A).
"""
