"""Pendular liquid bridges between two spheres: force (seed 002 Eq. 4) and rupture (Eq. 5).

All functions take numpy arrays (or scalars) and broadcast. SI units; contact angles in radians.
The gap s is surface to surface, |x_j - x_i| - R_i - R_j. Unequal spheres use the effective
radius R = 2 R_i R_j / (R_i + R_j), as YADE's ``Law2_ScGeom_ViscElCapPhys_Basic`` does (digest §10).
"""

from __future__ import annotations

import numpy as np

#: Largest pendular bridge, V_max = 0.057 R^3 (seed 002 §3.2, after Scheel et al. 2008; digest §4.4)
V_MAX_OVER_R3 = 0.057

#: Linear coefficient of Eq. 4's denominator: 1 as the chapter prints it, 2.1 in Willett et al.
#: (2000) and YADE's ``Willett_analytic`` (digest §4.2, §9 item 2; docs/decisions.md #98)
LINEAR_COEFFICIENT = {"chapter": 1.0, "willett": 2.1}


def effective_radius(radius_i, radius_j):
    """R = 2 R_i R_j / (R_i + R_j), the radius of Eqs. 4 and 5 for unequal spheres [m]."""
    radius_i, radius_j = np.asarray(radius_i, float), np.asarray(radius_j, float)
    return 2.0 * radius_i * radius_j / (radius_i + radius_j)


def max_bridge_volume(radius):
    """V_max = 0.057 R^3 [m^3] (digest §4.4): the pendular cap; more stays in the films."""
    return V_MAX_OVER_R3 * np.asarray(radius, float) ** 3


def bridge_force(gap, volume, radius, surface_tension, contact_angle, law="chapter", switch_volume=0.0):
    """Attractive force [N] of a pendular bridge, seed 002 Eq. 4 (Willett et al. 2000):

        F = 4 pi R gamma cos(theta) / (2 + c s sqrt(R/V) + 5 s^2 R/V),

    with c = 1 (``law="chapter"``, as printed) or 2.1 (``law="willett"``). At contact (s <= 0,
    overlapping soft grains included) it is the constant 2 pi R gamma cos(theta) whatever V
    (digest A1). The force is zero below the roughness threshold V < ``switch_volume`` (the
    chapter's Heaviside switch V_c, §4.2, whose value it does not give) and for V = 0. It does not
    test rupture: see :func:`rupture_distance`. The chapter states Eq. 4 for V <= 0.03 R^3.
    """
    try:
        c = LINEAR_COEFFICIENT[law]
    except KeyError:
        raise ValueError(f"law must be one of {sorted(LINEAR_COEFFICIENT)}, not {law!r}") from None
    gap, volume, radius = np.broadcast_arrays(*(np.asarray(a, float) for a in (gap, volume, radius)))
    s = np.maximum(gap, 0.0)
    wet = (volume > 0.0) & (volume >= switch_volume)
    ratio = np.divide(radius, volume, out=np.zeros_like(radius), where=wet)  # R/V
    denominator = 2.0 + c * s * np.sqrt(ratio) + 5.0 * s * s * ratio
    force = 4.0 * np.pi * radius * surface_tension * np.cos(contact_angle) / denominator
    return np.where(wet, force, 0.0)[()]


def rupture_distance(volume, radius, contact_angle):
    """Gap s_c [m] at which a bridge of volume V ruptures, seed 002 Eq. 5 read normalised
    (digest §4.3, §9 item 3): s_c = R (1 + theta/2) (V*^(1/3) + 0.1 V*^(2/3)), V* = V/R^3, theta in
    radians. This is YADE's ``ViscElCapPhys.sCrit``."""
    volume, radius = np.asarray(volume, float), np.asarray(radius, float)
    v = volume / radius**3
    return radius * (1.0 + 0.5 * contact_angle) * (np.cbrt(v) + 0.1 * np.cbrt(v) ** 2)
