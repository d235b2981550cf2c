"""A YADE scene of 3D spheres for the wet granular runs (seed 002; digest §3.3, §10).

The chapter's grains are rigid Contact Dynamics spheres; here they are soft frictional spheres
(``FrictMat``, ``Law2_ScGeom_FrictPhys_CundallStrack``), the surrogate of digest §3.3 option b.
Liquid bridge forces enter as YADE permanent forces, refreshed by the caller every step;
hmdem keeps its own bridge list (CundallStrack erases an interaction once the spheres part).
Everything crosses this boundary as numpy arrays.
"""

from __future__ import annotations

import math

import numpy as np

from ..yade_env import import_yade
from .assembly import SceneClock, body_centres, set_permanent_forces


class SphereAssembly(SceneClock):
    """Spheres (centres (n, 3), radii (n,)) in a fresh YADE scene, ready to step."""

    def __init__(self, centres, radii, *, young: float = 1e8, poisson: float = 0.3, friction: float = 0.3,
                 density: float = 2650.0, damping: float = 0.0, timestep_safety: float = 0.5):
        import_yade()
        from yade import O, utils
        from yade.wrapper import (Bo1_Sphere_Aabb, ForceResetter, FrictMat, Ig2_Sphere_Sphere_ScGeom,
                                  InsertionSortCollider, InteractionLoop, Ip2_FrictMat_FrictMat_FrictPhys,
                                  Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator)

        self._O = O
        O.reset()
        self.radii = np.asarray(radii, float)
        material = O.materials.append(FrictMat(young=young, poisson=poisson, density=density,
                                               frictionAngle=math.atan(friction)))
        self.ids = [O.bodies.append(utils.sphere(tuple(c), r, material=material))
                    for c, r in zip(np.asarray(centres, float).tolist(), self.radii.tolist())]
        O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb()]),
                     InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                                     [Law2_ScGeom_FrictPhys_CundallStrack()]),
                     NewtonIntegrator(damping=damping)]
        O.dt = timestep_safety * utils.PWaveTimeStep()

    def positions(self) -> np.ndarray:
        """Current centres (n, 3), read in C++ (the scene holds these spheres only, none erased)."""
        return body_centres(self.ids)

    def velocities(self) -> np.ndarray:
        """Current velocities (n, 3) [m/s]."""
        bodies = self._O.bodies
        return np.array([tuple(bodies[i].state.vel) for i in self.ids], float).reshape(-1, 3)

    def masses(self) -> np.ndarray:
        """Sphere masses (n,) [kg], as YADE holds them."""
        return np.array([self._O.bodies[i].state.mass for i in self.ids])

    def drive(self, index: int, velocity) -> None:
        """Move sphere ``index`` at a constant ``velocity`` (3,), whatever the forces on it."""
        from yade.minieigenHP import Vector3

        state = self._O.bodies[self.ids[index]].state
        state.blockedDOFs = "xyzXYZ"
        state.vel = Vector3(*map(float, velocity))
        state.angVel = Vector3(0.0, 0.0, 0.0)

    def hold(self, index: int) -> None:
        """Fix sphere ``index`` where it is."""
        self.drive(index, (0.0, 0.0, 0.0))

    def set_external_forces(self, forces) -> None:
        """Permanent forces (n, 3) [N], kept until replaced (liquid bridges, seed 002 Eq. 4)."""
        set_permanent_forces(self._O, self.ids, forces)

    def total_forces(self) -> np.ndarray:
        """The force (n, 3) [N] YADE applied to each sphere at the last step: contacts and
        permanent forces together."""
        force = self._O.forces.f
        return np.array([tuple(force(i, True)) for i in self.ids], float).reshape(-1, 3)

    def step(self) -> None:
        self._O.step()
