"""``python -m sph_bridge {droplet,poiseuille,hydrostatic,calibrate}``: PF-SPH validation cases
with run directories; ``python -m sph_bridge lga ...``: the FHP-II lattice-gas studies
(:mod:`sph_bridge.lga.cli`).

    python -m sph_bridge droplet     [--dx M] [--theta DEG] [--volume M3] [--gravity G] [--ridge] [--start-height M]
                                     [--anneal U] [--seed N] [--checkpoint DIR] [--out DIR]
    python -m sph_bridge calibrate   [--dx M] [--theta DEG] [--surface-tension N/M] [--ridge-sizes N ...] [--anneal U]
                                     [--checkpoint DIR] [--out DIR]
    python -m sph_bridge hydrostatic [--dx M] [--layers N] [--gravity G] [--out DIR]
    python -m sph_bridge poiseuille  [--dx M] [--layers N] [--gravity G] [--viscosity MU] [--out DIR]

``hydrostatic`` and ``poiseuille`` put water between two 3-layer walls, periodic sideways
(``sph_bridge.cases``); ``droplet`` relaxes a sessile drop (or a ridge) on a wall and measures
its height, width and contact angle against the spherical cap, de Gennes' puddle height and
the Young-Laplace shape (``sph_bridge.droplet``); ``calibrate`` finds s_ff and s_sf for a
surface tension and a contact angle (``sph_bridge.calibrate``). A run directory holds
config.toml, summary.json (measured against theory, particles, steps, wall time),
timeseries.csv, PNG figures and ParaView point clouds (.vtu; a droplet's series in
particles.pvd). Bad input: one line, exit status 2, nothing written. Ctrl-C stops the run and
writes the directory with status "interrupted".
"""

from __future__ import annotations

import json
import math
import shutil
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from hmdem import __version__
from hmdem.cli import (InputError, OneLineParser, dispatch, int_at_least, new_run_directory, non_negative_number,
                       number_in, open_bar, positive_number, seed_value, stop_note)
from hmdem.rundir import atomic_run_directory, write_json, write_rows, write_toml
from hmdem.snapshots import write_collection

from . import calibrations, cases, checkpoint, droplet
from .calibrate import DROP_RADIUS_CELLS, MIN_RIDGE_CELLS
from .interrupts import exit_status, interrupted
from .output import particle_state, run_table, write_particles
from .simulation import stable_step

PROG = "python -m sph_bridge"
MIN_LAYERS = 8  # the channel must hold a full kernel (h = 3.42 dx) from each wall
DEFAULT_DX = 5e-4  # m: the coarsest resolution of seed 000 Table 1 (CI runs the droplet here)
DEFAULT_THETA = 65.16  # degrees: PMMA, the lab value of seed 000 §4.1
DEFAULT_VOLUME = 2.5e-7  # m^3: ~2,000 particles at dx = 5e-4 m
MIN_DROP_CELLS = 400  # a drop needs a few kernel supports across to have a surface and a bulk
MAX_DROP_CELLS = 10_000_000  # the shipped drops have 2,000-31,000; --volume 1e300 failed building its block
MAX_LAYERS = 10_000  # 1.4M particles in the channel; 1e8 layers asked numpy for 107 GiB
MAX_CHANNEL_STEPS = 1_000_000  # 3-10 h at the default size; the defaults take 355 (Poiseuille) and 674 steps
MAX_CHANNEL_GRAVITY = 1e150  # squared accelerations overflow near 1.3e154 m/s^2: at 1e160 the column came out garbage
MIN_START_LAYERS = 3  # a starting slab lower than this is mostly surface
WATER_SOUND_SPEED = 1500.0  # m/s: a weakly compressible fluid's c0 stays below it (Table 1: 1.5-18)
# pairwise strengths per dx: 1000x the calibration's first guess (sigma 0.074 N/m at 2e-3 N/m;
# sigma grows as about s^1.5); at 1e300 N the accelerations' squares overflowed
MAX_STRENGTH_PER_DX = 2.0  # N/m
SNAPSHOT_EVERY = 4  # samples between the droplet's ParaView frames
# seed 000's spacings are 0.2-0.5 mm; at 1e-300 m, dx^3 underflowed to a division by zero
particle_spacing = number_in("a particle spacing in [1e-06, 1] m", lambda v: 1e-6 <= v <= 1)
channel_gravity = number_in(f"a body force in (0, {MAX_CHANNEL_GRAVITY:g}] m/s^2 (squared accelerations overflow beyond)",
                            lambda v: 0 < v <= MAX_CHANNEL_GRAVITY)


ANNEAL_HELP = ("starting rms thermal speed [m/s] of an annealed relaxation: Langevin kicks against the "
               "damping, falling to none by twice its minimum duration, then damping alone until it settles "
               "(0: damping alone)")


class _Parser(OneLineParser):
    command = PROG


angle = number_in("a contact angle in (0, 180) degrees", lambda v: 0 < v < 180)


def sound_speed_allowed(c0: float) -> bool:
    """A speed of sound up to water's own (at 1e300 m/s the equation of state's c0^2 overflowed
    and the drop came out as NaN)."""
    return 0 < c0 <= WATER_SOUND_SPEED


