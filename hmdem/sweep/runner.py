"""One sweep point = one ``python -m hmdem.hele_shaw linear`` run, in-process.

The base case is Lenormand's Case 2 (``sd``: glucose solution into oil, both with K = 2000 MPa,
gamma = 14.5 dyn/cm, theta = 180 deg, drainage): M changes the invading viscosity (the
defending oil keeps 5.6 cP) and Ca* the rate (Eq. 24), so the two axes of the diagram are the
only things that change (decisions.md #28). The nominal step follows the rate (``hmdem.scenario.build_scenario``).
"""

from __future__ import annotations

import io
import json
import shlex
import shutil
import tomllib
from contextlib import redirect_stdout
from pathlib import Path

from .grid import SweepPoint

BASE_CASE = "sd"
INCOMPLETE = ("interrupted", "diverged")  # statuses of a run directory that does not count as done


def cli_arguments(point: SweepPoint, out: Path, packing: str | None = None) -> list[str]:
    """The single-run command line of a point (also stored in its config.toml)."""
    args = ["linear", "--case", BASE_CASE, "--viscosity-ratio", repr(10.0 ** point.log_m),
            "--ca-star", repr(10.0 ** point.log_ca_star), "--seed", str(point.seed), "--out", str(out), "--quiet"]
    if packing:
        args += ["--packing", str(packing)]
    return args


def read_summary(run_dir: Path, finished_only: bool = True) -> dict | None:
    """summary.json of a run directory; None if absent or (``finished_only``) the run was
    interrupted or stopped by a failed solve."""
    path = Path(run_dir) / "summary.json"
    if not path.is_file():
        return None
    summary = json.loads(path.read_text())
    return None if finished_only and summary.get("status") in INCOMPLETE else summary


class RunFailed(RuntimeError):
    """A point's run that did not finish; ``exit_status`` is the run's own (130/143: interrupted)."""

    def __init__(self, message: str, exit_status: int = 1):  # the default: rebuilt by pickle from the message
        super().__init__(message)
        self.exit_status = exit_status


class NotThisPoint(ValueError):
    """``out`` exists and is not a run directory of the point asked for."""


def point_arguments(argv: list[str]) -> tuple[list[str], str | None]:
    """A run's arguments without --out, --quiet and --packing, which do not make it another
    point's, and the --packing value (None without)."""
    kept, packing = [], None
    words = iter(argv)
    for word in words:
        if word == "--packing":
            packing = next(words, None)
        elif word == "--out":
            next(words, None)
        elif word != "--quiet":
            kept.append(word)
    return kept, packing


def recorded_run(run_dir: Path) -> tuple[list[str], str | None] | None:
    """(the recorded command's arguments without --out, --quiet and --packing; the packing's
    SHA-256 or None) of a run directory, from its config.toml; None if it has none or it is
    unreadable. A run written before config.toml had [packing] is hashed from the file its
    command names (the shipped one without --packing), if that file is still there."""
    from ..cases import default_packing_path
    from ..report import packing_record

    try:
        config = tomllib.loads((Path(run_dir) / "config.toml").read_text())
        kept, packing = point_arguments(shlex.split(config["run"]["command"])[3:])  # after python -m hmdem.hele_shaw
    except (OSError, ValueError, KeyError):
        return None
    if "packing" in config:
        return kept, config["packing"].get("sha256")
    path = Path(packing) if packing else Path(default_packing_path())
    return kept, packing_record(path)["sha256"] if path.is_file() else None


def check_out_is_this_point(out: Path, point: SweepPoint, packing: str | None) -> None:
    """A :class:`NotThisPoint` unless ``out`` holds a run of ``point`` on ``packing``'s bytes (the
    shipped packing for None), made with the point's own command: a run there of another point,
    or of this one with other options (--max-steps, --dt, ...), or any other directory, is not
    taken as this point's result, nor removed to make room (found in a new-user pass: the YADE
    script reported a cf1 run as its point's, and wiped a directory of other files)."""
    from ..cases import default_packing_path
    from ..report import packing_record

    expected = point_arguments(cli_arguments(point, out))[0]
    sha256 = packing_record(packing or default_packing_path())["sha256"]
    if recorded_run(out) != (expected, sha256):
        raise NotThisPoint(f"--out: {str(out)!r} exists and is not a run of point {point.run_id} on this packing; "
                           "choose a new run directory")


def run_point(point: SweepPoint, out: Path, packing: str | None = None, recorded_as: list[str] | None = None,
              recorded_packing: str | None = None, shown_as: str | None = None) -> dict:
    """Run one point into ``out`` (written atomically by the run itself); its summary.

    ``recorded_as``: the command line config.toml records (default: the one run here);
    ``recorded_packing``: the packing path its [packing] names (default: ``packing``'s), for a
    worker that reads a scratch copy; ``shown_as``: the run directory its warnings name (default
    ``out``), for a worker's scratch copy. An existing ``out`` must be a run of this point
    (:func:`check_out_is_this_point`): a finished one is its result, one left by an interrupted
    or diverged run is replaced. Raises on any failure; the sweep records the error text."""
    from ..cli import read_packing
    from ..hele_shaw import build_parser, run_linear

    out = Path(out)
    if packing is not None:  # a missing or unreadable file is named before an out is checked against it
        read_packing(packing)
    if out.exists():
        check_out_is_this_point(out, point, packing)
        finished = read_summary(out)
        if finished is not None:
            return finished
        shutil.rmtree(out)
    argv = cli_arguments(point, out, packing)
    args = build_parser().parse_args(argv)
    args.argv = recorded_as or argv  # config.toml's command (hele_shaw.recorded_argv)
    args.packing_recorded = recorded_packing
    # its warnings name the directory the sweep keeps, not a worker's scratch copy (a new-user pass)
    args.shown_out = shown_as
    with redirect_stdout(io.StringIO()):  # the run's two result lines; the sweep reports instead
        code = run_linear(args)
    summary = read_summary(out, finished_only=False)
    if code != 0 or summary is None or summary.get("status") in INCOMPLETE:
        reason = (summary or {}).get("status_message")
        raise RunFailed(f"run {point.run_id} ended with exit status {code}" + (f": {reason}" if reason else ""),
                        code or 1)
    return summary
