"""Plane-shear liquid migration (seed 002 §6.2), from YADE's own launchers.

    yade -n -x yade_scripts/wet_shear.py                    # A = 0.01 R^3 into runs/shear-<time>
    yade-batch yade_scripts/wet_shear.table yade_scripts/wet_shear.py

Parameters (``readParamsFromTable``; defaults in brackets): amplitude [0.01, A in R^3],
cohesionNumber [0], strain [2], n [800], seed [0], liquidEvery [1], flags ['' = none; any
further flags of the CLI, comma-separated, e.g. '--sigma0=6,--redistribution=mani': YADE splits
a table's columns at blanks and allows no quoting], out [runs/batch/<job description>, or a
fresh runs/shear-<time> outside a batch]. The run is ``python -m hmdem.wet shear`` with those
flags (and --quiet in a batch, whose log is a file), and its run directory is the same;
config.toml's [launcher] names the YADE launcher. As in radial_injection.py, the repository
root goes first on sys.path and the project venv's pure-Python packages last.
"""
import os
import sys
from pathlib import Path

# under `yade -x`, __file__ is the launcher; sys.argv[0] is this script
ROOT = Path(sys.argv[0]).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.extend(str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")))

from hmdem.cli import TableColumnsOnStderr, read_yade_table, yade_script_arguments  # noqa: E402

SCRIPT = "yade_scripts/wet_shear.py"
yade_script_arguments(SCRIPT, __doc__, sys.argv[1:])  # before YADE's scene and any run

from yade import O, utils  # noqa: E402

read_yade_table(SCRIPT, utils.readParamsFromTable, amplitude=0.01, cohesionNumber=0.0, strain=2.0, n=800, seed=0,
                liquidEvery=1, flags="", out="")
from yade.params import table  # noqa: E402

from hmdem.wet.__main__ import main  # noqa: E402

description = O.tags["description"] if "description" in O.tags.keys() else ""
argv = []
columns = {}  # flag -> the table column that set it, for the command's messages
for column, flag in (("amplitude", "--amplitude"), ("cohesionNumber", "--cohesion-number"), ("strain", "--strain"),
                     ("n", "--n"), ("seed", "--seed"), ("liquidEvery", "--liquid-every")):
    value = getattr(table, column)
    argv += [flag, str(int(value)) if column in ("n", "seed", "liquidEvery") and float(value).is_integer()
             else str(value)]
    columns[flag] = column
if description:  # a batch job's bar would fill its log file; `yade -n -x` shows it on the terminal
    argv.append("--quiet")
if table.flags:
    if not isinstance(table.flags, str):
        print(f"{SCRIPT}: table: flags must be a quoted string of comma-separated CLI flags, got {table.flags!r}",
              file=sys.stderr)
        sys.exit(2)
    argv += [flag for flag in table.flags.split(",") if flag]
if table.out:
    argv += ["--out", table.out]
    columns["--out"] = "out"
elif description:
    argv += ["--out", f"runs/batch/{description}"]
batch = os.environ.get("YADE_BATCH", "")
launcher = (f"yade-batch {batch} ({description!r})" if description else "yade -n -x") + f" {SCRIPT}"
sys.stderr = TableColumnsOnStderr(sys.stderr, columns)  # an error names the column, as the user wrote it
sys.exit(main(["shear"] + argv, launcher=launcher))
