"""Regenerate the default Lenormand packing from inside YADE.

    yade -n -x yade_scripts/make_packing.py [OUT.npz [OPTIONS]]   # default: lenormand_packing.npz here

The same as `make packing` / `python -m hmdem.dem.packing --out FILE [OPTIONS]` (e.g.
--overwrite, --seed 3; an existing OUT.npz is kept unless --overwrite). The yade launcher runs
Debian's Python, so the repository root is put on sys.path to find hmdem.
"""
import sys
from pathlib import Path

# under `yade -x`, __file__ is the launcher; sys.argv[0] is this script
sys.path.insert(0, str(Path(sys.argv[0]).resolve().parent.parent))

from hmdem.dem.packing import main  # noqa: E402

# OUT is optional: options alone (e.g. --seed 3) go to the default file
named = len(sys.argv) > 1 and not sys.argv[1].startswith("-")
out = sys.argv[1] if named else "lenormand_packing.npz"
code = main(["--out", out, *sys.argv[2 if named else 1:]])
sys.exit(code)
