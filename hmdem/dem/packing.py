"""Random dense disc packings generated with YADE (radius growth in a fixed box).

Discs are seeded at random without overlap at a fraction of their size, then grown to their
final radii with frictionless contacts inside four frictionless walls and relaxed with local
damping. The target porosity fixes the radii: sum(pi r^2) = (1 - porosity) W H. The result is
deterministic for a given seed (YADE runs single-threaded here).
"""

from __future__ import annotations

import time
import numpy as np
from scipy.spatial import cKDTree

from ..network.packing import CONTACT_STIFFNESS, GRAIN_DENSITY, DiscPacking
from .discs import add_discs, disc_contacts, disc_engines, disc_state


def target_radii(n: int, mean_radius: float, spread: float, porosity: float, box, rng) -> np.ndarray:
    """Radii uniform in mean (1 +- spread), rescaled so the packing has the target porosity."""
    r = mean_radius * rng.uniform(1.0 - spread, 1.0 + spread, n)
    return r * np.sqrt((1.0 - porosity) * box[0] * box[1] / np.sum(np.pi * r**2))


def random_seed_positions(radii: np.ndarray, box, shrink: float, rng) -> np.ndarray:
    """Random sequential placement of discs of radius shrink * r without overlap."""
    n = len(radii)
    pos = np.empty((n, 2))
    placed = 0
    cell = 2 * shrink * radii.max()
    grid: dict[tuple[int, int], list[int]] = {}
    for k in range(n):  # set-up only, once per packing
        r = shrink * radii[k]
        for _ in range(100_000):
            p = rng.uniform([r, r], [box[0] - r, box[1] - r])
            ci, cj = int(p[0] // cell), int(p[1] // cell)
            near = [m for di in (-1, 0, 1) for dj in (-1, 0, 1) for m in grid.get((ci + di, cj + dj), [])]
            if not near or np.all(np.linalg.norm(pos[near] - p, axis=1) > shrink * radii[near] + r):
                break
        else:
            raise RuntimeError("could not place discs: lower the number of grains or the initial shrink")
        pos[k] = p
        grid.setdefault((ci, cj), []).append(k)
        placed += 1
    return pos


def generate_packing(
    n: int = 1188,
    box: tuple[float, float] = (0.065, 0.065),
    mean_radius: float = 1.0e-3,
    spread: float = 0.05,
    porosity: float = 0.117,
    seed: int = 0,
    k_n: float = CONTACT_STIFFNESS,
    density: float = GRAIN_DENSITY,
    growth_stages: int = 60,
    cycles_per_stage: int = 300,
    relax_cycles: int = 4000,
) -> DiscPacking:
    """Generate a dense random disc packing with YADE (seed 004 §4.1 geometry by default)."""
    from ..yade_env import import_yade

    import_yade()
    from yade import O, utils
    from yade.wrapper import FrictMat

    rng = np.random.default_rng(seed)
    radii = target_radii(n, mean_radius, spread, porosity, box, rng)
    shrink = 0.55
    pos = random_seed_positions(radii, box, shrink, rng)

    O.reset()
    wall_mat = O.materials.append(FrictMat(young=k_n / mean_radius, poisson=1.0, frictionAngle=0.0, density=density))
    for origin, axis in (((0, 0, 0), 0), ((box[0], 0, 0), 0), ((0, 0, 0), 1), ((0, box[1], 0), 1)):
        O.bodies.append(utils.wall(origin, axis=axis, material=wall_mat))
    ids = add_discs(pos, radii, k_n, 1.0, 0.0, density, size_factor=shrink)
    O.engines = disc_engines(walls=True)
    O.dt = 0.5 * utils.PWaveTimeStep()
    factor = (1.0 / shrink) ** (1.0 / growth_stages)
    for _ in range(growth_stages):
        utils.growParticles(factor, updateMass=False, dynamicOnly=True)
        O.run(cycles_per_stage, True)
    O.run(relax_cycles, True)
    centres, final_radii = disc_state(ids)
    contacts = disc_contacts(ids)
    O.reset()
    return DiscPacking(centres, final_radii, contacts, tuple(box), seed, contact_stiffness=k_n)


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(prog="python -m hmdem.dem.packing", description="Generate a disc packing with YADE.")
    parser.add_argument("--out", required=True)
    parser.add_argument("--n", type=int, default=1188)
    parser.add_argument("--size", type=float, default=0.065, help="square box side [m]")
    parser.add_argument("--mean-radius", type=float, default=1.0e-3)
    parser.add_argument("--spread", type=float, default=0.05)
    parser.add_argument("--porosity", type=float, default=0.117)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    pk = generate_packing(args.n, (args.size, args.size), args.mean_radius, args.spread, args.porosity, args.seed)
    pk.save(args.out)
    print(f"{len(pk.radii)} discs, porosity {pk.porosity:.4f}, {len(pk.contacts)} contacts, "
          f"{time.perf_counter() - t0:.1f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
