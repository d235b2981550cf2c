"""The single-phase Darcy test of seed 004 App. D.1 (digest §11.3, U16): a run against Eqs. 37-38.

Oil displaces oil at a constant rate Q through the Lenormand sample from a flux boundary at x = 0
to p = 0 at x = L. In the dimensionless variables x_D = x / L, t_D = k K t / (c_v eta L^2),
p_D = -p k H / (eta L Q) (p gauge, so p_D <= 0, the sign convention of Eq. 37) the pressure and
flux are Eqs. 37-38, with the digest's fix of the printed boundary condition (d p_D / d x_D = 1 at
x_D = 0, printed as a time derivative; digest §14 item 3). As the paper does, k is read off the
simulated steady state (Eq. 21: k = eta L Q / (H dP)) and the storage fraction is
c_v = sum V / (L H) (digest §3.3). L is the distance between the inflow and outflow domains'
mean centroids, the length the pressure drops over, not the sample's side.
A run compares p_in(t) and q_out(t) over the transient and its final (steady) profile; the
profile in mid-transient is compared in tests/test_solver.py (U16 at t_D ~ 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

U16_TOLERANCE = 0.05  # digest U16: within 5 % of the steady values (a random packing scatters domains)
SERIES_TERMS = 200  # terms of Eqs. 37-38: their tail is 1e-3 of p_D at t_D = 0, 2e-6 at 1e-5, 1e-22 at 1e-4
PROFILE_BINS = 10  # x-bins the pressure profile is averaged over (single domains scatter)
STEADY_T_D = 3.0  # q_D(1, 3) = 1 - 7.8e-4: a run that ends later ends steady, and k read there is Eq. 21's


def series(x_d: np.ndarray, t_d: np.ndarray, terms: int = SERIES_TERMS) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 37-38: p_D(x_D, t_D) and q_D(x_D, t_D) on the broadcast of ``x_d`` and ``t_d``."""
    x_d, t_d = np.broadcast_arrays(np.asarray(x_d, float), np.asarray(t_d, float))
    p_d, q_d = -1.0 + x_d, np.ones_like(x_d)
    for m in range(1, 2 * terms, 2):  # term by term: memory stays that of x_d and t_d (a run has ~1e6 steps)
        decay = np.exp(-(m**2) * np.pi**2 * t_d / 4)
        p_d = p_d + 8 / np.pi**2 * np.cos(m * np.pi * x_d / 2) / m**2 * decay
        q_d = q_d - 4 / np.pi * np.sin(m * np.pi * x_d / 2) / m * decay
    return p_d, q_d


def binned_profile(x_d: np.ndarray, values: np.ndarray, bins: int = PROFILE_BINS) -> tuple[np.ndarray, np.ndarray]:
    """Bin centres on [0, 1] and the mean of ``values`` in each bin of ``x_d``."""
    edges = np.linspace(0, 1, bins + 1)
    index = np.clip(np.digitize(x_d, edges) - 1, 0, bins - 1)
    return 0.5 * (edges[1:] + edges[:-1]), np.bincount(index, values, bins) / np.bincount(index, minlength=bins)


@dataclass(frozen=True)
class DarcyTest:
    """A run read against Eqs. 37-38. The errors are the largest over the run, as fractions of the
    steady values (U16's measure): the injection pressure against p_D(0, t_D), the outflow
    against q_D(1, t_D) and the final profile (``PROFILE_BINS`` bins) against p_D(x_D, t_D)."""

    permeability: float  # k [m^2] from the last step's injection pressure (Eq. 21)
    storage_fraction: float  # c_v = sum V / (L H) of the domains not held at p = 0
    t_d: np.ndarray  # the recorded steps' t_D
    inflow_pressure: np.ndarray  # p_in / dP of the recorded steps (dP: the last one's)
    outflow_rate: np.ndarray  # q_out / Q of the recorded steps
    profile_x_d: np.ndarray  # bin centres of the final profile
    profile: np.ndarray  # the final p / dP, mean per bin

    @cached_property
    def inflow_pressure_error(self) -> float:
        return float(np.max(np.abs(self.inflow_pressure + series(0.0, self.t_d)[0])))

    @cached_property
    def outflow_rate_error(self) -> float:
        return float(np.max(np.abs(self.outflow_rate - series(1.0, self.t_d)[1])))

    @cached_property
    def profile_error(self) -> float:
        return float(np.max(np.abs(self.profile + series(self.profile_x_d, self.t_d[-1])[0])))

    @property
    def steady(self) -> bool:
        """Whether the run ended steady, so that k and the normalisation by its last drop hold."""
        return float(self.t_d[-1]) >= STEADY_T_D

    @property
    def within_u16(self) -> bool:
        if not self.steady:  # the errors are normalised by a drop that is not dP
            return False
        return max(self.inflow_pressure_error, self.outflow_rate_error, self.profile_error) < U16_TOLERANCE

    def write_figure(self, directory) -> None:
        """darcy.png in ``directory``: the run against Eqs. 37-38."""
        from ..plots import plot_darcy_transient

        plot_darcy_transient(directory / "darcy.png", self)

    def summary(self) -> dict:
        """The summary.json keys of a darcy run; k, t_D and the errors are null for a run that did not
        end steady (its last drop is not dP: k would be too high and t_D an upper bound)."""
        names = ("darcy_permeability_m2", "darcy_final_t_d", "darcy_inflow_pressure_error",
                 "darcy_outflow_rate_error", "darcy_profile_error")
        readings = dict.fromkeys(names)  # not computed for a run that did not end steady
        if self.steady:
            readings = dict(zip(names, (self.permeability, float(self.t_d[-1]), self.inflow_pressure_error,
                                        self.outflow_rate_error, self.profile_error)))
        return {**readings, "darcy_storage_fraction": self.storage_fraction, "darcy_steady": self.steady,
                "darcy_within_u16": self.within_u16}


def dimensionless_time(permeability: float, c_v: float, length: float, fluids, t: np.ndarray) -> np.ndarray:
    """t_D = k K t / (c_v eta L^2) of the defending (= invading) oil."""
    return permeability * fluids.bulk_modulus_def * np.asarray(t) / (c_v * fluids.viscosity_def * length**2)


def read_darcy_test(net, setup, height: float, times: np.ndarray, injection_pressure: np.ndarray,
                    outflow: np.ndarray, final_pressure: np.ndarray) -> DarcyTest:
    """The App. D.1 comparison of a run (its recorded rows and final pressures). k is read on the
    last drop, so it holds only for a run that ended steady (:attr:`DarcyTest.steady`)."""
    x_in = net.domain_centroid[net.inlet_domains, 0].mean()
    x_out = net.domain_centroid[net.outlet_domains, 0].mean()
    length, fluids, rate = x_out - x_in, setup.fluids, setup.rate
    steady_drop = float(injection_pressure[-1])
    k = fluids.viscosity_def * length * rate / (height * steady_drop)
    free = np.ones(net.n_domains, bool)
    free[net.outlet_domains] = False
    c_v = float(net.domain_volume[free].sum() / (length * height))
    x_d = (net.domain_centroid[free, 0] - x_in) / length
    centres, profile = binned_profile(x_d, final_pressure[free] / steady_drop)
    return DarcyTest(permeability=float(k), storage_fraction=c_v,
                     t_d=dimensionless_time(k, c_v, length, fluids, times),
                     inflow_pressure=np.asarray(injection_pressure) / steady_drop,
                     outflow_rate=np.asarray(outflow) / rate, profile_x_d=centres, profile=profile)
