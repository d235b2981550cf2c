"""Two-way coupled flow step with moving grains: the pressure-volume iteration (seed 004 §3.2,
Fig. 3a; digest §6, §9).

Each flow step first runs the fixed-grain front logic (Eqs. 18-19 choose dt, the active set
resolves Eq. 6) with the domain volumes changing at the rate of the last accepted step (a
predictor; decisions.md #18): that gives p_trial. Then, at that dt:

1. the pressure forces of p_trial (Eq. 8) are applied to the grains and the DEM is advanced by
   dt from t^n (by default the DEM is rewound to t^n before every iteration, so that each
   iteration evaluates the same map p_trial -> p_calc);
2. dV_i = V_i(grains now) - V_i^n enters the pressure equation as -dV/dt and it is re-solved,
   giving p_calc;
3. until |p_calc - p_trial| <= rtol max|p| + atol in every domain (the paper tests the inflow
   domain only), p_trial is updated by interface quasi-Newton (IQN-ILS, quasi_newton.py) on the
   map preconditioned by the Newton step of the linearised grain skeleton (skeleton.py), and
   by a scalar Newton step on each trapped pocket (pockets.py); each case chooses which.
   A step that does not converge within the cap, or diverges, is retried from t^n at half the
   step (up to ``max_dt_halvings`` times); the cap grows back after easy steps.

By default the evaluations of steps 1-3 run on a numba replica of the YADE disc scene
(replica.py), loaded from YADE's state at t^n. Once the replica's evaluation passes, YADE runs
the step from t^n at the same p_trial and its evaluation is tested in turn: it is the one kept,
and if it misses the tolerance the iteration goes on in YADE (decisions #65).

``pv_rewind=False`` is the paper's likely practice (digest §6): the DEM continues through the
iterations and p_trial <- p_calc. It lets loosely held grains near the front swing from one
iteration to the next; A1 then runs into the iteration cap from step ~900 and diverges at step
~2,120, and the reduced B3 diverges at step 50 (BENCHMARKS.md).

On acceptance the domain volumes and the pipe apertures (Eqs. 13-14, from the contact forces
and gaps) are updated for the next step; the network topology stays fixed and a contact that
detaches becomes a fracture pipe. ``one_way=True`` is the sequential model the paper compares
against (Zhang et al.): grains move under p, but dV never enters the pressure equation, or with
``one_way_volume="lagged"`` enters it one step late.

The DEM is reached only through the small protocol :class:`GrainModel`; this module does not
import YADE (``hmdem.dem.assembly.DiscAssembly`` implements the protocol).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..flow.grain_forces import pressure_force_matrix
from ..flow.simulation import FlowModel, FlowSetup, SimulationDiverged
from ..network.network import Network
from .apertures import ApertureLaw
from .geometry import DomainGeometry, contact_gaps
from .pockets import PocketNewton, trapped_pockets
from .quasi_newton import InterfaceQuasiNewton
from .replica import DiscReplica
from .skeleton import SkeletonNewton, skeleton_stiffness


DIVERGED = 1e3  # a P-V mismatch this many times the step's pressure scale is divergence
# a domain squeezed below this fraction of its initial area is held there: its grains have
# rearranged beyond what the fixed network topology describes (the polygon would fold over)
VOLUME_FLOOR = 0.01
# a contact whose shear force is within 1 % of the Coulomb limit counts as sliding (skeleton.py)
SLIDING = 0.99


class GrainModel(Protocol):
    """What the coupling needs from a DEM."""

    radii: np.ndarray
    timestep: float
    k_n: float  # contact normal stiffness [N/m per m of depth]
    k_s: float  # contact shear stiffness [N/m per m of depth]
    free_dofs: np.ndarray  # (n, 3): the x, y and spin about z of each grain that the DEM moves
    friction: float  # Coulomb coefficient of the contacts
    damping: float  # local damping of the grains' accelerations

    # optional: ``carried_state()`` after ``save_state()`` hands the state to the numba replica
    # (replica.CarriedState); a model without it iterates in the DEM itself. ``boundary_load``
    # (n, 2), the constant forces on loaded boundary grains, is optional too (none without it)
    def positions(self) -> np.ndarray: ...
    def save_state(self) -> None: ...
    def restore_state(self) -> None: ...
    def set_external_forces(self, forces: np.ndarray) -> None: ...
    def run(self, cycles: int) -> None: ...
    def normal_forces(self, pairs: np.ndarray) -> np.ndarray: ...
    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...
    def masses(self) -> np.ndarray: ...


@dataclass
class CouplingSetup:
    """Parameters of the pressure-volume iteration and of the DEM sub-stepping."""

    aperture_law: ApertureLaw = field(default_factory=ApertureLaw)
    pv_rtol: float = 1e-3  # max |p_calc - p_trial| / max |p| over all domains (digest §6: 1e-3)
    pv_atol: float = 1.0  # Pa, absolute floor of the same test
    pv_max_iter: int = 12
    # where the P-V test is made: "every" domain (default, decisions #18) or the "inflow"
    # domains only, as seed 004 §3.2 does ("convergence is controlled by the pressure-volume
    # equilibrium at the injection port"; digest §6 step 5)
    pv_test: str = "every"
    max_dt_halvings: int = 6  # rewound iteration: retries of an unconverged step at dt / 2^k
    # the halved cap doubles back after this many consecutive easy steps (<= pv_max_iter // 3
    # iterations): doubling after every easy step made hard stretches alternate between a
    # converged step and a failed one at twice its size
    pv_easy_steps_to_grow: int = 1
    # DEM cycles per flow step are at least this many (the paper: 2000) and at least enough that
    # the DEM step stays under stable_dem_step; None: only the latter
    dem_cycles_per_step: int | None = None
    stable_dem_step: float = 0.0  # DEM stability step [s] (start_grains sets it from the grains)
    one_way: bool = False
    # what the one-way variant does with the grains' volume change: "ignored", dV never enters
    # the pressure equation (digest H10's no-dV variant); "lagged", the change of the last
    # accepted step enters the next step's pressure solve, at most at the rate it came (a
    # shorter step books its share, the rest waits), so that every change is booked, a step
    # late (sequential coupling; at the realistic K of water B3 swings, decisions #66)
    one_way_volume: str = "ignored"
    # rewind the DEM to t^n before every P-V iteration after the first and update p_trial by
    # interface quasi-Newton (IQN-ILS): each iteration is then a function evaluation of one
    # fixed point. False: the DEM continues and p_trial <- p_calc (the paper's likely practice)
    pv_rewind: bool = True
    # the first p_trial of a step is solved with the domain volumes changing at the rate of the
    # last accepted step (dV = rate x dt) rather than standing still: where the grains move
    # smoothly the first iteration then already converges
    pv_predictor: bool = True
    # trapped pockets (pockets.py): each IQN update is followed by a safeguarded scalar Newton
    # step on their trial pressures (B1 and B3 leave it off: decisions #52, #55)
    pv_pocket_newton: bool = True
    # flow steps of the same dt whose secant pairs the IQN update reuses (IQN-ILS(q)); 0: none.
    # They save ~10 % over the first steps of A3 and B3 and hurt where the map changes from
    # one step to the next (B1's late stretch: decisions #47, BENCHMARKS.md)
    pv_reuse_steps: int = 5
    # secant pairs the IQN update fits at most, newest first (reused ones included). Where the
    # map is rough (B1), a fit to many pairs from iterates far apart can cancel the Newton step
    # and stall the iteration a few tolerances from convergence (decisions #56); past the cap, the
    # last slot keeps the step's largest residual change (quasi_newton.py, decisions #81)
    pv_max_columns: int = 40
    # YADE local damping of the grains during the run (the sample always settles at 0.7). The
    # seed does not state it; 0.7 is PFC's default (digest §2.4, decisions #49)
    dem_damping: float = 0.7
    # precondition the IQN update with the Newton step of the linearised grain skeleton
    # (skeleton.py): IQN then works on p -> p + (I - J)^-1 (H(p) - p) (decisions #55)
    pv_skeleton_newton: bool = True
    skeleton_inertia_factor: float = 0.5  # c in the grains' m / (c dt^2) (skeleton.py)
    # iterate on the numba replica of the disc scene (replica.py) and run YADE once per attempt,
    # at the pressures the replica converged to; that run is tested and kept (decisions #65)
    dem_replica: bool = True

    @property
    def iterates_on_replica(self) -> bool:
        """The P-V iteration runs on the replica: asked for, and rewound to the step's start each
        evaluation (the replica is loaded from that snapshot); the one-way variant iterates not
        at all."""
        return self.dem_replica and self.pv_rewind and not self.one_way


def replica_for(grains: GrainModel, coupling: CouplingSetup) -> DiscReplica | None:
    """The numba replica the P-V iteration runs on, where the DEM can hand over its state."""
    return DiscReplica.of(grains) if coupling.iterates_on_replica and hasattr(grains, "carried_state") else None


@dataclass(frozen=True)
class PVEvaluation:
    """One P-V evaluation: the step's start time and dt, the iteration within the attempt, the
    largest mismatch over its tolerance, the domain where it sits, whether the update that
    produced this p_trial used secant pairs of earlier steps."""

    t: float
    dt: float
    iteration: int
    mismatch_over_tolerance: float
    worst_domain: int
    reused_pairs: bool
    on_replica: bool = False  # evaluated on the numba replica rather than YADE
    confirmation: bool = False  # YADE's run at the pressures the replica converged to


@dataclass
class CouplingRecord:
    pv_iterations: list = field(default_factory=list)
    dem_cycles: int = 0
    unconverged_steps: int = 0
    dt_halvings: int = 0
    dem_seconds: float = 0.0  # wall time in DEM cycles
    rewind_seconds: float = 0.0  # wall time saving and restoring the DEM state
    pocket_attempts: int = 0  # P-V attempts with trapped pockets (pockets.py)
    replica_cycles: int = 0  # DEM cycles run on the numba replica (replica.py)
    replica_seconds: float = 0.0
    confirmations: int = 0  # YADE runs at pressures the replica converged to
    confirmations_failed: int = 0  # ... whose own evaluation missed the tolerance
    # YADE runs at the last trial pressures of a last attempt the replica left unconverged
    unconverged_yade_runs: int = 0

    @property
    def all_dem_cycles(self) -> int:
        """DEM cycles on either engine (YADE and the replica): the P-V iteration's work."""
        return self.dem_cycles + self.replica_cycles


