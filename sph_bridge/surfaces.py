"""Self-affine rough profiles: Voss's successive random additions in 1-D (random midpoint
displacement) and the structure-function estimate of the Hurst exponent.

Seed 003 §4.1 prints the generation variance as 1/r^(2nH) with r = 1/sqrt(2); that grows with n
and belongs to Voss's 2-D diagonal grid. Used literally in 1-D it gives an exponent near H/2.
We use the 1-D midpoint variance sigma_0^2 2^(-2kH) (1 - 2^(2H-2)) at generation k (digest §2.1,
decisions #41). Shared by the lattice-gas fractures (``sph_bridge.lga``) and any SPH rough-wall
case.
"""

from __future__ import annotations

import numpy as np


def midpoint_displacement(generations: int, hurst: float, rng: np.random.Generator) -> np.ndarray:
    """A profile of 2**generations + 1 heights with h(0) = h(end) = 0: each generation puts new
    points midway between the old ones, at their mean plus a Gaussian of standard deviation
    2^(-kH) sqrt(1 - 2^(2H-2)) (unit sigma_0)."""
    if not 0.0 < hurst < 1.0:
        raise ValueError(f"hurst must be in (0, 1), got {hurst}")
    h = np.zeros(2)
    for k in range(1, generations + 1):
        mid = 0.5 * (h[:-1] + h[1:])
        mid += 2.0 ** (-k * hurst) * np.sqrt(1.0 - 2.0 ** (2 * hurst - 2)) * rng.standard_normal(mid.size)
        out = np.empty(2 * h.size - 1)
        out[0::2], out[1::2] = h, mid
        h = out
    return h


def rough_profile(generations: int, hurst: float, largest_asperity: float, seed: int) -> np.ndarray:
    """A midpoint-displacement profile with zero mean, scaled so that its highest point stands
    ``largest_asperity`` above the mean plane (seed 003's y_max, measured from the mean plane:
    digest §2.2)."""
    h = midpoint_displacement(generations, hurst, np.random.default_rng(seed))
    h -= h.mean()
    return h * (largest_asperity / h.max())


def structure_function(profiles: np.ndarray, lags) -> np.ndarray:
    """Ensemble mean of |h(x + lag) - h(x)|^2 over all profiles and positions, per lag."""
    profiles = np.atleast_2d(profiles)
    return np.array([np.mean((profiles[:, lag:] - profiles[:, :-lag]) ** 2) for lag in lags])


def hurst_exponent(profiles: np.ndarray, lags=(1, 2, 4, 8, 16, 32, 64)) -> float:
    """Half the log-log slope of the structure function: S(lag) ~ lag^(2H) (digest claim C19)."""
    lags = np.asarray(lags)
    slope = np.polyfit(np.log(lags), np.log(structure_function(profiles, lags)), 1)[0]
    return 0.5 * slope
