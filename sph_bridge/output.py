"""ParaView output of particle states (meshio .vtu point clouds; hmdem.snapshots writes the .pvd of a series)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def particle_state(sim) -> tuple:
    """Copies of what a frame shows: positions, velocities, pressures, densities, fluid flags."""
    return sim.pos.copy(), sim.vel.copy(), sim.pressure.copy(), sim.rho.copy(), sim.fluid.copy()


def write_particles(path: Path, state: tuple) -> None:
    """One point cloud of a :func:`particle_state` with velocity, pressure, density and the fluid flag."""
    import meshio

    points, vel, pressure, rho, fluid = state
    cells = [("vertex", np.arange(len(points)).reshape(-1, 1))]
    meshio.write(path, meshio.Mesh(points, cells, point_data={
        "velocity": vel, "pressure": pressure, "density": rho, "fluid": fluid.astype(np.int8)}))
