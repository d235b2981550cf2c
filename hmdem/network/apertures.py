"""Pipe apertures for fixed grains (seed 004 §4.1): a = a_mean * U[1 - spread, 1 + spread]."""

from __future__ import annotations

import numpy as np


def uniform_apertures(n_pipes: int, mean_aperture: float, spread: float, rng: np.random.Generator) -> np.ndarray:
    """Uniform random apertures; the paper's spread is 0.7, i.e. U[0.126, 0.714] mm for 0.42 mm."""
    return mean_aperture * rng.uniform(1.0 - spread, 1.0 + spread, n_pipes)
