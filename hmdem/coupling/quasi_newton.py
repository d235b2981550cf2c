"""Interface quasi-Newton acceleration of the pressure-volume fixed point (IQN-ILS).

With the DEM rewound to t^n before every iteration, one P-V iteration is a function evaluation
p_calc = H(p_trial): forces of p_trial, DEM over dt, volume changes, pressure solve. Plain
substitution p_trial <- p_calc diverges where a loosely held grain is more compliant than the
fluid pocket next to it is drained within dt (the iteration then swings from side to side; seen
in Huang A1 near the front). IQN-ILS (Degroote, Bathe & Vierendeels 2009, Comput. Struct. 87)
builds a least-squares model of the inverse Jacobian of the residual r = H(x) - x from the
iterations so far, which captures those few unstable modes; the first update is a relaxed
substitution.
"""

from __future__ import annotations

import numpy as np


class InterfaceQuasiNewton:
    """x_{k+1} from (x_k, H(x_k)) pairs of one time step (call :meth:`reset` at each new step)."""

    def __init__(self, first_relaxation: float = 0.5, filter_tolerance: float = 1e-10, max_columns: int = 30):
        self.first_relaxation = first_relaxation
        self.filter_tolerance = filter_tolerance
        self.max_columns = max_columns
        self.reset()

    def reset(self) -> None:
        self._residuals: list[np.ndarray] = []
        self._outputs: list[np.ndarray] = []

    def update(self, x: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Next input after evaluating H(x) = h."""
        r = h - x
        self._residuals.append(r)
        self._outputs.append(h)
        if len(self._residuals) == 1:
            return x + self.first_relaxation * r
        # columns: differences to the latest iterate (span of the secant information)
        dr = np.column_stack([r - ri for ri in self._residuals[-self.max_columns - 1:-1]])
        dh = np.column_stack([h - hi for hi in self._outputs[-self.max_columns - 1:-1]])
        q, tri = np.linalg.qr(dr)
        # drop columns that add (next to) nothing: keeps the least-squares problem well posed
        keep = np.abs(np.diag(tri)) > self.filter_tolerance * max(np.abs(np.diag(tri)).max(), 1e-300)
        if not keep.all():
            dr, dh = dr[:, keep], dh[:, keep]
            if dr.shape[1] == 0:
                return x + self.first_relaxation * r
            q, tri = np.linalg.qr(dr)
        c = np.linalg.solve(tri, -(q.T @ r))
        return h + dh @ c
