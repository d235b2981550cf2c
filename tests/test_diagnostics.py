"""Pattern dimensions of radial patterns (decisions.md #27): the mass-radius dimension reads a
filled disc as 2 where box counting over the Huang sample's ~1.5 decades reads it below 1.9."""

import numpy as np
import pytest

from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario
from hmdem.flow.diagnostics import fractal_dimension, mass_radius_dimension


@pytest.fixture(scope="module")
def huang_network():
    net = build_radial_scenario(RADIAL_CASES["A1"]).net
    centre = net.domain_centroid[net.inlet_domains].mean(axis=0)
    grain = float(np.median(net.pipe_length))
    return net, centre, grain


@pytest.mark.parametrize("radius", [0.2e-3, 0.4e-3, 0.6e-3])
def test_filled_disc_has_mass_radius_dimension_two(huang_network, radius):
    net, centre, grain = huang_network
    disc = np.linalg.norm(net.domain_centroid - centre, axis=1) < radius
    # M(r) = pi r^2 inside the disc; 0.01: the rasterised triangles' staircase edge
    assert mass_radius_dimension(net, disc, centre, grain)[0] == pytest.approx(2.0, abs=0.01)
    # the bias the sandbox method avoids: box counting from a grain to a quarter of the sample
    extent = max(net.extent[1] - net.extent[0], net.extent[3] - net.extent[2])
    assert fractal_dimension(net, disc, grain, extent / 4)[0] < 1.9


def test_finger_has_a_low_dimension(huang_network):
    # a straight finger one grain wide, from the port to near the edge: a line (D = 1) once r
    # exceeds its width; 1.5 bounds the grain-scale part where the finger is still 2-D
    net, centre, grain = huang_network
    d = net.domain_centroid - centre
    finger = (np.abs(d[:, 1]) < grain / 2) & (d[:, 0] > 0) & (d[:, 0] < 0.55e-3)
    assert mass_radius_dimension(net, finger, centre, grain)[0] < 1.5


def test_empty_pattern_has_no_dimension(huang_network):
    net, centre, grain = huang_network
    assert np.isnan(mass_radius_dimension(net, np.zeros(net.n_domains, bool), centre, grain)[0])


@pytest.mark.parametrize("opened, d_f, regime", [
    (0, float("nan"), "infiltration"),
    (0, 1.5, "infiltration"),
    (3, 1.95, "infiltration-dominated with fracturing"),
    (3, 1.80, "fracturing-dominated"),
    (3, float("nan"), "undetermined"),  # a pattern too small to measure is not called fingered
])
def test_radial_regime_label(opened, d_f, regime):
    from hmdem.coupling.radial import classify_radial_regime

    assert classify_radial_regime(opened, d_f) == regime


def test_early_peak_is_the_peak_before_the_first_fall():
    from hmdem.flow.diagnostics import early_peak

    t = np.linspace(0.0, 1.0, 2001)
    rise = 1e5 * t
    # a monotonic rise (A1): its overall peak, at the end, and no fall
    assert tuple(early_peak(t, rise)) == (pytest.approx(1e5), pytest.approx(1.0), False)
    # dips of one step (a meniscus jump), falls of < 2 % and an end that sags do not end it
    dipped = rise.copy()
    dipped[1000] *= 0.5
    dipped[1500:1520] = dipped[1499] * 0.985
    dipped[-10:] = dipped[-11] * 0.999
    peak = early_peak(t, dipped)
    assert not peak.fell and peak.time == pytest.approx(t[-11])
    # a hump (A3: peak 0.86 MPa at 0.2, down 10 %, then a rise past it): the hump's top
    hump = np.where(t < 0.2, 4.3e6 * t, np.maximum(0.86e6 - 0.4e6 * (t - 0.2), 0.78e6 + 0.8e6 * (t - 0.4)))
    peak = early_peak(t, hump)
    assert peak.fell and peak.pressure == pytest.approx(0.86e6) and peak.time == pytest.approx(0.2)
    assert hump.max() > 1.2 * peak.pressure
    # a 3 % fall ends it, a 1 % one does not (a step down, a flat stretch, a rise past it)
    for depth, fell in ((0.03, True), (0.01, False)):
        shallow = np.where(t < 0.5, t, 0.5 * (1 - depth) + np.maximum(t - 0.7, 0.0))
        assert early_peak(t, shallow).fell is fell
    # negative pressures (suction) rising towards zero do not count as a fall; NaNs are left out
    assert not early_peak(t, -1e5 + 5e4 * t).fell
    nan = hump.copy()
    nan[7] = np.nan
    assert early_peak(t, nan).pressure == pytest.approx(0.86e6)
    assert np.isnan(early_peak([], []).pressure)
