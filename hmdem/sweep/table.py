"""``sweep.csv``: one row per run directory under a sweep (or ``yade-batch``) directory, plus
one per failed run of the manifest, with its error text."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import tomllib
from pathlib import Path

from ..flow.diagnostics import regime_at_breakthrough
from ..rundir import UNSAVED, write_text_atomic
from .runner import INCOMPLETE

COLUMNS = ["run", "log_m", "log_ca_star", "viscosity_ratio", "ca_star", "ca", "seed", "status", "regime",
           "fractal_dimension", "breakthrough_time_s", "breakthrough_saturation", "peak_injection_pressure_pa",
           "peak_compression",
           "injection_energy_j", "dissipated_energy_j", "steps", "wall_time_s", "packing_sha256", "error"]
# columns that differ between two executions of the same runs
TIMING_COLUMNS = ("wall_time_s",)
# statuses of rows that carry no result: no run, a run stopped by a failed solve, or by Ctrl-C
NO_RESULT = ("failed", *INCOMPLETE)


def run_directories(root: Path) -> list[Path]:
    """Directories under ``root`` holding a run (summary.json and config.toml); hidden ones,
    e.g. partial writes, and runs kept aside because another process took their name
    (:class:`~hmdem.rundir.RunDirectoryTaken`) are skipped."""
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".") and UNSAVED not in d)
        if "summary.json" in filenames and "config.toml" in filenames:
            found.append(Path(dirpath))
            dirnames[:] = []
    return found


def lenormand_run(run_dir: Path) -> bool:
    """Whether a run directory holds a point of Lenormand's diagram: a two-phase run of the
    linear cell (``hele_shaw linear``, geometry "lenormand"). Radial, lattice and single-phase
    runs, and directories whose files do not parse, are not."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        config = tomllib.loads((run_dir / "config.toml").read_text())
        return (config["case"]["geometry"] == "lenormand" and summary["regime"] != "single phase"
                and all(k in summary for k in ("ca_star", "viscosity_ratio")))
    except (OSError, ValueError, KeyError, TypeError):
        return False


def other_run_directories(root: Path) -> list[Path]:
    """Run directories under ``root`` that :func:`collect` leaves out (not Lenormand points)."""
    return [d for d in run_directories(root) if not lenormand_run(d)]


def run_row(root: Path, run_dir: Path) -> dict:
    """One sweep.csv row from a run directory (Ca = Ca* a_mean / L, seed 004 Eq. 24)."""
    summary = json.loads((run_dir / "summary.json").read_text())
    config = tomllib.loads((run_dir / "config.toml").read_text())
    case = config.get("case", {})
    ca_star, m = summary["ca_star"], summary["viscosity_ratio"]
    ca = ca_star * case["mean_aperture_m"] / case["length_m"] if "length_m" in case else math.nan
    row = {k: summary.get(k) for k in COLUMNS if k in summary}
    # a run directory written before decisions #76 may carry a regime read before breakthrough
    row["regime"] = regime_at_breakthrough(summary.get("status"), summary.get("regime"))
    # log10 rounded to 1e-9: 10 ** 0.25 read back gives 0.24999999999999997, not the grid's 0.25
    row.update(run=run_dir.relative_to(root).as_posix(), log_m=round(math.log10(m), 9),
               log_ca_star=round(math.log10(ca_star), 9),
               viscosity_ratio=m, ca_star=ca_star, ca=ca, seed=config.get("run", {}).get("seed"),
               packing_sha256=config.get("packing", {}).get("sha256"),
               error=summary.get("status_message", "") if summary.get("status") == "diverged" else "")
    return row


def failed_rows(root: Path) -> list[dict]:
    """Rows of the manifest's failed runs (no run directory), with the error text."""
    path = Path(root) / "manifest.json"
    if not path.is_file():
        return []
    rows = []
    for run_id, rec in json.loads(path.read_text())["runs"].items():
        if rec["status"] == "failed":
            rows.append({"run": f"runs/{run_id}", "log_m": rec["log_m"], "log_ca_star": rec["log_ca_star"],
                         "viscosity_ratio": 10.0 ** rec["log_m"], "ca_star": 10.0 ** rec["log_ca_star"],
                         "seed": rec["seed"], "status": "failed", "error": rec["error"]})
    return rows


def collect(root: Path) -> list[dict]:
    """All rows of a sweep directory, ordered by M, Ca*, seed: its Lenormand runs and the
    manifest's failed points."""
    root = Path(root)
    rows = [run_row(root, d) for d in run_directories(root) if lenormand_run(d)]
    by_run = {r["run"]: r for r in rows}
    for failed in failed_rows(root):
        if failed["run"] in by_run:  # a directory left by a run stopped on a failed solve
            by_run[failed["run"]]["error"] = failed["error"]
        else:
            rows.append(failed)
    return sorted(rows, key=lambda r: (r["log_m"], r["log_ca_star"], r.get("seed") or 0, r["run"]))


def mixed_runs(rows: list[dict]) -> str:
    """What makes ``rows`` more than one sweep, or "": a point (M, Ca*, seed) run more than once,
    or runs on different packings (a new-user pass: ``collect runs`` merged five sweeps, one
    point four times, and drew them as seeds of one)."""
    seen: dict[tuple, str] = {}
    for row in rows:
        key = (row["log_m"], row["log_ca_star"], row.get("seed"))
        if key in seen:
            return (f"log M {key[0]:g}, log Ca* {key[1]:g}, seed {key[2]} is in both {seen[key]} and {row['run']}")
        seen[key] = row["run"]
    packings = {row.get("packing_sha256") for row in rows} - {None}
    return f"the runs are on {len(packings)} different packings" if len(packings) > 1 else ""


def format_value(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def write_csv(path: Path, rows: list[dict]) -> None:
    """sweep.csv, written through a temporary file and a rename."""
    buffer = io.StringIO()
    w = csv.writer(buffer, lineterminator="\n")
    w.writerow(COLUMNS)
    for row in rows:
        w.writerow([format_value(row.get(k)) for k in COLUMNS])
    write_text_atomic(path, buffer.getvalue())
