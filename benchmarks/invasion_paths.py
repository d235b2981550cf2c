"""Whether a radial run's fluid went in through its opened contacts, read from finished run directories (digest H4, H5).

    .venv/bin/python benchmarks/invasion_paths.py RUN_DIR [RUN_DIR ...]

Seed 004 §4.2 says B3's pressure "creates fractures before fluid infiltration", "guiding the
fluid to penetrate the fracturing domains", so that the front is finger-like. Per run:
- ``fracture_guidance``'s three fractions (hmdem.coupling.micromechanics; decisions #87), read
  from the run's arrays: the feeding pipes (each filled domain's pipes to neighbours filled
  earlier, the port first) whose contact had opened by the time their domain filled, against
  the front's other pipes at the same moments; and the filled domains fed, from a neighbour
  already filled, through a contact that opened before the fluid first entered them;
- the invaded zone's reach (its farthest domain from the port, on the starting positions)
  against the radius of a disc of its starting area: 1 for a disc round the port;
- the breakthrough path, traced back from the outflow domain that filled first, each step to
  the feeding neighbour filled last before it (where the front came from), and how many of its
  pipes had opened by the time the fluid went through.
A second per directory.
"""
import json
from pathlib import Path

import numpy as np

from b3_volume_split import starting_geometry  # a sibling script (benchmarks/ is its folder)
from md_table import print_run_table
from hmdem.coupling.micromechanics import filling_order, fracture_guidance


def breakthrough_path(t: np.ndarray, pipe_domains: np.ndarray, outlets: np.ndarray) -> np.ndarray:
    """Pipes from the port to the first filled outflow domain, each step back to the neighbour
    filled last before (``filling_order``'s t and pipe ends); none if no outflow domain filled."""
    if not np.isfinite(t[outlets]).any():
        return np.zeros(0, int)
    domain = int(outlets[np.argmin(t[outlets])])
    path = []
    while t[domain] >= 0.0:  # the port's is -1
        pipes = np.flatnonzero((pipe_domains == domain).any(axis=1))
        other = np.where(pipe_domains[pipes, 0] == domain, pipe_domains[pipes, 1], pipe_domains[pipes, 0])
        earlier = t[other] < t[domain]
        if not earlier.any():
            raise ValueError(f"domain {domain} filled at {t[domain]:.6g} s with no neighbour filled before")
        came_from = np.argmax(np.where(earlier, t[other], -np.inf))
        path.append(pipes[came_from])
        domain = int(other[came_from])
    return np.array(path[::-1], int)


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    net, fractures, state = (np.load(run / f"{name}.npz") for name in ("network", "fractures", "state"))
    opened_at, port = fractures["opened_time"], net["inlet_domains"]
    guidance = fracture_guidance(opened_at, net["pipe_domains"], fractures["pore_wetted_time"],
                                 state["invasion_time"], port)
    t, ends = filling_order(state["invasion_time"], port, net["pipe_domains"])
    zone = np.flatnonzero(np.isfinite(t[:-1]))  # the filled domains and the port
    start = fractures["initial_positions"]
    geometry = starting_geometry(net, start)
    radius = np.sqrt(geometry.volumes(start)[zone].sum() / np.pi)
    centre = geometry.centroids(start)
    reach = np.linalg.norm(centre[zone] - centre[port].mean(axis=0), axis=1).max()
    path = breakthrough_path(t, ends, net["outlet_domains"])
    path_opened = opened_at[path] <= t[ends[path]].max(axis=1)
    end = summary.get("breakthrough_time_s") or float(state["t"])
    return (f"| {run} | {summary['case']} | {summary['status']} at {end:.3g} | {len(zone) - len(port)} | "
            f"{guidance['feeding_pipes_opened_fraction']:.0%} | {guidance['front_pipes_opened_fraction']:.0%} | "
            f"{guidance['fracture_fed_fraction']:.0%} | {radius * 1e6:.0f} | {reach * 1e6:.0f} | "
            f"{reach / radius:.2f} | {path_opened.sum()} of {len(path)} |")


def main() -> None:
    print_run_table(__doc__.splitlines()[0],
                    ["run", "case", "end [s]", "filled domains", "feeding pipes opened by the filling",
                     "the front's other pipes opened, at the same moments",
                     "filled domains fed through a contact opened before the fluid came", "disc radius of the zone [um]", "reach [um]", "reach / radius", "breakthrough path: pipes opened"],
                    row)


if __name__ == "__main__":
    main()
