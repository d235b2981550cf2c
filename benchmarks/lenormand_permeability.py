"""Where the Lenormand sample's Darcy permeability stands against the paper's (decisions #75).

    .venv/bin/python benchmarks/lenormand_permeability.py [--seeds N]

`linear --case darcy` reads k = 1.37-1.43e-9 m2 over seeds 0-3 on the shipped packing; seed 004
§4.1 gives 1.066e-9 for its network of 1,874 domains and 3,061 pipes. This prints the steady
network permeability (one sparse solve, the `darcy` case's network and boundaries, Eq. 21 with
H the packing's height, as the darcy run reads it) for:

- the near-contact gap that decides which grain pairs are pipes (#2; 0.08 is the default), to see
  whether the paper's pipe count explains the difference;
- the same pipes at the uniform mean aperture (spread 0), to see what the U[0.3, 1.7] spread does;
- the mean aperture that would give the paper's k on each network: every conductance is
  a^3 / (12 eta l), so k scales with a_mean^3 exactly.

Seconds on one core.
"""
import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.cases import CASES  # noqa: E402
from hmdem.coupling.darcy import solve_darcy  # noqa: E402
from hmdem.scenario import build_network  # noqa: E402
from md_table import header  # noqa: E402

PAPER_PERMEABILITY = 1.066e-9  # seed 004 §4.1, Eq. 21 on the paper's network
PAPER_PIPES = 3061
GAPS = (0.0, 0.04, 0.08, 0.15, 0.25, 0.4)


def permeability(case, seed: int) -> tuple[float, int, int]:
    """Steady k of the case's network on aperture draw ``seed``, with its pipe and domain counts."""
    net, height, *_ = build_network(case, seed)  # height: the injection 'area' H, as in read_darcy_run
    return solve_darcy(net, height=height).permeability, net.n_pipes, net.n_domains


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=4, help="aperture draws per row (seeds 0..N-1)")
    args = ap.parse_args(argv)
    base = CASES["darcy"]
    a_mean = base.mean_aperture
    print(f"paper: k = {PAPER_PERMEABILITY:.4g} m2 on {PAPER_PIPES} pipes, a_mean = {a_mean * 1e3:.2f} mm")
    print(header("near-contact gap", "pipes", "domains", "k, spread 0.7 [m2] (seeds)", "k, uniform a_mean [m2]",
                 "k / paper's", "a_mean for the paper's k [mm]"))
    for gap in GAPS:
        case = replace(base, contact_gap=gap)
        ks = [permeability(case, seed)[0] for seed in range(args.seeds)]
        uniform, pipes, domains = permeability(replace(case, aperture_spread=0.0), 0)  # same pipes, any seed
        k = float(np.mean(ks))
        print(f"| {gap:g} | {pipes} | {domains} | {k:.3e} ({min(ks):.3e}-{max(ks):.3e}) | {uniform:.3e} "
              f"| {k / PAPER_PERMEABILITY:.2f} | {a_mean * 1e3 * (PAPER_PERMEABILITY / k) ** (1 / 3):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
