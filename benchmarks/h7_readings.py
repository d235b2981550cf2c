"""Readings of one step's viscous dissipation against Figs. 15-16 (digest H7; decisions #95).

    .venv/bin/python benchmarks/h7_readings.py [--cases A3 B3] [--dt 8e-7]

Eq. 26 writes dE_v = sum_k q_ij (p_i - p_j) dt. The model's summary uses the flux its solve
carried (Eq. 6, capillary term included, viscosities and apertures of the step's start). This
runs paper-size A3 and B3 past their first opened contact and prints, for the first step and
the onset step (the step at whose end the first contact opened), the dissipated fraction and
the residual energy dE_f = p_in Q dt - dE_v under three readings:

- ``solve``: the solve's flux (the summary's ``first_step_*`` / ``fracture_onset_*``);
- ``end viscosity``: the solve's flux times eta_start / eta_end per pipe (Eq. 4 at the step's
  start and end), p_c kept;
- ``Eq. 27 at the end``: (p_i - p_j)^2 / R_s with each pipe's R_s = 12 eta l / a^3 at the step's
  end (its viscosity and, as the grains moved, its aperture), front pipes held shut left out.

and the port's mean pipe resistance at the step's start and end (the paper reports 1.1 and 3.0
GPa s/m^2 for A3, 9.4 and 35.8 for B3). Each run ~5 s on one core. The later readings were
measured and rejected: they are not energies of the model's step (their fluxes do not carry Q
out of the port), and B3's Eq. 27 figure comes from the port's apertures opened in the onset
step itself.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from md_table import header  # noqa: E402

UJ, GPA = 1e-6, 1e9


class ReadingModel(CoupledFlowModel):
    """A coupled model that records, per accepted step, dE_in and dE_v under the three readings."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.readings = []  # (t, dE_in, solve, end viscosity, Eq. 27, port R_s start, port R_s end)
        a, b = self.pipe_a, self.pipe_b
        self.port_pipes = np.isin(a, self.inlet) | np.isin(b, self.inlet)

    def _accept(self, state, sol, fill, dt, limiter):
        dp = sol.pressure[self.pipe_a] - sol.pressure[self.pipe_b]
        injected = float(sol.pressure[self.inlet].mean()) * self.setup.rate * dt
        g_start = self.pipe_properties(state)[0]
        eta_start = self.fluids.pipe_viscosity(state.saturation[self.pipe_a], state.saturation[self.pipe_b])
        solve = sol.pipe_flux * dp * dt
        super()._accept(state, sol, fill, dt, limiter)
        g_end = self.pipe_properties(state)[0]
        eta_end = self.fluids.pipe_viscosity(state.saturation[self.pipe_a], state.saturation[self.pipe_b])
        eq27 = np.where(sol.blocked, 0.0, g_end * dp * dp * dt)
        port = self.port_pipes
        self.readings.append((state.t, injected, solve.sum(), (solve * eta_start / eta_end).sum(), eq27.sum(),
                              float(np.mean(1.0 / g_start[port])), float(np.mean(1.0 / g_end[port]))))


def run(case: str, dt: float) -> list[str]:
    sc = build_radial_scenario(RADIAL_CASES[case])
    sc.setup.dt, sc.setup.t_max = dt, 10 * dt
    model = ReadingModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    model.run()
    onset = float(np.where(model.opened, model.opened_time, np.inf).min())
    rows = []
    for label, k in (("first step", 0), ("onset", next((i for i, r in enumerate(model.readings) if r[0] >= onset), None))):
        if k is None:
            rows.append(f"| {case} | {label} | no contact opened by {10 * dt:.2g} s | | | | |")
            continue
        t, e_in, *dissipated, r_start, r_end = model.readings[k]
        cells = " | ".join(f"{100 * e_v / e_in:.1f} %, {(e_in - e_v) / UJ:.3g} uJ" for e_v in dissipated)
        rows.append(f"| {case} | {label} ({t * 1e6:.3g} us, p_in Q dt {e_in / UJ:.4g} uJ) | {cells} | "
                    f"{r_start / GPA:.3g} -> {r_end / GPA:.3g} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=("A3", "B3"), default=["A3", "B3"])
    parser.add_argument("--dt", type=float, default=8e-7, help="flow step [s] (both cases' default 8e-7)")
    args = parser.parse_args()
    print(header("case", "step", "solve: dissipated, dE_f", "end viscosity", "Eq. 27 at the end",
                 "port R_s, start -> end [GPa s/m^2]"))
    for case in args.cases:
        for row in run(case, args.dt):
            print(row, flush=True)


if __name__ == "__main__":
    main()
