"""Time loop of the two-phase pore-network model with fixed grains (seed 004 §3, Fig. 2).

Each step starts from the nominal dt and is shortened by the front criteria: Eq. 19 when front
pipes are shut by capillarity, so that one of them just opens (decisions #5: the paper applies it
when the whole front is shut), and Eq. 18 so that at most one domain fills per step. The
implicit scheme solves Eqs. 15-17 (see :mod:`hmdem.flow.pressure`); the explicit reference
scheme (Eqs. 29-30) uses p^n in the fluxes and a step below the stability limit.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..interrupts import deferred_interrupts
from ..network.network import Network
from . import front as fr
from .fluids import FluidPair, conductance
from .pressure import PressureSolution, PressureSystem
from .sparse import LinearSolveError

MAX_EQ18_PASSES = 30
MAX_EQ19_PASSES = 10  # bisections of a missed Eq. 19 step, geometric: 1/1024 of its range in log


class SimulationDiverged(RuntimeError):
    """A step could not be completed (e.g. a coupling iteration diverged); the run stops there."""


@dataclass
class FlowSetup:
    """Everything a run needs besides the network. SI units, 2D quantities per metre of depth."""

    fluids: FluidPair
    rate: float  # total injection rate Q [m^3/s per m]
    dt: float  # nominal flow step [s]
    inlet: str = "manifold"  # "manifold": inflow domains share one pressure; "split": Q/N_in each
    scheme: str = "implicit"  # or "explicit"
    chi: float = 1.005  # Eq. 19 timestep-expanding coefficient
    two_phase: bool = True  # False: single-phase run (Darcy test), no front
    t_max: float = np.inf  # stop time (single-phase runs stop here; two-phase runs at breakthrough)
    max_steps: int = 2_000_000


@dataclass
class FlowState:
    pressure: np.ndarray
    saturation: np.ndarray
    invaded: np.ndarray
    invasion_time: np.ndarray
    t: float = 0.0


@dataclass
class RunRecord:
    """Time series (one row per recorded step) and counters."""

    rows: list = field(default_factory=list)
    steps: int = 0
    eq18_steps: int = 0
    eq19_steps: int = 0
    eq19_bisected_steps: int = 0  # Eq. 19 steps whose interpolated step opened nothing (decisions #93)
    solves: int = 0
    unsettled_solves: int = 0  # solves whose shut front pipes cycled or ran out of passes (decisions #88)
    injection_energy: float = 0.0
    dissipated_energy: float = 0.0
    peak_injection_pressure: float = 0.0
    peak_compression: float = 0.0  # max over steps and domains of |p_i| / K_f,i (Eq. 3 mixture)
    max_mass_balance_error: float = 0.0
    stored_volume: float = 0.0  # sum over steps of sum_i (V_i/K_i)(p^{n+1} - p^n)
    outflow_volume: float = 0.0  # sum over steps of Q_out dt
    breakthrough_time: float = float("nan")
    status: str = "running"
    message: str = ""  # why the run stopped, when not at breakthrough or a limit
    wall_time: float = 0.0
    wall_start: float = field(default_factory=time.perf_counter, repr=False, compare=False)

    def series(self, *names: str) -> list[np.ndarray]:
        """The named columns of the recorded steps (:attr:`columns`, timeseries.csv's header) as
        float arrays, one row per accepted step from t = 0."""
        index = [self.columns.index(name) for name in names]
        rows = np.array([[r[i] for i in index] for r in self.rows], float).reshape(-1, len(index))
        return list(rows.T)

    def injection_pressure(self) -> tuple[np.ndarray, np.ndarray]:
        """(t, mean injection pressure) of the recorded steps (timeseries.csv's t, p_in_mean)."""
        return tuple(self.series("t", "p_in_mean"))

    def step_energies(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t, dt, p_in, dE_in, dE_v) of the recorded steps: the injection energy p_in Q dt
        (Eq. 25) and the viscous dissipation sum_k q_k (p_i - p_j) dt (Eq. 26) of each step, the
        differences of the cumulative energy and dissipation columns."""
        t, dt, p, energy, dissipation = self.series("t", "dt", "p_in_mean", "energy", "dissipation")
        return t, dt, p, np.diff(energy, prepend=0.0), np.diff(dissipation, prepend=0.0)

    def run_mass_balance_error(self, rate: float, t: float) -> float:
        """|stored + outflow - injected| / injected over the whole run (all steps' defects and
        the rounding of the stored pressures included)."""
        injected = rate * t
        return abs(self.stored_volume + self.outflow_volume - injected) / injected if injected > 0 else 0.0

    columns = ("t", "dt", "p_in_mean", "q_in", "q_out", "saturation", "energy", "dissipation", "n_invaded", "limiter",
               "wall_s")


class FlowModel:
    """Fixed-grain two-phase flow on a :class:`~hmdem.network.network.Network`."""

    # A step changes nothing outside the state until it is accepted, so an interrupt inside it
    # simply drops it; a model whose steps do (moving grains with no snapshot to return to)
    # sets this to hold Ctrl-C and SIGTERM until the step is accepted (deferred_interrupts)
    whole_steps = False
    # An Eq. 19 step that opened none of the shut pipes is searched again by bisection
    # (:meth:`_bisect_first_opening`); a coupled model, whose pressures are known to its P-V
    # tolerance only, counts pipes within that tolerance as open instead (threshold_tolerance)
    bisect_missed_openings = True

    def __init__(self, net: Network, setup: FlowSetup):
        if setup.inlet not in ("manifold", "split"):
            raise ValueError(f"inlet must be 'manifold' or 'split', got {setup.inlet!r}")
        if setup.scheme not in ("implicit", "explicit"):
            raise ValueError(f"scheme must be 'implicit' or 'explicit', got {setup.scheme!r}")
        self.net, self.setup, self.fluids = net, setup, setup.fluids
        n = net.n_domains
        self.inlet, self.outlet = np.asarray(net.inlet_domains), np.asarray(net.outlet_domains)
        node = np.full(n, -1)
        free = np.ones(n, bool)
        free[self.outlet] = False
        free[self.inlet] = False
        node[free] = np.arange(free.sum())
        start = free.sum()
        if setup.inlet == "manifold":
            node[self.inlet] = start
        else:
            node[self.inlet] = start + np.arange(len(self.inlet))
        pipes = net.flowing_pipes
        a, b = net.pipe_domains[pipes, 0], net.pipe_domains[pipes, 1]
        # pipes inside the inlet manifold or between two outflow domains carry no flow
        keep = node[a] != node[b]
        self.pipes = pipes[keep]
        self.system = PressureSystem(a[keep], b[keep], node, net.domain_centroid)
        self.pipe_a, self.pipe_b = a[keep], b[keep]
        self.source = np.zeros(n)
        self.source[self.inlet] = setup.rate / max(len(self.inlet), 1)
        # dV_i of the current step (Eq. 15's -dV/dt source): zero for fixed grains, set by a
        # hydro-mechanical coupling inside its pressure-volume iteration
        self.volume_change = np.zeros(n)
        self.volume = net.domain_volume
        # distance to the outlet, for a front-progress figure
        d_out = cKDTree(net.domain_centroid[self.outlet]).query(net.domain_centroid)[0]
        self.dist_to_outlet = d_out
        self.start_distance = max(d_out[self.inlet].max(), 1e-300)
        self.record = RunRecord()

    # ---- state -----------------------------------------------------------------------------
    def initial_state(self) -> FlowState:
        n = self.net.n_domains
        return FlowState(np.zeros(n), np.zeros(n), np.zeros(n, bool), np.full(n, np.inf))

    def progress(self, state: FlowState) -> float:
        """Fraction of the inlet-to-outlet distance covered by the invaded cluster."""
        if not state.invaded.any():
            return 0.0
        return float(np.clip(1.0 - self.dist_to_outlet[state.invaded].min() / self.start_distance, 0.0, 1.0))

    def fraction_done(self, state: FlowState) -> float:
        """How far the run is: :meth:`progress` for two-phase runs, else t / t_max (0 without one)."""
        if self.setup.two_phase:
            return self.progress(state)
        return state.t / self.setup.t_max if np.isfinite(self.setup.t_max) else 0.0

    def pipe_properties(self, state: FlowState):
        """G (Eq. 1 with Eq. 4 viscosity), front orientation and p_c (Eq. 5) of the flowing pipes."""
        s = state.saturation if self.setup.two_phase else np.zeros_like(state.saturation)
        a, b = self.pipe_a, self.pipe_b
        eta = self.fluids.pipe_viscosity(s[a], s[b])
        ap = self.net.pipe_aperture[self.pipes]
        g = conductance(ap, eta, self.net.pipe_length[self.pipes])
        if self.setup.two_phase:
            orient = fr.front_orientation(state.invaded, a, b)
            pc = np.where(orient != 0, self.fluids.entry_pressure(ap), 0.0)
        else:
            orient = np.zeros(len(a), np.int8)
            pc = np.zeros(len(a))
        return g, orient, pc

    def storage_coefficient(self, state: FlowState) -> np.ndarray:
        """V_i / K_f,i with the mixture modulus of Eq. 3."""
        s = state.saturation if self.setup.two_phase else np.zeros_like(state.saturation)
        return self.volume / self.fluids.mixture_bulk_modulus(s)

    # ---- implicit step ---------------------------------------------------------------------
    def _trial(self, state, dt, g, orient, pc, blocked, hold=False):
        storage = self.storage_coefficient(state) / dt
        source = self.source - self.volume_change / dt
        sol = self.system.solve(storage, state.pressure, source, g, orient, pc, blocked, hold_blocked=hold)
        self.record.solves += sol.passes
        self.record.unsettled_solves += not sol.settled
        fill = self._fill_rates(state, sol, storage, orient, dt)
        return sol, fill

    def _invading_inflow(self, state, orient, pipe_flux, inlet_rate):
        """Invading-fluid inflow per domain: open front pipes plus the inlet into unfilled inflow domains."""
        fill = fr.front_fill_rates(orient, pipe_flux, self.pipe_a, self.pipe_b, self.net.n_domains)
        filling = self.inlet[~state.invaded[self.inlet]]
        fill[filling] += np.maximum(inlet_rate[filling], 0.0)
        return fill

    def _fill_rates(self, state, sol, storage, orient, dt):
        if not self.setup.two_phase:
            return np.zeros(self.net.n_domains)
        # rate from the inlet into each inflow domain: its storage change plus its net pipe outflow
        inlet_rate = (storage * (sol.pressure - state.pressure) + self.volume_change / dt
                      + self.system.divergence(sol.pipe_flux))
        return self._invading_inflow(state, orient, sol.pipe_flux, inlet_rate)

    def _margins(self, pressure, orient, pc):
        """p_u - p_d + p_c on front pipes (0 elsewhere); > 0 means the pipe would open."""
        dp = pressure[self.pipe_a] - pressure[self.pipe_b]
        return np.where(orient != 0, orient * dp + pc, 0.0)

    def step_cap(self) -> float:
        """Longest step the implicit scheme may take: the nominal dt (a coupling may lower it)."""
        return self.setup.dt

    def threshold_tolerance(self, state: FlowState) -> float:
        """Pressure within which a front pipe's p_u - p_d + p_c counts as at its threshold rather
        than shut: 0 here, where each step's pressures are exact solves (a coupling whose
        pressures are only known to an iteration tolerance returns that tolerance)."""
        return 0.0

    def implicit_step(self, state: FlowState, blocked_guess: np.ndarray):
        g, orient, pc = self.pipe_properties(state)
        dt = min(self.step_cap(), self.setup.t_max - state.t)
        limiter = "nominal"
        front = orient != 0
        solved = None
        if self.setup.two_phase and front.any():
            m0 = self._margins(state.pressure, orient, pc)
            # a pipe within the pressures' tolerance of its threshold is left to the active set
            shut = front & (m0 <= min(0.0, -self.threshold_tolerance(state)))
            if shut.any():
                # Eq. 19, generalised: with the pipes shut at p^n held shut, find the step at
                # which the first of them opens, so that pipe openings, like domain fillings
                # (Eq. 18), happen one event per step and the pattern does not depend on the
                # nominal dt. When the whole front is shut this is the paper's Eq. 19 case.
                held, held_fill = self._trial(state, dt, g, orient, pc, shut, hold=True)
                dt19 = fr.blocked_front_step(dt, m0[shut], held.margin[shut], self.setup.chi)
                if dt19 < dt:
                    dt_nominal, dt, limiter = dt, dt19, "eq19"
                    # the pipes Eq. 19 steers by: those at their threshold to round-off set no step
                    steering = shut.copy()
                    steering[shut] = ~fr.at_threshold_to_roundoff(m0[shut], held.margin[shut])
                elif np.all(held.margin[shut] <= 0.0) and np.all(held.margin[front & ~shut] > 0.0):
                    # shut pipes stay shut and open ones open: the held solution already
                    # satisfies Eq. 6 everywhere, so it is the active-set solution at this dt
                    solved = held, held_fill
        sol, fill = solved or self._trial(state, dt, g, orient, pc, blocked_guess)
        if limiter == "eq19" and self.bisect_missed_openings and self._missed_opening(sol, steering, m0):
            dt = self._bisect_first_opening(state, dt, dt_nominal, g, orient, pc, shut, steering)
            sol, fill = self._trial(state, dt, g, orient, pc, blocked_guess)
            self.record.eq19_bisected_steps += 1
        if self.setup.two_phase:
            sol, fill, dt, refined = self._refine_overfill(state, dt, sol, fill, g, orient, pc)
            if refined:
                limiter = "eq18"
        return sol, fill, dt, limiter

    @staticmethod
    def _missed_opening(sol, steering, margin_start) -> bool:
        """Whether an Eq. 19 step's solution (the active set's) opened none of the ``steering``
        pipes and took none of them even half-way from ``margin_start`` to its threshold (the
        interpolation puts one there; with chi = 1 exactly on it, U9)."""
        if np.any(steering & ~sol.blocked):
            return False
        deficit = -margin_start[steering]
        return not np.any(sol.margin[steering] - margin_start[steering] >= 0.5 * deficit)

    def _bisect_first_opening(self, state, dt_shut, dt_open, g, orient, pc, shut, steering) -> float:
        """A step at whose end one of the ``steering`` pipes has opened, the ``shut`` ones held
        shut: geometric bisection between ``dt_shut`` (none open) and ``dt_open`` (one has, the
        nominal step), MAX_EQ19_PASSES times, returning the shortest step found open, to a factor
        (dt_open / dt_shut)^(1/1024) (1.6 % for the 1e-11 s against 7.6e-5 s below). Eq. 19
        interpolates each pipe's p_u - p_d + p_c linearly over the step; a margin that first
        falls and then rises breaks that, and the interpolated step opens nothing. In sd at
        M = 1, Ca* = 100 a pipe 2e-5 Pa short of its threshold, falling, drew steps of 1e-11 s
        that each left it further short, thousands of them (a new-user pass; decisions #93)."""
        for _ in range(MAX_EQ19_PASSES):
            middle = math.sqrt(dt_shut * dt_open)
            held, _ = self._trial(state, middle, g, orient, pc, shut, hold=True)
            if np.any(held.margin[steering] > 0.0):
                dt_open = middle
            else:
                dt_shut = middle
        return dt_open

    @staticmethod
    def _mark_filled(state: FlowState) -> None:
        """Domains whose saturation is within FILL_TOLERANCE of 1 become invaded (S = 1) now."""
        newly = (state.saturation >= 1.0 - fr.FILL_TOLERANCE) & ~state.invaded
        state.saturation[newly] = 1.0
        state.invaded |= newly
        state.invasion_time[newly] = state.t

    def _end_step(self, state: FlowState, dt: float) -> None:
        """What changes with the accepted step besides pressure and saturation, before its
        time-series row is written (nothing for fixed grains)."""

    def _refine_overfill(self, state, dt, sol, fill, g, orient, pc):
        """Shorten dt until no domain overfills, aiming at the fill time of the first domain to
        fill (seed 004 Eq. 18, iterated; digest U10). If the passes run out, the longest trial that
        overfilled nothing is taken when there is one."""
        s_new = state.saturation + dt * fill / self.volume
        if not np.any(s_new > 1.0 + fr.FILL_TOLERANCE):
            return sol, fill, dt, False
        dt_lo, dt_hi = 0.0, dt
        under = None  # (sol, fill, dt) of the longest trial that overfilled nothing
        for _ in range(MAX_EQ18_PASSES):
            over = s_new > 1.0 + fr.FILL_TOLERANCE
            if over.any():
                dt_hi = min(dt_hi, dt)
                t_fill = fr.fill_times(self.volume, state.saturation, fill)
                target = int(np.argmin(np.where(over, t_fill, np.inf)))
            elif s_new[target] >= 1.0 - fr.FILL_TOLERANCE:
                # nothing overfills and the target is full (U10). Testing any domain instead let
                # an invaded one (S = 1) pass every trial: 58 of the 135 Eq. 18 steps in cf1's
                # first 150 left the target short, at S down to 0.99, for a tiny step to top up
                # (decisions #89)
                return sol, fill, dt, True
            elif dt > dt_lo:
                dt_lo, under = dt, (sol, fill, dt)
            guess = float(fr.fill_times(self.volume[target], state.saturation[target], fill[target]))
            dt = guess if dt_lo < guess < dt_hi else 0.5 * (dt_lo + dt_hi)
            sol, fill = self._trial(state, dt, g, orient, pc, sol.blocked)
            s_new = state.saturation + dt * fill / self.volume
        if under is not None and np.any(s_new > 1.0 + fr.FILL_TOLERANCE):
            sol, fill, dt = under
        return sol, fill, dt, True

    # ---- explicit step (Eqs. 29-30) --------------------------------------------------------
    def explicit_step(self, state: FlowState, _blocked_guess):
        """Forward Euler: fluxes from p^n (Eq. 29), dt below the network's stability bound.

        The bound used is the Gershgorin one, min_i (V_i/K_i) / sum_j G_ij (x 0.9), of which
        Eq. 30 is the order-of-magnitude estimate.
        """
        g, orient, pc = self.pipe_properties(state)
        p = state.pressure
        dp = p[self.pipe_a] - p[self.pipe_b]
        margin = self._margins(p, orient, pc)
        blocked = (orient != 0) & (margin <= 0)
        g_open = np.where(blocked, 0.0, g)
        flux = g_open * dp + orient * g_open * pc
        div = self.system.divergence(flux)
        storage_node = self.system.to_nodes(self.storage_coefficient(state))
        g_node = self.system.to_nodes(self._sum_conductance(g))
        dt_stable = 0.9 * float(np.min(storage_node / np.maximum(g_node, 1e-300)))
        dt = min(self.setup.dt, dt_stable, self.setup.t_max - state.t)
        limiter = "stability" if dt == dt_stable else "nominal"
        fill = np.zeros(self.net.n_domains)
        if self.setup.two_phase:
            fill = self._invading_inflow(state, orient, flux, self.source)
            t_fill = float(fr.fill_times(self.volume, state.saturation, fill).min())
            if t_fill < dt:
                dt, limiter = t_fill, "eq18"
        increment = self.system.domain_values(dt * self.system.to_nodes(self.source - div) / storage_node)
        return PressureSolution(p + increment, flux, blocked, margin, 0, increment), fill, dt, limiter

    def _sum_conductance(self, g):
        """sum_j G_ij per domain."""
        n = self.net.n_domains
        return np.bincount(self.pipe_a, weights=g, minlength=n) + np.bincount(self.pipe_b, weights=g, minlength=n)

    # ---- driver ----------------------------------------------------------------------------
    def run(self, state: FlowState | None = None, progress=None) -> tuple[FlowState, RunRecord]:
        """Advance until breakthrough (two-phase) or t_max; Ctrl-C ends the run cleanly."""
        state = state or self.initial_state()
        self.record = rec = RunRecord()
        step = self.implicit_step if self.setup.scheme == "implicit" else self.explicit_step
        blocked = np.zeros(len(self.pipes), bool)
        try:
            while True:
                if self.setup.two_phase and state.invaded[self.outlet].any():
                    rec.status = "breakthrough"
                    break
                if state.t >= self.setup.t_max * (1 - 1e-12):
                    rec.status = "t_max"
                    break
                if rec.steps >= self.setup.max_steps:
                    rec.status = "max_steps"
                    break
                with deferred_interrupts() if self.whole_steps else contextlib.nullcontext():
                    sol, fill, dt, limiter = step(state, blocked)
                    self._check_fluid_left(state, sol, dt)
                    blocked = sol.blocked
                    with deferred_interrupts():  # a step is accepted whole, or not at all
                        self._accept(state, sol, fill, dt, limiter)
                if progress is not None:
                    progress(self, state)
        except KeyboardInterrupt as exc:
            # an interrupt held through a step that then failed is delivered over the failure
            # (deferred_interrupts): the failure ended the run and keeps its reason (review)
            failure = exc.__context__
            if isinstance(failure, (SimulationDiverged, LinearSolveError)):
                self._record_failure(rec, state, failure)
            else:
                rec.status = "interrupted"
        except (SimulationDiverged, LinearSolveError) as exc:
            self._record_failure(rec, state, exc)
        rec.wall_time = time.perf_counter() - rec.wall_start
        if rec.status == "breakthrough":
            rec.breakthrough_time = state.t
        return state, rec

    @staticmethod
    def _record_failure(rec: RunRecord, state: FlowState, exc: Exception) -> None:
        """A run that could not go on: status "diverged" and the reason (a failed linear solve
        leaves the flow state of the last completed step)."""
        rec.status = "diverged"
        rec.message = str(exc) if isinstance(exc, SimulationDiverged) else \
            f"step {rec.steps + 1} at t = {state.t:.6g} s: {exc}"

    def _check_fluid_left(self, state: FlowState, sol, dt: float) -> None:
        """Stop the run (before the step is accepted) if a domain's pressure is at or below minus
        its fluid's bulk modulus: the linear equation of state (digest §4) then leaves the domain
        no fluid, rho = rho_0 (1 + p/K) <= 0. Compression is not bounded this way: the law
        only grows inaccurate (``peak_compression``). No run with the every-domain P-V test has come near
        this; the seed's P-V test at the port alone (``--pv-test inflow``) let paper-size B3 run
        away to -3e13 Pa and go on for 37,000 steps (BENCHMARKS.md)."""
        ratio = sol.pressure * self.storage_coefficient(state) / self.volume  # p_i / K_f,i
        worst = int(np.argmin(ratio))
        if ratio[worst] <= -1.0:
            raise SimulationDiverged(
                f"step {self.record.steps + 1} (t = {state.t:.6g} s, dt = {dt:.3g} s): domain {worst}'s pressure "
                f"{sol.pressure[worst]:.3g} Pa is below minus its fluid's bulk modulus "
                f"({sol.pressure[worst] / ratio[worst]:.3g} Pa), where the linear equation of state leaves no fluid")

    def _accept(self, state: FlowState, sol, fill, dt: float, limiter: str) -> None:
        rec = self.record
        div = self.system.divergence(sol.pipe_flux)
        q_out = -float(div[self.outlet].sum())
        p_in = float(sol.pressure[self.inlet].mean())
        rec.injection_energy += p_in * self.setup.rate * dt  # Eq. 25
        dp = sol.pressure[self.pipe_a] - sol.pressure[self.pipe_b]
        rec.dissipated_energy += float(np.sum(sol.pipe_flux * dp)) * dt  # Eq. 26, viscous part
        rec.peak_injection_pressure = max(rec.peak_injection_pressure, p_in)
        storage = self.storage_coefficient(state)  # V_i / K_f,i
        rec.peak_compression = max(rec.peak_compression, float(np.max(np.abs(sol.pressure) * storage / self.volume)))
        # discrete mass balance of the step (digest U8): sum_i [(V_i/K_i)(p^{n+1} - p^n) + dV_i] =
        # (Q_in - Q_out) dt, with p^{n+1} - p^n the increment the scheme produced. Storing
        # p^n + increment in a double rounds it by ~1e-16 |p|, which in the shortest Eq. 18 steps
        # (dt ~1e-5 s in cf1) is ~1e-10 of Q dt; the run-long balance below includes that rounding.
        known = self.system.domain_is_unknown
        stored = float(np.sum((storage * sol.increment + self.volume_change)[known]))
        defect = abs(stored - (self.setup.rate - q_out) * dt) / (self.setup.rate * dt)
        rec.max_mass_balance_error = max(rec.max_mass_balance_error, defect)
        rec.stored_volume += float(np.sum((storage * (sol.pressure - state.pressure) + self.volume_change)[known]))
        rec.outflow_volume += q_out * dt
        state.pressure = sol.pressure
        state.t += dt
        if self.setup.two_phase:
            state.saturation = np.clip(state.saturation + dt * fill / self.volume, 0.0, 1.0)
            self._mark_filled(state)
        self._end_step(state, dt)
        rec.steps += 1
        rec.eq18_steps += limiter == "eq18"
        rec.eq19_steps += limiter == "eq19"
        sat = float(np.sum(state.saturation * self.volume) / np.sum(self.volume))
        rec.rows.append((state.t, dt, p_in, self.setup.rate, q_out, sat, rec.injection_energy,
                         rec.dissipated_energy, int(state.invaded.sum()), limiter,
                         round(time.perf_counter() - rec.wall_start, 3)))
