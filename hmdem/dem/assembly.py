"""A YADE scene of quasi-2D discs for coupled runs: the DEM side of issue 3 (seed 004 §2).

Grains are spheres in z = 0 behaving as 1 m thick discs (digest §15.1), with a linear
contact and Coulomb friction (Eqs. 9-10, ``Law2_ScGeom_FrictPhys_CundallStrack``) and local
damping. Fluid pressure forces enter as YADE permanent forces (refreshed by the coupling),
boundary grains can be fixed. Everything crosses this boundary as numpy arrays; YADE's Python
API is mostly per body, so most accessors below loop over bodies once per call (a few ms for
1,400 grains, against ~0.1-0.2 s of DEM cycles per P-V evaluation of B1); positions come in bulk.
"""

from __future__ import annotations

import numpy as np

from ..network.packing import CONTACT_STIFFNESS, GRAIN_DENSITY, GRAIN_FRICTION
from ..yade_env import import_yade
from .discs import add_discs, disc_engines


def body_centres(ids, axes: int = 3) -> np.ndarray:
    """The first ``axes`` coordinates (n, axes) of the bodies ``ids``, read in C++ one coordinate
    of every body at a time (YADE's ``coordsAndDisplacements``); the ids index its lists, so the
    scene must have no erased body before them."""
    from yade import _utils

    return np.column_stack([_utils.coordsAndDisplacements(axis)[0] for axis in range(axes)])[ids]


def set_permanent_forces(O, ids, forces) -> None:
    """YADE permanent forces (n, 3) [N] on the bodies ``ids``, kept until replaced. YADE takes
    them body by body; plain tuples convert in C++ (faster than building Vector3s)."""
    set_force = O.forces.setPermF
    for i, f in zip(ids, np.asarray(forces, float).reshape(-1, 3).tolist()):
        set_force(i, tuple(f))


class SceneClock:
    """The DEM step and time of a YADE scene held as ``self._O`` (the wet runs' scenes)."""

    @property
    def timestep(self) -> float:
        return float(self._O.dt)

    @property
    def time(self) -> float:
        return float(self._O.time)


def run_cycles(O, cycles: int) -> None:
    """``cycles`` DEM steps. ``O.run(n, True)`` costs ~40 ms of polling per call in YADE 2023.02a
    whatever n; ``O.step()`` is synchronous and costs ~3 us, so short runs stay cheap."""
    step = O.step
    for _ in range(int(cycles)):
        step()


