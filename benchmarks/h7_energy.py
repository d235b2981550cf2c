"""One flow step's energy partition against seed 004 Figs. 15-16 (digest H7; decisions #69).

    .venv/bin/python benchmarks/h7_energy.py [--cases A3 B3] [--variants free rho10 rho100 fixed] [--t-max 2e-5]

The paper reads, per flow step, the injection energy p_in Q dt (Eq. 25), the residual energy
dE_f = dE_in - dE_v (Eq. 26) and the dissipated fraction: at the start, with the port still
holding air (A3: 5.1 kPa, 2.5 uJ, 28 %; B3: 3.4 kPa, 0.4 uJ), and as fracturing is about to occur
(A3: 393.4 kPa, 194.5 uJ, 86 %, dE_f 27.4 uJ, contacts of 0.16 and 0.17 N open; B3: 4076.1 kPa,
dE_f 134.7 uJ, contacts of 0.47 and 0.79 N open). This runs paper-size A3 and B3 past their first
opened contact, with the port variants of ``b3_port.py`` (free: the default), and prints per run
the first step's and the onset step's figures (``summary.json``'s ``first_step_*`` and
``fracture_onset_*``) and the contact forces, after settling, of the contacts that opened in the
onset step. 5-15 s a run on one core (A3 with its port held, to 13 us: ~15 s).
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from b3_port import VARIANTS, variant_scenario  # noqa: E402
from hmdem.coupling.micromechanics import energy_partition  # noqa: E402
from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from md_table import header  # noqa: E402

KPA, UJ = 1e3, 1e-6


def run(case: str, label: str, t_max: float) -> str:
    sc = variant_scenario(case, label)
    sc.setup.t_max = t_max
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    state, rec = model.run()
    opened_time = np.where(model.opened, model.opened_time, np.inf)
    onset = float(opened_time.min())  # the summary's first_opening_time_s
    e = energy_partition(*rec.step_energies(), onset)
    first_forces = np.sort(model.initial_force[opened_time == onset])  # empty when none opened
    return (f"| {case} {label} | {e['first_step_injection_pressure_pa'] / KPA:.3g} kPa, "
            f"{e['first_step_injection_energy_j'] / UJ:.3g} uJ, {100 * e['first_step_dissipated_fraction']:.1f} % | "
            f"{onset * 1e6:.3g} us | {e['fracture_onset_step_s']:.2g} s | "
            f"{e['fracture_onset_injection_pressure_pa'] / KPA:.4g} kPa | "
            f"{e['fracture_onset_injection_energy_j'] / UJ:.4g} uJ | {e['fracture_onset_residual_energy_j'] / UJ:.3g} uJ | "
            f"{100 * e['fracture_onset_dissipated_fraction']:.1f} % | {len(first_forces)}: "
            f"{' '.join(f'{f:.2g}' for f in first_forces[:6])}{' ...' if len(first_forces) > 6 else ''} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=("A3", "B3"), default=["A3", "B3"])
    parser.add_argument("--variants", nargs="+", choices=tuple(VARIANTS), default=["free", "rho10", "rho100", "fixed"])
    parser.add_argument("--t-max", type=float, default=2e-5, help="stop here [s] (A3's held port opens at 13 us)")
    args = parser.parse_args()
    print(header("run", "first step: p_in, dE_in, dissipated", "first opening", "its step: length", "p_in", "dE_in",
                 "dE_f", "dissipated", "contacts opened in it: forces after settling [N per m], weakest first"))
    for case in args.cases:
        for label in args.variants:
            print(run(case, label, args.t_max), flush=True)


if __name__ == "__main__":
    main()
