"""sph_bridge surface tension, wetting and sessile drops (issue 5; seed 000 §3.1, digest §5.1, §7 #7-10).

The physics tests run at dx = 5e-4 m with the calibrated parameters of
:mod:`sph_bridge.calibrations` (``make test``); the same at 2e-4 m is under ``make validate``.
"""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from sph_bridge import calibrations, checkpoint, droplet, young_laplace
from sph_bridge.kernel import INTERACTION_RANGE, interaction_shape, wendland_gradient_over_r
from sph_bridge.simulation import SphParameters

THETA = 65.16  # PMMA (seed 000 §4.1)
CI_DX = 5e-4


def test_capillary_length_puddle_height_and_cap_aspect():
    # digest §5.1 / §7 #7-9: lambda_c = 2.709 mm, 2 lambda_c sin(theta/2) = 2.918 mm (rho = 1000),
    # h/w = tan(theta/2)/2 = 0.3195; the +-2.5° band gives 2.817-3.017 mm and 0.304-0.335
    assert droplet.capillary_length(0.072, 1000.0, 9.81) == pytest.approx(2.709e-3, abs=5e-7)
    assert droplet.puddle_height(0.072, 1000.0, 9.81, THETA) == pytest.approx(2.918e-3, abs=5e-7)
    assert droplet.puddle_height(0.072, 1000.0, 9.81, THETA - 2.5) == pytest.approx(2.817e-3, abs=5e-7)
    assert droplet.puddle_height(0.072, 1000.0, 9.81, THETA + 2.5) == pytest.approx(3.017e-3, abs=5e-7)
    assert droplet.cap_aspect(THETA) == pytest.approx(0.3195, abs=5e-5)
    assert droplet.cap_aspect(THETA - 2.5) == pytest.approx(0.304, abs=5e-4)
    assert droplet.cap_aspect(THETA + 2.5) == pytest.approx(0.335, abs=5e-4)


def test_young_laplace_limits():
    # zero gravity: a hemisphere (half cylinder) of radius R at 90°; any cap has h/w = tan(theta/2)/2.
    # A ridge much wider than lambda_c has de Gennes' height (exponential approach); an
    # axisymmetric puddle overshoots it by ~lambda_c/(2a) (the azimuthal curvature of its rim)
    r = 1e-3
    assert young_laplace.sessile_height(2 / 3 * math.pi * r**3, 90.0, math.inf) == pytest.approx((r, 2 * r), rel=1e-9)
    assert young_laplace.sessile_height(math.pi * r**2 / 2, 90.0, math.inf, False) == pytest.approx((r, 2 * r), rel=1e-9)
    h, w = young_laplace.sessile_height(3e-9, THETA, math.inf)
    assert h / w == pytest.approx(droplet.cap_aspect(THETA), rel=1e-9)
    lam = droplet.capillary_length(0.072, 1000.0, 9.81)
    puddle = droplet.puddle_height(0.072, 1000.0, 9.81, THETA)
    wide_ridge, _ = young_laplace.sessile_height(12 * lam * puddle, THETA, lam, False)  # ~6 lambda_c half-width
    assert wide_ridge == pytest.approx(puddle, rel=2e-3)
    h8, w8 = young_laplace.sessile_height(math.pi * (8 * lam) ** 2 * puddle * 1.02, THETA, lam)
    assert 1.03 < h8 / puddle < 1.08 and w8 > 15 * lam


def test_starting_drop_holds_the_volume():
    # the lattice sites of the starting hemisphere / cylinder / half cylinder / slab hold the
    # requested volume to within their ragged edge
    dx = 1e-3
    for volume, ridge, top in ((2 / 3 * math.pi * (10 * dx) ** 3, False, math.inf), (4000 * dx**3, False, 6 * dx),
                               (4000 * dx**3, True, 5 * dx), (3000 * dx**3, True, math.inf)):
        sites = droplet.starting_drop(volume, dx, top, ridge)
        assert len(sites) * dx**3 == pytest.approx(volume, rel=0.06)
        assert sites[:, 2].min() == pytest.approx(dx / 2)
        if math.isfinite(top):
            assert sites[:, 2].max() <= top + dx / 2 + 1e-12


def test_start_height_caps_the_starting_drop():
    # droplet --start-height: a puddle started below its equilibrium (a receding contact line)
    # is a slab of that height holding the volume; by default it starts no taller than 2 lambda_c
    entry = calibrations.lookup(CI_DX, THETA)
    params = SphParameters(dx=CI_DX, c0=entry.c0, rho0_fluid=entry.rho0_fluid, s_ff=entry.s_ff, s_sf=entry.s_sf,
                           gravity=(0.0, 0.0, -9.81))
    for start, top in ((None, 2 * droplet.capillary_length(entry.surface_tension, entry.rho0_fluid, 9.81)),
                       (2.5e-3, 2.5e-3)):
        sim, _ = droplet.prepare_drop(params, 5.7e-7, entry.surface_tension, True, start)
        fluid = sim.pos[sim.fluid]
        assert top - CI_DX < fluid[:, 2].max() + CI_DX / 2 <= top + CI_DX
        assert len(fluid) * CI_DX**3 == pytest.approx(5.7e-7, rel=0.06)


