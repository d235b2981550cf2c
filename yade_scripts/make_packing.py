"""Regenerate the default Lenormand packing from inside YADE.

    yade -n -x yade_scripts/make_packing.py            # writes lenormand_packing.npz here
The same as `make packing` / `python -m hmdem.dem.packing --out FILE`.
"""
import sys

from hmdem.dem.packing import main

sys.exit(main(["--out", "lenormand_packing.npz"]))
