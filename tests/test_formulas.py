"""Closed-form checks: digest seed 004 §13.1 U4, U11-U15 and Eqs. 3-4."""

import numpy as np
import pytest

from hmdem.calibration import mohr_coulomb_friction_angle, porosity_2d_to_3d, porosity_3d_to_2d
from hmdem.cases import AIR_OIL, CASES, CP, GLUCOSE_OIL, MPA, ca_star_from_rate, rate_from_ca_star
from hmdem.flow.fluids import FluidPair, explicit_critical_step


def test_u4_entry_pressure_range_case1():
    # seed004 U4: p_c = 4 gamma cos(theta) / a over a in [0.126, 0.714] mm: -635 ... -112 Pa
    pc = AIR_OIL.entry_pressure(np.array([0.126e-3, 0.714e-3]))
    np.testing.assert_allclose(pc, [-4 * 0.02 / 0.126e-3, -4 * 0.02 / 0.714e-3], rtol=1e-9)
    assert pc[0] == pytest.approx(-634.9, abs=0.1) and pc[1] == pytest.approx(-112.0, abs=0.1)


def test_imbibition_entry_pressure_is_positive():
    # digest §3.4: theta = 0 gives +4 gamma / a (Huang: +33.5 kPa at a0 = 7.53 um)
    water_air = FluidPair(5 * CP, 0.018 * CP, 2000 * MPA, 0.14 * MPA, 0.063, 0.0)
    assert water_air.entry_pressure(np.array([7.53e-6]))[0] == pytest.approx(33.47e3, rel=1e-3)


def test_mixture_rules_eq3_eq4():
    s = np.array([0.0, 0.25, 1.0])
    np.testing.assert_allclose(AIR_OIL.mixture_bulk_modulus(s), [2000e6, 0.25 * 0.14e6 + 0.75 * 2000e6, 0.14e6])
    eta = AIR_OIL.pipe_viscosity(np.array([1.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(eta, [0.018e-3, 0.5 * (0.018e-3 + 1.0), 1.0])


def test_u11_explicit_critical_step():
    # seed004 U11 (Eq. 30, N = 5): air-oil 6.17e-10 s; glycerol(176 cP)-air 4.22e-10 s, 1e-3 rel
    assert explicit_critical_step(AIR_OIL) == pytest.approx(6.171e-10, rel=1e-3)
    group_b = FluidPair(176 * CP, 0.018 * CP, 2000 * MPA, 0.14 * MPA, 0.063, 0.0)
    assert explicit_critical_step(group_b) == pytest.approx(4.224e-10, rel=1e-3)


def test_u12_porosity_map():
    # seed004 U12 (Eq. 22): phi3D 0.35 -> phi2D 0.1438; phi2D 0.117 -> phi3D 0.3022, 1e-4
    assert porosity_3d_to_2d(0.35) == pytest.approx(0.1438, abs=1e-4)
    assert porosity_2d_to_3d(0.117) == pytest.approx(0.3022, abs=1e-4)


def test_u13_mohr_coulomb():
    # seed004 U13: sigma1 = 309.6 kPa, sigma3 = 100 kPa -> 30.78 deg, 0.01 deg
    assert mohr_coulomb_friction_angle(309.6e3, 100e3) == pytest.approx(30.78, abs=0.01)


def test_u14_viscosity_ratios():
    # seed004 U14, 1e-3 rel
    assert AIR_OIL.viscosity_ratio == pytest.approx(1.8e-5, rel=1e-3)
    assert GLUCOSE_OIL.viscosity_ratio == pytest.approx(101.8, rel=1e-3)
    assert (5 / 0.018) == pytest.approx(277.8, rel=1e-3)
    assert (176 / 0.018) == pytest.approx(9777.8, rel=1e-3)


@pytest.mark.parametrize("case,q", [("vf", 8.87e-5), ("cf1", 1.45e-7), ("sd", 4.12e-4), ("cf2", 2.56e-8)])
def test_u15_ca_star_to_rate(case, q):
    # seed004 U15: Sigma = H = L = 65 mm, a_mean = 0.42 mm; 1e-3 rel of the digest's 3-digit values
    c = CASES[case]
    rate = rate_from_ca_star(c.ca_star, c.fluids, 0.065, 0.065, 0.42e-3)
    assert rate == pytest.approx(q, rel=3e-3)
    assert ca_star_from_rate(rate, c.fluids, 0.065, 0.065, 0.42e-3) == pytest.approx(c.ca_star, rel=1e-12)