@pytest.mark.parametrize("dx", [CI_DX, 2e-4])
def test_a_puddles_plate_holds_its_equilibrium_beyond_the_pairwise_range(dx):
    # decisions #62: the puddle test's contact line must come to rest where the plate still
    # reaches 2h beyond it (the pairwise force's range). The plate once reached 2 starting
    # widths: at 2e-4 m its edge lay 0.07 mm beyond the Young-Laplace equilibrium line
    from sph_bridge.kernel import INTERACTION_RANGE

    entry = calibrations.lookup(dx, THETA)
    params = SphParameters(dx=dx, c0=entry.c0, rho0_fluid=entry.rho0_fluid, s_ff=entry.s_ff, s_sf=entry.s_sf,
                           gravity=(0.0, 0.0, -9.81))
    lam = droplet.capillary_length(0.072, 1000.0, 9.81)
    volume = 8 * lam * 2.918e-3 * droplet.RIDGE_LENGTH * dx  # the puddle test's
    sim, _ = droplet.prepare_drop(params, volume, entry.surface_tension, True, None, THETA)
    # the fluid's volume from its particle count at the 1000 kg/m^3 its calibration gives the bulk
    fluid_area = sim.fluid.sum() * entry.rho0_fluid * dx**3 / 1000.0 / (droplet.RIDGE_LENGTH * dx)
    lam = droplet.capillary_length(entry.surface_tension, 1000.0, 9.81)
    plate_edge = sim.pos[~sim.fluid, 0].max() + dx / 2
    # with room to spread 10° flatter than the target (contact-angle offsets of ~2° are measured)
    for theta in (THETA, THETA - droplet.ROOM_BELOW_TARGET_DEG):
        _, width = young_laplace.sessile_height(fluid_area, theta, lam, False)
        assert plate_edge >= width / 2 + INTERACTION_RANGE * sim.h, theta


def test_a_round_puddles_plate_and_a_films():
    # plate_room for a round drop: the Young-Laplace radius 10° under the target plus 2h; at a
    # target angle whose puddle would be thinner than 2 dx, the radius of a 2 dx film
    lam, h, dx, volume = droplet.capillary_length(0.072, 1000.0, 9.81), 1.71e-3, 5e-4, 5e-6
    _, width = young_laplace.sessile_height(volume, THETA - 10.0, lam, True)
    assert droplet.plate_room(volume, False, THETA, lam, h, dx) == pytest.approx(width / 2 + 2 * h, rel=1e-9)
    film = math.sqrt(volume / (math.pi * 2 * dx))
    assert droplet.plate_room(volume, False, 2.0, lam, h, dx) == pytest.approx(film + 2 * h, rel=1e-12)


def test_pairwise_young_angle_errs_flat_of_the_calibrated_angles():
    # decisions #63: cos theta = 2 s_sf / s_ff - 1 (clipped), and at the shipped strengths it
    # is flatter than the angle measured, so a plate sized by it is wide enough
    young = droplet.pairwise_young_angle_deg
    assert young(1.0, 0.5) == pytest.approx(90.0) and young(1.0, 0.0) == pytest.approx(180.0)
    assert young(1.0, 1.0) == 0.0 and young(1.0, 1.5) == 0.0
    for entry in calibrations.TABLE.values():
        assert young(entry.s_ff, entry.s_sf) < entry.contact_angle_deg - 5.0


def test_plate_edge_clearance_counts_the_drops_drift():
    # the contact line's distance from the nearest edge: half-width - drift - half the base width
    params = SphParameters(dx=1e-3, c0=3.0, s_ff=4e-6, s_sf=3e-6, gravity=(0.0, 0.0, -9.81))
    shape = droplet.DropShape(3e-3, 6e-3, 60.0, 60.0, 4e-3, 0.0, 0.0)
    for ridge, shift in ((True, (3e-3, 5e-3, 0.0)), (False, (1e-3, -2e-3, 0.0))):
        sim = droplet.sessile(params, 6e-7, ridge=ridge, plate_radius=0.03)
        half = droplet.plate_half_width(sim)
        assert half == pytest.approx(0.03, abs=1e-12)  # a whole number of dx: the plate ends where asked
        drift = np.abs(sim.pos[sim.fluid, :2].mean(axis=0))
        sim.pos[sim.fluid] += shift
        moved = np.abs(sim.pos[sim.fluid, :2].mean(axis=0))
        expected = half - (moved[0] if ridge else moved.max()) - 3e-3  # a ridge's y is periodic: no edge
        assert droplet.plate_edge_clearance(sim, shape, ridge) == pytest.approx(expected, abs=1e-12)
        assert (drift[0] if ridge else drift.max()) < 1e-12 and expected < half - 3e-3 - 9e-4  # it did drift


def test_explicit_strengths_size_the_plate_for_their_young_angle(monkeypatch, tmp_path, capsys):
    # droplet --s-ff/--s-sf (no calibration): the plate holds the Young angle of the strengths
    # where that is flatter than --theta, and summary.json says so (decisions #63); a short
    # relaxation of a coarse ridge, the protocol shortened only to be quick
    import signal

    from sph_bridge import __main__ as cli

    monkeypatch.setattr(signal, "signal", lambda *args: None)
    for name, value in (("SAMPLES", 8), ("SETTLE_WINDOW", 2), ("MAX_EXTENSION", 2)):
        monkeypatch.setattr(droplet, name, value)
    short = droplet.relaxation
    monkeypatch.setattr(droplet, "relaxation", lambda *a: (short(*a)[0], 4e-3))
    params = SphParameters(dx=1e-3, c0=3.0, s_ff=4e-6, s_sf=3.6e-6, gravity=(0.0, 0.0, -9.81))

    def plate_edge(theta):
        sim, _ = droplet.prepare_drop(params, 2e-6, droplet.SURFACE_TENSION, True, None, theta)
        return float(np.abs(sim.pos[~sim.fluid, 0]).max()) + params.dx / 2

    young = droplet.pairwise_young_angle_deg(4e-6, 3.6e-6)  # 36.9°
    assert plate_edge(young) > plate_edge(THETA)  # the target's plate would be too small for them
    for name, extra, sized_for in (("default target", [], young), ("flatter target", ["--theta", "20"], 20.0)):
        args = ["droplet", "--dx", "1e-3", "--volume", "2e-6", "--ridge", "--s-ff", "4e-6", "--s-sf", "3.6e-6",
                "--c0", "3", "--quiet", "--out", str(tmp_path / name), *extra]
        assert cli.main(args) == 0
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        assert summary["plate_sized_for_deg"] == pytest.approx(sized_for)
        assert summary["plate_half_width_m"] == pytest.approx(plate_edge(sized_for), abs=1e-12)
        # less the drop's drift off the axis, under 0.1 dx in this short relaxation
        assert summary["plate_edge_clearance_m"] == pytest.approx(summary["plate_half_width_m"] - summary["width_m"] / 2,
                                                                  abs=1e-4)
    assert "warning" not in capsys.readouterr().err
    # a contact line within 2h of the edge is reported (here a plate made to end at the axis)
    monkeypatch.setattr(droplet, "plate_half_width", lambda sim: 0.0)
    assert cli.main(args[:-4] + ["--out", str(tmp_path / "edge")]) == 0
    assert "warning: the contact line ended" in capsys.readouterr().err


