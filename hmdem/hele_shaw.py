"""Command line: two-phase displacement in a granular Hele-Shaw cell (seed 004).

    python -m hmdem.hele_shaw                       # the vf case into a fresh run directory
    python -m hmdem.hele_shaw linear --case cf1 --seed 3 --out runs/cf1
    python -m hmdem.hele_shaw radial --case A3 --out runs/a3   # movable grains (YADE)
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

from . import __version__
from .cases import CASES, default_packing_path
from .cli import (InputError, OneLineParser, add_contact_arguments, check_aperture_fits_grains, contact_gap_fraction,
                  dispatch, interrupt_reason, interrupted_status, local_damping, near_contacts_checked,
                  new_run_directory, non_negative_int, number_in, positive_int, positive_number,
                  read_compacted_packing, read_packing, relative_tolerance, seed_value)
from .flow.darcy_transient import STEADY_T_D, read_darcy_test
from .flow.fluids import WEAK_COMPRESSION
from .interrupts import deferred_interrupts
from .network.contact_graph import BOUNDARY_HOLDS, NEAR_CONTACT_GAP
from .network.packing import GRAIN_DENSITY
from .snapshots import SnapshotRecorder
from .sweep.grid import LOG_CA_STAR_RANGE, LOG_M_RANGE

PROG = "python -m hmdem.hele_shaw"

CASE_NAMES = tuple(CASES)
RADIAL_NAMES = ("A1", "A3", "B1", "B3")
EXPLICIT_DEFAULT_MAX_STEPS = 100_000


def within_powers_of_ten(value: float, log_range: tuple[float, float]) -> bool:
    """Whether ``value`` lies in [10^a, 10^b] (to round-off at the ends)."""
    low, high = (10.0 ** e for e in log_range)
    return low * (1 - 1e-12) <= value <= high * (1 + 1e-12)


def power_of_ten_within(log_range: tuple[float, float]):
    """argparse type: a number in [10^a, 10^b], where the runs were measured to reach
    breakthrough (the sweep's axes, decisions #77, #78, #90): M = 1e300 was taken and ran for ever
    with nothing invaded, its pipes' conductances underflowing (a new-user pass)."""
    return number_in(f"a number in [1e{log_range[0]:g}, 1e{log_range[1]:g}] (where runs were measured to reach "
                     "breakthrough)", lambda v: within_powers_of_ten(v, log_range))


viscosity_ratio = power_of_ten_within(LOG_M_RANGE)
modified_capillary_number = power_of_ten_within(LOG_CA_STAR_RANGE)
# the narrowest mean aperture a linear run takes [m]: the seeds' smallest is Huang's a0 = 7.53 um;
# at 1e-12 m vf's entry pressures reached 1 GPa (decisions #94)
SMALLEST_MEAN_APERTURE = 1e-6
mean_aperture = number_in(f"a number >= {SMALLEST_MEAN_APERTURE:g} m", lambda v: v >= SMALLEST_MEAN_APERTURE)


class _Parser(OneLineParser):
    command = PROG


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    lin = sub.add_parser("linear", help="fixed-grain cases of seed 004 §4.1 and App. D")
    lin.add_argument("--case", choices=CASE_NAMES, default="vf", help="vf, cf1, sd, cf2 (Lenormand), chen, darcy (default vf)")
    rate = lin.add_mutually_exclusive_group()
    rate.add_argument("--ca-star", type=modified_capillary_number,
                      help="modified capillary number Ca* (seed 004 Eq. 24), in [1e-10, 1e4]")
    rate.add_argument("--rate", type=positive_number, help="injection rate Q [m^3/s per metre of cell depth]")
    lin.add_argument("--viscosity-ratio", type=viscosity_ratio,
                     help="M = eta_inv / eta_def in [1e-6, 1e6]; eta_def is kept, eta_inv = M eta_def")
    lin.add_argument("--mean-aperture", type=mean_aperture,
                     help=f"mean pipe aperture [m], at least {SMALLEST_MEAN_APERTURE:g} (default 0.42e-3)")
    lin.add_argument("--seed", type=seed_value, default=0, help="aperture field seed (default 0)")
    lin.add_argument("--dt", type=positive_number,
                     help="nominal flow step [s] (default per case, scaled with the rate when --ca-star, "
                          "--viscosity-ratio, --rate or --mean-aperture change it; darcy's is its own)")
    lin.add_argument("--scheme", choices=("implicit", "explicit"), default="implicit")
    lin.add_argument("--inlet", choices=("manifold", "split"), default="manifold",
                     help="manifold: inflow domains share one pressure (default); split: Q/N_in each")
    add_run_options(lin, "the shipped 65 mm packing")

    rad = sub.add_parser("radial", help="movable-grain Huang cases of seed 004 §4.2 (YADE)")
    rad.add_argument("--case", choices=RADIAL_NAMES, default="A1", help="A1, A3 (5 cP), B1, B3 (176 cP) (default A1)")
    rad.add_argument("--viscosity-ratio", type=viscosity_ratio,
                     help="M = eta_inv / eta_air in [1e-6, 1e6]; eta_inv = M x 0.018 cP")
    rad_rate = rad.add_mutually_exclusive_group()
    rad_rate.add_argument("--ca-star", type=modified_capillary_number,
                          help="modified capillary number Ca* (seed 004 Eq. 24), in [1e-10, 1e4]; Q follows from it")
    rad_rate.add_argument("--rate", type=positive_number,
                          help="injection rate Q [m^3/s per metre of cell depth] instead; its Ca* (Eq. 24, with "
                               "--sigma) must lie in --ca-star's range")
    rad.add_argument("--sigma", type=positive_number,
                     help="inlet perimeter Sigma of Ca* [m] (default 0.2 x sample side: the paper's 0.25 mm of "
                          "1.25 mm; the injection domain's own perimeter is in summary.json)")
    rad.add_argument("--one-way", action="store_true",
                     help="sequential coupling: grains move, dV is left out of the pressure equation")
    rad.add_argument("--one-way-volume", choices=("ignored", "lagged"),
                     help="with --one-way: the grains' volume change is left out (default) or enters the next "
                          "step's pressure solve, one step late (decisions #66)")
    rad.add_argument("--dt", type=positive_number, help="nominal flow step [s] (default per case, Table 4)")
    rad.add_argument("--grain-density", type=positive_number, default=GRAIN_DENSITY,
                     help="density of the 1 m-thick discs [kg/m^3] (default %(default)g, Table 2); heavier grains yield "
                          "more slowly to the injection pressure (BENCHMARKS.md: B3's port)")
    rad.add_argument("--fixed-port", action="store_true",
                     help="hold the grains around the injection domain in place, a rigid injection tube whose "
                          "pipes keep their apertures (default: only the boundary grains are fixed; decisions #68)")
    rad.add_argument("--boundary", choices=BOUNDARY_HOLDS, default="fixed",
                     help="fixed: the boundary grains are held in place, the seed's sealed cell edges (default); "
                          "loaded: each moves along the normal of its side, and spins, under the constant inward "
                          "force that held it once the sample settled, a stress-controlled boundary at the sample's "
                          "confining stress (corner grains and those the hold did not push stay held; decisions #86)")
    rad.add_argument("--contact-gap", type=contact_gap_fraction,
                     help="grain pairs closer than this fraction of the smaller radius are pipes, starting "
                          f"detached with the Eq. 14 aperture (default {NEAR_CONTACT_GAP:g}, as for the Lenormand "
                          "packing; 0.38 gives about the paper's 3,490 pipes and 141 outflow domains: decisions #73)")
    add_contact_arguments(rad, stiffness=False)  # k_n is the packing's: compaction --contact-stiffness
    rad.add_argument("--dem-cycles", type=positive_int,
                     help="DEM cycles per flow step at least (the paper: 2000), more where the stable DEM "
                          "step needs them; default: as the stable DEM step needs")
    rad.add_argument("--pv-tol", type=relative_tolerance,
                     help="P-V iteration relative tolerance, of the largest |p| (default 1e-3)")
    rad.add_argument("--pv-test", choices=("every", "inflow"),
                     help="where |p_calc - p_trial| must be within the tolerance: in every domain (default, "
                          "decisions #18) or in the inflow domains only, as seed 004 §3.2 tests it (paper-size B3 "
                          "then runs away at 0.63 ms: decisions #83)")
    rad.add_argument("--pv-max-iter", type=positive_int,
                     help="P-V iteration cap per attempt (default 12; 24 for B1)")
    rad.add_argument("--pv-grow-after", type=positive_int,
                     help="easy steps in a row before a halved flow-step cap doubles back (default 1)")
    rad.add_argument("--pv-reuse-steps", type=non_negative_int,
                     help="earlier flow steps (same dt) whose secant pairs the quasi-Newton update reuses "
                          "(default 5; 0 for B1, whose map changes from step to step: BENCHMARKS.md)")
    rad.add_argument("--pv-max-columns", type=positive_int,
                     help="secant pairs the quasi-Newton update fits at most: the newest, and past the cap the "
                          "step's largest residual change in the last slot (default 40; 4 for B1, where fits to "
                          "older pairs stall the iteration: decisions #56, #81)")
    rad.add_argument("--pocket-newton", action=argparse.BooleanOptionalAction, default=None,
                     help="a scalar Newton step on each trapped pocket after the quasi-Newton update "
                          "(hmdem/coupling/pockets.py; default on, off for B1 and B3); --no-pocket-newton leaves "
                          "the pockets to the quasi-Newton update alone")
    rad.add_argument("--skeleton-newton", action=argparse.BooleanOptionalAction, default=None,
                     help="precondition the quasi-Newton update with the Newton step of the linearised grain "
                          "skeleton (hmdem/coupling/skeleton.py; default on, off for A3); --no-skeleton-newton "
                          "gives the plain quasi-Newton update")
    rad.add_argument("--replica", action=argparse.BooleanOptionalAction, default=None,
                     help="iterate the P-V map on a numba replica of the YADE disc scene and run YADE once per "
                          "attempt at the converged pressures, keeping YADE's run when it passes the test "
                          "(hmdem/coupling/replica.py, decisions #65; default on); --no-replica evaluates every "
                          "iteration in YADE")
    rad.add_argument("--damping", type=local_damping,
                     help="YADE local damping of the grains during the run, in [0, 1) (default 0.7, PFC2D's; the "
                          "seed does not state it; the sample settles at 0.7 either way)")
    rad.add_argument("--threads", type=positive_int,
                     help="OpenMP threads of the DEM (YADE): 2 runs its cycles up to 1.7x faster on 2 cores but "
                          "the run is then not bit-reproducible (default 1, or as yade -jN / OMP_NUM_THREADS say)")
    pv = rad.add_mutually_exclusive_group()
    pv.add_argument("--pv-rewind", action="store_true",
                    help="rewind the DEM to t^n before each P-V iteration, quasi-Newton update (default)")
    pv.add_argument("--pv-continue", action="store_true",
                    help="continue the DEM between P-V iterations, p_trial <- p_calc (digest §6)")
    add_run_options(rad, "the shipped Huang sample")
    return parser


def add_run_options(sub: argparse.ArgumentParser, default_packing: str) -> None:
    """Stopping, input and output flags shared by the linear and radial commands."""
    sub.add_argument("--t-max", type=positive_number, help="stop at this simulated time [s]")
    sub.add_argument("--max-steps", type=positive_int, help="stop after this many steps")
    sub.add_argument("--packing", type=Path, help=f"packing .npz (default: {default_packing})")
    sub.add_argument("--out", type=Path, help="run directory to create (default runs/<case>-<time>-<pid>)")
    sub.add_argument("--quiet", action="store_true", help="no progress bar")
    sub.add_argument("--snapshots", type=positive_int,
                     help="keep N ParaView snapshots as the front advances (each 1/N of its way to the outflow; "
                          "t_max for single-phase runs) and the final state: domains.pvd (and contacts.pvd with "
                          "moving grains) over snapshots/*.vtu")


LONGEST_FILL_TIME = 1e300  # [s]: a run's clock, its steps and its plots stay inside double precision


def given_flags(args, names) -> list[str]:
    """``--flag value`` of each of ``names`` (argparse dests) the command line gave."""
    return [f"--{name.replace('_', '-')} {getattr(args, name):g}" for name in names if getattr(args, name) is not None]


def check_fill_time(args, pore_volume: float, rate: float, displacement: bool = True) -> None:
    """An :class:`InputError` naming the rate flags when the injection rate Q they give would fill
    the pores (``pore_volume`` / Q) in more than ``LONGEST_FILL_TIME``: ``--viscosity-ratio
    1e300`` scaled the flow step to 3e303 s, and the run's plot overflowed at t = 1.2e308 s.
    In a ``displacement``, --dt is at most that fill time: no step is longer (Eq. 18 fills one
    domain a step), and --dt 1e200 made the pressure matrix singular (a new-user pass)."""
    fill_time = pore_volume / rate if rate else math.inf
    flags = given_flags(args, ("rate", "ca_star", "viscosity_ratio"))
    if flags and rate and not fill_time < LONGEST_FILL_TIME:
        raise InputError(f"{', '.join(flags)}: must give an injection rate that fills the pores within "
                         f"{LONGEST_FILL_TIME:g} s; this one, Q = {rate:.3g} m^2/s, takes {fill_time:.3g} s")
    if displacement and args.dt is not None and args.dt > fill_time:
        raise InputError(f"--dt: must be at most the {fill_time:.3g} s the injection takes to fill the pores; "
                         f"got {args.dt:g}")


def check_ca_star_bounds(args, case, ca_star: float) -> None:
    """An :class:`InputError` naming ``--rate`` / ``--mean-aperture`` (and ``--viscosity-ratio``,
    which enters Eq. 24 through eta_inv) when the Ca* they give a two-phase run leaves
    ``--ca-star``'s range: ``--rate 1e30`` and ``1e-300`` ran for ever, past the fill-time
    bound's reach (a new-user pass; decisions #94)."""
    if args.rate is None and args.mean_aperture is None:
        return  # Ca* is --ca-star's, or the named case's
    if case.two_phase:
        require_ca_star_in_range(given_flags(args, ("rate", "mean_aperture", "viscosity_ratio")), ca_star)


def require_ca_star_in_range(flags: list[str], ca_star: float) -> None:
    """An :class:`InputError` naming ``flags`` when the Ca* they give leaves ``--ca-star``'s range."""
    if not within_powers_of_ten(ca_star, LOG_CA_STAR_RANGE):
        raise InputError(f"{', '.join(flags)}: must give a Ca* (Eq. 24) in [1e{LOG_CA_STAR_RANGE[0]:g}, "
                         f"1e{LOG_CA_STAR_RANGE[1]:g}], --ca-star's range; these give {ca_star:.3g}")


def make_case(args):
    """The named case with the command-line overrides applied.

    Without ``--dt``, an override of the rate (``--rate``, or Ca*, viscosity or aperture through
    Q = Ca* Sigma gamma a / (eta_inv L), Eq. 24) scales the case's nominal step with the fill
    time, dt x Q_case / Q (:func:`hmdem.scenario.build_scenario`, where Sigma and L are known).
    The front criteria (Eqs. 18-19) shorten steps where they must; the nominal step only sets
    how finely a smooth stretch is resolved, as the same fraction of the run. ``--rate`` and
    ``--mean-aperture`` used to keep the case's step: vf at its own Q given by --rate took
    20 times the steps of the same run given by --ca-star (a new-user pass)."""
    case = CASES[args.case]
    changes = {k: getattr(args, k) for k in ("dt", "mean_aperture", "t_max") if getattr(args, k) is not None}
    if args.viscosity_ratio is not None:
        if not case.two_phase:  # one fluid fills the pores: its pipes would ignore eta_inv
            raise InputError(f"--viscosity-ratio: the {case.name} case is single-phase (one fluid, M = 1); "
                             "leave it out")
        changes["fluids"] = replace(case.fluids, viscosity_inv=args.viscosity_ratio * case.fluids.viscosity_def)
    if args.ca_star is not None:
        if not case.two_phase:  # Eq. 24's Ca* is a displacement's: darcy at --ca-star 1e-3 ran at 1.2 Pa
            raise InputError(f"--ca-star: the {case.name} case is single-phase, with no capillary number; "
                             "set its rate with --rate")
        changes.update(ca_star=args.ca_star, rate=None)
    if args.rate is not None:
        changes["rate"] = args.rate
    if args.dt is None and case.ca_star is not None:
        changes["dt_follows_rate"] = True
    return replace(case, **changes)


class FrontProgress:
    """tqdm bar of the front's progress (two-phase) or of simulated time (single phase)."""

    def __init__(self, name, setup, every_s: float = 0.2):
        from tqdm import tqdm

        self.setup, self.every_s, self.last = setup, every_s, 0.0
        self.bar = tqdm(total=100, unit="%", desc=f"{name} {'front' if setup.two_phase else 'time'}", file=sys.stderr,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}{postfix}]")

    def __call__(self, model, state):
        now = time.perf_counter()
        if now - self.last < self.every_s:
            return
        self.last = now
        self.show(model, state)

    def show(self, model, state):
        self.bar.n = round(100 * model.fraction_done(state), 1)
        invaded = f", invaded={int(state.invaded.sum())}" if self.setup.two_phase else ""
        self.bar.set_postfix_str(f"t={state.t:.4g} s, steps={model.record.steps}{invaded}")  # and redraws

    def close(self, model, state):
        """The last step's numbers, and a full bar for a run that reached its end (breakthrough or
        t_max); a bar left at a throttled earlier step showed 92 % for a finished darcy run."""
        self.show(model, state)
        if model.record.status in ("breakthrough", "t_max"):
            self.bar.n = 100
        self.bar.refresh()
        self.bar.close()


