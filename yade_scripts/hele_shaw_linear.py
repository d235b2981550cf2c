"""One point of the Lenormand sweep (issue 4) from YADE's own launchers.

    yade -n -x yade_scripts/hele_shaw_linear.py                  # one point: log M 2, log Ca* 1
    yade-batch yade_scripts/lenormand.table yade_scripts/hele_shaw_linear.py
    python -m hmdem.sweep collect runs/lenormand-batch           # sweep.csv, phase_diagram.png

Parameters (``readParamsFromTable``; defaults in brackets): logM [2] = log10(eta_inv / eta_def)
in [-6, 6], logCa [1] = log10 Ca* in [-10, 4] (the sweep's bounds), seed [0] (aperture field),
packing [shipped 65 mm packing], out [runs/lenormand-batch/<run id>]. An out that holds this
point's finished run (same M, Ca*, seed and packing bytes) is its result; one of an interrupted
run is run again; any other existing directory is refused. The run is the one
``python -m hmdem.sweep lenormand`` makes for that point (``python -m hmdem.hele_shaw linear --case sd --viscosity-ratio ...``), in the
same run-directory layout. The yade launcher runs Debian's Python, so the repository root goes
on sys.path first and the project venv's pure-Python packages last, behind Debian's numpy
(config.toml records which numpy ran: round-off can differ from the venv's).
"""
import sys
from pathlib import Path

# under `yade -x`, __file__ is the launcher; sys.argv[0] is this script
ROOT = Path(sys.argv[0]).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.extend(str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")))

from hmdem.cli import InputError, read_yade_table, sigterm_as_interrupt, yade_script_arguments  # noqa: E402

yade_script_arguments("yade_scripts/hele_shaw_linear.py", __doc__, sys.argv[1:])  # before YADE's scene and any run

from yade import utils  # noqa: E402

read_yade_table("yade_scripts/hele_shaw_linear.py", utils.readParamsFromTable, logM=2.0, logCa=1.0, seed=0,
                packing="", out="")
from yade.params import table  # noqa: E402

from hmdem.sweep.grid import LOG_CA_STAR_RANGE, LOG_M_RANGE, SweepPoint  # noqa: E402
from hmdem.report import dimension_note  # noqa: E402
from hmdem.sweep.runner import NotThisPoint, RunFailed, read_summary, run_point  # noqa: E402

for column, (low, high) in (("logM", LOG_M_RANGE), ("logCa", LOG_CA_STAR_RANGE)):  # the sweep's own bounds
    value = getattr(table, column)
    if isinstance(value, str) or not low <= float(value) <= high:
        print(f"yade_scripts/hele_shaw_linear.py: table: {column} must be a number in [{low:g}, {high:g}], got "
              f"{value!r}", file=sys.stderr)
        sys.exit(2)
seed = table.seed  # an aperture field's seed, stored as a 64-bit integer (the CLI's --seed)
if isinstance(seed, (str, bool)) or not float(seed).is_integer() or not 0 <= seed <= 2**63 - 1:
    print(f"yade_scripts/hele_shaw_linear.py: table: seed must be an integer in [0, 2**63 - 1], got {seed!r}",
          file=sys.stderr)
    sys.exit(2)
point = SweepPoint(float(table.logM), float(table.logCa), int(seed))
out = Path(table.out or f"runs/lenormand-batch/{point.run_id}")
try:  # a finished run there is taken as the point's result (run_point checks it is this point's)
    earlier = read_summary(out)
except (OSError, ValueError):  # not a readable run: run_point refuses it in one line
    earlier = None
try:
    with sigterm_as_interrupt():  # a batch system's SIGTERM writes the run as Ctrl-C does
        summary = run_point(point, out, table.packing or None)
except RunFailed as exc:  # one line and the run's own exit status (yade-batch logs 130 / 143)
    print(f"{exc}; run directory {out}", file=sys.stderr)
    sys.exit(exc.exit_status)
except (InputError, NotThisPoint) as exc:  # a packing the run refuses, an out of another run: one line, exit 2
    print(f"yade_scripts/hele_shaw_linear.py: {exc}", file=sys.stderr)
    sys.exit(2)
print(f"{point.run_id}: {'taken from its earlier run: ' if earlier is not None else ''}{summary['status']}, "
      f"{summary['regime']}, {dimension_note(summary['fractal_dimension'])}; "
      f"run directory {out}")
