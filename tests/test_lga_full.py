"""The lattice-gas study of seed 003 at the paper's size (make validate; issue 6): the
permeability collapse over H = 0.3, 0.5, 0.7 with two surfaces each at delta_av/(2 y_max) =
1.35, 1.7, 2.4 (y_max = 90 rows, 512-long rough section), and the nonlinear drag in the
H = 0.5 channel of Fig. 12 against a smooth channel. Claim numbers are those of
../shared/digests/seed003.md §5. Both studies run through the command line, as a user would."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sph_bridge.lga.cli import main as lga_main

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("lga-full") / "permeability"
    assert lga_main(["permeability", "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


def test_forces_balance(study):
    # C6: applied = friction, <= 1 % typical, <= 3 % worst (Table I: 15 of 18 rows below 1 %)
    mismatches = [abs(d["force_mismatch"]) for p in study["points"] for d in p["drives"]]
    assert max(mismatches) <= 0.03 and float(np.median(mismatches)) <= 0.01
    assert all(d["steady"] for p in study["points"] for d in p["drives"])


def test_darcy_regime(study):
    # C9: Q against dP through the origin at the low drives: the two drives' slopes agree within 5 %
    # (mean velocities 0.005 and 0.01, Re 2.5-18.6: one octave above, 2 of 18 channels exceeded 5 %
    # as weak inertia set in; decisions #50)
    for p in study["points"]:
        assert abs(p["darcy_slope_change"]) <= 0.05, p["name"]


def test_cubic_law_overpredicts_and_ordering(study):
    # C12 (phi < 0.5 at rel <= 2.5) and C13 (phi rises with the opening; phi(2.4)/phi(1.35) in [2, 4])
    groups = study["by_opening"]
    assert all(p["phi"] < 0.5 for p in study["points"])
    means = [g["phi_mean"] for g in groups]
    assert means[0] < means[1] < means[2]
    assert 2.0 <= means[2] / means[0] <= 4.0


def test_hurst_independence(study):
    # C10: at each opening the H means agree within +-25 % of their mean (the digest's continuum
    # check shows a 15-30 % H trend itself)
    for g in study["by_opening"]:
        assert g["hurst_spread"] <= 0.25, g


def test_eq11_magnitude(study):
    # C11 as the issue bounds it: within a factor of 2 of Eq. 11 at every opening
    for g in study["by_opening"]:
        assert 0.5 <= g["ratio_to_eq11"] <= 2.0, g


def test_mach_bound(study):
    assert study["u_max"] <= 0.30  # C17


@pytest.fixture(scope="module")
def nonlinear(tmp_path_factory):
    out = tmp_path_factory.mktemp("lga-full") / "nonlinear"
    assert lga_main(["nonlinear", "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


def test_rough_drag_rises_more_than_smooth(nonlinear):
    # C14-C15: over the Re ladder Delta P/Q rises in the rough channel clearly more than in the
    # smooth one (the digest's key assertion: more than twice the smooth channel's rise); C17
    assert nonlinear["rough_drag_increase"] > 2.0 * max(nonlinear["smooth_drag_increase"], 0.0)
    assert nonlinear["rough_drag_increase"] > 0.05
    assert max(nonlinear["rough_u_max"], nonlinear["smooth_u_max"]) <= 0.30


def test_reynolds_range_covers_the_paper(nonlinear):
    # seed 003 §5 ran Re ~ 20-180 at u_max <= 0.30; its Re convention is unstated, and Fig. 12's
    # Re/Q = 3.83 against our 1/nu = 3.25 makes its 180 our ~153 (decisions #42, #44). The
    # ladder's last drive aims at u_max = 0.285 (decisions #53): Re 15.7-154.9, u_max 0.283
    # (2026-11-25)
    assert nonlinear["rough_reynolds_range"][0] <= 25 and nonlinear["rough_reynolds_range"][1] >= 150

