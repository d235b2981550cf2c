"""Servo-controlled isotropic compaction of a disc sample (Huang set-up, seed 004 §4.2).

Discs with radii uniform in [r_min, r_max] are seeded loosely in a box larger than the
target, grown to size and pushed together by four frictionless walls whose velocity is
servo-controlled until each wall's stress (force per wall length, 1 m depth) is within the
tolerance of the target confining stress and the sample is in equilibrium (unbalanced force
below UNBALANCED_FORCE). Compaction is frictionless (the usual way to reach a dense state);
the grains get their working friction afterwards. The grains touching a wall at the end are
the fixed boundary grains of the injection runs (digest §11.2: "all boundary grains are fixed").
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ..cli import CommandFailed, InputError, open_bar
from ..network.packing import CONTACT_STIFFNESS, GRAIN_DENSITY, DiscPacking
from ..yade_env import import_yade
from .assembly import run_cycles
from .discs import add_discs, disc_contacts, disc_engines, disc_state
from .packing import random_seed_positions

UNBALANCED_FORCE = 1e-3
WALLS = ((0, -1), (0, +1), (1, -1), (1, +1))  # (axis, side): left, right, bottom, top
R_MIN, R_MAX = 13.0e-6, 21.6e-6  # the Huang sample's radii [m] (seed 004 §4.2)
MAX_OVERLAP = 0.1  # the largest mean contact overlap a compaction may ask for, of the smallest radius


HUANG_GRAINS, HUANG_SIDE = 1395, 1.25e-3  # the shipped sample: discs, nominal box side [m]
# Nominal solid fractions n <pi r^2> / side^2 allowed: 150 discs were compacted from 0.2 to 2.0
# and 1395 at both 0.5 and 1.5 (the shipped sample is 0.857). At 3 the shrunk discs no longer fit
# the box; far below 0.5 a large sample's walls have further to go than the cycles allow.
NOMINAL_SOLID_FRACTION = (0.5, 1.5)


def nominal_side(n: int) -> float:
    """The box side that holds ``n`` discs at the shipped sample's nominal solid fraction: the
    Huang 1.25 mm scaled by sqrt(n / 1395)."""
    return HUANG_SIDE * float(np.sqrt(n / HUANG_GRAINS))


def check_nominal_side(flag: str, n: int, size: float, r_min: float = R_MIN, r_max: float = R_MAX) -> None:
    """An :class:`~hmdem.cli.InputError` naming ``flag`` when a box of side ``size`` would hold
    ``n`` discs of radii uniform in [r_min, r_max] outside :data:`NOMINAL_SOLID_FRACTION`."""
    disc_area = n * np.pi * (r_min**2 + r_min * r_max + r_max**2) / 3.0  # n <pi r^2>
    low, high = NOMINAL_SOLID_FRACTION
    if not disc_area / high <= size**2 <= disc_area / low:
        raise InputError(f"{flag}: must hold the {n} discs at a solid fraction in [{low:g}, {high:g}], a side in "
                         f"[{np.sqrt(disc_area / high):.3g}, {np.sqrt(disc_area / low):.3g}] m, got {size:g}")


class CompactionNotSettled(CommandFailed):
    """The servo did not bring the walls to the confining stress, in equilibrium, within its cycles."""


def max_confining_stress(k_n: float, r_min: float = R_MIN, r_max: float = R_MAX) -> float:
    """The confining stress [Pa] whose mean contact overlap is ``MAX_OVERLAP`` x r_min.

    A wall stress sigma on grains of mean diameter r_min + r_max puts ~sigma (r_min + r_max) on
    a contact, so the mean overlap is ~sigma (r_min + r_max) / k_n: 65 nm at the Huang sample's
    0.14 MPa, where the shipped packing's mean elastic overlap is 60 nm (decisions #20). The
    paper's Darcy calibration goes to 2.1 MPa, 0.075 r_min at Table 2's k_n; the bound, 0.1
    r_min, is 2.8 MPa there. Beyond it the linear contact stops describing touching discs: at
    7 MPa the discs' areas overlap so much that they cover all but 0.25 % of the box.
    """
    return MAX_OVERLAP * r_min * k_n / (r_min + r_max)


def check_confining_stress(flag: str, stresses, k_n: float) -> None:
    """An :class:`~hmdem.cli.InputError` naming ``flag`` when a stress asks the linear contact
    of stiffness ``k_n`` for more than :func:`max_confining_stress`."""
    limit = max_confining_stress(k_n)
    if max(stresses) > limit:
        raise InputError(f"{flag}: must be at most {limit:.3g} Pa with k_n {k_n:g} N/m (beyond it the mean contact "
                         f"overlap passes {MAX_OVERLAP:g} of the smallest radius), got {max(stresses):g}")


class CompactionBar:
    """A tqdm line for :func:`compact_sample`'s ``progress(cycles, wall_stresses)``: cycles run
    and the mean wall stress, refreshed at most every ``every_s`` seconds."""

    def __init__(self, every_s: float = 0.25):
        from tqdm import tqdm

        self.tqdm, self.every_s, self.last, self.bar = tqdm, every_s, 0.0, None

    def __call__(self, cycles: int, stresses: np.ndarray) -> None:
        if self.bar is None:  # opened at the first report, so that a closed bar can start again
            self.bar = open_bar(self.tqdm, desc="compaction", unit=" cycles", file=sys.stderr,
                                bar_format="{desc}: {n} cycles [{elapsed}]{postfix}")
        self.latest = (cycles, stresses.mean())
        now = time.perf_counter()
        if now - self.last >= self.every_s:
            self.last = now
            self._show()

    def _show(self) -> None:
        cycles, stress = self.latest
        self.bar.n = cycles
        self.bar.set_postfix_str(f"wall stress {stress / 1e3:.1f} kPa")

    def close(self) -> None:
        """Show the last report (the throttle may have skipped it), then end the line."""
        if self.bar is not None:
            self._show()
            self.bar.close()
            self.bar = None


def compact_sample(n: int = 1395, size: float = 1.25e-3, r_min: float = R_MIN, r_max: float = R_MAX,
                   stress: float = 0.14e6, seed: int = 0, k_n: float = CONTACT_STIFFNESS,
                   density: float = GRAIN_DENSITY,
                   loose_factor: float = 1.15, tolerance: float = 0.005, max_cycles: int = 400_000,
                   progress=None) -> DiscPacking:
    """Compact n discs to the confining ``stress`` [Pa]; returns the packing with ``fixed`` set.

    ``size``: nominal final box side (only sets the starting box, loose_factor x size); the
    final box follows from the stress. Stops when all four wall stresses are within
    ``tolerance`` of the target and the grains are in equilibrium (YADE's unbalanced force,
    mean resultant over mean contact force, below ``UNBALANCED_FORCE``); raises
    :class:`CompactionNotSettled` when that has not happened after ``max_cycles`` cycles
    (a stress of 1 Pa barely moves the servo's walls: 0 Pa on them after 400,000 cycles).
    """
    import_yade()
    from yade import O, utils
    from yade.minieigenHP import Vector3
    from yade.wrapper import FrictMat

    rng = np.random.default_rng(seed)
    radii = rng.uniform(r_min, r_max, n)
    box0 = loose_factor * size
    shrink = 0.5
    pos = random_seed_positions(radii, (box0, box0), shrink, rng)

    O.reset()
    wall_mat = O.materials.append(FrictMat(young=k_n / r_max, poisson=1.0, frictionAngle=0.0, density=density))
    walls = []
    for axis, side in WALLS:
        origin = [0.0, 0.0, 0.0]
        origin[axis] = 0.0 if side < 0 else box0
        walls.append(O.bodies.append(utils.wall(tuple(origin), axis=axis, sense=-side, material=wall_mat)))
    ids = add_discs(pos, radii, k_n, 1.0, 0.0, density, size_factor=shrink)
    O.engines = disc_engines(walls=True)
    O.dt = 0.5 * utils.PWaveTimeStep()
    stages = 40
    for _ in range(stages):
        utils.growParticles((1.0 / shrink) ** (1.0 / stages), updateMass=False, dynamicOnly=True)
        run_cycles(O, 200)

    def wall_positions():
        return np.array([O.bodies[w].state.pos[axis] for w, (axis, _) in zip(walls, WALLS)])

    def wall_stresses():
        x = wall_positions()
        width, height = x[1] - x[0], x[3] - x[2]
        force = np.array([abs(O.forces.f(w)[axis]) for w, (axis, _) in zip(walls, WALLS)])
        return force / np.array([height, height, width, width])  # N per m of wall per m of depth

    # servo: wall speed proportional to the stress deficit, scaled so one chunk of cycles moves a
    # wall by at most the overlap change that the deficit asks for over ~10 contacts in series
    chunk = 100
    gain = 0.2 * size / (k_n * chunk * O.dt)
    mean_r = radii.mean()
    cycles = 0
    while True:
        s = wall_stresses()
        deficit = (stress - s) / stress
        if np.all(np.abs(deficit) < tolerance) and utils.unbalancedForce() < UNBALANCED_FORCE:
            break
        if cycles >= max_cycles:
            O.reset()
            raise CompactionNotSettled(f"the walls did not settle at {stress:g} Pa within {max_cycles:,} cycles "
                                       f"(wall stresses {', '.join(f'{v:.3g}' for v in s)} Pa at the end)")
        speed = np.clip(gain * (stress - s), -0.02 * mean_r / (chunk * O.dt), 0.02 * mean_r / (chunk * O.dt))
        for w, (axis, side), v in zip(walls, WALLS, speed):
            vel = [0.0, 0.0, 0.0]
            vel[axis] = -side * v  # inward when the stress is too low
            O.bodies[w].state.vel = Vector3(*vel)
        run_cycles(O, chunk)
        cycles += chunk
        if progress is not None:
            progress(cycles, s)
    for w in walls:
        O.bodies[w].state.vel = Vector3(0, 0, 0)
    centres, final_radii = disc_state(ids)
    x = wall_positions()
    # grains touching a wall form the fixed boundary ring
    gap = np.min(np.stack([centres[:, 0] - x[0], x[1] - centres[:, 0],
                           centres[:, 1] - x[2], x[3] - centres[:, 1]], 1), 1)
    fixed = gap <= final_radii * (1.0 + 1e-6)
    contacts = disc_contacts(ids)
    box = (float(x[1] - x[0]), float(x[3] - x[2]))
    final = wall_stresses()
    O.reset()
    centres = centres - np.array([x[0], x[2]])
    return DiscPacking(centres, final_radii, contacts, box, seed, fixed=fixed, confining_stress=float(final.mean()),
                       contact_stiffness=k_n)


def main(argv=None) -> int:
    from pathlib import Path

    from ..cli import (OneLineParser, add_contact_arguments, check_packing_out, dispatch, grain_count,
                       positive_number, seed_value)

    prog = "python -m hmdem.dem.compaction"

    class Parser(OneLineParser):
        command = prog

    parser = Parser(prog=prog, description="Servo-compact a disc sample (Huang radial-injection set-up).")
    parser.add_argument("--out", type=Path, required=True, help="packing file to write, ending in .npz")
    parser.add_argument("--n", type=grain_count, default=1395, help="number of discs (default %(default)d)")
    parser.add_argument("--size", type=positive_number,
                        help="nominal box side [m] (default 1.25e-3 x sqrt(N / 1395), the shipped sample's grain "
                             "density; the final box follows from the stress)")
    parser.add_argument("--stress", type=positive_number, default=0.14e6,
                        help="confining stress [Pa] (default %(default)g, the Huang sample's)")
    parser.add_argument("--seed", type=seed_value, default=0, help="seed of the radii and the seeding "
                                                                          "(default %(default)d)")
    add_contact_arguments(parser, friction=False)  # compaction is frictionless; the runs set mu
    parser.add_argument("--overwrite", action="store_true",
                        help="replace --out if it exists (make huang-packing regenerates the shipped file)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    check_packing_out(parser, args.out, args.overwrite)
    args.command = "compaction"  # dispatch runs commands by name; this CLI has the one
    # Ctrl-C or SIGTERM: one line, exit 130 or 143, nothing written (the file is all or nothing)
    return dispatch(prog, parser, args, {"compaction": write_packing})


def write_packing(args) -> int:
    """The ``compaction`` command's work: compact, then write ``--out`` in one go."""
    from ..rundir import replaced_atomically

    check_confining_stress("--stress", [args.stress], args.contact_stiffness)
    if args.size is None:  # the shipped sample's nominal solid fraction, 0.857
        size = nominal_side(args.n)
    else:
        check_nominal_side("--size", args.n, args.size)
        size = args.size
    t0 = time.perf_counter()
    bar = None if args.quiet else CompactionBar()
    try:
        pk = compact_sample(args.n, size, stress=args.stress, seed=args.seed, k_n=args.contact_stiffness,
                            progress=bar)
    finally:
        if bar is not None:
            bar.close()
    args.out.absolute().parent.mkdir(parents=True, exist_ok=True)
    # a kill while writing leaves no part of a file; a file made at --out meanwhile is kept
    with replaced_atomically(args.out, keep_existing=not args.overwrite) as tmp:
        pk.save(tmp)
    print(f"{len(pk.radii)} discs in {pk.box[0] * 1e3:.4f} x {pk.box[1] * 1e3:.4f} mm, porosity {pk.porosity:.4f}, "
          f"{int(pk.fixed.sum())} grains touching a wall (stored as fixed; the runs fix the whole hull), "
          f"wall stress {pk.confining_stress / 1e6:.4f} MPa, "
          f"k_n {pk.contact_stiffness:g} N/m, {time.perf_counter() - t0:.0f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
