"""Two-way coupled flow step with moving grains: the pressure-volume iteration (seed 004 §3.2,
Fig. 3a; digest §6, §9).

Each flow step first runs the fixed-grain front logic (Eqs. 18-19 choose dt, the active set
resolves Eq. 6) with the grain geometry of t^n: that gives p_trial. Then, at that dt:

1. the pressure forces of p_trial (Eq. 8) are applied to the grains and the DEM is advanced by
   dt (continuing, not rewound: quasi-static relaxation under the updated pressure, digest §6);
2. dV_i = V_i(grains now) - V_i^n enters the pressure equation as -dV/dt and it is re-solved,
   giving p_calc;
3. until |p_calc - p_trial| is below the tolerance in every domain, p_trial <- p_calc.
   (The paper tests the inflow domain only; in A1 that let a pore away from the inlet carry a
   10x pressure error into the grain forces and the run blew up at step 1,388. With the test
   on every domain A1 gets to step 2,151 and then diverges: still open, see BENCHMARKS.md.)

On acceptance the domain volumes and the pipe apertures (Eqs. 13-14, from the contact forces
and gaps) are updated for the next step; the network topology stays fixed and a contact that
detaches becomes a fracture pipe. ``one_way=True`` is the sequential model the paper compares
against (Zhang et al.): grains move under p, but dV never enters the pressure equation.

The DEM is reached only through the small protocol :class:`GrainModel`; this module does not
import YADE (``hmdem.dem.assembly.DiscAssembly`` implements the protocol).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..flow.grain_forces import grain_pressure_forces
from ..flow.simulation import FlowModel, FlowSetup, SimulationDiverged
from ..network.network import Network
from .apertures import ApertureLaw
from .geometry import DomainGeometry, contact_gaps


DIVERGED = 1e3  # a P-V mismatch this many times the step's pressure scale is divergence


class GrainModel(Protocol):
    """What the coupling needs from a DEM."""

    radii: np.ndarray
    timestep: float

    def positions(self) -> np.ndarray: ...
    def save_state(self) -> None: ...
    def restore_state(self) -> None: ...
    def set_external_forces(self, forces: np.ndarray) -> None: ...
    def run(self, cycles: int) -> None: ...
    def normal_forces(self, pairs: np.ndarray) -> np.ndarray: ...


@dataclass
class CouplingSetup:
    """Parameters of the pressure-volume iteration and of the DEM sub-stepping."""

    aperture_law: ApertureLaw = field(default_factory=ApertureLaw)
    pv_rtol: float = 1e-3  # max |p_calc - p_trial| / max |p| over all domains (digest §6: 1e-3)
    pv_atol: float = 1.0  # Pa, absolute floor of the same test
    pv_max_iter: int = 30
    dem_cycles_per_step: int | None = None  # fixed count (the paper: 2000); None: stable DEM step
    stable_dem_step: float = 0.0  # DEM stability step [s], used when dem_cycles_per_step is None
    one_way: bool = False
    # rewind the DEM to t^n before every P-V iteration after the first, and relax p_trial
    # with Aitken's factor: each iteration is then a function evaluation of one fixed point
    pv_rewind: bool = False


@dataclass
class CouplingRecord:
    pv_iterations: list = field(default_factory=list)
    dem_cycles: int = 0
    unconverged_steps: int = 0


class CoupledFlowModel(FlowModel):
    """:class:`FlowModel` whose grains move (YADE through :class:`GrainModel`)."""

    def __init__(self, net: Network, setup: FlowSetup, grains: GrainModel, coupling: CouplingSetup):
        super().__init__(net, setup)
        self.grains, self.coupling = grains, coupling
        self.geometry = DomainGeometry(net)
        self.coupling_record = CouplingRecord()
        self.contact_pairs = net.pipe_grains
        self.positions = grains.positions()  # grain centres now (read from the DEM after each run)
        self.reference_volume = self.geometry.volumes(self.positions)
        self.volume[:] = self.reference_volume
        self.initially_closed = grains.normal_forces(self.contact_pairs) > 0.0
        self.opened = np.zeros(net.n_pipes, bool)
        self._update_apertures()

    # ---- grains ----------------------------------------------------------------------------
    def dem_cycles(self, dt: float) -> int:
        """DEM cycles covering dt, at a DEM step dt/cycles that is never above the stable one."""
        fixed = self.coupling.dem_cycles_per_step
        stable = self.coupling.stable_dem_step
        needed = math.ceil(dt / stable) if stable > 0 else 1
        return max(fixed or 0, needed, 1)

    def move_grains(self, pressure: np.ndarray, dt: float) -> np.ndarray:
        """Apply the Eq. 8 forces of ``pressure`` and advance the DEM by dt; new positions."""
        grains = self.grains
        forces = grain_pressure_forces(self.net, grains.radii, pressure, positions=self.positions)
        grains.set_external_forces(forces)
        cycles = self.dem_cycles(dt)
        grains.timestep = dt / cycles
        grains.run(cycles)
        self.coupling_record.dem_cycles += cycles
        self.positions = grains.positions()
        return self.positions

    def _update_apertures(self) -> None:
        g = self.contact_pairs
        force = self.grains.normal_forces(g)
        gap = contact_gaps(self.positions, self.grains.radii, g)
        self.net.pipe_aperture[:] = self.coupling.aperture_law(force, gap)
        self.opened |= self.initially_closed & self.coupling.aperture_law.opened(force)

    # ---- flow step with the P-V iteration --------------------------------------------------
    def implicit_step(self, state, blocked_guess):
        self.volume_change[:] = 0.0
        sol, fill, dt, limiter = super().implicit_step(state, blocked_guess)
        start_positions = self.positions
        if self.coupling.pv_rewind:
            self.grains.save_state()
        positions = self.move_grains(sol.pressure, dt)
        if self.coupling.one_way:
            self.coupling_record.pv_iterations.append(0)
            return sol, fill, dt, limiter
        g, orient, pc = self.pipe_properties(state)
        c = self.coupling
        p_trial = sol.pressure
        omega, r_prev = 1.0, None
        for iteration in range(1, c.pv_max_iter + 1):
            self.volume_change[:] = self.geometry.volumes(positions) - self.reference_volume
            calc, fill = self._trial(state, dt, g, orient, pc, sol.blocked)
            mismatch = np.abs(calc.pressure - p_trial)
            scale = max(np.abs(state.pressure).max(), np.abs(p_trial).max(), c.pv_atol)
            if not np.isfinite(mismatch).all() or mismatch.max() > DIVERGED * scale:
                raise SimulationDiverged(f"pressure-volume iteration diverged at t = {state.t:.6g} s "
                                         f"(step {self.record.steps + 1}, iteration {iteration}): pressure "
                                         f"mismatch {mismatch.max():.3g} Pa")
            sol = calc
            if np.all(mismatch <= c.pv_rtol * np.abs(calc.pressure).max() + c.pv_atol):
                break
            if c.pv_rewind:
                r = calc.pressure - p_trial
                if r_prev is None:
                    omega = 0.5
                else:  # Aitken's dynamic relaxation (Kuettler & Wall 2008)
                    dr = r - r_prev
                    omega = float(np.clip(-omega * (r_prev @ dr) / max(dr @ dr, 1e-300), 1e-4, 1.0))
                p_trial, r_prev = p_trial + omega * r, r
                self.grains.restore_state()
                self.positions = start_positions
            else:
                p_trial = calc.pressure
            positions = self.move_grains(p_trial, dt)
        else:
            self.coupling_record.unconverged_steps += 1
        self.coupling_record.pv_iterations.append(iteration)
        return sol, fill, dt, limiter

    def _accept(self, state, sol, fill, dt, limiter):
        super()._accept(state, sol, fill, dt, limiter)
        volume = self.geometry.volumes(self.positions)
        # saturation is a volume fraction: the invading volume is kept as the domain deforms
        invading = state.saturation * self.volume
        state.saturation = np.where(state.invaded, 1.0, np.clip(invading / volume, 0.0, 1.0))
        self.volume[:] = volume
        self.reference_volume = volume
        self.volume_change[:] = 0.0
        self._update_apertures()
