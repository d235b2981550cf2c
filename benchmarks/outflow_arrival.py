"""When the fluid first reaches the outflow ring, against breakthrough (digest H6; decisions #8).

    .venv/bin/python benchmarks/outflow_arrival.py RUN_DIR [RUN_DIR ...]

Breakthrough is the first outflow domain filled (S = 1, decisions #8); seed 004 leaves open
whether its t_f is that or the first outflow domain the fluid enters (digest §14.9). Run the
directories first (``python -m hmdem.hele_shaw radial --case X --out RUN_DIR``). Prints one row
per directory: the case, breakthrough time, when invading fluid first entered an outflow domain
(``pore_wetted_time`` in fractures.npz) and its fraction of the breakthrough time, the fluid
injected by each time as a fraction of the domain tiling's area (Q t / sum V), and the fraction of
that area filled at breakthrough. Takes a second.
"""
import json
from pathlib import Path

import numpy as np
from md_table import print_run_table

PAPER_BREAKTHROUGH_S = {"A1": 3.0e-2, "A3": 1.5e-3, "B1": 2.5e-2, "B3": 3.5e-4}  # seed 004 Table 4


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    if summary["status"] != "breakthrough":  # no breakthrough to read against
        return f"| {run} | {summary['case']} | {summary['status']} | – | – | – | – | – | – |"
    network, state = np.load(run / "network.npz"), np.load(run / "state.npz")
    wetted = np.load(run / "fractures.npz")["pore_wetted_time"]
    area = network["domain_volume"].sum()
    rate = summary["rate_m3_per_s_per_m"]
    breakthrough = summary["breakthrough_time_s"]
    arrival = wetted[network["outlet_domains"]].min()
    filled = network["domain_volume"][state["saturation"] >= 1.0].sum() / area
    paper = PAPER_BREAKTHROUGH_S.get(summary["case"])
    paper_cell = "–" if paper is None else f"{rate * paper / area:.1%}"
    return (f"| {run} | {summary['case']} | {summary['status']} | {breakthrough:.3e} | {arrival:.3e} "
            f"({arrival / breakthrough:.2f}) | {rate * arrival / area:.1%} | {rate * breakthrough / area:.1%} "
            f"| {paper_cell} | {filled:.1%} |")


def main() -> None:
    print_run_table(__doc__.splitlines()[0],
                    ["run", "case", "status", "breakthrough [s]", "fluid first in an outflow domain [s] (fraction)",
                     "injected by then", "injected by breakthrough", "injected by the paper's t_f",
                     "filled at breakthrough"], row)


if __name__ == "__main__":
    main()
