"""The plane-shear migration run: liquid bridges carried and redistributed by a sheared packing
(seed 002 §6.2, Mani et al. 2013; digest §6.2, claims B7, B8).

The grains come from a shear cell (``hmdem.dem.shear_cell.ShearCell``: YADE, periodic in x and y
between rough plates at pressure P); this module only sees its arrays. The liquid starts in
bridges on the touching pairs, V_b(z) = A exp(-(z - z_wall/2)^2 / sigma_0^2), and films empty.
Every ``liquid_every`` DEM steps :func:`hmdem.wet.pendular.pendular_step` breaks, forms and
redistributes bridges and gives their forces (Eq. 4), applied to the grains when the cohesion
number eta = F_c^max / (P R^2) is above 0 (F_c^max = 2 pi R gamma cos theta fixes gamma). At each
output the profile Q(z) is fitted with a Gaussian; D comes from sigma^2 = sigma_0^2 + 4 D gamma.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..interrupts import deferred_interrupts
from .bridges import bridge_force, max_bridge_volume, rupture_distance
from .liquid import PendularLiquid, bridge_radii
from .migration import GaussianFit, diffusion_fit, fit_gaussian, gaussian_bridges, liquid_profile
from .pendular import BridgeModel, bridge_laplace_pressure, branches, pendular_step
from .young_laplace import MAX_TABLE_ANGLE

TIMESERIES = ("strain", "t", "n_bridges", "n_ruptures", "v_bridges", "v_films", "sigma2", "wall_s")
#: Initial bridges are made where the Gaussian is at least this fraction of A: "only near the
#: centre" (§6.2). Eq. 4 gives a 1e-20 R^3 bridge the full contact force, so without a cut the
#: whole packing would be wet at eta > 0 (a review). It leaves out erfc(sqrt(ln 1000)) = 2.6e-4
#: of a Gaussian's liquid (decisions #106).
INITIAL_CUT = 1e-3


def surface_tension(cohesion_number: float, pressure: float, radius: float, contact_angle: float) -> float:
    """gamma [N/m] that gives eta^coh = 2 pi R gamma cos(theta) / (P R^2) (digest §6.2)."""
    return cohesion_number * pressure * radius / (2.0 * math.pi * math.cos(contact_angle))


@dataclass(frozen=True)
class ShearSettings:
    """A shear run's parameters: lengths in R, volumes in R^3 (R the mean grain radius)."""

    amplitude: float  # A / R^3
    sigma0: float  # sigma_0 / R
    cohesion_number: float
    strain: float  # total shear strain
    contact_angle: float = math.radians(5.0)  # [rad]
    force_law: str = "chapter"
    rule: str = "equal"
    inertial_number: float = 0.01  # I = gamma_dot 2R sqrt(rho / P) of the driven plate
    liquid_every: int = 1  # DEM steps per liquid step
    outputs: int = 20  # profiles (and ParaView frames) over the strain, besides the start


@dataclass
class Frame:
    """The state at one output, for profiles.npz and the ParaView series."""

    strain: float
    t: float
    q: np.ndarray  # Q(z) [m^3 per grain] per slab
    count: np.ndarray  # grains per slab
    velocity: np.ndarray  # mean x-velocity per slab over the plate speed (NaN before the shear)
    fit: GaussianFit | None  # of Q / R^3 against z / R (None: no Gaussian fits)
    centres: np.ndarray  # wrapped (n, 3)
    grain_radii: np.ndarray  # (n,)
    film: np.ndarray
    pairs: np.ndarray
    branch: np.ndarray  # (m, 3): first grain to second, nearest image
    volume: np.ndarray
    force: np.ndarray
    pressure: np.ndarray

    @property
    def sigma2(self) -> float:
        """The fitted width sigma^2 [R^2], NaN where no Gaussian fits."""
        return self.fit.sigma2 if self.fit is not None else math.nan

    @property
    def residual(self) -> float:
        return self.fit.residual if self.fit is not None else math.nan


@dataclass
class ShearResult:
    rows: list = field(default_factory=list)
    frames: list = field(default_factory=list)
    edges: np.ndarray | None = None  # slab edges [m]
    status: str = "finished"
    ruptures: int = 0
    liquid_volume_defect: float = 0.0
    max_overlap: float = 0.0  # [m]
    max_volume_over_vmax: float = 0.0
    max_gap_over_sc: float = 0.0
    initial_liquid: float = 0.0
    z_wall: float = math.nan  # plate gap at the start [m]


def initial_liquid(cell, settings: ShearSettings) -> PendularLiquid:
    """Bridges on the touching pairs with the Gaussian volumes of their mid-heights around z_wall/2
    (the bottom plate's sphere centres are at z = 0), where that is at least :data:`INITIAL_CUT`
    of A, capped at V_max; films empty (digest §6.2)."""
    centres = cell.centres()
    pairs, _ = cell.touching(centres)
    bridge_z = 0.5 * (centres[pairs[:, 0], 2] + centres[pairs[:, 1], 2])
    amplitude = settings.amplitude * cell.radius**3
    volume = gaussian_bridges(bridge_z, 0.5 * cell.plate_gap, amplitude, settings.sigma0 * cell.radius)
    wet = volume >= INITIAL_CUT * amplitude
    volume = np.minimum(volume[wet], max_bridge_volume(bridge_radii(pairs[wet], cell.radii)))
    return PendularLiquid(pairs[wet], volume, np.zeros(len(cell.radii)))


