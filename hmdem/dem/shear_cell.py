"""A YADE plane-shear cell of soft frictional spheres (seed 002 §6.2; digest §3.3, §6.2).

The cell is periodic in x and y (side ``plate_side`` diameters). Two rough plates bound it in z:
square lattices of spheres of the mean radius, each plate one YADE clump. The bottom plate is
fixed. The top plate carries the confining force P L^2 as a permanent force, free in z and held
in x and y, and is first let down onto the grains (compaction, with numerical damping), then
driven along x at the speed that gives the requested inertial number I = gamma_dot d sqrt(rho/P)
(shear, without numerical damping: it would brake the flow against the lab frame, and friction
dissipates). YADE's cell is periodic in z too; its z side is long enough that nothing meets
across it. Grain centres cross this boundary as numpy arrays; liquid forces come back as
permanent forces. The chapter's grains are rigid CD spheres; these are the soft surrogate
(digest §3.3 option b), with E / P (``stiffness``) setting the overlaps.
"""

from __future__ import annotations

import math

import numpy as np

from ..yade_env import import_yade
from .assembly import SceneClock, body_centres, set_permanent_forces

COMPACTION_DAMPING = 0.5
COMPACTION_CHECK = 500  # DEM steps between checks that the top plate has come to rest


class ShearCell(SceneClock):
    """``n`` grains of radii R (1 +- ``polydispersity``) in a periodic plane-shear cell at
    pressure ``pressure`` [Pa]; E = ``stiffness`` * P. Grain ids run 0..n-1 in every array."""

    def __init__(self, n: int, radius: float, pressure: float, *, stiffness: float = 2e3, friction: float = 0.3,
                 density: float = 2650.0, polydispersity: float = 0.1, plate_side: int = 8, seed: int = 0,
                 timestep_safety: float = 0.5):
        import_yade()
        from yade import O, utils
        from yade.minieigenHP import Vector3
        from yade.wrapper import (Bo1_Sphere_Aabb, ForceResetter, FrictMat, Ig2_Sphere_Sphere_ScGeom,
                                  InsertionSortCollider, InteractionLoop, Ip2_FrictMat_FrictMat_FrictPhys,
                                  Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator)

        self._O = O
        O.reset()
        O.periodic = True
        rng = np.random.default_rng(seed)
        self.radius, self.pressure, self.density = radius, pressure, density
        self.polydispersity, self.plate_side = polydispersity, plate_side
        self.side = plate_side * 2.0 * radius
        spacing = self.side / round(self.side / (2.2 * radius))  # a loose cubic lattice to start from
        per_layer = round(self.side / spacing) ** 2
        layers = -(-n // per_layer)
        start_gap = (layers + 1) * spacing + 2.0 * radius
        self.height = 2.0 * start_gap + 10.0 * radius  # the cell's z side: no contact across it
        O.cell.setBox(self.side, self.side, self.height)
        material = O.materials.append(FrictMat(young=stiffness * pressure, poisson=0.3, density=density,
                                               frictionAngle=math.atan(friction)))
        lattice = (np.stack(np.meshgrid(np.arange(plate_side), np.arange(plate_side)), -1).reshape(-1, 2) + 0.5)
        lattice *= 2.0 * radius
        self._bottom, _ = O.bodies.appendClumped([utils.sphere((x, y, 0.0), radius, material=material)
                                                  for x, y in lattice.tolist()])
        self._top, _ = O.bodies.appendClumped([utils.sphere((x + radius, y + radius, start_gap), radius,
                                                            material=material) for x, y in lattice.tolist()])
        O.bodies[self._bottom].state.blockedDOFs = "xyzXYZ"
        O.bodies[self._top].state.blockedDOFs = "xyXYZ"
        cells = np.stack(np.meshgrid(*(np.arange(round(self.side / spacing)),) * 2, np.arange(layers),
                                     indexing="ij"), -1).reshape(-1, 3)[:n]
        centres = (cells + 0.5) * spacing + [0.0, 0.0, 1.5 * radius] + rng.uniform(-0.05, 0.05, (n, 3)) * radius
        self.radii = radius * rng.uniform(1 - polydispersity, 1 + polydispersity, n)
        self.ids = [O.bodies.append(utils.sphere(tuple(c), r, material=material))
                    for c, r in zip(centres.tolist(), self.radii.tolist())]
        self._newton = NewtonIntegrator(damping=COMPACTION_DAMPING)
        O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb()], verletDist=0.1 * radius),
                     InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                                     [Law2_ScGeom_FrictPhys_CundallStrack()]),
                     self._newton]
        O.dt = timestep_safety * utils.PWaveTimeStep()
        O.forces.setPermF(self._top, Vector3(0.0, 0.0, -pressure * self.side**2))
        self.strain = 0.0
        self.shear_rate = self.plate_speed = 0.0

    @property
    def period(self) -> np.ndarray:
        """Box lengths of the periodic axes (x, y), inf for z (pendular.branches' ``period``)."""
        return np.array([self.side, self.side, np.inf])

    @property
    def plate_gap(self) -> float:
        """z_wall: the height of the top plate's sphere centres over the bottom plate's [m]."""
        return float(self._O.bodies[self._top].state.pos[2])

    def compact(self, progress=None, max_steps: int = 400_000) -> int:
        """Let the top plate down onto the grains until it rests: the plate gap moves less than
        1e-5 R over :data:`COMPACTION_CHECK` steps and the unbalanced force is below 5 % (a
        stricter bound on it stalls small cells on their rattlers). Returns the DEM steps taken.
        ``progress(steps, plate_gap)`` after each check."""
        from yade import utils

        steps, gap = 0, self.plate_gap
        while steps < max_steps:
            self._O.run(COMPACTION_CHECK, True)
            steps += COMPACTION_CHECK
            previous, gap = gap, self.plate_gap
            if progress is not None:
                progress(steps, gap)
            if abs(gap - previous) < 1e-5 * self.radius and utils.unbalancedForce() < 0.05:
                return steps
        raise RuntimeError(f"the shear cell did not come to rest in {max_steps} DEM steps")

    def start_shear(self, inertial_number: float) -> None:
        """Drive the top plate along x at gamma_dot * z_wall, gamma_dot = I / (2R sqrt(rho / P))."""
        from yade.minieigenHP import Vector3

        self.shear_rate = inertial_number / (2.0 * self.radius * math.sqrt(self.density / self.pressure))
        self._newton.damping = 0.0
        self.plate_speed = self.shear_rate * self.plate_gap
        self._O.bodies[self._top].state.vel = Vector3(self.plate_speed, 0.0, 0.0)

    def run(self, steps: int) -> None:
        """``steps`` DEM steps; the strain grows by the plate's travel over the plate gap."""
        for _ in range(int(steps)):  # O.step(): O.run(n, True) waits in ~10-40 ms sleeps
            self._O.step()
        self.strain += self.plate_speed * steps * self.timestep / self.plate_gap

    def centres(self) -> np.ndarray:
        """Grain centres (n, 3), unwrapped in x and y (YADE does not wrap them)."""
        return body_centres(self.ids)

    def wrapped(self, centres) -> np.ndarray:
        """``centres`` with x and y taken into [0, side)."""
        out = np.array(centres, float)
        out[:, :2] %= self.side
        out[:, :2][out[:, :2] >= self.side] = 0.0  # -1e-17 % side rounds to side itself
        return out

    def touching(self, centres) -> tuple[np.ndarray, np.ndarray]:
        """Grain pairs in contact (k, 2), and their overlaps (k,) [m], across the periodic sides."""
        from scipy.spatial import cKDTree

        tree = cKDTree(self.wrapped(centres), boxsize=[self.side, self.side, self.height])
        pairs = tree.query_pairs(2.0 * self.radii.max(), output_type="ndarray")
        branch = centres[pairs[:, 1]] - centres[pairs[:, 0]]
        branch[:, :2] -= self.side * np.round(branch[:, :2] / self.side)
        overlap = self.radii[pairs].sum(axis=1) - np.linalg.norm(branch, axis=1)
        touch = overlap >= 0.0
        return pairs[touch], overlap[touch]

    def yade_contacts(self) -> np.ndarray:
        """Grain pairs (k, 2) in YADE's own real interactions, sorted (a check on :meth:`touching`;
        read one interaction at a time)."""
        index = {body: k for k, body in enumerate(self.ids)}
        pairs = [sorted((index[i.id1], index[i.id2])) for i in self._O.interactions
                 if i.isReal and i.id1 in index and i.id2 in index]
        return np.array(sorted(pairs), np.int64).reshape(-1, 2)

    def velocities(self) -> np.ndarray:
        """Grain velocities (n, 3) [m/s] (read body by body: for outputs, not every step)."""
        bodies = self._O.bodies
        return np.array([tuple(bodies[i].state.vel) for i in self.ids], float).reshape(-1, 3)

    def set_grain_forces(self, forces) -> None:
        """Permanent forces (n, 3) [N] on the grains (liquid bridges), kept until replaced."""
        set_permanent_forces(self._O, self.ids, forces)
