"""Near-wall motion of a relaxing PF-SPH drop (issue 5, decisions #37): rms speed of the fluid
within 4 dx of the wall and above it, on a zero-gravity ridge of 8 dx radius with the shipped
calibration and the droplet command's damping, sampled through part of its relaxation.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/sph_near_wall.py [--dx 5e-4] [--theta 65.16] [--fraction 0.5] [--samples 8]

With the fluid's own pressure clamped at walls (before decisions #37) the near-wall rms stayed
at 0.08-0.10 m/s while the rest decayed to 0.03-0.04; with the fluid's own term unclamped both
decay together (0.006 and 0.009 m/s after half the minimum relaxation at dx = 5e-4 m).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace


def main(argv=None) -> None:
    from sph_bridge import calibrations, droplet
    from sph_bridge.simulation import SphParameters

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dx", type=float, default=5e-4)
    parser.add_argument("--theta", type=float, default=65.16)
    parser.add_argument("--fraction", type=float, default=0.5, help="of the minimum relaxation time")
    parser.add_argument("--samples", type=int, default=8)
    args = parser.parse_args(argv)
    if not (args.fraction > 0 and args.samples > 0):
        parser.error("--fraction and --samples must be positive")
    entry = calibrations.lookup(args.dx, args.theta)
    if entry is None:
        parser.error(f"--dx/--theta: no shipped calibration at dx = {args.dx:g} m, {args.theta:g}°")
    params = replace(SphParameters(dx=args.dx, c0=entry.c0, rho0_fluid=entry.rho0_fluid, s_ff=entry.s_ff,
                                   s_sf=entry.s_sf), gravity=(0.0, 0.0, 0.0))
    volume = droplet.ridge_volume(8, args.dx)
    sim, t_min = droplet.prepare_drop(params, volume, entry.surface_tension, ridge=True)
    print(f"{int(sim.fluid.sum())} fluid + {int((~sim.fluid).sum())} wall particles, minimum relaxation "
          f"{t_min:.3f} s, damping {sim.params.damping:.1f} 1/s")
    start = time.perf_counter()
    for k in range(1, args.samples + 1):
        sim.run(args.fraction * t_min * k / args.samples, record_every=math.inf)
        near, upper = droplet.rms_speeds(sim)
        angle = droplet.measure(sim, ridge=True).contact_angle_deg
        print(f"t = {sim.t:.4f} s ({sim.record.steps} steps): rms speed near the wall {near:.4f} m/s, above "
              f"{upper:.4f} m/s, cap angle {angle:.1f}°, {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
