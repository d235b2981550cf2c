"""Where B3's `peak_compression` warning comes from: the domains whose p / K_f exceeds 0.1.

    .venv/bin/python benchmarks/b3_compression.py [--packing P.npz]

Runs B3 (paper size, the CLI's defaults) to breakthrough. After each accepted step it takes the
domain with the largest p / K_f, K_f the Eq. 3 mixture modulus of the saturation at the step's
start (as `summary.json`'s `peak_compression` does), and keeps it when p / K_f > 0.1. Prints the
number of such steps and, for the 10 domains with the largest values, the time, p / K_f, p, the
saturation at the step's start and end, how many of the domain's neighbours are invaded and
their median pressure. 3-4 minutes on one core.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from hmdem.network.packing import DiscPacking  # noqa: E402
from md_table import header  # noqa: E402

WEAK = 0.1  # hmdem.report's weakly compressible bound (decisions #31)


class CompressionLog:
    """Per step, the most compressed domain when it passes WEAK."""

    def __init__(self, model: CoupledFlowModel):
        self.saturation = model.initial_state().saturation.copy()
        a, b = model.net.pipe_domains.T
        self.neighbours = [np.concatenate([b[a == i], a[b == i]]) for i in range(model.net.n_domains)]
        self.rows = []  # (t, domain, p/K, p, S before, S after, invaded neighbours, neighbours, their median p)

    def __call__(self, model: CoupledFlowModel, state) -> None:
        ratio = state.pressure / model.fluids.mixture_bulk_modulus(self.saturation)
        i = int(np.argmax(ratio))
        if ratio[i] > WEAK:
            nb = self.neighbours[i]
            self.rows.append((state.t, i, ratio[i], state.pressure[i], self.saturation[i], state.saturation[i],
                              int(state.invaded[nb].sum()), nb.size, float(np.median(state.pressure[nb]))))
        self.saturation = state.saturation.copy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--packing", help="packing .npz (default: the shipped paper-size one)")
    args = parser.parse_args()
    sc = build_radial_scenario(RADIAL_CASES["B3"], packing=DiscPacking.load(args.packing) if args.packing else None)
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    log = CompressionLog(model)
    state, rec = model.run(progress=log)
    print(f"B3: {rec.status} at t = {state.t:.4g} s after {rec.steps} steps; peak p/K {rec.peak_compression:.2f}; "
          f"{len(log.rows)} steps with a domain above p/K = {WEAK}")
    print(header("t [µs]", "domain", "p/K", "p [MPa]", "S at start / end", "invaded neighbours",
                 "their median p [MPa]"))
    shown = set()
    for t, i, ratio, p, s0, s1, wet, nb, p_nb in sorted(log.rows, key=lambda r: -r[2]):
        if i in shown:
            continue
        shown.add(i)
        print(f"| {t * 1e6:.1f} | {i} | {ratio:.2f} | {p / 1e6:.3f} | {s0:.3f} / {s1:.3f} | {wet} of {nb} | {p_nb / 1e6:.3f} |")
        if len(shown) == 10:
            break


if __name__ == "__main__":
    main()