def recorded_argv(args) -> list[str]:
    """The arguments config.toml records: ``args.argv``, set by :func:`main` (also when a YADE
    script calls it) and by the sweep runner, else the process's own."""
    return getattr(args, "argv", sys.argv[1:])


def run_watched(model, name: str, setup, args):
    """``model.run()`` with the progress bar (unless --quiet) and the --snapshots recorder the
    flags ask for: (state, record, bar, snapshots). An interrupted run's ``status_message``
    names the signal that stopped it."""
    bar = None if args.quiet else FrontProgress(name, setup)
    snapshots = None if args.snapshots is None else SnapshotRecorder(args.snapshots)
    state, rec = model.run(progress=each_step(bar, snapshots))
    if rec.status == "interrupted":
        rec.message = interrupt_reason()
    return state, rec, bar, snapshots


def run_linear(args) -> int:
    """One linear run from parsed arguments; config.toml records :func:`recorded_argv`."""
    from .report import dimension_note, packing_record, write_run
    from .scenario import build_scenario
    from .flow.simulation import FlowModel

    if args.packing is not None:
        if CASES[args.case].geometry == "lattice":
            raise InputError(f"--packing: the {args.case} case is a square lattice (App. D.2); it takes no packing")
        read_packing(args.packing)  # a missing or unreadable file stops here, before any work
    out = new_run_directory(args.out, args.case)
    case = make_case(args)
    packing = None if case.geometry == "lattice" else packing_record(
        args.packing or default_packing_path(), getattr(args, "packing_recorded", None))  # set by the sweep runner
    with near_contacts_checked():
        sc = build_scenario(case, seed=args.seed, inlet=args.inlet, scheme=args.scheme, packing_path=args.packing)
    check_aperture_fits_grains(case.mean_aperture, sc.packing_radii, args.mean_aperture is not None)
    check_ca_star_bounds(args, case, sc.ca_star)
    check_fill_time(args, float(sc.net.domain_volume.sum()), sc.setup.rate, displacement=case.two_phase)
    if args.max_steps is not None:
        sc.setup.max_steps = args.max_steps
    elif args.scheme == "explicit" and args.t_max is None:
        # the explicit step is ~1e-8 s: a run to breakthrough would take ~1e9 steps
        sc.setup.max_steps = EXPLICIT_DEFAULT_MAX_STEPS
        print(f"{PROG}: warning: the explicit scheme stops after {EXPLICIT_DEFAULT_MAX_STEPS} steps "
              "(set --max-steps or --t-max)", file=sys.stderr)
    model = FlowModel(sc.net, sc.setup)
    state, rec, bar, snapshots = run_watched(model, case.name, sc.setup, args)
    with deferred_interrupts():  # the run is over: a signal now stops the command once it is written
        if bar is not None:
            bar.close(model, state)
        # read against App. D.1 only when the run went to its end: k is read on the last step's drop
        darcy = read_darcy_run(sc, rec, state) if case.name == "darcy" and rec.status == "t_max" else None
        summary = write_run(out, sc, model, state, rec, seed=args.seed, argv=recorded_argv(args),
                            snapshots=None if snapshots is None else snapshots.taken,
                            packing=packing,
                            summary_extra=None if darcy is None else darcy.summary(),
                            extra_files=darcy.write_figure if darcy is not None and darcy.steady else None)
    print(f"{case.name}: {rec.status} at t = {state.t:.4g} s after {rec.steps} steps; regime: {summary['regime']}, "
          f"{dimension_note(summary['fractal_dimension'])}, peak injection pressure {summary['peak_injection_pressure_pa']:.4g} Pa")
    if darcy is not None and not darcy.steady:
        print(f"{case.name}: not steady at its end (t_D < {STEADY_T_D:g}), so k and the comparison with App. D.1 "
              "are not read; give a longer --t-max")
    elif darcy is not None:
        print(f"{case.name}: k = {darcy.permeability:.4g} m^2 (Eq. 21 at the last step); against App. D.1's Eqs. 37-38 "
              f"the largest errors are {darcy.inflow_pressure_error:.1%} (p_in), {darcy.outflow_rate_error:.1%} (q_out), "
              f"{darcy.profile_error:.1%} (final profile): {'within' if darcy.within_u16 else 'outside'} U16's 5 %")
    print(f"run directory: {out}")
    # a sweep's worker runs in a scratch copy: its warnings name the run directory the sweep keeps
    return finish(rec, summary, getattr(args, "shown_out", None) or out)


