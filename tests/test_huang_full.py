"""The Huang cases at paper size (issue 3; digest seed004 §13.3 H1-H8, H10): `make validate`.

Each case runs once per session, through the same command a user types
(``python -m hmdem.hele_shaw radial --case X``), to breakthrough; the assertions read the run
directory. Wall times on 2-core machines are in BENCHMARKS.md; with the P-V iteration on the
numba replica (decisions #65, #71), one run at a time on one core (2026-11-30): A1 11 min, A3 2,
B3 3, B1 17; B3 one-way 2 (2026-12-01, its Eq. 19 steps bisected); A3 and B3 again at half the flow step. Iterating in YADE they took 19-65, 5-22,
7-33 and 49-60 min (decisions #45, #55, #56). Tolerances are the digest's
(§13.3); where the model misses a claim the test is an expected failure that names the
measured figure, strict unless round-off could flip it (H2), so that a fix shows up.
"""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from hmdem.network.network import pipes_touching

pytestmark = [pytest.mark.yade, pytest.mark.slow]


@pytest.fixture(scope="module")
def huang(tmp_path_factory):
    """case -> (summary dict, time series columns); runs each case on first use."""
    root = tmp_path_factory.mktemp("huang")
    done = {}

    def run(case, *flags):
        key = (case, *flags)
        if key not in done:
            out = root / "-".join(key).replace("--", "")
            # ParaView snapshots at each twentieth of the front's way (fewer frames when a step
            # passes several): read by the H8 test; they leave the trajectory as it is
            cmd = [sys.executable, "-m", "hmdem.hele_shaw", "radial", "--case", case, *flags, "--out", str(out),
                   "--snapshots", "20", "--quiet"]
            subprocess.run(cmd, check=True)
            summary = json.loads((out / "summary.json").read_text())
            with open(out / "timeseries.csv") as f:
                rows = list(csv.DictReader(f))
            series = {k: np.array([float(r[k]) for r in rows]) for k in ("t", "p_in_mean")}
            done[key] = summary, series
            run.directory[key] = out
        return done[key]

    run.directory = {}  # (case, *flags) -> its run directory
    return run


def pressure_on_grid(series, points=10):
    """Injection pressure at ``points`` equally spaced times (the paper's figures' resolution)."""
    t, p = series["t"], series["p_in_mean"]
    return np.interp(np.linspace(0.0, t[-1], points + 1)[1:], t, p)


def sudden_drops(series, points=200, fraction=0.02):
    """Falls of more than ``fraction`` of the running peak between neighbouring times of a
    ``points`` grid (H10's "sudden drops", at 0.5 % of the run per grid interval)."""
    p = pressure_on_grid(series, points)
    return int(np.sum(np.diff(p) < -fraction * np.maximum.accumulate(p)[1:]))


def test_a1_infiltration_with_monotonic_pressure_and_circular_front(huang):
    s, series = huang("A1")
    assert s["status"] == "breakthrough"
    assert np.all(np.diff(pressure_on_grid(series)) >= 0.0)  # H1: monotonic rise
    assert s["fractal_dimension"] >= 1.90  # H1: circular front


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 3 open: at paper size A1 opens 4-6 "
                   "contacts by breakthrough (t = 0.0343 s, 2-3 still open at the end; BENCHMARKS.md), the "
                   "paper none; they separate 0.07-0.26 um, 1.2-4.3x the opening gap (the mean contact overlap, "
                   "0.06 um), and carried 0.009-0.13 N after settling (the weakest 1.5 % of contacts; mean "
                   "4.5 N). Capillary suction opens them (-33.5 kPa behind the front at theta = 0, Eq. 8): "
                   "with gamma = 0 the same run opens 1 (decisions #72). The criterion is not tuned to reach zero")
def test_a1_opens_no_contact(huang):
    assert huang("A1")[0]["n_opened_contacts"] == 0  # H1: zero fractures


def test_breakthrough_time_ratio_a1_a3(huang):
    ratio = huang("A1")[0]["breakthrough_time_s"] / huang("A3")[0]["breakthrough_time_s"]
    assert 15.0 <= ratio <= 25.0  # H6: 20 +- 5, the injection velocity ratio


# Table 4's t_f, the time each case ran to, its breakthrough (Fig. 13 is drawn there)
PAPER_BREAKTHROUGH_S = {"A1": 3.0e-2, "A3": 1.5e-3, "B1": 2.5e-2, "B3": 3.5e-4}


