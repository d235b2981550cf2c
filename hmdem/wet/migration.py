"""Liquid migration in plane shear: the initial Gaussian, the profile Q(z) and the diffusion
constant (seed 002 §6.2, Mani et al. 2013; digest §6.2, claims A17, A22, B7).

The liquid starts in bridges only, V_b(z) = A exp(-(z - z_wall/2)^2 / sigma_0^2) by the height z
of each bridge. Shear spreads it; the observable is Q(z), the mean bridge volume per grain in
horizontal slabs. A profile of the form exp(-z^2/sigma^2) that spreads by diffusion keeps its
shape with sigma^2 = sigma_0^2 + 4 D t (digest §6.2 [SUP]), t the shear strain. numpy and scipy
only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The chapter's fit D(A) = a / (1 + b A^(1/3)) (seed 002 §6.2): a in R^2, b in 1/R, A in R^3.
DIFFUSION_A_R2 = 0.633
DIFFUSION_B_PER_R = 2.936


def diffusion_law(amplitude_over_r3, a=DIFFUSION_A_R2, b=DIFFUSION_B_PER_R):
    """D / R^2 against the initial amplitude A / R^3 (seed 002 §6.2; claim A17)."""
    return a / (1.0 + b * np.cbrt(np.asarray(amplitude_over_r3, float)))


def water_content(liquid_volume, sample_volume, n_grains, radius):
    """W_c = V_liq / (V_sample - 4 pi N R^3 / 3): liquid over pore volume (seed 002 §4; claim A22)."""
    return liquid_volume / (sample_volume - 4.0 * np.pi * n_grains * radius**3 / 3.0)


def gaussian_bridges(bridge_z, z_middle, amplitude, sigma0):
    """The initial bridge volumes A exp(-(z - z_middle)^2 / sigma0^2) at heights ``bridge_z``."""
    return amplitude * np.exp(-((np.asarray(bridge_z, float) - z_middle) / sigma0) ** 2)


def liquid_profile(pairs, volume, grain_z, edges):
    """Q(z): the mean bridge volume per grain in the slabs between ``edges`` (k+1,), each bridge
    counted half on each of its grains at that grain's height (digest §6.2's observable; films
    are not bridges and not counted). Returns (Q (k,), grains per slab (k,))."""
    grain_z = np.asarray(grain_z, float)
    per_grain = np.bincount(np.asarray(pairs, np.int64).ravel(), weights=np.repeat(0.5 * np.asarray(volume), 2),
                            minlength=len(grain_z))
    slab = np.digitize(grain_z, edges) - 1
    inside = (slab >= 0) & (slab < len(edges) - 1)
    count = np.bincount(slab[inside], minlength=len(edges) - 1)
    total = np.bincount(slab[inside], weights=per_grain[inside], minlength=len(edges) - 1)
    return np.divide(total, count, out=np.zeros(len(count)), where=count > 0), count


@dataclass(frozen=True)
class GaussianFit:
    """Q(z) ~ amplitude exp(-(z - centre)^2 / sigma2), weighted by grains per slab;
    ``residual``: the weighted rms misfit over the amplitude."""

    amplitude: float
    centre: float
    sigma2: float
    residual: float


def fit_gaussian(z, q, count) -> GaussianFit:
    """Fit Q(z) (slab centres ``z``, values ``q``, grains per slab ``count``) with a Gaussian of
    free amplitude, centre and width; slabs without grains carry no weight. The start is the
    profile's own moments."""
    from scipy.optimize import curve_fit

    z, q, count = (np.asarray(a, float) for a in (z, q, count))
    used = count > 0
    z, q, weight = z[used], q[used], count[used]
    mass = np.sum(weight * q)
    centre = np.sum(weight * q * z) / mass
    sigma2 = 2.0 * np.sum(weight * q * (z - centre) ** 2) / mass  # exp(-x^2/s^2) has variance s^2/2

    def model(x, amplitude, mean, width2):
        return amplitude * np.exp(-((x - mean) ** 2) / width2)

    start = (q.max(), centre, sigma2)
    (amplitude, centre, sigma2), _ = curve_fit(model, z, q, p0=start, sigma=1.0 / np.sqrt(weight),
                                               bounds=([0.0, z.min(), 1e-12 * sigma2], np.inf))
    misfit = np.sqrt(np.sum(weight * (q - model(z, amplitude, centre, sigma2)) ** 2) / weight.sum())
    return GaussianFit(float(amplitude), float(centre), float(sigma2), float(misfit / amplitude))


def diffusion_fit(strain, sigma2):
    """(D, sigma_0^2) from sigma^2 = sigma_0^2 + 4 D gamma by least squares over the strains."""
    slope, intercept = np.polyfit(np.asarray(strain, float), np.asarray(sigma2, float), 1)
    return float(slope / 4.0), float(intercept)
