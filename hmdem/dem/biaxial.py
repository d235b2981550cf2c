"""Strain-controlled biaxial test of a disc sample in YADE: the Huang calibration (seed 004 §2.3, §4.2).

Procedure (digest §2.3): the sample is compacted isotropically to sigma3 with frictionless
grains and walls (:func:`hmdem.dem.compaction.compact_sample`); it is then rebuilt in a
walled YADE scene from the compacted packing (positions reproduce every overlap, hence every
normal force; a frictionless contact carries no shear force, so nothing is lost), the grains
get their working friction mu = 0.6 (walls stay frictionless, f_w = 0), the top and bottom
walls move towards each other at constant opposite velocity up to 2.5 % axial strain, and the
left and right walls hold sigma3 under force control (each is a free body loaded by sigma3 x the
current height; its equation of motion is the servo, see :func:`load_biaxial`).

Stresses are wall force per wall length per metre of depth (1 m thick discs). Strains are
compression-positive: eps_a = (H0 - H) / H0, eps_l = (W0 - W) / W0, and the volumetric
(area) strain eps_v = 1 - W H / (W0 H0). Elastic constants (see :func:`elastic_constants`):

    E  = least-squares slope of q = sigma1 - sigma3 against eps_a over eps_a in FIT_STRAIN,
    nu = -(least-squares slope of eps_l against eps_a) over the same range (2D Poisson ratio).

The friction angle is Mohr-Coulomb from the peak sigma1 and the sigma3 measured at the peak
(:func:`hmdem.calibration.mohr_coulomb_friction_angle`). The DEM runs in chunks of cycles
(:func:`hmdem.dem.assembly.run_cycles`); Python only reads the four wall forces between chunks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..calibration import mohr_coulomb_friction_angle
from ..network.packing import CONTACT_STIFFNESS, GRAIN_DENSITY, GRAIN_FRICTION, DiscPacking
from ..yade_env import import_yade
from .assembly import run_cycles
from .compaction import WALLS, compact_sample, nominal_side
from .discs import add_discs, disc_engines

SIGMA3 = 0.1e6  # confining stress of the calibration [Pa]
MAX_STRAIN = 0.025  # axial strain at the end of the test
STRAIN_RATE = 5.0  # default axial strain rate [1/s]: inertial number eps' d sqrt(rho / p) ~ 3e-5
FIT_STRAIN = (0.0, 0.001)  # axial-strain window of the E and nu fits (about 1/3 of the peak deviator)
CHUNK = 20  # DEM cycles between two wall-force reads / side-wall load updates

# the paper's calibration targets (seed 004 §4.2, digest §2.3)
TARGETS = {"young_modulus_pa": 65.4e6, "poisson_ratio": 0.102, "peak_sigma1_pa": 309.6e3,
           "friction_angle_deg": 30.8, "sigma3_pa": 0.1e6}


@dataclass
class BiaxialResult:
    """Time series (one entry per chunk of DEM cycles) and derived constants of one test."""

    cycles: np.ndarray
    time: np.ndarray
    strain_axial: np.ndarray
    strain_lateral: np.ndarray
    strain_volumetric: np.ndarray
    sigma1: np.ndarray
    sigma3: np.ndarray
    sigma3_target: float
    strain_rate: float
    fit_strain: tuple[float, float]
    young_modulus: float = float("nan")
    poisson_ratio: float = float("nan")
    peak_sigma1: float = float("nan")
    sigma3_at_peak: float = float("nan")
    strain_at_peak: float = float("nan")
    friction_angle: float = float("nan")
    max_sigma3_deviation: float = float("nan")  # max |sigma3 - target| / target during loading
    n_grains: int = 0
    porosity: float = float("nan")  # after compaction, box-area porosity
    box: tuple[float, float] = (0.0, 0.0)
    timestep: float = 0.0
    compaction_seconds: float = 0.0
    loading_seconds: float = 0.0
    settings: dict = field(default_factory=dict)
    packing: DiscPacking | None = None  # the compacted sample the test started from
    status: str = "finished"  # or "interrupted" (Ctrl-C, SIGTERM): the curve up to max_axial_strain
    interrupted_in: str | None = None  # "compaction" (no curve) or "loading" (the curve so far)

    def derive_constants(self) -> None:
        """E and nu (:func:`elastic_constants`), the peak, phi and the sigma3 deviation from the
        curve. A curve gives those it reaches: E and nu once it has passed ``fit_strain`` (the
        command line ends a test past it; an interrupted one may stop short), a peak (of the
        curve so far) once it has 5 samples; the rest stay NaN."""
        if len(self.sigma1) == 0:
            return
        if self.passed_fit_window:
            self.young_modulus, self.poisson_ratio = elastic_constants(self.strain_axial, self.strain_lateral,
                                                                       self.deviator, self.fit_strain)
        if len(self.sigma1) >= 5:
            self.peak_sigma1, self.sigma3_at_peak, self.strain_at_peak = peak(self.sigma1, self.sigma3,
                                                                              self.strain_axial)
            self.friction_angle = mohr_coulomb_friction_angle(self.peak_sigma1, self.sigma3_at_peak)
        self.max_sigma3_deviation = float(np.max(np.abs(self.sigma3 - self.sigma3_target)) / self.sigma3_target)

    @property
    def deviator(self) -> np.ndarray:
        return self.sigma1 - self.sigma3

    @property
    def passed_fit_window(self) -> bool:
        return len(self.strain_axial) > 0 and self.strain_axial[-1] > self.fit_strain[1]

    def secant_modulus_50(self) -> float:
        """E50: secant of q at half its (smoothed) peak, for comparison with the fitted E (of an
        interrupted curve, like its peak: of the curve so far)."""
        q = self.deviator
        if len(q) < 5:
            return float("nan")
        half = 0.5 * np.convolve(q, np.ones(5) / 5, mode="valid").max()
        k = int(np.argmax(q >= half))
        return float(q[k] / self.strain_axial[k]) if self.strain_axial[k] > 0 else float("nan")

    def summary(self) -> dict:
        """Scalars for summary.json, with the paper's targets and the relative errors."""
        out = {
            "status": self.status,
            "interrupted_in": self.interrupted_in,
            "young_modulus_pa": self.young_modulus,
            "poisson_ratio": self.poisson_ratio,
            "peak_sigma1_pa": self.peak_sigma1,
            "friction_angle_deg": self.friction_angle,
            "sigma3_pa": self.sigma3_target,
            "sigma3_at_peak_pa": self.sigma3_at_peak,
            "axial_strain_at_peak": self.strain_at_peak,
            "max_sigma3_deviation": self.max_sigma3_deviation,
            "fit_axial_strain_range": list(self.fit_strain),
            "young_modulus_definition": "least-squares slope of sigma1 - sigma3 vs axial strain over fit_axial_strain_range",
            "poisson_ratio_definition": "-(least-squares slope of lateral strain vs axial strain) over the same range",
            "young_modulus_secant50_pa": self.secant_modulus_50(),
            "strain_rate_per_s": self.strain_rate,
            "max_axial_strain": float(self.strain_axial[-1]) if len(self.strain_axial) else float("nan"),
            "n_grains": self.n_grains,
            "porosity_after_compaction": self.porosity,
            "box_m": list(self.box),
            "dem_timestep_s": self.timestep,
            "dem_cycles": int(self.cycles[-1]) if len(self.cycles) else 0,
            "compaction_seconds": self.compaction_seconds,
            "loading_seconds": self.loading_seconds,
            "targets": dict(TARGETS),
        }
        out["relative_errors"] = {k: (out[k] - v) / v for k, v in TARGETS.items() if k != "sigma3_pa"}
        out.update(self.settings)
        return out