class DiscAssembly:
    """Discs (centres (n, 2), radii (n,)) in a fresh YADE scene, ready to cycle."""

    _saved = None  # what save_state kept, if anything
    _contact_read = None  # (O.iter, the last _read_contacts)
    _time_offset = 0.0  # O.time runs on through rewinds
    restores = 0  # rewinds by restore_state

    def __init__(self, centres: np.ndarray, radii: np.ndarray, *, k_n: float = CONTACT_STIFFNESS,
                 ks_over_kn: float = 1.0, friction: float = GRAIN_FRICTION, density: float = GRAIN_DENSITY,
                 damping: float = 0.7,
                 fixed: np.ndarray | None = None, timestep_safety: float = 0.5, threads: int | None = None):
        import_yade(threads)
        from yade import O, utils


        self._O = O
        O.reset()
        self.radii = np.asarray(radii, float)
        self.ids = add_discs(centres, self.radii, k_n, ks_over_kn, friction, density)
        fixed = np.zeros(len(self.ids), bool) if fixed is None else np.asarray(fixed, bool)
        self.free_dofs = np.repeat(~fixed[:, None], 3, axis=1)  # x, y and the spin about z the DEM moves
        self.boundary_load = np.zeros((len(self.ids), 2))  # constant forces on released discs (release_along)
        self._external = np.zeros((len(self.ids), 2))  # the permanent forces set last (set_external_forces)
        for i in np.flatnonzero(fixed):
            O.bodies[self.ids[i]].state.blockedDOFs = "xyzXYZ"
        # contacts that exist now (touching within round-off) must be detected on the first step
        O.engines = disc_engines(walls=False, damping=damping, detection_factor=1.0 + 1e-6)
        O.dt = timestep_safety * utils.PWaveTimeStep()
        self.k_n = k_n
        self.k_s = ks_over_kn * k_n
        self.friction = friction
        ids = np.asarray(self.ids, int)
        self._grain_of_body = np.full(int(ids.max()) + 1 if len(ids) else 0, -1, int)  # body id -> grain, -1: none
        self._grain_of_body[ids] = np.arange(len(ids))
        self._masses = np.array([O.bodies[i].state.mass for i in self.ids])  # fixed at creation

    @property
    def fixed(self) -> np.ndarray:
        """Discs held in place (none of their degrees of freedom move)."""
        return ~self.free_dofs.any(axis=1)

    @property
    def timestep(self) -> float:
        return float(self._O.dt)

    @timestep.setter
    def timestep(self, dt: float) -> None:
        self._O.dt = dt

    def stable_timestep(self, safety: float = 0.8) -> float:
        """A DEM step near the stability limit of the contact network as it is now: ``safety``
        x min over free grains of sqrt(m / (Z k)), Z the grain's contact count and k the larger
        contact stiffness: the translational estimate of YADE's GlobalStiffnessTimeStepper (same
        default safety). On the Huang sample this is 1.47x the 0.5 x PWaveTimeStep used to build
        it, and runs at 1.8x that step stay stable while 2x diverges (BENCHMARKS.md)."""
        pairs, _ = self.contact_forces()
        free = ~self.fixed
        contacts = np.bincount(pairs.ravel(), minlength=len(self.ids))[free]
        stiffness = np.maximum(contacts, 1) * max(self.k_n, self.k_s)
        return safety * float(np.min(np.sqrt(self.masses()[free] / stiffness)))

    @property
    def damping(self) -> float:
        """YADE's local (non-viscous) damping of the grains' accelerations, 0 <= damping < 1."""
        return float(self._newton().damping)

    @damping.setter
    def damping(self, value: float) -> None:
        self._newton().damping = float(value)

    def _newton(self):
        return next(e for e in self._O.engines if type(e).__name__ == "NewtonIntegrator")

    @property
    def threads(self) -> int:
        """OpenMP threads YADE runs on (1 unless asked: more are faster but not bit-reproducible)."""
        return int(self._O.numThreads)

    @property
    def time(self) -> float:
        """DEM time; a rewind by :meth:`restore_state` takes it back to the saved scene's."""
        return float(self._O.time) - self._time_offset

    def positions(self) -> np.ndarray:
        """Current centres (n, 2). YADE's ``coordsAndDisplacements`` reads one coordinate of every
        body in C++ (0.35 ms for x and y of 1,395 discs, against 3.8 ms body by body); the scene
        holds these discs only, so the body ids index its lists."""
        return self._coordinates(2)

    def _coordinates(self, axes: int) -> np.ndarray:
        return body_centres(self.ids, axes)

    def velocities(self) -> np.ndarray:
        bodies = self._O.bodies
        return np.array([[bodies[i].state.vel[0], bodies[i].state.vel[1]] for i in self.ids])

    def set_external_forces(self, forces: np.ndarray) -> None:
        """Permanent forces (n, 2) [N per m of depth], kept until replaced (fluid pressure, Eq. 8),
        on top of the :attr:`boundary_load` (:meth:`release_along`)."""
        self._external = np.asarray(forces, float).reshape(-1, 2).copy()
        set_force = self._O.forces.setPermF
        # plain tuples convert to YADE's Vector3 in C++: 0.5 ms for 1,395 discs, 3.2 ms via Vector3
        for i, (fx, fy) in zip(self.ids, (self._external + self.boundary_load).tolist()):
            set_force(i, (fx, fy, 0.0))

    def contact_force_sums(self) -> np.ndarray:
        """Net force (n, 2) [N per m] the contacts exerted on each disc at the last DEM step (held
        discs included: YADE sums their contacts too): YADE's total less the permanent forces as
        they are set now, so read it before setting others than the last step ran with."""
        force = self._O.forces.f
        total = np.array([(f[0], f[1]) for f in (force(i, True) for i in self.ids)], float).reshape(-1, 2)
        return total - self._external - self.boundary_load

    def release_along(self, normals: np.ndarray) -> np.ndarray:
        """Let held discs move along their ``normals`` (n, 2) (unit x or y vectors pointing into
        the sample; zero rows: left as they are) and spin, each under a constant force along its
        normal: the inward push that held it at the last step (minus its contacts' net force
        along it). A disc stays put until the discs inside push harder: a piston at the stress
        it was held at. Discs the hold did not push inward (sheltered behind others) stay held:
        with no load, any outward force would carry them off. The mask of released discs."""
        normals = np.asarray(normals, float).reshape(-1, 2)
        push = np.sum(-self.contact_force_sums() * normals, axis=1)
        released = self.fixed & normals.any(axis=1) & (push > 0.0)
        self.boundary_load[released] = push[released, None] * normals[released]
        bodies = self._O.bodies
        for i in np.flatnonzero(released):
            along_x = normals[i, 0] != 0.0
            # discs keep z and the out-of-plane spins held; the axis across the normal is held too
            bodies[self.ids[i]].state.blockedDOFs = "zXY" + ("y" if along_x else "x")
            self.free_dofs[i] = (along_x, not along_x, True)
        self.set_external_forces(self._external)  # the load goes in beside what was set
        return released

    def save_state(self) -> None:
        """Keep what the DEM carries from one cycle to the next (:meth:`restore_state` returns to
        it): each disc's position, velocity and spin, and each real contact's normal (the shear
        force is rotated from it, ``ScGeom::precompute``) and shear force (Law2, Eq. 10). The
        normal force, penetration, contact point and shear increment are recomputed each cycle
        from these. A sphere's orientation enters no force here and is not kept. Velocities are
        kept in the plane (x, y and the spin about z: the blocked components stay zero). ~10 ms
        for the discs and ~20 ms for ~2,600 contacts, most of it boost.python's attribute access;
        YADE's ``saveTmp`` of the whole scene took ~26 ms and its ``loadTmp`` ~20 ms (decisions
        #54)."""
        self._saved = None  # a save interrupted half-way leaves nothing to return to
        bodies = self._O.bodies
        positions = self._coordinates(3)
        motion = np.array([(s.vel[0], s.vel[1], s.angVel[2]) for s in (bodies[i].state for i in self.ids)])
        self._saved = positions, motion.reshape(-1, 3), self._read_contacts(), self.time

    def _read_contacts(self):
        """One pass over YADE's real interactions: body id pairs, copies of their normals and
        shear forces (YADE hands out views of the live values), and the sizes of their normal and
        shear forces (k, 2). Kept until the scene moves or is rewound: the read after a step is
        accepted (apertures) and the snapshot of the next step's start see the same scene."""
        from yade.minieigenHP import Vector3

        now = self._O.iter
        if self._contact_read is not None and self._contact_read[0] == now:
            return self._contact_read[1]
        pairs, normals, shears, sizes = [], [], [], []
        for c in self._O.interactions:
            if c.isReal:
                phys = c.phys
                shear = Vector3(phys.shearForce)
                pairs.append((c.id1, c.id2))
                normals.append(Vector3(c.geom.normal))
                shears.append(shear)
                sizes.append((phys.normalForce.norm(), shear.norm()))
        read = pairs, normals, shears, np.array(sizes, float).reshape(-1, 2)
        self._contact_read = now, read
        return read

    def carried_state(self):
        """What :meth:`save_state` kept, as numpy arrays in the plane (``CarriedState``: positions,
        velocities, spins about z, contact pairs as grain indices i < j with their normals from i
        to j and shear forces), for the numba replica (``hmdem.coupling.replica``)."""
        from ..coupling.replica import CarriedState

        if self._saved is None:
            raise RuntimeError("no saved DEM state to read (save_state was not called or was interrupted)")
        positions, motion, (ids, normals, shears, _), _ = self._saved
        pairs, disc = self._grain_pairs(ids)
        vectors = np.array([(n[0], n[1], f[0], f[1]) for n, f in zip(normals, shears)], float).reshape(-1, 4)[disc]
        flip = pairs[:, 0] > pairs[:, 1]  # YADE keeps id1 < id2; grain indices follow body ids, but make sure
        vectors[flip] *= -1.0  # normal and shear force are both seen from the first grain
        pairs[flip] = pairs[flip, ::-1]
        return CarriedState(positions[:, :2].copy(), motion[:, :2].copy(), motion[:, 2].copy(), pairs,
                            vectors[:, :2].copy(), vectors[:, 2:].copy())

    def restore_state(self) -> None:
        """Return to the state kept by :meth:`save_state`: contacts made since are unmade (left to
        the collider as potential ones), contacts broken since are made again (YADE's
        ``createInteraction``, from the restored positions) before every saved contact's normal
        and shear force are set, and the collider runs at the next cycle, so that bounds the
        rewound discs have left are rebuilt before contacts are looked for. The next cycles repeat
        the saved ones to round-off: contacts made again are summed in another order
        (tests/test_coupled_run.py). A rewind interrupted half-way is completed by the next one."""
        from yade import utils
        from yade.minieigenHP import Vector3

        if self._saved is None:
            raise RuntimeError("no saved DEM state to return to (save_state was not called or was interrupted)")
        positions, motion, (ids, normals, shears, _), time = self._saved
        self._contact_read = None
        interactions = self._O.interactions
        saved = dict(zip(ids, zip(normals, shears)))
        real = {(c.id1, c.id2) for c in interactions if c.isReal}
        for pair in real.difference(saved):
            interactions.erase(*pair)
        bodies = self._O.bodies
        for i, (x, y, z), (vx, vy, spin) in zip(self.ids, positions.tolist(), motion.tolist()):
            state = bodies[i].state
            state.pos, state.vel, state.angVel = Vector3(x, y, z), Vector3(vx, vy, 0.0), Vector3(0.0, 0.0, spin)
        for pair in set(saved).difference(real):
            utils.createInteraction(*pair)
        for pair, (normal, shear) in saved.items():
            contact = interactions[pair]
            contact.geom.normal = normal
            contact.phys.shearForce = shear
        self._newton().maxVelocitySq = 1.0  # makes the collider update bounds and sort at the next cycle
        self._time_offset = float(self._O.time) - time
        self.restores += 1

    def run(self, cycles: int) -> None:
        """Advance the DEM by ``cycles`` steps of :attr:`timestep`."""
        run_cycles(self._O, cycles)

    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All real disc-disc contacts: grain index pairs (k, 2), i < j, and the sizes of their
        normal and shear forces (k,) [N per m]."""
        ids, _, _, sizes = self._read_contacts()
        pairs, disc = self._grain_pairs(ids)
        return np.sort(pairs, axis=1), sizes[disc, 0], sizes[disc, 1]

    def _grain_pairs(self, ids) -> tuple[np.ndarray, np.ndarray]:
        """Grain index pairs (k, 2) of the disc-disc contacts among YADE body id pairs, in their
        order, and which of the id pairs those are (a mask)."""
        body = np.asarray(ids, int).reshape(-1, 2)
        known = body < len(self._grain_of_body)
        grain = np.where(known, self._grain_of_body[np.where(known, body, 0)], -1)
        disc = np.all(grain >= 0, axis=1)
        return grain[disc], disc

    def contact_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """All real disc-disc contacts: grain index pairs (k, 2), i < j, and normal forces (k,)."""
        pairs, normal, _ = self.contacts()
        return pairs, normal

    def normal_forces(self, pairs: np.ndarray) -> np.ndarray:
        """Compressive normal contact force per grain pair (k, 2) [N per m]; 0 where detached."""
        found, force = self.contact_forces()
        out = np.zeros(len(pairs))
        if len(found) == 0:
            return out
        n = len(self.ids)
        keys = found[:, 0].astype(np.int64) * n + found[:, 1]
        order = np.argsort(keys)
        keys, force = keys[order], force[order]
        pairs = np.sort(np.asarray(pairs, int), axis=1)
        wanted = pairs[:, 0].astype(np.int64) * n + pairs[:, 1]
        slot = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
        hit = keys[slot] == wanted
        out[hit] = force[slot[hit]]
        return out

    def masses(self) -> np.ndarray:
        return self._masses.copy()
