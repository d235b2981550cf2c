"""FHP-II lattice gas (issue 6, seed 003): the automaton's exact invariants, its transport
coefficients, the surface generator and the smooth-channel validation. Claim numbers (C1...)
are those of ../shared/digests/seed003.md §5."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import popen_interruptible, sigterm_once_stderr_shows
from sph_bridge import surfaces
from sph_bridge.lga import automaton, channels, rules, studies
from sph_bridge.lga.cli import main as lga_main
from sph_bridge.lga.lattice import Geometry, Lattice, node_positions

CMD = [sys.executable, "-m", "sph_bridge", "lga"]


def open_box(ny=40, nx=150):
    empty = np.zeros((ny, nx), dtype=bool)
    return Geometry(empty, empty, periodic_y=True)


# --- C1-C3: the rules and the transport coefficients ---------------------------------------


def test_collision_table_is_fhp2():
    # C1: the bit-parallel kernel's table equals R1-R4 written as sets, every outcome conserves
    # particles and momentum (integer half units), and nothing collides with four or more particles
    table = rules.kernel_outcomes()
    for state in range(rules.STATES):
        assert table[state] == rules.reference_outcomes(state), state
        assert all(rules.conserves(state, out) for out in table[state])
        if bin(state).count("1") >= 4:
            assert table[state] == {state: 1.0}
    changed = sum(1 for s in range(rules.STATES) if table[s] != {s: 1.0})
    assert changed == 3 * 2 + 2 + 6 * 2  # head-on pairs with and without rest, two triples, R4 both ways


def test_boltzmann_viscosity_of_the_table_is_eq6():
    # C2: the linearised Boltzmann operator of the implemented table gives Eq. 6 (0.307279 at
    # rho = 1, digest XCHK) at every density; the operator itself reproduces FHP-I's known
    # 1/(12 d (1-d)^3) - 1/8, and a table without R2 gives the digest's 0.3382 (so the check bites)
    table = rules.kernel_outcomes()
    assert rules.boltzmann_viscosity(table, 1 / 7) == pytest.approx(0.307279, abs=1e-6)
    for d in (0.1, 0.2, 0.3):
        assert rules.boltzmann_viscosity(table, d) == pytest.approx(rules.viscosity(7 * d), rel=1e-9)
    no_r2 = [dict(t) for t in table]
    for s in range(rules.STATES):
        chs = rules.channels(s)
        if 0 in chs and len(chs) == 3 and rules.reference_outcomes(s) != {s: 1.0}:
            no_r2[s] = {s: 1.0}
    assert rules.boltzmann_viscosity(no_r2, 1 / 7) == pytest.approx(0.3382, abs=5e-4)

    def fhp1(s):  # head-on pairs and symmetric triples only; a rest particle is a pure spectator
        chs = rules.channels(s)
        moving, rest = chs - {0}, chs & {0}
        if len(moving) == 2 and max(moving) - min(moving) == 3:
            k = min(moving)
            return {rules.state_of(rest | {k + 1, (k + 3) % 6 + 1}): 0.5,
                    rules.state_of(rest | {(k - 2) % 6 + 1, k + 2}): 0.5}
        if moving in ({1, 3, 5}, {2, 4, 6}):
            return {rules.state_of(rest | ({1, 2, 3, 4, 5, 6} - moving)): 1.0}
        return {s: 1.0}

    table1 = [fhp1(s) for s in range(rules.STATES)]
    for d in (1 / 6, 0.25):
        assert rules.boltzmann_viscosity(table1, d) == pytest.approx(1 / (12 * d * (1 - d) ** 3) - 0.125, rel=1e-9)


def test_constants():
    # C3: g(rho = 1) = 35/72 (Eq. 5) and the sound speed sqrt(3/7)
    assert rules.galilean_factor(1.0) == pytest.approx(35 / 72, abs=1e-6)
    assert rules.SOUND_SPEED == pytest.approx(0.65465, abs=1e-5)
    assert rules.viscosity(1.0) == pytest.approx(0.307279, abs=1e-6)


def test_eq11_reference_values():
    # the digest's table of Eq. 11 (§3.2): 0.100 at 1.35, 0.169 at 1.70, 0.264 at 2.40
    assert [round(studies.eq11(x), 3) for x in (1.35, 1.7, 2.4)] == [0.1, 0.169, 0.264]


def test_reynolds_ladder_lands_on_its_aims_and_holds_the_mach_bound():
    # seed 003 §5 drives Re ~ 20-180 at u_max <= 0.30. On a channel whose Re grows as g^0.6 (drag
    # rising) and whose u_max is 2e-3 Re, the forcing read from two drives lands on the next aim
    # exactly (scaling g by the Re still missing would land at 106 for an aim of 120 from 88), an
    # aim that would pass the bound becomes the Re at the bound, and a ladder already there stops
    def row(g):
        re = 400.0 * g**0.6
        return {"g": g, "reynolds": re, "u_max": 2e-3 * re}

    rows = [row(0.05), row(0.08)]
    g, aim = studies.next_rung(rows, 120.0, 0.285)
    assert aim == 120.0 and row(g)["reynolds"] == pytest.approx(120.0, rel=1e-12)
    g, aim = studies.next_rung(rows + [row(g)], 180.0, 0.285)
    assert aim == pytest.approx(142.5, rel=1e-12) and row(g)["u_max"] == pytest.approx(0.285, rel=1e-12)
    assert studies.next_rung(rows + [row(g)], 180.0, 0.285) is None
    # one drive: Re taken as proportional to g (the linear regime)
    g, aim = studies.next_rung([{"g": 0.01, "reynolds": 20.0, "u_max": 0.04}], 50.0, 0.285)
    assert (g, aim) == (pytest.approx(0.025, rel=1e-12), 50.0)


# --- the automaton: packing, propagation, invariants ---------------------------------------


def test_pack_round_trip():
    rng = np.random.default_rng(0)
    sites = rng.random((7, 5, 130)) < 0.4
    words = automaton.pack(sites)
    assert words.shape == (7, 5, 3) and words.dtype == np.uint64
    assert np.array_equal(automaton.unpack(words, 130), sites)


@pytest.mark.parametrize("nx", [70, 128])
def test_a_lone_particle_moves_along_its_channel(nx):
    # every channel, from even and odd rows, starting at the row's ends and on both sides of a
    # word boundary: each step is c_k (periodic in x); a full lap of the periodic row returns a
    # c1 and a c4 particle to their nodes
    ny = 20
    x, y = node_positions(ny, nx)
    for k in range(1, 7):
        for row in (4, 5):
            for start in (0, 63, 64, nx - 1):
                lattice = Lattice(open_box(ny, nx), density=1e-9)
                occupied = np.zeros((7, ny, nx), dtype=bool)
                occupied[k, row, start % nx] = True
                lattice.state[:] = automaton.pack(occupied)
                path = []
                for _ in range(3):
                    kk, jj, ii = np.nonzero(automaton.unpack(lattice.state, nx))
                    assert list(kk) == [k]
                    path.append((x[jj[0], ii[0]], y[jj[0], ii[0]]))
                    lattice.run(1, 0.0)
                step = np.diff(np.array(path), axis=0)
                step[:, 0] = (step[:, 0] + nx / 2) % nx - nx / 2  # periodic in x
                assert np.allclose(step, rules.VELOCITIES[k], atol=1e-12), (k, row, start)
    for k in (1, 4):
        lattice = Lattice(open_box(ny, nx), density=1e-9)
        occupied = np.zeros((7, ny, nx), dtype=bool)
        occupied[k, 3, 5] = True
        lattice.state[:] = automaton.pack(occupied)
        lattice.run(nx, 0.0)
        assert np.array_equal(automaton.unpack(lattice.state, nx), occupied)


def test_unforced_open_box_conserves_particles_and_momentum():
    # C4: no walls, no forcing: particle number and x-momentum the same after every step, and
    # the mean occupation of each channel 1/7 within 3 standard deviations
    lattice = Lattice(open_box(), seed=3)
    first = lattice.totals()
    for _ in range(60):
        lattice.run(1, 0.0)
        assert lattice.totals() == first
    occupation = automaton.unpack(lattice.state, lattice.nx).reshape(7, -1).mean(axis=1)
    n = lattice.ny * lattice.nx
    sd = math.sqrt((1 / 7) * (6 / 7) / n)
    assert np.all(np.abs(occupation - 1 / 7) < 3 * sd * math.sqrt(7))  # 3 sigma, Bonferroni over 7 channels


def test_mirrors_conserve_x_momentum():
    # walls without friction: between two mirror rows and without forcing, particle number and
    # x-momentum are conserved to the bit every step (only bounce-back removes momentum)
    ny, nx = 30, 150
    mirror = np.zeros((ny, nx), dtype=bool)
    mirror[0] = mirror[-1] = True
    lattice = Lattice(Geometry(np.zeros_like(mirror), mirror), seed=4)
    first = lattice.totals()
    for _ in range(100):
        lattice.run(1, 0.0)
        assert lattice.totals() == first


def test_momentum_identity_every_step():
    # C5: with walls, a mirror and forcing, P_x(t+1) - P_x(t) = forcing - bounce-back loss exactly
    profile = surfaces.midpoint_displacement(6, 0.5, np.random.default_rng(1))
    geometry = channels.rough_channel(profile, 64, 8.0, 14.0, flat=8)
    lattice = Lattice(geometry, seed=2)
    particles, momentum = lattice.totals()
    forced = 0
    for _ in range(300):
        gains, losses = lattice.run(1, 0.02)
        n, p = lattice.totals()
        assert n == particles
        assert p - momentum == gains[0] - losses[0]
        momentum = p
        forced += gains[0]
    assert forced > 0


def test_parallel_kernel_is_bit_identical_to_serial():
    # the chirality bits are a hash of (seed, step, row, word): thread count cannot change a run
    geometry = channels.smooth_channel(200, 30)
    results = []
    for kernel in (automaton.advance_serial, automaton.advance_parallel):
        lattice = Lattice(geometry, seed=5)
        gains = np.zeros(50, dtype=np.int64)
        losses = np.zeros(50, dtype=np.int64)
        kernel(lattice.state, lattice.spare, lattice.solid, lattice.mirror, lattice.fluid, lattice.nx, False, 5, 0,
               0.0, lattice.fluid_nodes, gains, losses)
        results.append((lattice.state.copy(), losses.copy()))
    assert np.array_equal(results[0][0], results[1][0]) and np.array_equal(results[0][1], results[1][1])


KERNEL_CACHE_SCRIPT = """
import numpy as np
from sph_bridge.lga import automaton, channels
from sph_bridge.lga.lattice import Lattice
lattice = Lattice(channels.smooth_channel(64, 4), seed=1)
for kernel in (automaton.advance_serial, automaton.advance_parallel):
    steps = np.zeros(2, dtype=np.int64)
    kernel(lattice.state, lattice.spare, lattice.solid, lattice.mirror, lattice.fluid, lattice.nx, False, 1, 0, 0.0,
           lattice.fluid_nodes, steps, steps.copy())