def elastic_constants(strain_axial: np.ndarray, strain_lateral: np.ndarray, deviator: np.ndarray,
                      fit: tuple[float, float] = FIT_STRAIN) -> tuple[float, float]:
    """(E, nu): slopes of q and -eps_l against eps_a over eps_a in ``fit`` (least squares)."""
    ea = np.asarray(strain_axial, float)
    sel = (ea >= fit[0]) & (ea <= fit[1])
    if sel.sum() < 3:
        raise ValueError(f"fewer than 3 samples with axial strain in {fit}: record more often or widen the range")
    young = np.polyfit(ea[sel], np.asarray(deviator, float)[sel], 1)[0]
    poisson = -np.polyfit(ea[sel], np.asarray(strain_lateral, float)[sel], 1)[0]
    return float(young), float(poisson)


def peak(sigma1: np.ndarray, sigma3: np.ndarray, strain_axial: np.ndarray, window: int = 5):
    """Peak of sigma1 after a centred moving average over ``window`` samples (wall-force reads are
    snapshots; the average removes the step-to-step rattle). Returns (sigma1, sigma3, eps_a) there."""
    kernel = np.ones(window) / window
    s1 = np.convolve(sigma1, kernel, mode="valid")
    s3 = np.convolve(sigma3, kernel, mode="valid")
    k = int(np.argmax(s1))
    return float(s1[k]), float(s3[k]), float(strain_axial[k + window // 2])


def walled_scene(pk: DiscPacking, *, k_n: float, friction: float, density: float, damping: float,
                 r_max: float, ks_over_kn: float = 1.0) -> tuple[list[int], list[int]]:
    """A fresh YADE scene of the packing between four frictionless walls at x = 0, W, y = 0, H
    (the compaction's walls: same material and order :data:`WALLS`). Returns (grain ids, wall ids)."""
    import_yade()
    from yade import O, utils
    from yade.wrapper import FrictMat

    O.reset()
    wall_mat = O.materials.append(FrictMat(young=k_n / r_max, poisson=1.0, frictionAngle=0.0, density=density))
    walls = []
    for axis, side in WALLS:
        origin = [0.0, 0.0, 0.0]
        origin[axis] = 0.0 if side < 0 else pk.box[axis]
        walls.append(O.bodies.append(utils.wall(tuple(origin), axis=axis, sense=-side, material=wall_mat)))
    ids = add_discs(pk.centres, pk.radii, k_n, ks_over_kn, friction, density)
    # a tiny detection margin: pairs touching to round-off are caught on the first step
    O.engines = disc_engines(walls=True, damping=damping, detection_factor=1.0 + 1e-6)
    O.dt = 0.5 * utils.PWaveTimeStep()
    return ids, walls


class _Walls:
    """Positions, contact stresses and motion of the four walls (order :data:`WALLS`)."""

    def __init__(self, O, walls):
        from yade.minieigenHP import Vector3

        self.O, self.walls, self.Vector3 = O, walls, Vector3

    def positions(self) -> np.ndarray:
        b = self.O.bodies
        return np.array([b[w].state.pos[axis] for w, (axis, _) in zip(self.walls, WALLS)])

    def sizes(self) -> tuple[float, float]:
        x = self.positions()
        return float(x[1] - x[0]), float(x[3] - x[2])

    def stresses(self) -> np.ndarray:
        """Contact normal stress on each wall [Pa]: grain force / current wall length / 1 m
        (a wall's permanent load is subtracted from YADE's resultant)."""
        width, height = self.sizes()
        f, perm = self.O.forces.f, self.O.forces.permF
        force = np.array([abs(f(w)[axis] - perm(w)[axis]) for w, (axis, _) in zip(self.walls, WALLS)])
        return force / np.array([height, height, width, width])

    def set_inward_speed(self, k: int, speed: float) -> None:
        axis, side = WALLS[k]
        vel = [0.0, 0.0, 0.0]
        vel[axis] = -side * float(speed)
        self.O.bodies[self.walls[k]].state.vel = self.Vector3(*vel)

    def make_dynamic(self, k: int, mass: float) -> None:
        """Wall k becomes a body of this mass free to translate along its normal only."""
        axis, _ = WALLS[k]
        b = self.O.bodies[self.walls[k]]
        b.dynamic = True
        b.state.blockedDOFs = "".join(c for c in "xyzXYZ" if c != "xyz"[axis])
        b.state.mass = mass
        b.state.inertia = self.Vector3(1.0, 1.0, 1.0)  # rotations are blocked

    def set_inward_load(self, k: int, force: float) -> None:
        """Permanent inward force on wall k [N per m of depth]."""
        axis, side = WALLS[k]
        vec = [0.0, 0.0, 0.0]
        vec[axis] = -side * float(force)
        self.O.forces.setPermF(self.walls[k], self.Vector3(*vec))


def load_biaxial(pk: DiscPacking, sigma3: float = SIGMA3, strain_rate: float = STRAIN_RATE,
                 max_strain: float = MAX_STRAIN, *, friction: float = GRAIN_FRICTION,
                 ks_over_kn: float = 1.0, density: float = GRAIN_DENSITY, damping: float = 0.7, r_max: float = 21.6e-6,
                 fit_strain: tuple[float, float] = FIT_STRAIN, chunk: int = CHUNK, progress=None) -> BiaxialResult:
    """Shear a compacted packing (walls at 0, W, 0, H, as :func:`compact_sample` returns it).

    Top and bottom walls move inwards at ``0.5 strain_rate H0`` each (kinematic). The side
    walls hold sigma3 by force control: each is a free body (normal translation only, the
    mass of one row of grains along it, the same local damping as the grains) loaded by
    ``sigma3 H`` with H the current sample height, refreshed every chunk. Its equation of
    motion is the servo: the wall moves until the grain force balances the load, so sigma3 is
    held without the steady-state lag of a proportional velocity servo.
    k_n is the packing's own (the one its overlaps were compacted with).
    ``progress(eps_a, sigma1, sigma3)`` is called every chunk.
    """
    import_yade()
    from yade import O

    ids, wall_ids = walled_scene(pk, k_n=pk.contact_stiffness, friction=friction, density=density, damping=damping,
                                 r_max=r_max, ks_over_kn=ks_over_kn)
    walls = _Walls(O, wall_ids)
    dt = float(O.dt)
    w0, h0 = walls.sizes()
    grain_mass = density * np.pi * pk.radii**2  # 1 m thick discs
    row_mass = float(grain_mass.mean() * h0 / (2.0 * pk.radii.mean()))
    for k in (0, 1):
        walls.make_dynamic(k, row_mass)
        walls.set_inward_load(k, sigma3 * h0)
    axial_speed = 0.5 * strain_rate * h0
    walls.set_inward_speed(2, axial_speed)
    walls.set_inward_speed(3, axial_speed)
    run_cycles(O, 1)  # creates the contacts: the starting stresses
    rec = {k: [] for k in ("cycles", "time", "ea", "el", "ev", "s1", "s3")}
    cycles = 1
    status = "finished"
    t0 = time.perf_counter()
    try:
        while True:
            s = walls.stresses()
            width, height = walls.sizes()
            ea, el = (h0 - height) / h0, (w0 - width) / w0
            s1, s3 = 0.5 * (s[2] + s[3]), 0.5 * (s[0] + s[1])
            row = (cycles, cycles * dt, ea, el, 1.0 - width * height / (w0 * h0), s1, s3)
            for key, value in zip(rec, row):
                rec[key].append(value)
            if progress is not None:
                progress(ea, s1, s3)
            if ea >= max_strain:
                break
            for k in (0, 1):
                walls.set_inward_load(k, sigma3 * height)
            run_cycles(O, chunk)
            cycles += chunk
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the curve so far
        status = "interrupted"
    loading_seconds = time.perf_counter() - t0
    O.reset()
    rows = min(len(v) for v in rec.values())  # an interrupt may land between two appends
    arr = {k: np.array(v[:rows]) for k, v in rec.items()}
    res = BiaxialResult(arr["cycles"], arr["time"], arr["ea"], arr["el"], arr["ev"], arr["s1"], arr["s3"],
                        sigma3_target=sigma3, strain_rate=strain_rate, fit_strain=tuple(fit_strain),
                        n_grains=len(ids), porosity=pk.porosity, box=(w0, h0), timestep=dt,
                        loading_seconds=loading_seconds, status=status,
                        interrupted_in="loading" if status == "interrupted" else None)
    res.derive_constants()
    return res


def run_biaxial(n: int = 1395, sigma3: float = SIGMA3, strain_rate: float = STRAIN_RATE, seed: int = 0,
                max_strain: float = MAX_STRAIN, *, r_min: float = 13.0e-6, r_max: float = 21.6e-6,
                k_n: float = CONTACT_STIFFNESS, ks_over_kn: float = 1.0, density: float = GRAIN_DENSITY,
                friction: float = GRAIN_FRICTION,
                size: float | None = None, fit_strain: tuple[float, float] = FIT_STRAIN,
                packing: DiscPacking | None = None, progress=None, compaction_progress=None) -> BiaxialResult:
    """The full calibration test: frictionless isotropic compaction of ``n`` discs to ``sigma3``
    (Huang sample parameters by default), then :func:`load_biaxial`. ``size`` is the nominal box
    side (default :func:`~hmdem.dem.compaction.nominal_side`); a given ``packing`` (compacted
    to ``sigma3`` between walls at 0, W, 0, H) skips the compaction. ``k_n`` is the compaction's
    contact stiffness; the loading uses the packing's (so a given packing keeps its own).
    ``friction`` and ``ks_over_kn`` are the loading's (compaction is frictionless). ``compaction_progress`` is
    :func:`compact_sample`'s ``progress(cycles, wall_stresses)``, ``progress`` that of
    :func:`load_biaxial`."""
    t0 = time.perf_counter()
    settings = {"seed": seed, "ks_over_kn": ks_over_kn, "friction": friction, "wall_friction": 0.0,
                "density": density, "r_min": r_min, "r_max": r_max, "damping": 0.7}
    if packing is None:
        if size is None:
            size = nominal_side(n)
        try:
            packing = compact_sample(n, size, r_min, r_max, stress=sigma3, seed=seed, k_n=k_n, density=density,
                                     progress=compaction_progress)
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM before the loading: a result without a curve
            empty = np.zeros(0)
            return BiaxialResult(empty, empty, empty, empty, empty, empty, empty, sigma3_target=sigma3,
                                 strain_rate=strain_rate, fit_strain=tuple(fit_strain), n_grains=n,
                                 compaction_seconds=time.perf_counter() - t0, status="interrupted",
                                 interrupted_in="compaction", settings={**settings, "k_n": k_n})
    compaction_seconds = time.perf_counter() - t0
    res = load_biaxial(packing, sigma3, strain_rate, max_strain, friction=friction, ks_over_kn=ks_over_kn,
                       density=density, r_max=r_max, fit_strain=fit_strain, progress=progress)
    res.compaction_seconds = compaction_seconds
    res.packing = packing
    res.settings = {**settings, "k_n": packing.contact_stiffness, "compaction_stress_pa": packing.confining_stress}
    return res
