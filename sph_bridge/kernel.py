"""SPH kernel and the pairwise-force shape of PF-SPH (seed 000 §2.2, §2.7).

``h`` is the kernel's full support radius (W = 0 for r >= h, seed 000 Eq. 5), not a smoothing
length with support 2h. Resolution: h = 40^(1/3) dx (Eq. 33), particle mass m = rho0 dx^3 (Eq. 34).
"""

from __future__ import annotations

import math

from numba import njit

PARTICLES_PER_SUPPORT = 40  # N of seed 000 Eq. 33: h^3 = N dx^3
SUPPORT_OVER_SPACING = PARTICLES_PER_SUPPORT ** (1.0 / 3.0)  # h / dx = 3.41995
INTERACTION_RANGE = 2.0  # the pairwise force reaches 2h (h2 = 2 h1, seed 000 Eq. 27)


def support(dx: float) -> float:
    """h = 40^(1/3) dx (seed 000 Eq. 33)."""
    return SUPPORT_OVER_SPACING * dx


@njit(cache=True)
def wendland(r, h):
    """3-D Wendland C2 kernel W(r, h) = 21/(2 pi h^3) (1 - q)^4 (1 + 4 q), q = r/h < 1.

    Seed 000 Eq. 8 prints 168/(16 pi h^3) (1 - q)^3, which integrates to 0.70; its constant is
    that of Wendland C2, the kernel the text names (digest §2.2 and §8 item 1)."""
    q = r / h
    if q >= 1.0:
        return 0.0
    return 21.0 / (2.0 * math.pi * h**3) * (1.0 - q) ** 4 * (1.0 + 4.0 * q)


@njit(cache=True)
def wendland_gradient_over_r(r, h):
    """(1/r) dW/dr = -210/(pi h^5) (1 - q)^3: regular at r = 0, so grad_i W_ij = r_ij times this
    (with r_ij = r_i - r_j, the digest's orientation of e_ij, §8 item 2)."""
    q = r / h
    if q >= 1.0:
        return 0.0
    return -210.0 / (math.pi * h**5) * (1.0 - q) ** 3


@njit(cache=True)
def cubic_spline_shape(q):
    """Unnormalised cubic spline f(q) = 1 - 1.5 q^2 + 0.75 q^3 (q < 1), 0.25 (2 - q)^3 (q < 2)."""
    if q < 1.0:
        return 1.0 - 1.5 * q * q + 0.75 * q**3
    if q < 2.0:
        return 0.25 * (2.0 - q) ** 3
    return 0.0


@njit(cache=True)
def interaction_shape(r, h):
    """Dimensionless bracket of the pairwise force, 8 f(2r/h) - f(r/h) (seed 000 Eqs. 26-27).

    The digest's working reading (§2.7, §8 item 4): A = (h2/h1)^3 = 8, B = 1, h2 = 2 h, each
    spline unnormalised so that s carries the units of force (Table 1). Repulsive (> 0) below
    r = 0.675 h, most attractive at r = 0.862 h, zero from r = 2 h."""
    return 8.0 * cubic_spline_shape(2.0 * r / h) - cubic_spline_shape(r / h)


@njit(cache=True)
def lattice_sum(h, dx):
    """sum_j W(r_ij, h) dx^3 for a particle in a simple-cubic lattice of spacing dx (1.00195 at
    h = 40^(1/3) dx, digest §2.2): the bulk density from summation in units of m/dx^3."""
    reach = int(math.ceil(h / dx))
    total = 0.0
    for i in range(-reach, reach + 1):
        for j in range(-reach, reach + 1):
            for k in range(-reach, reach + 1):
                total += wendland(dx * math.sqrt(i * i + j * j + k * k), h)
    return total * dx**3
