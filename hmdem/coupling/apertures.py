"""Pipe apertures from contact forces and gaps (seed 004 Eqs. 13-14, digest §2.5).

    a = a0 F0 / (F + F0)          F > 0 (compressive normal contact force)
    a = a0 + lambda (d - r1 - r2) F <= 0 (detached contact: a fracture pipe)

Both branches give a0 at F = 0, d = r1 + r2; a(F0) = a0 / 2 (digest U6). Per metre of depth,
F in N per m. Huang values (Table 3): a0 = 7.53 um, F0 = 195.5 N, lambda = 1.12.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ApertureLaw:
    residual_aperture: float = 7.53e-6  # a0 [m]
    half_aperture_force: float = 195.5  # F0 [N per m]
    fracture_multiplier: float = 1.12  # lambda [-]

    def __call__(self, normal_force: np.ndarray, gap: np.ndarray) -> np.ndarray:
        """Aperture per pipe from its contact's normal force F and gap d - r1 - r2."""
        a0, f0, lam = self.residual_aperture, self.half_aperture_force, self.fracture_multiplier
        force = np.asarray(normal_force, float)
        closed = a0 * f0 / (np.maximum(force, 0.0) + f0)
        # a detached contact can sit at a gap of -1e-16 m after the force dropped to zero
        opened = a0 + lam * np.maximum(np.asarray(gap, float), 0.0)
        return np.where(force > 0.0, closed, opened)

    def opened(self, normal_force: np.ndarray) -> np.ndarray:
        """Pipes whose contact has detached (F <= 0): the paper's fracture initiation."""
        return np.asarray(normal_force) <= 0.0
