"""Trapped pockets in the pressure-volume iteration: one scalar root per pocket (issue 3).

A trapped pocket is a partly filled domain that is not invaded while every neighbour is:
defending fluid enclosed by invading liquid. No flux leaves it, so its computed pressure
follows the area of the polygon of its grains, with the Eq. 3 mixture modulus (saturation
weighted, Voigt; the paper's rule, kept): a pocket 61 % air is still 779 MPa stiff. In Huang A1
at paper size (t > 0.0225 s) two such pockets held 97 % of the unconverged P-V evaluations
(BENCHMARKS.md). Their map p_trial -> p_calc is local and, in the reduced variable
y = p - (mean pressure of the pocket's neighbours), nearly linear with a gain of -3 to -8 (a
grain pushed apart by its own pocket, pushed back by the liquid around), which IQN's
least-squares model over all domains captures slowly. It also has a kink: once the pocket's
pressure drops below the neighbour's plus the entry pressure, liquid enters and holds it
there, p_calc = max(c, f(p_trial)).

So after each IQN update the pockets' trial pressures are replaced by a safeguarded scalar
Newton step: the gain is learned from two evaluations on the closed branch (f) and kept from
step to step per domain; evaluations with p_calc > p_trial and < p_trial bracket the root,
and a Newton step that leaves the bracket is replaced by bisection. Leaving the pockets out
of IQN made things worse (the neighbours' updates move them), so IQN still sees them.
"""

from __future__ import annotations

import numpy as np

# gain of a pocket that has not learned its own (A1: -3 to -8). Steep on purpose: a Newton step
# that falls short stays on the closed branch, where the next evaluation teaches the gain, while
# one that overshoots lands where liquid enters and p_calc = c says nothing about the gain
DEFAULT_GAIN = -8.0


def trapped_pockets(invaded: np.ndarray, saturation: np.ndarray, pipe_a: np.ndarray,
                    pipe_b: np.ndarray) -> np.ndarray:
    """Indices of the partly filled, not invaded domains whose every neighbour is invaded."""
    n = len(invaded)
    dry_neighbours = np.bincount(pipe_a, ~invaded[pipe_b], n) + np.bincount(pipe_b, ~invaded[pipe_a], n)
    return np.flatnonzero(~invaded & (saturation > 0) & (dry_neighbours == 0))


class PocketNewton:
    """Safeguarded Newton steps on the trapped pockets; :meth:`new_step` at each flow step."""

    def __init__(self, n_domains: int, pipe_a: np.ndarray, pipe_b: np.ndarray):
        self.pipe_a, self.pipe_b = pipe_a, pipe_b
        self.gain = np.full(n_domains, np.nan)  # learned d p_calc / d y per domain, kept across steps
        self.pockets = np.zeros(0, int)

    def new_step(self, pockets: np.ndarray) -> None:
        """Start a flow step with these pockets (:func:`trapped_pockets`)."""
        self.pockets = pockets
        k = len(pockets)
        # neighbours of each pocket as (pocket slot, domain) pairs over the pipes touching it
        slot = np.full(len(self.gain), -1)
        slot[pockets] = np.arange(k)
        a_side, b_side = slot[self.pipe_a] >= 0, slot[self.pipe_b] >= 0
        self._slot = np.r_[slot[self.pipe_a[a_side]], slot[self.pipe_b[b_side]]]
        self._neighbour = np.r_[self.pipe_b[a_side], self.pipe_a[b_side]]
        self._count = np.maximum(np.bincount(self._slot, minlength=k), 1)
        self._closed = (np.full(k, np.nan), np.full(k, np.nan))  # last (y, p_calc) on the closed branch
        self._low, self._high = np.full(k, np.nan), np.full(k, np.nan)  # p_trial with residual > 0 / < 0

    def neighbour_mean(self, pressure: np.ndarray) -> np.ndarray:
        return np.bincount(self._slot, pressure[self._neighbour], len(self.pockets)) / self._count

    def update(self, p_trial: np.ndarray, p_calc: np.ndarray, p_next: np.ndarray,
               closed: np.ndarray) -> np.ndarray:
        """Next trial pressures of the pockets after the evaluation p_calc = H(p_trial); p_next is
        IQN's proposal for every domain (the neighbours' part is used), closed: the pockets with no
        open pipe at this evaluation (on the f branch)."""
        k = self.pockets
        x, h = p_trial[k], p_calc[k]
        y = x - self.neighbour_mean(p_trial)
        last_y, last_h = self._closed
        dy = y - last_y
        pair = closed & (np.abs(dy) > 0.0)  # nan compares False: no earlier closed point
        gain = np.where(pair, (h - last_h) / np.where(pair, dy, 1.0), np.nan)
        learned = pair & (gain <= 0.0)  # a pocket's own pressure pushes its grains apart
        self.gain[k[learned]] = gain[learned]
        self._closed = (np.where(closed, y, last_y), np.where(closed, h, last_h))
        closed_y, closed_h = self._closed
        g = np.where(np.isnan(self.gain[k]), DEFAULT_GAIN, self.gain[k])
        # p_calc = closed_h + g (y' - closed_y) = p' with y' = p' - mean of the neighbours' next p
        newton = (closed_h - g * (self.neighbour_mean(p_next) + closed_y)) / (1.0 - g)
        proposal = np.where(np.isnan(closed_y), h, newton)  # only open evaluations yet: substitute
        r = h - x
        self._low = np.where((r > 0) & ~(self._low > x), x, self._low)
        self._high = np.where((r < 0) & ~(self._high < x), x, self._high)
        bracketed = ~np.isnan(self._low) & ~np.isnan(self._high)
        inside = (proposal > self._low) & (proposal < self._high)
        return np.where(bracketed & ~inside, 0.5 * (self._low + self._high), proposal)
