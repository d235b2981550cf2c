"""PF-SPH time loop: modified velocity Verlet with bounce-back walls and an adaptive step
(seed 000 §2.10-2.12, digest's per-step algorithm).

One step, from positions r, velocities v and accelerations a at t:

1. v_half = v + dt/2 a and the extrapolated v_bar = v + dt a (Eq. 29a with the missing dt
   restored, digest §8 item 7; Eq. 29b); r += dt v_half (Eq. 29c), wrapped on periodic axes.
2. Bin; density by summation (Eq. 15) for every particle, walls with their own reference
   density (digest §2.9a, the consistent reading), and the proximity ratio, in one pass; fluid
   particles with proximity ratio < 0.5 bounce back and stop (Eq. 24); bin again and sum the
   densities again within h of them.
3. Pressure from the EOS (Eq. 13).
4. Wall velocities extrapolated from v_bar (Eq. 25); accelerations from v_bar (Eq. 11).
5. v = v_half + dt/2 a (Eq. 29d); the next dt from Eqs. 30-32.

Static cases relax with a velocity damping (decisions #33), annealed with thermal kicks
against it where asked (decisions #59); neither is part of seed 000's dynamics.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .cells import CellGrid
from .kernel import INTERACTION_RANGE, lattice_sum, support
from .pfsph import accelerations, density, density_from_pressure, pressure, refresh_density
from .walls import bounce_back, proximity, wall_state

GRAVITY = 9.81  # m/s^2 (not printed in seed 000; digest §2.8)
FULL_KERNEL = 0.98  # number density / bulk lattice value above which a particle has no surface within h


def stable_step(h: float, c0: float, acceleration: float, density_over_viscosity: float) -> float:
    """min of Eq. 30 (0.25 h / (3 c0)), Eq. 31 (0.25 sqrt(h / (3 |a|))) and the viscous limit
    rho h^2 / (32 mu), Morris et al.'s 0.125 h_s^2 / nu with the smoothing length h_s = h/2 of a
    kernel with support h. The printed Eq. 32, rho h^2 / (9 mu), is 3.6x longer and let a viscous
    Poiseuille run (nu = 2.6e-3 m^2/s, dx = 1 mm) blow up; in the paper's water runs neither binds
    (decisions #34)."""
    sound = 0.25 * h / (3.0 * c0)
    force = 0.25 * math.sqrt(h / (3.0 * acceleration)) if acceleration > 0 else math.inf
    return min(sound, force, density_over_viscosity * h * h / 32.0)


@dataclass
class SphParameters:
    """Resolution, fluid and wall properties (SI). ``s_ff``/``s_sf``: pairwise-force strengths
    [N] of fluid-fluid and solid-fluid pairs (seed 000 Eq. 27, Table 1 values are a starting guess)."""

    dx: float
    c0: float  # speed of sound [m/s] (Table 1: 1.5-18)
    rho0_fluid: float = 1000.0  # EOS reference density of the fluid (Table 1 uses 930-950)
    rho0_wall: float = 1000.0  # rho_s,0 (§3.1)
    viscosity: float = 1e-3  # mu of water, fluid and wall particles alike (§2.6)
    s_ff: float = 0.0
    s_sf: float = 0.0
    gravity: tuple = (0.0, 0.0, -GRAVITY)
    p0: float = 0.0  # EOS background pressure (not given in the paper)
    damping: float = 0.0  # [1/s] fluid velocities decay as exp(-damping t): relaxation of static cases only
    anneal: float = 0.0  # [m/s] starting thermal speed of an annealed relaxation (droplet.relax; decisions #59)
    seed: int = 0  # of the annealing's random kicks

    @property
    def h(self) -> float:
        return support(self.dx)


@dataclass
class StepRecord:
    rows: list = field(default_factory=list)
    steps: int = 0
    bounced: int = 0
    columns = ("t", "dt", "kinetic_energy_j", "max_density_deviation", "bounced", "momentum_x", "momentum_y",
               "momentum_z", "wall_s")


class Simulation:
    """Fluid and wall particles in the box [lo, hi] (``periodic`` per axis)."""

    def __init__(self, fluid_pos, wall_pos, params: SphParameters, lo, hi, periodic=(False, False, False)):
        fluid_pos = np.asarray(fluid_pos, float).reshape(-1, 3)
        wall_pos = np.asarray(wall_pos, float).reshape(-1, 3)
        self.params = p = params
        self.h = p.h
        self.pos = np.concatenate([fluid_pos, wall_pos])
        n_fluid, n = len(fluid_pos), len(self.pos)
        self.fluid = np.zeros(n, bool)
        self.fluid[:n_fluid] = True
        self.rho0 = np.where(self.fluid, p.rho0_fluid, p.rho0_wall)
        self.mass = self.rho0 * p.dx**3  # Eq. 34 with each particle's reference density
        self.mu = np.full(n, p.viscosity)
        self.gravity = np.asarray(p.gravity, float)
        self.vel = np.zeros((n, 3))
        # the pairwise force reaches 2h; without it the kernel support h is the whole range
        reach = int(math.ceil(INTERACTION_RANGE)) if (p.s_ff or p.s_sf) else 1
        self.grid = CellGrid(lo, hi, periodic, self.h, reach=reach)
        self.t = 0.0
        self.anneal_end = 0.0  # [s] the annealing's kicks fall linearly from params.anneal to 0 at this time
        self.rng = np.random.default_rng(p.seed)
        self.record = StepRecord()
        self.wall_start = time.perf_counter()
        self.number_density = np.zeros(n)
        self.bulk_number_density = lattice_sum(self.h, p.dx) / p.dx**3
        self._bin()
        self.acc = self._accelerations(self.vel)
        self.dt = self.stable_step()

    # ---- particle sums ---------------------------------------------------------------------
    def _bin(self):
        self.cell, self.order, self.start = self.grid.bin(self.pos)

    def _lists(self):
        return self.cell, self.order, self.start, self.grid.neighbours, self.grid.shifts

    def _accelerations(self, vel_seen, rho=None):
        """Accelerations seen with ``vel_seen``; ``rho``: the summation density at the current
        positions if already computed."""
        g, p, walls = self.grid, self.params, ~self.fluid
        self.rho = density(self.pos, self.mass, self.h, *self._lists(), g.inner) if rho is None else rho
        self.pressure = pressure(self.rho, self.rho0, p.c0, p.p0)
        # walls take the fluid's velocity mirrored (Eq. 25) and its pressure extrapolated with the
        # hydrostatic head (decisions #33), and the density that pressure implies
        vel_seen, self.pressure = wall_state(self.pos, vel_seen, self.pressure, self.rho, self.fluid, self.gravity,
                                             self.h, *self._lists(), g.inner)
        self.rho[walls] = density_from_pressure(self.pressure[walls], self.rho0[walls], p.c0, p.p0)
        return accelerations(self.pos, vel_seen, self.mass, self.rho, self.pressure, self.mu, self.fluid, p.s_ff,
                             p.s_sf, self.h, self.gravity, *self._lists(), g.forward)

    def stable_step(self) -> float:
        """:func:`stable_step` of the fluid particles' largest acceleration and smallest rho / mu."""
        a = np.sqrt((self.acc[self.fluid] ** 2).sum(axis=1)).max(initial=0.0)
        density_over_viscosity = float(np.min(self.rho[self.fluid] / self.mu[self.fluid], initial=math.inf))
        return stable_step(self.h, self.params.c0, a, density_over_viscosity)

    # ---- time step -------------------------------------------------------------------------
    def step(self) -> None:
        dt, f = self.dt, self.fluid
        v_half = self.vel.copy()
        v_bar = self.vel.copy()
        v_half[f] += 0.5 * dt * self.acc[f]
        v_bar[f] += dt * self.acc[f]
        self.pos[f] += dt * v_half[f]
        self._wrap()
        self._bin()
        rho, phi, normal, self.number_density = proximity(self.pos, self.mass, f, self.h, self.bulk_number_density,
                                                          *self._lists(), self.grid.inner)
        bounced = bounce_back(self.pos, (v_half, v_bar), phi, normal, f, self.params.dx)
        if len(bounced):
            was_in = self.cell[bounced]
            self._wrap(bounced)  # the others stay to the bit where the densities saw them
            self._bin()
            # only the densities within h of a bounced particle's old or new place change
            g = self.grid
            near = g.neighbours[np.concatenate([was_in, self.cell[bounced]]), :g.inner]
            dirty = np.zeros(g.n_cells, bool)
            dirty[near[near >= 0]] = True
            refresh_density(rho, dirty, self.pos, self.mass, self.h, *self._lists(), g.inner)
        self.acc = self._accelerations(v_bar, rho)
        self.vel = v_half
        self.vel[f] += 0.5 * dt * self.acc[f]
        if self.params.damping:
            self.vel[f] *= math.exp(-self.params.damping * dt)
            if self.t < self.anneal_end:
                self._thermal_kicks(dt, self.params.anneal * (1.0 - self.t / self.anneal_end))
        self.t += dt
        self.record.steps += 1
        self.record.bounced += len(bounced)
        self.dt = self.stable_step()

    def _thermal_kicks(self, dt: float, speed: float) -> None:
        """Langevin kicks with the damping as friction (an Ornstein-Uhlenbeck step): alone they drive
        each fluid velocity component to a Gaussian of rms ``speed``, the fluctuation the damping
        dissipates. Their mean is taken out, so they carry no momentum (fluid masses are equal).
        An annealed relaxation lets contact lines cross the barriers a damped one stops at
        (decisions #59)."""
        f = self.fluid
        kicks = self.rng.standard_normal((int(f.sum()), 3))
        kicks -= kicks.mean(axis=0)
        self.vel[f] += speed * math.sqrt(1.0 - math.exp(-2.0 * self.params.damping * dt)) * kicks

    def _wrap(self, which=slice(None)):
        """Put the particles ``which`` (default all) back into the box along periodic axes."""
        g = self.grid
        for a in np.flatnonzero(g.periodic):
            self.pos[which, a] = g.lo[a] + np.mod(self.pos[which, a] - g.lo[a], g.length[a])

    def run(self, t_end: float, record_every: float | None = None, progress=None) -> None:
        """Advance to ``t_end``; a row of :attr:`record` every ``record_every`` seconds."""
        next_row = self.t
        while self.t < t_end * (1 - 1e-12):
            self.dt = min(self.dt, t_end - self.t)
            self.step()
            if record_every is None or self.t >= next_row:
                self.record.rows.append(self.state_row())
                next_row = self.t + (record_every or 0.0)
            if progress is not None:
                progress(self)

    def state_row(self) -> tuple:
        f = self.fluid
        m, v = self.mass[f], self.vel[f]
        momentum = (m[:, None] * v).sum(axis=0)
        return (self.t, self.dt, 0.5 * float((m * (v**2).sum(axis=1)).sum()), self.max_density_deviation(),
                self.record.bounced, *momentum, round(time.perf_counter() - self.wall_start, 3))

    def max_density_deviation(self) -> float:
        """max |rho - rho0| / rho0 over fluid particles whose kernel is full (number density at
        least 0.98 of the bulk lattice value, so no free surface within h; walls complete it):
        the weak-compressibility check of digest §7 #5."""
        full = self.fluid & (self.number_density >= FULL_KERNEL * self.bulk_number_density)
        return float(np.max(np.abs(self.rho[full] / self.rho0[full] - 1.0), initial=0.0))
