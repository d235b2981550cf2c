"""What opens A1's contacts (digest H1: "no fractures are formed"; decisions #20, #72).

    .venv/bin/python benchmarks/a1_openings.py [--packing P.npz] [--surface-tension G]

Runs A1 (paper size on the shipped packing unless ``--packing``) to breakthrough and reports, for
every opened contact (decisions #20), the force it carried after settling, its distance from the
port, when it detached (F <= 0) and how far the fluid had got from the port by then (its farthest
wetted domain), when it counted as opened, and the fluid around its two grains
at the step it detached: whether any domain touching either grain held invading fluid, the lowest
pressure among them, the largest fall of one of their pressures in that step (a filled domain whose
front pipes open drops to capillary suction) and the fluid's separating force on
the pair (Eq. 8 forces on the two grains projected on the contact normal, + pulls them apart) just
before and at that step. ``--surface-tension 0`` is a diagnostic, not a model: the same run (same Q)
without capillary entry pressures, to tell capillary suction (+33.5 kPa at theta = 0 behind the
front) from the viscous pressure field. Paper size takes 14-20 min on one core; a 150-disc
packing (``h2_packings.py``'s samples) ~10 s.
"""
import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from hmdem.flow.grain_forces import pressure_force_matrix  # noqa: E402
from hmdem.network.network import pipes_touching  # noqa: E402
from hmdem.network.packing import DiscPacking  # noqa: E402
from md_table import header  # noqa: E402


def scenario(packing: str | None, surface_tension: float | None):
    """A1 on ``packing``; ``surface_tension`` replaces gamma after Q is set from Ca* (diagnostic)."""
    sc = build_radial_scenario(RADIAL_CASES["A1"], packing=DiscPacking.load(packing) if packing else None)
    if surface_tension is not None:
        fluids = dataclasses.replace(sc.setup.fluids, surface_tension=surface_tension)
        sc = dataclasses.replace(sc, setup=dataclasses.replace(sc.setup, fluids=fluids))
    return sc


class DetachmentLog:
    """Each contact's first detachment: the time, the pressures before and at that step, the saturations at it."""

    def __init__(self, model: CoupledFlowModel):
        self.last_pressure = model.initial_state().pressure.copy()
        self.seen = model.detached.copy()
        self.events = {}  # pipe -> (t, p before, p at, S at)

    def __call__(self, model: CoupledFlowModel, state) -> None:
        for pipe in np.flatnonzero(model.detached & ~self.seen):
            self.events[int(pipe)] = (state.t, self.last_pressure, state.pressure.copy(), state.saturation.copy())
        self.seen = model.detached.copy()
        self.last_pressure = state.pressure.copy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--packing", help="packing .npz (default: the shipped paper-size one)")
    parser.add_argument("--surface-tension", type=float,
                        help="gamma [N/m] after Q is set (diagnostic; default the case's 63e-3)")
    args = parser.parse_args()
    sc = scenario(args.packing, args.surface_tension)
    model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
    log = DetachmentLog(model)
    state, rec = model.run(progress=log)
    net, pk = sc.net, sc.packing
    closed_force = model.initial_force[model.initially_closed]
    moved = np.linalg.norm(model.positions - pk.centres, axis=1)
    print(f"A1 ({args.packing or 'shipped packing'}, gamma {sc.setup.fluids.surface_tension:g} N/m): {rec.status} at "
          f"t = {state.t:.4e} s, peak p_in {rec.peak_injection_pressure / 1e3:.1f} kPa, "
          f"{int(model.opened.sum())} opened of {int(model.detached.sum())} detached, "
          f"{closed_force.size} contacts (mean force {closed_force.mean():.2f} N), largest grain displacement "
          f"{moved.max() * 1e6:.3f} um (median {np.median(moved) * 1e9:.1f} nm)")
    forces = pressure_force_matrix(net, pk.radii)
    port = net.domain_centroid[net.inlet_domains].mean(axis=0)
    radius = np.linalg.norm(net.domain_centroid - port, axis=1)
    print(header("contact", "force after settling [N] (weaker contacts)", "r from port [um]", "detached at [s]",
                 "fluid out to [um]", "opened at [s]", "largest separation [um]",
                 "grains' domains at detachment: wet", "lowest p [kPa]", "largest fall of p in the step [kPa]",
                 "separating fluid force before / at [N]"))
    for pipe in np.flatnonzero(model.opened):
        g0, g1 = net.pipe_grains[pipe]
        normal = pk.centres[g1] - pk.centres[g0]
        normal /= np.linalg.norm(normal)
        around = np.unique(net.pipe_domains[pipes_touching(net.pipe_grains, (g0, g1))])
        around = around[around >= 0]
        t, p_before, p_at, s_at = log.events[int(pipe)]
        on_grains = [(forces @ p).reshape(-1, 2) for p in (p_before, p_at)]
        separating = [(f[g1] - f[g0]) @ normal for f in on_grains]
        wet = bool((s_at[around] > 0).any())
        fall = float((p_before[around] - p_at[around]).max())
        force = model.initial_force[pipe]
        print(f"| {pipe} | {force:.3g} ({int((closed_force < force).sum())}) | "
              f"{np.linalg.norm((pk.centres[g0] + pk.centres[g1]) / 2 - port) * 1e6:.0f} | {t:.4g} | "
              f"{radius[s_at > 0].max() * 1e6:.0f} | {model.opened_time[pipe]:.4g} | {model.max_gap[pipe] * 1e6:.3f} | {'wet' if wet else 'dry'} | "
              f"{p_at[around].min() / 1e3:.1f} | {fall / 1e3:.1f} | "
              f"{separating[0]:+.3f} / {separating[1]:+.3f} |")


if __name__ == "__main__":
    main()