@pytest.mark.parametrize("case", [
    "A1", "A3", "B1",
    pytest.param("B3", marks=pytest.mark.xfail(
        strict=True, reason="known model discrepancy, issue 3 open: B3 breaks through at 6.1e-4 to 1.15e-3 s "
        "(8.07e-4 on 2026-11-30, 6.12e-4 on 2026-12-01), 1.7-3.3x the paper's 3.5e-4. B3 injects at A3's rate "
        "(Ca* / viscosity is the same to 0.1 %), and the paper's B3 reaches the outlets with 4.3x less fluid than "
        "its A3, ours with 2.1-2.8x less: away from the port its contacts open by a median 0.4-6 um, where the paper's fractures "
        "conduct as if ~18 um apart (H8; decisions #92, BENCHMARKS.md)")),
])
def test_breakthrough_time_within_40_percent_of_the_papers(huang, case):
    # H6: Table 4's times, +-40 % (digest §13.3). Measured 2026-11-30 at paper size: A1 3.43e-2 s
    # (+14 %), A3 1.715e-3 (+14 %), B1 3.46e-2 (+38 %; 3.459-3.474e-2 in every run recorded since
    # 2026-11-27, BENCHMARKS.md), B3 8.07e-4 (+131 %); 2026-12-01: +14, +15, +38 and +75 %
    s = huang(case)[0]
    assert s["status"] == "breakthrough"
    assert s["breakthrough_time_s"] == pytest.approx(PAPER_BREAKTHROUGH_S[case], rel=0.4)


@pytest.mark.parametrize("case", ["A3", "B1"])
def test_fractures_start_at_the_port(huang, case):
    # H2, H3: from A1 to A3 and B1 "the injection energy becomes large enough to mobilize grains
    # near the inflow port, initiating fractures": contacts open, the first of them one of the
    # injection domain's own (2026-12-01 at paper size: A3's and B1's first opened alone in its
    # step, a port contact each; B3's first 15 include all 4 of the port's)
    s = huang(case)[0]
    assert s["status"] == "breakthrough" and s["n_opened_contacts"] > 0
    run = huang.directory[(case,)]
    fractures, network = np.load(run / "fractures.npz"), np.load(run / "network.npz")
    opened_time = fractures["opened_time"]
    first = fractures["opened"] & (opened_time == opened_time[fractures["opened"]].min())
    assert np.all(pipes_touching(network["pipe_domains"], network["inlet_domains"])[first])


def test_a3_fractures_stay_in_the_infiltration_zone(huang):
    # H2: A3's fractures "remain within the fluid infiltration zone, not altering the circular flow
    # front": at breakthrough most opened contacts have both pores filled (decisions #48;
    # 318 of 349 on 2026-11-24)
    s = huang("A3")[0]
    assert s["n_opened_in_invaded_zone"] > s["n_opened_contacts"] / 2


@pytest.mark.xfail(strict=False, reason="known model discrepancy, issue 3 open (not strict: the fall sits at its threshold "
                   "and round-off moves it across): on 2026-11-30, after decisions #89 (Eq. 18 fills its "
                   "target), A3's curve fell only 1.99 % below its running peak on the 200-interval grid (754 kPa at "
                   "62 us, the fall by 86 us), under the 2 % that reads an early peak (#51), so the overall peak, "
                   "1.14 MPa at breakthrough, gave 11.4x A1's 100 kPa; on 2026-12-01 (HEAD of that day, a new venv) "
                   "it fell 2.5 % and passed at 7.5x (752 kPa at 63 us). The fall was always thin: 2.1-2.75 % on the "
                   "shipped packing before, 2.7 % on seed 1's, none on seed 2's (decisions #70). Read at 754 kPa "
                   "the ratio would be 7.5. The threshold is not moved")
