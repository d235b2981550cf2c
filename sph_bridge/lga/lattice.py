"""A lattice-gas run: geometry masks, the packed state, forcing and the running measurements.

Units are the lattice's: length 1 = the triangle side, row spacing sqrt(3)/2, time 1 = one
step, mass 1 = one particle. Node areas are sqrt(3)/2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import automaton

ROW = math.sqrt(3.0) / 2.0  # row spacing and area per node


@dataclass
class Geometry:
    """Where the walls are: ``solid`` (bounce-back) and ``mirror`` (specular) nodes, ``(ny, nx)``
    booleans; every other node is fluid. ``periodic_y`` wraps rows (needs an even row count);
    otherwise the first and last rows must hold no fluid."""

    solid: np.ndarray
    mirror: np.ndarray
    periodic_y: bool = False
    description: dict = field(default_factory=dict)

    def __post_init__(self):
        self.solid = np.asarray(self.solid, dtype=bool)
        self.mirror = np.asarray(self.mirror, dtype=bool) & ~self.solid
        ny = self.solid.shape[0]
        if self.periodic_y and ny % 2:
            raise ValueError(f"a y-periodic lattice needs an even number of rows, got {ny}")
        if not self.periodic_y and (self.fluid[0].any() or self.fluid[-1].any()):
            raise ValueError("the first and last rows must be walls or mirrors (y is not periodic)")

    @property
    def fluid(self) -> np.ndarray:
        return ~self.solid & ~self.mirror

    @property
    def shape(self) -> tuple[int, int]:
        return self.solid.shape

    def positions(self) -> tuple[np.ndarray, np.ndarray]:
        return node_positions(*self.shape)


def node_positions(ny: int, nx: int) -> tuple[np.ndarray, np.ndarray]:
    """Node coordinates x = i + (j mod 2)/2, y = j sqrt(3)/2, each ``(ny, nx)``."""
    j, i = np.mgrid[0:ny, 0:nx]
    return i + 0.5 * (j % 2), j * ROW


class Lattice:
    """The automaton on a geometry, started at rest with occupation ``density``/7 per channel
    at every fluid node (seed 003 §3: the seven states equally likely), reproducible from
    ``seed``."""

    def __init__(self, geometry: Geometry, density: float = 1.0, seed: int = 0):
        if not 0.0 < density < 7.0:
            raise ValueError(f"density must be in (0, 7) particles per node, got {density}")
        self.geometry = geometry
        self.ny, self.nx = geometry.shape
        self.seed = int(seed)
        self.step_count = 0
        fluid = geometry.fluid
        self.solid = automaton.pack(geometry.solid)
        self.mirror = automaton.pack(geometry.mirror)
        self.fluid = automaton.pack(fluid)
        self.fluid_nodes = np.flatnonzero(fluid).astype(np.int32 if fluid.size < 2**31 else np.int64)
        self.n_fluid = len(self.fluid_nodes)
        rng = np.random.default_rng(self.seed)
        occupied = (rng.random((automaton.CHANNELS,) + geometry.shape) < density / 7.0) & fluid
        self.state = automaton.pack(occupied)
        self.spare = np.empty_like(self.state)
        automaton.seed_forcing(self.seed)
        self.applied = 0  # x-momentum added by forcing since the last reset (half units)
        self.lost = 0  # x-momentum lost to bounce-back since the last reset (half units)
        self.window_steps = 0

    def run(self, steps: int, g: float) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``steps`` steps with forcing fraction ``g``; returns the per-step momentum
        gained by forcing and lost at walls (half units)."""
        gains = np.zeros(steps, dtype=np.int64)
        losses = np.zeros(steps, dtype=np.int64)
        kernel = automaton.advance_parallel if self.state[0].size >= automaton.PARALLEL_WORDS else automaton.advance_serial
        kernel(self.state, self.spare, self.solid, self.mirror, self.fluid, self.nx, self.geometry.periodic_y,
               self.seed, self.step_count, float(g), self.fluid_nodes, gains, losses)
        self.step_count += steps
        self.applied += int(gains.sum())
        self.lost += int(losses.sum())
        self.window_steps += steps
        return gains, losses

    def reset_window(self) -> None:
        self.applied = self.lost = self.window_steps = 0

    def totals(self, where: str = "all") -> tuple[int, int]:
        """(particles, x-momentum in half units) over all nodes or over the fluid nodes."""
        mask = self.fluid if where == "fluid" else self.solid | self.mirror | self.fluid
        counts = np.zeros(self.ny, dtype=np.int64)
        momentum = np.zeros(self.ny, dtype=np.int64)
        automaton.row_sums(self.state, mask, counts, momentum)
        return int(counts.sum()), int(momentum.sum())

    def flow_rate(self, fluid_totals: tuple[int, int] | None = None) -> float:
        """Instantaneous flux across a section, Q = (sqrt(3)/2) sum(j_x) / (rho_mean L) (digest §3.1:
        mass conservation makes Q the same at every x), from the fluid's (particles, x-momentum in
        half units) if already summed."""
        particles, momentum = fluid_totals or self.totals("fluid")
        if particles <= 0:
            return math.nan
        return ROW * 0.5 * momentum / (particles / self.n_fluid) / self.nx

    def force_per_node(self) -> tuple[float, float]:
        """(applied, friction): x-momentum per step per fluid node since the last reset."""
        n = max(self.window_steps, 1) * self.n_fluid
        return 0.5 * self.applied / n, 0.5 * self.lost / n


@dataclass
class Fields:
    """Time sums of node density and momentum, for averages over a window."""

    density: np.ndarray
    momentum_x: np.ndarray
    momentum_y: np.ndarray
    samples: int = 0

    @classmethod
    def zeros(cls, shape) -> "Fields":
        return cls(*(np.zeros(shape, dtype=np.int64) for _ in range(3)))

    def add(self, lattice: Lattice) -> None:
        automaton.accumulate_fields(lattice.state, lattice.nx, self.density, self.momentum_x, self.momentum_y)
        self.samples += 1

    def mean(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rho, u_x, u_y) per node, averaged over the samples (NaN where no particle came)."""
        n = max(self.samples, 1)
        rho = self.density / n
        with np.errstate(invalid="ignore", divide="ignore"):
            ux = 0.5 * self.momentum_x / n / rho
            uy = ROW * self.momentum_y / n / rho
        return rho, ux, uy

