"""A numba replica of the YADE disc scene, for the trial evaluations of the P-V iteration (issue 3).

Every P-V evaluation of a rewound step runs the DEM over the whole flow step from t^n
(model.py); on B1 that is ~5 evaluations per accepted step, and YADE's cycles cost ~0.45 ms
each on 1,395 discs (BENCHMARKS.md), so four fifths of B1's wall went on trajectories that were
thrown away. This module integrates the same discs with the same laws, written out for the
plane, at about a sixth of YADE's cost per cycle. The iteration converges on it; YADE then
runs the step once at the converged pressures and that run is tested and kept (model.py,
decisions #65), so every accepted trajectory is still YADE's.

What is replicated, from YADE's sources (read in a 2019 trunk fork; the installed 2023.02a
agrees to round-off, tests/test_replica.py), the engines of ``hmdem.dem.discs.disc_engines``:

- ``Ig2_Sphere_Sphere_ScGeom`` (avoidGranularRatcheting): normal n from disc 1 to disc 2,
  penetration r1 + r2 - d, shear increment dt x the tangential part of
  alpha (v2 - v1) + (r1 w1 + r2 w2) (n_y, -n_x), alpha = (r1 + r2) / d; ``ScGeom::rotate``
  turns the carried shear force by the normal's rotation, f -= f x (n_old x n) (the twist term
  is zero in the plane);
- ``Law2_ScGeom_FrictPhys_CundallStrack`` (seed 004 Eqs. 9-10): F_n = k_n x penetration along
  n, f_s -= k_s x shear increment, capped at tan(phi) |F_n|; a contact whose penetration turns
  negative is erased (its shear force is lost); the force on disc 1 is -(F_n + f_s), with
  torques (r - penetration / 2) n x F on both discs (sphericalBodies);
- ``NewtonIntegrator``: a = F / m, each component damped by 1 - damping sign(a (v + a dt / 2)),
  then v += a dt, x += v dt (leapfrog), the same for the spin about z; held degrees of freedom
  (YADE's blockedDOFs) stay put.

Summation order differs from YADE's, so the two agree to round-off, not bit for bit
(tests/test_replica.py measures it). Contacts are looked for among pairs closer than a skin
(half the smallest radius, YADE's Verlet distance) when the replica is loaded; the list is
rebuilt whenever a disc has moved by half the skin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np


@dataclass
class CarriedState:
    """What a disc scene carries from one DEM cycle to the next (``DiscAssembly.carried_state``):
    positions (n, 2), velocities (n, 2), spins about z (n,); real contacts as index pairs (k, 2)
    with i < j, their unit normals (k, 2) from i to j and shear forces (k, 2) [N per m]."""

    positions: np.ndarray
    velocities: np.ndarray
    spins: np.ndarray
    pairs: np.ndarray
    normals: np.ndarray
    shear_forces: np.ndarray


@numba.njit(cache=True)
def _candidate_pairs(positions, radii, skin):
    """Pairs (i < j) closer than ``skin`` between surfaces, in key order i * n + j (a sweep
    along x: each disc meets only the discs within the largest reach of it)."""
    n = len(radii)
    order = np.argsort(positions[:, 0])
    reach_max = 2.0 * radii.max() + skin
    found_i = np.empty(16 * n, np.int64)
    found_j = np.empty(16 * n, np.int64)
    count = 0
    for a in range(n):
        i = order[a]
        for b in range(a + 1, n):
            j = order[b]
            dx = positions[j, 0] - positions[i, 0]
            if dx > reach_max:
                break
            dy = positions[j, 1] - positions[i, 1]
            reach = radii[i] + radii[j] + skin
            if dx * dx + dy * dy < reach * reach:
                if count == len(found_i):  # a denser packing than expected: grow the buffers
                    found_i = np.concatenate((found_i, np.empty(len(found_i), np.int64)))
                    found_j = np.concatenate((found_j, np.empty(len(found_j), np.int64)))
                found_i[count] = min(i, j)
                found_j[count] = max(i, j)
                count += 1
    keys = found_i[:count] * n + found_j[:count]
    ranked = np.argsort(keys)
    return found_i[:count][ranked].copy(), found_j[:count][ranked].copy()


@numba.njit(cache=True)
def _carry_over(new_keys, old_keys, old_active, old_normal, old_shear):
    """Contact states of the old candidate list moved to the new one (both sorted by key); a
    contact whose pair has left the candidates cannot be touching, so it is dropped."""
    m = len(new_keys)
    active = np.zeros(m, np.bool_)
    normal = np.zeros((m, 2))
    shear = np.zeros((m, 2))
    k = 0
    for q in range(m):
        while k < len(old_keys) and old_keys[k] < new_keys[q]:
            k += 1
        if k < len(old_keys) and old_keys[k] == new_keys[q] and old_active[k]:
            active[q] = True
            normal[q, 0], normal[q, 1] = old_normal[k, 0], old_normal[k, 1]
            shear[q, 0], shear[q, 1] = old_shear[k, 0], old_shear[k, 1]
    return active, normal, shear


@numba.njit(cache=True)
def _apart(ci, cj, radii):
    """Per candidate pair, a squared centre distance beyond which the discs cannot touch: the
    squared sum of radii, widened by 1e-9 so that round-off cannot make a touching pair look
    apart (the contact test itself is made on the distance, as YADE's)."""
    out = np.empty(len(ci))
    for q in range(len(ci)):
        touch = radii[ci[q]] + radii[cj[q]]
        out[q] = touch * touch * (1.0 + 1e-9)
    return out


@numba.njit(cache=True)
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@numba.njit(cache=True, error_model="numpy")  # no Python zero-division checks in the loop
def _cycles(pos, vel, spin, radii, inverse_mass, inverse_inertia, free, external, ci, cj, active, normal, shear,
            k_n, k_s, tan_phi, damping, dt, cycles, anchor, half_skin):
    """Up to ``cycles`` DEM cycles (contact forces at x^n and v^(n-1/2), then the leapfrog);
    returns how many ran: fewer when a disc has moved half the skin from ``anchor`` (the
    candidate list must then be rebuilt)."""
    n = len(radii)
    apart = _apart(ci, cj, radii)  # derived once per call: ~1 us against ~15 ms of cycles
    force = np.empty((n, 2))
    torque = np.empty(n)
    limit = half_skin * half_skin
    for cycle in range(cycles):
        for i in range(n):
            dx = pos[i, 0] - anchor[i, 0]
            dy = pos[i, 1] - anchor[i, 1]
            if dx * dx + dy * dy > limit:
                return cycle
        force[:, :] = external
        torque[:] = 0.0
        for q in range(len(ci)):
            i, j = ci[q], cj[q]
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            touch = radii[i] + radii[j]
            distance_sq = dx * dx + dy * dy
            # over a quarter of the candidates are apart (B1): the squared test spares them a root
            dist = math.sqrt(distance_sq) if distance_sq <= apart[q] else math.inf
            penetration = touch - dist
            if penetration < 0.0:
                if active[q]:  # Law2 erases the contact, and its shear force with it
                    active[q] = False
                    shear[q, 0] = shear[q, 1] = 0.0
                continue
            inverse = 1.0 / dist
            nx, ny = dx * inverse, dy * inverse
            fx, fy = shear[q, 0], shear[q, 1]
            if active[q]:  # ScGeom::rotate: f -= f x (n_old x n), the axis along z
                axis = normal[q, 0] * ny - normal[q, 1] * nx
                fx, fy = fx - fy * axis, fy + fx * axis
            else:
                fx = fy = 0.0
                active[q] = True
            normal[q, 0], normal[q, 1] = nx, ny
            alpha = touch * inverse
            arm = radii[i] * spin[i] + radii[j] * spin[j]
            ux = alpha * (vel[j, 0] - vel[i, 0]) + arm * ny
            uy = alpha * (vel[j, 1] - vel[i, 1]) - arm * nx
            un = ux * nx + uy * ny
            fx -= k_s * (ux - un * nx) * dt
            fy -= k_s * (uy - un * ny) * dt
            fn = k_n * penetration
            cap = fn * fn * tan_phi * tan_phi
            size = fx * fx + fy * fy
            if size > cap:
                ratio = math.sqrt(cap) / math.sqrt(size)
                fx *= ratio
                fy *= ratio
            shear[q, 0], shear[q, 1] = fx, fy
            # force on disc i: -(F_n + f_s); disc j gets the opposite
            gx, gy = -fn * nx - fx, -fn * ny - fy
            force[i, 0] += gx
            force[i, 1] += gy
            force[j, 0] -= gx
            force[j, 1] -= gy
            moment = nx * gy - ny * gx
            torque[i] += (radii[i] - 0.5 * penetration) * moment
            torque[j] += (radii[j] - 0.5 * penetration) * moment
        for i in range(n):
            for a in range(2):
                if free[i, a]:
                    acc = force[i, a] * inverse_mass[i]
                    acc *= 1.0 - damping * _sign(acc * (vel[i, a] + 0.5 * dt * acc))
                    vel[i, a] += dt * acc
                    pos[i, a] += vel[i, a] * dt
            if free[i, 2]:
                acc = torque[i] * inverse_inertia[i]
                acc *= 1.0 - damping * _sign(acc * (spin[i] + 0.5 * dt * acc))
                spin[i] += dt * acc
    return cycles


class DiscReplica:
    """The disc scene of a ``DiscAssembly`` integrated in numba: the ``GrainModel`` calls the P-V
    iteration makes (model.py), loaded from YADE's carried state with :meth:`load`."""

    def __init__(self, radii: np.ndarray, masses: np.ndarray, free_dofs: np.ndarray, *, k_n: float, k_s: float,
                 friction: float, damping: float, boundary_load: np.ndarray | None = None):
        """``free_dofs``: (n, 3) the x, y and spin about z of each disc that move; ``boundary_load``:
        (n, 2) constant forces added to every external force (a DiscAssembly's, both copied)."""
        self.radii = np.asarray(radii, float)
        self.masses_ = np.asarray(masses, float)
        self.inertia = 0.5 * self.masses_ * self.radii**2  # discs (hmdem.dem.discs.add_disc)
        self.free_dofs = np.array(free_dofs, bool).reshape(len(self.radii), 3)  # a copy
        self._inverse_mass, self._inverse_inertia = 1.0 / self.masses_, 1.0 / self.inertia
        self.k_n, self.k_s, self.friction, self.damping = float(k_n), float(k_s), float(friction), float(damping)
        # the friction angle goes through atan and back in YADE's FrictMat
        self.tan_phi = math.tan(math.atan(self.friction))
        self.skin = 0.5 * float(self.radii.min())
        self.timestep = 0.0
        loads = np.zeros((len(self.radii), 2)) if boundary_load is None else boundary_load
        self.boundary_load = np.array(loads, float).reshape(len(self.radii), 2)
        self.external = self.boundary_load.copy()
        self._loaded = None

    @classmethod
    def of(cls, grains) -> "DiscReplica":
        """The replica of a ``DiscAssembly``'s discs (its laws' constants; load its state later)."""
        return cls(grains.radii, grains.masses(), grains.free_dofs, k_n=grains.k_n, k_s=grains.k_s,
                   friction=grains.friction, damping=grains.damping,
                   boundary_load=getattr(grains, "boundary_load", None))

    def load(self, state: CarriedState) -> None:
        """Start from ``state`` (and return to it at every :meth:`restore_state`)."""
        self.pos, self.vel, self.spin = state.positions.copy(), state.velocities.copy(), state.spins.copy()
        self._build_candidates(state.pairs, state.normals, state.shear_forces)
        self._loaded = [a.copy() for a in self._arrays()]

    def _arrays(self):
        return self.pos, self.vel, self.spin, self.ci, self.cj, self.active, self.normal, self.shear, self.anchor

    def save_state(self) -> None:
        raise NotImplementedError("the replica returns to the state it was loaded from (load)")

    def restore_state(self) -> None:
        if self._loaded is None:
            raise RuntimeError("the replica was not loaded")
        (self.pos, self.vel, self.spin, self.ci, self.cj, self.active, self.normal, self.shear,
         self.anchor) = [a.copy() for a in self._loaded]

    def _build_candidates(self, pairs, normals, shear) -> None:
        n = len(self.radii)
        ci, cj = _candidate_pairs(self.pos, self.radii, self.skin)
        keys = pairs[:, 0].astype(np.int64) * n + pairs[:, 1]
        order = np.argsort(keys)
        self.active, self.normal, self.shear = _carry_over(ci * n + cj, keys[order], np.ones(len(keys), np.bool_),
                                                           normals[order], shear[order])
        self.ci, self.cj = ci, cj
        self.anchor = self.pos.copy()

    def set_external_forces(self, forces: np.ndarray) -> None:
        self.external = np.asarray(forces, float).reshape(-1, 2) + self.boundary_load

    def run(self, cycles: int) -> None:
        left = int(cycles)
        while left > 0:
            done = _cycles(self.pos, self.vel, self.spin, self.radii, self._inverse_mass, self._inverse_inertia,
                           self.free_dofs, self.external, self.ci, self.cj, self.active, self.normal, self.shear,
                           self.k_n, self.k_s, self.tan_phi, self.damping, self.timestep, left, self.anchor,
                           0.5 * self.skin)
            left -= done
            if left > 0:
                pairs = np.column_stack((self.ci, self.cj))[self.active]
                self._build_candidates(pairs, self.normal[self.active], self.shear[self.active])

    def positions(self) -> np.ndarray:
        return self.pos.copy()

    def masses(self) -> np.ndarray:
        return self.masses_

    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Touching pairs (k, 2) as of the last cycle, the sizes of their normal forces from the
        overlaps now (YADE's are one cycle older) and of their shear forces (k,)."""
        a = self.active
        pairs = np.column_stack((self.ci[a], self.cj[a]))
        d = np.linalg.norm(self.pos[pairs[:, 1]] - self.pos[pairs[:, 0]], axis=1)
        normal = self.k_n * np.maximum(self.radii[pairs].sum(axis=1) - d, 0.0)
        return pairs, normal, np.linalg.norm(self.shear[a], axis=1)
