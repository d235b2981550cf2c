"""The linearised skeleton's Newton step for the P-V iteration (issue 3; hmdem/coupling/skeleton.py)."""

import numpy as np
import pytest
import scipy.sparse as sp

from hmdem.coupling.geometry import DomainGeometry
from hmdem.coupling.skeleton import SkeletonNewton, skeleton_stiffness
from hmdem.flow.grain_forces import grain_pressure_forces, pressure_force_matrix
from hmdem.flow.pressure import PressureSystem
from hmdem.network import build_contact_network
from hmdem.scenario import load_packing

K_N = 7.49e7


@pytest.fixture(scope="module")
def packing_network():
    pk = load_packing()
    return pk, build_contact_network(pk.centres, pk.radii, pk.contacts)


def rigid_motion(x, shift, angle):
    """Per-disc (x, y, rotation) dofs of a small rigid motion of the whole set about the origin."""
    u = np.c_[shift[0] - angle * x[:, 1], shift[1] + angle * x[:, 0]]
    return np.c_[u, np.full(len(x), angle)].ravel()


def test_contact_springs_are_symmetric_and_free_under_rigid_motion(packing_network):
    # K is symmetric (to the round-off of summing its blocks) and a rigid translation of the
    # packing stretches no spring: K u = 0 to round-off; any other motion stores energy u.K.u > 0
    pk, _ = packing_network
    k = skeleton_stiffness(pk.centres, pk.radii, pk.contacts, K_N, K_N)
    assert abs(k - k.T).max() <= 1e-14 * K_N
    u = rigid_motion(pk.centres, (1e-9, -2e-9), 0.0)
    assert np.abs(k @ u).max() <= 1e-14 * K_N * np.abs(u).max()
    rng = np.random.default_rng(3)
    w = rng.normal(size=u.shape) * 1e-9
    assert w @ (k @ w) > 0.0
    # a rigid rotation too, for touching discs (the shear spring sits at the contact point, so
    # discs held apart by a gap g would slide by w g): three mutually tangent discs
    r = np.array([13e-6, 21.6e-6, 17e-6])
    d01, d02, d12 = r[0] + r[1], r[0] + r[2], r[1] + r[2]
    x2 = (d02**2 - d12**2 + d01**2) / (2 * d01)
    x = np.array([[0.0, 0.0], [d01, 0.0], [x2, np.sqrt(d02**2 - x2**2)]]) + 1e-4
    k = skeleton_stiffness(x, r, np.array([[0, 1], [0, 2], [1, 2]]), K_N, K_N)
    u = rigid_motion(x, (1e-9, 3e-9), 1e-5)
    assert np.abs(k @ u).max() <= 1e-9 * K_N * 1e-9


def test_one_contact_pushes_back_with_k_n_and_k_s():
    # two discs along x; K u is the force that holds the displacement u. Stretching the contact by
    # d takes k_n d on each disc, outwards; sliding grain 1 by d along y takes k_s d, and its moment
    # on grain 0; turning both discs the same way slides the contact point by (r_0 + r_1) w
    r = np.array([13e-6, 21.6e-6])
    x = np.array([[0.0, 0.0], [r.sum(), 0.0]])
    k = skeleton_stiffness(x, r, np.array([[0, 1]]), K_N, 0.5 * K_N).toarray()
    d = 1e-9
    stretch = np.array([0, 0, 0, d, 0, 0])
    np.testing.assert_allclose(k @ stretch, [-K_N * d, 0, 0, K_N * d, 0, 0], atol=1e-12)
    slide = np.array([0, 0, 0, 0, d, 0])
    f = k @ slide
    assert f[4] == pytest.approx(0.5 * K_N * d)
    assert f[2] == pytest.approx(-0.5 * K_N * d * r[0])  # the shear force's moment on grain 0
    turn = np.array([0, 0, 1e-6, 0, 0, 1e-6])
    assert (k @ turn)[1] == pytest.approx(0.5 * K_N * r.sum() * 1e-6)
    # a sliding contact (k_s = 0) resists only along its normal
    k_slide = skeleton_stiffness(x, r, np.array([[0, 1]]), K_N, np.array([0.0])).toarray()
    assert np.abs(k_slide @ slide).max() == 0.0


