"""The YADE side of the coupling's runs (issue 3): a radial scenario's grains loaded and settled,
a stored packing's contact forces, and the Darcy permeability sweep that compacts the sample
at each confining stress. The solver side (:mod:`hmdem.coupling`) takes what these return as
objects and arrays and never imports YADE itself."""

from __future__ import annotations

import time

import numpy as np

from ..coupling.apertures import ApertureLaw
from ..coupling.darcy import STRESSES, PackingPermeability, packing_permeability
from ..network.contact_graph import NEAR_CONTACT_GAP
from ..network.packing import CONTACT_STIFFNESS, GRAIN_DENSITY, DiscPacking
from .assembly import DiscAssembly
from .compaction import compact_sample, nominal_side

SETTLE_CYCLES = 2000  # relaxation after loading the packing (contact shear history is not stored)


def start_grains(sc, threads: int | None = None) -> DiscAssembly:
    """The YADE disc assembly of a radial scenario's packing (``hmdem.coupling.radial``), settled
    (at the default damping 0.7, then the run's ``sc.coupling.dem_damping``); sets the stable DEM
    step. ``threads``: YADE's OpenMP threads (None: as the process was started, else 1). With
    ``sc.boundary_hold == "loaded"`` the boundary grains are released after settling, each along
    the normal of its side under the constant force that held it (``sc.boundary_normals``)."""
    pk = sc.packing
    grains = DiscAssembly(pk.centres, pk.radii, k_n=pk.contact_stiffness, ks_over_kn=sc.stiffness_ratio,
                          friction=sc.friction, fixed=sc.fixed, density=sc.grain_density, threads=threads)
    grains.run(SETTLE_CYCLES)
    if sc.boundary_hold == "loaded":
        # each boundary grain a piston at the stress that held it (decisions.md #86); their
        # spins were held too, so they settle again
        grains.release_along(sc.boundary_normals)
        grains.run(SETTLE_CYCLES)
    grains.damping = sc.coupling.dem_damping
    sc.coupling.stable_dem_step = grains.timestep = grains.stable_timestep()
    return grains


def packing_contact_forces(pk: DiscPacking, pairs: np.ndarray) -> np.ndarray:
    """Normal contact force of each grain pair [N per m] in the packing as it is stored: the
    packing is loaded into YADE (with the k_n it was compacted with) and its boundary grains fixed
    (they replace the walls), and one DEM step creates the interactions; 0 for pairs not in contact."""
    fixed = pk.fixed if len(pk.fixed) == len(pk.radii) else None
    grains = DiscAssembly(pk.centres, pk.radii, k_n=pk.contact_stiffness, fixed=fixed)
    grains.run(1)
    return grains.normal_forces(pairs)


def stored_permeability(pk: DiscPacking, law: ApertureLaw | None = None,
                        contact_gap: float = NEAR_CONTACT_GAP) -> PackingPermeability:
    """Network Darcy permeability of a packing at its stored state, with contact forces from YADE."""
    return packing_permeability(pk, lambda pairs: packing_contact_forces(pk, pairs), law, contact_gap)


def permeability_sweep(stresses=STRESSES, n: int = 1395, seed: int = 0, *, size: float | None = None,
                       r_min: float = 13.0e-6, r_max: float = 21.6e-6, k_n: float = CONTACT_STIFFNESS,
                       density: float = GRAIN_DENSITY, law: ApertureLaw | None = None,
                       contact_gap: float = NEAR_CONTACT_GAP, progress=None,
                       compaction_progress=None) -> list[PackingPermeability]:
    """Compact the sample (same seed, hence the same initial seeding) to each confining stress
    with :func:`hmdem.dem.compaction.compact_sample` (nominal box side ``size``, default
    :func:`~hmdem.dem.compaction.nominal_side`) and return the permeability at each.
    ``progress(k, stress, result)`` is called after each stress, ``compaction_progress`` is
    :func:`compact_sample`'s ``progress(cycles, wall_stresses)``."""
    size = nominal_side(n) if size is None else size
    out = []
    for k, stress in enumerate(stresses):
        t0 = time.perf_counter()
        pk = compact_sample(n, size, r_min, r_max, stress=float(stress), seed=seed, k_n=k_n, density=density,
                            progress=compaction_progress)
        res = stored_permeability(pk, law, contact_gap)
        res.extra = {"target_stress": float(stress), "seconds": time.perf_counter() - t0}
        out.append(res)
        if progress is not None:
            progress(k, stress, res)
    return out
