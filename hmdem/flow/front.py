"""Flow-front bookkeeping after Holtzman & Segre (seed 004 §3.3, digest §7).

Domains: DFD (S = 0), FDD (0 < S < 1 or touching the invaded cluster), FUD (S = 1, "invaded").
A pipe between an invaded domain and a domain with S < 1 is a front pipe (FMP when open, FFP
when blocked by capillarity); a pipe between two invaded domains is an IFP; any other pipe is
ordinary and uses the mixture viscosity of Eq. 4.
"""

from __future__ import annotations

import numpy as np

FILL_TOLERANCE = 1e-6  # S within this of 1 counts as filled (digest §13.1 U10 tolerance)
THRESHOLD_ROUNDOFF = 1e-9  # a pipe that opens within this fraction of dt is at its threshold


def front_orientation(invaded: np.ndarray, pipe_a: np.ndarray, pipe_b: np.ndarray) -> np.ndarray:
    """+1 if end a is the invaded side of a front pipe, -1 if end b is, 0 otherwise."""
    ia, ib = invaded[pipe_a], invaded[pipe_b]
    return ia.astype(np.int8) - ib.astype(np.int8)


def front_fill_rates(orient: np.ndarray, pipe_flux: np.ndarray, pipe_a, pipe_b, n_domains: int) -> np.ndarray:
    """Invading-fluid inflow of every domain through open front pipes (digest §7.2)."""
    front = orient != 0
    downstream = np.where(orient > 0, pipe_b, pipe_a)[front]
    inflow = (orient * pipe_flux)[front]  # flux from the invaded side into the downstream side, >= 0
    return np.bincount(downstream, weights=np.maximum(inflow, 0.0), minlength=n_domains).astype(float)


def fill_times(volume, saturation, fill_rate) -> np.ndarray:
    """Time to fill each domain at the given rate, V (1 - S) / q (seed 004 Eq. 18); inf if q = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = volume * (1.0 - saturation) / fill_rate
    return np.where(fill_rate > 0, t, np.inf)


def blocked_front_step(dt: float, margin_start: np.ndarray, margin_end: np.ndarray, chi: float) -> float:
    """Step that just opens the first blocked front pipe (seed 004 Eq. 19, implicit form).

    With the front pipes shut at p^n held shut (decisions #5), p_u - p_d + p_c grows from
    ``margin_start`` (<= 0) to ``margin_end`` over ``dt``; Eq. 19 is the linear interpolation to
    zero for the first pipe to cross, expanded by chi (1.005 in the paper) so the threshold is
    just passed. Pipes already at their threshold to round-off (they would open within 1e-9 dt:
    a nearly incompressible invading fluid, e.g. Case 2, closes a 1e-4 Pa deficit in
    picoseconds, and such a step carries no information) set no limit, but the others still do.
    Returns dt unchanged when no other pipe would open within dt.
    """
    frac = crossing_fraction(margin_start, margin_end)
    frac = frac[np.isfinite(frac) & (frac >= THRESHOLD_ROUNDOFF)]
    return dt if frac.size == 0 else min(dt, chi * dt * float(frac.min()))


def crossing_fraction(margin_start: np.ndarray, margin_end: np.ndarray) -> np.ndarray:
    """The fraction of the step at which each shut pipe's p_u - p_d + p_c, taken linearly from
    ``margin_start`` (<= 0) to ``margin_end``, reaches 0 (Eq. 19's interpolation); inf for the
    pipes it does not open."""
    crossing = (margin_end > 0) & (margin_start <= 0)
    frac = np.full(np.shape(margin_start), np.inf)
    frac[crossing] = -margin_start[crossing] / (margin_end[crossing] - margin_start[crossing])
    return frac


def at_threshold_to_roundoff(margin_start: np.ndarray, margin_end: np.ndarray) -> np.ndarray:
    """Shut pipes that would open within THRESHOLD_ROUNDOFF of the step (linearly from
    ``margin_start`` to ``margin_end``): at their threshold, they set no step (Eq. 19 and its
    bisection, :meth:`hmdem.flow.simulation.FlowModel._bisect_first_opening`)."""
    return crossing_fraction(margin_start, margin_end) < THRESHOLD_ROUNDOFF