def strongest_pair(dx: float) -> float:
    """The largest pairwise strength [N] allowed at particle spacing ``dx``."""
    return MAX_STRENGTH_PER_DX * dx


sound_speed_value = number_in(f"a speed of sound in (0, {WATER_SOUND_SPEED:g}] m/s, water's own at most",
                              sound_speed_allowed)


def build_parser() -> OneLineParser:
    parser = _Parser(prog=PROG, description="PF-SPH validation cases (seed 000); 'python -m sph_bridge lga -h' for "
                                            "the lattice-gas fracture studies (seed 003)")
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    text = "sessile drop (or --ridge) relaxed on a wall: height, width and contact angle against theory"
    p = sub.add_parser("droplet", help=text, description=text)
    p.add_argument("--dx", type=particle_spacing, default=DEFAULT_DX,
                   help=f"particle spacing [m] (default {DEFAULT_DX})")
    p.add_argument("--theta", type=angle,
                   help=f"target static contact angle [deg] selecting the calibration (default {DEFAULT_THETA}, "
                        "or the --calibration run's)")
    p.add_argument("--volume", type=positive_number, default=DEFAULT_VOLUME,
                   help=f"fluid volume [m^3] (a ridge: over its periodic length; default {DEFAULT_VOLUME})")
    p.add_argument("--gravity", type=non_negative_number, default=cases.GRAVITY,
                   help=f"downward gravity [m/s^2] (default {cases.GRAVITY}; 0: a spherical cap at any size)")
    p.add_argument("--ridge", action="store_true",
                   help=f"a 2-D drop, periodic over {droplet.RIDGE_LENGTH} dx along y (de Gennes' puddle limit)")
    p.add_argument("--start-height", type=positive_number,
                   help="the starting drop's greatest height [m]: a slab (cylinder) of this height where the "
                        "hemisphere (half cylinder) would be taller; started below its equilibrium the contact "
                        "line recedes (default: 2 lambda_c under gravity, none at zero gravity)")
    p.add_argument("--calibration", type=Path, help="a calibrate run directory whose s_ff, s_sf, c0, rho0 to use")
    p.add_argument("--s-ff", type=positive_number, help="fluid-fluid pairwise strength [N] (with --s-sf, "
                   "instead of a calibration)")
    p.add_argument("--s-sf", type=non_negative_number, help="solid-fluid pairwise strength [N]")
    p.add_argument("--c0", type=sound_speed_value, help="speed of sound [m/s] (default: seed 000 Table 1)")
    p.add_argument("--anneal", type=non_negative_number,
                   help=ANNEAL_HELP + " (default: the calibration's own, 0.3 for the shipped ones; 0 with "
                        "--s-ff/--s-sf)")
    p.add_argument("--seed", type=seed_value, default=0, help="seed of the annealing's kicks (default 0)")
    p.add_argument("--checkpoint", type=Path, metavar="DIR",
                   help="save the relaxation in DIR after every shape sample; the same command run again "
                        "with a new --out goes on from there (a long run killed or cut by its batch slot), to "
                        "the result of a straight run")
    text = "find s_ff for a surface tension (free slab) and s_sf for a contact angle (zero-gravity drop)"
    p = sub.add_parser("calibrate", help=text, description=text)
    p.add_argument("--dx", type=particle_spacing, default=DEFAULT_DX,
                   help=f"particle spacing [m] (default {DEFAULT_DX})")
    p.add_argument("--theta", type=angle, default=DEFAULT_THETA, help=f"target contact angle [deg] (default {DEFAULT_THETA})")
    p.add_argument("--surface-tension", type=positive_number, default=droplet.SURFACE_TENSION,
                   help=f"target surface tension [N/m] (default {droplet.SURFACE_TENSION})")
    p.add_argument("--c0", type=sound_speed_value, help="speed of sound [m/s] (default: seed 000 Table 1)")
    p.add_argument("--ridge-sizes", type=int_at_least(MIN_RIDGE_CELLS), nargs="+", default=[DROP_RADIUS_CELLS],
                   metavar="N", help="starting radii [dx] of the zero-gravity ridges whose mean angle is "
                   f"calibrated (each >= {MIN_RIDGE_CELLS}; default {DROP_RADIUS_CELLS})")
    p.add_argument("--anneal", type=non_negative_number, default=0.0,
                   help=ANNEAL_HELP + " of the ridges (default 0)")
    p.add_argument("--checkpoint", type=Path, metavar="DIR",
                   help="save the trials in DIR as they finish; the same command run again with a new --out "
                        "takes them as measured and goes on from there, to the result of a straight run")
    for name, text in (("hydrostatic", "water at rest between two walls under gravity: dP/dz = rho g"),
                       ("poiseuille", "body-force flow between two walls: the parabolic profile")):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("--dx", type=particle_spacing, default=1e-3, help="particle spacing [m] (default 1e-3)")
        p.add_argument("--layers", type=int_at_least(MIN_LAYERS, maximum=MAX_LAYERS), default=16,
                       help=f"channel width in particle layers (>= {MIN_LAYERS}, default 16)")
        p.add_argument("--gravity", type=channel_gravity, default=cases.DEFAULT_GRAVITY[name],
                       help=f"body force per mass [m/s^2] (default {cases.DEFAULT_GRAVITY[name]}; "
                            + ("downward" if name == "hydrostatic" else "along the channel") + ")")
        if name == "poiseuille":
            p.add_argument("--viscosity", type=positive_number, default=2.6,
                           help="dynamic viscosity [Pa s] (default 2.6: the flow settles in ~0.05 s)")
    for p in sub.choices.values():
        p.add_argument("--out", type=Path, help="run directory (must not exist; default runs/<case>-<time>-<pid>)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
    # listed here so that the usage names it; main() hands `lga ...` to its own parser first
    sub.add_parser("lga", help="FHP-II lattice-gas fracture studies (seed 003): python -m sph_bridge lga -h")
    return parser


def progress_bar(args, total: float, unit: str = "s", extend: float = 0.0, desc: str | None = None,
                 leave: bool = True, start: float = 0.0):
    """A tqdm bar over simulated time (None with --quiet) and the callback that advances it.
    ``extend`` > 0: a run that goes on past ``total`` (a drop not settled by its minimum
    duration) moves the bar's end on by this much at a time, so it never reads over 100 %.
    ``start``: where a resumed run begins; a bar opened at 0 took the resumed span as its first
    update, and tqdm then waited for another jump that size before it redrew (a new-user pass)."""
    if args.quiet:
        return None, None
    from tqdm import tqdm

    bar = open_bar(tqdm, total=max(total, start), initial=start, desc=desc or args.command, unit=unit, leave=leave,
                   bar_format="{l_bar}{bar}| {n:.4f}/{total:.4f} " + unit + " [{elapsed}<{remaining}]")

    def advance(sim):
        if extend > 0 and sim.t > bar.total:
            bar.total += extend * math.ceil((sim.t - bar.total) / extend)
        bar.update(sim.t - bar.n)

    return bar, advance


def config_of(args, sim, **sections) -> dict:
    return {"run": run_table(PROG, args.argv, args.command), **sections,
            "parameters": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(sim.params).items()}}