def read_darcy_run(sc, rec, state):
    """The darcy case's run against seed 004 App. D.1 (:mod:`hmdem.flow.darcy_transient`); the
    Lenormand sample's injection area sigma is its height H (digest §10.1)."""
    times, injection_pressure, outflow = rec.series("t", "p_in_mean", "q_out")
    return read_darcy_test(sc.net, sc.setup, sc.sigma, times, injection_pressure, outflow, state.pressure)


def each_step(*callbacks):
    """One progress callback calling those given (None ones left out)."""
    called = [c for c in callbacks if c is not None]
    if not called:
        return None

    def progress(model, state):
        for callback in called:
            callback(model, state)

    return progress


def busy_cores_warning(threads: int | None) -> str | None:
    """A warning when YADE is asked for more OpenMP threads than the machine has idle cores (the
    1-minute load average taken as the busy ones): its threads then wait on each other, and on
    2 vCPUs with the other busy 10 B3 steps took 50-52 s on two threads against 3.5 s on one."""
    if not threads or threads < 2:
        return None
    busy, cores = os.getloadavg()[0], os.cpu_count() or 1
    if busy + threads <= cores + 0.5:
        return None
    return (f"{PROG}: warning: --threads {threads} with a load of {busy:.1f} on {cores} cores; YADE's threads "
            f"will wait on each other, and --threads 1 may be many times faster")


