"""Run output: ParaView particle states (meshio .vtu point clouds; hmdem.snapshots writes the .pvd
of a series) and config.toml's [run] table."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def run_table(prog: str, argv, case: str) -> dict:
    """config.toml's [run] table of an sph_bridge run: hmdem's (command, versions), plus the
    numba that compiled the kernels."""
    import numba

    from hmdem.cli import run_record

    return run_record(prog, argv, case=case, numba=numba.__version__)


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
