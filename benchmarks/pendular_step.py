"""Cost of one pendular liquid step (hmdem.wet.pendular_step) against the number of spheres.

Spheres of unit radius on a jittered simple-cubic lattice, a bridge on every pair closer than
2.1 R (5.4 a sphere), about 1.5 % of them past Eq. 5's rupture distance each call (3 % are
given too little liquid for their gap; half of those gaps are open), and the touching pairs
offered for new bridges. Reports the wall time per call for each redistribution
rule, per bridge, and the Young-Laplace table's build time (the pressure rules build it once).

    .venv/bin/python benchmarks/pendular_step.py [--sizes 1000 8000 27000] [--repeat 5]
"""
import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from md_table import header  # noqa: E402

from hmdem.wet.bridges import rupture_distance  # noqa: E402
from hmdem.wet.liquid import REDISTRIBUTION_RULES, PendularLiquid  # noqa: E402
from hmdem.wet.pendular import BridgeModel, branches, pendular_step  # noqa: E402
from hmdem.wet.young_laplace import bridge_table  # noqa: E402


def assembly(n: int, seed: int = 0):
    """Centres (n, 3), and the pairs closer than 2.1 R."""
    from scipy.spatial import cKDTree

    side = round(n ** (1 / 3))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3) * 2.0
    centres = grid + np.random.default_rng(seed).uniform(-0.04, 0.04, grid.shape)
    pairs = cKDTree(centres).query_pairs(2.1, output_type="ndarray")
    return centres, pairs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 8000, 27000])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    theta = math.radians(5.0)
    started = time.perf_counter()
    bridge_table(theta)
    print(f"Young-Laplace table at 5 degrees: {time.perf_counter() - started:.1f} s to build\n")
    print(header("spheres", "bridges", *(f"{rule} [ms]" for rule in REDISTRIBUTION_RULES),
                 "mani per bridge [us]", "ruptures"))
    for n in args.sizes:
        centres, pairs = assembly(n)
        distance, _ = branches(centres, pairs)
        volume = np.full(len(pairs), 0.01)
        # stretch 3 % of the bridges past rupture by shrinking their volume below the gap's
        stretched = np.random.default_rng(1).random(len(pairs)) < 0.03
        gap = distance - 2.0
        volume[stretched] = 0.5 * (np.maximum(gap[stretched], 1e-3) / rupture_distance(1.0, 1.0, theta)) ** 3
        touching = pairs[gap <= 0]
        row = [str(len(centres)), str(len(pairs))]
        for rule in REDISTRIBUTION_RULES:
            model = BridgeModel(0.0728, theta, rule=rule)
            times = []
            for _ in range(args.repeat):
                liquid = PendularLiquid(pairs, volume, np.full(len(centres), 1e-3))
                t = time.perf_counter()
                ruptures = pendular_step(liquid, centres, np.ones(len(centres)), model, touching)[2]
                times.append(time.perf_counter() - t)
            row.append(f"{1e3 * min(times):.1f}")
        row += [f"{1e6 * min(times) / len(pairs):.2f}", str(ruptures)]
        print("| " + " | ".join(row) + " |", flush=True)


if __name__ == "__main__":
    main()