print(*(sum(k.stats.cache_hits.values()) for k in (automaton.advance_serial, automaton.advance_parallel)))
"""


def test_serial_and_parallel_kernels_are_cached_apart(tmp_path):
    # numba's disk cache keys compiled code by function and signature, not by jit options (numba
    # issue #6845): with one Python function behind both kernels, the parallel one was served
    # the serial one's cached code (1 cache hit here), and the test above compared a kernel
    # with itself. In an empty cache directory neither may find the other's entry (~10 s).
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", KERNEL_CACHE_SCRIPT], env=env, capture_output=True, text=True,
                         check=True, timeout=300)
    assert out.stdout.split() == ["0", "0"]


def test_forcing_gain_at_rest():
    # digest §1.5: at rest equilibrium a chosen node gains 4 d (1 - d) = 24/49 x-momentum on average
    lattice = Lattice(open_box(200, 640), seed=7)
    gains = []
    for _ in range(20):
        lattice.state[:] = Lattice(open_box(200, 640), seed=len(gains) + 8).state  # fresh equilibrium
        g, _ = lattice.run(1, 0.05)
        gains.append(g[0])
    per_node = 0.5 * np.sum(gains) / (20 * 0.05 * lattice.n_fluid)
    # ~6,400 events per step: the mean's standard error is ~0.3 %
    assert per_node == pytest.approx(24 / 49, rel=0.02)


# --- C19: the surface generator --------------------------------------------------------------


@pytest.mark.parametrize("hurst", [0.3, 0.5, 0.7])
def test_profile_hurst_exponent(hurst):
    # C19: 50 profiles of 513 points, the structure function's slope over lags 1-64 gives H within
    # 0.06 (the digest's own midpoint displacement reads 0.33 / 0.48 / 0.65)
    profiles = np.array([surfaces.midpoint_displacement(9, hurst, np.random.default_rng(s)) for s in range(50)])
    assert surfaces.hurst_exponent(profiles) == pytest.approx(hurst, abs=0.06)


def test_rough_profile_scaling():
    h = surfaces.rough_profile(9, 0.5, 77.9, seed=3)
    assert len(h) == 513 and abs(h.mean()) < 1e-9 and h.max() == pytest.approx(77.9)


# --- geometry ---------------------------------------------------------------------------------


def test_rough_channel_apertures():
    # the wall is continuous into the smooth sections, its mean plane is the mean over the whole
    # periodic length, y_max stands above it, and the mirror sits delta_av/2 above it within a row
    y_max = 90 * 0.8660254
    profile = surfaces.midpoint_displacement(9, 0.7, np.random.default_rng(1))
    geometry = channels.rough_channel(profile, 512, y_max, y_max / 0.741)
    d = geometry.description
    assert d["mean_aperture"] / 2 == pytest.approx(y_max / 0.741, abs=0.9)
    assert channels.relative_aperture(geometry) == pytest.approx(1 / 0.741, rel=0.01)
    assert geometry.mirror[d["mirror_row"]].all() and not geometry.fluid[0].any()
    column = geometry.solid.sum(axis=0)  # solid nodes per column (x = i on even rows)
    for junction in (20, 20 + 512):  # no cliff where the flats meet the profile (a flat at the mean
        # plane left a step of 51 rows on this surface)
        assert abs(int(column[junction]) - int(column[junction - 1])) <= 9
    x, y = node_positions(*geometry.shape)
    top = np.where(geometry.solid, y, -np.inf).max(axis=0)  # highest solid node per column
    assert top.max() - d["mean_plane"] == pytest.approx(y_max, abs=1.0)


# --- C7, C8: smooth channels (seed 003 §3) ---------------------------------------------------


@pytest.fixture(scope="module")
def poiseuille(tmp_path_factory):
    """The paper's validation channel (600 x 100 rows) through the command line, three drives."""
    out = tmp_path_factory.mktemp("lga") / "poiseuille"
    assert lga_main(["poiseuille", "--out", str(out), "--quiet"]) == 0
    return out, json.loads((out / "summary.json").read_text())


