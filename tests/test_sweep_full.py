"""The issue-4 acceptance grid: 5 x 6 points (log M -5..2, log Ca* -8..2) on the default packing,
through the command a user types (`make validate`; ~15 min on 2 cores, BENCHMARKS.md)."""

import csv
import subprocess
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    out = tmp_path_factory.mktemp("lenormand") / "sweep"
    subprocess.run([sys.executable, "-m", "hmdem.sweep", "lenormand", "--out", str(out), "--quiet"], check=True)
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    return {(float(r["log_m"]), float(r["log_ca_star"])): r for r in rows}


def column(grid, log_m):
    keys = sorted(k for k in grid if k[0] == log_m)
    return np.array([k[1] for k in keys]), np.array([float(grid[k]["fractal_dimension"]) for k in keys])


def test_every_point_runs_to_breakthrough(grid):
    assert len(grid) == 30
    assert {r["status"] for r in grid.values()} == {"breakthrough"}


def test_regime_fields_sit_where_lenormands_do(grid):
    # issue 4: capillary fingering at low Ca* for all M; viscous fingering at high Ca* for
    # log M <= -2; stable displacement at high Ca* for log M >= 1
    ms = sorted({k[0] for k in grid})
    assert all(grid[(m, -8.0)]["regime"] == "capillary fingering" for m in ms)
    assert all(grid[(m, 2.0)]["regime"] == "viscous fingering" for m in ms if m <= -2)
    assert all(grid[(m, 2.0)]["regime"] == "stable displacement" for m in ms if m >= 1)


def test_fractal_dimension_trends_with_ca_star(grid):
    # seed 004 §4.1 (digest L1-L4): along low M, D_f falls from capillary to viscous fingering;
    # along high M it rises from capillary fingering to stable displacement. The least-squares
    # slope of D_f against log Ca* carries the sign.
    ca, d_low = column(grid, -5.0)
    assert np.polyfit(ca, d_low, 1)[0] < 0
    ca, d_high = column(grid, 2.0)
    assert np.polyfit(ca, d_high, 1)[0] > 0