def finish(rec, summary: dict, out: Path) -> int:
    """Warnings, naming the run directory (a sweep runs many side by side), then the exit
    status: 0 for a finished run, 130 (Ctrl-C) or 143 (SIGTERM) if interrupted, 1 if it could
    not go on (reason on stderr)."""
    if not summary["weakly_compressible"]:
        print(f"{PROG}: warning: {out}: a domain's pressure reached {summary['peak_compression']:.2g} of its fluid's bulk "
              f"modulus; a constant K is accurate only up to p/K = {WEAK_COMPRESSION}", file=sys.stderr)
    if rec.status == "diverged":
        print(f"{PROG}: {rec.message}", file=sys.stderr)
        return 1
    return interrupted_status() if rec.status == "interrupted" else 0


# radial flags that override a CouplingSetup field (case defaults included) when given
COUPLING_FLAGS = (
    ("dem_cycles", "dem_cycles_per_step", int),
    ("pv_tol", "pv_rtol", float),
    ("pv_max_iter", "pv_max_iter", int),
    ("pv_test", "pv_test", str),
    ("pv_grow_after", "pv_easy_steps_to_grow", int),
    ("pocket_newton", "pv_pocket_newton", bool),
    ("pv_reuse_steps", "pv_reuse_steps", int),
    ("pv_max_columns", "pv_max_columns", int),
    ("skeleton_newton", "pv_skeleton_newton", bool),
    ("damping", "dem_damping", float),
    ("replica", "dem_replica", bool),
    ("one_way_volume", "one_way_volume", str),
)