def check_poiseuille_steps(args, params, t_end: float) -> None:
    """Refuse a Poiseuille run that would take more than MAX_CHANNEL_STEPS steps: the stable step
    (Eqs. 30-31 and the viscous limit) with the body force as the acceleration, over the case's
    end time. Its c0 grows with the flow speed, so the count grows with --gravity and falls with
    --viscosity. The hydrostatic column's count is set by --layers (674 at 16 layers; the viscous
    limit adds some at the finest dx) and stays under 4.3e5 at MAX_LAYERS for any allowed dx and
    gravity, so it needs no check."""
    step = stable_step(params.h, params.c0, args.gravity, params.rho0_fluid / params.viscosity)
    steps = t_end / step
    if steps > MAX_CHANNEL_STEPS:
        raise InputError(f"--gravity, --viscosity, --dx, --layers: this channel needs about {steps:.3g} steps of "
                         f"{step:.3g} s to {t_end:.3g} s; at most {MAX_CHANNEL_STEPS:,} are allowed")


def run_case(args) -> int:
    out = new_run_directory(args.out, args.command)
    height = args.layers * args.dx
    if args.command == "hydrostatic":
        params, t_end = cases.hydrostatic_parameters(args.dx, args.layers, args.gravity)
    else:
        params, t_end = cases.poiseuille_parameters(args.dx, args.layers, args.gravity, args.viscosity)
        check_poiseuille_steps(args, params, t_end)
    sim = cases.channel(args.dx, args.layers, params)
    bar, advance = progress_bar(args, t_end)
    status = "finished"
    try:
        sim.run(t_end, record_every=t_end / 200, progress=advance)
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            raise
        status = "interrupted"
    if bar is not None:
        bar.close()
    measure = cases.measure_hydrostatic if args.command == "hydrostatic" else cases.measure_poiseuille
    result = measure(sim, height, args.gravity)
    summary = {"case": args.command, "status": status, **result.summary, **run_figures(sim)}
    config = config_of(args, sim, geometry={"dx_m": args.dx, "layers": args.layers, "side_cells": cases.SIDE_CELLS})
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", sim.record.columns, sim.record.rows)
        write_particles(tmp / "particles.vtu", particle_state(sim))
        profile_figure(tmp / "profile.png", result.profile, f"{args.command}: {summary['steps']} steps, "
                       f"{summary['fluid_particles']} fluid particles", status)
    print(f"{args.command}: {status} after {sim.record.steps} steps; "
          + ", ".join(f"{k} = {v:.4g}" for k, v in result.summary.items() if isinstance(v, float)))
    print(f"run directory: {out}")
    return exit_status(status)


def run_figures(sim) -> dict:
    return {"particles": len(sim.pos), "fluid_particles": int(sim.fluid.sum()), "steps": sim.record.steps,
            "simulated_time_s": sim.t, "wall_time_s": time.perf_counter() - sim.wall_start}


