"""Command line of hmdem's sweeps.

    python -m hmdem.sweep lenormand [--log-m A:B:N] [--log-ca A:B:N] [--seeds K] [--workers W]
                                    [--scheduler ADDRESS] [--packing NPZ] [--out DIR] [--quiet]
    python -m hmdem.sweep collect DIR

``lenormand`` runs the linear Hele-Shaw model over a grid of log10 M and log10 Ca* with K
aperture seeds each; re-running it with the same ``--out`` resumes (finished runs are kept,
failed ones retried). ``collect`` writes sweep.csv and phase_diagram.png for the linear
two-phase runs under a directory, e.g. a ``yade-batch`` job of ``yade_scripts/hele_shaw_linear.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .. import __version__
from ..cases import CASES, default_packing_path
from ..cli import (InputError, OneLineParser, check_aperture_fits_grains, check_out_parent, dangling_link, dispatch,
                   interrupted_status, near_contacts_checked, positive_int, read_packing)
from .grid import LOG_CA_STAR_RANGE, LOG_M_RANGE

PROG = "python -m hmdem.sweep"
DEFAULT_LOG_M = "-5:2:5"
DEFAULT_LOG_CA = "-8:2:6"
# the manifest lists every run: 100,000 take ~4 s to plan and 17 MB (a million, 43 s and 175 MB)
MAX_RUNS = 100_000


class _Parser(OneLineParser):
    command = PROG


def axis_within(bounds: tuple[float, float]):
    """argparse type: a ``START:STOP:COUNT`` axis whose ends lie within ``bounds``."""

    def axis(text: str):
        from .grid import parse_axis

        try:
            return parse_axis(text, bounds)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return axis


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    len_ = sub.add_parser("lenormand", help="the Lenormand phase diagram: linear runs over (M, Ca*) and seeds")
    log_m, log_ca = axis_within(LOG_M_RANGE), axis_within(LOG_CA_STAR_RANGE)
    len_.add_argument("--log-m", type=log_m, default=log_m(DEFAULT_LOG_M),
                      help=f"log10 M = log10(eta_inv / eta_def) as START:STOP:COUNT, ends in "
                           f"[{LOG_M_RANGE[0]:g}, {LOG_M_RANGE[1]:g}] (default {DEFAULT_LOG_M})")
    len_.add_argument("--log-ca", type=log_ca, default=log_ca(DEFAULT_LOG_CA),
                      help=f"log10 Ca* (seed 004 Eq. 24) as START:STOP:COUNT, ends in "
                           f"[{LOG_CA_STAR_RANGE[0]:g}, {LOG_CA_STAR_RANGE[1]:g}] (default {DEFAULT_LOG_CA})")
    len_.add_argument("--seeds", type=positive_int, default=1, help="aperture seeds per point, 0..K-1 (default 1)")
    len_.add_argument("--workers", type=positive_int,
                      help="worker processes of the embedded Dask cluster (default: one per core; more are cut "
                           "to the core count, with a warning)")
    len_.add_argument("--scheduler", help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    len_.add_argument("--packing", type=Path, help="packing .npz (default: the shipped 65 mm packing)")
    len_.add_argument("--out", type=Path, help="sweep directory (default runs/lenormand-<time>); an existing "
                                              "sweep directory is resumed")
    len_.add_argument("--quiet", action="store_true", help="no progress bar")
    col = sub.add_parser("collect", help="sweep.csv and phase_diagram.png of the linear two-phase runs under a "
                                         "directory")
    col.add_argument("dir", type=Path, help="a sweep directory or a yade-batch output directory")
    return parser


def write_tables(root: Path, rows: list[dict] | None = None) -> list[dict]:
    """sweep.csv and phase_diagram.png of ``root`` (``rows``: already collected); the rows. A
    sweep directory's diagram marks the points its manifest plans that have not run."""
    from .boundaries import capillary_crossover
    from .manifest import planned_runs
    from .phase_diagram import plot_phase_diagram
    from .table import collect, write_csv

    rows = collect(root) if rows is None else rows
    write_csv(root / "sweep.csv", rows)
    finished = [root / r["run"] for r in rows if r["status"] != "failed"]
    # the crossover lines are drawn for the network of the first finished run (seed 0 first)
    crossover = capillary_crossover(finished[0]) if finished else None
    plot_phase_diagram(root / "phase_diagram.png", rows, crossover, planned_runs(root))
    return rows