# flags of the P-V iteration, which the --one-way variant does not run
PV_ONLY_FLAGS = ("pv_tol", "pv_max_iter", "pv_test", "pv_grow_after", "pocket_newton", "pv_reuse_steps",
                 "pv_max_columns", "skeleton_newton", "replica")


def unused_with_one_way(args) -> list[str]:
    """The P-V flags given to a --one-way run, as written (a new-user pass: --pv-continue --one-way
    was taken without a word, and did nothing)."""
    given = [f"--{'no-' * (getattr(args, flag) is False)}{flag.replace('_', '-')}" for flag in PV_ONLY_FLAGS
             if getattr(args, flag) is not None]
    return given + ["--pv-rewind"] * args.pv_rewind + ["--pv-continue"] * args.pv_continue if args.one_way else []


# nominal flow steps to fill a radial sample's pores beyond which a run warns: the named cases
# take 3,000-5,000 (A1: 0.05 s at 1e-5 s; B3: 2.5 ms at 8e-7 s), and each step runs the DEM over it
MANY_NOMINAL_STEPS = 1e6


def long_fill_warning(sc) -> str | None:
    """A warning when the injection rate fills the sample's pores in more than
    :data:`MANY_NOMINAL_STEPS` nominal flow steps and neither --t-max nor --max-steps ends the run
    sooner (a new-user pass: A1 at Ca* 1e-3 fills in ~80 s of simulated time, 8e6 steps, weeks of
    DEM, behind a bar at 0 %). The DEM resolves the grains' inertia over every step, so a longer
    --dt does not make such a run much cheaper."""
    setup = sc.setup
    fill_time = float(sc.net.domain_volume.sum()) / setup.rate
    steps = fill_time / setup.dt
    if min(steps, setup.max_steps, setup.t_max / setup.dt) <= MANY_NOMINAL_STEPS:
        return None
    return (f"{PROG}: warning: at Q = {setup.rate:.3g} m^2/s (Ca* {sc.ca_star:.3g}) the pores take {fill_time:.3g} s "
            f"to fill, {steps:.2g} flow steps of {setup.dt:g} s, where the named cases take 3,000-5,000; the run "
            f"stops at --max-steps {setup.max_steps:g} unless --t-max stops it sooner")


