"""YADE against its numba replica on the Huang sample: cost per DEM cycle and agreement (issue 3).

    .venv/bin/python benchmarks/dem_replica.py [--case B1] [--cycles 150 1000] [--push 5.0]

The shipped sample is settled as ``radial`` does it (``start_grains``); 200 grains get a random
push of ``--push`` N/m (seed 0) for 200 cycles, the state is saved and loaded into the replica
(``hmdem.coupling.replica``, decisions #65), and then both run each count of ``--cycles`` from
that state under three times the push. Printed per count: YADE's and the replica's ms per
cycle, the largest displacement and the largest difference between the two (round-off grows
with the cycles where a hard push makes grains collide), and the contact counts.
"""
import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from hmdem.coupling.replica import DiscReplica  # noqa: E402
from md_table import header  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--case", default="B1", choices=sorted(RADIAL_CASES))
    parser.add_argument("--cycles", type=int, nargs="+", default=[150, 1000])
    parser.add_argument("--push", type=float, default=5.0)
    args = parser.parse_args()
    grains = start_grains(build_radial_scenario(RADIAL_CASES[args.case]))
    push = np.zeros((len(grains.radii), 2))
    push[:200] = np.random.default_rng(0).normal(0.0, args.push, (200, 2))
    grains.set_external_forces(push)
    grains.run(200)
    grains.save_state()
    start = time.perf_counter()
    state = grains.carried_state()
    carried_ms = 1e3 * (time.perf_counter() - start)
    twin = DiscReplica.of(grains)
    twin.timestep = grains.timestep
    twin.load(state)
    twin.run(1)  # compiles (or loads numba's cache) outside the timings
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}; {args.case} sample, "
          f"{len(grains.radii)} discs, DEM step {grains.timestep:.3g} s; carried state read in {carried_ms:.1f} ms")
    print(header("cycles", "YADE ms/cycle", "replica ms/cycle", "largest displacement [m]", "largest difference [m]",
                 "contacts YADE / replica"))
    for cycles in args.cycles:
        grains.restore_state()
        twin.restore_state()
        x0 = grains.positions()
        timings = []
        for dem in (grains, twin):
            dem.set_external_forces(3.0 * push)
            start = time.perf_counter()
            dem.run(cycles)
            timings.append(1e3 * (time.perf_counter() - start) / cycles)
        moved = np.abs(grains.positions() - x0).max()
        differ = np.abs(grains.positions() - twin.positions()).max()
        print(f"| {cycles} | {timings[0]:.3f} | {timings[1]:.4f} | {moved:.3g} | {differ:.3g} | "
              f"{len(grains.contacts()[0])} / {len(twin.contacts()[0])} |")


if __name__ == "__main__":
    main()
