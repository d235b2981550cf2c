"""The fracture zone's D_f under other readings of "the fracturing regions" (digest H5; decisions #97).

    .venv/bin/python benchmarks/fracture_dimension.py RUN_DIR [RUN_DIR ...]

Seed 004 box-counts "the fracturing zone" (App. E, Fig. 25b) without saying how it is drawn.
``summary.json``'s ``fracture_fractal_dimension`` draws every opened contact as a crack on the
packing's positions. Prints one row per finished radial run directory: that figure as recomputed
here, then the same box counting on the cracks the fluid reached (invading fluid in one of the
contact's two pores by the end), on those inside the invaded zone (both pores filled), on every
crack at the grains' final positions, and on the pores beside the opened contacts (both domains
of each, filled areas instead of lines). Run the directories first (``python -m hmdem.hele_shaw
radial --case X --out RUN_DIR``). Takes a few seconds.
"""
import argparse
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hmdem.coupling.micromechanics import fracture_zone_dimension
from hmdem.flow.diagnostics import fractal_dimension


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    network, fractures = np.load(run / "network.npz"), np.load(run / "fractures.npz")
    invasion_time = np.load(run / "state.npz")["invasion_time"]
    # network.npz holds the grains where the run left them; the summary reads the packing's
    net = SimpleNamespace(**{k: network[k] for k in network.files})
    net.extent, net.points = tuple(network["extent"]), fractures["initial_positions"]
    opened, radii = fractures["opened"], fractures["radii"]
    pipe_domains = network["pipe_domains"]
    inner = pipe_domains >= 0
    pore = np.maximum(pipe_domains, 0)
    reached = opened & (inner & np.isfinite(fractures["pore_wetted_time"][pore])).any(axis=1)
    inside = opened & (inner & np.isfinite(invasion_time[pore])).all(axis=1)
    beside = np.zeros(len(network["domain_volume"]), bool)
    beside[pipe_domains[opened][inner[opened]]] = True
    size = max(net.extent[1] - net.extent[0], net.extent[3] - net.extent[2])
    pores = fractal_dimension(net, beside, float(np.median(net.pipe_length)), size / 4)[0] if opened.any() else np.nan

    def d_f(subset, positions=fractures["initial_positions"]):
        return f"{fracture_zone_dimension(net, positions, radii, subset):.3f} ({subset.sum()})"

    recorded = summary.get("fracture_fractal_dimension")  # null with none opened; absent before decisions #97
    recorded = "–" if recorded is None else f"{recorded:.3f}"
    return (f"| {run} | {summary['case']} | {summary['status']} | {recorded} "
            f"| {d_f(opened)} | {d_f(reached)} | {d_f(inside)} | {d_f(opened, fractures['positions'])} "
            f"| {pores:.3f} ({beside.sum()}) |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="finished radial run directories")
    args = parser.parse_args()
    print("| run | case | status | summary's D_f | every opened contact (count) | reached by the fluid "
          "| inside the invaded zone | at the final positions | the pores beside them (count) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for run in args.runs:
        print(row(run))


if __name__ == "__main__":
    main()
