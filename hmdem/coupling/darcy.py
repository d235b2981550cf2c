"""Network Darcy permeability of a packing (seed 004 §4.2, App. D.1; digest §10.1-10.2).

The pore network of the packing is the one the movable-grain runs use (:func:`radial_network`:
contacts plus near-contacts closer than 8 % of the smaller radius), with its boundaries
replaced by the linear-flow ones: the edge domains within 2.5 mean radii of the left and right
hull are held at p = dP and p = 0; top and bottom are impervious (hull pipes carry no flow).
Apertures follow the contact forces of the packing (Eq. 13, a = a0 F0 / (F + F0)); pipes whose
grains do not touch get the fracture aperture of Eq. 14, a0 + lambda (d - r1 - r2).

Single-phase steady flow: sum_j G_ij (p_j - p_i) = 0 in every interior domain with the
Poiseuille conductance G = a^3 / (12 eta l) (Eq. 1), one sparse SPD solve. The permeability is

    k = eta L Q / (H dP)   (Eq. 21 as corrected in digest §14.2, per metre of depth)

with Q the flow rate through the sample, L the distance between the mean centroids of the inflow
and the outflow domains (the length over which dP acts) and H the height of the domain region
(the extent of the grain centres). On a lattice of channels of aperture a and spacing s this
gives exactly a^3 / (12 s). k does not depend on eta or dP.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from ..calibration import kozeny_carman, porosity_2d_to_3d
from ..flow.fluids import conductance
from ..network.boundaries import linear_flow_boundaries
from ..network.contact_graph import NEAR_CONTACT_GAP
from ..network.network import Network
from ..network.packing import DiscPacking
from .apertures import ApertureLaw
from .geometry import contact_gaps
from .radial import radial_network

BAND_RADII = 2.5  # boundary band width in mean radii (as the Lenormand linear cases)
STRESSES = (0.1e6, 0.14e6, 0.5e6, 1.0e6, 1.5e6, 2.1e6)  # Darcy-test confining stresses [Pa]
PAPER_PERMEABILITY = 7.43e-13  # k_Darcy at 0.14 MPa (seed 004 §4.2)
PAPER_STRESS = 0.14e6


@dataclass
class DarcyFlow:
    """Steady single-phase flow through a network between its inlet and outlet domains."""

    permeability: float  # m^2
    rate: float  # Q [m^3/s per m of depth] at the given viscosity and pressure drop
    length: float  # L [m]
    height: float  # H [m]
    viscosity: float
    pressure_drop: float
    pressure: np.ndarray  # per domain (nan where not connected to a boundary)
    balance_error: float  # |Q_in - Q_out| / Q_in


def flow_length_and_height(net: Network) -> tuple[float, float]:
    """L: distance between the mean x of the inflow and outflow domain centroids; H: the y
    extent of the network's vertices (grain centres)."""
    x = net.domain_centroid[:, 0]
    length = float(x[net.outlet_domains].mean() - x[net.inlet_domains].mean())
    ys = net.points[np.unique(net.pipe_grains), 1] if net.points is not None else net.domain_centroid[:, 1]
    return length, float(ys.max() - ys.min())