def take_frame(cell, liquid, model, edges, forces_on_bridges) -> Frame:
    """The state at an output: Q(z) and its fit, the velocity profile, grains and bridges."""
    centres = cell.centres()
    q, count = liquid_profile(liquid.pairs, liquid.volume, centres[:, 2], edges)
    middle = 0.5 * (edges[1:] + edges[:-1])
    try:
        fit = fit_gaussian(middle / cell.radius, q / cell.radius**3, count)
    except (RuntimeError, ValueError):  # no optimum, or no liquid left to fit: no Gaussian
        fit = None
    velocity = np.full(len(middle), math.nan)
    if cell.plate_speed > 0:
        slab = np.clip(np.digitize(centres[:, 2], edges) - 1, 0, len(middle) - 1)
        speed = cell.velocities()[:, 0] / cell.plate_speed
        velocity = np.bincount(slab, weights=speed, minlength=len(middle)) / np.maximum(count, 1)
    distance, unit = branches(centres, liquid.pairs, cell.period)
    radius = bridge_radii(liquid.pairs, cell.radii)
    gap = distance - cell.radii[liquid.pairs].sum(axis=1)
    pressure = np.full(len(gap), math.nan)  # none without surface tension, or past the table's angles
    if model.surface_tension > 0 and model.contact_angle <= MAX_TABLE_ANGLE * (1 + 1e-12):
        pressure = bridge_laplace_pressure(liquid.volume, gap, radius, model)
    return Frame(cell.strain, cell.time, q, count, velocity, fit, cell.wrapped(centres), cell.radii,
                 liquid.film.copy(), liquid.pairs.copy(), unit * distance[:, None], liquid.volume.copy(),
                 forces_on_bridges(gap, liquid.volume, radius), pressure)


def run_shear(cell, settings: ShearSettings, progress=None) -> ShearResult:
    """Shear ``cell`` (compacted, not yet sheared) to ``settings.strain`` with the liquid, and
    return what the run directory needs. Ctrl-C or SIGTERM ends the run early with status
    "interrupted" and the outputs so far (none, if it comes before the first is taken).
    ``progress(strain)`` after each liquid step. Raises ValueError when no bridge starts wet."""
    gamma = surface_tension(settings.cohesion_number, cell.pressure, cell.radius, settings.contact_angle)
    model = BridgeModel(gamma, settings.contact_angle, settings.force_law, 0.0, settings.rule)
    result = ShearResult(z_wall=cell.plate_gap)
    # slabs of R up to a quarter above the start's plate, so that a dilating cell stays inside
    result.edges = np.arange(0.0, 1.25 * cell.plate_gap + cell.radius, cell.radius)
    targets = np.linspace(0.0, settings.strain, settings.outputs + 1)[1:]
    started = time.perf_counter()
    ruptures_since = 0

    def forces_on_bridges(gap, volume, radius):
        return bridge_force(gap, volume, radius, gamma, settings.contact_angle, settings.force_law)

    def record():
        with deferred_interrupts():  # a frame and its row together, or neither
            frame = take_frame(cell, liquid, model, result.edges, forces_on_bridges)
            result.frames.append(frame)
            result.rows.append((cell.strain, cell.time, len(liquid.pairs), ruptures_since,
                                float(liquid.volume.sum()), float(liquid.film.sum()), frame.sigma2,
                                time.perf_counter() - started))
        radius = bridge_radii(liquid.pairs, cell.radii)
        gap = np.linalg.norm(frame.branch, axis=1) - cell.radii[liquid.pairs].sum(axis=1)
        s_c = rupture_distance(liquid.volume, radius, settings.contact_angle)
        result.max_gap_over_sc = max(result.max_gap_over_sc, float(np.max(gap / s_c, initial=0.0)))
        result.max_volume_over_vmax = max(result.max_volume_over_vmax,
                                          float(np.max(liquid.volume / max_bridge_volume(radius), initial=0.0)))

    try:
        liquid = initial_liquid(cell, settings)
        result.initial_liquid = liquid.total
        if result.initial_liquid <= 0:
            raise ValueError(f"no touching pair within the Gaussian's reach (sigma0 = {settings.sigma0:g} R) "
                             "holds liquid at the start")
        record()
        cell.start_shear(settings.inertial_number)
        done = 0  # outputs taken after the start
        while done < len(targets):
            cell.run(settings.liquid_every)
            centres = cell.centres()
            touching, overlap = cell.touching(centres)
            result.max_overlap = max(result.max_overlap, float(np.max(overlap, initial=0.0)))
            liquid, forces, broken = pendular_step(liquid, centres, cell.radii, model, touching, cell.period)
            if gamma > 0:
                cell.set_grain_forces(forces)
            ruptures_since += broken
            result.ruptures += broken
            defect = abs(liquid.total - result.initial_liquid) / result.initial_liquid
            if not defect <= result.liquid_volume_defect:  # NaN too
                result.liquid_volume_defect = defect
            if progress is not None:
                progress(cell.strain)
            if cell.strain >= targets[done]:  # one output, however many targets a step passed
                record()
                ruptures_since = 0
                done = int(np.searchsorted(targets, cell.strain, side="right"))
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the outputs so far
        result.status = "interrupted"
    return result


def diffusion_constant(result: ShearResult) -> tuple[float, float]:
    """(D / R^2, sigma_0^2 / R^2) fitted over the outputs (NaN with fewer than three)."""
    strain = np.array([f.strain for f in result.frames])
    sigma2 = np.array([f.sigma2 for f in result.frames])
    good = np.isfinite(sigma2)
    if good.sum() < 3:
        return math.nan, math.nan
    return diffusion_fit(strain[good], sigma2[good])

