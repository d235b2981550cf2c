"""Quasi-2D discs in YADE: spheres in the plane z = 0 that behave as 1 m thick discs.

Digest seed 004 §15.1: per-particle ``FrictMat(young = k_n / r, poisson = k_s / k_n,
density = 3 rho (1 m) / (4 r))`` makes ``Ip2_FrictMat_FrictMat_FrictPhys`` give exactly
k_n = k_s = k for any radius pair and the sphere mass equal to the disc mass rho pi r^2 (1 m);
the inertia is overridden with the disc value m r^2 / 2.
"""

from __future__ import annotations

import math

import numpy as np

from ..yade_env import import_yade

DEPTH = 1.0  # out-of-plane disc thickness [m]


def disc_material(radius: float, k_n: float, ks_over_kn: float, friction: float, density: float):
    """FrictMat that turns a sphere of this radius into a 1 m thick disc (digest §15.1)."""
    import_yade()
    from yade.wrapper import FrictMat

    return FrictMat(
        young=k_n / radius,
        poisson=ks_over_kn,
        frictionAngle=math.atan(friction),
        density=3.0 * density * DEPTH / (4.0 * radius),
    )


def add_disc(x: float, y: float, radius: float, material) -> int:
    """Append one disc body (z fixed, no out-of-plane rotation) and return its id."""
    import_yade()
    from yade import O, utils
    from yade.minieigenHP import Vector3

    b = utils.sphere((x, y, 0.0), radius, material=material)
    b.state.blockedDOFs = "zXY"
    inertia = 0.5 * b.state.mass * radius**2
    b.state.inertia = Vector3(inertia, inertia, inertia)
    return O.bodies.append(b)


def disc_state(ids: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Centres (n, 2) and radii (n,) of the given bodies."""
    import_yade()
    from yade import O

    centres = np.array([[O.bodies[i].state.pos[0], O.bodies[i].state.pos[1]] for i in ids])
    radii = np.array([O.bodies[i].shape.radius for i in ids])
    return centres, radii


def disc_contacts(ids: list[int]) -> np.ndarray:
    """Real disc-disc interactions as index pairs into ``ids`` (i < j)."""
    import_yade()
    from yade import O

    index = {b: k for k, b in enumerate(ids)}
    pairs = [
        (index[i.id1], index[i.id2])
        for i in O.interactions
        if i.isReal and i.id1 in index and i.id2 in index
    ]
    return np.sort(np.array(pairs, dtype=int).reshape(-1, 2), axis=1)


def add_discs(centres: np.ndarray, radii: np.ndarray, k_n: float, ks_over_kn: float, friction: float,
              density: float, size_factor: float = 1.0) -> list[int]:
    """Append one disc per centre, each with its own disc-equivalent material; their ids.

    ``size_factor`` shrinks the bodies (packings are seeded small and grown); the materials are
    those of the final radii."""
    import_yade()
    from yade import O

    ids = []
    for (x, y), r in zip(np.asarray(centres, float), np.asarray(radii, float)):  # scene set-up, once
        mat = O.materials.append(disc_material(r, k_n, ks_over_kn, friction, density))
        ids.append(add_disc(x, y, size_factor * r, mat))
    return ids


def collider_threads(bodies: int, threads: int) -> int:
    """The most OpenMP threads, up to ``threads``, that YADE 2023.02's parallel insertion sort
    survives on a scene of ``bodies`` bodies.

    ``InsertionSortCollider::insertionSortParallel`` (used from 1,000 bodies on) cuts each
    axis's 2 x bodies bounds into m = threads chunks starting at k (s // m + 1), then lowers m
    one by one while a chunk is narrower than 4 Verlet distances. In the plane every z bound
    lies within a radius of 0, so m always goes down through every count from ``threads`` to 1.
    A count whose last chunk starts at or past the end of the list reads past it: Debian's
    build aborts on its assertion (``--threads 64`` on the paper-size Huang sample, 2,790
    bounds, aborted at 63). The sort then joins the chunks reading up to half a chunk beyond
    each start, so a count whose last chunk is shorter than half a chunk is refused too.
    """
    size = 2 * bodies
    safe = 1
    for chunks in range(2, threads + 1):
        width = size // chunks + 1
        if (chunks - 1) * width + width // 2 >= size:
            break
        safe = chunks
    return safe


def disc_engines(walls: bool, damping: float = 0.7, detection_factor: float | None = None) -> list:
    """The engine list of a disc scene: collider, sphere(-wall) geometry, the linear Cundall-Strack
    contact with Coulomb friction (seed 004 Eqs. 9-10) and local damping. ``detection_factor``
    (> 1) also catches pairs that touch only to round-off on the first step. Call it once the
    scene's bodies are in: the collider's threads are capped for their count (collider_threads)."""
    import_yade()
    from yade import O
    from yade.wrapper import (Bo1_Sphere_Aabb, Bo1_Wall_Aabb, ForceResetter, Ig2_Sphere_Sphere_ScGeom,
                              Ig2_Wall_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                              Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                              NewtonIntegrator)

    enlarge = {} if detection_factor is None else {"aabbEnlargeFactor": detection_factor}
    detect = {} if detection_factor is None else {"interactionDetectionFactor": detection_factor}
    bounds = [Bo1_Sphere_Aabb(**enlarge)] + ([Bo1_Wall_Aabb()] if walls else [])
    geometry = [Ig2_Sphere_Sphere_ScGeom(**detect)] + ([Ig2_Wall_Sphere_ScGeom()] if walls else [])
    collider = InsertionSortCollider(bounds)
    threads = collider_threads(len(O.bodies), O.numThreads)
    if threads < O.numThreads:  # the other engines keep every thread
        collider.ompThreads = threads
    return [
        ForceResetter(),
        collider,
        InteractionLoop(geometry, [Ip2_FrictMat_FrictMat_FrictPhys()], [Law2_ScGeom_FrictPhys_CundallStrack()]),
        NewtonIntegrator(damping=damping),
    ]
