"""FHP-II lattice-gas throughput (issue 6): site updates per second on a 10^6-site lattice, one
thread and numba-parallel over rows, and the state's memory per site.

    .venv/bin/python benchmarks/lga_sites.py [--rows 1000] [--length 1000] [--steps 2000]

A site update is one node through propagation, wall rules and collision (a step of the whole
lattice is rows x length site updates). The lattice is a smooth channel with bounce-back walls
and forcing at g = 1e-4 (the forcing's cost is per forced node, negligible here). The parallel
kernel's speed depends on numba's threading layer (reported; set NUMBA_THREADING_LAYER=omp,
tbb or workqueue to compare).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1000)
    parser.add_argument("--length", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)

    import numba

    from sph_bridge.lga import automaton, channels
    from sph_bridge.lga.lattice import Lattice

    lattice = Lattice(channels.smooth_channel(args.length, args.rows - 2), seed=1)
    sites = lattice.ny * lattice.nx
    for name, kernel in (("1 thread", automaton.advance_serial), ("parallel", automaton.advance_parallel)):
        best = np.inf
        for repeat in range(args.repeats + 1):  # the first call compiles
            steps = 2 if repeat == 0 else args.steps
            gains, losses = np.zeros(steps, np.int64), np.zeros(steps, np.int64)
            start = time.perf_counter()
            kernel(lattice.state, lattice.spare, lattice.solid, lattice.mirror, lattice.fluid, lattice.nx, False,
                   1, 0, 1e-4, lattice.fluid_nodes, gains, losses)
            if repeat:
                best = min(best, time.perf_counter() - start)
        print(f"{name:9s}: {args.steps * sites / best:.3g} site updates/s ({sites} sites, {args.steps} steps, "
              f"best of {args.repeats})")
    print(f"threads {numba.get_num_threads()}, threading layer {numba.threading_layer()}")
    state_bytes = lattice.state.nbytes + lattice.spare.nbytes + lattice.solid.nbytes * 3
    print(f"state + spare + masks: {state_bytes / sites:.2f} bytes per site "
          f"(+ {lattice.fluid_nodes.nbytes / sites:.0f} B per site of forcing index)")


if __name__ == "__main__":
    main()
