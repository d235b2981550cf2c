"""Pressure forces on grains, seed 004 Eq. 8: digest §13.1 U5."""

import numpy as np

from hmdem.flow.grain_forces import grain_pressure_forces
from hmdem.network import build_contact_network
from hmdem.scenario import load_packing


def test_u5_single_corner_force_is_2_p_r_sin_beta():
    # one triangular domain of three touching discs: each corner gets 2 p r sin(beta), beta = 30 deg,
    # along the bisector pointing away from the domain (1e-12 rel)
    r = 1e-3
    pts = np.array([[0.0, 0.0], [2 * r, 0.0], [r, np.sqrt(3) * r]])
    net = build_contact_network(pts, np.full(3, r), np.array([[0, 1], [0, 2], [1, 2]]))
    assert net.n_domains == 1
    p = 1234.5
    f = grain_pressure_forces(net, np.full(3, r), np.array([p]))
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 2 * p * r * np.sin(np.pi / 6), rtol=1e-12)
    centre = pts.mean(axis=0)
    away = (pts - centre) / np.linalg.norm(pts - centre, axis=1)[:, None]
    np.testing.assert_allclose(f / np.linalg.norm(f, axis=1)[:, None], away, atol=1e-12)


def test_u5_uniform_pressure_gives_zero_net_force_on_inner_grains():
    pk = load_packing()
    net = build_contact_network(pk.centres, pk.radii, pk.contacts)
    p = 5.0e4
    f = grain_pressure_forces(net, pk.radii, np.full(net.n_domains, p))
    # grains whose every contact edge has a domain on both sides are surrounded by fluid
    g = net.pipe_grains
    on_hull = np.zeros(len(pk.radii), bool)
    on_hull[g[(net.pipe_domains < 0).any(axis=1)].ravel()] = True
    inner = ~on_hull & (np.bincount(g.ravel(), minlength=len(pk.radii)) > 0)
    assert inner.sum() > 900
    scale = 2 * p * pk.radii.max()
    assert np.abs(f[inner]).max() < 1e-12 * scale

