"""When a radial case's centre polygons turn inside out (decisions #26; BENCHMARKS.md "Where B3's
injected volume goes").

    .venv/bin/python benchmarks/b3_inside_out.py [--case B3]

Runs the paper-size case on the shipped packing to breakthrough (B3: 3-7 minutes on one core) and
counts, after every accepted step, the domains whose centre polygon has a negative signed area on
the current grain positions (the fixed topology folded over), the floored domains and their
total negative area. Prints the first inside-out step and the counts at 15 times of the run.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=tuple(RADIAL_CASES), default="B3")
    args = parser.parse_args()
    sc = build_radial_scenario(RADIAL_CASES[args.case])
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    rows = []  # t, p_in, inside-out polygons, floored domains, their negative area, invaded domains

    def count(m, state):
        polygon = m.geometry.volumes(m.positions)
        rows.append((state.t, m.record.rows[-1][2], (polygon < 0).sum(), m.floored.sum(),
                     np.minimum(polygon, 0.0).sum(), state.invaded.sum()))

    state, rec = model.run(progress=count)
    rows = np.array(rows, float)
    print(f"{args.case}: {rec.status} at {state.t:.4g} s after {len(rows)} steps")
    if (rows[:, 2] > 0).any():
        k = int(np.argmax(rows[:, 2] > 0))
        print(f"first inside-out polygon at {rows[k, 0]:.3g} s (step {k + 1}), p_in {rows[k, 1] / 1e6:.3g} MPa, "
              f"{int(rows[k, 5])} domains invaded")
    for k in np.linspace(0, len(rows) - 1, 15).astype(int):
        t, p, inside_out, floored, negative, invaded = rows[k]
        print(f"t {t:.3g} s  p_in {p / 1e6:.3g} MPa  inside-out {int(inside_out)}  floored {int(floored)}  "
              f"negative area {negative:.3g} m^2  invaded {int(invaded)}")


if __name__ == "__main__":
    main()
