"""Interface quasi-Newton acceleration of the pressure-volume fixed point (IQN-ILS).

With the DEM rewound to t^n before every iteration, one P-V iteration is a function evaluation
p_calc = H(p_trial): forces of p_trial, DEM over dt, volume changes, pressure solve. Plain
substitution p_trial <- p_calc diverges where a loosely held grain is more compliant than the
fluid pocket next to it is drained within dt (the iteration then swings from side to side; seen
in Huang A1 near the front). IQN-ILS (Degroote, Bathe & Vierendeels 2009, Comput. Struct. 87)
builds a least-squares model of the inverse Jacobian of the residual r = H(x) - x from the
secant pairs (differences of successive residuals and outputs), which captures those few
unstable modes. The pairs of the last ``reuse_steps`` flow steps taken with the same dt are
kept (IQN-ILS(q)): the Jacobian changes little from step to step, so most steps then start with
a quasi-Newton update instead of a relaxed substitution. When an update built on reused pairs
makes the residual larger than the step's best so far, those pairs describe a response the
grains no longer have (a contact made or lost since): they are dropped, and the step goes on
with its own pairs only. Seen in Huang A1 at paper size: at a failed step the map was strongly
contracting (1 kPa on the worst domain moved its computed pressure by 5 Pa), yet the first
update from reused pairs sent the residual from 52 to 7,553 times the tolerance.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class InterfaceQuasiNewton:
    """x_{k+1} from (x_k, H(x_k)) pairs; call :meth:`new_step` at the start of each flow step."""

    def __init__(self, first_relaxation: float = 0.5, filter_tolerance: float = 1e-3, reuse_steps: int = 5,
                 max_columns: int = 40):
        self.first_relaxation = first_relaxation
        self.filter_tolerance = filter_tolerance
        self.max_columns = max_columns
        self._archive: deque = deque(maxlen=reuse_steps)  # (dt, dr columns, dh columns) per step
        self._dt = None
        self._last = None  # (r, h) of the previous iterate of this step
        self._dr: list[np.ndarray] = []
        self._dh: list[np.ndarray] = []
        self._best = np.inf  # smallest residual norm of this step
        self._reused = False  # the last update used pairs of earlier steps

    @property
    def reused(self) -> bool:
        """The last update used secant pairs of earlier steps."""
        return self._reused

    def new_step(self, dt: float | None = None) -> None:
        """Archive this step's secant pairs and start a step at ``dt`` (pairs are reused only
        between steps of the same dt: the map's Jacobian depends on dt)."""
        if self._dr:
            self._archive.append((self._dt, self._dr, self._dh))
        self._dt, self._last, self._dr, self._dh = dt, None, [], []
        self._best, self._reused = np.inf, False

    def _columns(self):
        """Secant pairs, newest first (they survive the filter), and whether earlier steps' are among them.
        Where this step has more pairs than ``max_columns``, the newest ``max_columns - 1`` are
        fitted with the one of largest residual change among the older ones (decisions #81):
        without it, each time the pair that spans the attempt's large early residuals left the
        window, the fit was left to differences of nearly converged iterates, which the map's
        roughness dominates, and the next evaluation often jumped back up towards the first one's
        mismatch (at evaluations 7, 13, 19 with 4 pairs)."""
        dr, dh = self._dr[::-1], self._dh[::-1]
        window = self.max_columns - 1
        if window >= 1 and len(dr) > self.max_columns:
            lever = window + int(np.argmax([np.linalg.norm(d) for d in dr[window:]]))
            dr, dh = dr[:window] + [dr[lever]], dh[:window] + [dh[lever]]
        reused = False
        for dt, old_dr, old_dh in reversed(self._archive):
            if dt is not None and self._dt is not None and abs(dt - self._dt) <= 1e-9 * self._dt:
                dr, dh, reused = dr + old_dr[::-1], dh + old_dh[::-1], True
        # no more columns than unknowns: beyond that they cannot be independent
        keep = min(self.max_columns, len(dr[0])) if dr else 0
        return dr[:keep], dh[:keep], reused and len(self._dr) < keep

    def update(self, x: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Next input after evaluating H(x) = h."""
        r = h - x
        norm = float(np.linalg.norm(r))
        if self._reused and norm > self._best:
            self._archive.clear()  # stale: see the module docstring
        self._best = min(self._best, norm)
        if self._last is not None:
            self._dr.append(r - self._last[0])
            self._dh.append(h - self._last[1])
        self._last = (r, h)
        dr, dh, self._reused = self._columns()
        if not dr:
            return x + self.first_relaxation * r
        v, w = np.column_stack(dr), np.column_stack(dh)
        # drop the first column (oldest last) whose part not explained by the earlier ones is
        # below filter_tolerance of its length, until none is: keeps the least squares well posed
        keep = np.flatnonzero(np.linalg.norm(v, axis=0) > 0.0)
        while len(keep):
            q, tri = np.linalg.qr(v[:, keep])
            weak = np.abs(np.diag(tri)) <= self.filter_tolerance * np.linalg.norm(v[:, keep], axis=0)
            if not weak.any():
                c = np.linalg.solve(tri, -(q.T @ r))
                return h + w[:, keep] @ c
            keep = np.delete(keep, np.argmax(weak))
        return x + self.first_relaxation * r
