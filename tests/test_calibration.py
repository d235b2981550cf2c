"""Calibration tests of the Huang sample (seed 004 §4.2): network Darcy permeability, the biaxial
test and the ``python -m hmdem.calibrate`` command line."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import sigterm_once_stderr_shows
from hmdem.calibrate import main
from hmdem.coupling.apertures import ApertureLaw
from hmdem.coupling.darcy import darcy_network, packing_permeability, solve_darcy
from hmdem.coupling.geometry import contact_gaps
from hmdem.coupling.radial import default_huang_packing_path
from hmdem.dem.biaxial import elastic_constants
from hmdem.network import square_lattice_network
from hmdem.network.boundaries import linear_flow_boundaries
from hmdem.network.packing import DiscPacking

N_SIDE, SPACING = 8, 1.0e-3


def lattice(n_side=N_SIDE, spacing=SPACING):
    """Square lattice of touching discs; inflow = first column of domains, outflow = last."""
    net = square_lattice_network(n_side, spacing)
    net.inlet_domains, net.outlet_domains = linear_flow_boundaries(net, band=spacing)
    return net


def lattice_pipes(net, n_side=N_SIDE):
    """For each pipe: is it a flow-direction pipe (grains stacked vertically, separating two
    domain columns), its grain column ix and its domain row."""
    g = net.pipe_grains
    ix, iy = g % n_side, g // n_side
    along = ix[:, 0] == ix[:, 1]
    return along, ix[:, 0], iy.min(axis=1)


def test_lattice_layout_is_what_the_formulas_below_assume():
    net = lattice()
    assert len(net.inlet_domains) == len(net.outlet_domains) == N_SIDE - 1
    np.testing.assert_allclose(net.domain_centroid[net.inlet_domains, 0], 0.5 * SPACING)
    np.testing.assert_allclose(net.domain_centroid[net.outlet_domains, 0], (N_SIDE - 1.5) * SPACING)


def test_uniform_lattice_gives_the_channel_permeability():
    # n-1 rows of n-2 identical pipes in series between the inflow and outflow columns:
    # Q = (n-1) G dP / (n-2), G = a^3 / (12 eta s); with L = (n-2) s between the boundary
    # centroids and H = (n-1) s the centre extent, k = eta L Q / (H dP) = a^3 / (12 s)
    net = lattice()
    a = 40e-6
    net.pipe_aperture[:] = a
    flow = solve_darcy(net, viscosity=1e-3, pressure_drop=2e4)
    assert flow.length == pytest.approx((N_SIDE - 2) * SPACING, rel=1e-12)
    assert flow.height == pytest.approx((N_SIDE - 1) * SPACING, rel=1e-12)
    assert flow.permeability == pytest.approx(a**3 / (12 * SPACING), rel=1e-10)
    assert flow.balance_error < 1e-12


def test_columns_in_series_give_the_harmonic_mean_of_a_cubed():
    # flow pipes of grain column ix (1..n-2) get aperture a_ix; every row is the same series
    # chain, so the cross pipes carry nothing and k = (n-2) / (12 s sum_ix a_ix^-3)
    net = lattice()
    along, ix, _ = lattice_pipes(net)
    a_col = np.linspace(10e-6, 60e-6, N_SIDE)
    net.pipe_aperture[:] = np.where(along, a_col[ix], 25e-6)
    flow = solve_darcy(net)
    inner = a_col[1:N_SIDE - 1]
    expected = (N_SIDE - 2) / (12 * SPACING * np.sum(inner**-3.0))
    assert flow.permeability == pytest.approx(expected, rel=1e-10)
    # an arithmetic mean of a^3 (a wrong series rule) would be 3.7x larger here
    assert np.mean(inner**3) / (12 * SPACING) > 3 * expected


def test_rows_in_parallel_give_the_arithmetic_mean_of_a_cubed():
    # flow pipes of domain row r get a_r; p is linear in x in every row, cross pipes carry
    # nothing, and k = sum_r a_r^3 / (12 s (n-1))
    net = lattice()
    along, _, row = lattice_pipes(net)
    a_row = np.linspace(10e-6, 60e-6, N_SIDE - 1)
    net.pipe_aperture[:] = np.where(along, a_row[np.minimum(row, N_SIDE - 2)], 5e-6)
    flow = solve_darcy(net)
    assert flow.permeability == pytest.approx(np.sum(a_row**3) / (12 * SPACING * (N_SIDE - 1)), rel=1e-10)


def test_random_lattice_lies_between_the_rayleigh_bounds_and_ignores_eta_and_dp():
    # Rayleigh monotonicity: closing every cross pipe (parallel rows of series chains) can
    # only lower the conductance; making them infinitely conductive (series of parallel
    # columns) can only raise it. k must also be independent of eta and dP.
    rng = np.random.default_rng(4)
    net = lattice()
    along, ix, row = lattice_pipes(net)
    a = rng.uniform(5e-6, 50e-6, net.n_pipes)
    net.pipe_aperture[:] = a
    k = solve_darcy(net, viscosity=1e-3, pressure_drop=1e3).permeability
    assert solve_darcy(net, viscosity=0.7, pressure_drop=3e6).permeability == pytest.approx(k, rel=1e-10)
    inner = along & (ix >= 1) & (ix <= N_SIDE - 2)
    g = a**3 / (12 * SPACING)  # eta = 1
    n_rows, n_steps = N_SIDE - 1, N_SIDE - 2
    lower = sum(1.0 / np.sum(1.0 / g[inner & (row == r)]) for r in range(n_rows))
    upper = 1.0 / sum(1.0 / np.sum(g[inner & (ix == c)]) for c in range(1, N_SIDE - 1))
    to_k = n_steps * SPACING / (n_rows * SPACING)  # k = L Q / (H dP) with eta = dP = 1
    assert lower * to_k < k < upper * to_k
    assert upper / lower > 1.2  # the bounds are not trivially equal for this field


def test_isolated_domains_are_left_out_not_singular():
    # closing the pipes round one interior domain leaves it floating: still a solution, no flow there
    net = lattice()
    net.pipe_aperture[:] = 20e-6
    target = int(np.argmin(np.linalg.norm(net.domain_centroid - net.domain_centroid.mean(axis=0), axis=1)))
    net.pipe_aperture[(net.pipe_domains == target).any(axis=1)] = 0.0
    flow = solve_darcy(net)
    assert np.isnan(flow.pressure[target])
    assert 0 < flow.permeability < 20e-6**3 / (12 * SPACING)
    assert flow.balance_error < 1e-12


def test_contact_forces_set_eq13_apertures_of_the_shipped_packing():
    # with F = F0 on every pipe the Eq. 13 aperture is a0/2 everywhere, with F -> 0+ it is a0:
    # k must drop by exactly (1/2)^3, whatever the geometry
    pk = DiscPacking.load(default_huang_packing_path())
    law = ApertureLaw()
    m = darcy_network(pk).n_pipes
    k_a0 = packing_permeability(pk, lambda pairs: np.full(m, 1e-12 * law.half_aperture_force), law).permeability
    k_half = packing_permeability(pk, lambda pairs: np.full(m, law.half_aperture_force), law).permeability
    assert k_half / k_a0 == pytest.approx(0.125, rel=1e-9)
    # ... and with a0 everywhere k is the network's a0^3 / 12 scale: between 0.1x and 10x of the
    # paper's 7.43e-13 (a sign, power or unit slip would miss by orders of magnitude)
    assert 7.43e-14 < k_a0 < 7.43e-12


def test_elastic_constants_use_compression_positive_strains():
    ea = np.linspace(0, 0.004, 41)
    q = 60e6 * ea + 3e3  # an offset must not change the slope
    el = -0.15 * ea  # the sample widens: lateral strain is negative (compression positive)
    young, poisson = elastic_constants(ea, el, q, (0.0, 0.001))
    assert young == pytest.approx(60e6, rel=1e-10)
    assert poisson == pytest.approx(0.15, rel=1e-10)
    with pytest.raises(ValueError):
        elastic_constants(ea, el, q, (0.5, 0.6))


# ------------------------------------------------------------------------ command line, bad input

@pytest.mark.parametrize("args,flag", [
    (["biaxial", "--sigma3", "-1"], "--sigma3"),
    (["biaxial", "--sigma3", "0"], "--sigma3"),
    (["biaxial", "--sigma3", "nan"], "--sigma3"),
    (["biaxial", "--strain-rate", "0"], "--strain-rate"),
    (["biaxial", "--strain-rate", "inf"], "--strain-rate"),
    (["biaxial", "--n", "3"], "--n"),
    (["biaxial", "--n", "1.5"], "--n"),
    (["biaxial", "--seed", "-1"], "--seed"),
    (["biaxial", "--max-strain", "0.9"], "--max-strain"),
    # a new-user pass: a test ended inside the fit window reported E and nu from part of it
    (["biaxial", "--max-strain", "0.0005"], "--max-strain"),
    (["biaxial", "--contact-stiffness", "0"], "--contact-stiffness"),
    (["biaxial", "--friction", "nan"], "--friction"),
    (["biaxial", "--stiffness-ratio", "-1"], "--stiffness-ratio"),
    (["darcy", "--contact-stiffness", "inf"], "--contact-stiffness"),
    (["darcy", "--stresses", "1e5,-2e5"], "--stresses"),
    (["darcy", "--stresses", "1e5,,2e5"], "--stresses"),
    (["darcy", "--stresses", "abc"], "--stresses"),
    (["darcy", "--packing", "missing.npz"], "--packing"),
    # a new-user pass: an uncompacted packing ran for minutes to k = 7e-18 (no contact forces)
    (["darcy", "--packing", str(Path(__file__).resolve().parent.parent / "hmdem" / "data" / "lenormand_packing.npz")],
     "--packing"),
    (["darcy", "--contact-gap", "50"], "--contact-gap"),
    # a new-user pass: compaction at 1e30 Pa ran its whole cycle budget; the bound is 2.8 MPa at
    # Table 2's k_n (overlap ~ sigma (r_min + r_max) / k_n = 0.1 r_min; the paper's 2.1 MPa is 0.075)
    (["biaxial", "--sigma3", "3e6"], "--sigma3"),
    (["darcy", "--stresses", "1e5,3e6"], "--stresses"),
    (["darcy", "--stresses", "1e5", "--contact-stiffness", "1e6"], "--stresses"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, monkeypatch, capsys, args, flag):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    try:
        code = main([*args, "--out", str(out)])
    except SystemExit as exc:  # argparse errors exit from inside parse_args
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"python -m hmdem.calibrate: {flag}: ")
    assert list(tmp_path.iterdir()) == []  # no run directory, no temporary one


@pytest.mark.parametrize("args,flag", [
    (["--contact-stiffness", "-7.49e7"], "--contact-stiffness"),
    (["--n", "3"], "--n"),
    (["--stress", "0"], "--stress"),
    (["--out", "a_file/p.npz"], "--out"),
    (["--out", "p"], "--out"),  # numpy would write p.npz
    (["--seed", "-1"], "--seed"),
    (["--stress", "1e30"], "--stress"),  # see the calibrate test's --sigma3 3e6
    (["--stress", "2e6", "--contact-stiffness", "5e7"], "--stress"),
    # a new-user pass: these ended in tracebacks (the shrunk discs did not fit the box, or the
    # box was narrower than a disc) or ran the whole cycle budget (a 10 m box)
    (["--n", "5000", "--size", "1.25e-3"], "--size"),
    (["--size", "1e-6"], "--size"),
    (["--size", "10"], "--size"),
])
def test_compaction_bad_input_is_one_line_exit_2_nothing_written(tmp_path, monkeypatch, capsys, args, flag):
    from hmdem.dem.compaction import main as compaction_main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("x")  # an --out through a file
    argv = args if "--out" in args else [*args, "--out", "p.npz"]
    try:
        code = compaction_main(argv)
    except SystemExit as exc:  # argparse errors exit from inside parse_args
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"python -m hmdem.dem.compaction: {flag}: ")
    assert [p.name for p in tmp_path.iterdir()] == ["a_file"]


class _Called(Exception):
    """Stops a command at the function under test, with the arguments it was given."""


def test_contact_flags_reach_the_biaxial_and_darcy_tests(tmp_path, monkeypatch):
    # decisions #74: the flags arrive as the tests' keyword arguments (no YADE run here)
    import hmdem.dem.biaxial as biaxial
    import hmdem.dem.runs as runs

    def stop(*args, **kwargs):
        raise _Called(kwargs)

    monkeypatch.setattr(biaxial, "run_biaxial", stop)
    monkeypatch.setattr(runs, "permeability_sweep", stop)
    with pytest.raises(_Called) as call:
        main(["biaxial", "--contact-stiffness", "8.9e7", "--friction", "0.85", "--stiffness-ratio", "2",
              "--out", str(tmp_path / "bi"), "--quiet"])
    kwargs = call.value.args[0]
    assert (kwargs["k_n"], kwargs["friction"], kwargs["ks_over_kn"]) == (8.9e7, 0.85, 2.0)
    with pytest.raises(_Called) as call:
        main(["darcy", "--contact-stiffness", "8.9e7", "--out", str(tmp_path / "da"), "--quiet"])
    assert call.value.args[0]["k_n"] == 8.9e7
    assert list(tmp_path.iterdir()) == []


def test_interrupted_darcy_sweep_writes_the_stresses_done(tmp_path, monkeypatch, capsys):
    # Ctrl-C (or SIGTERM) during the third compaction: a valid run directory with the two
    # stresses done, the stored packing's row, status "interrupted", exit 130 (no compaction here)
    import hmdem.dem.runs as runs

    def two_then_ctrl_c(stresses, *args, progress, **kwargs):
        pk = DiscPacking.load(default_huang_packing_path())
        for k, stress in enumerate(stresses[:2]):
            res = runs.stored_permeability(pk)
            res.extra = {"target_stress": float(stress), "seconds": 0.0}
            progress(k, stress, res)
        raise KeyboardInterrupt

    monkeypatch.setattr(runs, "permeability_sweep", two_then_ctrl_c)
    out = tmp_path / "da"
    assert main(["darcy", "--stresses", "1e5,1.4e5,5e5", "--out", str(out), "--quiet"]) == 130
    assert "interrupted after 2 of 3 stresses" in capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and [r["target_stress"] for r in s["results"]] == [1e5, 1.4e5]
    assert s["sweep_permeability_at_paper_stress_m2"] == s["results"][1]["permeability"]
    assert len((out / "permeability.csv").read_text().splitlines()) == 4  # header, 2 stresses, stored packing
    assert (out / "permeability.png").stat().st_size > 0
    assert [p.name for p in tmp_path.iterdir()] == ["da"]


def _loading(max_strain, status):
    """A synthetic biaxial curve to ``max_strain``: q = 5e7 e - 1e9 e^2 [Pa] (its peak at 2.5 %),
    nu = 0.2, 100 samples per 1 % of axial strain."""
    import hmdem.dem.biaxial as biaxial

    n = int(round(1e4 * max_strain)) + 1
    ea = np.linspace(0.0, max_strain, n)
    res = biaxial.BiaxialResult(np.arange(n), 1e-6 * np.arange(n), ea, -0.2 * ea, 0.8 * ea,
                                1e5 + 5e7 * ea - 1e9 * ea**2, np.full(n, 1e5), sigma3_target=1e5, strain_rate=5.0,
                                fit_strain=biaxial.FIT_STRAIN, status=status,
                                interrupted_in="loading" if status == "interrupted" else None)
    res.derive_constants()
    return res


def test_interrupted_biaxial_writes_the_curve_so_far(tmp_path, monkeypatch, capsys):
    # a loading stopped at 0.4 % axial strain: E and nu (fitted below 0.1 %) are known, the rest
    # is of the curve so far; status "interrupted", exit 130, the curve in timeseries.csv
    import hmdem.dem.biaxial as biaxial

    monkeypatch.setattr(biaxial, "run_biaxial", lambda *args, **kwargs: _loading(0.004, "interrupted"))
    out = tmp_path / "bi"
    assert main(["biaxial", "--rate-check", "--out", str(out), "--quiet"]) == 130
    assert "interrupted in the loading at axial strain 0.400%" in capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and "rate_check" not in s  # no second loading after a stop
    assert s["interrupted_in"] == "loading"
    # least squares of q = 5e7 e - 1e9 e^2 over e uniform in [0, 0.001]: slope 5e7 - 1e9 x 0.001
    assert s["young_modulus_pa"] == pytest.approx(4.9e7, rel=1e-9) and s["poisson_ratio"] == pytest.approx(0.2)
    assert s["max_axial_strain"] == pytest.approx(0.004)
    assert len((out / "timeseries.csv").read_text().splitlines()) == 42


def test_biaxial_interrupted_in_the_compaction_writes_a_run_directory_without_a_curve(tmp_path, monkeypatch, capsys):
    # a new-user rule (Ctrl-C leaves a valid partial run directory): a stop in the compaction,
    # before any loading, wrote nothing at all; now the run directory holds the settings, an
    # empty curve and a picture, with status "interrupted", interrupted_in "compaction", exit 130
    import hmdem.dem.biaxial as biaxial

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(biaxial, "compact_sample", stopped)
    out = tmp_path / "bi"
    assert main(["biaxial", "--rate-check", "--out", str(out), "--quiet"]) == 130
    printed = capsys.readouterr()
    assert "interrupted in the compaction" in printed.err and "nan" not in printed.out
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["interrupted_in"] == "compaction" and "rate_check" not in s
    assert s["young_modulus_pa"] is None and s["max_axial_strain"] is None and s["n_grains"] == 1395
    assert s["k_n"] == biaxial.CONTACT_STIFFNESS and s["friction"] == 0.6
    assert (out / "timeseries.csv").read_text().splitlines() == [
        "cycles,time_s,axial_strain,lateral_strain,volumetric_strain,sigma1_pa,sigma3_pa,deviator_pa"]
    assert (out / "biaxial.png").stat().st_size > 0


def test_a_curve_stopped_inside_the_fit_window_gives_no_moduli(tmp_path, monkeypatch, capsys):
    # a new-user pass: stopped at 0.05 % axial strain (the fit window ends at 0.1 %), the console
    # printed "E = nan MPa (+nan% vs 65.4)"
    import hmdem.dem.biaxial as biaxial

    monkeypatch.setattr(biaxial, "run_biaxial", lambda *args, **kwargs: _loading(0.0005, "interrupted"))
    out = tmp_path / "bi"
    assert main(["biaxial", "--out", str(out), "--quiet"]) == 130
    printed = capsys.readouterr().out
    assert "E = n/a, nu = n/a" in printed and "nan MPa" not in printed and "nan%" not in printed
    s = json.loads((out / "summary.json").read_text())
    assert s["young_modulus_pa"] is None and s["poisson_ratio"] is None
    # the curve so far still has its largest sigma1, the 5-sample mean of its last samples:
    # q = 5e7 e - 1e9 e^2 at e = 1e-4 ... 5e-4 gives 4,990 ... 24,750 Pa, mean 14,890
    assert s["peak_sigma1_pa"] == pytest.approx(1e5 + 14_890, rel=1e-9)


def test_interrupted_rate_check_keeps_the_full_rate_test(tmp_path, monkeypatch, capsys):
    # the half-rate loading stopped at 0.4 %: the full-rate results stay whole, and the check
    # reports no peak change (a partial curve's peak is not the half-rate peak)
    import hmdem.dem.biaxial as biaxial

    full = _loading(0.025, "finished")
    full.packing = None
    monkeypatch.setattr(biaxial, "run_biaxial", lambda *args, **kwargs: full)
    monkeypatch.setattr(biaxial, "load_biaxial", lambda *args, **kwargs: _loading(0.004, "interrupted"))
    out = tmp_path / "bi"
    assert main(["biaxial", "--rate-check", "--out", str(out), "--quiet"]) == 130
    captured = capsys.readouterr()
    assert "interrupted in the half-rate check at axial strain 0.400%" in captured.err
    assert "peak sigma1 changes" not in captured.out
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["max_axial_strain"] == pytest.approx(0.025)
    assert s["peak_sigma1_pa"] == pytest.approx(full.peak_sigma1)
    assert s["rate_check"]["status"] == "interrupted" and s["rate_check"]["max_axial_strain"] == pytest.approx(0.004)
    assert s["interrupted_in"] == "rate check"
    assert "peak_relative_change" not in s["rate_check"]


def test_existing_run_directory_is_refused(tmp_path, capsys):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    assert main(["darcy", "--out", str(out)]) == 2
    assert capsys.readouterr().err.startswith("python -m hmdem.calibrate: --out: ")
    assert [p.name for p in tmp_path.iterdir()] == ["taken"] and [p.name for p in out.iterdir()] == ["keep.txt"]


def test_unreadable_packing_is_refused(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_text("not a packing")
    assert main(["darcy", "--packing", str(bad), "--out", str(tmp_path / "run")]) == 2
    assert capsys.readouterr().err.startswith("python -m hmdem.calibrate: --packing: ")
    assert [p.name for p in tmp_path.iterdir()] == ["bad.npz"]


# ------------------------------------------------------------------------------------ with YADE

@pytest.mark.yade
def test_yade_contact_forces_are_k_n_times_the_stored_overlaps():
    # digest §15.1: k_n = 7.49e7 N/m for any radius pair; after one step each contact of the
    # stored packing carries k_n x overlap, and near-contacts (gap > 0) carry nothing
    from hmdem.dem.runs import packing_contact_forces

    pk = DiscPacking.load(default_huang_packing_path())
    net = darcy_network(pk)
    force = packing_contact_forces(pk, net.pipe_grains)
    overlap = -contact_gaps(pk.centres, pk.radii, net.pipe_grains)
    touching = overlap > 0
    assert touching.sum() > 0.8 * net.n_pipes
    np.testing.assert_allclose(force[touching], 7.49e7 * overlap[touching], rtol=1e-6)
    assert np.all(force[overlap < -1e-12] == 0.0)


def test_darcy_contact_gap_its_sample_cannot_take_is_one_line_before_any_compaction(tmp_path, monkeypatch, capsys):
    # a new-user pass: --contact-gap 1 gave a traceback after the sweep's compactions; the stored
    # sample's network (144 contacts off its triangulation at that gap) is now built first
    import hmdem.dem.runs as runs

    def compaction(*args, **kwargs):
        raise AssertionError("the sweep started")

    monkeypatch.setattr(runs, "permeability_sweep", compaction)
    out = tmp_path / "darcy"
    assert main(["darcy", "--contact-gap", "1", "--out", str(out), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--contact-gap: at 1 " in lines[0] and not out.exists()


def test_darcy_sample_whose_network_fails_keeps_the_stresses_done(tmp_path, monkeypatch, capsys):
    # a compacted sample of the sweep whose near contacts leave its triangulation (review): the
    # stresses done are written with status "failed" and the reason, exit 1, not a traceback
    import hmdem.dem.runs as runs
    from hmdem.network.contact_graph import ContactsOffTriangulation

    def one_then_off(stresses, *args, progress, **kwargs):
        res = runs.stored_permeability(DiscPacking.load(default_huang_packing_path()))
        res.extra = {"target_stress": float(stresses[0]), "seconds": 0.0}
        progress(0, stresses[0], res)
        raise ContactsOffTriangulation("3 of its contacts (e.g. grains 1 and 2) are not edges")

    monkeypatch.setattr(runs, "permeability_sweep", one_then_off)
    out = tmp_path / "da"
    assert main(["darcy", "--stresses", "1e5,1.4e5", "--out", str(out), "--quiet"]) == 1
    assert "compacted to 0.14 MPa (--n 1395, --seed 0) has no network" in capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "3 of its contacts" in s["status_message"]
    assert [r["target_stress"] for r in s["results"]] == [1e5]


@pytest.mark.yade
def test_near_contact_gap_038_gives_the_papers_network_and_permeability():
    # decisions #73. Seed 004 §4.2: the Huang sample's network has 2,096 domains, 3,490 pipes and
    # 141 outflow domains, and k_Darcy = 7.43e-13 m^2 at 0.14 MPa. With pairs closer than 0.38 x
    # the smaller radius as pipes, the shipped packing's network has those counts (1 % for pipes
    # and domains, 3 % for the outflow ring: the spread over three packings; the gap was read off
    # the pipe count) and, independently, that permeability within H9's 5 %. The default 0.08 (the
    # Lenormand packing's) gives 3,047 pipes, 1,653 domains and a k 7 % higher.
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario, radial_network
    from hmdem.dem.runs import stored_permeability

    pk = DiscPacking.load(default_huang_packing_path())
    net = radial_network(pk, 0.38)
    assert net.n_pipes == pytest.approx(3490, rel=0.01)
    assert net.n_domains == pytest.approx(2096, rel=0.01)
    assert len(net.outlet_domains) == pytest.approx(141, rel=0.03)
    assert stored_permeability(pk, contact_gap=0.38).permeability == pytest.approx(7.43e-13, rel=0.05)
    # radial --contact-gap builds the coupled runs on that network and records the gap (config.toml)
    sc = build_radial_scenario(RADIAL_CASES["B3"], contact_gap=0.38)
    assert sc.net.n_pipes == net.n_pipes and sc.case.contact_gap == 0.38


@pytest.mark.yade
def test_darcy_sweep_permeability_falls_with_confining_stress():
    # a reduced sample (200 discs): from 0.1 to 2.1 MPa the porosity drops and the contact forces
    # rise ~20x, closing the Eq. 13 apertures; both lower k, so k must fall, as must KC
    from hmdem.dem.runs import permeability_sweep

    lo, hi = permeability_sweep((0.1e6, 2.1e6), n=200, size=0.47e-3)
    assert lo.confining_stress == pytest.approx(0.1e6, rel=0.01)
    assert hi.confining_stress == pytest.approx(2.1e6, rel=0.01)
    assert hi.porosity_2d < lo.porosity_2d
    assert hi.mean_contact_force > 10 * lo.mean_contact_force
    assert hi.permeability < 0.8 * lo.permeability
    assert hi.kozeny_carman < lo.kozeny_carman
    assert lo.balance_error < 1e-10 and hi.balance_error < 1e-10


@pytest.fixture(scope="module")
def small_biaxial():
    # 200 discs, Huang radii, compacted to 0.1 MPa, sheared at 20 /s to 2.5 % (~6 s); on the
    # full sample 20 /s and 10 /s give peaks within 1.5 % of each other
    from hmdem.dem.biaxial import run_biaxial

    return run_biaxial(n=200, strain_rate=20.0, seed=0)


@pytest.mark.yade
def test_biaxial_starts_isotropic_and_holds_sigma3(small_biaxial):
    res = small_biaxial
    # the rebuilt scene reproduces the compacted state: sigma1 = sigma3 = 0.1 MPa at the start
    # (compaction servo tolerance 0.5 %, plus one step of wall motion)
    assert res.sigma1[0] == pytest.approx(0.1e6, rel=0.02)
    assert res.sigma3[0] == pytest.approx(0.1e6, rel=0.02)
    # force-controlled side walls: every wall-force snapshot within 3 % of sigma3, the mean within 0.5 %
    assert res.max_sigma3_deviation < 0.03
    assert np.mean(res.sigma3) == pytest.approx(0.1e6, rel=0.005)
    assert np.all(np.diff(res.strain_axial) > 0) and res.strain_axial[-1] == pytest.approx(0.025, abs=5e-5)


@pytest.mark.yade
def test_biaxial_dense_sample_contracts_then_dilates(small_biaxial):
    # digest §2.3: a dense packing first contracts (eps_v > 0) then dilates past its start
    ev = small_biaxial.strain_volumetric
    k = int(np.argmax(ev))
    assert ev[k] > 1e-4 and small_biaxial.strain_axial[k] < 0.015
    assert ev[-1] < 0.0


@pytest.mark.yade
def test_biaxial_friction_angle_is_physical_and_comes_from_grain_friction(small_biaxial):
    # Bounds: rotating frictional discs (mu = 0.6, inter-particle angle 31 deg) mobilise a
    # macroscopic peak angle of roughly 20-35 deg in 2D DEM (the paper: 30.8); frictionless
    # discs only have geometric interlocking, well under 15 deg. So 20-40 deg with friction, and
    # removing the grain friction from the same sample must cost more than 10 deg.
    from hmdem.dem.biaxial import load_biaxial

    res = small_biaxial
    assert 20.0 < res.friction_angle < 40.0
    assert res.friction_angle == pytest.approx(
        math.degrees(math.asin((res.peak_sigma1 - res.sigma3_at_peak) / (res.peak_sigma1 + res.sigma3_at_peak))))
    smooth = load_biaxial(res.packing, strain_rate=20.0, friction=0.0)
    assert smooth.friction_angle < 15.0
    assert res.friction_angle - smooth.friction_angle > 10.0
    # elastic constants: positive, E below the contact stiffness scale, 2D nu in (0, 0.5)
    assert 0.1 * 7.49e7 < res.young_modulus < 7.49e7
    assert 0.0 < res.poisson_ratio < 0.5


@pytest.mark.yade
def test_interrupted_loading_keeps_the_curve_and_its_elastic_constants(small_biaxial):
    # Ctrl-C at 0.5 % axial strain (raised from the progress callback, inside the loading loop):
    # the same trajectory as the full test up to there, so the same E and nu (their fit window
    # ends at 0.1 %), and the scene is reset for the next test
    from hmdem.dem.biaxial import load_biaxial

    def ctrl_c_at(ea, s1, s3):
        if ea > 0.005:
            raise KeyboardInterrupt

    cut = load_biaxial(small_biaxial.packing, strain_rate=20.0, progress=ctrl_c_at)
    assert cut.status == "interrupted" and small_biaxial.status == "finished"
    assert cut.interrupted_in == "loading" and small_biaxial.interrupted_in is None
    assert 0.005 < cut.strain_axial[-1] < 0.01 and len(cut.sigma1) == len(cut.strain_lateral)
    assert cut.young_modulus == pytest.approx(small_biaxial.young_modulus, rel=1e-9)
    assert cut.poisson_ratio == pytest.approx(small_biaxial.poisson_ratio, rel=1e-9)
    from yade import O

    assert len(O.bodies) == 0


def test_compaction_keeps_an_existing_packing_unless_told(tmp_path, capsys):
    # a calibrated packing is minutes of work: an existing --out is refused before compacting
    # (make huang-packing passes --overwrite to regenerate the shipped file)
    from hmdem.dem.compaction import main as compaction_main

    (tmp_path / "calibrated.npz").write_bytes(b"keep")
    with pytest.raises(SystemExit) as exc:
        compaction_main(["--out", str(tmp_path / "calibrated.npz")])
    assert exc.value.code == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "calibrated.npz").read_bytes() == b"keep"


@pytest.mark.yade
def test_compaction_sigterm_is_one_line_exit_143_nothing_written(tmp_path):
    # a batch system's SIGTERM during compaction: no traceback, exit 128 + 15, no packing file
    code, err = sigterm_once_stderr_shows(["hmdem.dem.compaction", "--out", str(tmp_path / "pk.npz")], "cycles")
    assert code == 143
    assert err.rstrip().splitlines()[-1] == "python -m hmdem.dem.compaction: interrupted; the results in " \
                                            "progress were not written"
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


@pytest.mark.yade
def test_darcy_sigterm_writes_the_stresses_done_and_exits_143(tmp_path):
    # a batch system's SIGTERM after the first stress of a long sweep: exit 128 + 15 and a valid
    # run directory with the stresses finished
    out = tmp_path / "da"
    stresses = ",".join(f"{s:g}" for s in np.linspace(1e5, 2e6, 12))
    code, err = sigterm_once_stderr_shows(["hmdem.calibrate", "darcy", "--n", "300", "--stresses", stresses,
                                           "--out", str(out)], "[1/12]")
    assert code == 143, err[-2000:]
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and 1 <= len(s["results"]) < 12
    assert len((out / "permeability.csv").read_text().splitlines()) == len(s["results"]) + 2


@pytest.mark.yade
def test_calibrate_cli_writes_complete_run_directories(tmp_path):
    out = tmp_path / "bi"
    assert main(["biaxial", "--n", "100", "--strain-rate", "40", "--max-strain", "0.004", "--out", str(out),
                 "--quiet"]) == 0
    assert {p.name for p in out.iterdir()} == {"summary.json", "timeseries.csv", "biaxial.png"}
    s = json.loads((out / "summary.json").read_text())
    for key in ("young_modulus_pa", "poisson_ratio", "peak_sigma1_pa", "friction_angle_deg", "sigma3_pa"):
        assert math.isfinite(s[key])
        if key != "sigma3_pa":
            assert s["relative_errors"][key] == pytest.approx((s[key] - s["targets"][key]) / s["targets"][key])
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0].startswith("cycles,time_s,axial_strain") and len(rows) > 20

    out = tmp_path / "da"
    assert main(["darcy", "--n", "100", "--stresses", "1.4e5", "--out", str(out), "--quiet"]) == 0
    assert {p.name for p in out.iterdir()} == {"summary.json", "permeability.csv", "permeability.png"}
    s = json.loads((out / "summary.json").read_text())
    assert s["paper_permeability_m2"] == 7.43e-13 and len(s["results"]) == 1
    assert s["sweep_relative_error_vs_paper"] == pytest.approx(s["results"][0]["permeability"] / 7.43e-13 - 1)
    stored = s["stored_packing"]
    assert stored["relative_error_vs_paper"] == pytest.approx(stored["permeability"] / 7.43e-13 - 1)
    assert len((out / "permeability.csv").read_text().splitlines()) == 3  # header, sweep, stored packing
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial directory left


def test_compaction_bar_ends_on_the_last_report(capsys):
    # a new-user pass: the line is refreshed at most every 0.25 s, so calibrate darcy's bars
    # ended on a stale wall stress (~92 % of the target); closing shows the last report
    from hmdem.dem.compaction import CompactionBar

    bar = CompactionBar(every_s=3600.0)
    bar(10, np.array([1.0e3, 3.0e3]))  # shown: the first report
    bar(5000, np.array([139.0e3, 141.0e3]))  # throttled
    bar.close()
    err = capsys.readouterr().err
    last_line = err.rstrip().split("\r")[-1].splitlines()[-1]  # tqdm redraws with \r
    assert "5000 cycles" in last_line and last_line.endswith("wall stress 140.0 kPa")