def profile_figure(path: Path, profile, title: str, status: str) -> None:
    from hmdem.plots import plt

    z, measured, zt, theory, label = profile
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(measured, z * 1e3, ".", ms=2, alpha=0.4, label="particles")
    ax.plot(theory, zt * 1e3, "k-", label="theory")
    ax.set_xlabel(label)
    ax.set_ylabel("z [mm]")
    ax.legend()
    ax.set_title(title + stop_note(status, "finished"))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def droplet_parameters(args):
    """(SphParameters, surface tension, where they came from): explicit strengths, a calibrate run
    directory or the package's calibration table (:mod:`sph_bridge.calibrations`). Sets
    ``args.theta`` (the target angle) where it was not given."""
    from .calibrate import sound_speed
    from .simulation import SphParameters

    gravity = (0.0, 0.0, -args.gravity)
    sigma = droplet.SURFACE_TENSION
    if (args.s_ff is None) != (args.s_sf is None):
        raise InputError("--s-ff and --s-sf: give both strengths or neither")
    if args.s_ff is not None:
        strongest = strongest_pair(args.dx)
        for flag, value in (("--s-ff", args.s_ff), ("--s-sf", args.s_sf)):
            if value > strongest:
                raise InputError(f"{flag}: must be at most {strongest:g} N at dx = {args.dx:g} m "
                                 f"({MAX_STRENGTH_PER_DX:g} dx, 1000x the strength near water's surface tension), "
                                 f"got {value:g}")
        args.theta = args.theta or DEFAULT_THETA
        args.anneal = args.anneal or 0.0
        c0 = args.c0 or sound_speed(args.dx)
        return (SphParameters(dx=args.dx, c0=c0, s_ff=args.s_ff, s_sf=args.s_sf, gravity=gravity, anneal=args.anneal,
                              seed=args.seed), sigma, "command line")
    if args.c0 is not None:
        raise InputError("--c0: a calibration fixes c0 (surface tension and angle depend on it); give it with "
                         "--s-ff/--s-sf or calibrate at that c0")
    if args.calibration is not None:
        keys = ("dx_m", "c0_m_per_s", "rho0_fluid", "s_ff_n", "s_sf_n", "surface_tension_n_per_m",
                "target_contact_angle_deg")
        try:
            cal = json.loads((args.calibration / "summary.json").read_text())
            if not isinstance(cal, dict):
                raise ValueError("its summary.json is not a JSON object")
            if cal.get("status") != "finished":  # an interrupted one has no strengths yet
                raise ValueError(f"its status is {cal.get('status')!r}")
            values = {k: float(cal[k]) for k in keys}
            anneal = float(cal.get("anneal_m_per_s", 0.0))  # older calibrations were damped
            if not all(map(math.isfinite, [*values.values(), anneal])):
                raise ValueError("it records a value that is not finite")
            if not (sound_speed_allowed(values["c0_m_per_s"])
                    and max(values["s_ff_n"], values["s_sf_n"]) <= strongest_pair(values["dx_m"])):
                raise ValueError("its c0 or strengths are beyond what --c0, --s-ff and --s-sf allow")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"--calibration: {str(args.calibration)!r} is not a finished calibrate run "
                             f"directory ({exc.__class__.__name__}: {exc})") from None
        if abs(values["dx_m"] / args.dx - 1.0) > 1e-3:
            raise InputError(f"--calibration: calibrated at dx = {values['dx_m']:g} m, not --dx {args.dx:g}")
        if args.theta is not None and abs(args.theta - values["target_contact_angle_deg"]) > 1e-2:
            raise InputError(f"--theta: the calibration targets {values['target_contact_angle_deg']:g}°")
        args.theta = values["target_contact_angle_deg"]
        same_protocol(args, anneal, f"the calibration {str(args.calibration)!r}")
        params = SphParameters(dx=args.dx, c0=values["c0_m_per_s"], rho0_fluid=values["rho0_fluid"],
                               s_ff=values["s_ff_n"], s_sf=values["s_sf_n"], gravity=gravity, anneal=args.anneal,
                               seed=args.seed)
        return params, values["surface_tension_n_per_m"], str(args.calibration)
    args.theta = args.theta or DEFAULT_THETA
    entry = calibrations.lookup(args.dx, args.theta)
    if entry is None:
        raise InputError(f"--theta: no calibration for dx = {args.dx:g} m and theta = {args.theta:g}°; run "
                         f"'{PROG} calibrate --dx {args.dx:g} --theta {args.theta:g}' and pass its run directory "
                         "with --calibration")
    same_protocol(args, entry.anneal, f"the shipped calibration for dx = {args.dx:g} m and theta = {args.theta:g}°")
    params = SphParameters(dx=args.dx, c0=entry.c0, rho0_fluid=entry.rho0_fluid, s_ff=entry.s_ff, s_sf=entry.s_sf,
                           gravity=gravity, anneal=args.anneal, seed=args.seed)
    return params, entry.surface_tension, entry.command