def test_poiseuille_run_directory(poiseuille):
    out, summary = poiseuille
    assert {"config.toml", "summary.json", "timeseries.csv", "profile.png", "flow_rate.png",
            "field.vtu"} <= {p.name for p in out.iterdir()}
    assert summary["status"] == "finished" and len(summary["drives"]) == 3
    import tomllib

    from hmdem import __version__
    assert tomllib.loads((out / "config.toml").read_text())["run"]["hmdem_version"] == __version__
    rows = (out / "timeseries.csv").read_text().splitlines()
    assert rows[0] == "step,drive,flow_rate,force_applied_per_node,force_friction_per_node" and len(rows) > 100
    # ParaView's field: walls and mirrors at rest, so the colour range is the fluid's (a new-user pass)
    import meshio

    field = meshio.read(out / "field.vtu").point_data
    fluid = field["kind"] == 0
    assert np.all(field["velocity"][~fluid] == 0.0) and 0.0 < np.abs(field["velocity"][fluid]).max() < 0.5


def test_poiseuille_profile_is_a_parabola(poiseuille):
    # C7a: R^2 >= 0.98, u_max/u_mean = 1.5 within 5 %, zeros within a row of the wall rows
    _, s = poiseuille
    assert s["profile_r2"] >= 0.98
    assert s["u_max_over_mean"] == pytest.approx(1.5, rel=0.05)
    for zero, wall in zip(s["profile_zeros_rows"], s["wall_rows"]):
        assert abs(zero - wall) <= 1.0


