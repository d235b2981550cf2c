"""What holds B3's injection port, and what raises its pressure later (digest H4; decisions #68).

    .venv/bin/python benchmarks/b3_port.py [--t-max 3e-5] [--variants free dem2000 rho10 rho100 fixed no_compaction]

Seed 004 has B3 peak at 9.73 MPa while "the flow resistance around the injection port remains
relatively high" (44.4 GPa s/m^2), then decline to a plateau (H4). This runs paper-size B3 with the
port's grains free (the default), with the paper's 2000 DEM cycles per flow step, with 10x and 100x
heavier grains (``--grain-density``) and with the port's grains held (``--fixed-port``), and, as a
diagnostic of the later rise, with closed contacts keeping a0 whatever their force (Eq. 13 switched
off), and prints per run: the early peak of the injection pressure and when (decisions #51), the
pressure at 10, 20 and 29 us and on a 10-point grid of the run (the test's H4 reading), the late
rise p(end) / p(end / 5), how the run ended, the fractal dimension, the largest grain displacement
and the mean aperture of the port's pipes at the end.
Short runs (``--t-max 3e-5``) take 10-40 s each; to breakthrough 3-5 minutes each, on one core.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.apertures import ApertureLaw  # noqa: E402
from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario, port_pipes  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from hmdem.flow.diagnostics import early_peak  # noqa: E402
from hmdem.network.packing import GRAIN_DENSITY  # noqa: E402
from hmdem.report import radial_pattern_dimension  # noqa: E402
from md_table import header  # noqa: E402

MPA = 1e6
VARIANTS = {  # label -> (build_radial_scenario keywords, CouplingSetup fields)
    "free": ({}, {}),
    "dem2000": ({}, {"dem_cycles_per_step": 2000}),
    "rho10": ({"grain_density": 10 * GRAIN_DENSITY}, {}),
    "rho100": ({"grain_density": 100 * GRAIN_DENSITY}, {}),
    "fixed": ({"fixed_port": True}, {}),
    # a diagnostic, not a model: closed contacts keep a0 whatever their force (Eq. 13 with F0 -> inf)
    "no_compaction": ({"aperture_law": ApertureLaw(half_aperture_force=1e30)}, {}),
}


def variant_scenario(case: str, label: str):
    """The paper-size scenario of ``case`` with the port variant ``label`` of :data:`VARIANTS`."""
    scenario_keywords, coupling_fields = VARIANTS[label]
    sc = build_radial_scenario(RADIAL_CASES[case], **scenario_keywords)
    for field, value in coupling_fields.items():
        setattr(sc.coupling, field, value)
    return sc


def run(label: str, t_max: float | None) -> str:
    sc = variant_scenario("B3", label)
    if t_max is not None:
        sc.setup.t_max = t_max
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    state, rec = model.run()
    t, p = rec.injection_pressure()
    peak = early_peak(t, p)  # the largest pressure before the curve first falls (decisions #51)
    early = ", ".join(f"{np.interp(s, t, p) / MPA:.3g}" for s in (1e-5, 2e-5, 2.9e-5))
    grid = np.interp(np.linspace(0.0, t[-1], 11)[1:], t, p)
    d_f = radial_pattern_dimension(sc, state) if state.invaded.any() else float("nan")
    moved = np.linalg.norm(model.positions - sc.packing.centres, axis=1).max()
    port = port_pipes(sc.net)
    return (f"| {label} | {peak.pressure / MPA:.3g} at {peak.time * 1e6:.3g} us | {early} | "
            f"{' '.join(f'{x / MPA:.3g}' for x in grid)} | {p[-1] / np.interp(t[-1] / 5, t, p):.2f} | "
            f"{rec.status} at {state.t:.3g} s | {int(model.opened.sum())} | {d_f:.3f} | {moved * 1e6:.0f} | "
            f"{np.mean(sc.net.pipe_aperture[port]) * 1e6:.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", choices=tuple(VARIANTS), default=list(VARIANTS))
    parser.add_argument("--t-max", type=float, help="stop here [s] (default: breakthrough)")
    args = parser.parse_args()
    print(header("port", "early peak p_in [MPa]", "p_in at 10 / 20 / 29 us [MPa]", "p_in on a 10-point grid [MPa]",
                 "p(end) / p(end / 5)", "end", "opened", "D_f", "largest displacement [um]",
                 "port pipes' mean aperture [um]"))
    for label in args.variants:
        print(run(label, args.t_max), flush=True)


if __name__ == "__main__":
    main()