def test_slab_surface_tension_sums_every_pair_once():
    # the numba virial against a direct double sum over the pairs of a small jittered slab
    from sph_bridge.tension import slab, surface_tension

    params = SphParameters(dx=1e-3, c0=2.0, s_ff=3e-6, gravity=(0.0, 0.0, 0.0))
    sim = slab(params, side=18, layers=6, seed=3)
    pos, m, rho, p, h = sim.pos, sim.mass, sim.rho, sim.pressure, sim.h
    length = sim.grid.length
    total = 0.0
    for i in range(len(pos)):
        d = pos[i] - pos[i + 1:]
        d[:, :2] -= length[:2] * np.round(d[:, :2] / length[:2])  # nearest periodic image
        r = np.linalg.norm(d, axis=1)
        for k in np.flatnonzero(r < INTERACTION_RANGE * h):
            j = i + 1 + k
            f = params.s_ff * interaction_shape(r[k], h) / r[k]
            if r[k] < h:
                f -= m[i] * m[j] * (p[i] / rho[i] ** 2 + p[j] / rho[j] ** 2) * wendland_gradient_over_r(r[k], h)
            total += f * (d[k, 2] ** 2 - 0.5 * (d[k, 0] ** 2 + d[k, 1] ** 2))
    assert surface_tension(sim) == pytest.approx(total / (2 * length[0] * length[1]), rel=1e-10)


def calibrated(dx):
    entry = calibrations.lookup(dx, THETA)
    assert entry is not None, f"no calibration at dx = {dx}"
    return entry


@pytest.mark.parametrize("dx", [CI_DX, pytest.param(2e-4, marks=pytest.mark.slow)])
def test_calibrated_slab_has_water_surface_tension_and_density(dx):
    # the stored calibration reproduces its targets: sigma = 0.072 N/m within the calibration's
    # 1 % and the bulk at 1000 kg/m^3 within 0.5 % (decisions #36); `calibrate`'s bar is told the
    # slab's duration (SLAB_PERIODS acoustic periods of its thickness) and follows every step to it
    from sph_bridge.calibrate import DENSITY_TOLERANCE, SIGMA_TOLERANCE, SLAB_PERIODS, slab_tension
    from sph_bridge.tension import SLAB_LAYERS

    entry = calibrated(dx)
    bars, times = [], []

    def progress(label, duration, extend):
        bars.append((label, duration, extend))
        return lambda sim: times.append(sim.t)

    sigma, bulk, steps = slab_tension(SphParameters(dx=dx, c0=entry.c0, rho0_fluid=entry.rho0_fluid, s_ff=entry.s_ff),
                                      progress)
    assert sigma == pytest.approx(0.072, rel=SIGMA_TOLERANCE)
    assert bulk == pytest.approx(1000.0, rel=DENSITY_TOLERANCE)
    duration = SLAB_PERIODS * 2 * SLAB_LAYERS * dx / entry.c0
    assert bars == [("slab", pytest.approx(duration, rel=1e-12), 0.0)]
    assert len(times) == steps and times[-1] == pytest.approx(duration, rel=1e-9)


