"""Random dense disc packings generated with YADE (radius growth in a fixed box).

Discs are seeded at random without overlap at a fraction of their size, then grown to their
final radii with frictionless contacts inside four frictionless walls and relaxed with local
damping. The target porosity fixes the radii: sum(pi r^2) = (1 - porosity) W H. The result is
deterministic for a given seed (YADE runs single-threaded here).
"""

from __future__ import annotations

import math
import time

import numpy as np

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


HEXAGONAL_POROSITY = 1.0 - math.pi / (2.0 * math.sqrt(3.0))  # the densest disc packing's, 0.0931


def grain_count_for(mean_radius: float, spread: float, porosity: float, size: float) -> int:
    """Discs of mean radius r (radii r U[1 - spread, 1 + spread], E[r^2] = r^2 (1 + spread^2 / 3))
    that fill a size x size box to ``porosity``."""
    return round((1.0 - porosity) * size**2 / (math.pi * mean_radius**2 * (1.0 + spread**2 / 3.0)))


def main(argv=None) -> int:
    from pathlib import Path

    from ..cli import (MAX_GRAINS, MIN_GRAINS, OneLineParser, check_packing_out, dispatch, grain_count,
                       number_in, positive_number, seed_value)

    prog = "python -m hmdem.dem.packing"

    class Parser(OneLineParser):
        command = prog

    parser = Parser(prog=prog, description="Generate a random dense disc packing with YADE (the Lenormand "
                                           "sample by default). The radii follow from --n, --size and --porosity.")
    parser.add_argument("--out", type=Path, required=True, help="packing file to write, ending in .npz")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--n", type=grain_count, help="number of discs (default 1188, the shipped packing's)")
    size.add_argument("--mean-radius", type=positive_number,
                      help="mean disc radius [m], instead of --n: the count that fills the box to --porosity")
    parser.add_argument("--size", type=positive_number, default=0.065, help="square box side [m] (default %(default)g)")
    parser.add_argument("--spread", type=number_in("a number in [0, 1)", lambda v: 0 <= v < 1), default=0.05,
                        help="radii uniform in mean (1 +- spread) (default %(default)g)")
    parser.add_argument("--porosity", default=0.117,
                        type=number_in(f"a number in ({HEXAGONAL_POROSITY:.4f}, 1): no disc packing is denser than "
                                       "the hexagonal one", lambda v: HEXAGONAL_POROSITY < v < 1),
                        help="porosity of the box (default %(default)g)")
    parser.add_argument("--seed", type=seed_value, default=0, help="seed of the radii and the seeding "
                                                                          "(default %(default)d)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace --out if it exists (make packing regenerates the shipped file)")
    args = parser.parse_args(argv)
    check_packing_out(parser, args.out, args.overwrite)
    if args.mean_radius is not None:
        args.n = grain_count_for(args.mean_radius, args.spread, args.porosity, args.size)
        if not MIN_GRAINS <= args.n <= MAX_GRAINS:
            parser.error(f"--mean-radius: {args.mean_radius:g} m fills the box with {args.n} discs; "
                         f"between {MIN_GRAINS} and {MAX_GRAINS} are allowed")
    args.command = "packing"  # dispatch runs commands by name; this CLI has the one
    # Ctrl-C or SIGTERM: one line, exit 130 or 143, nothing written (the file is all or nothing)
    return dispatch(prog, parser, args, {"packing": write_packing})


def check_network(pk: DiscPacking, porosity: float) -> None:
    """An :class:`~hmdem.cli.InputError` naming --porosity when a run could build no network on the
    packing: past about 0.2 the discs no longer touch (a new-user pass: 0.5 wrote a file of one
    contact, which every run then refused)."""
    from ..cli import InputError
    from ..network.boundaries import NoBoundaryDomains
    from ..network.contact_graph import NEAR_CONTACT_GAP, ContactsOffTriangulation
    from ..scenario import linear_network

    try:
        linear_network(pk, NEAR_CONTACT_GAP)
    except NoBoundaryDomains as exc:
        raise InputError(f"--porosity: at {porosity:g} the {len(pk.radii)} discs make {len(pk.contacts)} contact(s) "
                         f"and no run can use them: {exc}; a dense packing has a porosity below about 0.2") from None
    except ContactsOffTriangulation as exc:  # a run would refuse the file
        raise InputError(f"--seed: the packing drawn has near contacts no run can use ({exc}); try another "
                         "seed") from None


def write_packing(args) -> int:
    """The command's work: generate, then write ``--out`` in one go."""
    from ..rundir import replaced_atomically

    t0 = time.perf_counter()
    mean_radius = 1.0e-3 if args.mean_radius is None else args.mean_radius  # sets the walls' stiffness only
    pk = generate_packing(args.n or 1188, (args.size, args.size), mean_radius, args.spread, args.porosity, args.seed)
    check_network(pk, args.porosity)
    args.out.absolute().parent.mkdir(parents=True, exist_ok=True)
    # a kill while writing leaves no part of a file; a file made at --out meanwhile is kept
    with replaced_atomically(args.out, keep_existing=not args.overwrite) as tmp:
        pk.save(tmp)
    print(f"{len(pk.radii)} discs, mean radius {pk.radii.mean() * 1e3:.4g} mm, porosity {pk.porosity:.4f}, "
          f"{len(pk.contacts)} contacts, {time.perf_counter() - t0:.1f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
