"""One pendular liquid step for a set of spheres (seed 002 §3.2; digest §4.7).

Given the spheres' current centres, break the bridges stretched past Eq. 5 (moving their
liquid, §4.5), form bridges on touching pairs that have none (§4.4), and return each sphere's
net bridge force (Eq. 4, attractive along the line of centres). numpy only; the caller applies
the forces to its DEM (``hmdem.dem.spheres``). Pairs across a periodic boundary are taken at
their nearest image (``period``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .bridges import bridge_force, max_bridge_volume
from .liquid import PRESSURE_RULES, PendularLiquid, bridge_radii, form_bridges, pair_keys, rupture_bridges, ruptured
from .young_laplace import bridge_table


@dataclass(frozen=True)
class BridgeModel:
    """The pendular model's parameters (digest §4): surface tension [N/m], contact angle [rad],
    Eq. 4's ``force_law`` ("chapter" or "willett"), the switch volume V_c [m^3] and the
    redistribution ``rule`` (:data:`hmdem.wet.liquid.REDISTRIBUTION_RULES`)."""

    surface_tension: float
    contact_angle: float
    force_law: str = "chapter"
    switch_volume: float = 0.0
    rule: str = "equal"


def branches(centres, pairs, period=None):
    """Centre distances (m,) and unit vectors (m, d) from each pair's first sphere to its second.
    ``period`` (d,): the box lengths of periodic axes (inf where not periodic); a pair is taken
    at its nearest image."""
    branch = centres[pairs[:, 1]] - centres[pairs[:, 0]]
    if period is not None:
        period = np.asarray(period, float)
        periodic = np.isfinite(period)
        branch[:, periodic] -= period[periodic] * np.round(branch[:, periodic] / period[periodic])
    distance = np.linalg.norm(branch, axis=1)
    return distance, branch / distance[:, None]


def bridge_laplace_pressure(volume, gap, radius, model: BridgeModel):
    """Each bridge's Laplace pressure P = P_liquid - P_gas [Pa] (negative when concave, digest §1)
    from the Young–Laplace table at the model's contact angle (seed 002 Eq. 3), with R the
    pair's effective radius (the table is for equal spheres; docs/decisions.md #102). Volumes
    are held to the table's range, 5e-4 to 0.1 R^3; NaN past Eq. 5's rupture."""
    table = bridge_table(model.contact_angle)
    scaled = np.clip(volume / radius**3, table.volumes[0], table.volumes[-1])
    return -model.surface_tension / radius * table.suction(scaled, gap / radius)


def pendular_step(liquid: PendularLiquid, centres, radii, model: BridgeModel, touching=None, period=None):
    """Advance the liquid to the spheres' ``centres`` (n, d) and return (liquid, forces (n, d),
    number of ruptures). ``touching`` (k, 2): pairs in contact now (s <= 0); those without a
    bridge get one, if their films hold liquid. ``period``: as for :func:`branches`. Ruptures
    come first, so the liquid a rupture frees is in the films when new bridges draw on them."""
    radii = np.asarray(radii, float)
    centres = np.asarray(centres, float)
    distance, unit = branches(centres, liquid.pairs, period)
    gap = distance - radii[liquid.pairs[:, 0]] - radii[liquid.pairs[:, 1]]
    radius = bridge_radii(liquid.pairs, radii)
    broken = ruptured(liquid, gap, radius, model.contact_angle)
    if broken.any():
        pressures = {}
        if model.rule in PRESSURE_RULES:
            # the rules share by P_f - P_i, which scales with gamma: gamma cancels, and a model
            # without forces (gamma = 0, eta^coh = 0) shares as any gamma would, not nothing
            weighing = model if model.surface_tension > 0 else replace(model, surface_tension=1.0)
            pressures = dict(bridge_pressure=bridge_laplace_pressure(liquid.volume, gap, radius, weighing),
                             film_pressure=weighing.surface_tension / radii)  # P_f = +gamma/R (§9 item 15)
        liquid = rupture_bridges(liquid, broken, radii, unit, max_bridge_volume(radius), model.rule, **pressures)
        gap, unit, radius = gap[~broken], unit[~broken], radius[~broken]
    if touching is not None and len(touching):
        n = len(radii)
        touching = np.unique(np.sort(np.asarray(touching, np.int64).reshape(-1, 2), axis=1), axis=0)
        new = touching[~np.isin(pair_keys(touching, n), pair_keys(liquid.pairs, n))]
        if len(new):
            formed = len(liquid.pairs)
            new_radius = bridge_radii(new, radii)
            liquid = form_bridges(liquid, new, max_bridge_volume(new_radius))
            wet = np.isin(pair_keys(new, n), pair_keys(liquid.pairs[formed:], n))  # dry pairs get none
            new, new_radius = new[wet], new_radius[wet]
            new_distance, new_unit = branches(centres, new, period)
            gap = np.r_[gap, new_distance - radii[new[:, 0]] - radii[new[:, 1]]]
            unit = np.r_[unit, new_unit]
            radius = np.r_[radius, new_radius]
    magnitude = bridge_force(gap, liquid.volume, radius, model.surface_tension, model.contact_angle,
                             model.force_law, model.switch_volume)
    pull = magnitude[:, None] * unit  # on the first sphere, towards the second
    forces = np.zeros((len(radii), centres.shape[1]))
    np.add.at(forces, liquid.pairs[:, 0], pull)
    np.add.at(forces, liquid.pairs[:, 1], -pull)
    return liquid, forces, int(broken.sum())