def same_protocol(args, anneal: float, what: str) -> None:
    """A calibrated angle belongs to its relaxation protocol (decisions #57, #59): the droplet
    relaxes as its calibration did; sets ``args.anneal`` where it was not given."""
    if args.anneal is not None and abs(args.anneal - anneal) > 1e-12:
        raise InputError(f"--anneal: {what} relaxed with --anneal {anneal:g}; calibrate with --anneal "
                         f"{args.anneal:g} and pass its run directory with --calibration")
    args.anneal = anneal


def open_checkpoint(directory: Path, out: Path, state: str, restore):
    """Check and lock a ``--checkpoint`` directory whose saved state is the file ``state``, and
    read it: (the lock, to be held for the whole run, and what ``restore()`` returns). A
    directory that is no such checkpoint, or that another run holds, is bad input."""
    try:
        checkpoint.check_directory(directory, out, state=state)
        return checkpoint.hold(directory), restore()
    except (checkpoint.CheckpointError, OSError) as exc:
        raise InputError(f"--checkpoint: {exc}") from None


def drop_cells(volume: float, dx: float) -> float:
    """How many dx^3 cells a drop of ``volume`` fills, rounded off at 1e-6 of a cell (5e-8 m^3 at
    dx = 5e-4 m is 399.99999999999994 in floating point)."""
    return round(volume / dx**3, 6)


def run_droplet(args) -> int:
    cells = drop_cells(args.volume, args.dx)
    if not MIN_DROP_CELLS <= cells <= MAX_DROP_CELLS:
        raise InputError(f"--volume: {args.volume:g} m^3 is {cells:.3g} particles at dx = "
                         f"{args.dx:g} m; from {MIN_DROP_CELLS:,} to {MAX_DROP_CELLS:,} are allowed")
    if args.start_height is not None and args.start_height < MIN_START_LAYERS * args.dx:
        raise InputError(f"--start-height: {args.start_height:g} m is under {MIN_START_LAYERS} particle layers at "
                         f"dx = {args.dx:g} m; at least {MIN_START_LAYERS * args.dx:g} m is allowed")
    params, sigma, source = droplet_parameters(args)
    if args.gravity > 0:
        # a puddle, at most 2 lambda_c tall (the default start), must be resolved like a given
        # --start-height: at 1e300 m/s^2 the particles flew to overflow without end
        puddle = 2.0 * droplet.capillary_length(sigma, params.rho0_fluid, args.gravity)
        if puddle < MIN_START_LAYERS * args.dx:
            largest = sigma / params.rho0_fluid / (MIN_START_LAYERS * args.dx / 2.0) ** 2
            raise InputError(f"--gravity: must be at most {largest:.3g} m/s^2 at dx = {args.dx:g} m, where a "
                             f"puddle, 2 lambda_c, spans {MIN_START_LAYERS} particle layers (or give a finer --dx); "
                             f"got {args.gravity:g}, 2 lambda_c = {puddle:.3g} m")
    out = new_run_directory(args.out, args.command)
    plate_theta = args.theta
    if source == "command line":  # no calibration ties these strengths to --theta (decisions #63)
        plate_theta = min(plate_theta, droplet.pairwise_young_angle_deg(params.s_ff, params.s_sf))
    sim, t_min = droplet.prepare_drop(params, args.volume, sigma, args.ridge, args.start_height, plate_theta)
    start_top = float(sim.pos[sim.fluid, 2].max()) + args.dx / 2  # the starting drop's surface
    shapes, rows, frames = [], [], []  # frames: (t, particle state or the checkpoint's .vtu of it)
    key = None
    if args.checkpoint is not None:
        key = checkpoint.key(sim, t_min, args.volume, args.ridge, args.start_height)
        lock, restored = open_checkpoint(args.checkpoint, out, checkpoint.STATE,  # noqa: F841 (held to the end)
                                         lambda: checkpoint.restore(args.checkpoint, key, sim))
        if restored is not None:
            shapes, rows, frame_times = restored
            frames = [(t, checkpoint.frame_path(args.checkpoint, k)) for k, t in enumerate(frame_times)]
            print(f"droplet: resuming {str(args.checkpoint)!r} at t = {sim.t:.5g} s after {len(shapes)} shape "
                  f"samples ({sim.record.steps} steps)", file=sys.stderr)
    # the bar runs to the shortest relaxation; one that has not settled by then moves it on to its next settle check
    shortest, extend = droplet.relaxation_span(t_min, params.anneal > 0)
    bar, advance = progress_bar(args, shortest, extend=extend, start=sim.t)
    status, settled = "finished", False

    def on_sample(s, k):
        if k % SNAPSHOT_EVERY == 0 or k == 1:
            frames.append((s.t, particle_state(s)))
            if args.checkpoint is not None:  # kept beside the state, not in memory
                frames[-1] = (s.t, checkpoint.save_frame(args.checkpoint, len(frames) - 1, frames[-1][1]))
        if args.checkpoint is not None:
            checkpoint.save(args.checkpoint, key, s, shapes, rows, [t for t, _ in frames])

    try:
        shape, settled = droplet.relax(sim, t_min, args.ridge, progress=advance, on_sample=on_sample, rows=rows,
                                       shapes=shapes)
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            raise
        status = "interrupted"
        shape = droplet.measure(sim, args.ridge)
    finally:  # an error's traceback then starts on a line of its own
        if bar is not None:
            bar.close()
    summary = droplet_summary(args, sim, shape, sigma, source, status)
    summary["settled"] = settled
    summary["height_drift"] = droplet.height_drift(shapes)  # the last settle check's, for a drop that has not settled
    if status == "finished" and not settled:
        print(f"droplet: warning: the drop had not settled after {droplet.MAX_EXTENSION} times its minimum relaxation "
              f"(its mean height still moved {summary['height_drift']:+.2%} over the last quarter, settled below "
              f"{droplet.SETTLED:.1%}): its shape is the last quarter's mean", file=sys.stderr)
    summary["plate_sized_for_deg"] = plate_theta if args.gravity > 0 else math.nan
    if summary["plate_edge_clearance_m"] < droplet.INTERACTION_RANGE * sim.params.h:  # NaN: no shape, no warning
        print(f"droplet: warning: the contact line ended {summary['plate_edge_clearance_m'] * 1e3:.2f} mm from the "
              f"plate's edge, inside the pairwise range 2h = {droplet.INTERACTION_RANGE * sim.params.h * 1e3:.2f} mm: "
              "the edge, not the wetting, may have held it",
              file=sys.stderr)
    config = config_of(args, sim, geometry={"dx_m": args.dx, "volume_m3": args.volume, "ridge": args.ridge,
                                            "start_top_m": start_top,
                                            "ridge_length_m": droplet.RIDGE_LENGTH * args.dx if args.ridge else 0.0},
                       calibration={"source": source})
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", ("t", "kinetic_energy_j", "height_m", "width_m", "contact_angle_deg"), rows)
        write_frames(tmp, sim, frames)
        side_view(tmp / "side_view.png", sim, shape, summary, args.ridge)
    print(f"droplet: {status} after {sim.record.steps} steps; height {shape.height * 1e3:.3f} mm, width "
          f"{shape.width * 1e3:.3f} mm, h/w {summary['aspect']:.4f}, cap angle 2 atan(2h/w) "
          f"{shape.contact_angle_deg:.1f}° (target {args.theta:g}°)")
    if summary.get("bond_number", 0.0) > 1.0:  # gravity flattens it: its h/w is no cap's, its height is the test
        print(f"droplet: Bond number {summary['bond_number']:.1f}, a puddle: height against 2 λc sin(θ/2) = "
              f"{summary['puddle_height_m'] * 1e3:.3f} mm ({summary['puddle_height_error']:+.1%}), Young-Laplace "
              f"{summary['young_laplace_height_m'] * 1e3:.3f} mm")
    print(f"run directory: {out}")
    return exit_status(status)


