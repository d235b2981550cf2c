"""The fracture zone's D_f under other readings of "the fracturing regions" (digest H5; decisions #97).

    .venv/bin/python benchmarks/fracture_dimension.py RUN_DIR [RUN_DIR ...]

Seed 004 box-counts "the fracturing zone" (App. E, Fig. 25b) without saying how it is drawn.
``summary.json``'s ``fracture_fractal_dimension`` draws every opened contact as a crack on the
packing's positions. Prints one row per finished radial run directory: that figure as recomputed
here, then the same box counting on the cracks the fluid reached (invading fluid in one of the
contact's two pores by the end), on those inside the invaded zone (both pores filled), on every
crack at the grains' final positions, and on the pores beside the opened contacts (both domains
of each, filled areas instead of lines). Then a control for how much of the figure is the
cracks' density: within the radius about the port that holds 90 % of the cracks, the opened
share of the contacts closed after settling, the opened ones' D_f there, and the mean D_f of five
random draws of as many of those contacts (seeds 0-4). Run the directories first (``python -m
hmdem.hele_shaw radial --case X --out RUN_DIR``). Takes a few seconds.
"""
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hmdem.coupling.micromechanics import crack_segments, fracture_timing, fracture_zone_dimension
from hmdem.flow.diagnostics import fractal_dimension, pattern_scales
from md_table import print_run_table


def random_control(net, positions, radii, opened, closed_at_start) -> str:
    """The opened cracks within the radius of 90 % of them, against random ones at their share."""
    if opened.sum() < 2:
        return "– | – | –"
    starts, ends = crack_segments(positions, radii, net.pipe_grains)
    port = net.domain_centroid[net.inlet_domains].mean(axis=0)
    distance = np.linalg.norm(0.5 * (starts + ends) - port, axis=1)
    zone = closed_at_start & (distance <= np.quantile(distance[opened], 0.9))
    chosen = opened & zone
    draws = []
    for seed in range(5):
        subset = np.zeros(len(zone), bool)
        subset[np.random.default_rng(seed).choice(np.flatnonzero(zone), chosen.sum(), replace=False)] = True
        draws.append(fracture_zone_dimension(net, positions, radii, subset))
    return (f"{chosen.sum() / zone.sum():.1%} of {zone.sum()} | {fracture_zone_dimension(net, positions, radii, chosen):.3f} "
            f"| {np.mean(draws):.3f} ({min(draws):.3f}–{max(draws):.3f})")


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    network, fractures = np.load(run / "network.npz"), np.load(run / "fractures.npz")
    # network.npz holds the grains where the run left them; the summary reads the packing's
    net = SimpleNamespace(**{k: network[k] for k in network.files})
    net.extent, net.points = tuple(network["extent"]), fractures["initial_positions"]
    opened, radii, initial = fractures["opened"], fractures["radii"], fractures["initial_positions"]
    timing = fracture_timing(opened, fractures["opened_time"], network["pipe_domains"], fractures["pore_wetted_time"],
                             np.load(run / "state.npz")["invasion_time"])
    inner = network["pipe_domains"] >= 0
    beside = np.zeros(len(network["domain_volume"]), bool)
    beside[network["pipe_domains"][opened][inner[opened]]] = True
    pores = fractal_dimension(net, beside, *pattern_scales(net))[0] if opened.any() else np.nan

    def d_f(subset, positions=initial):
        return f"{fracture_zone_dimension(net, positions, radii, subset):.3f} ({subset.sum()})"

    recorded = summary.get("fracture_fractal_dimension")  # null with none opened; absent before decisions #97
    recorded = "–" if recorded is None else f"{recorded:.3f}"
    return (f"| {run} | {summary['case']} | {summary['status']} | {recorded} | {d_f(opened)} "
            f"| {d_f(timing['reached'])} | {d_f(timing['in_invaded_zone'])} | {d_f(opened, fractures['positions'])} "
            f"| {pores:.3f} ({beside.sum()}) | {random_control(net, initial, radii, opened, fractures['initially_closed'])} |")


def main() -> None:
    print_run_table(__doc__.splitlines()[0],
                    ["run", "case", "status", "summary's D_f", "every opened contact (count)",
                     "reached by the fluid", "inside the invaded zone", "at the final positions",
                     "the pores beside them (count)", "opened share within 90 % of the cracks' reach", "their D_f",
                     "random at that share (range)"], row)


if __name__ == "__main__":
    main()
