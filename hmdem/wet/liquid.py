"""Where a pendular assembly's liquid is, and how it moves (seed 002 §3.2; digest §4.4–4.5).

The liquid sits in bridges (one per grain pair that has touched) and in one film per grain. It is
conserved at all times: a new bridge draws its volume from the two films (§4.4); a ruptured
bridge gives its volume back to the two films, and each grain passes its share on to its intact
bridges at once (§4.5). No bridge holds more than V_max; the excess stays in the film it came
from. Every step is vectorised over bridges and grains (no Python loop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bridges import effective_radius, rupture_distance

#: Rules for passing a grain's share of a ruptured bridge on to its intact bridges (digest §4.5):
#: ``equal`` shares (rule a, Mani et al. 2013); in proportion to P_f - P_i (``pressure``, rule b);
#: in inverse proportion to the chord L_i between the two bridges' contact points on that grain
#: (``distance``, rule c); or the chapter's own (P_f - P_i)/L_i (``mani``, Mani et al. 2012).
#: P_i is a bridge's Laplace pressure (negative when concave), P_f the film's.
REDISTRIBUTION_RULES = ("equal", "pressure", "distance", "mani")
PRESSURE_RULES = ("pressure", "mani")


@dataclass
class PendularLiquid:
    """Bridges on grain pairs and one film per grain [m^3].

    ``pairs`` (m, 2) grain ids of each bridge; ``volume`` (m,) bridge volumes; ``film`` (n_grains,)
    the liquid held on each grain outside its bridges.
    """

    pairs: np.ndarray
    volume: np.ndarray
    film: np.ndarray

    def __post_init__(self):
        self.pairs = np.asarray(self.pairs, dtype=np.int64).reshape(-1, 2)
        self.volume = np.asarray(self.volume, dtype=float).reshape(-1)
        self.film = np.asarray(self.film, dtype=float).reshape(-1)
        if len(self.volume) != len(self.pairs):
            raise ValueError(f"{len(self.pairs)} bridge pairs but {len(self.volume)} bridge volumes")

    @property
    def total(self) -> float:
        """All the liquid, in bridges and films [m^3]."""
        return float(self.volume.sum() + self.film.sum())

    def bridges_per_grain(self) -> np.ndarray:
        """How many bridges each grain carries."""
        return np.bincount(self.pairs.ravel(), minlength=len(self.film))


def bridge_radii(pairs, radii) -> np.ndarray:
    """Each bridge's effective radius 2 R1 R2 / (R1 + R2), from its grains' ``radii``."""
    pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
    return effective_radius(radii[pairs[:, 0]], radii[pairs[:, 1]])


def ruptured(liquid: PendularLiquid, gap, radius, contact_angle) -> np.ndarray:
    """Mask of the bridges whose gap exceeds Eq. 5's rupture distance (criterion d3);
    ``radius``: each bridge's effective radius (:func:`bridge_radii`)."""
    return np.asarray(gap, float) > rupture_distance(liquid.volume, radius, contact_angle)