class CoupledFlowModel(FlowModel):
    """:class:`FlowModel` whose grains move (YADE through :class:`GrainModel`)."""

    @property
    def bisect_missed_openings(self) -> bool:
        """Whether an Eq. 19 step that opens nothing is bisected (decisions #93): for the one-way
        variant, whose solves are exact as the fixed-grain model's, but not for the two-way
        model, whose pressures are known to the P-V tolerance, within which a pipe counts as at
        its threshold (threshold_tolerance), and where each pass would be a P-V prediction."""
        return self.coupling.one_way

    def __init__(self, net: Network, setup: FlowSetup, grains: GrainModel, coupling: CouplingSetup):
        if coupling.one_way_volume not in ("ignored", "lagged"):
            raise ValueError(f"one_way_volume must be 'ignored' or 'lagged', not {coupling.one_way_volume!r}")
        if coupling.pv_test not in ("every", "inflow"):
            raise ValueError(f"pv_test must be 'every' or 'inflow', not {coupling.pv_test!r}")
        if coupling.stable_dem_step <= 0.0 and not coupling.dem_cycles_per_step:
            raise ValueError("stable_dem_step must be > 0 (start_grains sets it) or dem_cycles_per_step given")
        super().__init__(net, setup)
        self.grains, self.coupling = grains, coupling
        self.geometry = DomainGeometry(net)
        self.coupling_record = CouplingRecord()
        self.quasi_newton = InterfaceQuasiNewton(reuse_steps=coupling.pv_reuse_steps, max_columns=coupling.pv_max_columns)
        self.pocket_newton = PocketNewton(net.n_domains, self.pipe_a, self.pipe_b)
        self.coupling_dt = setup.dt  # flow-step cap of the coupling (halved when P-V fails)
        self._easy_steps = 0  # consecutive easy steps since the cap was last changed
        self._tried_dt = setup.dt  # the last step the P-V iteration was tried at
        self.contact_pairs = net.pipe_grains
        self.replica = replica_for(grains, coupling)
        self._grains_moved = False  # YADE has run since the step's snapshot (a rewind must restore it)
        self.positions = grains.positions()  # grain centres now (read from the DEM after each run)
        initial_volume = self.geometry.volumes(self.positions)
        self.volume_floor = VOLUME_FLOOR * initial_volume
        self.floored = np.zeros(net.n_domains, bool)  # domains that have been held at the floor
        self.reference_volume = initial_volume
        self.volume[:] = self.reference_volume
        initial_force = grains.normal_forces(self.contact_pairs)
        self.initial_force = initial_force  # per pipe [N per m]: Figs. 15c-16c name the weak contacts that open first
        self.initially_closed = initial_force > 0.0
        # a contact counts as opened (a fracture) once its surfaces have separated by more than
        # the mean elastic overlap of the sample's contacts, F_mean / k_n (decisions.md): smaller
        # separations are the contact network's own deformation scale (the Eq. 14 aperture then
        # differs from a0 by < 1 %), e.g. weak contacts flickering as the skeleton relaxes
        self.opening_gap = float(initial_force[self.initially_closed].mean()) / grains.k_n
        self.detached = np.zeros(net.n_pipes, bool)  # F <= 0 at some accepted step (literal Eq. 14)
        self.max_gap = np.full(net.n_pipes, -np.inf)
        self.opened_time = np.full(net.n_pipes, np.inf)  # when each contact first counted as opened
        self.wetted_time = np.full(net.n_domains, np.inf)  # when invading fluid first entered each domain
        self.volume_rate = np.zeros(net.n_domains)  # dV/dt of the last accepted step
        self.unbooked_volume = np.zeros(net.n_domains)  # lagged one-way: dV moved, not yet in a solve
        self._last_dt = setup.dt  # the last accepted step (over which its dV came)
        # a list to append a PVEvaluation to at every P-V evaluation (benchmarks/huang_pv_log.py); None: off
        self.pv_log: list | None = None
        self._predicting = False  # front-logic solves use dV = volume_rate x dt
        self._inside_step = False  # a step's DEM snapshot is kept and not yet accepted
        self._update_apertures(0.0)

    # ---- grains ----------------------------------------------------------------------------
    def dem_cycles(self, dt: float) -> int:
        """DEM cycles covering dt, at a DEM step dt/cycles that is never above the stable one."""
        fixed = self.coupling.dem_cycles_per_step
        stable = self.coupling.stable_dem_step
        needed = math.ceil(dt / stable) if stable > 0 else 1
        return max(fixed or 0, needed, 1)

    def move_grains(self, pressure: np.ndarray, dt: float, on_replica: bool = False) -> np.ndarray:
        """Apply the Eq. 8 forces of ``pressure`` and advance the DEM (YADE, or its numba replica)
        by dt; new positions."""
        grains = self.replica if on_replica else self.grains
        grains.set_external_forces((self._force_matrix(self.positions) @ pressure).reshape(-1, 2))
        cycles = self.dem_cycles(dt)
        grains.timestep = dt / cycles
        # before the run: a Ctrl-C or SIGTERM inside YADE's cycles must still rewind it
        self._grains_moved |= not on_replica
        start = time.perf_counter()
        grains.run(cycles)
        rec = self.coupling_record
        if on_replica:
            rec.replica_seconds += time.perf_counter() - start
            rec.replica_cycles += cycles
        else:
            rec.dem_seconds += time.perf_counter() - start
            rec.dem_cycles += cycles
        self.positions = grains.positions()
        return self.positions

    def _force_matrix(self, positions: np.ndarray):
        """Eq. 8 at ``positions`` (pressure_force_matrix), kept while the same positions array is
        passed: every evaluation of a rewound step starts from t^n's."""
        if getattr(self, "_force_positions", None) is not positions:
            self._force_positions = positions
            self._force = pressure_force_matrix(self.net, self.grains.radii, positions)
        return self._force

    def _rewind(self, save: bool = False) -> None:
        """Keep (save=True) or return to the DEM state, and the grain positions, of t^n."""
        start = time.perf_counter()
        if save:
            self.grains.save_state()
            self._saved_positions = self.positions
            if self.replica is not None:
                self.replica.damping = self.grains.damping  # it may have been changed since
                self.replica.load(self.grains.carried_state())
        else:
            if self._grains_moved:
                self.grains.restore_state()
            if self.replica is not None:
                self.replica.restore_state()
            self.positions = self._saved_positions
        self._grains_moved = False
        self.coupling_record.rewind_seconds += time.perf_counter() - start

    def domain_volumes(self, positions: np.ndarray) -> np.ndarray:
        """Centre-polygon areas, held at :data:`VOLUME_FLOOR` x the initial area (the same
        function gives V^n and V^{n+1}, so the Eq. 15 mass balance is exact either way)."""
        return np.maximum(self.geometry.volumes(positions), self.volume_floor)

    def _update_apertures(self, t: float) -> None:
        """Eqs. 13-14 apertures from the live contact forces and gaps at time t; records
        detachments, the largest separations and when each contact first counted as opened."""
        g = self.contact_pairs
        force = self.grains.normal_forces(g)
        gap = contact_gaps(self.positions, self.grains.radii, g)
        self.net.pipe_aperture[:] = self.coupling.aperture_law(force, gap)
        self.detached |= self.initially_closed & self.coupling.aperture_law.opened(force)
        self.detached_gap = np.where(force > 0.0, -np.inf, gap)  # now; -inf where in compression
        self.max_gap = np.maximum(self.max_gap, self.detached_gap)
        self.opened_time[self.opened & np.isinf(self.opened_time)] = t

    @property
    def opened(self) -> np.ndarray:
        """Initially closed contacts that have separated by more than :attr:`opening_gap`."""
        return self.detached & (self.max_gap > self.opening_gap)

    @property
    def open_now(self) -> np.ndarray:
        """Opened contacts still separated by more than :attr:`opening_gap` (the fracture map of a
        snapshot, as the paper's Fig. 13 shows it at breakthrough; :attr:`opened` also keeps
        those that have closed again)."""
        return self.opened & (self.detached_gap > self.opening_gap)

    def grain_snapshot(self) -> dict:
        """What a ParaView snapshot keeps of the grains (hmdem/snapshots.py): their centres, the
        pipes' apertures and which contacts have opened."""
        return {"points": self.positions.copy(), "pipe_aperture": self.net.pipe_aperture.copy(),
                "pipe_opened": self.opened.copy()}

    @property
    def whole_steps(self) -> bool:
        """--one-way and --pv-continue move the grains with no snapshot of t^n to rewind to, so
        Ctrl-C and SIGTERM wait for the step's acceptance (a review found them leaving the
        grains a step ahead of the flow state)."""
        return self.coupling.one_way or not self.coupling.pv_rewind

    def run(self, state=None, progress=None):
        """:meth:`FlowModel.run`; a run stopped inside a step (Ctrl-C, SIGTERM, divergence) is
        rewound to the last accepted step when the rewound P-V iteration kept it, so that the
        run directory's grains, contacts and apertures belong to the flow state it writes
        (--one-way and --pv-continue finish the step instead, :attr:`whole_steps`)."""
        state, rec = super().run(state, progress)
        if self._inside_step:
            self._rewind()
            self._inside_step = False
        return state, rec

    # ---- flow step with the P-V iteration --------------------------------------------------
    def implicit_step(self, state, blocked_guess):
        c, rec = self.coupling, self.coupling_record
        if c.one_way or not c.pv_rewind:
            sol, fill, dt, limiter, iterations, converged = self._pv_step(state, blocked_guess)
        else:
            sol, fill, dt, limiter, iterations, converged = self._pv_step_with_retries(state, blocked_guess)
        rec.unconverged_steps += not converged
        rec.pv_iterations.append(iterations)
        return sol, fill, dt, limiter

    def _pv_step_with_retries(self, state, blocked_guess):
        """Rewound iteration: a step whose P-V iteration does not converge (or diverges) is
        retried from t^n with half the step; the cap grows back after easy steps."""
        c = self.coupling
        self._rewind(save=True)
        self._inside_step = True  # the DEM is at t^n in the snapshot until _accept
        for halving in range(c.max_dt_halvings + 1):
            try:
                sol, fill, dt, limiter, iterations, converged = self._pv_step(
                    state, blocked_guess, last_attempt=halving == c.max_dt_halvings)
            except SimulationDiverged:
                if halving == c.max_dt_halvings:
                    raise
                converged = False
            if converged or halving == c.max_dt_halvings:
                break
            self._rewind()
            self.coupling_dt = 0.5 * self._tried_dt
            self.coupling_record.dt_halvings += 1
            self._easy_steps = 0
        if converged and iterations <= c.pv_max_iter // 3:
            self._easy_steps += 1
            if self._easy_steps >= c.pv_easy_steps_to_grow:
                self.coupling_dt = min(2.0 * self.coupling_dt, self.setup.dt)
                self._easy_steps = 0
        else:
            self._easy_steps = 0
        return sol, fill, dt, limiter, iterations, converged

    def step_cap(self) -> float:
        return min(self.setup.dt, self.coupling_dt)

    def threshold_tolerance(self, state) -> float:
        """The P-V test's pressure tolerance at p^n: the iteration resolves the pressures no
        closer, so a front pipe shut by less is at its threshold, and an Eq. 19 step cut for it
        would resolve the iteration's noise (decisions #71). The one-way variant solves each step
        once, exactly, and keeps 0."""
        return 0.0 if self.coupling.one_way else self._pv_tolerance(state.pressure)

    def _pv_tolerance(self, pressure: np.ndarray) -> float:
        """The P-V test's bound on |p_calc - p_trial| (decisions #18): relative to max |p|, with a floor."""
        c = self.coupling
        return c.pv_rtol * float(np.abs(pressure).max()) + c.pv_atol

    def _trial(self, state, dt, g, orient, pc, blocked, hold=False):
        if self._predicting:
            self.volume_change[:] = self.volume_rate * dt
        elif self.coupling.one_way and self.coupling.one_way_volume == "lagged":  # every solve is a step's
            self.volume_change[:] = self.unbooked_volume * min(1.0, dt / self._last_dt)
        return super()._trial(state, dt, g, orient, pc, blocked, hold)

    def _pv_evaluation(self, state, dt, positions, g, orient, pc, blocked):
        """One evaluation of the P-V map H (digest §6): the domain volumes of the grains moved to
        ``positions`` enter the Eq. 15 balance as dV, and the flow is re-solved from t^n."""
        self.volume_change[:] = self.domain_volumes(positions) - self.reference_volume
        return self._trial(state, dt, g, orient, pc, blocked)

    def _pv_step(self, state, blocked_guess, last_attempt: bool = True):
        """One flow step at the front logic's dt with the P-V iteration; also returns the
        iteration count and whether it converged. On the ``last_attempt`` a step that is kept
        unconverged is YADE's, not the replica's."""
        c = self.coupling
        self.volume_change[:] = 0.0
        self._predicting = c.pv_predictor and not c.one_way
        try:
            sol, fill, dt, limiter = super().implicit_step(state, blocked_guess)
        finally:
            self._predicting = False
        self._tried_dt = dt
        pockets = np.zeros(0, int)
        if c.pv_pocket_newton and not c.one_way and c.pv_rewind:
            pockets = trapped_pockets(state.invaded, state.saturation, self.pipe_a, self.pipe_b)
            # outflow domains are held at p = 0; inflow domains receive the injection: neither is closed
            pockets = np.setdiff1d(pockets, np.r_[self.outlet, self.inlet])
            self.pocket_newton.new_step(pockets, dt)
            self.coupling_record.pocket_attempts += len(pockets) > 0
        on_replica = self.replica is not None
        positions = self.move_grains(sol.pressure, dt, on_replica)
        if c.one_way:
            return sol, fill, dt, limiter, 0, True
        g, orient, pc = self.pipe_properties(state)
        p_trial = sol.pressure
        self.quasi_newton.new_step(dt)
        newton = None  # the linearised skeleton's Newton step, built at the first unconverged evaluation
        iteration = 0
        confirming = False  # this evaluation is YADE's run at the pressures the replica converged to
        kept_unconverged = False  # ... or at its last trial, the replica out of iterations
        while True:
            iteration += not confirming
            calc, fill = self._pv_evaluation(state, dt, positions, g, orient, pc, sol.blocked)
            mismatch = np.abs(calc.pressure - p_trial)
            scale = max(np.abs(state.pressure).max(), np.abs(p_trial).max(), c.pv_atol)
            if not np.isfinite(mismatch).all() or mismatch.max() > DIVERGED * scale:
                raise SimulationDiverged(f"pressure-volume iteration diverged at t = {state.t:.6g} s "
                                         f"(step {self.record.steps + 1}, iteration {iteration}): pressure "
                                         f"mismatch {mismatch.max():.3g} Pa")
            sol = calc
            tolerance = self._pv_tolerance(calc.pressure)
            if self.pv_log is not None:
                worst = int(np.argmax(mismatch))
                self.pv_log.append(PVEvaluation(state.t, dt, iteration, float(mismatch[worst] / tolerance), worst,
                                                self.quasi_newton.reused, on_replica,
                                                confirming and not kept_unconverged))
            tested = mismatch[self.inlet] if c.pv_test == "inflow" else mismatch
            passed = bool(np.all(tested <= tolerance))
            if confirming and kept_unconverged:
                self.coupling_record.unconverged_yade_runs += 1
            elif confirming:
                self.coupling_record.confirmations += 1
                self.coupling_record.confirmations_failed += not passed
            confirming = False
            if passed and not on_replica:
                return sol, fill, dt, limiter, iteration, True
            if passed:
                # YADE runs the step from t^n at the pressures the replica converged to; that run
                # is tested as any evaluation, kept if it passes, iterated on (in YADE) if not
                on_replica, confirming = False, True
                self._rewind()
                positions = self.move_grains(p_trial, dt)
                continue
            if iteration == c.pv_max_iter and on_replica and last_attempt:
                # out of iterations on the replica with no halving left: YADE runs the step once
                # at the last trial pressures, so that the step kept unconverged is YADE's
                on_replica, confirming, kept_unconverged = False, True, True
                self._rewind()
                positions = self.move_grains(p_trial, dt)
                continue
            if iteration == c.pv_max_iter:
                break
            if c.pv_rewind:
                correction = calc.pressure - p_trial
                if c.pv_skeleton_newton:
                    newton = newton or self._skeleton_newton(state, dt, g, calc.blocked, on_replica)
                    correction = newton.step(correction)
                p_next = self.quasi_newton.update(p_trial, p_trial + correction)
                if len(pockets):
                    p_next[pockets] = self.pocket_newton.update(p_trial, calc.pressure, p_next,
                                                                self._closed(calc.blocked, g)[pockets], tolerance)
                p_trial = p_next
                self._rewind()
            else:
                p_trial = calc.pressure
            positions = self.move_grains(p_trial, dt, on_replica)
        return sol, fill, dt, limiter, c.pv_max_iter, False

    def _skeleton_newton(self, state, dt: float, g: np.ndarray, blocked: np.ndarray,
                         on_replica: bool = False) -> SkeletonNewton:
        """The Newton step of the linearised P-V map at the grains of t^n (skeleton.py), with the
        contacts the DEM (YADE or its replica) has now and this step's implicit pressure matrix."""
        grains = self.replica if on_replica else self.grains
        system, positions = self.system, self._saved_positions
        pairs, normal, shear = grains.contacts()
        # a contact sliding at the Coulomb limit carries no more shear as it is pushed on
        sliding = shear >= SLIDING * grains.friction * normal
        masses = grains.masses()
        flow_matrix = system.matrix(system.to_nodes(self.storage_coefficient(state) / dt), np.where(blocked, 0.0, g))
        force = self._force_matrix(positions)
        stiffness = skeleton_stiffness(positions, grains.radii, pairs, grains.k_n, np.where(sliding, 0.0, grains.k_s))
        return SkeletonNewton(flow_matrix, system.to_nodes_matrix, force, self.geometry.volume_gradient(positions),
                              stiffness, masses, 0.5 * masses * grains.radii**2, grains.free_dofs, dt,
                              self.coupling.skeleton_inertia_factor)

    def _closed(self, blocked: np.ndarray, g: np.ndarray) -> np.ndarray:
        """Domains with no open pipe (no flux in or out at this solve)."""
        return self._sum_conductance(np.where(blocked, 0.0, g)) == 0.0

    def _accept(self, state, sol, fill, dt, limiter):
        self._inside_step = False
        super()._accept(state, sol, fill, dt, limiter)

    def _end_step(self, state, dt):
        """The grains have moved: the domains take their new volumes and apertures before the
        step's row is written, so that its n_invaded counts domains squeezed full."""
        volume = self.domain_volumes(self.positions)
        self.floored |= volume <= self.volume_floor
        # the lagged one-way variant booked volume_change in this step's solve (and its balance)
        self.unbooked_volume += volume - self.volume - self.volume_change
        self._last_dt = dt
        self.volume_rate = (volume - self.volume) / dt
        # saturation is a volume fraction: the invading volume is kept as the domain deforms
        invading = state.saturation * self.volume
        state.saturation = np.where(state.invaded, 1.0, np.clip(invading / volume, 0.0, 1.0))
        self._mark_filled(state)  # a partly filled domain squeezed full is filled
        self.volume[:] = volume
        self.reference_volume = volume
        self.volume_change[:] = 0.0
        self.wetted_time[(state.saturation > 0.0) & np.isinf(self.wetted_time)] = state.t
        self._update_apertures(state.t)
