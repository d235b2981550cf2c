"""Where a radial run's contacts open against where its fluid is, over time (digest H1, H4).

    .venv/bin/python benchmarks/opening_front.py RUN_DIR [RUN_DIR ...]

Seed 004 §4.2 has B3's fractures form "before fluid infiltration" and guide the fluid, which
takes the fractures because they conduct far better than their sides (H8: 2 % of the sides'
resistance, about 3.7 times their aperture). Per run and per time window (doubling from the
first opening to the end), the contacts that opened then (decisions #20): how many, how many of
them the fluid never reached by the end, how far they lie from the port (their grains' midpoint
on the starting positions), against how far the fluid had got by the window's end (the
farthest wetted domain), and how wide they opened: the largest gap each reached during the
run (``fractures.npz`` max_gap), which Eq. 14 adds, times lambda, to the aperture a0. A second
per directory.
"""
import argparse
import json
from pathlib import Path

import numpy as np

from b3_volume_split import starting_geometry  # a sibling script (benchmarks/ is its folder)
from hmdem.coupling.micromechanics import fracture_timing
from md_table import header


def windows(first: float, end: float) -> list[tuple[float, float]]:
    """Time windows doubling from (0, 2 first) to one that holds ``end``."""
    edges = [0.0, 2.0 * first]
    while edges[-1] < end:
        edges.append(2.0 * edges[-1])
    edges[-1] = end * (1.0 + 1e-12)
    return list(zip(edges[:-1], edges[1:]))


def median_um(values: np.ndarray) -> str:
    return f"{np.median(values) * 1e6:.1f}" if len(values) else "-"


def table(run: Path) -> list[str]:
    summary = json.loads((run / "summary.json").read_text())
    net, fractures, state = (np.load(run / f"{name}.npz") for name in ("network", "fractures", "state"))
    opened, opened_at = fractures["opened"], fractures["opened_time"]
    wetted = fractures["pore_wetted_time"]
    never = opened & ~fracture_timing(opened, opened_at, net["pipe_domains"], wetted,
                                      state["invasion_time"])["reached"]
    start = fractures["initial_positions"]
    centre = starting_geometry(net, start).centroids(start)
    port = centre[net["inlet_domains"]].mean(axis=0)
    contact_distance = np.linalg.norm(start[fractures["pipe_grains"]].mean(axis=1) - port, axis=1)
    domain_distance = np.linalg.norm(centre - port, axis=1)
    gap = fractures["max_gap"]
    lines = [f"**{run}** ({summary['case']}, {summary['status']} at {float(state['t']):.3g} s, "
             f"{int(opened.sum())} opened, {int(never.sum())} never reached by the fluid)", "",
             header("window [us]", "opened", "never reached", "their distance from the port, median / max [um]",
                    "the fluid's reach at the window's end [um]",
                    "largest gap, never reached / reached, median [um]")]
    if not opened.any():
        return lines + ["| - | 0 | 0 | - | - | - |"]
    for lo, hi in windows(float(opened_at[opened].min()), float(state["t"])):
        now = opened & (opened_at >= lo) & (opened_at < hi)
        far = now & never
        wet = wetted < hi
        reach = domain_distance[wet].max() if wet.any() else 0.0
        distance = (f"{np.median(contact_distance[far]) * 1e6:.0f} / {contact_distance[far].max() * 1e6:.0f}"
                    if far.any() else "-")
        lines.append(f"| {lo * 1e6:.3g}-{hi * 1e6:.3g} | {int(now.sum())} | {int(far.sum())} | {distance} | "
                     f"{reach * 1e6:.0f} | {median_um(gap[far])} / {median_um(gap[now & ~never])} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="finished radial run directories")
    for run in parser.parse_args().runs:
        print("\n".join(table(run)) + "\n", flush=True)


if __name__ == "__main__":
    main()
