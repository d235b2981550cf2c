"""PF-SPH pair throughput (issue 5): particle-pair evaluations per second of the force sum and the
density sum on a periodic water lattice, and memory per particle.

    .venv/bin/python benchmarks/sph_pairs.py [--particles 100000] [--repeats 5]

Then whole Verlet steps of a periodic fluid box of the same particles (particle-steps per
second).

A pair evaluation is one (i, j) pair within the force range 2h visited by the force sum (each
unordered pair twice, gathered per particle), or within h by the density sum. Memory is the
resident-set growth from before the particles are made to after one step's sums, per particle.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)

    from numba import get_num_threads

    from sph_bridge.cells import CellGrid
    from sph_bridge.kernel import INTERACTION_RANGE, lattice_sum, support
    from sph_bridge.pfsph import accelerations, density, pressure

    # compile on a small system first, so the timings and memory see the work alone
    dx = 5e-4

    def system(n_side):
        axis = (np.arange(n_side) + 0.5) * dx
        pos = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
        pos += np.random.default_rng(0).normal(0, 0.05 * dx, pos.shape)
        grid = CellGrid([0, 0, 0], [n_side * dx] * 3, [True] * 3, support(dx), reach=2)
        return pos, grid

    def sums(pos, grid):
        n = len(pos)
        h = support(dx)
        mass = np.full(n, 1000 * dx**3)
        cell, order, start = grid.bin(pos)
        t0 = time.perf_counter()
        rho = density(pos, mass, h, cell, order, start, grid.neighbours, grid.shifts, grid.inner)
        t1 = time.perf_counter()
        p = pressure(rho, np.full(n, 1000.0), 1.5)
        acc = accelerations(pos, np.zeros((n, 3)), mass, rho, p, np.full(n, 1e-3), np.ones(n, bool), 3e-5, 8e-6, h,
                            np.zeros(3), cell, order, start, grid.neighbours, grid.shifts, grid.forward)
        t2 = time.perf_counter()
        return t1 - t0, t2 - t1, acc

    sums(*system(18))
    rss0 = peak_rss_bytes()
    n_side = round(args.particles ** (1 / 3))
    pos, grid = system(n_side)
    n = len(pos)
    t_density, t_force = [], []
    for _ in range(args.repeats):
        a, b, _ = sums(pos, grid)
        t_density.append(a)
        t_force.append(b)
    per_particle = (peak_rss_bytes() - rss0) / n
    # pairs per particle on the lattice (the jitter changes them by < 1 %)
    h = support(dx)
    k = np.arange(-8, 9)
    i, j, l = np.meshgrid(k, k, k, indexing="ij")
    r = dx * np.sqrt(i**2 + j**2 + l**2)
    force_pairs = np.count_nonzero((r > 0) & (r < INTERACTION_RANGE * h))
    density_pairs = np.count_nonzero(r < h)
    print(f"{n} particles ({n_side}^3 periodic lattice, dx = {dx} m, h = {h:.4g} m), {get_num_threads()} threads; "
          f"lattice sum {lattice_sum(h, dx):.5f}")
    print(f"force sum:   {min(t_force):.3f} s per call (best of {args.repeats}), {force_pairs} pairs per particle "
          f"-> {n * force_pairs / min(t_force):.3g} pair evaluations/s")
    print(f"density sum: {min(t_density):.3f} s per call, {density_pairs} pairs per particle "
          f"-> {n * density_pairs / min(t_density):.3g} pair evaluations/s")
    print(f"memory: {per_particle:.0f} bytes per particle (peak RSS growth)")

    # whole Verlet steps (two density sums, proximity, wall pressure and velocity, forces)
    from sph_bridge.simulation import Simulation, SphParameters

    params = SphParameters(dx=dx, c0=1.5, s_ff=3e-5, s_sf=8e-6, gravity=(0.0, 0.0, 0.0))
    sim = Simulation(pos, np.zeros((0, 3)), params, [0, 0, 0], [n_side * dx] * 3, (True, True, True))
    sim.step()  # warm
    t0 = time.perf_counter()
    for _ in range(args.repeats):
        sim.step()
    per_step = (time.perf_counter() - t0) / args.repeats
    print(f"Verlet step: {per_step:.3f} s -> {n / per_step:.3g} particle-steps/s; "
          f"memory with the simulation: {(peak_rss_bytes() - rss0) / n:.0f} bytes per particle")


if __name__ == "__main__":
    main()
