"""Sample-characterisation formulas of seed 004 §4 (Eqs. 20-23)."""

from __future__ import annotations

import math

# Eq. 22 anchors: square (loosest) and hexagonal (densest) disc / sphere packings
PHI2D_SQUARE, PHI2D_HEX = 0.2146, 0.0931
PHI3D_SQUARE, PHI3D_HEX = 0.4764, 0.2595


def porosity_2d_to_3d(phi_2d: float) -> float:
    """Linear map of seed 004 Eq. 22 from 2D (disc) to 3D-equivalent porosity."""
    return PHI3D_HEX + (phi_2d - PHI2D_HEX) / (PHI2D_SQUARE - PHI2D_HEX) * (PHI3D_SQUARE - PHI3D_HEX)


def porosity_3d_to_2d(phi_3d: float) -> float:
    """Inverse of :func:`porosity_2d_to_3d`."""
    return PHI2D_HEX + (phi_3d - PHI3D_HEX) / (PHI3D_SQUARE - PHI3D_HEX) * (PHI2D_SQUARE - PHI2D_HEX)


def kozeny_carman(mean_diameter: float, phi_3d: float) -> float:
    """k_KC = d^2 phi^3 / (180 (1 - phi)^2) (seed 004 Eq. 20)."""
    return mean_diameter**2 * phi_3d**3 / (180.0 * (1.0 - phi_3d) ** 2)


def darcy_permeability(viscosity: float, length: float, rate: float, height: float, pressure_drop: float,
                       depth: float = 1.0) -> float:
    """k = eta L Q / (W H dP) with W the out-of-plane depth (seed 004 Eq. 21 as corrected in digest §14.2)."""
    return viscosity * length * rate / (depth * height * pressure_drop)


def mohr_coulomb_friction_angle(sigma1: float, sigma3: float) -> float:
    """phi [deg] from sigma1 / sigma3 = (1 + sin phi) / (1 - sin phi) (seed 004 §4.2)."""
    ratio = sigma1 / sigma3
    return math.degrees(math.asin((ratio - 1.0) / (ratio + 1.0)))
