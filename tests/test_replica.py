"""The numba replica of the YADE disc scene (hmdem/coupling/replica.py; decisions #65)."""

import numpy as np
import pytest

from hmdem.coupling.replica import CarriedState, DiscReplica

K_N = 7.49e7  # N/m per m, the Huang sample's (digest §15.1)


def replica(centres, radii, fixed, damping=0.7, friction=0.6, density=2650.0):
    masses = density * np.pi * np.asarray(radii) ** 2  # 1 m thick discs
    free_dofs = np.repeat(~np.asarray(fixed, bool)[:, None], 3, axis=1)
    return DiscReplica(radii, masses, free_dofs, k_n=K_N, k_s=K_N, friction=friction, damping=damping)


def at_rest(centres):
    n = len(centres)
    return CarriedState(np.asarray(centres, float), np.zeros((n, 2)), np.zeros(n), np.zeros((0, 2), int),
                        np.zeros((0, 2)), np.zeros((0, 2)))


def test_a_pushed_disc_settles_at_overlap_f_over_k():
    # a disc pushed by F onto a fixed one settles at overlap F / k_n (Eq. 9); 1e-6: the damped
    # relaxation (the same check as for YADE in test_coupled_run.py)
    r, force = 15e-6, 2.0
    disc = replica([[0.0, 0.0], [2 * r, 0.0]], [r, r], [True, False])
    disc.load(at_rest([[0.0, 0.0], [2 * r, 0.0]]))
    disc.timestep = 0.2 * np.sqrt(disc.masses()[1] / K_N)
    disc.set_external_forces([[0.0, 0.0], [-force, 0.0]])
    disc.run(20000)
    overlap = 2 * r - (disc.positions()[1, 0] - disc.positions()[0, 0])
    assert overlap == pytest.approx(force / K_N, rel=1e-6)
    pairs, normal, shear = disc.contacts()
    assert pairs.tolist() == [[0, 1]] and normal[0] == pytest.approx(force, rel=1e-6) and shear[0] < 1e-9 * force


@pytest.mark.parametrize("gap, touching", [(-1e-12, True), (1e-12, False), (0.1, False)])
def test_contact_is_decided_on_the_centre_distance(gap, touching):
    # two fixed discs at 2 r (1 + gap): Law2's test is penetration = 2 r - distance >= 0, and the
    # replica's squared-distance shortcut for pairs clearly apart must not change it near zero
    r = 15e-6
    centres = [[0.0, 0.0], [2 * r * (1.0 + gap), 0.0]]
    pair = replica(centres, [r, r], [True, True])
    pair.load(at_rest(centres))
    pair.timestep = 1e-9
    pair.run(1)
    assert pair.contacts()[0].tolist() == ([[0, 1]] if touching else [])


def test_contact_forces_conserve_momentum():
    # undamped, no external force, nothing fixed: the contact forces come in equal and opposite
    # pairs, so the total momentum of a jostling heap stays zero to round-off
    rng = np.random.default_rng(3)
    side = 12
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2) * 30e-6
    radii = rng.uniform(14e-6, 16.5e-6, len(grid))  # neighbours overlap up to 3 um
    heap = replica(grid, radii, np.zeros(len(grid)), damping=0.0)
    state = at_rest(grid)
    state.velocities = rng.normal(0.0, 1e-3, (len(grid), 2))
    state.velocities -= (heap.masses()[:, None] * state.velocities).sum(axis=0) / heap.masses().sum()
    heap.load(state)
    heap.timestep = 0.1 * np.sqrt(heap.masses().min() / K_N)
    heap.run(5)
    assert len(heap.contacts()[0]) > len(grid) // 2  # still jostling, not yet flown apart
    momentum = (heap.masses()[:, None] * heap.vel).sum(axis=0)
    scale = (heap.masses()[:, None] * np.abs(heap.vel)).sum(axis=0)
    assert np.all(np.abs(momentum) <= 1e-12 * scale)


@pytest.mark.parametrize("carried", [0.3, 10.0])
def test_shear_force_is_capped_at_the_coulomb_limit(carried):
    # Eq. 10: a contact carrying `carried` x mu F_n of shear keeps it below the limit and is cut
    # back to mu F_n above it (two fixed discs overlapping by 0.1 um: no relative motion)
    r, overlap, mu = 15e-6, 1e-7, 0.6
    centres = [[0.0, 0.0], [2 * r - overlap, 0.0]]
    pair = replica(centres, [r, r], [True, True], friction=mu)
    normal_force = K_N * overlap
    state = at_rest(centres)
    state.pairs, state.normals = np.array([[0, 1]]), np.array([[1.0, 0.0]])
    state.shear_forces = np.array([[0.0, carried * mu * normal_force]])
    pair.load(state)
    pair.timestep = 1e-9
    pair.run(1)
    _, normal, shear = pair.contacts()
    assert normal[0] == pytest.approx(normal_force, rel=1e-9)
    assert shear[0] == pytest.approx(min(carried, 1.0) * mu * normal_force, rel=1e-9)


@pytest.mark.yade
@pytest.mark.parametrize("loaded", [False, True])
def test_replica_follows_yade_through_a_flow_step(loaded):
    # the replica integrates YADE's laws; over 150 cycles (a B1 flow step is ~140) of a push
    # that makes and breaks contacts it ends where YADE does to round-off: 1e-9 of the largest
    # displacement (measured 3e-11 to 1e-10 on the Huang sample, summation order aside). With a
    # loaded boundary (decisions #86) its grains move along one axis each, under a constant load
    from hmdem.coupling.radial import boundary_normals
    from hmdem.dem.assembly import DiscAssembly
    from hmdem.dem.compaction import compact_sample

    pk = compact_sample(n=150, size=0.41e-3, seed=1)
    grains = DiscAssembly(pk.centres, pk.radii, fixed=pk.fixed)
    grains.run(200)
    normals = boundary_normals(pk.centres, pk.box, pk.fixed if loaded else np.zeros(len(pk.radii), bool),
                               2.0 * pk.radii.max())
    pistons = grains.release_along(normals)
    assert pistons.any() == loaded
    grains.save_state()
    start = grains.carried_state()
    twin = DiscReplica.of(grains)
    twin.timestep = grains.timestep
    twin.load(start)
    centre = pk.centres.mean(axis=0)
    d = start.positions - centre
    r = np.linalg.norm(d, axis=1, keepdims=True)
    push = 1e4 * d / np.maximum(r, 1e-12) * np.exp(-(r / 1e-4) ** 2)
    for dem in (grains, twin):
        dem.set_external_forces(push)
        dem.run(150)
    moved = np.abs(grains.positions() - start.positions).max()
    assert moved > 1e-7  # far enough to change contacts
    assert np.abs(twin.positions() - grains.positions()).max() <= 1e-9 * moved
    before = {tuple(p) for p in start.pairs}
    after_yade = {tuple(p) for p in grains.contacts()[0]}
    assert before != after_yade  # contacts were made or broken
    assert {tuple(p) for p in twin.contacts()[0]} == after_yade
    shift = grains.positions()[pistons] - start.positions[pistons]
    across = shift[:, 0] * normals[pistons, 1] - shift[:, 1] * normals[pistons, 0]
    assert np.all(across == 0.0)  # the axis across the normal is held exactly
    assert not loaded or np.abs(shift).max() > 1e-3 * moved  # the push reaches them too: they move