def test_poiseuille_forces_balance_and_mach(poiseuille):
    # C6 in the smooth channel (Table I: <= 1 % typical, 3 % worst); C17: u_max <= 0.30; every
    # window steady (its halves agree within 1 % or 3 standard errors)
    _, s = poiseuille
    assert s["force_mismatch_max"] <= 0.01
    assert s["u_max"] <= 0.30
    assert all(d["steady"] for d in s["drives"])


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 6: the automaton's Poiseuille viscosity "
                   "at 600 x 100 rows is 0.328 (+6.8 % over Eq. 6's 0.3075; the paper measured 0.30); it grows "
                   "with the channel width (0.315, 0.323, 0.328, 0.335 at 25, 50, 100, 200 rows), the scale dependence "
                   "expected of a 2-D lattice gas beyond the Boltzmann approximation; a wall-free shear wave reads +6 to +13 % "
                   "too, and an independent table-driven FHP-II reads the same shear wave within its "
                   "noise (decisions #43, #58)")
def test_poiseuille_viscosity_matches_eq6(poiseuille):
    # C7b: nu from the Q-dP slope within 5 % of Eq. 6
    _, s = poiseuille
    assert abs(s["viscosity_error"]) <= 0.05


def test_poiseuille_viscosity_approaches_eq6_at_low_density(poiseuille, tmp_path):
    # decisions #43: the excess over Eq. 6 (the Boltzmann viscosity) grows with the density, as
    # the correlations Eq. 6 neglects do. At rho = 0.35 C7b's 5 % holds (measured +2.1 %), and
    # the excess sits more than 2 points (~1.5x the flow-rate error of one drive) under rho = 1's
    _, dense = poiseuille
    out = tmp_path / "dilute"
    assert lga_main(["poiseuille", "--density", "0.35", "--out", str(out), "--quiet"]) == 0
    dilute = json.loads((out / "summary.json").read_text())
    assert abs(dilute["viscosity_error"]) <= 0.05
    assert dilute["viscosity_error"] <= dense["viscosity_error"] - 0.02


