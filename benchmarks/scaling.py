"""Solver cost per step against packing size (issue 2: no worse than ~N log N up to 20,000 grains).

    .venv/bin/python benchmarks/scaling.py [--sizes 1188 2500 5000 10000 20000] [--steps 60]
Packings are generated with YADE at the default grain size and porosity (box grows with N) and
cached in benchmarks/.cache/; each runs the vf case for a fixed number of steps.
"""
import argparse
import math
import time
from pathlib import Path

from hmdem.cases import CASES
from hmdem.flow.simulation import FlowModel
from hmdem.scenario import build_scenario
from md_table import header

CACHE = Path(__file__).parent / ".cache"


def packing_file(n: int) -> Path:
    path = CACHE / f"packing_{n}.npz"
    if not path.exists():
        from hmdem.dem.packing import generate_packing

        CACHE.mkdir(exist_ok=True)
        size = 0.065 * math.sqrt(n / 1188)
        t0 = time.perf_counter()
        generate_packing(n=n, box=(size, size), seed=0).save(path)
        print(f"  generated {n} grains in {time.perf_counter() - t0:.0f} s")
    return path


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[1188, 2500, 5000, 10000, 20000])
    ap.add_argument("--steps", type=int, default=60)
    args = ap.parse_args()
    print(header("grains", "domains", "unknowns", "steps", "solves", "s per step", "ms per solve",
                 "solve / (N log N) rel."))
    base = None
    for n in args.sizes:
        sc = build_scenario(CASES["vf"], packing_path=packing_file(n))
        sc.setup.max_steps = args.steps
        model = FlowModel(sc.net, sc.setup)
        t0 = time.perf_counter()
        _, rec = model.run()
        wall = time.perf_counter() - t0
        per_solve = wall / rec.solves
        nlogn = model.system.n_unknowns * math.log(model.system.n_unknowns)
        base = base or per_solve / nlogn
        print(f"| {n} | {sc.net.n_domains} | {model.system.n_unknowns} | {rec.steps} | {rec.solves} | "
              f"{wall / rec.steps:.4f} | {1e3 * per_solve:.2f} | {per_solve / nlogn / base:.2f} |", flush=True)


if __name__ == "__main__":
    main()
