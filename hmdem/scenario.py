"""Turn a :class:`~hmdem.cases.Case` into a network with apertures, boundaries and a flow setup."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cases import CASES, Case, ca_star_from_rate, default_packing_path, rate_from_ca_star
from .flow.simulation import FlowSetup
from .network.packing import DiscPacking
from .network import (Network, build_contact_network, find_contacts, central_injection_boundaries, linear_flow_boundaries,
                      square_lattice_network, uniform_apertures)


CHEN_DISCS_PER_SIDE = 40  # App. D.2: 39 x 39 square domains
CHEN_SPACING = 0.5e-3  # channel length; disc radius = aperture = 0.25 mm


@dataclass
class Scenario:
    case: Case
    net: Network
    setup: FlowSetup
    sigma: float  # injection "area" per m of depth in Ca* (m)
    length: float  # sample length in Ca* (m)
    ca_star: float
    packing_radii: np.ndarray | None = None  # grain radii for drawing (disc packings only)


def load_packing(path=None) -> DiscPacking:
    return DiscPacking.load(path or default_packing_path())


def linear_network(pk: DiscPacking, contact_gap: float) -> Network:
    """Contact network of a Lenormand-type packing, pairs closer than ``contact_gap`` x the smaller
    radius counting as contacts, with the inflow domains along its left side and the outflow
    domains along its right (NoBoundaryDomains when it has none)."""
    near = find_contacts(pk.centres, pk.radii, tolerance=contact_gap)
    contacts = np.unique(np.concatenate([pk.contacts.reshape(-1, 2), near]), axis=0)
    net = build_contact_network(pk.centres, pk.radii, contacts)
    net.inlet_domains, net.outlet_domains = linear_flow_boundaries(net, band=2.5 * pk.radii.mean())
    return net


def build_network(case: Case, seed: int, packing_path=None) -> tuple[Network, float, float, np.ndarray]:
    """Network with apertures and boundary domains; returns (net, Sigma, L) for Ca* and the grain radii."""
    rng = np.random.default_rng(seed)
    if case.geometry == "lattice":
        net = square_lattice_network(CHEN_DISCS_PER_SIDE, CHEN_SPACING)
        net.inlet_domains, net.outlet_domains = central_injection_boundaries(net)
        sigma = 4 * CHEN_SPACING  # perimeter of the square inflow domain
        length = net.points[:, 0].max() - net.points[:, 0].min()
        radii = np.full(len(net.points), CHEN_SPACING / 2)
    else:
        pk = load_packing(packing_path)
        net = linear_network(pk, case.contact_gap)
        sigma, length = pk.box[1], pk.box[0]
        radii = pk.radii
    net.check_euler()
    net.pipe_aperture = uniform_apertures(net.n_pipes, case.mean_aperture, case.aperture_spread, rng)
    return net, sigma, length, radii


def build_scenario(case: Case, seed: int = 0, inlet: str = "manifold", scheme: str = "implicit",
                   packing_path=None) -> Scenario:
    net, sigma, length, radii = build_network(case, seed, packing_path)
    if case.rate is not None:
        rate = case.rate
        ca = ca_star_from_rate(rate, case.fluids, sigma, length, case.mean_aperture)
    else:
        ca = case.ca_star
        rate = rate_from_ca_star(ca, case.fluids, sigma, length, case.mean_aperture)
    dt = case.dt
    if case.dt_follows_rate:  # the named case's step, as the same fraction of the fill time
        named = CASES[case.name]
        dt = named.dt * rate_from_ca_star(named.ca_star, named.fluids, sigma, length, named.mean_aperture) / rate
    setup = FlowSetup(case.fluids, rate, dt, inlet=inlet, scheme=scheme, two_phase=case.two_phase, t_max=case.t_max)
    return Scenario(case, net, setup, sigma, length, ca, radii)
