"""Pipe flow resistance inside B3's fractures against their sides over a run (digest H8).

    .venv/bin/python -m hmdem.hele_shaw radial --case B3 --snapshots 20 --out runs/b3
    .venv/bin/python benchmarks/fracture_resistance.py runs/b3

Seed 004 (§4.2, Fig. 16e) reads B3 early in the run: "the lowest pipe flow resistance inside
the fracturing zone is only 2.5 GPa s/m2, merely 2 % of the lowest resistance at the sides".
For each ParaView snapshot of a radial run this prints the lowest R_s (Eq. 27 at the invading
viscosity) of the fractures the fluid has reached away from the port and of their sides, and
the ratio (``hmdem.coupling.output.fracture_resistance_series``, decisions #67).
"""
import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.output import GPA, fracture_resistance_series  # noqa: E402
from md_table import header  # noqa: E402


def main(run: Path) -> None:
    print(header("t [s]", "fractures reached by the fluid", "lowest R_s in them [GPa s/m2]", "at their sides",
                 "ratio"))
    for t, reached, fracture, side in fracture_resistance_series(run):
        print(f"| {t:.3g} | {reached} | {fracture / GPA:.3g} | {side / GPA:.3g} | {fracture / side:.2g} |")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a radial run directory with ParaView snapshots (--snapshots N)")
    main(parser.parse_args().run)
