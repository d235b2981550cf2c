"""Where the regimes should part, from this model's own criteria and a run's network.

Decisions.md #10 labels a fingered run capillary when its median injection pressure is below
10x the spread of the pipes' entry pressures, viscous above. The viscous pressure across the
cell is Darcy's, dp = eta Q L / (k H), of the defending fluid while M < 1 (it holds the cell)
and of the invading one for M > 1; with Q from Ca* (seed 004 Eq. 24, Sigma = H) that is
dp = Ca* gamma a_mean / (k min(M, 1)). The crossover is therefore the line

    Ca*_c(M) = 10 dp_c,spread k min(M, 1) / (gamma a_mean),

slope 1 in log-log for M < 1 and flat above, with the Saffman-Taylor boundary M = 1 between
viscous fingering and stable displacement: the shape of Lenormand et al.'s (1988) diagram.
"""

from __future__ import annotations

import tomllib
from dataclasses import fields
from pathlib import Path

import numpy as np

from ..coupling.darcy import solve_darcy
from ..network.network import Network

LABEL_RATIO = 10.0  # decisions.md #10: viscous above 10x the entry-pressure spread


def load_network(path: Path) -> tuple[Network, np.ndarray]:
    """A :class:`Network` from a run directory's network.npz, and its pipes' entry pressures."""
    with np.load(path) as f:
        data = {k.name: f[k.name] for k in fields(Network) if k.name in f.files}
        entry = f["pipe_entry_pressure"]
    data["extent"] = tuple(float(v) for v in data.get("extent", (0.0, 1.0, 0.0, 1.0)))
    return Network(**data), entry


def capillary_crossover(run_dir: Path) -> float:
    """Ca*_c at M >= 1 for the network, fluids and aperture field of one run directory."""
    run_dir = Path(run_dir)
    net, entry = load_network(run_dir / "network.npz")
    entry = np.abs(entry[net.flowing_pipes])
    config = tomllib.loads((run_dir / "config.toml").read_text())
    gamma = config["fluids"]["surface_tension"]
    mean_aperture = config["case"]["mean_aperture_m"]
    k = solve_darcy(net).permeability
    return LABEL_RATIO * float(np.std(entry)) * k / (gamma * mean_aperture)
