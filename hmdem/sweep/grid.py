"""Sweep grids: ``A:B:N`` axes of log10 M and log10 Ca*, and the points they span."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class Axis:
    """``count`` values evenly spaced from ``start`` to ``stop`` (both included)."""

    start: float
    stop: float
    count: int

    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.count)

    def spec(self) -> str:
        return f"{self.start:g}:{self.stop:g}:{self.count}"


# Where the linear model's runs reach breakthrough, measured with the sd case at the grid's
# corners (decisions #77, #78): down to Ca* = 1e-10 at the seven M measured across [-6, 6], the
# run's mass balance within 1.5e-8 (decisions #78); up to 1e4 the runs finish, beyond the
# constant bulk modulus's range already (p/K 2.8 at M = 1e-5). Lenormand's diagram lies inside (log Ca -10..0 in his micromodel,
# log Ca* -7.4..2.6).
LOG_M_RANGE = (-6.0, 6.0)
LOG_CA_STAR_RANGE = (-10.0, 4.0)
RUN_ID_STEP = 1e-4  # the resolution of a run directory's name in log10 M and log10 Ca*


def parse_axis(text: str, bounds: tuple[float, float] = (-math.inf, math.inf)) -> Axis:
    """``"A:B:N"`` -> Axis(A, B, N) with A and B within ``bounds``; ValueError naming what is
    allowed otherwise."""
    parts = text.split(":")
    if len(parts) != 3:
        raise ValueError(f"expected START:STOP:COUNT (e.g. -5:2:5), got {text!r}")
    try:
        start, stop = float(parts[0]), float(parts[1])
        count = int(parts[2])
    except ValueError:
        raise ValueError(f"expected numbers START:STOP and an integer COUNT, got {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise ValueError(f"START and STOP must be finite, got {text!r}")
    low, high = bounds
    if not (low <= start <= high and low <= stop <= high):
        raise ValueError(f"START and STOP must lie in [{low:g}, {high:g}], got {text!r}")
    if count < 1:
        raise ValueError(f"COUNT must be >= 1, got {text!r}")
    if count == 1 and start != stop:
        raise ValueError(f"COUNT 1 needs START = STOP, got {text!r}")
    if count > 1 and start == stop:
        raise ValueError(f"START = STOP needs COUNT 1, got {text!r}")
    if count > 1 and abs(stop - start) / (count - 1) < RUN_ID_STEP * (1 - 1e-9):
        # closer points would share a run directory (SweepPoint.run_id; a new-user pass)
        raise ValueError(f"points must be at least {RUN_ID_STEP:g} apart, got {text!r}")
    return Axis(start, stop, count)


@dataclass(frozen=True)
class SweepPoint:
    """One run: log10 of the viscosity ratio M = eta_inv / eta_def, log10 Ca*, aperture seed."""

    log_m: float
    log_ca_star: float
    seed: int

    @property
    def run_id(self) -> str:
        """Directory name; round-trips the grid values to RUN_ID_STEP in log10."""
        return f"logM{self.log_m:+.4f}_logCa{self.log_ca_star:+.4f}_seed{self.seed}"

    def as_dict(self) -> dict:
        return asdict(self)


def lenormand_spec(log_m: Axis, log_ca_star: Axis, seeds: int, packing_sha256: str) -> dict:
    """What a Lenormand sweep is, as its manifest records it (a resumed sweep must match): the
    packing by the SHA-256 of its bytes, so that a file replaced under the same name is not
    resumed into the same sweep, and the same file named another way is (a new-user pass)."""
    return {"kind": "lenormand", "log_m": log_m.spec(), "log_ca_star": log_ca_star.spec(), "seeds": seeds,
            "packing_sha256": packing_sha256}


def lenormand_points(log_m: Axis, log_ca_star: Axis, seeds: int) -> list[SweepPoint]:
    """Every (M, Ca*, seed) of the grid, seeds 0 .. seeds-1, M outermost."""
    return [SweepPoint(round(float(m), 10), round(float(c), 10), s)
            for m in log_m.values() for c in log_ca_star.values() for s in range(seeds)]
