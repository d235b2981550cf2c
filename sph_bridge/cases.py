"""Validation cases with analytical answers (issue 5): water between two 3-layer walls, periodic
sideways, at rest under gravity (hydrostatic) or driven along x by a body force (Poiseuille).

Each case builds a :class:`~sph_bridge.simulation.Simulation`, runs it to its end time and
measures itself against the analytical profile. Channel width ``layers`` dx between the walls'
nominal surfaces at z = 0 and z = H.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import lattice_block, wall_slab
from .simulation import GRAVITY, Simulation, SphParameters

SIDE_CELLS = 12  # periodic width in dx: at least 3 kernel supports (h = 3.42 dx) without the pairwise force


@dataclass
class CaseResult:
    summary: dict  # measured values, theory and errors (summary.json)
    profile: tuple  # (z, measured, z_theory, theory, label) for the figure


def channel(dx: float, layers: int, params: SphParameters) -> Simulation:
    """Fluid filling [0, L]^2 x [0, H] between walls at z = 0 and z = H, periodic in x and y."""
    length, height = SIDE_CELLS * dx, layers * dx
    fluid = lattice_block([0, 0, 0], [length, length, height], dx)
    walls = np.concatenate([wall_slab(2, 0.0, +1, [0, 0, 0], [length, length, 0], dx),
                            wall_slab(2, height, -1, [0, 0, height], [length, length, height], dx)])
    return Simulation(fluid, walls, params, [0, 0, -3 * dx], [length, length, height + 3 * dx], (True, True, False))


def hydrostatic_parameters(dx: float, layers: int, gravity: float) -> tuple[SphParameters, float]:
    """c0 with rho g H = 1 % of rho c0^2 (digest §7 #5 asks <= 3 %), and damping of about twice
    the fundamental acoustic mode pi c0 / (2H); relaxed for 3 of its periods (velocities decay as
    exp(-2 mode t), to e^-38). The column is closed: a background pressure P0 of its own head
    rho g H keeps it in compression up to the top wall, whose own pressure term only pushes (decisions #35).
    Returns the parameters and the end time."""
    height = layers * dx
    c0 = math.sqrt(gravity * height / 0.01)
    mode = math.pi * c0 / (2 * height)
    params = SphParameters(dx=dx, c0=c0, damping=2.0 * mode, gravity=(0.0, 0.0, -gravity),
                           p0=1000.0 * gravity * height)
    return params, 3 * 2 * math.pi / mode


def measure_hydrostatic(sim: Simulation, height: float, gravity: float) -> CaseResult:
    """dP/dz between the walls (a full kernel: more than h from each) against -rho g."""
    f = sim.fluid
    z, p, rho = sim.pos[f, 2], sim.pressure[f], sim.rho[f]
    inner = (z > sim.h) & (z < height - sim.h)
    slope, offset = np.polyfit(z[inner], p[inner], 1)
    expected = -rho[inner].mean() * gravity
    summary = {"pressure_gradient_pa_per_m": slope, "expected_gradient_pa_per_m": expected,
               "gradient_error": abs(slope / expected - 1.0), "max_density_deviation": sim.max_density_deviation(),
               "bounced_particles": sim.record.bounced}
    zt = np.linspace(0.0, height, 50)
    return CaseResult(summary, (z, p, zt, offset + expected * zt, "pressure [Pa]"))


def poiseuille_parameters(dx: float, layers: int, gravity: float, viscosity: float) -> tuple[SphParameters, float]:
    """Body force g along x; c0 = 10 u_max (Mach 0.1) but at least 1 m/s; end time five decay
    times of the slowest mode, H^2 / (pi^2 nu)."""
    height = layers * dx
    nu = viscosity / 1000.0
    u_max = gravity * height**2 / (8 * nu)
    params = SphParameters(dx=dx, c0=max(1.0, 10 * u_max), viscosity=viscosity, gravity=(gravity, 0.0, 0.0))
    return params, 5 * height**2 / (math.pi**2 * nu)


def measure_poiseuille(sim: Simulation, height: float, gravity: float) -> CaseResult:
    """u_x(z) against g z (H - z) / (2 nu); the error is max |u - u_theory| / u_max."""
    nu = sim.params.viscosity / sim.params.rho0_fluid
    f = sim.fluid
    z, u = sim.pos[f, 2], sim.vel[f, 0]

    def parabola(z):
        return gravity * z * (height - z) / (2 * nu)

    u_max = parabola(height / 2)
    theory = parabola(z)
    summary = {"max_velocity_m_per_s": float(u.max()), "theory_max_velocity_m_per_s": u_max,
               "max_profile_error": float(np.abs(u - theory).max() / u_max),
               "max_cross_velocity_m_per_s": float(np.abs(sim.vel[f, 1:]).max()),
               "max_density_deviation": sim.max_density_deviation()}
    zt = np.linspace(0.0, height, 50)
    return CaseResult(summary, (z, u, zt, parabola(zt), "u_x [m/s]"))


DEFAULT_GRAVITY = {"hydrostatic": GRAVITY, "poiseuille": 0.8}
