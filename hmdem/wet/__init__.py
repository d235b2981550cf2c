"""Wet granular media, pendular state (seed 002 §3.2; digest §4): liquid bridges between spheres.

- :mod:`hmdem.wet.bridges`: the bridge force (Eq. 4) and rupture distance (Eq. 5).
- :mod:`hmdem.wet.liquid`: where the liquid is (bridges and grain films), and how it moves when
  bridges form and rupture (§4.4, §4.5), conserving its volume exactly.

numpy only; nothing here imports YADE. The funicular clusters, the Eq. 3 bridge tables and the
plane-shear run are still to come (docs/roadmap.md, Draft A).
"""
