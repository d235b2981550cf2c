"""H10's one-way variants of B3 at paper size (decisions #66).

    .venv/bin/python benchmarks/one_way_variants.py [--variants ignored lagged] [--water-moduli 2000 0.75]
                                                    [--t-max T]

Seed 004 says Zhang et al.'s one-way model shows "sudden drops" of B3's injection pressure
where the P-V iteration gives a smooth curve (digest H10). This runs B3 one-way with the grains'
volume change left out of the pressure equation ("ignored", the ``--one-way`` default) or put in
one step late ("lagged", ``--one-way-volume lagged``), at the realistic water modulus (2,000 MPa)
and at Zhang et al.'s reduced 0.75 MPa (digest §4), and prints per run: how it ended, steps,
opened contacts, the lowest and highest injection pressure, H10's count of falls (more than 2 %
of the running peak between neighbouring points of a 200-point grid, as
tests/test_huang_full.py counts them) and the single-step falls of more than 2 % and 10 %;
on stderr, the injection pressure over each run's first 8 steps.
Each run takes 1-4 minutes on one core.
"""
import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from md_table import header  # noqa: E402

MPA = 1e6


def falls(t: np.ndarray, p: np.ndarray) -> tuple[int, int, int]:
    """H10's grid falls, and single steps falling by > 2 % and > 10 % of the running peak."""
    grid = np.interp(np.linspace(0.0, t[-1], 201)[1:], t, p)
    on_grid = int(np.sum(np.diff(grid) < -0.02 * np.maximum.accumulate(grid)[1:]))
    step = np.diff(p) / np.maximum.accumulate(np.abs(p))[1:]
    return on_grid, int(np.sum(step < -0.02)), int(np.sum(step < -0.10))


def run(volume: str, water_modulus: float, t_max: float | None) -> str:
    sc = build_radial_scenario(RADIAL_CASES["B3"], one_way=True)
    sc.coupling.one_way_volume = volume
    sc.setup.fluids = replace(sc.setup.fluids, bulk_modulus_inv=water_modulus)
    if t_max is not None:
        sc.setup.t_max = t_max
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    state, rec = model.run()
    t, p = rec.injection_pressure()
    on_grid, over_2, over_10 = falls(t, p)
    start = ", ".join(f"{p_k / MPA:.3g}" for p_k in p[:8])
    print(f"{volume}, K {water_modulus / MPA:g} MPa: p_in over the first steps [MPa] {start} "
          f"(at t = {t[min(7, len(t) - 1)]:.3g} s)", file=sys.stderr)
    return (f"| {volume} | {water_modulus / MPA:g} | {rec.status} at {state.t:.3g} s | {rec.steps} | "
            f"{int(model.opened.sum())} | {p.min() / MPA:.3g} | {p.max() / MPA:.3g} | {on_grid} | {over_2} | {over_10} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", choices=("ignored", "lagged"), default=["ignored", "lagged"])
    parser.add_argument("--water-moduli", nargs="+", type=float, default=[2000.0, 0.75], help="[MPa]")
    parser.add_argument("--t-max", type=float, help="stop here [s] (default: breakthrough)")
    args = parser.parse_args()
    print(header("dV", "K water [MPa]", "end", "steps", "opened", "min p_in [MPa]", "max p_in [MPa]", "H10 falls",
                 "steps falling > 2 %", "> 10 %"))
    for modulus in args.water_moduli:
        for volume in args.variants:
            print(run(volume, modulus * MPA, args.t_max), flush=True)


if __name__ == "__main__":
    main()