def test_a3_early_peak_opens_contacts_then_drops(huang):
    # H2: A3 "peaks at 0.86 MPa—6.6 times higher than the maximum pressure in A1—initiating
    # fractures", then drops and rises again; the paper calls it "the early peak in A3" (seed 004
    # §4.2). Its early peak is the largest pressure before the curve, read as means over 200
    # intervals, first falls 2 % below its running peak (decisions #51), and contacts have opened
    # by then. Measured 2026-11-24: 753 kPa at 61 us, a fall of 2.1 % on that grid (the margin
    # is thin: at 2.2 % none is found, and the overall-peak ratio is 11.4), ratio 7.51. On the
    # packings of `compaction --seed 1/2`: 8.13 (a 2.7 % fall), and no 2 % fall (decisions #70)
    a3, a1 = huang("A3")[0], huang("A1")[0]
    assert a3["early_peak_fell"]
    assert a3["first_opening_time_s"] <= a3["early_peak_time_s"] < a3["breakthrough_time_s"]
    ratio = a3["early_peak_injection_pressure_pa"] / a1["peak_injection_pressure_pa"]
    assert 4.0 <= ratio <= 10.0  # H2: 6.6 in the paper


def test_b1_infiltration_dominated_with_fractures_inside_the_infiltrated_zone(huang):
    # H3: B1 is "infiltration-dominated", its fractures stay inside the infiltrated zone and the
    # front stays circular (qualitative in the digest). Read as for A1 and A3: the regime, a
    # mass-radius D_f >= 1.90 (H1's bound for a circular front) and most opened contacts with
    # both pores filled at breakthrough (measured 2026-11-25: 399 of 454, D_f 1.998, in 49 min;
    # 2026-11-27 on the replica: 409 of 464, D_f 1.998, in 26 min; with decisions #71 402 of 456)
    s = huang("B1")[0]
    assert s["status"] == "breakthrough"
    assert s["regime"] == "infiltration-dominated with fracturing"
    assert s["fractal_dimension"] >= 1.90
    assert s["n_opened_in_invaded_zone"] > s["n_opened_contacts"] / 2 > 0


def test_b3_opens_contacts_beyond_a3(huang):
    b3, a3 = huang("B3")[0], huang("A3")[0]
    assert b3["status"] == "breakthrough"
    assert b3["n_opened_contacts"] > a3["n_opened_contacts"] > 0  # H2, H4: fracturing grows with Ca*


def test_b3_fracturing_dominated(huang):
    # H4: finger-like front. At full size (BENCHMARKS.md) mass-radius D_f 1.88, four arms; with
    # Sigma = 0.25 mm exactly 1.83
    assert huang("B3")[0]["regime"] == "fracturing-dominated"


def test_b3_front_less_compact_than_the_infiltration_cases(huang):
    # H5: "the circular infiltration zones of A1, A3 and B1 have D_f ~ 1.95" and D_f "decreases when
    # fracturing shapes the front (B3)"; the digest's tolerance is the ordering. Mass-radius D_f
    # (decisions #27), measured 2026-11-27/28 at paper size: A1 1.997-1.998, A3 1.997-2.000, B1
    # 1.998; B3 1.67-1.88 over three packings, a halved step, the paper's network and the
    # calibrated sample (1.825 shipped). The experiments' [1.70, 1.82] is the fracture zone's (next test)
    b3 = huang("B3")[0]["fractal_dimension"]
    for case in ("A1", "A3", "B1"):
        assert b3 < huang(case)[0]["fractal_dimension"], case


FRACTURING_CASES = ("A3", "B1", "B3")  # in order of Ca*: 32.3, 56.3, 1138.1


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 3 open: the fracture zone's D_f rises with "
                   "Ca* (A3 1.53, B1 1.64, B3 1.78 at paper size; decisions #97): A3's and B1's contacts open "
                   "sparsely through their infiltrated discs, B3's throughout the sample")
def test_fracture_zone_dimension_falls_with_ca_star(huang):
    # H5: "the fractal dimension of the fracturing finger decreases as Ca* increases"; the
    # digest's tolerance is the ordering. App. E's box counting on the opened contacts drawn as
    # cracks (decisions #97); the other readings of benchmarks/fracture_dimension.py rise too
    d = [huang(case)[0]["fracture_fractal_dimension"] for case in FRACTURING_CASES]
    assert d[0] > d[1] > d[2]


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 3 open: A3's and B1's fracture zones read "
                   "1.53 and 1.64 at paper size, below the range; B3's 1.78 is inside it, as are random cracks at "
                   "its density (decisions #97)")