def test_pressure_force_matrix_is_eq8(packing_network):
    pk, net = packing_network
    rng = np.random.default_rng(5)
    p = rng.uniform(0, 1e5, net.n_domains)
    moved = pk.centres + rng.uniform(-0.05, 0.05, pk.centres.shape) * pk.radii[:, None]
    force = pressure_force_matrix(net, pk.radii, moved) @ p
    # Eq. 8 per corner, 2 p r sin(beta) along the bisector, summed: the same as the per-edge sums
    np.testing.assert_allclose(force.reshape(-1, 2), grain_pressure_forces(net, pk.radii, p, moved),
                               rtol=1e-12, atol=1e-12 * np.abs(force).max())


def test_volume_gradient_is_the_derivative_of_the_volumes(packing_network):
    pk, net = packing_network
    geo = DomainGeometry(net)
    rng = np.random.default_rng(9)
    step = rng.normal(size=pk.centres.shape) * 1e-10
    dv = geo.volumes(pk.centres + step) - geo.volumes(pk.centres - step)
    predicted = 2 * geo.volume_gradient(pk.centres) @ step.ravel()
    # central difference: exact for the shoelace area up to round-off of the volumes (~1e-16 V)
    assert np.abs(dv - predicted).max() <= 1e-6 * np.abs(dv).max()


@pytest.mark.parametrize("pistons", [False, True])
def test_newton_step_solves_the_linearised_map(packing_network, pistons):
    # (I - J) dp = r with J = -A^-1 D S^-1 C / dt written out densely on the unknown domains.
    # With pistons, some held grains move along x or y only (--boundary loaded, decisions #86)
    pk, net = packing_network
    n_dom = net.n_domains
    outlet = np.arange(n_dom)[-5:]
    node = np.full(n_dom, -1)
    node[:n_dom - 5] = np.arange(n_dom - 5)
    node[[0, 1]] = 0  # a two-domain manifold shares one unknown
    node[2:n_dom - 5] -= 1
    pipes = net.flowing_pipes
    a, b = net.pipe_domains[pipes, 0], net.pipe_domains[pipes, 1]
    keep = node[a] != node[b]
    system = PressureSystem(a[keep], b[keep], node)
    rng = np.random.default_rng(11)
    dt = 1e-6
    storage = system.to_nodes(net.domain_volume / 2e9 / dt)
    flow = system.matrix(storage, rng.uniform(1e-12, 1e-11, keep.sum()))
    masses = 2650 * np.pi * pk.radii**2
    free = np.ones((len(masses), 3), bool)  # x, y, spin
    free[:20] = False
    if pistons:
        free[:10] = (True, False, True)
        free[10:16] = (False, True, True)
    force = pressure_force_matrix(net, pk.radii, pk.centres)
    gradient = DomainGeometry(net).volume_gradient(pk.centres)
    stiffness = skeleton_stiffness(pk.centres, pk.radii, pk.contacts, K_N, K_N)
    newton = SkeletonNewton(flow, system.to_nodes_matrix, force, gradient, stiffness, masses,
                            0.5 * masses * pk.radii**2, free, dt)
    # the same operators, dense
    dofs = np.flatnonzero(free.ravel())
    s = (stiffness + sp.diags(np.c_[masses, masses, 0.5 * masses * pk.radii**2].ravel() / (0.5 * dt * dt)))
    s = s.toarray()[np.ix_(dofs, dofs)]
    xy = np.zeros((3 * len(masses), 2 * len(masses)))
    xy[np.arange(3 * len(masses)).reshape(-1, 3)[:, :2].ravel(), np.arange(2 * len(masses))] = 1.0
    e = system.to_nodes_matrix.toarray()
    jacobian = -np.linalg.solve(flow.toarray(), e @ gradient.toarray() @ xy.T[:, dofs]
                                @ np.linalg.solve(s, xy[dofs] @ force.toarray() @ e.T)) / dt
    r = system.domain_values(rng.normal(size=system.n_unknowns) * 1e3)
    dp = newton.step(r)
    assert np.all(dp[outlet] == 0.0) and dp[0] == dp[1]
    dp_node = system.node_values(dp)
    np.testing.assert_allclose(dp_node - jacobian @ dp_node, system.node_values(r), rtol=0, atol=1e-6 * 1e3)
    assert np.abs(jacobian).max() > 0.1  # the coupling is not negligible in this test