def run_droplet(tmp_path, name, *args):
    out = tmp_path / name
    proc = subprocess.run([sys.executable, "-m", "sph_bridge", "droplet", "--out", str(out), "--quiet", *args],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out, json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module", params=[CI_DX, pytest.param(2e-4, marks=pytest.mark.slow)])
def small_ridge(request, tmp_path_factory):
    """A ridge at zero gravity (Bond number 0: "small" at any size) of another size than the
    calibration's (8 against 10 dx), a ridge because the calibration reads its angle on one
    (decisions #39)."""
    dx = request.param
    volume = droplet.ridge_volume(8, dx)
    out, s = run_droplet(tmp_path_factory.mktemp("cap"), "cap", "--dx", str(dx), "--gravity", "0", "--ridge",
                         "--volume", str(volume))
    return dx, out, s


def test_small_drop_has_the_calibrated_angle(small_ridge):
    # the issue's +-3° of the calibrated target, on a drop size the calibration did not see
    dx, out, s = small_ridge
    assert s["settled"]
    assert abs(s["contact_angle_deg"] - THETA) <= 3.0
    assert {"config.toml", "summary.json", "timeseries.csv", "particles.pvd", "particles.vtu",
            "side_view.png"} <= {p.name for p in out.iterdir()}


def test_drop_at_rest_along_the_wall(small_ridge):
    # decisions #37: with the fluid's own pressure clamped at walls the lowest 4 dx kept
    # 0.08-0.1 m/s rms under the relaxation's damping; with the fluid's own term unclamped it
    # decays with the rest of the drop (0.0016 and 0.0020 m/s at the end at 5e-4 and 2e-4 m damped,
    # 0.0014 and 0.0018 annealed; BENCHMARKS.md). Bound: a tenth of the clamp's circulation
    dx, out, s = small_ridge
    assert s["near_wall_rms_speed_m_per_s"] <= 0.01


def test_small_drop_aspect_is_the_caps(small_ridge):
    # h/w within the +-2.5° band of tan(theta/2)/2 (digest §5.1: 0.304-0.335). Measured with the
    # annealed calibrations (decisions #60, #61): 0.3141 at 5e-4 m, 0.3120 at 2e-4 m (damped,
    # 2e-4 m had read 0.3356, just over the band)
    dx, out, s = small_ridge
    assert droplet.cap_aspect(THETA - 2.5) <= s["aspect"] <= droplet.cap_aspect(THETA + 2.5)


@pytest.mark.parametrize("dx", [CI_DX, pytest.param(2e-4, marks=pytest.mark.slow)])
def test_wide_puddle_has_de_gennes_height(tmp_path, dx):
    # a ridge 8 lambda_c wide under gravity settles at 2 lambda_c sin(theta/2) = 2.918 mm within
    # the +-2.5° band 2.82-3.02 mm (digest §5.1, §7 #8); a ridge rather than a round puddle,
    # which even at a base radius of 8 lambda_c stands 6 % above that limit (Young-Laplace).
    # At 5e-4 m it needs the annealed relaxation: damped alone its advancing line stopped at
    # 3.027 mm, over the band (decisions #57, #60)
    lam = droplet.capillary_length(0.072, 1000.0, 9.81)
    volume = 8 * lam * 2.918e-3 * droplet.RIDGE_LENGTH * dx
    out, s = run_droplet(tmp_path, "puddle", "--dx", str(dx), "--ridge", "--volume", str(volume))
    assert s["width_m"] > 6 * lam
    assert s["settled"]
    assert 2.817e-3 <= s["height_m"] <= 3.017e-3


def test_an_annealed_relaxation_settles_only_after_its_kicks(monkeypatch):
    # decisions #60: a shape steady under the kicks is not settled; the two quarter-windows the
    # settle check compares both lie after the kicks end (ANNEAL_FRACTION t_min), while a
    # damped relaxation of the same steady shape stops at its minimum duration
    from types import SimpleNamespace

    class Clock:  # a stand-in simulation whose shape never changes
        def __init__(self, anneal):
            self.t, self.anneal_end, self.params = 0.0, 0.0, SimpleNamespace(anneal=anneal)

        def run(self, t_end, record_every=None, progress=None):
            self.t = t_end

        def state_row(self):
            return (self.t, 0.0, 0.0)

    monkeypatch.setattr(droplet, "measure", lambda sim, ridge: droplet.DropShape(*[1e-3] * 7))
    t_min, window = 1.0, droplet.SAMPLES // 4
    for anneal, stop in ((0.0, t_min), (0.3, droplet.ANNEAL_FRACTION * t_min + 2 * window * t_min / droplet.SAMPLES)):
        sim, rows = Clock(anneal), []
        shape, settled = droplet.relax(sim, t_min, rows=rows)
        assert settled and sim.t == pytest.approx(stop)
        assert sim.anneal_end == (droplet.ANNEAL_FRACTION * t_min if anneal else 0.0)


def test_a_killed_droplet_goes_on_from_its_checkpoint_to_the_straight_runs_result(monkeypatch, tmp_path, capsys):
    # droplet --checkpoint DIR: a run stopped after 3 of its shape samples and given the same
    # command again ends, bit for bit, where a run that was never stopped does: the same samples,
    # settle check, steps, final particles, frames and annealing kicks (a short annealed
    # relaxation of a coarse drop whose kicks end at its 2nd sample and whose settle check runs
    # from its 8th; the shortened protocol only makes it quick)
    import signal

    import meshio

    from sph_bridge import __main__ as cli

    monkeypatch.setattr(signal, "signal", lambda *args: None)  # the CLI's SIGTERM handler stays out of pytest
    for name, value in (("SAMPLES", 8), ("SETTLE_WINDOW", 2), ("MAX_EXTENSION", 2), ("ANNEAL_FRACTION", 0.25)):
        monkeypatch.setattr(droplet, name, value)
    short = droplet.relaxation
    monkeypatch.setattr(droplet, "relaxation", lambda *a: (short(*a)[0], 4e-3))
    args = ["droplet", "--dx", "1e-3", "--volume", "6e-7", "--gravity", "0", "--s-ff", "4e-6", "--s-sf", "3e-6",
            "--c0", "3", "--anneal", "0.2", "--seed", "7", "--quiet"]
    ck = str(tmp_path / "ck")

    def run(name, *extra):
        return cli.main(args + ["--out", str(tmp_path / name), *extra])

    measure, calls = droplet.measure, []

    def counted(sim, ridge):
        calls.append(sim.t)
        if len(calls) == stop_at:
            with pytest.raises(checkpoint.CheckpointError, match="being written"):
                checkpoint.hold(ck)  # the running droplet holds its checkpoint
            raise KeyboardInterrupt
        return measure(sim, ridge)

    monkeypatch.setattr(droplet, "measure", counted)
    stop_at = 0
    assert run("straight") == 0
    samples = len(calls)
    assert samples > droplet.minimum_samples(True) == 8  # the settle check ran
    calls.clear()
    stop_at = 4
    assert run("stopped", "--checkpoint", ck) == 130
    progress = json.loads((tmp_path / "ck" / "progress.json").read_text())  # how far it got, for a look
    stopped = json.loads((tmp_path / "stopped" / "summary.json").read_text())
    assert progress["shape_samples"] == 3 and 0 < progress["steps"] <= stopped["steps"]
    assert progress["simulated_time_s"] <= stopped["simulated_time_s"] and progress["height_m"] > 0
    calls.clear()
    stop_at = 0
    capsys.readouterr()
    assert run("resumed", "--checkpoint", ck) == 0
    assert "resuming" in capsys.readouterr().err and len(calls) == samples - 3  # from its 3rd sample on
    calls.clear()
    assert run("again", "--checkpoint", ck) == 0 and not calls  # a finished checkpoint: nothing left to run
    summaries = {n: json.loads((tmp_path / n / "summary.json").read_text())
                 for n in ("straight", "stopped", "resumed", "again")}
    assert summaries["stopped"]["status"] == "interrupted"
    assert 0 < summaries["stopped"]["steps"] < summaries["straight"]["steps"]
    for n in ("resumed", "again"):
        for k in ("steps", "simulated_time_s", "height_m", "width_m", "contact_angle_deg", "final_kinetic_energy_j",
                  "settled"):
            assert summaries[n][k] == summaries["straight"][k], (n, k)
        assert (tmp_path / n / "timeseries.csv").read_text() == (tmp_path / "straight" / "timeseries.csv").read_text()
        names = sorted(p.name for p in (tmp_path / n).glob("particles*.vtu"))
        assert names == sorted(p.name for p in (tmp_path / "straight").glob("particles*.vtu")) and len(names) >= 3
        for name in names:
            assert np.array_equal(meshio.read(tmp_path / n / name).points, meshio.read(tmp_path / "straight" / name).points)
    # a checkpoint belongs to its drop, and a directory of other files is no checkpoint: refused, nothing written
    other = args[:4] + ["7e-7"] + args[5:]
    for command, directory in ((other, ck), (args, str(tmp_path / "straight"))):
        assert cli.main(command + ["--out", str(tmp_path / "other"), "--checkpoint", directory]) == 2
        assert not (tmp_path / "other").exists()
    # a checkpoint another run is still writing is refused: two runs would write one trajectory twice
    held = checkpoint.hold(ck)
    try:
        capsys.readouterr()
        assert cli.main(args + ["--out", str(tmp_path / "other"), "--checkpoint", ck]) == 2
        assert f"pid {os.getpid()}" in capsys.readouterr().err and not (tmp_path / "other").exists()
    finally:
        held.close()


def test_a_droplet_stopped_before_its_first_sample_still_has_a_frame(monkeypatch, tmp_path):
    # Ctrl-C leaves a valid partial run directory: the ParaView series ends with the state the
    # run stopped in, even when no sample was taken (it used to be an empty particles.pvd)
    import signal
    import xml.etree.ElementTree as ET

    import meshio

    from sph_bridge import __main__ as cli

    monkeypatch.setattr(signal, "signal", lambda *args: None)  # the CLI's SIGTERM handler stays out of pytest
    measure, calls = droplet.measure, []

    def stopped_at_first_sample(sim, ridge):
        calls.append(sim.t)
        if len(calls) == 1:
            raise KeyboardInterrupt
        return measure(sim, ridge)

    monkeypatch.setattr(droplet, "measure", stopped_at_first_sample)
    out = tmp_path / "stopped"
    assert cli.main(["droplet", "--dx", "1e-3", "--volume", "6e-7", "--gravity", "0", "--s-ff", "4e-6",
                     "--s-sf", "3e-6", "--c0", "3", "--quiet", "--out", str(out)]) == 130
    summary = json.loads((out / "summary.json").read_text())
    datasets = ET.parse(out / "particles.pvd").getroot().findall("./Collection/DataSet")
    assert summary["status"] == "interrupted" and len(datasets) == 1
    assert float(datasets[0].get("timestep")) == pytest.approx(summary["simulated_time_s"])
    frame = meshio.read(out / datasets[0].get("file"))
    assert np.array_equal(frame.points, meshio.read(out / "particles.vtu").points)


def test_droplet_bad_input_is_one_line(tmp_path):
    cmd = [sys.executable, "-m", "sph_bridge"]
    for args, name in ((["droplet", "--theta", "190"], "--theta"), (["droplet", "--volume", "1e-9"], "--volume"),
                       (["droplet", "--theta", "40"], "--theta"), (["droplet", "--s-ff", "1e-6"], "--s-sf"),
                       (["calibrate", "--dx", "0"], "--dx"), (["droplet", "--gravity", "-1"], "--gravity"),
                       (["calibrate", "--ridge-sizes", "5"], "--ridge-sizes"),
                       (["droplet", "--start-height", "1e-3"], "--start-height"),
                       (["droplet", "--anneal", "-0.1"], "--anneal"), (["calibrate", "--anneal", "-1"], "--anneal"),
                       (["droplet", "--anneal", "0.1"], "--anneal"),
                       # a new-user pass (decisions #84): a 2e-152 m puddle ran on at overflow, 20 min past SIGTERM
                       (["droplet", "--gravity", "1e300"], "--gravity"),
                       # dx^3 underflowed to a division by zero; 1e300 m^3 failed building its block
                       (["droplet", "--dx", "1e-300"], "--dx"), (["droplet", "--volume", "1e300"], "--volume"),
                       (["hydrostatic", "--layers", "100000000"], "--layers"),
                       # a new-user pass: c0^2 and the forces' squares overflowed to a NaN drop, which
                       # a SIGTERM then turned into a traceback with no run directory
                       (["droplet", "--s-ff", "1e-6", "--s-sf", "1e-6", "--c0", "1e300"], "--c0"),
                       (["calibrate", "--c0", "1e300"], "--c0"),
                       (["droplet", "--s-ff", "1e300", "--s-sf", "1e-6"], "--s-ff"),
                       (["droplet", "--s-ff", "1e-6", "--s-sf", "1e300"], "--s-sf")):
        bad = tmp_path / "bad"
        proc = subprocess.run(cmd + args + ["--out", str(bad)], capture_output=True, text=True)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1 and name in lines[0], (args, proc.stderr)
        assert not bad.exists()
    # an interrupted calibration has no strengths: said so, not float(None)'s TypeError (a new-user pass)
    interrupted = tmp_path / "cal"
    interrupted.mkdir()
    (interrupted / "summary.json").write_text('{"status": "interrupted", "s_ff_n": null, "dx_m": 0.0005}')
    proc = subprocess.run(cmd + ["droplet", "--calibration", str(interrupted), "--out", str(tmp_path / "bad")],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.strip() == (
        f"python -m sph_bridge: --calibration: {str(interrupted)!r} is not a finished calibrate run directory "
        "(ValueError: its status is 'interrupted')")
    # a new-user pass: the first two ended in AttributeError and TypeError tracebacks; the third
    # holds a c0 that --c0 refuses (it overflowed)
    finished = ('{"status": "finished", "dx_m": 0.0005, "c0_m_per_s": %s, "rho0_fluid": 1000, "s_ff_n": 1e-6, '
                '"s_sf_n": 7e-7, "surface_tension_n_per_m": 0.072, "target_contact_angle_deg": 65.16, '
                '"anneal_m_per_s": %s}')
    for text in ('[1, 2]', finished % ("1.5", "null"), finished % ("1e300", "0.3")):
        (interrupted / "summary.json").write_text(text)
        proc = subprocess.run(cmd + ["droplet", "--calibration", str(interrupted), "--out", str(tmp_path / "bad")],
                              capture_output=True, text=True)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1, proc.stderr
        assert lines[0].startswith(f"python -m sph_bridge: --calibration: {str(interrupted)!r} is not a finished ")
        assert not (tmp_path / "bad").exists()


def test_a_drop_of_exactly_the_smallest_size_is_allowed(tmp_path, monkeypatch):
    # a new-user pass: 5e-8 m^3 at dx = 5e-4 m is 399.99999999999994 cells in floating point, and
    # was refused as "400 particles ... from 400 to 10,000,000 are allowed"
    from sph_bridge import __main__ as cli

    class PassedTheVolumeCheck(Exception):
        pass

    def stop(args):
        raise PassedTheVolumeCheck

    assert 5e-8 / 5e-4**3 < cli.MIN_DROP_CELLS
    monkeypatch.setattr(cli, "droplet_parameters", stop)  # what the command does next
    with pytest.raises(PassedTheVolumeCheck):
        cli.main(["droplet", "--gravity", "0", "--volume", "5e-8", "--quiet", "--out", str(tmp_path / "d")])


def stand_in_calibration_trials(monkeypatch, measured=None):
    """Stand-in slab and ridge responses shaped like the measured ones: sigma ~ s_ff^1.5 with the
    bulk compressed by cohesion (1.054 rho0 at s_ff = 1e-6 N), and cos(theta) linear in s_sf.
    Each call is passed to ``measured`` first, if given."""
    import signal

    from sph_bridge import calibrate as cal_mod

    def slab(params, progress=None):
        if measured is not None:
            measured("tension")
        sigma = 0.0742 * (params.s_ff / 1e-6) ** 1.55 * (params.rho0_fluid / 1000.0) ** 2
        return sigma, params.rho0_fluid * (1.0 + 0.054 * params.s_ff / 1e-6), 843

    def drop(params, sigma, progress=None, radius_cells=cal_mod.DROP_RADIUS_CELLS):
        if measured is not None:
            measured("contact_angle")
        cos_theta = min(1.0, -1.0 + 1.9 * params.s_sf / params.s_ff)
        theta = math.degrees(math.acos(cos_theta))
        return droplet.DropShape(1e-3, 3e-3, theta, theta, 2e-3, 0.0, 1e-5), 3500, True

    monkeypatch.setattr(signal, "signal", lambda *args: None)  # the CLI's SIGTERM handler stays out of pytest
    monkeypatch.setattr(cal_mod, "slab_tension", slab)
    monkeypatch.setattr(cal_mod, "zero_gravity_drop", drop)


def test_calibration_search_converges_on_model_responses(monkeypatch, tmp_path):
    # the search logic on stand-in responses shaped like the measured ones: sigma ~ s_ff^1.5
    # with the bulk compressed by cohesion (1.054 rho0 at s_ff = 1e-6 N), and cos(theta) linear
    # in s_sf; the command writes its run directory with the found values and every trial
    from sph_bridge import __main__ as cli
    from sph_bridge import calibrate as cal_mod

    stand_in_calibration_trials(monkeypatch)
    trials = []
    cal = cal_mod.calibrate(5e-4, THETA, report=trials.append)
    assert cal.surface_tension == pytest.approx(0.072, rel=cal_mod.SIGMA_TOLERANCE)
    assert cal.rho0_fluid * (1.0 + 0.054 * cal.s_ff / 1e-6) == pytest.approx(1000.0, rel=cal_mod.DENSITY_TOLERANCE)
    assert abs(cal.contact_angle_deg - THETA) <= cal_mod.ANGLE_TOLERANCE_DEG
    assert len(trials) <= 8 and cal.c0 == 1.5  # Table 1 at 5e-4 m
    out = tmp_path / "cal"
    assert cli.main(["calibrate", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["s_ff_n"] == pytest.approx(cal.s_ff)
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert len(rows) == summary["trials"] + 1 and rows[0].startswith("stage,")


def test_a_killed_calibration_goes_on_from_its_checkpoint_to_the_straight_runs_result(monkeypatch, tmp_path,
                                                                                       capsys):
    # calibrate --checkpoint DIR: the trials are saved as they finish; a run stopped during its
    # 4th trial and given the same command again takes the 3 saved ones as measured, runs only the
    # rest and finds what a run never stopped finds, trial for trial (stand-in responses)
    from sph_bridge import __main__ as cli

    calls, stop_at = [], 0

    def measured(stage):
        calls.append(stage)
        if len(calls) == stop_at:
            raise KeyboardInterrupt

    stand_in_calibration_trials(monkeypatch, measured)
    ck = tmp_path / "ck"

    def run(name, *extra):
        return cli.main(["calibrate", "--quiet", "--out", str(tmp_path / name), *extra])

    assert run("straight") == 0
    straight = len(calls)
    assert straight >= 5 and {"tension", "contact_angle"} == set(calls)
    calls.clear()
    stop_at = 4
    assert run("stopped", "--checkpoint", str(ck)) == 130
    assert len(json.loads((ck / "trials.json").read_text())["trials"]) == 3
    calls.clear()
    stop_at = 0
    capsys.readouterr()
    assert run("resumed", "--checkpoint", str(ck)) == 0
    assert "took the 3 trials" in capsys.readouterr().err and len(calls) == straight - 3
    calls.clear()
    assert run("again", "--checkpoint", str(ck)) == 0 and not calls  # finished: nothing left to run
    summaries = {n: json.loads((tmp_path / n / "summary.json").read_text()) for n in ("straight", "resumed", "again")}
    for n in ("resumed", "again"):
        for k in ("status", "s_ff_n", "s_sf_n", "rho0_fluid", "surface_tension_n_per_m", "contact_angle_deg",
                  "trials", "steps"):
            assert summaries[n][k] == summaries["straight"][k], (n, k)
        assert (tmp_path / n / "timeseries.csv").read_text() == (tmp_path / "straight" / "timeseries.csv").read_text()
    assert summaries["resumed"]["replayed_trials"] == 3 and summaries["straight"]["replayed_trials"] == 0
    # another calibration's checkpoint, or a droplet's, is refused: one line, exit 2, nothing written
    (tmp_path / "drop").mkdir()
    (tmp_path / "drop" / "state.npz").write_bytes(b"")
    saved = json.loads((ck / "trials.json").read_text())
    for name, edit in (("moved", lambda t: t[1].update(s_ff=t[1]["s_ff"] * 1.01)),  # trials another search made
                       ("longer", lambda t: t.append(dict(t[-1])))):  # one that went on further
        changed = json.loads(json.dumps(saved))
        edit(changed["trials"])
        (tmp_path / name).mkdir()
        (tmp_path / name / "trials.json").write_text(json.dumps(changed))
    for extra, says in ((["--theta", "60", "--checkpoint", str(ck)], "theta_deg 65.16 (now 60.0)"),
                        (["--checkpoint", str(tmp_path / "drop")], "no trials.json"),
                        (["--checkpoint", str(tmp_path / "moved")], "its trial 2 (tension"),
                        (["--checkpoint", str(tmp_path / "longer")], "ended after")):
        capsys.readouterr()
        assert run("other", *extra) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--checkpoint" in err[0] and says in err[0], err
        assert not (tmp_path / "other").exists()
    # the Python API refuses replayed trials its search ends before, as the command does
    from sph_bridge import calibrate as cal_mod

    found = cal_mod.calibrate(5e-4, 65.16)
    with pytest.raises(cal_mod.ReplayMismatch, match="ended after"):
        cal_mod.calibrate(5e-4, 65.16, replay=found.trials + found.trials[-1:])
    assert len(cal_mod.calibrate(5e-4, 65.16, replay=found.trials).trials) == len(found.trials)
    # and so is one saved under another protocol (a constant its trials depend on changed)
    monkeypatch.setattr(cal_mod, "SLAB_PERIODS", cal_mod.SLAB_PERIODS + 1)
    capsys.readouterr()
    assert run("other", "--checkpoint", str(ck)) == 2
    assert "protocol.calibrate.SLAB_PERIODS" in capsys.readouterr().err and not (tmp_path / "other").exists()


def test_a_calibration_that_found_no_cap_resumes_to_the_same_end(monkeypatch, tmp_path):
    # a ridge with no readable cap (NaN angle) ends the search not converged; its checkpoint,
    # NaN included, is replayed to the same end
    from sph_bridge import __main__ as cli
    from sph_bridge import calibrate as cal_mod

    stand_in_calibration_trials(monkeypatch)
    monkeypatch.setattr(cal_mod, "zero_gravity_drop", lambda *a, **k: (droplet.DropShape(*[math.nan] * 7), 10, True))
    ends = []
    for name in ("first", "again"):
        out = tmp_path / name
        assert cli.main(["calibrate", "--quiet", "--out", str(out), "--checkpoint", str(tmp_path / "ck")]) == 1
        ends.append(json.loads((out / "summary.json").read_text()))
        assert (out / "timeseries.csv").read_text().splitlines()[-1].endswith(",nan,0")  # angle; ridges unsettled
    assert ends[0]["status"] == ends[1]["status"] == "not_converged" and "no measurable cap" in ends[1]["error"]
    assert ends[1]["replayed_trials"] == ends[0]["trials"] == ends[1]["trials"]


def test_a_calibration_whose_ridge_did_not_settle_says_so(monkeypatch, tmp_path, capsys):
    # left from earlier sessions: a contact-angle trial took its ridge's angle whether or not the
    # ridge had settled, and a calibration from a ridge still moving read as sound
    from sph_bridge import __main__ as cli
    from sph_bridge import calibrate as cal_mod

    stand_in_calibration_trials(monkeypatch)
    settled_drop = cal_mod.zero_gravity_drop
    monkeypatch.setattr(cal_mod, "zero_gravity_drop", lambda *a, **k: (*settled_drop(*a, **k)[:2], False))
    out = tmp_path / "cal"
    assert cli.main(["calibrate", "--quiet", "--out", str(out), "--checkpoint", str(tmp_path / "ck")]) == 0
    assert "1 of the last trial's 1 ridge(s) had not settled" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["ridges_settled"] is False
    # trials saved before the count was kept replay as unknown, not as settled
    saved = json.loads((tmp_path / "ck" / "trials.json").read_text())
    for t in saved["trials"]:
        del t["ridges_unsettled"]
    (tmp_path / "ck" / "trials.json").write_text(json.dumps(saved))
    assert cli.main(["calibrate", "--quiet", "--out", str(tmp_path / "again"), "--checkpoint",
                     str(tmp_path / "ck")]) == 0
    assert json.loads((tmp_path / "again" / "summary.json").read_text())["ridges_settled"] is None


def test_calibration_sets_the_mean_angle_of_several_ridges(monkeypatch):
    # decisions #39: with --ridge-sizes the angle stage calibrates the mean cap angle of ridges
    # of several sizes; stand-in ridges read Young's angle plus a size offset (+3.5° at 8 dx,
    # +1.5° at 12 dx, as scattered as the measured ones), so the mean sits 2.5° above Young's,
    # beyond the angle tolerance: the first trial (Young's law) misses and the secant corrects
    from sph_bridge import calibrate as cal_mod

    offsets = {8: 3.5, 12: 1.5}
    asked = []

    def drop(params, sigma, progress=None, radius_cells=cal_mod.DROP_RADIUS_CELLS):
        asked.append(radius_cells)
        theta = math.degrees(math.acos(min(1.0, -1.0 + 2.0 * params.s_sf / params.s_ff))) + offsets[radius_cells]
        return droplet.DropShape(1e-3, 3e-3, theta, theta, 2e-3, 0.0, 1e-5), 100, True

    monkeypatch.setattr(cal_mod, "slab_tension", lambda params, progress=None: (0.072, 1000.0, 10))
    monkeypatch.setattr(cal_mod, "zero_gravity_drop", drop)
    cal = cal_mod.calibrate(5e-4, THETA, cal=cal_mod.Calibration(dx=5e-4, c0=1.5), ridge_sizes=(8, 12))
    angles = [t for t in cal.trials if t.stage == "contact_angle"]
    assert len(angles) >= 2 and asked == [8, 12] * len(angles) and angles[-1].steps == 200
    assert abs(cal.contact_angle_deg - THETA) <= cal_mod.ANGLE_TOLERANCE_DEG
    young = math.degrees(math.acos(-1.0 + 2.0 * cal.s_sf / cal.s_ff))
    assert cal.contact_angle_deg == pytest.approx(young + 2.5, abs=1e-9)
    assert angles[-1].ridge_angles_deg == pytest.approx((young + 3.5, young + 1.5), abs=1e-9)


def test_shape_reading_of_a_lattice_block_on_a_wall():
    # the fluid fraction's 0.5 level sits dx/2 beyond the outer particle layers (decisions #38):
    # a 20 x 20 x 6 dx block resting on a wall reads 6 dx tall and 20 dx wide
    from sph_bridge.geometry import lattice_block, wall_slab
    from sph_bridge.simulation import Simulation

    dx = 5e-4
    block = lattice_block([-10 * dx, -10 * dx, 0], [10 * dx, 10 * dx, 6 * dx], dx)
    plate = wall_slab(2, 0.0, 1, [-20 * dx, -20 * dx, 0], [20 * dx, 20 * dx, 0], dx)
    sim = Simulation(block, plate, SphParameters(dx=dx, c0=1.5, gravity=(0.0, 0.0, 0.0)), [-20 * dx, -20 * dx, -4 * dx],
                     [20 * dx, 20 * dx, 14 * dx])
    sim.step()
    shape = droplet.measure(sim)
    assert shape.height == pytest.approx(6 * dx, abs=0.01 * dx)
    assert shape.width == pytest.approx(20 * dx, abs=0.01 * dx)


def test_a_drop_running_past_its_minimum_duration_moves_the_bar_on(capsys):
    # a relaxation not settled by its minimum duration goes on window by window: its bar's end
    # moves to the next settle check, so it never reads past 100 % (with a negative time left)
    from types import SimpleNamespace

    from sph_bridge import __main__ as cli

    bar, advance = cli.progress_bar(SimpleNamespace(quiet=False, command="droplet"), 1.0, extend=0.25)
    for t, end in ((0.5, 1.0), (1.0, 1.0), (1.1, 1.25), (1.6, 1.75), (1.75, 1.75)):
        advance(SimpleNamespace(t=t))
        assert bar.n == t and bar.total == pytest.approx(end)
    bar.close()


def test_a_drop_that_never_settles_says_so(tmp_path, monkeypatch, capsys):
    # a new-user pass (session 65): a drop that had not settled by MAX_EXTENSION minimum
    # relaxations ended "finished" with nothing said but summary.json's "settled": false
    import signal

    from sph_bridge import __main__ as cli

    monkeypatch.setattr(signal, "signal", lambda *args: None)  # the CLI's SIGTERM handler stays out of pytest
    monkeypatch.setattr(droplet, "RELAXATION_TIMES", 0.8)  # a tenth of a relaxation's time, for speed
    monkeypatch.setattr(droplet, "MAX_EXTENSION", 1)  # one minimum relaxation ...
    monkeypatch.setattr(droplet, "SETTLED", 0.0)  # ... and no settle check passes
    out = tmp_path / "unsettled"
    assert cli.main(["droplet", "--dx", "1e-3", "--volume", "6e-7", "--gravity", "0", "--s-ff", "4e-6",
                     "--s-sf", "3e-6", "--c0", "3", "--quiet", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["settled"] is False
    assert summary["simulated_time_s"] > 0 and math.isfinite(summary["height_drift"])
    err = capsys.readouterr().err
    assert "droplet: warning: the drop had not settled after 1 times its minimum relaxation" in err
    assert f"{summary['height_drift']:+.2%}" in err