def test_bulk_shear_wave_viscosity_is_above_eq6():
    # decisions #43: without walls or forcing (a periodic lattice, a decaying sin(ky) shear wave
    # 128 rows long) the automaton's viscosity at the paper's rho = 1 is 0.341, +11 % over Eq. 6,
    # +-1.6 % (standard error over the 8 lattices); so C7b's miss is the automaton's, not the
    # channel's. Bounds: 3 standard errors under the measurement, and 20 % (a wrong row spacing,
    # sqrt(3)/2, would read +33 %). The start carries j_x = 3 e sin(ky) per node: amplitude 6 e L
    from sph_bridge.lga.shear_wave import shear_wave_viscosity

    wave = shear_wave_viscosity(rows=128, length=16384, density=1.0, seeds=8)
    e = 0.05 * 1.0 / 3.0
    # the mean of 8 starts: noise sqrt(2 x 12 d (1 - d) L / rows / 8) = 7 half units; 20 is 3 of them
    assert wave.amplitude[0] == pytest.approx(6 * e * 16384, abs=20.0)
    assert wave.viscosity_eq6 == pytest.approx(0.307279, abs=1e-6)
    assert 0.06 <= wave.excess <= 0.20


def test_table_driven_reference_automaton_reads_the_kernels_viscosity():
    # decisions #58: an FHP-II written the other way round (a byte per node, a look-up table of
    # R1-R4 as sets, explicit neighbour indices; sph_bridge/lga/reference.py) decays the same
    # shear wave at the kernel's viscosity, within 3 combined standard errors (jackknife over
    # the 16 lattices each; measured 0.347 +- 0.006 kernel, 0.335 +- 0.006 reference: this size
    # resolves a difference of ~8 %, the 128-row runs of BENCHMARKS.md one of ~2 %), and on its
    # own it sits above Eq. 6 by more than 3 of its standard errors (+9 %, 4.3 of them): the
    # excess that makes C7b fail is not an artefact of the bit-parallel kernel
    from sph_bridge.lga.reference import collision_table
    from sph_bridge.lga.rules import conserves, kernel_outcomes
    from sph_bridge.lga.shear_wave import shear_wave_viscosity

    table = collision_table()
    assert [set(o) for o in kernel_outcomes()] == [{int(table[0, s]), int(table[1, s])} for s in range(128)]
    assert all(conserves(s, int(table[c, s])) for c in range(2) for s in range(128))
    kernel = shear_wave_viscosity(rows=64, length=4096, seeds=16)
    ref = shear_wave_viscosity(rows=64, length=4096, seeds=16, implementation="reference")
    combined = math.hypot(kernel.viscosity_stderr, ref.viscosity_stderr)
    assert abs(ref.viscosity_fit - kernel.viscosity_fit) <= 3 * combined
    assert ref.viscosity_fit - ref.viscosity_eq6 >= 3 * ref.viscosity_stderr


