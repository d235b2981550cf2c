"""The fixed-grain cases of seed 004 (§4.1, App. D): fluids, injection and geometry.

Rates come from the modified capillary number (seed 004 Eq. 24, Holtzman et al. 2012):
    Ca* = Q eta_inv L / (Sigma gamma |cos theta| a_mean)
with Sigma the injection "area" per metre of depth (the cell height H for linear flow, the
inflow-domain perimeter for radial flow), L the sample length and a_mean the mean aperture.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from .flow.fluids import FluidPair
from .network.contact_graph import NEAR_CONTACT_GAP

CP = 1e-3  # centipoise in Pa s
MPA = 1e6
DYN_PER_CM = 1e-3  # N/m

AIR_OIL = FluidPair(0.018 * CP, 1000 * CP, 0.14 * MPA, 2000 * MPA, 20.0 * DYN_PER_CM, 180.0)  # Table 1, Case 1
GLUCOSE_OIL = FluidPair(570 * CP, 5.6 * CP, 2000 * MPA, 2000 * MPA, 14.5 * DYN_PER_CM, 180.0)  # Table 1, Case 2
OIL_GLYCERINE = FluidPair(1 * CP, 1200 * CP, 2000 * MPA, 2000 * MPA, 20.0 * DYN_PER_CM, 180.0)  # App. D.2
OIL_OIL = FluidPair(1000 * CP, 1000 * CP, 2000 * MPA, 2000 * MPA, 20.0 * DYN_PER_CM, 180.0)  # App. D.1


def rate_from_ca_star(ca_star: float, fluids: FluidPair, sigma: float, length: float, mean_aperture: float) -> float:
    """Q = Ca* Sigma gamma |cos theta| a_mean / (eta_inv L) (seed 004 Eq. 24 rearranged, digest §10.3)."""
    return ca_star * sigma * fluids.surface_tension * abs(fluids.cos_theta) * mean_aperture / (fluids.viscosity_inv * length)


def ca_star_from_rate(rate: float, fluids: FluidPair, sigma: float, length: float, mean_aperture: float) -> float:
    """Ca* = Q eta_inv L / (Sigma gamma |cos theta| a_mean) (seed 004 Eq. 24)."""
    return rate * fluids.viscosity_inv * length / (sigma * fluids.surface_tension * abs(fluids.cos_theta) * mean_aperture)


@dataclass(frozen=True)
class Case:
    """One named case of ``python -m hmdem.hele_shaw linear``."""

    name: str
    title: str
    fluids: FluidPair
    geometry: str  # "lenormand" (default packing, linear flow) or "lattice" (central injection)
    ca_star: float | None  # None: the rate is given directly
    dt: float  # nominal flow step [s]
    rate: float | None = None
    two_phase: bool = True
    t_max: float = np.inf
    mean_aperture: float = 0.42e-3
    aperture_spread: float = 0.7
    contact_gap: float = NEAR_CONTACT_GAP  # gaps below this fraction of the smaller radius are contacts (#2)
    expected_regime: str = ""  # the paper's label, for reference only (never used to label a run)
    dt_follows_rate: bool = False  # scale dt by the named case's rate over this one's (scenario.build_scenario)
    notes: str = ""
    extra: dict = field(default_factory=dict)


CASES = {
    "vf": Case("vf", "Case 1 viscous fingering: air into oil", AIR_OIL, "lenormand", 1.9e-4, 0.05,
               expected_regime="viscous fingering", notes="seed 004 Table 6 dt = 0.05 s"),
    "cf1": Case("cf1", "Case 1 capillary fingering: air into oil", AIR_OIL, "lenormand", 3.1e-7, 100.0,
                expected_regime="capillary fingering", notes="seed 004 Table 6 dt = 100 s"),
    "sd": Case("sd", "Case 2 stable displacement: glucose solution into oil", GLUCOSE_OIL, "lenormand", 38.6, 0.02,
               expected_regime="stable displacement", notes="dt not given by the paper; t_f / 400"),
    "cf2": Case("cf2", "Case 2 capillary fingering: glucose solution into oil", GLUCOSE_OIL, "lenormand", 2.4e-3, 200.0,
                expected_regime="capillary fingering", notes="dt not given by the paper; t_f / 360"),
    "chen": Case("chen", "Chen-Wilkinson: oil into glycerine on a 39 x 39 square lattice", OIL_GLYCERINE, "lattice",
                 0.03, 0.01, mean_aperture=0.25e-3, aperture_spread=0.0, expected_regime="viscous fingering"),
    "darcy": Case("darcy", "Single-phase Darcy test (App. D.1): oil into oil", OIL_OIL, "lenormand", None, 2e-5,
                  rate=3.1e-4, two_phase=False, t_max=0.02),
}


def default_packing_path():
    """The shipped 65 x 65 mm, r = 1 mm packing (regenerate with ``make packing``)."""
    return resources.files("hmdem") / "data" / "lenormand_packing.npz"

