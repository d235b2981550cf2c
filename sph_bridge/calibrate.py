"""Calibration of the pairwise-force strengths s_ff and s_sf at a resolution (seed 000 §2.7: they
are resolution-dependent constants, and Table 1's values are a starting guess, not trusted).

1. s_ff for a target surface tension: sigma of a free slab (:mod:`sph_bridge.tension`) at
   trial strengths, each next trial from the power law through the last two (sigma grows about
   as s_ff^1.5: cohesion also compresses the bulk). Each trial also rescales the EOS reference
   density rho_f,0 so that the compressed bulk sits at 1000 kg/m^3: the paper's fluids "have
   bulk properties of water" with rho_f,0 = 930-950 in Table 1 (digest §2.11, decisions #36).
2. s_sf for a target static contact angle: a ridge (a 2-D drop, straight contact lines) at zero
   gravity (a circular cap at any size) spreads from a half cylinder on a 3-layer wall, and the
   fitted cap's angle is read (:mod:`sph_bridge.droplet`); with several ridge sizes, the mean of
   their angles (a ridge's angle scatters with its size by a few degrees, decisions #39). The first
   trial is Young's law for pairwise-additive forces,
   cos theta = 2 s_sf / s_ff - 1; the next ones follow the secant through the last two trials
   in cos theta, which is close to linear in s_sf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from . import droplet, tension
from .simulation import SphParameters

SIGMA_TOLERANCE = 0.01  # relative
ANGLE_TOLERANCE_DEG = 1.0  # a third of the issue's ±3° band around the target
MAX_TRIALS = 8
WATER_DENSITY = droplet.WATER_DENSITY  # kg/m^3: the bulk density the fluid relaxes to
DENSITY_TOLERANCE = 0.005  # relative
TENSION_FIRST_GUESS = 2e-3  # s_ff / dx [N/m]: sigma = 0.074 N/m at dx = 5e-4 m, c0 = 1.5 m/s
SLAB_PERIODS = 6  # periods 2 L / c0 of the free slab's fundamental acoustic mode: sigma settles to 0.1 % by then
DROP_RADIUS_CELLS = 10  # starting half-cylinder radius in dx
MIN_RIDGE_CELLS = 6  # smaller ridges are too few particles tall for a cap to be read

# Table 1 of seed 000: speed of sound per resolution (dx [m], c0 [m/s])
TABLE1_SOUND_SPEED = ((5e-5, 18.0), (1e-4, 4.0), (2e-4, 2.5), (3e-4, 2.0), (4e-4, 1.75), (5e-4, 1.5))


def sound_speed(dx: float) -> float:
    """c0 of seed 000 Table 1, interpolated in log dx between its rows and clamped at its ends."""
    xs = np.log([row[0] for row in TABLE1_SOUND_SPEED])
    return float(np.interp(math.log(dx), xs, [row[1] for row in TABLE1_SOUND_SPEED]))


@dataclass
class Trial:
    stage: str  # "tension" or "contact_angle"
    s_ff: float
    s_sf: float
    rho0_fluid: float
    measured: float  # sigma [N/m] or theta [deg]
    bulk_density: float  # kg/m^3 (slab trials; nan for drops)
    steps: int
    ridge_angles_deg: tuple = ()  # each ridge's angle (contact-angle trials; ``measured`` is their mean)
    ridges_unsettled: float = 0  # of those ridges, how many had not settled by their longest relaxation (NaN: unknown)


@dataclass
class Calibration:
    dx: float
    c0: float
    rho0_fluid: float = WATER_DENSITY
    s_ff: float = math.nan
    s_sf: float = math.nan
    surface_tension: float = math.nan
    bulk_density: float = math.nan
    contact_angle_deg: float = math.nan
    anneal: float = 0.0  # m/s: the ridges' relaxation is annealed at this thermal speed (decisions #59)
    trials: list = field(default_factory=list)

    def parameters(self, **changes) -> SphParameters:
        return replace(SphParameters(dx=self.dx, c0=self.c0, rho0_fluid=self.rho0_fluid, s_ff=self.s_ff,
                                     s_sf=self.s_sf, anneal=self.anneal), **changes)


def slab_tension(params: SphParameters, progress=None) -> tuple[float, float, int]:
    """sigma of a free slab relaxed for :data:`SLAB_PERIODS` acoustic periods, its bulk density and
    the steps taken. ``progress(label, duration, extend)``, if given, is called once with the
    simulated time the slab runs for and returns the per-step callback of ``Simulation.run``."""
    thickness = tension.SLAB_LAYERS * params.dx
    period = 2.0 * thickness / params.c0
    params = replace(params, gravity=(0.0, 0.0, 0.0), damping=2.0 * math.pi / period)
    sim = tension.slab(params)
    duration = SLAB_PERIODS * period
    advance = None if progress is None else progress("slab", duration, 0.0)
    sim.run(duration, record_every=math.inf, progress=advance)
    return tension.surface_tension(sim), tension.bulk_density(sim), sim.record.steps


def zero_gravity_drop(params: SphParameters, surface_tension: float, progress=None,
                      radius_cells: int = DROP_RADIUS_CELLS):
    """The relaxed shape (:class:`sph_bridge.droplet.DropShape`) of a ridge starting as a half
    cylinder of ``radius_cells`` dx radius at zero gravity, and the steps taken. A ridge's contact
    line is straight: its angle is Young's, while a round drop this small (~7 dx tall) stands
    ~10° steeper at dx = 5e-4 m (decisions #39). ``progress``: as :func:`slab_tension`'s, told
    the relaxation's minimum duration and how far each further settle check extends it. Also
    returns whether its height settled (:func:`sph_bridge.droplet.relax`)."""
    volume = droplet.ridge_volume(radius_cells, params.dx)
    sim, t_min = droplet.prepare_drop(replace(params, gravity=(0.0, 0.0, 0.0)), volume, surface_tension, ridge=True)
    advance = None
    if progress is not None:
        advance = progress(f"ridge of {radius_cells} dx", *droplet.relaxation_span(t_min, params.anneal > 0))
    shape, settled = droplet.relax(sim, t_min, ridge=True, progress=advance)
    return shape, sim.record.steps, settled


def ridge_angles(params: SphParameters, surface_tension: float, radius_cells: tuple[int, ...],
                 progress=None) -> tuple[tuple, int, int]:
    """Cap angles [deg] of zero-gravity ridges of the given starting radii, their steps and how
    many of them had not settled."""
    angles, steps, unsettled = [], 0, 0
    for n in radius_cells:
        shape, ridge_steps, settled = zero_gravity_drop(params, surface_tension, progress=progress, radius_cells=n)
        angles.append(shape.contact_angle_deg)
        steps += ridge_steps
        unsettled += not settled
    return tuple(angles), steps, unsettled


def protocol() -> dict:
    """The constants a calibration's trials depend on beyond its targets: the search's, the
    slab's and the ridges' relaxation (a checkpoint's trials are replayed only under the same)."""
    from . import tension

    names = {"calibrate": ("SIGMA_TOLERANCE", "ANGLE_TOLERANCE_DEG", "MAX_TRIALS", "DENSITY_TOLERANCE",
                           "TENSION_FIRST_GUESS", "SLAB_PERIODS"),
             "tension": ("SLAB_SIDE", "JITTER", "SLAB_LAYERS"),
             "droplet": ("RELAXATION_TIMES", "RIDGE_LENGTH", "SAMPLES", "SETTLE_WINDOW", "SETTLED", "MAX_EXTENSION",
                         "ANNEAL_FRACTION")}
    modules = {"calibrate": globals(), "tension": vars(tension), "droplet": vars(droplet)}
    return {f"{m}.{name}": modules[m][name] for m, group in names.items() for name in group}


class ReplayMismatch(ValueError):
    """A replayed trial is not the one this calibration asks for (another calibration's trials)."""


def calibrate(dx: float, theta_deg: float, target_tension: float = droplet.SURFACE_TENSION, c0: float | None = None,
              report=None, cal: Calibration | None = None,
              ridge_sizes: tuple[int, ...] = (DROP_RADIUS_CELLS,), replay: list[Trial] = (),
              on_replayed=None, progress=None) -> Calibration:
    """s_ff (and the EOS reference density) for ``target_tension``, then s_sf for ``theta_deg``, at
    resolution ``dx`` (module docstring), the angle being the mean over ridges of ``ridge_sizes``
    dx starting radius. ``report(trial)`` is called after every trial run; ``cal``, if given, is
    filled in place (what an interrupted calibration had found). The trials of ``replay`` (an
    earlier run of the same calibration, ``calibrate --checkpoint``) are taken as measured
    instead of being run again: each step depends only on the trials before it, so the
    calibration goes on exactly where that run stopped; ``on_replayed()`` is called once the last
    of them has been taken. ``progress(label, duration, extend)`` is :func:`slab_tension`'s, called
    for every simulation a trial runs. Raises RuntimeError when a stage does
    not converge in :data:`MAX_TRIALS` trials, ReplayMismatch when a replayed trial's stage or
    strengths are not the ones asked for or the search ends before the replayed trials do."""
    cal = cal or Calibration(dx=dx, c0=sound_speed(dx) if c0 is None else c0)
    try:
        search(cal, dx, theta_deg, target_tension, report, ridge_sizes, replay, on_replayed, progress)
    except RuntimeError:
        unused_replay(cal, replay)
        raise
    unused_replay(cal, replay)
    return cal


def unused_replay(cal: Calibration, replay: list[Trial]) -> None:
    """Refuse replayed trials the search did not ask for (it ended before them)."""
    if len(cal.trials) < len(replay):
        raise ReplayMismatch(f"this search ended after {len(cal.trials)} of its {len(replay)} trials: another "
                             "version's search?")


def search(cal: Calibration, dx: float, theta_deg: float, target_tension: float, report,
           ridge_sizes: tuple[int, ...], replay: list[Trial], on_replayed, progress=None) -> None:
    """:func:`calibrate`'s two stages (module docstring), filling ``cal``."""

    def trial(stage, s_ff, s_sf, rho0, measure):
        """The trial at these strengths: the next replayed one, or ``measure()``'s (measured,
        bulk density, steps[, ridge angles, ridges unsettled])."""
        k = len(cal.trials)
        if k < len(replay):
            done = replay[k]
            same = all(math.isclose(a, b, rel_tol=1e-12)  # another libm may differ in the last bit
                       for a, b in ((done.s_ff, s_ff), (done.s_sf, s_sf), (done.rho0_fluid, rho0)))
            if done.stage != stage or not same:
                raise ReplayMismatch(f"its trial {k + 1} ({done.stage} at s_ff = {done.s_ff!r}, s_sf = {done.s_sf!r}, "
                                     f"rho0 = {done.rho0_fluid!r}) is not the one this search asks for ({stage} at "
                                     f"s_ff = {s_ff!r}, s_sf = {s_sf!r}, rho0 = {rho0!r}): another version's search?")
            cal.trials.append(done)
            if k + 1 == len(replay) and on_replayed is not None:
                on_replayed()
        else:
            cal.trials.append(Trial(stage, s_ff, s_sf, rho0, *measure()))
            if report is not None:
                report(cal.trials[-1])
        return cal.trials[-1]

    # 1. s_ff: log sigma against log s_ff through the last two trials; rho0 scaled each trial so
    #    that the bulk, compressed by cohesion, sits at water's density (Table 1's 930-950 < 1000)
    s, history = TENSION_FIRST_GUESS * dx, []
    for _ in range(MAX_TRIALS):
        rho0 = cal.rho0_fluid
        slab = trial("tension", s, 0.0, rho0, lambda: slab_tension(cal.parameters(s_ff=s, s_sf=0.0), progress))
        sigma, bulk = slab.measured, slab.bulk_density
        if not (sigma > 0.0 and math.isfinite(bulk)):
            raise RuntimeError(f"the slab at s_ff = {s:.4g} N measured sigma = {sigma:.4g} N/m, bulk {bulk:.4g} kg/m^3")
        history.append((math.log(s), math.log(max(sigma, 1e-12))))
        if abs(sigma / target_tension - 1.0) <= SIGMA_TOLERANCE and abs(bulk / WATER_DENSITY - 1.0) <= DENSITY_TOLERANCE:
            break
        cal.rho0_fluid = rho0 * WATER_DENSITY / bulk
        if len(history) < 2 or history[-1][0] == history[-2][0]:
            slope = 1.5
        else:
            (x0, y0), (x1, y1) = history[-2:]
            slope = max((y1 - y0) / (x1 - x0), 0.5)
        step = (math.log(target_tension) - history[-1][1]) / slope
        s = math.exp(history[-1][0] + max(-0.7, min(0.7, step)))  # at most a factor 2 per trial
    else:
        raise RuntimeError(f"surface tension did not reach {target_tension} N/m within {MAX_TRIALS} trials")
    cal.s_ff, cal.surface_tension, cal.bulk_density = s, sigma, bulk

    # 2. s_sf: cos theta against s_sf through the last two trials
    target_cos = math.cos(math.radians(theta_deg))
    young = 2.0 / cal.s_ff  # d cos(theta) / d s_sf of Young's law with pairwise forces
    s_sf, history = droplet.pairwise_young_s_sf(cal.s_ff, theta_deg), []

    def ridges():  # at the current s_sf
        angles, steps, unsettled = ridge_angles(cal.parameters(s_sf=s_sf), cal.surface_tension, ridge_sizes,
                                                progress)
        return float(np.mean(angles)), math.nan, steps, angles, unsettled

    for _ in range(MAX_TRIALS):
        angle = trial("contact_angle", cal.s_ff, s_sf, cal.rho0_fluid, ridges).measured
        if not math.isfinite(angle):
            raise RuntimeError(f"a drop at s_sf = {s_sf:.4g} N has no measurable cap")
        cos_now = math.cos(math.radians(angle))
        history.append((s_sf, cos_now))
        if abs(angle - theta_deg) <= ANGLE_TOLERANCE_DEG:
            break
        slope = young
        if len(history) >= 2 and history[-1][0] != history[-2][0]:
            (x0, y0), (x1, y1) = history[-2:]
            slope = (y1 - y0) / (x1 - x0) if (y1 - y0) / (x1 - x0) > 0.0 else young
        s_sf = max(0.0, s_sf + (target_cos - cos_now) / slope)
    else:
        raise RuntimeError(f"contact angle did not reach {theta_deg}° within {MAX_TRIALS} trials")
    cal.s_sf, cal.contact_angle_deg = s_sf, angle
