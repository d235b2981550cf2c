"""Where a radial run's injected volume went by breakthrough, read from finished run directories (digest H4).

    .venv/bin/python benchmarks/b3_volume_split.py RUN_DIR [RUN_DIR ...]

Domain volumes are centre-polygon areas (digest §3.3), so the invading fluid sum S_i V_i splits
exactly into the part that fills the invaded domains' areas at the start (infiltration of the
original pore network) and the part that fills their growth as the grains moved away (the cavity
the injection pressure opens). The final volumes are the model's own (network.npz, which holds
the final state; a domain whose polygon has turned inside out is held at 1 % of its starting
area), the starting ones are the same polygons on the starting positions (fractures.npz). The
dry domains shrink by about as much as the wet ones grow (the hull is fixed), so the growth is
also the compaction of the dry skeleton, given as a fraction of its starting area; the last
columns count the polygons that have turned inside out and the room their floors add (the model's
sum of V less the hull area, which the polygons' own signed areas keep exactly). Takes a second
per directory.
"""
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hmdem.coupling.geometry import DomainGeometry
from md_table import print_run_table


def starting_geometry(net, initial: np.ndarray) -> DomainGeometry:
    """The model's domain geometry of a run directory's ``network.npz``, its triangles oriented
    on the starting grain positions ``initial`` (so that areas stay positive as grains move)."""
    fields = ("triangles", "triangle_domain", "pipe_domains", "pipe_grains")
    return DomainGeometry(SimpleNamespace(n_domains=len(net["domain_volume"]), points=initial,
                                          **{name: net[name] for name in fields}))


def domain_areas(net, initial: np.ndarray, final: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each domain's centre-polygon area with the grains at ``initial`` and at ``final``."""
    geometry = starting_geometry(net, initial)
    return geometry.volumes(initial), geometry.volumes(final)


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    net, fractures, state = (np.load(run / f"{name}.npz") for name in ("network", "fractures", "state"))
    v0, polygon = domain_areas(net, fractures["initial_positions"], fractures["positions"])
    v1 = net["domain_volume"]  # the model's final volumes (inside-out polygons held at their floor)
    s = state["saturation"]
    fluid, infiltrated = float(s @ v1), float(s @ v0)
    dry = s == 0
    injected = summary["rate_m3_per_s_per_m"] * float(state["t"])
    return (f"| {run} | {summary['case']} | {summary['status']} at {float(state['t']):.3g} s | {injected:.3g} | "
            f"{fluid:.3g} | {infiltrated / fluid:.0%} | {(fluid - infiltrated) / fluid:.0%} | {int((~dry).sum())} | "
            f"{(v0[dry] - v1[dry]).sum() / v0[dry].sum():.1%} | {fluid / injected:.3f} | {int((polygon < 0).sum())} | "
            f"{(v1.sum() - polygon.sum()) / fluid:.1%} |")


def main() -> None:
    print_run_table(__doc__.splitlines()[0],
                    ["run", "case", "end", "injected Q t [m^2 per m]", "fluid sum S V [m^2 per m]",
                     "into the starting areas", "into their growth", "wet domains", "dry skeleton compacted by",
                     "sum S V / Q t", "inside-out polygons", "sum V - hull area, of sum S V"], row)


if __name__ == "__main__":
    main()
