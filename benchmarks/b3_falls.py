"""How B3's injection pressure falls, read from finished run directories (digest H10).

    .venv/bin/python benchmarks/b3_falls.py RUN_DIR [RUN_DIR ...]

Run the directories first, e.g. ``python -m hmdem.hele_shaw radial --case B3 [--one-way]
[--packing P.npz] [--dt 4e-7] --out RUN_DIR``. Prints one table row per directory: coupling,
the command's packing and flow step, steps, breakthrough time, the largest fall of p_in in one
accepted step (as a fraction of its running peak) and when, the "dips" (a step falling by more
than 2 % or 5 % of the running peak whose next step rises by more than the same fraction: the seed's
"pressure fluctuations (sudden drops)", which the steady decline after the early peak that H4 asks
for does not count) and H10's own count of falls on its 200-point grid (``one_way_variants.falls``,
as tests/test_huang_full.py counts them). Takes a second.
"""
import csv
import json
import shlex
import tomllib
from pathlib import Path

import numpy as np

# sibling modules: importable when this file is run as a script (its folder leads sys.path)
from md_table import print_run_table
from one_way_variants import falls


def dips(t: np.ndarray, p: np.ndarray, fraction: float) -> np.ndarray:
    """Times of steps that fall by more than ``fraction`` of the running peak, the next step rising by more."""
    peak = np.maximum.accumulate(p)[1:-1]
    fall, rise = (p[:-2] - p[1:-1]) / peak, (p[2:] - p[1:-1]) / peak
    return t[1:-1][(fall > fraction) & (rise > fraction)]


def row(run: Path) -> str:
    summary = json.loads((run / "summary.json").read_text())
    config = tomllib.loads((run / "config.toml").read_text())
    words = shlex.split(config["run"]["command"])
    packing = words[words.index("--packing") + 1] if "--packing" in words else "shipped"
    with open(run / "timeseries.csv") as f:
        series = list(csv.DictReader(f))
    t = np.array([float(r["t"]) for r in series])
    p = np.array([float(r["p_in_mean"]) for r in series])
    step_fall = (p[:-1] - p[1:]) / np.maximum.accumulate(p)[1:]
    k = int(np.argmax(step_fall))
    counted = []
    for fraction in (0.02, 0.05):
        at = dips(t, p, fraction)
        counted.append(f"{at.size}" + (f" ({', '.join(f'{x * 1e6:.1f}' for x in at)} µs)" if at.size else ""))
    coupling = "one-way" if summary["one_way"] else "two-way"
    return (f"| {coupling} | {packing} | {config['solver']['dt']:g} | {summary['steps']} | {summary['breakthrough_time_s']:.3g} | "
            f"{step_fall[k]:.1%} ({t[k + 1] * 1e6:.1f} µs) | {counted[0]} | {counted[1]} | {falls(t, p)[0]} |")


def main() -> None:
    print_run_table(__doc__.splitlines()[0],
                    ["run", "packing", "dt [s]", "steps", "breakthrough [s]", "largest one-step fall (at)",
                     "dips > 2 %", "dips > 5 %", "H10 grid falls"], row, "run directories of radial --case B3")


if __name__ == "__main__":
    main()
