"""The sweep manifest: what the sweep is and where each run stands, in ``manifest.json``.

Every write goes to a temporary file that is then renamed over the old one, so a kill at any
moment leaves either the previous or the new manifest. The run directories are the truth about
which runs finished (a run directory only appears, atomically, when its run is complete); the
manifest adds what they cannot say: failures, their error text and the number of attempts.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from ..rundir import write_text_atomic
from .grid import SweepPoint
from .runner import read_summary

PENDING, DONE, FAILED = "pending", "done", "failed"


def planned_runs(root: Path) -> list[tuple[float, float]] | None:
    """The runs a sweep directory's manifest plans, as (log M, log Ca*), one per seed; None
    without a readable manifest (a yade-batch directory), for ``collect``'s diagram."""
    try:
        runs = json.loads((Path(root) / "manifest.json").read_text())["runs"].values()
        return [(float(r["log_m"]), float(r["log_ca_star"])) for r in runs]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


class Manifest:
    """``manifest.json`` of a sweep directory: the grid (``spec``) and one record per run."""

    def __init__(self, root: Path, spec: dict, points: list[SweepPoint]):
        self.root = Path(root)
        self.path = self.root / "manifest.json"
        self.spec = spec
        self.points = {p.run_id: p for p in points}
        self.runs = {p.run_id: {**p.as_dict(), "status": PENDING, "attempts": 0, "error": None} for p in points}

    @classmethod
    def open(cls, root: Path, spec: dict, points: list[SweepPoint]) -> "Manifest":
        """A new manifest, or the existing one of ``root`` if it describes the same sweep
        (ValueError otherwise); either way reconciled with the run directories on disk."""
        m = cls(root, spec, points)
        if m.path.is_file():
            old = json.loads(m.path.read_text())
            old_spec = m.upgraded(old.get("spec", {}))
            if old_spec != spec:
                differ = ", ".join(f"{key} {old_spec.get(key)} there, {spec.get(key)} here"
                                   for key in sorted(old_spec.keys() | spec.keys()) if old_spec.get(key) != spec.get(key))
                raise ValueError(f"{str(root)!r} holds a different sweep ({differ}); use a new --out, "
                                 f"or the same grid, seeds and packing to resume it")
            for run_id, record in old.get("runs", {}).items():
                if run_id in m.runs:
                    m.runs[run_id].update(status=record["status"], attempts=record["attempts"],
                                          error=record["error"])
        m.root.mkdir(parents=True, exist_ok=True)
        m.reconcile()
        return m

    def upgraded(self, old_spec: dict) -> dict:
        """A spec written before the packing was recorded by its bytes (it named the file, or
        None for the shipped one) as this version writes it: with this sweep's packing SHA-256
        when every finished run's config.toml names those bytes, so that the sweep resumes."""
        if "packing_sha256" in old_spec or "packing" not in old_spec:
            return old_spec
        runs = [self.run_dir(r) / "config.toml" for r in self.runs]
        recorded = {tomllib.loads(c.read_text()).get("packing", {}).get("sha256") for c in runs if c.is_file()}
        sha = self.spec.get("packing_sha256")
        rest = {k: v for k, v in old_spec.items() if k != "packing"}
        return {**rest, "packing_sha256": sha if recorded <= {sha} else f"other bytes ({len(recorded)} files)"}

    def run_dir(self, run_id: str) -> Path:
        return self.root / "runs" / run_id

    def reconcile(self) -> None:
        """Done exactly when the run directory holds a finished run."""
        for run_id, record in self.runs.items():
            finished = read_summary(self.run_dir(run_id)) is not None
            if finished:  # at least the attempt that wrote it (Ctrl-C may land before it was counted)
                record.update(status=DONE, error=None, attempts=max(record["attempts"], 1))
            elif record["status"] == DONE:
                record["status"] = PENDING
        self.save()

    def todo(self) -> list[SweepPoint]:
        """Pending and failed runs (failed ones are retried)."""
        return [self.points[r] for r, rec in self.runs.items() if rec["status"] != DONE]

    def finished(self, run_id: str, error: str | None) -> None:
        """A run came back, done or with ``error``: one attempt more (a run submitted but stopped
        by Ctrl-C before it came back is not one; a new-user pass saw 4 for runs that ran once)."""
        record = self.runs[run_id]
        record.update(status=FAILED if error else DONE, error=error, attempts=record["attempts"] + 1)
        self.save()

    def counts(self) -> dict:
        out = {PENDING: 0, DONE: 0, FAILED: 0}
        for rec in self.runs.values():
            out[rec["status"]] += 1
        return out

    def save(self) -> None:
        write_text_atomic(self.path, json.dumps({"spec": self.spec, "runs": self.runs}, indent=1) + "\n")