def droplet_summary(args, sim, shape, sigma, source, status) -> dict:
    """Measured shape against the spherical cap, de Gennes' puddle and the Young-Laplace drop of
    the same volume (at the target angle, the calibration's surface tension and the fluid's
    bulk density)."""
    from .simulation import FULL_KERNEL
    from .young_laplace import sessile_height

    f = sim.fluid
    full = f & (sim.number_density >= FULL_KERNEL * sim.bulk_number_density)
    rho = float(sim.rho[full].mean()) if full.any() else float(sim.params.rho0_fluid)
    g = args.gravity
    lam = droplet.capillary_length(sigma, rho, g) if g > 0 else math.inf
    volume = float(sim.mass[f].sum()) / rho
    if args.ridge:
        volume /= droplet.RIDGE_LENGTH * args.dx
    try:
        yl_height, yl_width = sessile_height(volume, args.theta, lam, axisymmetric=not args.ridge)
    except ValueError:
        yl_height = yl_width = math.nan
    aspect = shape.height / shape.width if shape.width > 0 else math.nan
    summary = {"case": "droplet", "status": status, "geometry": "ridge" if args.ridge else "drop",
               "calibration": source, "s_ff_n": sim.params.s_ff, "s_sf_n": sim.params.s_sf,
               "c0_m_per_s": sim.params.c0, "rho0_fluid": sim.params.rho0_fluid, "surface_tension_n_per_m": sigma,
               "anneal_m_per_s": sim.params.anneal, "seed": sim.params.seed,
               "height_m": shape.height, "width_m": shape.width, "aspect": aspect,
               "contact_angle_deg": shape.contact_angle_deg, "target_contact_angle_deg": args.theta,
               "contact_angle_error_deg": shape.contact_angle_deg - args.theta,
               "fitted_contact_angle_deg": shape.fitted_angle_deg, "cap_fit_rms_m": shape.fit_rms,
               "cap_aspect": droplet.cap_aspect(args.theta), "bulk_density_kg_per_m3": rho,
               "fluid_volume_m3": volume * (droplet.RIDGE_LENGTH * args.dx if args.ridge else 1.0),
               "young_laplace_height_m": yl_height, "young_laplace_width_m": yl_width,
               "height_error": shape.height / yl_height - 1.0,
               "plate_half_width_m": droplet.plate_half_width(sim),
               "plate_edge_clearance_m": droplet.plate_edge_clearance(sim, shape, args.ridge)}
    if g > 0:
        puddle = droplet.puddle_height(sigma, rho, g, args.theta)
        summary.update({"capillary_length_m": lam, "puddle_height_m": puddle,
                        "puddle_height_error": shape.height / puddle - 1.0,
                        "bond_number": rho * g * (shape.width / 2) ** 2 / sigma})
    summary["final_kinetic_energy_j"] = sim.state_row()[2]
    summary["near_wall_rms_speed_m_per_s"], summary["upper_rms_speed_m_per_s"] = droplet.rms_speeds(sim)
    summary.update(run_figures(sim))
    return summary