def test_reference_automaton_moves_particles_and_picks_chirality():
    # the reference's own propagation: from an even and an odd row, one step moves a lone
    # particle of channel k by c_k (x = i + (j mod 2)/2, y = j sqrt(3)/2), across both seams.
    # Its chirality: a lattice of head-on pairs {1, 4} turns each to either side with
    # probability 1/2; on 4,096 nodes the share is 0.5 +- 0.008, bound 5 of those
    from sph_bridge.lga.reference import _seed, _step, collision_table

    table = collision_table()
    pairs = np.full((64, 64), 0b10010, np.uint8)
    turned = np.empty_like(pairs)
    _seed(3)
    _step(pairs, turned, table)
    assert set(np.unique(turned)) == {table[0, 0b10010], table[1, 0b10010]}
    assert np.mean(turned == table[1, 0b10010]) == pytest.approx(0.5, abs=0.04)
    for k in range(1, 7):
        for row, column in ((2, 4), (3, 4), (0, 0), (7, 9)):
            nodes = np.zeros((8, 10), np.uint8)
            nodes[row, column] = 1 << k
            moved = np.empty_like(nodes)
            _step(nodes, moved, table)
            (j, i), = np.argwhere(moved)
            assert moved[j, i] == 1 << k
            height = 8 * math.sqrt(3) / 2
            dx = ((i + 0.5 * (j % 2)) - (column + 0.5 * (row % 2)) + 5) % 10 - 5  # nearest periodic image
            dy = ((j - row) * math.sqrt(3) / 2 + height / 2) % height - height / 2
            angle = math.pi * (k - 1) / 3
            assert (dx, dy) == pytest.approx((math.cos(angle), math.sin(angle)), abs=1e-12)