def form_bridges(liquid: PendularLiquid, new_pairs, v_max, film_minimum=0.0) -> PendularLiquid:
    """Add bridges on ``new_pairs`` (k, 2), pairs that touch and have none yet (digest §4.4).

    Each grain gives (V_film - V_min)/n_new to each of its n_new new bridges (the rule of YADE's
    LiqControl, which the chapter leaves open; docs/decisions.md #99). A bridge takes at most
    ``v_max`` (scalar or (k,)); what it cannot take stays in the films in proportion to what each
    offered. A pair whose films are dry gets no bridge.
    """
    new_pairs = np.asarray(new_pairs, dtype=np.int64).reshape(-1, 2)
    n = len(liquid.film)
    if np.any(new_pairs[:, 0] == new_pairs[:, 1]):
        raise ValueError("a bridge joins two different grains")
    keys, new_keys = pair_keys(liquid.pairs, n), pair_keys(new_pairs, n)
    if np.isin(new_keys, keys).any() or len(np.unique(new_keys)) < len(new_keys):
        raise ValueError("new bridges must be on pairs that have no bridge yet, each once")
    ends = new_pairs.ravel()
    n_new = np.bincount(ends, minlength=n)
    available = np.maximum(liquid.film - film_minimum, 0.0)
    offered = (available[ends] / n_new[ends]).reshape(-1, 2)
    wanted = offered.sum(axis=1)
    taken = np.minimum(wanted, v_max)
    fraction = np.divide(taken, wanted, out=np.zeros_like(wanted), where=wanted > 0)
    took = offered * fraction[:, None]
    film = liquid.film - np.bincount(ends, weights=took.ravel(), minlength=n)
    wet = took.sum(axis=1) > 0  # no liquid, no bridge: the pair may get one when it touches again
    return PendularLiquid(np.r_[liquid.pairs, new_pairs[wet]], np.r_[liquid.volume, took.sum(axis=1)[wet]], film)


def pair_keys(pairs, n_grains):
    """One integer per unordered grain pair, for set operations on pairs."""
    return np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1) @ np.array([n_grains, 1])


def _ends(pairs, unit_branch):
    """Each bridge's two ends: grain id, and the unit vector from that grain towards its partner."""
    grain = pairs.ravel()
    direction = np.stack([unit_branch, -unit_branch], axis=1).reshape(len(grain), unit_branch.shape[-1])
    return grain, direction


def _same_grain_pairs(grain_a, grain_b):
    """All index pairs (a, b) with grain_a[a] == grain_b[b], without a Python loop."""
    order = np.argsort(grain_b, kind="stable")
    start = np.searchsorted(grain_b[order], grain_a, side="left")
    count = np.searchsorted(grain_b[order], grain_a, side="right") - start
    a = np.repeat(np.arange(len(grain_a)), count)
    offset = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return a, order[np.repeat(start, count) + offset]