def write_frames(tmp: Path, sim, frames) -> None:
    """particles_NNNN.vtu per frame (a state, or a checkpoint's file of it) and particles.pvd listing them; the
    final state as particles.vtu. The series ends with the final state, so that a run stopped before its first
    sample still has a frame to open in ParaView."""
    final = particle_state(sim)
    if not frames or frames[-1][0] < sim.t:
        frames = [*frames, (sim.t, final)]
    names = []
    for k, (t, state) in enumerate(frames):
        names.append((t, f"particles_{k:04d}.vtu"))
        if isinstance(state, Path):  # a frame a checkpoint holds
            shutil.copyfile(state, tmp / names[-1][1])
        else:
            write_particles(tmp / names[-1][1], state)
    write_collection(tmp / "particles.pvd", names)
    write_particles(tmp / "particles.vtu", final)


def side_view(path: Path, sim, shape, summary: dict, ridge: bool) -> None:
    """Fluid particles seen from the side (x-z) with the fitted cap and the theoretical heights."""
    from hmdem.plots import plt

    f = sim.fluid
    pos, walls = sim.pos[f], sim.pos[~f]
    centre = pos[:, :2].mean(axis=0)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot((walls[:, 0] - centre[0]) * 1e3, walls[:, 2] * 1e3, ".", color="0.75", ms=2)
    ax.plot((pos[:, 0] - centre[0]) * 1e3, pos[:, 2] * 1e3, ".", color="tab:blue", ms=3, alpha=0.3)
    if math.isfinite(shape.cap_radius):
        phi = np.linspace(0, 2 * math.pi, 400)
        x, z = shape.cap_radius * np.cos(phi), shape.cap_centre_z + shape.cap_radius * np.sin(phi)
        keep = z >= 0
        fitted = "circle" if summary.get("geometry") == "ridge" else "sphere"  # a ridge's section is a circle
        ax.plot(x[keep] * 1e3, z[keep] * 1e3, "k-", lw=1, label=f"fitted {fitted}: {shape.fitted_angle_deg:.1f}°")
    ax.axhline(summary["young_laplace_height_m"] * 1e3, color="tab:green", ls="--", lw=1,
               label=f"Young-Laplace at {summary['target_contact_angle_deg']:g}°")
    if "puddle_height_m" in summary:
        ax.axhline(summary["puddle_height_m"] * 1e3, color="tab:red", ls=":", lw=1, label="2 λc sin(θ/2)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title(f"{summary['geometry']}: h = {shape.height * 1e3:.3f} mm, w = {shape.width * 1e3:.3f} mm, "
                 f"cap angle {shape.contact_angle_deg:.1f}°, {summary['fluid_particles']} particles"
                 f"{stop_note(summary['status'], 'finished')}"
                 f"{' (not settled)' if summary['status'] == 'finished' and not summary['settled'] else ''}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def run_calibrate(args) -> int:
    from .calibrate import Calibration, ReplayMismatch, calibrate, protocol, sound_speed

    out = new_run_directory(args.out, args.command)
    cal = Calibration(dx=args.dx, c0=args.c0 or sound_speed(args.dx), anneal=args.anneal)
    targets = {"dx_m": args.dx, "theta_deg": args.theta, "surface_tension_n_per_m": args.surface_tension,
               "c0_m_per_s": cal.c0, "ridge_sizes_dx": list(args.ridge_sizes), "anneal_m_per_s": args.anneal}
    identity = {**targets, **{f"protocol.{name}": value for name, value in protocol().items()}}
    replay = []
    if args.checkpoint is not None:
        lock, replay = open_checkpoint(args.checkpoint, out, checkpoint.TRIALS,  # noqa: F841 (held to the end)
                                       lambda: checkpoint.restore_trials(args.checkpoint, identity))
    start = time.perf_counter()
    bar = None  # the running simulation's, one at a time: a slab, or each ridge of a contact-angle trial

    def trial_bar(label, duration, extend):
        nonlocal bar
        close_bar()
        bar, advance = progress_bar(args, duration, extend=extend, desc=f"trial {len(cal.trials) + 1}: {label}",
                                    leave=False)
        return advance

    def close_bar():
        if bar is not None:
            bar.close()

    def report(trial):
        close_bar()  # the trial's line replaces its bar
        if args.checkpoint is not None:
            checkpoint.save_trials(args.checkpoint, identity, cal.trials)
        if not args.quiet:
            if trial.stage == "tension":
                what = f"sigma = {trial.measured:.4f} N/m, bulk {trial.bulk_density:.1f} kg/m^3"
            else:
                what = f"theta = {trial.measured:.2f}°"
                if len(trial.ridge_angles_deg) > 1:
                    what += " (ridges: " + ", ".join(f"{a:.2f}°" for a in trial.ridge_angles_deg) + ")"
                if trial.ridges_unsettled > 0:
                    what += f", {trial.ridges_unsettled:.0f} ridge(s) not settled"
            print(f"  {trial.stage}: s_ff = {trial.s_ff:.4g} N, s_sf = {trial.s_sf:.4g} N, rho0 = "
                  f"{trial.rho0_fluid:.1f}: {what} ({trial.steps} steps, {time.perf_counter() - start:.0f} s)",
                  flush=True)

    status, error = "finished", ""
    try:
        calibrate(args.dx, args.theta, args.surface_tension, report=report, cal=cal,
                  ridge_sizes=tuple(args.ridge_sizes), replay=replay,
                  on_replayed=lambda: print(f"calibrate: took the {len(replay)} trials saved in "
                                            f"{str(args.checkpoint)!r}", file=sys.stderr),
                  progress=trial_bar)
    except ReplayMismatch as exc:
        raise InputError(f"--checkpoint: {str(args.checkpoint)!r}: {exc}") from None
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            raise
        status = "interrupted"
    except RuntimeError as exc:
        status, error = "not_converged", str(exc)
    finally:
        close_bar()
    summary = {"case": "calibrate", "status": status, "dx_m": args.dx, "c0_m_per_s": cal.c0,
               "rho0_fluid": cal.rho0_fluid, "s_ff_n": cal.s_ff, "s_sf_n": cal.s_sf,
               "surface_tension_n_per_m": cal.surface_tension, "target_surface_tension_n_per_m": args.surface_tension,
               "bulk_density_kg_per_m3": cal.bulk_density, "contact_angle_deg": cal.contact_angle_deg,
               "target_contact_angle_deg": args.theta, "ridge_sizes_dx": list(args.ridge_sizes),
               "anneal_m_per_s": args.anneal, "trials": len(cal.trials), "replayed_trials": len(replay),
               "steps": sum(t.steps for t in cal.trials), "wall_time_s": time.perf_counter() - start}
    if error:
        summary["error"] = error
    # the angle found is the last contact-angle trial's: did its ridges settle (null: not recorded)?
    angle_trials = [t for t in cal.trials if t.stage == "contact_angle"]
    unsettled = angle_trials[-1].ridges_unsettled if angle_trials else 0
    summary["ridges_settled"] = None if math.isnan(unsettled) else bool(unsettled == 0)
    if status == "finished" and unsettled > 0:
        print(f"calibrate: warning: {unsettled:.0f} of the last trial's {len(args.ridge_sizes)} ridge(s) had not "
              f"settled by {droplet.MAX_EXTENSION} times their minimum relaxation: its angle, and so s_sf, is of a "
              "ridge still moving", file=sys.stderr)
    config = {"run": run_table(PROG, args.argv, "calibrate"), "targets": targets}
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        columns = ("stage", "s_ff_n", "s_sf_n", "rho0_fluid", "measured", "bulk_density_kg_per_m3", "steps",
                   "ridge_angles_deg", "ridges_unsettled")
        rows = [(t.stage, t.s_ff, t.s_sf, t.rho0_fluid, t.measured, t.bulk_density, t.steps,
                 " ".join(f"{a:.3f}" for a in t.ridge_angles_deg), t.ridges_unsettled) for t in cal.trials]
        write_rows(tmp / "timeseries.csv", columns, rows)
    # a stage not finished has found nothing yet (its values are null in summary.json)
    found = [f"after {len(cal.trials)} trial(s)"]
    found.append("s_ff not found yet" if math.isnan(cal.s_ff) else
                 f"s_ff = {cal.s_ff:.4g} N, rho0 = {cal.rho0_fluid:.1f} kg/m^3 (sigma {cal.surface_tension:.4f} N/m)")
    if not math.isnan(cal.s_ff):
        found.append("s_sf not found yet" if math.isnan(cal.s_sf) else
                     f"s_sf = {cal.s_sf:.4g} N (theta {cal.contact_angle_deg:.2f}°)")
    print(f"calibrate: {status} " + ", ".join(found) + (f": {error}" if error else ""))
    print(f"run directory: {out}")
    return exit_status(status)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["lga"]:  # the lattice-gas studies have their own parser (sph_bridge.lga.cli)
        from .lga.cli import main as lga_main

        return lga_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv  # recorded in config.toml
    return dispatch(PROG, parser, args, {"hydrostatic": run_case, "poiseuille": run_case, "droplet": run_droplet,
                                         "calibrate": run_calibrate})


if __name__ == "__main__":
    raise SystemExit(main())