def test_fracture_zone_dimension_in_the_experimental_range(huang):
    # H5: the fracturing fingers' D_f is "consistent with the experimental range [1.70, 1.82]"
    # (Fig. 25b measures B3's). The figure mostly reads how densely the contacts open: random
    # cracks at B3's share of its contacts read 1.77 (benchmarks/fracture_dimension.py), so B3
    # alone inside the range would not show fingers, and the three are tested together
    d = {case: huang(case)[0]["fracture_fractal_dimension"] for case in FRACTURING_CASES}
    assert all(1.70 <= x <= 1.82 for x in d.values()), d


def test_b3_fractures_open_before_the_fluid_comes(huang):
    # H4: B3's injection pressure "creates fractures before fluid infiltration, guiding the fluid
    # to penetrate the fracturing domains at later stages": of the opened contacts the fluid
    # reached, most had opened before it entered either of their pores (decisions #48; by 0.2 ms
    # 112 of 143, reduced B3 27 of 35; at breakthrough, with arrival read as filling, 271 of 315)
    s = huang("B3")[0]
    assert s["n_opened_before_fluid"] > s["n_opened_reached_by_fluid"] / 2 > 0


def test_b3_fluid_goes_in_through_the_fractures(huang):
    # H4 from the fluid's side (decisions #87): B3's fractures guide "the fluid to penetrate the
    # fracturing domains"; A3's and B1's "remain within the fluid infiltration zone". Read as an
    # ordering, as H5's D_f: more of B3's filled pores were fed through a contact that had opened
    # before the fluid came than of A3's or B1's, and B3's fluid went in through opened pipes
    # more often than through the front's other pipes at the same moments. At paper size B3 is
    # near half, 0.47-0.565 over seven runs, so "most" is not asserted here (the reduced test
    # does, at 0.81). Measured 2026-11-30 (benchmarks/invasion_paths.py): B3 0.47 and 0.505-0.565
    # (shipped twice, seed 1, one-way, heavier, softer and stiffer grains), feeding pipes
    # 49-57 % open against 38-47 %; A3 0.16, 13 % against 11 %; B1 0.24, 17 % against 17 %
    b3 = huang("B3")[0]
    for case in ("A3", "B1"):
        assert b3["fracture_fed_fraction"] > huang(case)[0]["fracture_fed_fraction"], case
    assert b3["feeding_pipes_opened_fraction"] > b3["front_pipes_opened_fraction"]


def test_b3_fractures_conduct_far_better_than_their_sides(huang):
    # H8: "the lowest pipe flow resistance inside the fracturing zone is only 2.5 GPa s/m2, merely
    # 2 % of the lowest resistance at the sides" (seed 004 §4.2, Fig. 16e; digest bound < 0.1).
    # Read at each of the run's snapshots where the fluid has reached fractures away from the
    # port, R_s at the invading viscosity (decisions #67). Measured 2026-11-27: 0.084 at 12 us,
    # 0.012 at 32 us (2.05 against 164 GPa s/m2), below 0.01 from 49 us on
    from hmdem.coupling.output import fracture_resistance_series

    huang("B3")
    rows = [(t, fracture, side) for t, reached, fracture, side in fracture_resistance_series(huang.directory[("B3",)])
            if reached > 0 and np.isfinite(side)]
    assert len(rows) >= 10
    for t, fracture, side in rows:
        assert fracture < 0.1 * side, f"t = {t:.3g} s: {fracture:.3g} against {side:.3g} Pa s/m^2"


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 3 open: B3 has an early peak (3.5 MPa at "
                   "1.6 us, down to 2.2 MPa by 0.1 ms) but then rises to breakthrough (2.5-3.2 -> 4.9-7.7 MPa "
                   "on a 10-point grid) as the dry skeleton is compacted against the fixed hull: p_in = 2.1 MPa + "
                   "53.3 MPa x its area strain (R2 0.993; the sample's biaxial E is 54.9), the slope following "
                   "k_n; the paper peaks at 9.7 MPa and plateaus. "
                   "100x heavier grains give an 11.9 MPa peak and still rise 1.47x over the last 80 % of the run; "
                   "compaction --seed 2's packing has the paper's early peak (9.65 MPa) and still rises 2.2x over "
                   "the last 80 %; only held port grains are flat, at 32-35 MPa (BENCHMARKS.md, decisions #68). "
                   "Boundary grains under a constant load instead of fixed (--boundary loaded, not the seed's) "
                   "turn the rise into a fall towards the 0.14 MPa confining stress (decisions #86)")