def check_inlet_perimeter(sc) -> None:
    """--sigma, the Eq. 24 inlet perimeter that sets Q from Ca*, is a port's inside the sample:
    from one diameter of its smallest grain to the sample's own perimeter (a new-user pass: 1 m
    on the 1.25 mm sample ran to 11 GPa and exit status 0)."""
    smallest, perimeter = 2.0 * float(sc.packing.radii.min()), 2.0 * float(sum(sc.packing.box))
    if not smallest <= sc.sigma <= perimeter:
        raise InputError(f"--sigma: the inlet perimeter must be from the smallest grain's diameter, {smallest:.3g} m, "
                         f"to the sample's perimeter, {perimeter:.3g} m; got {sc.sigma:g} m")


def run_radial(args) -> int:
    from dataclasses import replace as replace_case

    from .coupling.model import CoupledFlowModel
    from .coupling.output import write_radial_run
    from .coupling.radial import RADIAL_CASES, build_radial_scenario, default_huang_packing_path
    from .dem.runs import start_grains
    from .report import dimension_note, packing_record

    packing = None if args.packing is None else read_compacted_packing(args.packing)
    recorded_packing = packing_record(args.packing or default_huang_packing_path())
    if args.one_way_volume is not None and not args.one_way:
        raise InputError("--one-way-volume: only with --one-way (the P-V iteration always puts dV in)")
    out = new_run_directory(args.out, args.case)
    case = RADIAL_CASES[args.case]
    if args.dt is not None:
        case = replace_case(case, dt=args.dt)
    with near_contacts_checked(args.contact_gap):
        sc = build_radial_scenario(case, packing, ca_star=args.ca_star, rate=args.rate,
                                   viscosity_ratio=args.viscosity_ratio,
                                   one_way=args.one_way, sigma=args.sigma, fixed_port=args.fixed_port,
                                   grain_density=args.grain_density, contact_gap=args.contact_gap,
                                   friction=args.friction, stiffness_ratio=args.stiffness_ratio,
                                   boundary_hold=args.boundary)
    check_inlet_perimeter(sc)
    check_fill_time(args, float(sc.net.domain_volume.sum()), sc.setup.rate)
    if args.rate is not None:
        require_ca_star_in_range(given_flags(args, ("rate", "viscosity_ratio", "sigma")), sc.ca_star)
    for flag, field, convert in COUPLING_FLAGS:
        if getattr(args, flag) is not None:
            setattr(sc.coupling, field, convert(getattr(args, flag)))
    sc.coupling.pv_rewind = not args.pv_continue
    if args.t_max is not None:
        sc.setup.t_max = args.t_max
    if args.max_steps is not None:
        sc.setup.max_steps = args.max_steps
    unused = unused_with_one_way(args)
    unused_note = f"{PROG}: warning: {', '.join(unused)} not used: --one-way runs no P-V iteration" if unused else None
    for warning in filter(None, (unused_note, long_fill_warning(sc), busy_cores_warning(args.threads))):
        print(warning, file=sys.stderr)
    grains = start_grains(sc, threads=args.threads)
    model = CoupledFlowModel(sc.net, sc.setup, grains, sc.coupling)
    state, rec, bar, snapshots = run_watched(model, case.name, sc.setup, args)
    with deferred_interrupts():  # the run is over: a signal now stops the command once it is written
        if bar is not None:
            bar.close(model, state)
        summary = write_radial_run(out, sc, model, state, rec, argv=recorded_argv(args),
                                   snapshots=None if snapshots is None else snapshots.taken,
                                   packing=recorded_packing, launcher=getattr(args, "launcher", None))
    early = ""
    if summary["early_peak_fell"]:
        early = (f" (early peak {summary['early_peak_injection_pressure_pa']:.4g} Pa "
                 f"at {summary['early_peak_time_s']:.3g} s)")
    print(f"{case.name}: {rec.status} at t = {state.t:.4g} s after {rec.steps} steps; regime: {summary['regime']}, "
          f"{summary['n_opened_contacts']} opened contacts, {dimension_note(summary['fractal_dimension'])}, "
          f"peak injection pressure {summary['peak_injection_pressure_pa']:.4g} Pa{early}")
    print(f"run directory: {out}")
    return finish(rec, summary, out)


def main(argv=None, launcher: str | None = None) -> int:
    """The command line; ``launcher`` names a YADE launcher calling it (config.toml's [launcher])."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0].startswith("--") and argv[0] not in ("--help", "-h", "--version"):
        argv = ["linear", *argv]
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = argv  # config.toml's command: the arguments given, also when YADE's launchers call main
    args.launcher = launcher
    # SIGTERM ends a run like Ctrl-C: status "interrupted", the partial run directory written
    return dispatch(PROG, parser, args, {"linear": run_linear, "radial": run_radial})


if __name__ == "__main__":
    raise SystemExit(main())
