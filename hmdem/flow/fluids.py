"""Two immiscible compressible fluids: mixture rules and capillary entry pressure (seed 004 §2.1).

Pressures are gauge pressures (outflow p = 0). Each fluid has a constant bulk modulus (linear
equation of state, digest §4); "inv" is the invading fluid, "def" the defending fluid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


# Largest p/K up to which a constant bulk modulus (linear equation of state, digest §4) is
# accurate: at p/K = 0.1 it differs from rho0 exp(p/K) by 0.5 % in density, and for a gas K
# itself (~ the absolute pressure) has grown by 10 %. Runs beyond it in some domain are
# flagged (e.g. Ca* = 100 at M = 1e-5: 1.3 GPa in oil with K = 2 GPa; the Huang cases' air).
WEAK_COMPRESSION = 0.1


@dataclass(frozen=True)
class FluidPair:
    """Invading and defending fluid properties (SI units).

    viscosity_* [Pa s], bulk_modulus_* [Pa], surface_tension [N/m], contact_angle_deg: contact
    angle of the *invading* fluid (180 for drainage, 0 for the wetting Huang cases).
    """

    viscosity_inv: float
    viscosity_def: float
    bulk_modulus_inv: float
    bulk_modulus_def: float
    surface_tension: float
    contact_angle_deg: float

    @property
    def viscosity_ratio(self) -> float:
        """M = eta_inv / eta_def (seed 004 §4.1)."""
        return self.viscosity_inv / self.viscosity_def

    @property
    def cos_theta(self) -> float:
        return float(np.cos(np.deg2rad(self.contact_angle_deg)))

    def mixture_bulk_modulus(self, saturation: np.ndarray) -> np.ndarray:
        """K_f,i = S K_inv + (1 - S) K_def (seed 004 Eq. 3, arithmetic by saturation)."""
        return saturation * self.bulk_modulus_inv + (1.0 - saturation) * self.bulk_modulus_def

    def pipe_viscosity(self, s_i: np.ndarray, s_j: np.ndarray) -> np.ndarray:
        """eta_ij = (S_i + S_j) eta_inv / 2 + (2 - S_i - S_j) eta_def / 2 (seed 004 Eq. 4)."""
        s = s_i + s_j
        return 0.5 * (s * self.viscosity_inv + (2.0 - s) * self.viscosity_def)

    def entry_pressure(self, aperture: np.ndarray) -> np.ndarray:
        """p_c^entry = 2 gamma cos(theta) / r_min with r_min = a / 2 (seed 004 Eq. 5).

        Sign convention of digest §3.4: negative for drainage (a threshold the pressure jump
        p_inv - p_def must exceed), positive for imbibition (capillarity assists).
        """
        return 4.0 * self.surface_tension * self.cos_theta / aperture


def conductance(aperture: np.ndarray, viscosity: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Plane Poiseuille conductance per metre of depth, G = a^3 / (12 eta l) (seed 004 Eq. 1)."""
    return aperture**3 / (12.0 * viscosity * length)


def explicit_critical_step(fluids: FluidPair, pipes_per_domain: int = 5) -> float:
    """Order-of-magnitude critical step of the explicit scheme, 24/N min(eta/K) (seed 004 Eq. 30)."""
    return 24.0 / pipes_per_domain * min(
        fluids.viscosity_inv / fluids.bulk_modulus_inv, fluids.viscosity_def / fluids.bulk_modulus_def
    )