def test_b3_early_peak_then_decline(huang):
    p = pressure_on_grid(huang("B3")[1])
    # H4: early peak, then decline to a plateau: the peak in the first half of the run and the
    # pressure at breakthrough below 80 % of it
    assert np.argmax(p) < len(p) // 2
    assert p[-1] < 0.8 * p.max()


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 3 open: the two-way B3 curve is not free "
                   "of drops: 3-7 falls of > 2 % on a 200-point grid, about half of them in the decline after the "
                   "early peak, and single steps falling 3-42 % of the running peak (three packings, two steps). The "
                   "one-way variant does fall harder, as the paper says: 7-21 grid falls, single steps of 14-68 % "
                   "(BENCHMARKS.md, 2026-11-28 and 2026-12-01). --one-way-volume lagged swings and collapses at "
                   "water's K instead, and is smooth at Zhang's 0.75 MPa (decisions #66)")
def test_b3_two_way_smooth_where_one_way_drops(huang):
    # H10: the P-V iteration gives a smooth B3 pressure curve, the one-way variant shows drops
    two_way, one_way = huang("B3")[1], huang("B3", "--one-way")[1]
    assert sudden_drops(two_way) == 0
    assert sudden_drops(one_way) > 0


def test_fractures_start_at_the_papers_injection_pressures(huang):
    # H7, Figs. 15b and 16b: A3's first contacts open at 393.4 kPa with 86 % of that step's
    # injection energy dissipated, B3's at 4076.1 kPa (decisions #69: the step at whose end the
    # first contact counts as opened). Pressures within 40 % (the digest's bound for a
    # different packing, H4), the fraction within 15 points (H7). Measured 2026-11-27: A3
    # 366 kPa at 2.9 us with 99.2 % dissipated (1.8 points inside the bound), B3 3.54 MPa at
    # 1.6 us, both in full 8e-7 s steps as the paper's
    a3, b3 = huang("A3")[0], huang("B3")[0]
    assert a3["fracture_onset_injection_pressure_pa"] == pytest.approx(393.4e3, rel=0.4)
    assert b3["fracture_onset_injection_pressure_pa"] == pytest.approx(4076.1e3, rel=0.4)
    assert abs(a3["fracture_onset_dissipated_fraction"] - 0.86) <= 0.15


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="known model discrepancy, issue 3 open: the first step dissipates 76 % of "
                   "its 2.58 uJ at 5.26 kPa (paper 28 % of 2.5 uJ at 5.1 kPa), and the residual energy of the step "
                   "that opens the first contact is 1.48 uJ in A3 and 629 uJ in B3 (paper 27.4 and 134.7 uJ), "
                   "a ratio of ~430 against 4.9 (BENCHMARKS.md, decisions #69). Readings of dE_v at the step's end "
                   "match A3's figures but are post hoc, and rejected (decisions #95)")
def test_energy_partition_of_figs_15_and_16(huang):
    a3, b3 = huang("A3")[0], huang("B3")[0]
    # H7: with the port still air-filled, 28 % of the step's injection energy is dissipated
    assert abs(a3["first_step_dissipated_fraction"] - 0.28) <= 0.15
    # H7: as fracturing is about to occur, B3's residual energy is 4.9x A3's (within x2)
    ratio = b3["fracture_onset_residual_energy_j"] / a3["fracture_onset_residual_energy_j"]
    assert 4.9 / 2 <= ratio <= 4.9 * 2


@pytest.mark.parametrize("case", ["A3", "B3"])
def test_halved_flow_step_keeps_regime_and_opened_contacts(huang, case):
    # issue 3 acceptance: halving the flow step leaves the regime and the opened-contact count
    # within 15 % (the reduced A3 is checked in make test). Measured 2026-11-26 at paper size:
    # A3 345 and 344 opened at 8e-7 and 4e-7 s, B3 841 and 840, each in its regime; 2026-11-28,
    # with decisions #71: A3 346 and 345, B3 831 and 858 (BENCHMARKS.md)
    from hmdem.coupling.radial import RADIAL_CASES

    full = huang(case)[0]
    half = huang(case, "--dt", repr(RADIAL_CASES[case].dt / 2))[0]
    assert half["status"] == "breakthrough"
    assert abs(half["n_opened_contacts"] - full["n_opened_contacts"]) <= 0.15 * full["n_opened_contacts"]
    assert half["regime"] == full["regime"]
