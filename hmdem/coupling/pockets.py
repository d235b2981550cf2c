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
Newton step in y: the gain is learned from two evaluations on the closed branch (f) and kept
from step to step per domain and per octave of dt (grains pushed for 1e-9 s barely move, for
1e-5 s they settle: the gain depends on dt); evaluations with p_calc > p_trial and < p_trial
bracket the root in y, each bound taken again as the neighbours move, and a Newton step that
leaves the bracket, or follows an evaluation on the open branch, is replaced by bisection.
Where the map follows more than the neighbours' mean (B1's pocket, BENCHMARKS.md) this scalar
step fights IQN and is slower than IQN alone (--no-pocket-newton).
Leaving the pockets out of IQN made things worse (the neighbours' updates move them), so IQN
still sees them.
"""

from __future__ import annotations

import numpy as np

# gain of a pocket that has not learned its own (A1: -3 to -8). Steep on purpose: a Newton step
# that falls short stays on the closed branch, where the next evaluation teaches the gain, while
# one that overshoots lands where liquid enters and p_calc = c says nothing about the gain
DEFAULT_GAIN = -8.0
# steepest gain believed (A1: -8): a secant over a small dy with the neighbours' own changes in
# it can come out at any size; a gain of -100 already makes a Newton step 1 % of the residual
STEEPEST_GAIN = -100.0


def trapped_pockets(invaded: np.ndarray, saturation: np.ndarray, pipe_a: np.ndarray,
                    pipe_b: np.ndarray) -> np.ndarray:
    """Indices of the partly filled, not invaded domains that have neighbours, all invaded."""
    n = len(invaded)
    dry_neighbours = np.bincount(pipe_a, ~invaded[pipe_b], n) + np.bincount(pipe_b, ~invaded[pipe_a], n)
    neighbours = np.bincount(pipe_a, minlength=n) + np.bincount(pipe_b, minlength=n)
    return np.flatnonzero(~invaded & (saturation > 0) & (neighbours > 0) & (dry_neighbours == 0))


def dt_octave(dt: float) -> int:
    """The key a learned gain is kept under: gains learned at dt and 2 dt are kept apart."""
    return int(np.floor(np.log2(dt)))


class PocketNewton:
    """Safeguarded Newton steps on the trapped pockets; :meth:`new_step` at each flow step."""

    def __init__(self, n_domains: int, pipe_a: np.ndarray, pipe_b: np.ndarray):
        self.n_domains = n_domains
        self.pipe_a, self.pipe_b = pipe_a, pipe_b
        self.gains = {}  # dt octave -> learned d p_calc / d y per domain (nan: none), kept across steps
        self.pockets = np.zeros(0, int)

    def new_step(self, pockets: np.ndarray, dt: float) -> None:
        """Start a flow step of length dt with these pockets (:func:`trapped_pockets`)."""
        self.pockets = pockets
        self.gain = self.gains.setdefault(dt_octave(dt), np.full(self.n_domains, np.nan))
        k = len(pockets)
        # distinct neighbours of each pocket as (pocket slot, domain) pairs over the pipes touching it
        slot = np.full(self.n_domains, -1)
        slot[pockets] = np.arange(k)
        a_side, b_side = slot[self.pipe_a] >= 0, slot[self.pipe_b] >= 0
        pairs = np.unique(np.c_[np.r_[slot[self.pipe_a[a_side]], slot[self.pipe_b[b_side]]],
                                np.r_[self.pipe_b[a_side], self.pipe_a[b_side]]], axis=0)
        self._slot, self._neighbour = pairs[:, 0], pairs[:, 1]
        self._count = np.maximum(np.bincount(self._slot, minlength=k), 1)
        self._closed = (np.full(k, np.nan), np.full(k, np.nan))  # last (y, p_calc) on the closed branch
        # the bracket in y: the highest y with residual > 0 on the open branch (kept all step), the
        # highest on the closed branch and the lowest with residual < 0, with p_calc at those two
        self._open_low = np.full(k, np.nan)
        self._low, self._low_h = np.full(k, np.nan), np.full(k, np.nan)
        self._high, self._high_h = np.full(k, np.nan), np.full(k, np.nan)

    def neighbour_mean(self, pressure: np.ndarray) -> np.ndarray:
        return np.bincount(self._slot, pressure[self._neighbour], len(self.pockets)) / self._count

    def update(self, p_trial: np.ndarray, p_calc: np.ndarray, p_next: np.ndarray, closed: np.ndarray,
               tolerance: float) -> np.ndarray:
        """Next trial pressures of the pockets after the evaluation p_calc = H(p_trial); p_next is
        IQN's proposal for every domain (the neighbours' part is used), closed: the pockets with no
        open pipe at this evaluation (on the f branch); tolerance: the P-V iteration's, in Pa."""
        k = self.pockets
        x, h = p_trial[k], p_calc[k]
        y = x - self.neighbour_mean(p_trial)
        last_y, last_h = self._closed
        dy = y - last_y
        # a secant over a dy inside the tolerance measures the neighbours' moves as much as the gain
        pair = closed & (np.abs(dy) > tolerance)  # nan compares False: no earlier closed point
        gain = np.where(pair, (h - last_h) / np.where(pair, dy, 1.0), np.nan)
        learned = pair & (gain <= 0.0)  # a pocket's own pressure pushes its grains apart
        self.gain[k[learned]] = np.maximum(gain[learned], STEEPEST_GAIN)
        self._closed = (np.where(closed, y, last_y), np.where(closed, h, last_h))
        closed_y, closed_h = self._closed
        g = np.where(np.isnan(self.gain[k]), DEFAULT_GAIN, self.gain[k])
        # p_calc = closed_h + g (y' - closed_y) = p' with y' = p' - mean of the neighbours' next p
        next_mean = self.neighbour_mean(p_next)
        newton = (closed_h - g * (next_mean + closed_y)) / (1.0 - g) - next_mean
        proposal = np.where(np.isnan(closed_y), h - next_mean, newton)  # only open evaluations yet: substitute
        # bracket of the root in y. The residual at y, max(p_c - y, f(y) - y - m) for neighbours'
        # mean m, falls as m rises: a low bound from the open branch (p_c - y > 0) holds for any m;
        # the others are taken again at the neighbours' next mean, p_calc - y - m (an upper bound of
        # a high one's), and drop out when that turns their sign
        r = h - x
        self._open_low = np.where(~closed & (r > 0) & ~(self._open_low > y), y, self._open_low)
        new_low, new_high = closed & (r > 0) & ~(self._low > y), (r < 0) & ~(self._high < y)
        self._low, self._low_h = np.where(new_low, y, self._low), np.where(new_low, h, self._low_h)
        self._high, self._high_h = np.where(new_high, y, self._high), np.where(new_high, h, self._high_h)
        stale_low = ~(self._low_h - self._low - next_mean > 0)
        stale_high = ~(self._high_h - self._high - next_mean < 0)
        # crossed bounds: the map also follows pressures beyond the neighbours' mean (B1); only the
        # open-branch low is sure, the other two start again
        crossed = np.fmax(self._open_low, self._low) >= self._high
        self._low[stale_low | crossed], self._high[stale_high | crossed] = np.nan, np.nan
        low = np.fmax(self._open_low, self._low)
        bracketed = low < self._high
        inside = (proposal > low) & (proposal < self._high)
        # after an open evaluation a Newton step would start from the same closed point as the one
        # that just failed (the neighbours' moves can keep it inside the bracket): bisect instead
        bisect = bracketed & (~inside | ~closed)
        return next_mean + np.where(bisect, 0.5 * (low + self._high), proposal)
