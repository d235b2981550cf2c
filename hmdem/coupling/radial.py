"""Huang et al. (2012) radial-injection cases with movable grains (seed 004 §4.2, digest §11.2).

Wetting water-glycerol (5 cP, group A; 176 cP, group B) injected at the centre of an
air-filled, servo-compacted 1.25 mm sample of 1,395 discs, r in [13, 21.6] um, boundary grains
fixed, outflow domains (p = 0) all round. Q follows from Ca* (Eq. 24) with a0 as the mean
aperture, L = the sample side and Sigma = 0.2 L: the paper's inlet perimeter, ~0.25 mm of its
1.25 mm sample, implied by its A1 pressure and breakthrough time (digest §10.3; decisions.md #21).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from importlib import resources

import numpy as np

from ..cases import CP, MPA, ca_star_from_rate, rate_from_ca_star
from ..flow.diagnostics import UNDETERMINED
from ..flow.fluids import FluidPair
from ..flow.simulation import FlowSetup
from ..network import build_contact_network, find_contacts
from ..network.boundaries import central_injection_boundaries
from ..network.contact_graph import BOUNDARY_HOLDS, NEAR_CONTACT_GAP, hull_grains
from ..network.network import Network, pipes_touching
from ..network.packing import GRAIN_DENSITY, GRAIN_FRICTION, DiscPacking
from .apertures import ApertureLaw
from .model import CouplingSetup

AIR_VISCOSITY = 0.018 * CP
# Sigma / L of Eq. 24: the paper's ~0.25 mm inlet perimeter on its 1.25 mm sample (digest §10.3)
PAPER_SIGMA_OVER_LENGTH = 0.2


def huang_fluids(viscosity_inv: float) -> FluidPair:
    """Water-glycerol into air, Table 3: K 2000 / 0.14 MPa, gamma 63 dyn/cm, theta 0 (imbibition)."""
    return FluidPair(viscosity_inv, AIR_VISCOSITY, 2000 * MPA, 0.14 * MPA, 63.0e-3, 0.0)


@dataclass(frozen=True)
class RadialCase:
    name: str
    viscosity_inv: float  # Pa s
    ca_star: float
    dt: float  # nominal flow step [s] (seed 004 Table 4)
    expected_regime: str  # the paper's label, for reference only
    geometry: str = "radial"
    mean_aperture: float = 7.53e-6  # a0: the Ca* aperture scale
    aperture_spread: float = 0.0  # apertures come from the contact forces (Eq. 13), not drawn
    contact_gap: float = NEAR_CONTACT_GAP  # as for the fixed-grain packings (decisions.md #17, #73)
    # CouplingSetup fields this case sets otherwise (decisions.md #52); the CLI flags override them
    coupling_defaults: tuple[tuple[str, object], ...] = ()

    @property
    def title(self) -> str:
        """The case's title with its own viscosity, saying which of the named case's M and Ca*
        the command changed (a new-user pass: an 18 cP run was titled "(5 cP)")."""
        title = f"Huang {self.name}: water-glycerol ({self.viscosity_inv / CP:.3g} cP) into air, movable grains"
        named = RADIAL_CASES.get(self.name)
        if named is None:
            return title
        changed = [what for what, ours, paper in (("M", self.viscosity_inv, named.viscosity_inv),
                                                  ("Ca*", self.ca_star, named.ca_star))
                   if not math.isclose(ours, paper, rel_tol=1e-9)]  # a rate given as the case's own is not a change
        return f"{title}, with {' and '.join(changed)} changed" if changed else title


RADIAL_CASES = {
    "A1": RadialCase("A1", 5 * CP, 1.6, 1.0e-5, "infiltration"),
    # A3's steps mostly converge within three evaluations of a few DEM cycles each, so building
    # the skeleton's Newton step costs more than it saves (BENCHMARKS.md, decisions #55)
    "A3": RadialCase("A3", 5 * CP, 32.3, 8.0e-7, "infiltration-dominated with fracturing",
                     coupling_defaults=(("pv_skeleton_newton", False),)),
    # B1's P-V iteration converges faster with a higher cap, without reused secant pairs, without
    # the pocket step (its map changes from step to step; BENCHMARKS.md, decisions #52) and with
    # the quasi-Newton fit kept to the 4 newest secant pairs (decisions #56)
    "B1": RadialCase("B1", 176 * CP, 56.3, 1.0e-5, "infiltration-dominated with fracturing",
                     coupling_defaults=(("pv_max_iter", 24), ("pv_reuse_steps", 0), ("pv_pocket_newton", False),
                                        ("pv_max_columns", 4))),
    # with the skeleton's Newton step, B3's pocket step slows it down (decisions #55)
    "B3": RadialCase("B3", 176 * CP, 1138.1, 8.0e-7, "fracturing-dominated",
                     coupling_defaults=(("pv_pocket_newton", False),)),
}


def default_huang_packing_path():
    """The shipped servo-compacted Huang sample (regenerate with ``make huang-packing``)."""
    return resources.files("hmdem") / "data" / "huang_packing.npz"


def domain_perimeter(net: Network, domain: int) -> float:
    """Centre-polygon perimeter of a domain: the lengths of its contact edges."""
    edges = net.pipe_grains[(net.pipe_domains == domain).any(axis=1)]
    return float(np.linalg.norm(net.points[edges[:, 1]] - net.points[edges[:, 0]], axis=1).sum())


def radial_network(pk: DiscPacking, contact_gap: float = NEAR_CONTACT_GAP) -> Network:
    """Contact network of the sample with the central inflow domain and the outer ring of outflow
    domains. Pairs closer than ``contact_gap`` x the smaller radius count as contacts, as for the
    fixed-grain packings (decisions.md); those start detached, with the Eq. 14 aperture."""
    near = find_contacts(pk.centres, pk.radii, tolerance=contact_gap)
    contacts = np.unique(np.concatenate([pk.contacts.reshape(-1, 2), near]), axis=0)
    net = build_contact_network(pk.centres, pk.radii, contacts)
    net.check_euler()
    net.inlet_domains, net.outlet_domains = central_injection_boundaries(net)
    return net


@dataclass
class RadialScenario:
    case: RadialCase
    packing: DiscPacking
    net: Network
    setup: FlowSetup
    coupling: CouplingSetup
    sigma: float
    length: float
    ca_star: float
    fixed: np.ndarray  # grains held in place (the wall ring, the contact graph's hull; the port's with fixed_port)
    grain_density: float = GRAIN_DENSITY  # kg/m^3 of the 1 m-thick discs
    fixed_port: bool = False  # the inflow domain's grains are held too (a rigid injection tube)
    friction: float = GRAIN_FRICTION  # Coulomb coefficient of the grain contacts during the run
    stiffness_ratio: float = 1.0  # k_s / k_n; k_n is the packing's (the one it was compacted with)
    # how the boundary grains are held: "fixed" in place (the seed's), or "loaded": each moves
    # normal to its side under the constant force that held it once the sample settled
    boundary_hold: str = "fixed"
    # (n, 2) the inward normal of each boundary grain's side, along which it moves when loaded;
    # zero off the boundary and at the corners (boundary_normals)
    boundary_normals: np.ndarray | None = None

    @property
    def packing_radii(self) -> np.ndarray:
        return self.packing.radii


def build_radial_scenario(case: RadialCase, packing: DiscPacking | None = None, *, ca_star: float | None = None,
                          viscosity_ratio: float | None = None, one_way: bool = False, rate: float | None = None,
                          aperture_law: ApertureLaw | None = None, sigma: float | None = None,
                          grain_density: float = GRAIN_DENSITY, fixed_port: bool = False,
                          contact_gap: float | None = None, friction: float = GRAIN_FRICTION,
                          stiffness_ratio: float = 1.0, boundary_hold: str = "fixed") -> RadialScenario:
    """Network, flow set-up and coupling parameters of a radial case (no DEM yet, no YADE).
    ``sigma``: the Eq. 24 inlet perimeter Sigma [m] (default :data:`PAPER_SIGMA_OVER_LENGTH` x L).
    ``rate``: the injection rate Q [m^3/s per m] instead of Ca*, whose Eq. 24 value it then gives.
    ``grain_density``: of the discs [kg/m^3]; it sets how fast the port's grains yield (BENCHMARKS.md).
    ``fixed_port``: hold the grains around the inflow domain as well, a rigid injection tube
    whose pipes keep their apertures (decisions.md #68); the seed fixes the boundary grains only.
    ``contact_gap``: pairs closer than this fraction of the smaller radius are pipes (default the case's).
    ``friction``, ``stiffness_ratio``: the contacts' Coulomb coefficient and k_s / k_n (Table 2's
    0.6 and 1 by default); k_n is the packing's own, so its overlaps give back its confining stress.
    ``boundary_hold``: "fixed" (the seed's) or "loaded" (see :class:`RadialScenario`; decisions.md #86)."""
    if boundary_hold not in BOUNDARY_HOLDS:
        raise ValueError(f"boundary_hold must be one of {BOUNDARY_HOLDS}, not {boundary_hold!r}")
    pk = packing or DiscPacking.load(default_huang_packing_path())
    if contact_gap is not None:
        case = replace(case, contact_gap=contact_gap)
    net = radial_network(pk, case.contact_gap)
    eta_inv = case.viscosity_inv if viscosity_ratio is None else viscosity_ratio * AIR_VISCOSITY
    fluids = huang_fluids(eta_inv)
    law = aperture_law or ApertureLaw()
    length = float(pk.box[0])
    sigma = PAPER_SIGMA_OVER_LENGTH * length if sigma is None else sigma
    if rate is None:
        ca = case.ca_star if ca_star is None else ca_star
        rate = rate_from_ca_star(ca, fluids, sigma, length, case.mean_aperture)  # ā = a0 (decisions #21)
    else:
        ca = ca_star_from_rate(rate, fluids, sigma, length, case.mean_aperture)
    case = replace(case, viscosity_inv=eta_inv, ca_star=ca)  # the run's own, as its title says
    setup = FlowSetup(fluids, rate, case.dt)
    coupling = CouplingSetup(aperture_law=law, one_way=one_way, **dict(case.coupling_defaults))
    # "all boundary grains are fixed, imitating the sealed cell edges" (digest §11.2): the grains
    # that touched a compaction wall and every grain on the contact graph's hull. A hull grain
    # left free has fluid on one side only and nothing outside it: it is pushed out of the cell
    boundary = hull_grains(net)
    if len(pk.fixed):
        boundary |= pk.fixed
    fixed = boundary.copy()  # held while the sample settles, whatever boundary_hold says
    if fixed_port:
        fixed[port_grains(net)] = True
    normals = boundary_normals(pk.centres, pk.box, boundary, 2.0 * float(pk.radii.max()))
    return RadialScenario(case, pk, net, setup, coupling, sigma, length, ca, fixed, grain_density, fixed_port,
                          friction, stiffness_ratio, boundary_hold, normals)


def boundary_normals(centres: np.ndarray, box, boundary: np.ndarray, corner: float) -> np.ndarray:
    """Inward unit normals (n, 2) of the side nearest each ``boundary`` grain of a box sample
    [0, W] x [0, H]: (1, 0) at the left side, (-1, 0) at the right, (0, 1) at the bottom, (0, -1)
    at the top. Zero off the boundary and at the corners (within ``corner`` of both a vertical
    and a horizontal side), where a grain pushed along one side would slide out along the other."""
    x, y = np.asarray(centres, float).T
    gaps = np.c_[x, box[0] - x, y, box[1] - y]  # to the left, right, bottom and top sides
    inward = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    normals = inward[np.argmin(gaps, axis=1)]
    at_corner = np.maximum(gaps[:, :2].min(axis=1), gaps[:, 2:].min(axis=1)) < corner
    normals[~np.asarray(boundary, bool) | at_corner] = 0.0
    return normals


def port_pipes(net: Network) -> np.ndarray:
    """Mask of the inflow domains' pipes."""
    return pipes_touching(net.pipe_domains, net.inlet_domains)


def port_grains(net: Network) -> np.ndarray:
    """The grains around the inflow domains: the ends of their pipes."""
    return np.unique(net.pipe_grains[port_pipes(net)])


def classify_radial_regime(n_opened_contacts: int, fractal_dimension: float) -> str:
    """Huang et al.'s three regimes from the run: no opened contact is infiltration; opened
    contacts with a compact front (D_f >= 1.90, digest H1/H5; D_f the mass-radius dimension
    about the port, decisions.md #27) are infiltration-dominated with fracturing; opened
    contacts with a fingered front are fracturing-dominated; "undetermined" when contacts opened
    but the pattern is too small to measure (D_f nan: it reaches less than two grain sizes)."""
    if n_opened_contacts == 0:
        return "infiltration"
    if not math.isfinite(fractal_dimension):
        return UNDETERMINED
    if fractal_dimension >= 1.90:
        return "infiltration-dominated with fracturing"
    return "fracturing-dominated"
