"""Wall time of the plane-shear run (python -m hmdem.wet shear) wet against dry.

One compacted shear cell (``--n`` grains, seed 0) is sheared for ``--steps`` DEM steps dry
(YADE alone), then for as many with the liquid at each ``--liquid-every``: a pendular step
(ruptures, new bridges, Eq. 4 forces; η = 0.5, the ``mani`` rule, which reads the Young-Laplace
table) and the forces set as YADE permanent forces. Reports ms per DEM step and the ratio to the
dry run (the draft's target: at most 2). Film flow (ω > 0) is not built, so not timed.

    .venv/bin/python benchmarks/wet_shear.py [--n 2000] [--steps 2000] [--liquid-every 1 10]
"""
import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from md_table import header  # noqa: E402

from hmdem.dem.shear_cell import ShearCell  # noqa: E402
from hmdem.wet.pendular import BridgeModel, pendular_step  # noqa: E402
from hmdem.wet.shear import ShearSettings, initial_liquid, surface_tension  # noqa: E402
from hmdem.wet.young_laplace import bridge_table  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--liquid-every", type=int, nargs="+", default=[1, 10])
    args = parser.parse_args()
    theta = math.radians(5.0)
    bridge_table(theta)  # built once per process (~5 s), not timed
    cell = ShearCell(args.n, 1e-3, 1e4, seed=0)
    t = time.perf_counter()
    compaction = cell.compact()
    print(f"{args.n} grains compacted in {compaction} DEM steps, {time.perf_counter() - t:.0f} s\n")
    settings = ShearSettings(0.03, 6.0, 0.5, 1.0, theta, rule="mani")
    liquid = initial_liquid(cell, settings)
    model = BridgeModel(surface_tension(0.5, cell.pressure, cell.radius, theta), theta, rule="mani")
    cell.start_shear(settings.inertial_number)
    cell.run(args.steps)  # out of the start's transient
    t = time.perf_counter()
    cell.run(args.steps)
    dry = (time.perf_counter() - t) / args.steps
    print(header("run", "bridges", "ms per DEM step", "wet / dry"))
    print(f"| dry (YADE alone) | - | {1e3 * dry:.2f} | 1 |")
    for every in args.liquid_every:
        t = time.perf_counter()
        for _ in range(args.steps // every):
            cell.run(every)
            centres = cell.centres()
            touching, _ = cell.touching(centres)
            liquid, forces, _ = pendular_step(liquid, centres, cell.radii, model, touching, cell.period)
            cell.set_grain_forces(forces)
        wet = (time.perf_counter() - t) / (args.steps // every * every)
        print(f"| liquid every {every} | {len(liquid.pairs)} | {1e3 * wet:.2f} | {wet / dry:.2f} |", flush=True)


if __name__ == "__main__":
    main()
