"""Driven flow to a steady state and its averages: flow rate, the two force estimators,
velocity fields in boxes, and the hydraulic aperture (seed 003 §3-4; digest §1.6, §3.1).

The body-force form of the cubic law is used throughout (digest §1.6): with f the x-momentum
injected per fluid node per step and rho the particles per node,
delta_H^3 = 12 nu rho Q_full / f, which is seed 003 Eq. 10 with Delta P / L = f / (sqrt(3)/2)
and mu = rho nu / (sqrt(3)/2) (decisions #42).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..interrupts import STOP, interrupted
from . import automaton
from .lattice import ROW, Fields, Lattice
from .rules import viscosity

BOX = 10  # lattice units: the side of the averaging boxes (seed 003 §3)
MACH_BOX = 4  # lattice units: boxes for the largest speed (10 x 10 boxes smooth a throat's peak)
SAMPLE_EVERY = 10  # steps between flow-rate samples
FIELD_EVERY = 50  # steps between samples of the node fields (pictures and the Mach check)
RECORD_EVERY = 1000  # steps per timeseries row
SPINUP_TIMES = 6  # spin-up in slowest-mode relaxation times delta^2 / (pi^2 nu)
AVERAGE_TIMES = 30  # averaging window in the same unit


def relaxation_time(aperture: float, nu: float = 0.31) -> float:
    """Slowest viscous mode of a channel of full aperture ``aperture``: delta^2 / (pi^2 nu)
    (digest §1.7)."""
    return aperture**2 / (math.pi**2 * nu)


@dataclass
class FlowResult:
    """Averages over the window after spin-up. Forces are x-momentum per fluid node per step;
    flow rates are through the simulated domain (a half channel's is half the full one)."""

    g: float
    spinup_steps: int
    averaging_steps: int
    density: float
    viscosity: float
    force_applied: float
    force_friction: float
    flow_rate: float
    flow_rate_error: float
    drift: float
    u_max: float
    row_velocity: np.ndarray = field(repr=False)
    fields: Fields | None = field(default=None, repr=False)
    interrupted: bool = False
    precision: float = 0.0  # the relative standard error of Q the window aimed at; 0: a fixed window
    precise: bool = True  # the window's own test (:func:`precise`) passed: it may end at its longest first

    @property
    def steady(self) -> bool:
        """The window's two halves agree: |drift| within 1 % or three standard errors of the
        difference (twice Q's standard error), whichever is larger."""
        return bool(abs(self.drift) <= max(0.01, 6.0 * self.relative_error))

    @property
    def relative_error(self) -> float:
        """Q's standard error over |Q|."""
        return self.flow_rate_error / abs(self.flow_rate) if self.flow_rate else math.nan

    @property
    def force_mismatch(self) -> float:
        """Applied / friction - 1 (seed 003 Table I: < 1 % in almost all cases)."""
        return self.force_applied / self.force_friction - 1.0 if self.force_friction else math.nan

    def summary(self) -> dict:
        return {"g": self.g, "spinup_steps": self.spinup_steps, "averaging_steps": self.averaging_steps,
                "density_per_node": self.density, "viscosity_eq6": self.viscosity,
                "force_applied_per_node": self.force_applied, "force_friction_per_node": self.force_friction,
                "force_mismatch": self.force_mismatch, "flow_rate": self.flow_rate,
                "flow_rate_error": self.flow_rate_error, "flow_rate_drift": self.drift, "steady": self.steady,
                "precision_target": self.precision, "precise": self.precise, "u_max": self.u_max,
                "mach_max": self.u_max / math.sqrt(3.0 / 7.0), "interrupted": self.interrupted}


def block_error(samples: np.ndarray, blocks: int = 10) -> float:
    """Standard error of the mean from ``blocks`` consecutive block means (the samples are
    correlated over about one relaxation time)."""
    n = len(samples) // blocks * blocks
    if n < blocks:
        return math.nan
    means = samples[:n].reshape(blocks, -1).mean(axis=1)
    return float(means.std(ddof=1) / math.sqrt(blocks))


def box_average(values: np.ndarray, weights: np.ndarray, box: int = BOX) -> np.ndarray:
    """Weighted mean over boxes of ``box`` nodes along x and the nearest number of rows to
    ``box`` lattice units along y; NaN where the weights vanish."""
    rows = max(1, round(box / ROW))
    ny, nx = values.shape
    ny2, nx2 = ny // rows * rows, nx // box * box
    v = (values * weights)[:ny2, :nx2].reshape(ny2 // rows, rows, nx2 // box, box).sum(axis=(1, 3))
    w = weights[:ny2, :nx2].reshape(ny2 // rows, rows, nx2 // box, box).sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(w > 0, v / w, np.nan)


def drive(lattice: Lattice, g: float, spinup: int, average: int, progress=None, timeseries=None,
          fields: bool = True, precision: float = 0.0, max_average: int = 0) -> FlowResult:
    """Spin up for ``spinup`` steps, then average over ``average`` steps at forcing fraction
    ``g``, and on in quarters of that while the flow rate's standard error is above
    ``precision`` (relative) and fewer than ``max_average`` steps were averaged.
    ``progress(steps)`` is called as steps complete; ``timeseries`` (a list) receives rows
    (step, Q, applied, friction) averaged over every :data:`RECORD_EVERY` steps. A
    KeyboardInterrupt during the averaging returns what was averaged so far, marked
    ``interrupted``."""
    chunk = SAMPLE_EVERY
    record = _Recorder(lattice, timeseries)
    done = 0
    try:
        while done < spinup:
            n = min(chunk * 10, spinup - done)
            gains, losses = lattice.run(n, g)
            done += n
            record.add(n, gains, losses, lattice.flow_rate())
            if progress:
                progress(n)
    except STOP as exc:
        if not interrupted(exc):
            raise
        record.flush()
        return _result(lattice, g, done, 0, [], np.zeros(lattice.ny), np.zeros(lattice.ny), 0, None, True)
    lattice.reset_window()
    counts = np.zeros(lattice.ny, dtype=np.int64)
    momentum = np.zeros(lattice.ny, dtype=np.int64)
    row_counts = np.zeros(lattice.ny)
    row_momentum = np.zeros(lattice.ny)
    node_fields = Fields.zeros((lattice.ny, lattice.nx)) if fields else None
    flow_rates, samples, averaged, stopped = [], 0, 0, False
    target = average
    try:
        while averaged < target or (averaged < max_average and not precise(flow_rates, precision)):
            if averaged >= target:
                target = min(max_average, target + max(chunk, average // 4))
            n = min(chunk, target - averaged)
            gains, losses = lattice.run(n, g)
            averaged += n
            automaton.row_sums(lattice.state, lattice.fluid, counts, momentum)
            row_counts += counts
            row_momentum += momentum
            samples += 1
            flow_rates.append(lattice.flow_rate((int(counts.sum()), int(momentum.sum()))))
            if node_fields is not None and averaged % FIELD_EVERY < n:
                node_fields.add(lattice)
            record.add(n, gains, losses, flow_rates[-1])
            if progress:
                progress(n)
    except STOP as exc:
        if not interrupted(exc):
            raise
        stopped = True
    record.flush()
    result = _result(lattice, g, spinup, averaged, flow_rates, row_counts, row_momentum, samples, node_fields,
                     stopped)
    result.precision, result.precise = precision, precise(flow_rates, precision)
    return result


class _Recorder:
    """Timeseries rows averaged over :data:`RECORD_EVERY` steps (a run of 10^6 steps stays ~1,000
    rows)."""

    def __init__(self, lattice: Lattice, rows):
        self.lattice, self.rows = lattice, rows
        self.steps = self.samples = 0
        self.q = self.gain = self.loss = 0.0

    def add(self, steps: int, gains: np.ndarray, losses: np.ndarray, flow_rate: float) -> None:
        if self.rows is None:
            return
        self.steps += steps
        self.samples += 1
        self.q += flow_rate
        self.gain += float(gains.sum())
        self.loss += float(losses.sum())
        if self.steps >= RECORD_EVERY:
            self.flush()

    def flush(self) -> None:
        if self.rows is None or not self.steps:
            return
        per = 0.5 / (self.steps * self.lattice.n_fluid)
        self.rows.append((self.lattice.step_count, self.q / self.samples, self.gain * per, self.loss * per))
        self.steps = self.samples = 0
        self.q = self.gain = self.loss = 0.0


def precise(flow_rates: list, precision: float) -> bool:
    q = np.asarray(flow_rates)
    return precision <= 0 or bool(len(q) >= 20 and block_error(q) <= precision * abs(q.mean()))


def _result(lattice, g, spinup, averaged, flow_rates, row_counts, row_momentum, samples, node_fields,
            stopped) -> FlowResult:
    q = np.asarray(flow_rates, dtype=float)
    density = row_counts.sum() / max(samples, 1) / lattice.n_fluid if samples else math.nan
    applied, friction = lattice.force_per_node() if averaged else (math.nan, math.nan)
    half = len(q) // 2
    drift = (q[half:].mean() / q[:half].mean() - 1.0) if half >= 1 and q[:half].mean() != 0 else math.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        row_velocity = 0.5 * row_momentum / row_counts
    u_max = math.nan
    if node_fields is not None and node_fields.samples:
        rho, ux, uy = node_fields.mean()
        fluid = lattice.geometry.fluid
        weight = np.where(fluid, rho, 0.0)
        speed = np.hypot(box_average(np.nan_to_num(ux), weight, MACH_BOX),
                         box_average(np.nan_to_num(uy), weight, MACH_BOX))
        u_max = float(np.nanmax(speed)) if np.isfinite(speed).any() else math.nan
    return FlowResult(g=g, spinup_steps=spinup, averaging_steps=averaged,
                      density=density, viscosity=viscosity(density) if math.isfinite(density) else math.nan,
                      force_applied=applied, force_friction=friction,
                      flow_rate=float(q.mean()) if len(q) else math.nan,
                      flow_rate_error=block_error(q), drift=drift, u_max=u_max,
                      row_velocity=row_velocity, fields=node_fields, interrupted=stopped)


def hydraulic_aperture(result: FlowResult, mirrored: bool) -> float:
    """delta_H from the cubic law in body-force form, delta_H^3 = 12 nu rho Q_full / f (seed 003
    Eq. 10; digest §1.6); Q_full is twice the simulated flow rate under a mirror."""
    q_full = result.flow_rate * (2.0 if mirrored else 1.0)
    cube = 12.0 * result.viscosity * result.density * q_full / result.force_applied
    return cube ** (1.0 / 3.0) if cube > 0 else math.nan  # a mean flow against the drive (noise) has none


def reynolds_number(result: FlowResult, mirrored: bool) -> float:
    """Re = Q_full / nu = mean velocity x aperture / nu (seed 003 defines none; digest §3.3)."""
    return result.flow_rate * (2.0 if mirrored else 1.0) / result.viscosity


def forcing_for(mean_velocity: float, aperture: float, nu: float = 0.31, density: float = 1.0) -> float:
    """The forcing fraction g that drives a smooth channel of ``aperture`` at ``mean_velocity``:
    u_mean = f delta^2 / (12 nu rho) with f = 4 d (1 - d) g per node at rest (digest §1.5, §1.7)."""
    d = density / 7.0
    return mean_velocity * 12.0 * nu * density / aperture**2 / (4.0 * d * (1.0 - d))