def solve_darcy(net: Network, viscosity: float = 1.0e-3, pressure_drop: float = 1.0e5,
                length: float | None = None, height: float | None = None) -> DarcyFlow:
    """Steady flow with p = dP on ``net.inlet_domains`` and p = 0 on ``net.outlet_domains``.

    Domains not connected to any boundary through open pipes carry no flow and get nan.
    ``length`` / ``height`` default to :func:`flow_length_and_height`."""
    n = net.n_domains
    inlet = np.asarray(net.inlet_domains, int)
    outlet = np.asarray(net.outlet_domains, int)
    if len(inlet) == 0 or len(outlet) == 0:
        raise ValueError("the network needs inflow and outflow domains")
    if np.intersect1d(inlet, outlet).size:
        raise ValueError("a domain cannot be both inflow and outflow")
    pipes = net.flowing_pipes
    pipes = pipes[net.pipe_aperture[pipes] > 0.0]
    i, j = net.pipe_domains[pipes, 0], net.pipe_domains[pipes, 1]
    g = conductance(net.pipe_aperture[pipes], viscosity, net.pipe_length[pipes])

    fixed = np.full(n, np.nan)
    fixed[inlet] = pressure_drop
    fixed[outlet] = 0.0
    # domains in clusters without a boundary domain are left out (their system is singular)
    graph = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    has_boundary = np.zeros(label.max() + 1, bool)
    has_boundary[label[np.isfinite(fixed)]] = True
    unknown = np.flatnonzero(~np.isfinite(fixed) & has_boundary[label])
    index = np.full(n, -1)
    index[unknown] = np.arange(len(unknown))

    # Laplacian rows of the unknowns: sum_j g (p_i - p_j) = 0
    rows, cols, vals = [], [], []
    b = np.zeros(len(unknown))
    for a_, c_ in ((i, j), (j, i)):
        ia, ic = index[a_], index[c_]
        own = ia >= 0
        rows.append(ia[own])
        cols.append(ia[own])
        vals.append(g[own])
        both = own & (ic >= 0)
        rows.append(ia[both])
        cols.append(ic[both])
        vals.append(-g[both])
        to_fixed = own & (ic < 0) & np.isfinite(fixed[c_])
        np.add.at(b, ia[to_fixed], g[to_fixed] * fixed[c_][to_fixed])
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(len(unknown), len(unknown)))
    p = fixed.copy()
    if len(unknown):
        p[unknown] = spla.spsolve(A.tocsc(), b)

    # flux out of every domain through its pipes; Q_in leaves the inlets, Q_out enters the outlets
    q = g * (p[i] - p[j])  # from i to j
    q = np.nan_to_num(q)
    out_of = np.bincount(i, weights=q, minlength=n) - np.bincount(j, weights=q, minlength=n)
    q_in = float(out_of[inlet].sum())
    q_out = float(-out_of[outlet].sum())
    if q_in <= 0.0:
        raise ValueError("no flow path joins the inflow and outflow domains")
    if length is None or height is None:
        l0, h0 = flow_length_and_height(net)
        length = l0 if length is None else length
        height = h0 if height is None else height
    k = viscosity * length * q_in / (height * pressure_drop)
    return DarcyFlow(k, q_in, length, height, viscosity, pressure_drop, p, abs(q_in - q_out) / q_in)


def darcy_network(pk: DiscPacking, contact_gap: float = NEAR_CONTACT_GAP, band_radii: float = BAND_RADII) -> Network:
    """The packing's contact network (:func:`radial_network`) with left / right boundary bands."""
    net = radial_network(pk, contact_gap)
    net.inlet_domains, net.outlet_domains = linear_flow_boundaries(net, band=band_radii * float(pk.radii.mean()))
    return net


def set_contact_apertures(net: Network, pk: DiscPacking, forces: np.ndarray, law: ApertureLaw) -> None:
    """Eq. 13 where the pipe's grains press on each other, Eq. 14 (a0 + lambda gap) elsewhere."""
    gap = contact_gaps(pk.centres, pk.radii, net.pipe_grains)
    net.pipe_aperture[:] = law(forces, gap)


@dataclass
class PackingPermeability:
    """Darcy permeability of one packing with the Kozeny-Carman value for comparison."""

    confining_stress: float  # Pa (the packing's wall stress)
    permeability: float
    porosity_2d: float  # box-area porosity of the packing
    porosity_3d: float  # Eq. 22 map
    kozeny_carman: float
    mean_diameter: float
    n_domains: int
    n_pipes: int
    n_closed_pipes: int  # pipes whose grains touch (Eq. 13)
    mean_contact_force: float  # over the closed pipes [N per m]
    mean_aperture: float  # over the flowing pipes [m]
    length: float
    height: float
    balance_error: float
    extra: dict = field(default_factory=dict)

    def row(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k != "extra"}
        out.update(self.extra)
        return out


def packing_permeability(pk: DiscPacking, contact_forces, law: ApertureLaw | None = None,
                         contact_gap: float = NEAR_CONTACT_GAP) -> PackingPermeability:
    """Network Darcy permeability of a packing at its stored state. ``contact_forces(pairs)``
    gives the normal force of each grain pair (k, 2) [N per m], 0 where they are apart
    (:func:`hmdem.dem.runs.stored_permeability` reads them from YADE)."""
    law = law or ApertureLaw()
    net = darcy_network(pk, contact_gap)
    forces = np.asarray(contact_forces(net.pipe_grains), float)
    set_contact_apertures(net, pk, forces, law)
    flow = solve_darcy(net)
    phi2 = pk.porosity
    phi3 = porosity_2d_to_3d(phi2)
    d = 2.0 * float(pk.radii.mean())
    closed = forces > 0.0
    flowing = net.flowing_pipes
    return PackingPermeability(
        confining_stress=float(pk.confining_stress), permeability=flow.permeability, porosity_2d=phi2,
        porosity_3d=phi3, kozeny_carman=kozeny_carman(d, phi3), mean_diameter=d, n_domains=net.n_domains,
        n_pipes=net.n_pipes, n_closed_pipes=int(closed.sum()),
        mean_contact_force=float(forces[closed].mean()) if closed.any() else 0.0,
        mean_aperture=float(net.pipe_aperture[flowing].mean()), length=flow.length, height=flow.height,
        balance_error=flow.balance_error)
