"""Where a PF-SPH step's time goes on a real drop: the wide puddle of the issue 5 acceptance
(a ridge 8 lambda_c wide on its plate, the `droplet --ridge` set-up at --dx), after --warm steps
so that the drop has started to move and particles bounce; then --steps steps timed whole and
per particle sum.

    NUMBA_NUM_THREADS=2 .venv/bin/python benchmarks/sph_step.py --dx 2e-4 --warm 30 --steps 5

A --state FILE (a ``droplet --checkpoint`` state.npz of the same drop) starts from that state
instead, e.g. a puddle well into its spreading.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dx", type=float, default=2e-4)
    parser.add_argument("--warm", type=int, default=30)
    parser.add_argument("--steps", type=int, default=5)
    parser.add_argument("--state", type=Path, default=None)
    args = parser.parse_args(argv)

    from numba import get_num_threads

    from sph_bridge import __main__ as cli
    from sph_bridge import droplet, simulation

    lam = droplet.capillary_length(droplet.SURFACE_TENSION, droplet.WATER_DENSITY, 9.81)
    volume = 8 * lam * 2.918e-3 * droplet.RIDGE_LENGTH * args.dx  # as tests/test_sph_droplet.py's puddle
    drop = cli.build_parser().parse_args(["droplet", "--dx", repr(args.dx), "--ridge", "--volume", repr(volume)])
    params, sigma, _ = cli.droplet_parameters(drop)
    sim, _ = droplet.prepare_drop(params, volume, sigma, True, None, drop.theta)
    if args.state is not None:
        with np.load(args.state) as saved:
            for name in ("pos", "vel", "acc", "rho", "pressure", "number_density"):
                getattr(sim, name)[...] = saved[name]
        sim.dt = sim.stable_step()
    seconds: dict[str, float] = {}

    def timed(name, function):
        def call(*a, **k):
            t0 = time.perf_counter()
            result = function(*a, **k)
            seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t0
            return result
        return call

    for name in ("density", "proximity", "refresh_density", "wall_state", "accelerations", "bounce_back"):
        if hasattr(simulation, name):
            setattr(simulation, name, timed(name, getattr(simulation, name)))
    for _ in range(args.warm):
        sim.step()
    seconds.clear()
    bounced = sim.record.bounced
    t0 = time.perf_counter()
    for _ in range(args.steps):
        sim.step()
    per_step = (time.perf_counter() - t0) / args.steps
    n = len(sim.pos)
    print(f"puddle ridge at dx = {args.dx:g} m: {n} particles ({int(sim.fluid.sum())} fluid), "
          f"{get_num_threads()} threads, after {args.warm} steps; "
          f"{(sim.record.bounced - bounced) / args.steps:.1f} bounced per step")
    print(f"step: {per_step:.3f} s -> {n / per_step:.3g} particle-steps/s")
    for name, total in seconds.items():
        print(f"  {name}: {total / args.steps:.3f} s ({total / args.steps / per_step:.0%})")
    rest = per_step - sum(seconds.values()) / args.steps
    print(f"  the rest (binning, Verlet updates, step size): {rest:.3f} s ({rest / per_step:.0%})")


if __name__ == "__main__":
    main()