def rupture_bridges(liquid: PendularLiquid, broken, radii, unit_branch, v_max, rule="equal",
                    bridge_pressure=None, film_pressure=None) -> PendularLiquid:
    """Remove the ``broken`` bridges (mask (m,)) and move their liquid (seed 002 §3.2; digest §4.5).

    A broken bridge's volume goes to its two grains in proportion to their radii (50/50 for the
    chapter's equal spheres; docs/decisions.md #100). Each grain passes its share on to its intact
    bridges at once, by ``rule`` (:data:`REDISTRIBUTION_RULES`); a grain with no intact bridge
    keeps it in its film. A bridge that would exceed ``v_max`` (scalar or (m,)) takes up to
    V_max and the rest stays in the film of the grain that gave it.
    ``unit_branch`` (m, d): unit vectors from each bridge's first grain to its second (the caller
    resolves periodic images); ``radii`` (n_grains,). The ``pressure`` and ``mani`` rules need
    ``bridge_pressure`` (m,) [Pa], each bridge's P_i, and ``film_pressure`` (n_grains,) [Pa],
    P_f = +gamma/R as the chapter prints it (digest §9 item 15); a bridge at or above its
    grain's film pressure, or with a NaN pressure, draws nothing, and a grain whose bridges all
    are keeps its share.
    """
    if rule not in REDISTRIBUTION_RULES:
        raise ValueError(f"rule must be one of {REDISTRIBUTION_RULES}, not {rule!r}")
    if rule in PRESSURE_RULES and (bridge_pressure is None or film_pressure is None):
        raise ValueError(f"rule {rule!r} needs the bridges' and the films' pressures")
    broken = np.asarray(broken)
    if broken.dtype != bool or broken.shape != liquid.volume.shape:
        raise ValueError(f"broken must be a boolean mask of the {len(liquid.volume)} bridges")
    unit_branch = np.asarray(unit_branch, float)
    unit_branch = unit_branch.reshape(len(liquid.pairs), unit_branch.shape[-1])
    v_max = np.broadcast_to(np.asarray(v_max, float), liquid.volume.shape)
    radii = np.asarray(radii, float)
    n = len(liquid.film)
    keep = ~broken

    pairs = liquid.pairs[broken]
    ratio = radii[pairs[:, 0]] / (radii[pairs[:, 0]] + radii[pairs[:, 1]])
    first = liquid.volume[broken] * ratio
    share = np.c_[first, liquid.volume[broken] - first].ravel()
    broken_grain, broken_direction = _ends(pairs, unit_branch[broken])
    intact_grain, intact_direction = _ends(liquid.pairs[keep], unit_branch[keep])

    a, b = _same_grain_pairs(broken_grain, intact_grain)
    weight = np.ones(len(a))
    if rule in ("distance", "mani"):  # the chord between the two contact points on the grain's surface
        chord = radii[broken_grain[a]] * np.linalg.norm(broken_direction[a] - intact_direction[b], axis=1)
        weight /= np.maximum(chord, 1e-12 * radii[broken_grain[a]])
    if rule in PRESSURE_RULES:  # P_f - P_i of the intact bridge, on the giving grain
        intact_pressure = np.repeat(np.asarray(bridge_pressure, float)[keep], 2)
        drive = np.asarray(film_pressure, float)[broken_grain[a]] - intact_pressure[b]
        weight *= np.where(np.isfinite(drive), np.maximum(drive, 0.0), 0.0)  # an unknown P_i draws nothing
    weight_sum = np.bincount(a, weights=weight, minlength=len(share))
    kept = weight_sum == 0  # no intact bridge on that grain, or none that draws
    fraction = np.divide(weight, weight_sum[a], out=np.zeros_like(weight), where=weight_sum[a] > 0)
    offered = np.bincount(b, weights=share[a] * fraction, minlength=len(intact_grain))
    offered = offered.astype(float).reshape(-1, 2)  # bincount of nothing is integer

    volume = liquid.volume[keep]
    room = np.maximum(v_max[keep] - volume, 0.0)
    wanted = offered.sum(axis=1)
    fraction = np.divide(np.minimum(wanted, room), wanted, out=np.ones_like(wanted), where=wanted > room)
    given = offered * fraction[:, None]
    excess = (offered - given).ravel()
    film = (liquid.film
            + np.bincount(broken_grain[kept], weights=share[kept], minlength=n)
            + np.bincount(intact_grain, weights=excess, minlength=n))
    return PendularLiquid(liquid.pairs[keep], volume + given.sum(axis=1), film)


def film_flow_rates(liquid: PendularLiquid, bridge_pressure, radii, surface_tension, conductance) -> np.ndarray:
    """dV/dt [m^3/s] of each bridge from film flow between bridges that share a grain (digest §4.6):
    seed 002 Eq. 8's form with bridges as the clusters (§5.6),

        dV_b/dt = (R / gamma) sum_b' omega (P_b' - P_b),

    over the bridges b' on a grain of b, R that grain's radius, P the bridges' Laplace pressures
    [Pa] (m,), omega = ``conductance`` [m^3/s] (the chapter's "dimensionless" omega carries volume
    per time, §9 item 10). Liquid goes from the higher (less negative) pressure to the lower one,
    and the rates sum to zero (A9, A10). The chapter gives no pendular flux law (§4.6); this is
    the digest's proposal (docs/decisions.md #104).
    """
    pressure = np.asarray(bridge_pressure, float)
    grain = liquid.pairs.ravel()
    bridge = np.repeat(np.arange(len(liquid.pairs)), 2)
    a, b = _same_grain_pairs(grain, grain)
    other = a != b
    a, b = a[other], b[other]
    scale = np.asarray(radii, float)[grain[a]] / surface_tension * conductance
    flow = scale * (pressure[bridge[b]] - pressure[bridge[a]])
    return np.bincount(bridge[a], weights=flow, minlength=len(liquid.pairs)).astype(float)
