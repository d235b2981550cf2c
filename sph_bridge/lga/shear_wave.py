"""Bulk viscosity of the automaton from a decaying shear wave (decisions #43).

A fully periodic lattice (no walls, no forcing) starts with the x-velocity u_x(y) = U sin(k y),
k = 2 pi / (rows sqrt(3)/2): each moving channel is occupied with probability d + e c_kx sin(k y),
d = density / 7. Momentum diffuses across rows, d j_x / dt = nu d^2 j_x / dy^2, so the mode's
amplitude decays as exp(-nu k^2 t) once the kinetic (non-hydrodynamic) modes have died out, a
few collision times. The fitted nu is the automaton's own, free of walls, slip and forcing, to
set against Eq. 6 (the Boltzmann value, ``rules.viscosity``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import automaton, reference
from .lattice import ROW, Geometry, Lattice, node_positions
from .rules import viscosity

CX = automaton.H_UNITS / 2.0  # c_kx of channels 0..6


@dataclass(frozen=True)
class ShearWave:
    """A fitted decay: the lattice, the mode's mean amplitude per step and nu against Eq. 6."""

    rows: int
    length: int
    density: float  # particles per node
    wavenumber: float
    amplitude: np.ndarray  # the sin(k y) mode of j_x per step, averaged over the seeds [half units per row]
    viscosity_fit: float
    viscosity_eq6: float
    fit_steps: tuple[int, int]  # the window of the log-linear fit
    viscosity_stderr: float  # standard error of viscosity_fit, jackknife over the seeds (nan for one seed)

    @property
    def excess(self) -> float:
        """nu_fit / nu_Eq.6 - 1."""
        return self.viscosity_fit / self.viscosity_eq6 - 1.0


def mode_amplitude(lattice: Lattice, sines: np.ndarray, all_nodes: np.ndarray) -> float:
    """Projection of the rows' x-momentum (half units) on sin(k y): 2/rows sum_j P_j sin(k y_j)."""
    counts = np.zeros(lattice.ny, dtype=np.int64)
    momentum = np.zeros(lattice.ny, dtype=np.int64)
    automaton.row_sums(lattice.state, all_nodes, counts, momentum)
    return 2.0 * float(momentum @ sines) / lattice.ny


def decay(rows: int, length: int, density: float, velocity: float, steps: int, seed: int) -> tuple[np.ndarray, float]:
    """The mode's amplitude at steps 0..steps of one lattice, and k."""
    shape = (rows, length)
    lattice = Lattice(Geometry(np.zeros(shape, bool), np.zeros(shape, bool), periodic_y=True), density, seed)
    k = 2.0 * math.pi / (rows * ROW)
    _, y = node_positions(rows, length)
    wave = np.sin(k * y)
    d = density / 7.0
    # occupation d + e c_kx sin(ky) carries j_x = 3 e sin(ky) per node (sum of c_kx^2 over the six)
    # and u_x = j_x / density; e is set from the requested peak velocity
    e = velocity * density / 3.0
    if not (velocity > 0.0 and 0.0 < d - e and d + e < 1.0):
        raise ValueError(f"velocity must be > 0 and keep the channel occupations inside (0, 1) at density "
                         f"{density}, got {velocity}")
    rng = np.random.default_rng(seed + 7919)
    occupied = np.stack([rng.random(shape) < d + e * CX[c] * wave for c in range(automaton.CHANNELS)])
    lattice.state = automaton.pack(occupied)
    all_nodes = automaton.pack(np.ones(shape, bool))
    sines = wave[:, 0]  # y is the row's: the odd rows' offset is along x
    amplitude = np.empty(steps + 1)
    amplitude[0] = mode_amplitude(lattice, sines, all_nodes)
    for t in range(1, steps + 1):
        lattice.run(1, 0.0)
        amplitude[t] = mode_amplitude(lattice, sines, all_nodes)
    return amplitude, k


def shear_wave_viscosity(rows: int = 64, length: int = 4096, density: float = 1.0, velocity: float = 0.05,
                         seeds: int = 4, start: int = 20, stop_fraction: float = 0.25,
                         implementation: str = "kernel") -> ShearWave:
    """nu from the decay of the amplitude averaged over ``seeds`` lattices (:func:`fit_decay`; the
    window ends at ``stop_fraction`` because later the thermal noise of the rows' momentum,
    ~sqrt(length), takes over), with its standard error over the lattices. ``implementation``
    "reference" runs the table-driven one-byte-per-node FHP-II of :mod:`.reference` instead of
    the bit-parallel kernel (decisions #58)."""
    decays = {"kernel": decay, "reference": reference.decay}
    if implementation not in decays:
        raise ValueError(f"implementation must be one of {sorted(decays)}, got {implementation!r}")
    if seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {seeds}")
    nu_guess = viscosity(density)
    k = 2.0 * math.pi / (rows * ROW)
    steps = start + int(math.ceil(math.log(1.0 / stop_fraction) / (nu_guess * k * k) * 1.5))
    runs = np.array([decays[implementation](rows, length, density, velocity, steps, seed)[0]
                     for seed in range(seeds)])
    amplitude = runs.mean(axis=0)
    nu, window = fit_decay(amplitude, k, start, stop_fraction)
    stderr = math.nan
    if seeds > 1:  # jackknife over the lattices: the fit repeated with each one left out
        left_out = np.array([fit_decay(np.delete(runs, i, axis=0).mean(axis=0), k, start, stop_fraction)[0]
                             for i in range(seeds)])
        stderr = math.sqrt((seeds - 1) / seeds * float(np.sum((left_out - left_out.mean()) ** 2)))
    return ShearWave(rows, length, density, k, amplitude, nu, nu_guess, window, stderr)


def fit_decay(amplitude: np.ndarray, k: float, start: int, stop_fraction: float) -> tuple[float, tuple[int, int]]:
    """nu = -slope / k^2 of a least-squares line through log A(t) from ``start`` until A first
    falls below ``stop_fraction`` of A(start), and that window."""
    below = np.flatnonzero(amplitude[start:] < stop_fraction * amplitude[start])
    stop = start + (int(below[0]) if len(below) else len(amplitude) - start)
    if amplitude[start] <= 0.0 or stop - start < 2:
        raise ValueError(f"no decay to fit: the mode's amplitude at step {start} is {amplitude[start]:.3g} "
                         "(raise velocity, length or seeds)")
    t = np.arange(start, stop)
    slope = np.polyfit(t, np.log(amplitude[start:stop]), 1)[0]
    return -slope / (k * k), (start, stop)
