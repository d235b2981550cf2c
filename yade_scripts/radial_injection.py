"""Huang radial injection with movable grains (issue 3), from YADE's own launchers.

    yade -n -x yade_scripts/radial_injection.py                 # A1 into runs/A1-<time>
    yade-batch yade_scripts/huang.table yade_scripts/radial_injection.py

Parameters (``readParamsFromTable``; defaults in brackets): case [A1], oneWay [0], maxSteps
[0 = to breakthrough], dt [0 = the case's], viscosityRatio [0 = the case's M], caStar [0 = the
case's Ca*], grainDensity [0 = 2650 kg/m^3, Table 2], fixedPort
[0; 1 holds the injection domain's grains], friction [-1 = 0.6, Table 2], stiffnessRatio
[0 = 1, Table 2], boundary ['fixed'; 'loaded' for pistons at the confining stress, decisions #86],
packing ['' = the shipped sample; a path in quotes, its k_n comes with it], flags ['' = none;
any further flags of the CLI, comma-separated, e.g. '--damping=0.3,--snapshots=40': YADE splits
a table's columns at blanks and allows no quoting],
out [runs/batch/<job description>, or a fresh runs/<case>-<time> outside a batch]. The run is
``python -m hmdem.hele_shaw radial`` with those flags (and --quiet in a batch, whose log is a
file), and its run directory is the same; config.toml's [launcher] names the YADE launcher. The yade
launcher runs Debian's Python, so the repository root goes on sys.path first and the project
venv's pure-Python packages (meshio, tqdm) last, behind Debian's numpy that YADE has already
loaded (1.24 on Debian 12, the venv's is 2.x; config.toml records which). The model is the same,
the round-off is not, and B3's fracturing amplifies it: 300 steps of a two-way B3 opened 588
contacts under yade-batch and 598 from the CLI.
"""
import os
import sys
from pathlib import Path

# under `yade -x`, __file__ is the launcher; sys.argv[0] is this script
ROOT = Path(sys.argv[0]).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.extend(str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")))

from hmdem.cli import TableColumnsOnStderr, read_yade_table, yade_script_arguments  # noqa: E402

yade_script_arguments("yade_scripts/radial_injection.py", __doc__, sys.argv[1:])  # before YADE's scene and any run

from yade import O, utils  # noqa: E402

read_yade_table("yade_scripts/radial_injection.py", utils.readParamsFromTable, case="A1", oneWay=0, maxSteps=0,
                dt=0.0, viscosityRatio=0.0, caStar=0.0, grainDensity=0.0, fixedPort=0, friction=-1.0,
                stiffnessRatio=0.0, boundary="fixed", packing="", flags="", out="")
from yade.params import table  # noqa: E402

from hmdem.hele_shaw import main  # noqa: E402

description = O.tags["description"] if "description" in O.tags.keys() else ""
argv = []
columns = {}  # flag -> the table column that set it, for the command's messages


def pass_on(column, flag, *values):
    argv.extend((flag, *values))
    columns[flag] = column


pass_on("case", "--case", table.case)
if description:  # a batch job's bar would fill its log file; `yade -n -x` shows it on the terminal
    argv.append("--quiet")
if table.oneWay:
    pass_on("oneWay", "--one-way")
if table.maxSteps:  # a table may write 2e4; 2.5 goes on to the CLI's check
    steps = table.maxSteps
    pass_on("maxSteps", "--max-steps", str(int(steps)) if float(steps).is_integer() else str(steps))
# columns whose 0 means "the case's own value"; the CLI checks the others
for column, flag in (("dt", "--dt"), ("viscosityRatio", "--viscosity-ratio"), ("caStar", "--ca-star"),
                     ("grainDensity", "--grain-density"), ("stiffnessRatio", "--stiffness-ratio")):
    if getattr(table, column):
        pass_on(column, flag, str(getattr(table, column)))
if table.fixedPort:
    pass_on("fixedPort", "--fixed-port")
if table.friction != -1:  # 0 is a valid coefficient, so "unset" is -1; other values go to the CLI's check
    pass_on("friction", "--friction", str(table.friction))
pass_on("boundary", "--boundary", table.boundary)  # the CLI checks the value
if table.packing:
    pass_on("packing", "--packing", table.packing)
if table.flags:  # 0 or '' for none, as the other columns' "unset"
    if not isinstance(table.flags, str):
        print(f"yade_scripts/radial_injection.py: table: flags must be a quoted string of comma-separated CLI "
              f"flags, got {table.flags!r}", file=sys.stderr)
        sys.exit(2)
    given = [flag for flag in table.flags.split(",") if flag]  # the CLI checks each (a repeated flag: the last)
    argv += given
    for flag in given:  # a flag written there is named as written
        columns.pop(flag.split("=", 1)[0], None)
if table.out:
    pass_on("out", "--out", table.out)
elif description:  # the batch's own place: no column to name
    argv += ["--out", f"runs/batch/{description}"]
# yade-batch starts a job with YADE_BATCH=<table>:<line>, which names the row that set its columns
batch = os.environ.get("YADE_BATCH", "")
launcher = (f"yade-batch {batch} ({description!r})" if description else "yade -n -x") + " yade_scripts/radial_injection.py"
sys.stderr = TableColumnsOnStderr(sys.stderr, columns)  # an error names the column, as the user wrote it
sys.exit(main(["radial"] + argv, launcher=launcher))