@pytest.fixture(scope="module")
def half_channel(tmp_path_factory):
    out = tmp_path_factory.mktemp("lga") / "half"
    assert lga_main(["poiseuille", "--mirror", "--ny", "50", "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


@pytest.mark.xfail(strict=True, reason="known model discrepancy, issue 6: the 50-row half channel under a mirror "
                   "reads (delta_H/delta)^3 = 0.91-0.93 with Eq. 6's viscosity, because the automaton's own "
                   "viscosity is ~7-8 % higher at this size (see the C7b xfail); the full channel of the same "
                   "width carries the same flow within 0.3 % (decisions #40, #43)")
def test_half_channel_recovers_cubic_law(half_channel):
    # C8: the flat half channel with a mirror top gives phi = 1 within 3 %
    assert all(abs(phi - 1.0) <= 0.03 for phi in half_channel["phi"])


def test_half_channel_equals_full_channel(poiseuille, half_channel):
    # the mirror is a symmetry plane: 50 rows under a mirror (full width 101 rows) carry the flow
    # of the 100-row full channel scaled by (101/100)^3, i.e. the same viscosity, within 3 %
    # (C8's tolerance for the wall-position ambiguity)
    _, full = poiseuille
    assert half_channel["viscosity_fit"] == pytest.approx(full["viscosity_fit"], rel=0.03)


# --- rough channels, reduced size (seed 003 §4.2; the full study is tests/test_lga_full.py) ---


@pytest.fixture(scope="module")
def reduced_study(tmp_path_factory):
    """H = 0.5, one surface, delta_av/(2 y_max) = 1.35, 1.7, 2.4, with a 256-long rough section
    and y_max = 45 rows (half the paper's in both directions): ~3 minutes on 2 workers."""
    out = tmp_path_factory.mktemp("lga") / "permeability"
    assert lga_main(["permeability", "--hurst", "0.5", "--surfaces", "1", "--nx", "296", "--ny", "45",
                     "--out", str(out), "--quiet"]) == 0
    return out, json.loads((out / "summary.json").read_text())


def test_workers_do_not_change_the_numbers(tmp_path, monkeypatch):
    # each channel carries its own geometry and lattice seed, so a study run on worker processes
    # gives the serial run's numbers to the bit (tiny channels, fixed 200-step windows)
    from sph_bridge.lga import cli, pool

    calls = []
    monkeypatch.setattr(cli, "run_in_workers", lambda *a, **k: calls.append(a[1]) or pool.run_in_workers(*a, **k))
    args = ["permeability", "--hurst", "0.5", "--surfaces", "1", "--nx", "104", "--ny", "8", "--steps", "200",
            "--relative-roughness", "0.741", "--relative-roughness", "0.417", "--quiet"]
    runs = {}
    for workers in ("1", "2"):
        out = tmp_path / f"workers{workers}"
        assert lga_main(args + ["--workers", workers, "--out", str(out)]) == 0
        summary = json.loads((out / "summary.json").read_text())
        summary.pop("wall_time_s")
        runs[workers] = summary, (out / "timeseries.csv").read_text()
    assert calls == [2]  # the serial run did not use workers, the other ran on two
    assert runs["1"] == runs["2"]
    assert [len(p["drives"]) for p in runs["2"][0]["points"]] == [2, 2]


def _worker_lost_on_job_0(conn, slot, *shared):
    """A worker the system kills (SIGKILL, as the out-of-memory killer sends) when it runs job 0."""
    from sph_bridge.lga import pool

    if slot == 0:
        os.kill(os.getpid(), signal.SIGKILL)
    pool._run_channel(conn, slot, *shared)


def test_a_lost_worker_fails_the_run_and_keeps_the_other_channels(tmp_path, monkeypatch):
    # a worker killed outright loses only its own channel: the run is "failed" (exit status 1, not
    # an interrupt's 130), says which channel and signal, and writes the other channel whole
    from sph_bridge.lga import pool

    monkeypatch.setattr(pool, "_run_channel", _worker_lost_on_job_0)  # pickled by name into the workers
    out = tmp_path / "run"
    assert lga_main(["permeability", "--hurst", "0.5", "--surfaces", "1", "--nx", "104", "--ny", "8", "--steps",
                     "200", "--relative-roughness", "0.741", "--relative-roughness", "0.417", "--quiet",
                     "--workers", "2", "--out", str(out)]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    # the channel as summary.json's points name it (a new-user pass: "channel 0" said nothing)
    assert summary["status_message"] == ("channel H0.5-s0-r0.741's worker was killed by SIGKILL "
                                         "(the out-of-memory killer?)")
    assert [len(p["drives"]) for p in summary["points"]] == [2]
    assert (out / "config.toml").exists() and (out / "timeseries.csv").exists()


def test_a_lost_worker_is_named_by_its_signal():
    from sph_bridge.lga.pool import lost_worker

    assert lost_worker(2, -9) == "channel 2's worker was killed by SIGKILL (the out-of-memory killer?)"
    assert lost_worker(0, -35) == "channel 0's worker was killed by signal 35"  # real-time: no name
    assert lost_worker(1, 1) == "channel 1's worker ended (exit code 1) without sending its results"
    # a new-user pass: the command names its channels as summary.json's points do
    assert lost_worker("H0.3-s0-r0.741", -9).startswith("channel H0.3-s0-r0.741's worker was killed by SIGKILL")


def test_sigterm_stops_the_workers_and_keeps_their_drives(tmp_path):
    # a batch system's SIGTERM reaches the main process (the workers ignore it) once the workers
    # have run thousands of steps ("k/" on the bar): every running channel sends back what it ran,
    # the directory is valid and the exit status is 128 + 15
    out = tmp_path / "run"
    code, err = sigterm_once_stderr_shows(["sph_bridge", "lga", "permeability", "--hurst", "0.5", "--surfaces",
                                           "1", "--nx", "296", "--ny", "45", "--workers", "2", "--out", str(out)],
                                          "k/")
    assert code == 143, err
    assert "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["status_message"] == ""
    assert (out / "config.toml").exists()
    assert len((out / "timeseries.csv").read_text().splitlines()) > 1  # the workers' rows came back


def test_reduced_study_run_directory(reduced_study):
    out, summary = reduced_study
    assert {"config.toml", "summary.json", "timeseries.csv", "collapse.png", "points.csv"} <= {
        p.name for p in out.iterdir()}
    assert len(summary["points"]) == 3 and math.isfinite(summary["alpha"])
    assert [p["opening"] for p in summary["points"]] == pytest.approx([1.35, 1.7, 2.4], rel=0.01)


def test_reduced_forces_balance(reduced_study):
    # C6: applied force = wall friction, <= 1 % typical and <= 3 % worst (Table I)
    mismatches = [abs(d["force_mismatch"]) for p in reduced_study[1]["points"] for d in p["drives"]]
    assert max(mismatches) <= 0.03 and float(np.median(mismatches)) <= 0.01
    assert all(d["steady"] for p in reduced_study[1]["points"] for d in p["drives"])


def test_reduced_permeability_ordering_and_magnitude(reduced_study):
    # C12: the cubic law with delta_av overpredicts (phi < 0.5 at rel <= 2.5); C13: phi rises with
    # the opening, phi(2.4)/phi(1.35) in [2, 4]; the bound on C11: within a factor of 2 of
    # Eq. 11; C17: u_max <= 0.30
    points = reduced_study[1]["points"]
    phis = [p["phi"] for p in points]
    assert all(phi < 0.5 for phi in phis)
    assert phis[0] < phis[1] < phis[2] and 2.0 <= phis[2] / phis[0] <= 4.0
    for p in points:
        assert 0.5 <= p["phi"] / studies.eq11(p["opening"]) <= 2.0
    assert reduced_study[1]["u_max"] <= 0.30


# --- the command line -----------------------------------------------------------------------


@pytest.mark.parametrize("argv, flag", [
    (["rough", "--relative-roughness", "1.35"], "--relative-roughness"),
    (["rough", "--nx", "500"], "--nx"),
    (["poiseuille", "--density", "8"], "--density"),
    (["permeability", "--hurst", "1.2"], "--hurst"),
    (["permeability", "--workers", "0"], "--workers"),
    (["poiseuille", "--g", "0"], "--g"),
    # a new-user pass (decisions #84): a 56 GiB allocation's traceback; planning 1e8 surfaces
    (["poiseuille", "--ny", "100000000"], "--ny"),
    (["permeability", "--surfaces", "100000000"], "--surfaces"),
])
def test_bad_input_is_one_line(tmp_path, argv, flag):
    out = tmp_path / "run"
    proc = subprocess.run(CMD + argv + ["--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0] and lines[0].startswith("python -m sph_bridge lga")
    assert not out.exists()


def test_ctrl_c_leaves_a_valid_partial_directory(tmp_path):
    out = tmp_path / "run"
    proc = popen_interruptible(CMD + ["poiseuille", "--ny", "200", "--out", str(out)])
    deadline = time.time() + 60
    while time.time() < deadline:  # the bar appears once the lattice runs
        line = proc.stderr.readline()
        if "steps" in line or proc.poll() is not None:
            break
    time.sleep(3.0)
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=120)
    assert proc.returncode == 130
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert (out / "config.toml").exists() and (out / "timeseries.csv").exists()


def test_workers_beyond_the_cores_run_on_the_cores_with_a_warning(capsys, monkeypatch):
    # a new-user pass: 100,000 workers were accepted and started as processes; a review: refusing
    # them broke replaying a command recorded on a larger machine (the numbers do not depend on it)
    from hmdem import cli

    monkeypatch.setattr(cli, "available_cores", lambda: 2)
    assert cli.worker_count(100000, "lga") == 2
    assert "lga: warning: --workers 100000 on 2 core(s); running 2" in capsys.readouterr().err
    assert cli.worker_count(1, "lga") == 1 and capsys.readouterr().err == ""


def test_a_drive_past_the_mach_limit_or_short_of_its_precision_says_so(tmp_path, capsys):
    # a new-user pass: in a 16-row channel the ladder's first rung (Re 20) ran at u_max 0.41,
    # past the seed's 0.30 (C17), with status "finished" and a console line quoting the aim
    # 0.285 as if measured; and a window that hit its longest length short of 1 % said nothing
    out = tmp_path / "nl"
    assert lga_main(["nonlinear", "--nx", "104", "--ny", "16", "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["rough_u_max"] > summary["mach_limit"] and summary["rough_within_mach_limit"] is False
    assert f"u_max = {summary['rough_u_max']:.3f}, past the seed's 0.3" in err
    drives = [d for rows in summary["series"].values() for d in rows]
    for d in drives:  # the window's own test: Q's standard error within the 1 % it aimed at
        assert d["precision_target"] == 0.01
        assert not d["precise"] or d["flow_rate_error"] <= 0.01 * abs(d["flow_rate"])
    assert ("longest averaging window" in err) == (not all(d["precise"] for d in drives))


@pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy's, from the cube root of a negative number
def test_a_drive_lost_in_the_noise_says_so(tmp_path, capsys):
    # a new-user pass: 100 steps at g = 0.001 in an 8-row channel gave nu = -0.16 from the slope
    # and a parabola of R^2 0.01, reported as a finished run with numpy's RuntimeWarning
    out = tmp_path / "p"
    assert lga_main(["poiseuille", "--nx", "64", "--ny", "8", "--g", "0.001", "--steps", "100", "--out", str(out),
                     "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["viscosity_fit"] <= 0 or summary["profile_r2"] < 0.9
    err = capsys.readouterr().err
    assert "the flow is lost in the lattice's noise" in err
