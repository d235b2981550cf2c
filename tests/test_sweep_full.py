"""The issue-4 acceptance grid: 5 x 6 points (log M -5..2, log Ca* -8..2) on the default packing,
through the command a user types (`make validate`; ~7 min on 2 cores, BENCHMARKS.md)."""

import csv
import subprocess
import sys

import numpy as np
import pytest

from hmdem.flow.fluids import WEAK_COMPRESSION

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    out = tmp_path_factory.mktemp("lenormand") / "sweep"
    subprocess.run([sys.executable, "-m", "hmdem.sweep", "lenormand", "--out", str(out), "--quiet"])
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    return {(float(r["log_m"]), float(r["log_ca_star"])): r for r in rows}


def liquid(row) -> bool:
    """The run's peak pressure stays within the linear equation of state's range (p/K <= 0.1)."""
    return float(row["peak_compression"]) <= WEAK_COMPRESSION


def column(grid, log_m, keep=lambda row: True):
    keys = sorted(k for k in grid if k[0] == log_m and keep(grid[k]))
    d_f = [float(grid[k]["fractal_dimension"] or "nan") for k in keys]  # empty: the run failed
    return np.array([k[1] for k in keys]), np.array(d_f)


def test_every_point_runs_to_breakthrough(grid):
    assert len(grid) == 30
    assert {r["status"] for r in grid.values()} == {"breakthrough"}


def test_regime_fields_sit_where_lenormands_do(grid):
    # issue 4: capillary fingering at low Ca* (read at -8 and -6) for all M; viscous fingering at
    # high Ca* for log M <= -2; stable displacement at high Ca* for log M >= 1
    ms = sorted({k[0] for k in grid})
    assert len(ms) == 5
    assert all(grid[(m, c)]["regime"] == "capillary fingering" for m in ms for c in (-8.0, -6.0))
    assert all(grid[(m, 2.0)]["regime"] == "viscous fingering" for m in ms if m <= -2)
    assert all(grid[(m, 2.0)]["regime"] == "stable displacement" for m in ms if m >= 1)


def test_fractal_dimension_rises_with_ca_star_at_high_m(grid):
    # seed 004 §4.1 (digest L3, L4): along high M, D_f rises from capillary fingering to stable
    # displacement; the least-squares slope of D_f against log Ca* carries the sign
    ca, d_high = column(grid, 2.0)
    assert np.polyfit(ca, d_high, 1)[0] > 0


def test_fractal_dimension_falls_with_ca_star_at_low_m_while_the_fluids_stay_liquids(grid):
    # seed 004 §4.1 (digest L1, L2): along low M, D_f falls from capillary to viscous fingering.
    # Lenormand's fluids are liquids; the model's linear equation of state describes one only for
    # p/K <= 0.1 (fluids.WEAK_COMPRESSION). Three high-rate points of the grid go beyond: at
    # (log M, log Ca*) = (-5, 2), (-5, 0) and (-3.25, 2) the injection pressure reaches 0.64, 0.13
    # and 0.18 K (1.3 GPa, 0.26 GPa, 0.36 GPa against K = 2 GPa). They are left out of the trend,
    # and the test names them, so the grid cannot drift out of the model's range unnoticed.
    assert {k for k, row in grid.items() if not liquid(row)} == {(-5.0, 2.0), (-5.0, 0.0), (-3.25, 2.0)}
    for log_m in (-5.0, -3.25):
        ca, d_low = column(grid, log_m, keep=liquid)
        assert np.polyfit(ca, d_low, 1)[0] < 0


@pytest.mark.xfail(strict=True, reason="outside the model's range, issue 4: along log M = -5 D_f is 1.79, 1.61, "
                   "1.66, 1.66, 1.67, 1.88 for log Ca* = -8..2 (2026-12-01, after decisions #93; 1.87-1.88 "
                   "before): it falls from capillary to viscous fingering, but "
                   "the log Ca* = 2 run (Q ~ 1e4 m^3/s per m, peak pressure 1.3 GPa = 0.64 K: the oil would "
                   "compress by tens of per cent under the linear equation of state) reads 1.88, so the slope over "
                   "the whole column is positive")
def test_fractal_dimension_falls_with_ca_star_at_low_m(grid):
    ca, d_low = column(grid, -5.0)
    assert np.polyfit(ca, d_low, 1)[0] < 0
