"""Sessile droplet on a horizontal wall (seed 000 §3.1, digest §5.1): placement, relaxation and
measurement of height, base width and contact angle.

The wall's nominal surface is the plane z = 0 (three particle layers below it, digest §2.9a);
the droplet starts as a hemisphere (contact angle 90°) of the requested volume on the dx
lattice, centred on the z axis, and spreads or retracts to its equilibrium with its velocities
damped (a relaxation, not a dynamic experiment).

Measured shape: the fluid's surface lies dx/2 beyond the outermost particle centres (each
particle stands for a dx^3 cell); the kernel-smoothed fluid fraction (:func:`fluid_fraction`)
is 0.5 there on a flat lattice and also between layers, so

- height = the 0.5 level of the fluid fraction above the drop's centre;
- base width = between the 0.5 levels along the first layer (z = dx/2), both ways;
- contact angle = that of the spherical (circular) cap with this height and width,
  2 atan(2 h / w), the reading the calibration and the small-drop test share (decisions #38);
  also reported, the angle where a sphere fitted to the outer shell (:func:`outer_shell`) above
  the first two layers, its radius grown by dx/2, meets the wall: cos theta = -z_centre / R.
  At zero gravity the drop is a spherical cap of any size (Bond number 0); under gravity both
  angles only describe drops smaller than the capillary length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .geometry import lattice_block, wall_slab
from .kernel import INTERACTION_RANGE
from .simulation import FULL_KERNEL, Simulation, SphParameters

SURFACE_TENSION = 0.072  # N/m, water at 20 °C (seed 000 §3.1)
WATER_DENSITY = 1000.0  # kg/m^3: the bulk density a calibrated fluid relaxes to
SHELL_BINS = 12  # angular bins of the outer shell per quarter turn
RELAXATION_TIMES = 8  # a relaxation lasts this many times 1/omega of the drop's slowest mode


@dataclass
class DropShape:
    height: float  # m, top of the surface above the wall's nominal surface
    width: float  # m, base diameter
    contact_angle_deg: float  # of the cap with this height and width, 2 atan(2 h / w)
    fitted_angle_deg: float  # where a sphere (circle) fitted to the outer shell meets the wall
    cap_radius: float  # m, of the fitted sphere
    cap_centre_z: float  # m
    fit_rms: float  # m, rms distance of the outer shell from the fitted sphere


def capillary_length(surface_tension: float, density: float, gravity: float) -> float:
    """lambda_c = sqrt(sigma / (rho g)) (seed 000 Eq. 36)."""
    return math.sqrt(surface_tension / (density * gravity))


def puddle_height(surface_tension: float, density: float, gravity: float, theta_deg: float) -> float:
    """Height of a drop much wider than the capillary length, 2 lambda_c sin(theta/2) (seed 000
    Eq. 37, de Gennes): 2.918 mm for water at 65.16° (digest §5.1)."""
    return 2.0 * capillary_length(surface_tension, density, gravity) * math.sin(math.radians(theta_deg) / 2.0)


def cap_aspect(theta_deg: float) -> float:
    """height / base width of a spherical cap meeting the wall at theta: tan(theta/2)/2 (Harris and
    Stocker 1999; 0.3195 at 65.16°, digest §5.1)."""
    return math.tan(math.radians(theta_deg) / 2.0) / 2.0


RIDGE_LENGTH = 18  # periodic length of a ridge in dx: 5 kernel supports (h = 3.42 dx), the pairwise reach each side


def ridge_volume(radius_cells: float, dx: float) -> float:
    """Volume of a half-cylinder ridge of ``radius_cells`` dx over its periodic length."""
    return 0.5 * math.pi * (radius_cells * dx) ** 2 * RIDGE_LENGTH * dx


def starting_drop(volume: float, dx: float, max_height: float, ridge: bool) -> np.ndarray:
    """Lattice sites (cells of dx^3 resting on z = 0) of the starting drop holding ``volume``: a
    hemisphere centred on the z axis (a ridge: a half cylinder along y over its periodic length
    :data:`RIDGE_LENGTH` dx), or, where that would be taller than ``max_height``, a cylinder
    (a slab) of that height rounded to whole layers (at least one), as wide as the volume needs.
    Starting no lower than the equilibrium, the contact line advances, as in the calibration."""
    length = RIDGE_LENGTH * dx
    radius = math.sqrt(2.0 * volume / (math.pi * length)) if ridge else (3.0 * volume / (2.0 * math.pi)) ** (1.0 / 3.0)
    if radius <= max_height:
        top, reach = radius, radius
    else:
        top = max(1, round(max_height / dx)) * dx  # the layers whose centres lie below max_height
        reach = volume / (2.0 * top * length) if ridge else math.sqrt(volume / (math.pi * top))
    n = int(math.ceil(reach / dx)) + 1
    if ridge:
        block = lattice_block([-n * dx, 0.0, 0.0], [n * dx, length, math.ceil(top / dx) * dx], dx)
        planar = block[:, 0] ** 2
    else:
        block = lattice_block([-n * dx, -n * dx, 0.0], [n * dx, n * dx, math.ceil(top / dx) * dx], dx)
        planar = block[:, 0] ** 2 + block[:, 1] ** 2
    if radius <= max_height:
        return block[planar + block[:, 2] ** 2 <= radius**2]
    return block[(planar <= reach**2) & (block[:, 2] <= top)]


def sessile(params: SphParameters, volume: float, ridge: bool = False, max_height: float = math.inf,
            plate_radius: float | None = None) -> Simulation:
    """The starting drop (:func:`starting_drop`) on a 3-layer plate reaching twice the starting
    drop's reach plus the pairwise force's range 2h from the axis (room to spread to a ~20°
    contact angle), or ``plate_radius`` where that is further. A ridge is periodic along y."""
    dx = params.dx
    fluid = starting_drop(volume, dx, max_height, ridge)
    reach = float(np.abs(fluid[:, 0]).max()) + dx / 2
    plate_radius = max(2.0 * reach + INTERACTION_RANGE * params.h, plate_radius or 0.0)
    half = dx * math.ceil(plate_radius / dx)
    top = float(fluid[:, 2].max()) + INTERACTION_RANGE * params.h + 4 * dx
    if ridge:
        length = RIDGE_LENGTH * dx
        plate = wall_slab(2, 0.0, +1, [-half, 0.0, 0.0], [half, length, 0.0], dx)
        return Simulation(fluid, plate, params, [-half, 0.0, -4 * dx], [half, length, top], (False, True, False))
    plate = wall_slab(2, 0.0, +1, [-half, -half, 0.0], [half, half, 0.0], dx)
    return Simulation(fluid, plate, params, [-half, -half, -4 * dx], [half, half, top])


def fluid_fraction(probes: np.ndarray, sim: Simulation) -> np.ndarray:
    """Kernel-smoothed fluid fraction at probe points: sum_f V_f W / (1 - sum_w V_w W) with V the
    volume a particle takes in the bulk (m over the mean density of the fluid particles with a
    full kernel; dx^3 for walls). It is 1 inside the fluid even beside a
    wall (whose share of the kernel is taken out), 0 outside, and 0.5 on a flat lattice surface
    dx/2 beyond the outer particle layer (the mirror argument of Eq. 21), so its 0.5 level
    places the surface between particle layers instead of on them."""
    h = sim.h
    fluid, walls = sim.fluid, ~sim.fluid
    full = fluid & (sim.number_density >= FULL_KERNEL * sim.bulk_number_density)
    bulk = float(sim.rho[full].mean()) if full.any() else float(np.median(sim.rho[fluid]))
    volume = np.where(fluid, sim.mass / bulk, sim.params.dx**3)
    sums = np.zeros((len(probes), 2))
    for start in range(0, len(probes), 64):
        d = np.linalg.norm(probes[start:start + 64, None, :] - sim.pos[None, :, :], axis=2)
        q = np.minimum(d / h, 1.0)
        w = 21.0 / (2.0 * math.pi * h**3) * (1.0 - q) ** 4 * (1.0 + 4.0 * q) * volume
        sums[start:start + 64, 0] = w[:, fluid].sum(axis=1)
        sums[start:start + 64, 1] = w[:, walls].sum(axis=1)
    return sums[:, 0] / np.maximum(1.0 - sums[:, 1], 0.05)


def half_level(samples: np.ndarray, values: np.ndarray) -> float:
    """Where ``values`` (sampled along ``samples``, fluid first) last falls through 0.5."""
    inside = values >= 0.5
    if not inside[0]:
        return float(samples[0])
    k = int(np.flatnonzero(inside)[-1])
    if k == len(samples) - 1:
        return float(samples[-1])
    return float(samples[k] + (values[k] - 0.5) / (values[k] - values[k + 1]) * (samples[k + 1] - samples[k]))


def outer_shell(pos: np.ndarray, centre: np.ndarray, dx: float, ridge: bool) -> np.ndarray:
    """The outermost particle seen from the drop's foot (centre, z = 0) in each angular bin,
    above the first two layers: (polar angle, azimuth) bins of 90°/:data:`SHELL_BINS` (a ridge:
    the x-z plane, both sides, returned as (x, z)). A particle's number density cannot tell the
    outer layer here: cohesion packs it to 0.9 of the bulk value."""
    above = pos[pos[:, 2] > 2 * dx]
    rel = above - np.array([centre[0], centre[1], 0.0])
    if ridge:
        rel = rel[:, [0, 2]]
        angle = np.arctan2(rel[:, 0], rel[:, 1])  # from the vertical, -90..90°
        key = np.floor(angle / (0.5 * math.pi / SHELL_BINS)).astype(np.int64)
    else:
        planar = np.hypot(rel[:, 0], rel[:, 1])
        polar = np.floor(np.arctan2(planar, rel[:, 2]) / (0.5 * math.pi / SHELL_BINS)).astype(np.int64)
        azimuth = np.floor((np.arctan2(rel[:, 1], rel[:, 0]) + math.pi) / (0.5 * math.pi / SHELL_BINS))
        key = polar * (8 * SHELL_BINS) + azimuth.astype(np.int64)
    distance = np.linalg.norm(rel, axis=1)
    order = np.lexsort((-distance, key))  # by bin, farthest first
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    keep = order[first]
    return above[keep][:, [0, 2]] if ridge else above[keep]


def measure(sim: Simulation, ridge: bool = False) -> DropShape:
    """Height, base width and fitted-cap contact angle of a sessile drop (module docstring); for a
    ridge, a circle fitted in the x-z plane and the width across x. Height and width are the 0.5
    levels of :func:`fluid_fraction` above the drop's centre and along the wall's first layer
    (z = dx/2; both ways along x, and along y for a round drop)."""
    dx = sim.params.dx
    f = sim.fluid
    pos = sim.pos[f]
    centre = pos[:, :2].mean(axis=0)
    if ridge:
        centre[1] = sim.grid.lo[1] + sim.grid.length[1] / 2  # away from the periodic images
    top = float(pos[:, 2].max()) + 2 * dx
    z = np.arange(0.0, top, dx / 10)
    height = half_level(z, fluid_fraction(np.column_stack([np.full_like(z, centre[0]), np.full_like(z, centre[1]), z]),
                                          sim))
    reach = float(np.abs(pos[:, :2] - centre).max()) + 2 * dx
    r = np.arange(0.0, reach, dx / 10)
    half_widths = []
    for axis, sign in ((0, 1), (0, -1)) + (() if ridge else ((1, 1), (1, -1))):
        probes = np.column_stack([np.full_like(r, centre[0]), np.full_like(r, centre[1]), np.full_like(r, dx / 2)])
        probes[:, axis] += sign * r
        half_widths.append(half_level(r, fluid_fraction(probes, sim)))
    width = 2.0 * float(np.mean(half_widths))
    cap_angle = math.degrees(2.0 * math.atan(2.0 * height / width)) if width > 0 else math.nan
    pts = outer_shell(pos, centre, dx, ridge)
    if len(pts) < 10:
        return DropShape(height, width, cap_angle, math.nan, math.nan, math.nan, math.nan)
    # sphere (circle) |x - c|^2 = R^2 as the linear least squares x.x = 2 c.x + (R^2 - c.c)
    a = np.column_stack([2 * pts, np.ones(len(pts))])
    sol, *_ = np.linalg.lstsq(a, (pts**2).sum(axis=1), rcond=None)
    c = sol[:-1]
    r_fit = math.sqrt(sol[-1] + c @ c)
    rms = float(np.sqrt(np.mean((np.linalg.norm(pts - c, axis=1) - r_fit) ** 2)))
    radius = r_fit + dx / 2
    cos_theta = max(-1.0, min(1.0, -c[-1] / radius))
    return DropShape(height, width, cap_angle, math.degrees(math.acos(cos_theta)), radius, float(c[-1]), rms)


NEAR_WALL_LAYERS = 4  # where clamping the fluid's own pressure at walls drove a circulation (decisions #37)


def rms_speeds(sim: Simulation) -> tuple[float, float]:
    """rms speed [m/s] of the fluid within :data:`NEAR_WALL_LAYERS` dx of the wall (z = 0) and of
    the fluid above: a drop relaxing under damping has no reason to move more at the wall than
    above it unless a wall force does net work around closed paths (decisions #37)."""
    f = sim.fluid
    speed2 = (sim.vel[f] ** 2).sum(axis=1)
    near = sim.pos[f, 2] < NEAR_WALL_LAYERS * sim.params.dx
    return tuple(float(np.sqrt(speed2[m].mean())) if m.any() else math.nan for m in (near, ~near))


def average(shapes: list[DropShape]) -> DropShape:
    """Field-wise mean of shapes sampled over the end of a relaxation."""
    return DropShape(*(float(np.mean([getattr(s, k) for s in shapes])) for k in DropShape.__dataclass_fields__))


def relaxation(params: SphParameters, surface_tension: float, size: float) -> tuple[SphParameters, float]:
    """Damping and duration of a drop's relaxation: omega^2 = g k + sigma k^3 / rho, the
    deep-water capillary-gravity wave of wavenumber k = 1/size, is the scale of the drop's
    slow shape modes (an estimate: a free drop's l = 2 mode is sqrt(8) faster, a shallow
    puddle's slower). The damping is 2 omega and the run lasts :data:`RELAXATION_TIMES` /
    omega; the shape is averaged over its last quarter (:func:`relax`)."""
    g = float(np.linalg.norm(params.gravity))
    omega = math.sqrt(g / size + surface_tension / (params.rho0_fluid * size**3))
    return replace(params, damping=2.0 * omega), RELAXATION_TIMES / omega


SAMPLES = 40  # shape samples per minimum relaxation; the last quarter of them is averaged
SETTLE_WINDOW = SAMPLES // 4  # samples in a quarter
SETTLED = 0.005  # the mean height of the last quarter moved less than this (relative) from the one before
MAX_EXTENSION = 4  # a relaxation ends by this many times its minimum duration, settled or not
ANNEAL_FRACTION = 2.0  # an annealed relaxation's kicks end at this multiple of its minimum duration


def relax(sim: Simulation, t_min: float, ridge: bool = False, progress=None, on_sample=None, rows=None,
          shapes=None):
    """Run for at least ``t_min`` measuring the shape every ``t_min`` / :data:`SAMPLES`, until the
    mean height over the last quarter of that time has moved by less than :data:`SETTLED` from
    the quarter before (a puddle spreads for longer than a cap), at most :data:`MAX_EXTENSION`
    ``t_min``. Returns the mean shape over the last quarter (a snapshot still carries the
    relaxation's leftover motion), whether it settled, and appends (t, kinetic energy, height,
    width, angle) per sample to ``rows`` (an interrupted run keeps them). ``on_sample(sim, k)``
    is called after sample k. With ``sim.params.anneal`` > 0 the relaxation is annealed: thermal
    kicks of that rms speed, falling linearly to none at :data:`ANNEAL_FRACTION` ``t_min`` (long
    enough for a puddle to finish spreading under them), and the settle check compares two
    quarters after they end (decisions #59, #60). ``shapes``: the samples taken so far, for a
    relaxation resumed from a checkpoint (:mod:`sph_bridge.checkpoint`) with ``sim`` restored to
    the last of them; whether it goes on depends on them alone, so a resumed run ends where a
    straight one does."""
    rows = [] if rows is None else rows
    shapes = [] if shapes is None else shapes
    sim.anneal_end = ANNEAL_FRACTION * t_min if sim.params.anneal > 0 else 0.0
    interval = t_min / SAMPLES
    first_check = minimum_samples(sim.params.anneal > 0)
    while not has_settled(shapes, first_check) and len(shapes) < MAX_EXTENSION * SAMPLES:
        k = len(shapes) + 1
        sim.run(interval * k, record_every=math.inf, progress=progress)
        shapes.append(measure(sim, ridge))
        rows.append((sim.t, sim.state_row()[2], shapes[-1].height, shapes[-1].width, shapes[-1].contact_angle_deg))
        if on_sample is not None:
            on_sample(sim, k)
    return average(shapes[-SETTLE_WINDOW:]), has_settled(shapes, first_check)


def relaxation_span(t_min: float, annealed: bool) -> tuple[float, float]:
    """What a progress bar over :func:`relax` needs: its shortest duration (the minimum samples)
    and how far each further settle check extends a relaxation that has not settled by then."""
    interval = t_min / SAMPLES
    return minimum_samples(annealed) * interval, SETTLE_WINDOW * interval


def minimum_samples(annealed: bool) -> int:
    """Samples (of t_min / :data:`SAMPLES`) before a relaxation may stop: t_min, or for an annealed
    one two windows after its kicks end (both quarters compared lie after the kicks: a shape
    still moving under them is not settled)."""
    kicks = math.ceil(ANNEAL_FRACTION * SAMPLES - 1e-9) if annealed else 0
    return max(SAMPLES, kicks + 2 * SETTLE_WINDOW)


def has_settled(shapes: list[DropShape], first_check: int) -> bool:
    """At a whole window from ``first_check`` samples on, the mean height of the last
    :data:`SETTLE_WINDOW` samples within :data:`SETTLED` of the window before."""
    k = len(shapes)
    if k < first_check or k % SETTLE_WINDOW:
        return False
    return bool(abs(height_drift(shapes)) < SETTLED)


def height_drift(shapes: list[DropShape]) -> float:
    """The mean height of the last :data:`SETTLE_WINDOW` samples relative to the window before,
    minus 1 (NaN with fewer than two windows): what :func:`has_settled` compares with :data:`SETTLED`."""
    if len(shapes) < 2 * SETTLE_WINDOW:
        return math.nan
    last = np.mean([s.height for s in shapes[-SETTLE_WINDOW:]])
    before = np.mean([s.height for s in shapes[-2 * SETTLE_WINDOW:-SETTLE_WINDOW]])
    return float(last / before - 1.0)


ROOM_BELOW_TARGET_DEG = 10.0  # a gravity drop's plate holds its equilibrium this much flatter


def pairwise_young_angle_deg(s_ff: float, s_sf: float) -> float:
    """Young's law for pairwise-additive forces, cos theta = 2 s_sf / s_ff - 1 (clipped to a
    complete wetting or drying): the calibration's first guess (:mod:`sph_bridge.calibrate`).
    It errs flat: the shipped calibrations measure 65.4° and 64.7° where it gives 56.3° and
    56.5° (decisions #63)."""
    return math.degrees(math.acos(min(1.0, max(-1.0, 2.0 * s_sf / s_ff - 1.0))))


def pairwise_young_s_sf(s_ff: float, theta_deg: float) -> float:
    """The inverse of :func:`pairwise_young_angle_deg`: s_sf = s_ff (1 + cos theta) / 2."""
    return s_ff * (1.0 + math.cos(math.radians(theta_deg))) / 2.0


def plate_half_width(sim: Simulation) -> float:
    """Distance [m] from the drop's axis to the plate's nearest edge, where its lattice cells end
    dx/2 beyond its outermost particles along x (the plate is square or, under a ridge, a strip)."""
    return float(np.abs(sim.pos[~sim.fluid, 0]).max()) + sim.params.dx / 2


def plate_edge_clearance(sim: Simulation, shape: DropShape, ridge: bool) -> float:
    """Distance [m] from the contact line to the plate's nearest edge: the plate's half-width
    less half the base width and the drop's drift off the axis (its fluid's mean x, and y on the
    square plate of a round drop)."""
    drift = np.abs(sim.pos[sim.fluid, :1 if ridge else 2].mean(axis=0)).max()
    return plate_half_width(sim) - float(drift) - shape.width / 2


THINNEST_FILM_CELLS = 2  # no plate is sized for a film thinner than this many dx


def plate_room(fluid_volume: float, ridge: bool, theta_deg: float, capillary_length: float, h: float,
               dx: float) -> float:
    """Plate radius a drop under gravity needs: half the Young-Laplace base width of its fluid
    volume at :data:`ROOM_BELOW_TARGET_DEG` under the target angle (at most halving it), plus
    the pairwise force's range 2h, so that the equilibrium contact line stays beyond the reach
    of the plate's edge, where wall particles are missing from the adhesion (decisions #62).
    A ridge's volume is per its periodic length. At small angles the room is that of a film
    :data:`THINNEST_FILM_CELLS` dx thick at most: a thinner one is below the resolution."""
    from .young_laplace import sessile_height

    film = THINNEST_FILM_CELLS * dx
    widest = fluid_volume / film / 2.0 if ridge else math.sqrt(fluid_volume / (math.pi * film))
    room_angle = max(theta_deg - ROOM_BELOW_TARGET_DEG, theta_deg / 2.0)
    if 2.0 * capillary_length * math.sin(math.radians(room_angle) / 2.0) <= film:  # a puddle thinner than that
        return widest + INTERACTION_RANGE * h
    try:
        half_width = sessile_height(fluid_volume, room_angle, capillary_length, axisymmetric=not ridge)[1] / 2.0
    except (ValueError, OverflowError):  # no drop so flat holds the volume: a film it is
        half_width = widest
    return min(half_width, widest) + INTERACTION_RANGE * h


def prepare_drop(params: SphParameters, volume: float, surface_tension: float, ridge: bool = False,
                 start_height: float | None = None, theta_deg: float | None = None):
    """The starting drop on its plate with the damping of :func:`relaxation`, and its minimum
    relaxation time for :func:`relax`. The calibration and the droplet command share this
    protocol. The drop is no taller than ``start_height`` (default 2 lambda_c, the puddle height
    at 180°, or none at zero gravity): starting above its equilibrium its contact line advances,
    starting below it recedes, and the two stop at different angles (contact-angle hysteresis of
    the lattice wall, decisions #57). Under gravity with a target angle ``theta_deg`` the plate
    is at least :func:`plate_room` wide."""
    g = float(np.linalg.norm(params.gravity))
    max_height = 2.0 * capillary_length(surface_tension, params.rho0_fluid, g) if g > 0 else math.inf
    if start_height is not None:
        max_height = start_height
    dx = params.dx
    fluid = starting_drop(volume, dx, max_height, ridge)
    reach = float(np.abs(fluid[:, 0]).max()) + dx / 2
    params, t_min = relaxation(params, surface_tension, reach)
    plate_radius = None
    if g > 0 and theta_deg is not None:
        # the fluid's volume at the bulk density a calibration sets (its mass is rho0 dx^3 a particle)
        fluid_volume = len(fluid) * params.rho0_fluid * dx**3 / WATER_DENSITY / (RIDGE_LENGTH * dx if ridge else 1.0)
        lam = capillary_length(surface_tension, WATER_DENSITY, g)
        plate_radius = plate_room(fluid_volume, ridge, theta_deg, lam, params.h, dx)
    return sessile(params, volume, ridge, max_height, plate_radius), t_min
