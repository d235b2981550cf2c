"""The studies of seed 003: Poiseuille validation (§3), one rough fracture (§4.2), the
permeability collapse over H and roughness (§4.2, Eq. 11) and the nonlinear drag (§5).

Each drive of a geometry continues from the previous drive's state, so only the first spin-up
starts from rest (later ones start near their steady state and spin up for half as long).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import surfaces
from . import channels
from .flow import (AVERAGE_TIMES, SPINUP_TIMES, FlowResult, drive, forcing_for, hydraulic_aperture,
                   relaxation_time, reynolds_number)
from .lattice import ROW, Geometry, Lattice
from .rules import viscosity

PAPER_ALPHA = 0.35  # seed 003 Eq. 11
ASPERITY_ROWS = 90  # seed 003 §4.2: y_max ~ 90 rows in every permeability run
ROUGH_GENERATIONS_MIN = 5
PRECISION = 0.01  # relative standard error of the flow rate that ends an averaging window
MAX_AVERAGE_TIMES = 400  # relaxation times: the longest averaging window
# digest §6 [XCHK]: continuum Stokes (lattice Boltzmann) values of (delta_H/delta_av)^3 for
# these profiles, res 0.5 means over 3 seeds: {delta_av/(2 y_max): {H: phi}}
CONTINUUM = {1.35: {0.3: 0.103, 0.5: 0.126, 0.7: 0.137}, 1.7: {0.3: 0.213, 0.5: 0.257, 0.7: 0.284},
             2.4: {0.3: 0.379, 0.5: 0.431, 0.7: 0.468}}


def eq11(opening: float, alpha: float = PAPER_ALPHA) -> float:
    """Seed 003 Eq. 11: (delta_H/delta_av)^3 = 1 - (y_max/(delta_av/2))^alpha, with
    ``opening`` = delta_av/(2 y_max)."""
    return 1.0 - (1.0 / opening) ** alpha


@dataclass
class Plan:
    """Steps for one geometry: the first spin-up from rest (later drives spin up half as long),
    the averaging window, and its extension up to ``max_average`` while the flow rate's
    standard error exceeds ``precision``."""

    spinup: int
    average: int
    precision: float = 0.0
    max_average: int = 0

    @classmethod
    def for_aperture(cls, aperture: float, average: int | None = None, times: float = AVERAGE_TIMES,
                     max_times: float = MAX_AVERAGE_TIMES) -> "Plan":
        """Fixed ``average`` steps if given, else ``times`` relaxation times extended up to
        ``max_times`` until the flow rate is known to 1 %."""
        tau = relaxation_time(aperture)
        if average:
            return cls(spinup=int(SPINUP_TIMES * tau), average=int(average))
        return cls(spinup=int(SPINUP_TIMES * tau), average=int(times * tau), precision=PRECISION,
                   max_average=int(max_times * tau))

    def steps(self, drives: int) -> int:
        return self.spinup + (drives - 1) * (self.spinup // 2) + drives * self.average

    def most_steps(self, drives: int) -> int:
        """:meth:`steps` with every averaging window extended to ``max_average``."""
        return self.steps(drives) + drives * max(0, self.max_average - self.average)


@dataclass
class Channel:
    """A geometry with its drives and results."""

    geometry: Geometry
    mirrored: bool
    aperture: float  # full (mirrored) aperture used for the cubic law and relaxation time
    results: list[FlowResult] = field(default_factory=list)

    def run(self, forcings, plan: Plan, density: float, seed: int, progress=None, timeseries=None) -> None:
        lattice = Lattice(self.geometry, density=density, seed=seed)
        for k, g in enumerate(forcings):
            spinup = plan.spinup if k == 0 else plan.spinup // 2
            result = drive(lattice, g, spinup, plan.average, progress=progress, timeseries=timeseries,
                           precision=plan.precision, max_average=plan.max_average)
            self.results.append(result)
            if result.interrupted:
                raise KeyboardInterrupt

    def phi(self, result: FlowResult) -> float:
        """(delta_H / delta)^3 with the aperture of this channel."""
        return (hydraulic_aperture(result, self.mirrored) / self.aperture) ** 3

    def rows(self) -> list[dict]:
        out = []
        for r in self.results:
            row = r.summary()
            row.update({"hydraulic_aperture": hydraulic_aperture(r, self.mirrored), "phi": self.phi(r),
                        "reynolds": reynolds_number(r, self.mirrored),
                        "flow_rate_full": r.flow_rate * (2.0 if self.mirrored else 1.0),
                        "pressure_drop_per_length": r.force_applied / ROW})
            out.append(row)
        return out


def through_origin(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of y = s x and its largest relative residual."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    s = float(x @ y / (x @ x))
    return s, float(np.max(np.abs(y - s * x) / np.abs(y)))


def smooth(length: int, rows: int, mirror: bool) -> Channel:
    geometry = channels.half_channel(length, rows) if mirror else channels.smooth_channel(length, rows)
    return Channel(geometry, mirror, geometry.description["width"])


def poiseuille_summary(channel: Channel) -> dict:
    """nu from the slope of Q against Delta P (seed 003 Eq. 2, body-force form) and the profile of
    the strongest drive against a parabola (claims C7a, C7b, C8)."""
    width = channel.aperture
    results = channel.results
    q_full = np.array([r.flow_rate for r in results]) * (2.0 if channel.mirrored else 1.0)
    force = np.array([r.force_applied for r in results])
    rho = float(np.mean([r.density for r in results]))
    slope, residual = through_origin(force, q_full)
    nu_fit = width**3 / (12.0 * rho * slope)
    nu_theory = viscosity(rho)
    profile = parabola_fit(channel, results[-1])
    return {"width": width, "density_per_node": rho, "viscosity_fit": nu_fit, "viscosity_eq6": nu_theory,
            "viscosity_error": nu_fit / nu_theory - 1.0, "linearity_residual": residual,
            "phi": [channel.phi(r) for r in results], **profile}


def parabola_fit(channel: Channel, result: FlowResult) -> dict:
    """Least-squares parabola through the fluid rows' mean velocities: R^2, zeros (in rows),
    u_max/u_mean. Under a mirror the parabola is symmetric about the mirror row."""
    geometry = channel.geometry
    fluid_rows = np.nonzero(geometry.fluid[:, 0])[0]
    y = fluid_rows.astype(float)
    u = result.row_velocity[fluid_rows]
    if channel.mirrored:
        top = geometry.shape[0] - 1
        y = np.concatenate([y, 2 * top - y])
        u = np.concatenate([u, u])
    coef = np.polyfit(y, u, 2)
    model = np.polyval(coef, y)
    r2 = 1.0 - np.sum((u - model) ** 2) / np.sum((u - u.mean()) ** 2)
    zeros = np.sort(np.roots(coef).real)
    return {"profile_r2": float(r2), "profile_zeros_rows": [float(z) for z in zeros],
            "profile_coefficients": [float(c) for c in coef],
            "wall_rows": [0.0, float(geometry.shape[0] - 1) if not channel.mirrored else float(2 * (geometry.shape[0] - 1))],
            "u_max_over_mean": float(np.max(model) / np.mean(u))}


def rough(hurst: float, roughness: float, asperity_rows: float, length: int, surface_seed: int) -> Channel:
    """A rough fracture of seed 003 §4.2: relative roughness ``roughness`` = y_max/(delta_av/2),
    largest asperity ``asperity_rows`` rows above the mean plane, total length ``length`` with
    the 20-unit smooth sections; the rough section must be a power of two (its generations)."""
    rough_length = length - 2 * channels.FLAT_SECTION
    generations = int(round(math.log2(rough_length))) if rough_length > 0 else 0
    if rough_length <= 0 or 2**generations != rough_length or generations < ROUGH_GENERATIONS_MIN:
        raise ValueError(f"the rough section (length - {2 * channels.FLAT_SECTION}) must be a power of two "
                         f">= {2**ROUGH_GENERATIONS_MIN}, got {rough_length}")
    y_max = asperity_rows * ROW
    profile = surfaces.midpoint_displacement(generations, hurst, np.random.default_rng(surface_seed))
    geometry = channels.rough_channel(profile, rough_length, y_max, y_max / roughness)
    geometry.description.update({"hurst": hurst, "surface_seed": surface_seed, "profile": profile})
    return Channel(geometry, True, geometry.description["mean_aperture"])


def opening(channel: Channel) -> float:
    """delta_av/(2 y_max) realised on the lattice."""
    return channels.relative_aperture(channel.geometry)


def fit_alpha(openings, phis) -> tuple[float, float]:
    """Fit Eq. 11's exponent: alpha = ln(1 - phi)/ln(y_max/(delta_av/2)) per point; mean and its
    standard error."""
    x = 1.0 / np.asarray(openings, float)
    phis = np.asarray(phis, float)
    alphas = np.log(1.0 - phis) / np.log(x)
    return float(alphas.mean()), float(alphas.std(ddof=1) / math.sqrt(len(alphas))) if len(alphas) > 1 else math.nan


def forcings_for_velocities(velocities, aperture: float, density: float) -> list[float]:
    return [forcing_for(u, aperture, viscosity(density), density) for u in velocities]


def next_rung(rows: list[dict], target: float, u_limit: float) -> tuple[float, float] | None:
    """Forcing fraction g and the Re it aims at for the next drive of a Re ladder (seed 003 §5),
    from the drives done so far (``rows``: their ``g``, ``reynolds`` and ``u_max``).

    Re grows as g^s near the last drive; s is read from the last two drives (1 while the drag is
    linear, below 1 once Delta P/Q rises), so a rung still lands near its aim where the drag
    rises (a linear scaling of g lands low: 130 for an aim of 150 in the rough channel of the
    nonlinear study). A ``target`` whose peak velocity would pass ``u_limit`` (u_max taken as
    proportional to Re from the last drive) is replaced by the Re at ``u_limit``. ``None`` when
    the last drive already sits within 2 % of that bound: the ladder is done."""
    last = rows[-1]
    exponent = 1.0
    if len(rows) >= 2 and rows[-2]["g"] != last["g"] and rows[-2]["reynolds"] > 0:
        exponent = math.log(last["reynolds"] / rows[-2]["reynolds"]) / math.log(last["g"] / rows[-2]["g"])
        exponent = min(max(exponent, 0.25), 1.0)  # noise guard: Re never grows faster than g
    aim = min(target, last["reynolds"] * u_limit / last["u_max"])
    if aim <= 1.02 * last["reynolds"]:
        return None
    return min(0.9, last["g"] * (aim / last["reynolds"]) ** (1.0 / exponent)), aim