def check_scheduler_address(address: str) -> None:
    """An :class:`InputError` unless ``address`` reads as a Dask scheduler's (e.g. tcp://host:8786)."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        protocol, location = parse_address(address)
        get_backend(protocol)
        if protocol in ("tcp", "tls"):
            parse_host_port(location)
    except ValueError as exc:
        raise InputError(f"--scheduler: {exc}; expected an address such as tcp://host:8786") from None


def run_lenormand(args) -> int:
    from ..cli import worker_count
    from ..report import packing_record
    from .execute import run_sweep
    from .grid import lenormand_points, lenormand_spec
    from .manifest import DONE, FAILED, Manifest
    from .runner import BASE_CASE
    from ..scenario import linear_network

    runs = args.log_m.count * args.log_ca.count * args.seeds
    if runs > MAX_RUNS:
        raise InputError(f"--log-m, --log-ca, --seeds: must give at most {MAX_RUNS:,} runs (the manifest lists "
                         f"each), got {runs:,}")
    if args.packing is not None:  # a missing, unreadable or misfit file is one line, not a failure per point
        packing = read_packing(args.packing)
        check_aperture_fits_grains(CASES[BASE_CASE].mean_aperture, packing.radii, False, can_set=False)
        with near_contacts_checked():  # and one no network can be built on (a new-user pass: 12 failed points)
            linear_network(packing, CASES[BASE_CASE].contact_gap)
    if args.scheduler is not None:
        check_scheduler_address(args.scheduler)
    out = args.out or Path("runs") / f"lenormand-{time.strftime('%Y%m%d-%H%M%S')}"
    if dangling_link(out):
        raise InputError(f"--out: {str(out)!r} is a symbolic link to nothing; choose a new sweep directory")
    if not out.exists():
        check_out_parent(out)
    elif not out.is_dir():
        raise InputError(f"--out: {str(out)!r} is a file, not a sweep directory")
    elif not (out / "manifest.json").is_file() and any(out.iterdir()):
        raise InputError(f"--out: {str(out)!r} exists and is not a sweep directory; choose a new one")
    spec = lenormand_spec(args.log_m, args.log_ca, args.seeds,
                          packing_record(args.packing or default_packing_path())["sha256"])
    points = lenormand_points(args.log_m, args.log_ca, args.seeds)
    try:
        manifest = Manifest.open(out, spec, points)
    except ValueError as exc:
        raise InputError(f"--out: {exc}") from None
    if args.scheduler is not None and args.workers is not None:
        print(f"{PROG}: warning: --workers {args.workers} is not used with --scheduler: the cluster's own "
              f"workers run the points", file=sys.stderr)
    if args.scheduler is None and args.workers is not None:
        # 100,000 workers broke the embedded cluster's start with a traceback; a command recorded on
        # a larger machine still replays (the runs do not depend on the count), as lga's does
        args.workers = worker_count(args.workers, PROG)
    print(f"sweep directory: {out} ({len(points)} run{'' if len(points) == 1 else 's'}, {len(manifest.todo())} to do)",
          file=sys.stderr)
    interrupted = False
    try:
        counts = run_sweep(manifest, args.packing, args.workers, args.scheduler, progress=not args.quiet)
    except OSError as exc:  # the scheduler cannot be reached: the sweep directory stays, resumable
        if args.scheduler is None:
            raise
        print(f"{PROG}: --scheduler: {exc}; the sweep directory {str(out)!r} is kept for a re-run", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        interrupted = True
        manifest.reconcile()
        counts = manifest.counts()
    rows = write_tables(out)
    print(f"{counts[DONE]} done, {counts[FAILED]} failed, {len(points) - counts[DONE] - counts[FAILED]} not run; "
          f"{len(rows)} rows in {out / 'sweep.csv'}")
    if interrupted:
        print(f"{PROG}: interrupted; run the same command again to finish the sweep", file=sys.stderr)
        return interrupted_status()
    return 1 if counts[FAILED] else 0


def run_collect(args) -> int:
    if not args.dir.is_dir():
        raise InputError(f"dir: {str(args.dir)!r} is a file, not a directory" if args.dir.exists()
                         else f"dir: no such directory {str(args.dir)!r}")
    if (args.dir / "summary.json").is_file():  # its tables would land among one run's files
        raise InputError(f"dir: {str(args.dir)!r} is a run directory; give the directory that holds the runs")
    from .table import collect, mixed_runs, other_run_directories

    rows = collect(args.dir)
    mixed = mixed_runs(rows)
    if mixed:
        print(f"{PROG}: warning: {mixed}; the diagram reads every run as a seed of one sweep (collect one "
              f"sweep directory at a time)", file=sys.stderr)
    others = other_run_directories(args.dir)
    named = ", ".join(str(d) for d in others[:3]) + (", ..." if len(others) > 3 else "")
    skipped = (f"; {len(others)} other run director{'y' if len(others) == 1 else 'ies'} left out ({named}: "
               "radial, lattice, single-phase or unreadable)") if others else ""
    if not rows:
        raise InputError(f"dir: no run directories of linear two-phase (Lenormand) runs under {str(args.dir)!r}"
                         + skipped)
    if others:
        print(f"{PROG}: note: {len(rows)} Lenormand runs collected" + skipped, file=sys.stderr)
    write_tables(args.dir, rows)
    print(f"{len(rows)} run{'' if len(rows) == 1 else 's'} -> {args.dir / 'sweep.csv'}, {args.dir / 'phase_diagram.png'}")
    return 0


def join_axis_values(argv: list[str]) -> list[str]:
    """``--log-m -5:2:5`` -> ``--log-m=-5:2:5``: argparse would take a value starting with '-'
    (a negative START) for an option."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] in ("--log-m", "--log-ca") and i + 1 < len(argv):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(join_axis_values(list(sys.argv[1:] if argv is None else argv)))
    return dispatch(PROG, parser, args, {"lenormand": run_lenormand, "collect": run_collect})


if __name__ == "__main__":
    raise SystemExit(main())
