"""Lenormand regimes on the default packing and the Chen-Wilkinson lattice (digest §13.2).

vf, cf1 and chen run here (CI); sd, cf2 and the dt-sensitivity study are marked slow (make validate).
"""

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from hmdem.cases import CASES
from hmdem.report import summarize

from conftest import run_case


def test_l1_l5_viscous_fingering(vf_run):
    sc, model, state, rec = vf_run
    s = summarize(sc, model, state, rec)
    assert rec.status == "breakthrough"
    assert s["regime"] == "viscous fingering"
    assert 1.58 <= s["fractal_dimension"] <= 1.70  # L1
    assert s["peak_injection_pressure_pa"] == pytest.approx(83.77e3, rel=0.30)  # L5 peak +-30 %
    assert 0.25 <= s["final_injection_pressure_pa"] / s["peak_injection_pressure_pa"] <= 0.5  # L5 shape
    assert s["breakthrough_time_s"] == pytest.approx(10.5, rel=0.30)  # L9
    assert 0.2 <= s["breakthrough_saturation"] <= 0.35  # L11 [DERIVED] injected volume / sum V


def test_l2_l6_capillary_fingering(cf1_run, vf_run):
    sc, model, state, rec = cf1_run
    s = summarize(sc, model, state, rec)
    vf = summarize(*vf_run)
    assert rec.status == "breakthrough"
    assert s["regime"] == "capillary fingering"
    assert vf["fractal_dimension"] < s["fractal_dimension"]  # L1: D_f(VF) < D_f(CF)
    assert s["peak_injection_pressure_pa"] < 1e3  # L6: max < 1 kPa
    p0 = rec.rows[0][2]
    assert p0 == pytest.approx(0.13e3, rel=0.30)  # L6 initial pressure +-30 %
    assert s["breakthrough_time_s"] == pytest.approx(9324.1, rel=0.30)  # L9


@pytest.mark.xfail(strict=True, reason="known model discrepancy (decisions #89): cf1's D_f is 1.760 on seed 0 "
                   "and 1.676-1.759 on aperture seeds 1-4, below the digest's [1.77, 1.88] around the paper's "
                   "1.83. Seed 0 gave 1.778 only while the Eq. 18 refinement accepted steps that left its target "
                   "short of full (U10); seeds 1-4 were the same then. The bound is the paper's, not moved")
def test_l2_capillary_fingering_fractal_dimension(cf1_run):
    assert 1.77 <= summarize(*cf1_run)["fractal_dimension"] <= 1.88  # L2


@pytest.mark.xfail(strict=True, reason="known open discrepancy (issue 2): |S_VF - S_CF| = 0.125 on seed 0, "
                   "the digest's L11 bound is 0.1 (the paper says 'nearly identical'); L11 is not an "
                   "acceptance item, both lie in the derived range [0.2, 0.35], and strict makes a fix visible")
def test_l11_case1_saturations_nearly_identical(cf1_run, vf_run):
    s, vf = summarize(*cf1_run), summarize(*vf_run)
    assert abs(s["breakthrough_saturation"] - vf["breakthrough_saturation"]) < 0.1  # L11


def count_fingers(sc, state, core_radius):
    """Arms of the invaded cluster outside a core disc around the inlet, and their directions."""
    net = sc.net
    centre = net.domain_centroid[net.inlet_domains[0]]
    rel = net.domain_centroid - centre
    far = state.invaded & (np.linalg.norm(rel, axis=1) > core_radius)
    pipes = net.flowing_pipes
    a, b = net.pipe_domains[pipes].T
    keep = far[a] & far[b]
    graph = coo_matrix((np.ones(keep.sum()), (a[keep], b[keep])), shape=(net.n_domains,) * 2)
    _, label = connected_components(graph, directed=False)
    arms = np.unique(label[far])
    angles = [np.degrees(np.arctan2(*rel[far & (label == k)].mean(axis=0)[::-1])) for k in arms]
    return len(arms), np.array(angles)


def test_l15_chen_wilkinson_four_fingers():
    sc, model, state, rec = run_case("chen")
    assert rec.status == "breakthrough"
    assert summarize(sc, model, state, rec)["regime"] == "viscous fingering"  # uniform thresholds: viscous selection
    n, angles = count_fingers(sc, state, core_radius=3 * 0.5e-3)
    assert n == 4  # L15: exactly four fingers
    along_axis = np.min(np.abs(((angles[:, None] - np.array([0, 90, 180, -90, -180])[None, :]) + 180) % 360 - 180), axis=1)
    assert np.all(along_axis < 10.0)  # along +-x and +-y


@pytest.mark.slow
def test_l3_l7_stable_displacement():
    sc, model, state, rec = run_case("sd")
    s = summarize(sc, model, state, rec)
    assert s["regime"] == "stable displacement"
    assert s["fractal_dimension"] >= 1.90  # L3
    assert s["peak_injection_pressure_pa"] == pytest.approx(196.07e3, rel=0.25)  # L7
    assert s["breakthrough_saturation"] == pytest.approx(0.90, abs=0.08)  # L10
    assert s["breakthrough_time_s"] == pytest.approx(8.1, rel=0.30)  # L9


@pytest.mark.slow
def test_l4_l8_capillary_fingering_case2():
    sc, model, state, rec = run_case("cf2")
    s = summarize(sc, model, state, rec)
    assert s["regime"] == "capillary fingering"
    assert 1.77 <= s["fractal_dimension"] <= 1.90  # L4
    assert s["peak_injection_pressure_pa"] == pytest.approx(0.16e3, rel=0.40)  # L8
    assert s["breakthrough_saturation"] == pytest.approx(0.56, abs=0.08)  # L10
    assert s["breakthrough_time_s"] == pytest.approx(72120.4, rel=0.30)  # L9


@pytest.mark.slow
@pytest.mark.parametrize("case", ["vf", "cf1"])
@pytest.mark.parametrize("factor", [0.5, 2.0])
def test_l14_independent_of_dt(case, factor, vf_run, cf1_run):
    # L14 / issue 2: dt x0.5 and x2 give the same regime and D_f within 0.03
    ref = summarize(*(vf_run if case == "vf" else cf1_run))
    sc, model, state, rec = run_case(case, dt=CASES[case].dt * factor)
    s = summarize(sc, model, state, rec)
    assert s["regime"] == ref["regime"]
    assert abs(s["fractal_dimension"] - ref["fractal_dimension"]) <= 0.03
