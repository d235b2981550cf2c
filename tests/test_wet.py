"""Pendular liquid bridges (seed 002 §3.2): Eq. 4 force, Eq. 5 rupture and the liquid's moves.

Expected numbers are the digest's claims A1–A8 and B5
(shared/digests/seed002.md §4.2, §4.3, §8) with their tolerances, YADE's own
``Law2_ScGeom_ViscElCapPhys_Basic`` as an independent oracle, and energy conservation of a sphere
that a bridge pulls in through YADE.
"""

import numpy as np
import pytest

from hmdem.wet.bridges import bridge_force, effective_radius, max_bridge_volume, rupture_distance
from hmdem.wet.liquid import PendularLiquid, bridge_radii, form_bridges, rupture_bridges, ruptured
from hmdem.yade_env import import_yade

THETA_5 = np.radians(5.0)


@pytest.mark.parametrize("law", ["chapter", "willett"])
def test_force_at_contact_is_independent_of_volume(law):
    # A1: F(s = 0) = 2 pi R gamma cos(theta) for every V, to 1e-12
    volume = np.array([1e-4, 1e-3, 0.01, 0.03, 0.057])
    assert bridge_force(0.0, volume, 1.0, 1.0, 0.0, law) == pytest.approx(2 * np.pi, rel=1e-12)
    # overlapping soft grains keep the contact value
    assert bridge_force(-0.01, 0.03, 1.0, 1.0, 0.0, law) == pytest.approx(2 * np.pi, rel=1e-12)


@pytest.mark.parametrize("law, s, v, expected", [
    ("chapter", 0.1, 0.03, 2.960961),   # A2
    ("willett", 0.1, 0.03, 2.575550),   # A3
    ("chapter", 0.05, 0.01, 3.351032),  # digest §4.2's table
    ("willett", 0.05, 0.01, 2.922412),
    ("chapter", 0.1, 0.01, 1.570796),
    ("willett", 0.1, 0.01, 1.380920),
    ("chapter", 0.2, 0.03, 1.279493),
    ("willett", 0.2, 0.03, 1.132969),
])
def test_force_matches_the_digests_values(law, s, v, expected):
    # R = gamma = 1, theta = 0; the digest prints 6 decimals (tolerance 1e-6, §8)
    assert bridge_force(s, v, 1.0, 1.0, 0.0, law) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("law", ["chapter", "willett"])
def test_force_falls_with_gap_and_grows_with_volume(law):
    # A4: monotone in s at fixed V, and in V at fixed s > 0 (exact)
    s = np.linspace(0.0, 0.4, 81)[:, None]
    v = np.linspace(1e-4, 0.057, 60)[None, :]
    force = bridge_force(s, v, 1.0, 1.0, THETA_5, law)
    assert np.all(np.diff(force, axis=0) < 0)
    assert np.all(np.diff(force[1:], axis=1) > 0)


def test_force_scales_with_radius_tension_and_contact_angle():
    # Eq. 4 is R gamma cos(theta) times a function of s/R and V/R^3 only
    base = bridge_force(0.1, 0.03, 1.0, 1.0, 0.0)
    scaled = bridge_force(0.1 * 61e-6, 0.03 * 61e-6**3, 61e-6, 0.0728, THETA_5)
    assert scaled == pytest.approx(base * 61e-6 * 0.0728 * np.cos(THETA_5), rel=1e-12)


def test_force_switches_on_at_the_threshold_volume():
    # digest §4.2: no force below V_c (roughness), Eq. 4 from V_c on; no liquid, no force
    volume = np.array([0.0, 0.004, 0.005, 0.01])
    force = bridge_force(0.1, volume, 1.0, 1.0, 0.0, switch_volume=0.005)
    assert force[0] == 0 and force[1] == 0
    assert force[2:] == pytest.approx(bridge_force(0.1, volume[2:], 1.0, 1.0, 0.0), rel=1e-15)


def test_unknown_force_law_is_refused():
    with pytest.raises(ValueError, match="law must be one of"):
        bridge_force(0.1, 0.03, 1.0, 1.0, 0.0, law="toroidal")


@pytest.mark.parametrize("v, theta, expected", [
    (0.03, 0.0, 0.320378),          # A5
    (0.03, 0.0872665, 0.334357),    # A6 (5 degrees as the digest rounds it)
    (0.057, 0.0, 0.399661),         # A7, V = V_max
    (0.001, 0.0, 0.101000),         # digest §4.3's table
    (0.01, THETA_5, 0.229688),
    (0.057, np.radians(10.0), 0.434538),
])
def test_rupture_distance_matches_the_digests_values(v, theta, expected):
    assert rupture_distance(v, 1.0, theta) == pytest.approx(expected, abs=1e-6)


def test_rupture_distance_scales_with_radius():
    # normalised reading of Eq. 5 (digest §9 item 3): s_c/R depends on V/R^3 only
    r = 61e-6
    assert rupture_distance(0.03 * r**3, r, 0.0) == pytest.approx(0.320378 * r, rel=2e-6)
    assert max_bridge_volume(r) == pytest.approx(0.057 * r**3, rel=1e-15)


@pytest.mark.parametrize("solid_fraction", [0.41, 0.51])
@pytest.mark.parametrize("theta_deg", [0.0, 10.0])
def test_split_cell_rupture_distance_is_about_24_um(solid_fraction, theta_deg):
    # B5 (Sec. 2.1): R = 61 um, W_c = 2.4 % of the void, 6 bridges a grain (3 per grain, each
    # shared by two) give s_c of about 24 um; digest tolerance +-25 %
    r = 61e-6
    void_per_grain = 4 / 3 * np.pi * r**3 * (1 - solid_fraction) / solid_fraction
    volume = 0.024 * void_per_grain / 3
    assert rupture_distance(volume, r, np.radians(theta_deg)) == pytest.approx(24e-6, rel=0.25)


def test_effective_radius_is_the_harmonic_mean():
    assert effective_radius(1.0, 1.0) == 1.0
    assert effective_radius(1.0, 2.0) == pytest.approx(4 / 3, rel=1e-15)


@pytest.mark.yade
@pytest.mark.parametrize("r1, r2, theta_deg", [(1.0, 1.0, 0.0), (1e-3, 2e-3, 0.0), (1e-3, 2e-3, 20.0)])
def test_willett_law_and_rupture_equal_yades(r1, r2, theta_deg):
    # YADE's Law2_ScGeom_ViscElCapPhys_Basic (Willett_analytic) is the 2.1 variant of Eq. 4, and
    # its sCrit is Eq. 5 with the harmonic effective radius (digest §10): same numbers to 1e-6
    import_yade()
    from yade import O, Vector3, utils
    from yade.wrapper import (ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb, InteractionLoop,
                              Ig2_Sphere_Sphere_ScGeom, Ip2_ViscElCapMat_ViscElCapMat_ViscElCapPhys,
                              Law2_ScGeom_ViscElCapPhys_Basic, NewtonIntegrator, ViscElCapMat)

    gap, volume, gamma = 0.1 * r1, 0.03 * r1**3, 0.07
    O.reset()
    mat = O.materials.append(ViscElCapMat(Capillar=True, CapillarType="Willett_analytic", Vb=volume,
                                          gamma=gamma, theta=theta_deg, kn=1e3, ks=1e3, cn=0, cs=0))
    O.bodies.append(utils.sphere((0, 0, 0), r1, material=mat, fixed=True))
    O.bodies.append(utils.sphere((r1 + r2 - 1e-4 * r2, 0, 0), r2, material=mat, fixed=True))
    O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb(aabbEnlargeFactor=1.5)]),
                 InteractionLoop([Ig2_Sphere_Sphere_ScGeom(interactionDetectionFactor=1.5)],
                                 [Ip2_ViscElCapMat_ViscElCapMat_ViscElCapPhys()],
                                 [Law2_ScGeom_ViscElCapPhys_Basic()]),
                 NewtonIntegrator()]
    O.dt = 1e-9
    O.step()  # the bridge forms at contact, then survives the pull to the gap
    O.bodies[1].state.pos = Vector3(r1 + r2 + gap, 0, 0)
    O.step()
    phys = O.interactions[0, 1].phys
    radius, theta = effective_radius(r1, r2), np.radians(theta_deg)
    # the digest's tolerance is 1e-6; the two agree to round-off (measured 1.6e-15)
    assert O.forces.f(0)[0] == pytest.approx(bridge_force(gap, volume, radius, gamma, theta, "willett"), rel=1e-12)
    assert phys.sCrit == pytest.approx(rupture_distance(volume, radius, theta), rel=1e-12)
    O.reset()


def _line_of_grains():
    """Grains 0-1-2-3 on the x axis and grain 4 above grain 1, unit radius, with films."""
    pairs = np.array([[0, 1], [1, 2], [2, 3], [1, 4]])
    unit = np.array([[1.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    liquid = PendularLiquid(pairs, [0.02, 0.01, 0.01, 0.01], np.full(5, 1e-3))
    return liquid, unit


def test_rupture_equal_rule_splits_shares_evenly():
    # rule (a): bridge 0-1 breaks; grain 0 keeps its half in its film (no intact bridge), grain 1
    # gives 0.005 to each of its two intact bridges 1-2 and 1-4
    liquid, unit = _line_of_grains()
    after = rupture_bridges(liquid, [True, False, False, False], np.ones(5), unit, v_max=0.057)
    assert after.pairs.tolist() == [[1, 2], [2, 3], [1, 4]]
    assert after.volume == pytest.approx([0.015, 0.01, 0.015], rel=1e-15)
    assert after.film == pytest.approx([0.011, 1e-3, 1e-3, 1e-3, 1e-3], rel=1e-15)


def test_rupture_distance_rule_weights_by_the_chord():
    # rule (c): on grain 1 the broken bridge's contact point is at -x; bridge 1-2's at +x (chord 2R),
    # bridge 1-4's at +y (chord sqrt(2) R): shares in the ratio 1/2 : 1/sqrt(2)
    liquid, unit = _line_of_grains()
    after = rupture_bridges(liquid, [True, False, False, False], np.ones(5), unit, v_max=0.057, rule="distance")
    w = np.array([1 / 2, 1 / np.sqrt(2)])
    gained = after.volume[[0, 2]] - 0.01
    assert gained == pytest.approx(0.01 * w / w.sum(), rel=1e-12)


def test_rupture_caps_bridges_at_v_max_and_keeps_the_rest_in_the_film():
    liquid, unit = _line_of_grains()
    after = rupture_bridges(liquid, [True, False, False, False], np.ones(5), unit, v_max=0.012)
    assert after.volume == pytest.approx([0.012, 0.01, 0.012], rel=1e-15)
    assert after.film[1] == pytest.approx(1e-3 + 0.006, rel=1e-12)  # grain 1 gave 0.01, 0.004 was taken
    assert after.total == pytest.approx(liquid.total, rel=1e-12)


def test_larger_grain_takes_the_larger_share_of_a_broken_bridge():
    liquid = PendularLiquid([[0, 1]], [0.03], [0.0, 0.0])
    after = rupture_bridges(liquid, [True], [1.0, 2.0], [[1.0, 0, 0]], v_max=0.057)
    assert len(after.pairs) == 0
    assert after.film == pytest.approx([0.01, 0.02], rel=1e-15)


def _random_assembly(seed, n=60):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 5, (n, 3))
    radii = rng.uniform(0.4, 0.6, n)
    i, j = np.triu_indices(n, 1)
    near = np.linalg.norm(centres[i] - centres[j], axis=1) < 1.6
    pairs = np.c_[i[near], j[near]]
    branch = centres[pairs[:, 1]] - centres[pairs[:, 0]]
    unit = branch / np.linalg.norm(branch, axis=1)[:, None]
    v_max = max_bridge_volume(effective_radius(radii[pairs[:, 0]], radii[pairs[:, 1]]))
    liquid = PendularLiquid(pairs, rng.uniform(0.2, 1.0, len(pairs)) * v_max, rng.uniform(0, 0.01, n))
    return rng, liquid, radii, unit, v_max


@pytest.mark.parametrize("rule", ["equal", "pressure", "distance", "mani"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rupture_conserves_liquid_and_the_cap(rule, seed):
    # A8: the ruptured volume is conserved (1e-12 relative), into intact bridges or, past V_max,
    # with no intact bridge or none below the film pressure, into the films; no bridge above
    # V_max, and the films only gain. Pressures: P_f = 1, P_i in [-5, 1.5] (some draw nothing)
    rng, liquid, radii, unit, v_max = _random_assembly(seed)
    broken = rng.random(len(liquid.pairs)) < 0.3
    pressures = dict(bridge_pressure=rng.uniform(-5, 1.5, len(liquid.pairs)), film_pressure=np.ones(len(radii)))
    after = rupture_bridges(liquid, broken, radii, unit, v_max, rule, **pressures)
    assert after.total == pytest.approx(liquid.total, rel=1e-12)
    assert np.all(after.volume <= v_max[~broken] * (1 + 1e-12))
    assert np.all(after.volume >= liquid.volume[~broken])
    assert np.all(after.film >= liquid.film)
    # every grain that kept a bridge that draws passed its share on, up to the cap
    drawing = np.ones(len(after.pairs), bool)
    if rule in ("pressure", "mani"):
        drawing = pressures["bridge_pressure"][~broken] < 1
    lost_all = np.setdiff1d(liquid.pairs[broken].ravel(), after.pairs[drawing].ravel())
    gained = after.film - liquid.film
    capped = after.volume >= v_max[~broken] * (1 - 1e-12)
    full_grains = np.unique(after.pairs[capped].ravel())
    free = np.setdiff1d(np.arange(len(radii)), np.r_[lost_all, full_grains])
    assert np.all(gained[free] <= 1e-15 * liquid.total)


def test_formation_draws_from_the_films_by_the_liqcontrol_rule():
    # digest §4.4: each grain gives (V_film - V_min)/n_new to each new bridge, capped at V_max
    liquid = PendularLiquid(np.empty((0, 2)), [], [0.004, 0.002, 0.001, 0.0])
    after = form_bridges(liquid, [[0, 1], [0, 2], [2, 3]], v_max=0.0025)
    # 0-1: 0.002 + 0.002 = 0.004, capped at 0.0025, taken in proportion (0.00125 from each)
    # 0-2: 0.002 + 0.001 / 2 = 0.0025; 2-3: 0.0005 + 0
    assert after.volume == pytest.approx([0.0025, 0.0025, 0.0005], rel=1e-15)
    assert after.film == pytest.approx([0.004 - 0.00125 - 0.002, 0.002 - 0.00125, 0.0, 0.0], abs=1e-18)
    assert after.total == pytest.approx(liquid.total, rel=1e-12)


def test_formation_refuses_a_pair_that_has_a_bridge():
    liquid, _ = _line_of_grains()
    with pytest.raises(ValueError, match="no bridge yet"):
        form_bridges(liquid, [[2, 1]], v_max=0.057)


def test_ruptured_mask_follows_eq_5():
    liquid = PendularLiquid([[0, 1], [1, 2]], [0.03, 0.03], np.zeros(3))
    s_c = rupture_distance(0.03, 1.0, 0.0)
    assert ruptured(liquid, [s_c * (1 - 1e-9), s_c * (1 + 1e-9)], bridge_radii(liquid.pairs, np.ones(3)), 0.0).tolist() == [False, True]


@pytest.mark.yade
@pytest.mark.parametrize("law, theta_deg", [("chapter", 5.0), ("willett", 0.0)])
def test_bridge_pull_on_yade_spheres(tmp_path, law, theta_deg):
    # `python -m hmdem.wet bridge`: the force YADE applies follows Eq. 4 along the pull (it starts
    # at A1's contact value), the bridge ruptures at Eq. 5's s_c within one step's travel, and
    # its liquid is all back in the films (conserved to round-off, digest §4.4)
    import csv
    import json

    from hmdem.wet.__main__ import TIMESERIES, main

    radius, gamma, theta = 61e-6, 0.0728, np.radians(theta_deg)
    out = tmp_path / "pull"
    assert main(["bridge", "--force-law", law, "--theta", str(theta_deg), "--resolution", "200",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["s_c_eq5_m"] == pytest.approx(rupture_distance(0.03 * radius**3, radius, theta), rel=1e-12)
    assert 0 < summary["rupture_overshoot_over_travel"] <= 1 + 1e-9
    assert summary["peak_force_n"] == pytest.approx(2 * np.pi * radius * gamma * np.cos(theta), rel=1e-9)
    assert summary["max_force_rel_error"] < 1e-9
    assert summary["force_after_rupture_n"] == 0
    assert summary["liquid_volume_defect"] < 1e-12
    with open(out / "timeseries.csv") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == TIMESERIES
    last = dict(zip(rows[0], map(float, rows[-1])))
    assert last["volume"] == 0 and last["film_volume"] == pytest.approx(0.03 * radius**3, rel=1e-12)
    assert (out / "force.png").stat().st_size > 0
    import tomllib

    # the replay command, not the bare subcommand (a field named "command" overwrote it until session 76)
    assert tomllib.loads((out / "config.toml").read_text())["run"]["command"].startswith("python -m hmdem.wet bridge")


@pytest.mark.parametrize("flags, message", [
    (["--volume", "1e-12"], "--volume: must be at most V_max"),
    (["--theta", "90"], "--theta: must be an angle in [0, 90) degrees"),
    (["--radius", "-1"], "--radius: must be a finite number > 0"),
])
def test_bridge_bad_input_is_one_line_and_writes_nothing(tmp_path, flags, message):
    import subprocess
    import sys

    out = tmp_path / "never"
    done = subprocess.run([sys.executable, "-m", "hmdem.wet", "bridge", *flags, "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_pendular_step_breaks_forms_and_balances_forces():
    # three unit spheres on the x axis: 0-1 stretched past s_c, 1-2 touching with no bridge yet
    from hmdem.wet.pendular import BridgeModel, pendular_step

    s_c = rupture_distance(0.03, 1.0, 0.0)
    centres = np.array([[0.0, 0, 0], [2.0 + 1.01 * s_c, 0, 0], [4.0 + 1.01 * s_c, 0, 0]])
    liquid = PendularLiquid([[0, 1]], [0.03], [0.0, 0.0, 0.02])
    after, forces, broken = pendular_step(liquid, centres, np.ones(3), BridgeModel(1.0, 0.0), touching=[[2, 1]])
    assert broken == 1
    # the broken bridge's 0.015 on grain 1 stays in its film (no intact bridge yet), then the new
    # bridge 1-2 takes grain 1's film 0.015 and grain 2's 0.02 (digest §4.4, §4.5)
    assert after.pairs.tolist() == [[1, 2]] and after.volume == pytest.approx([0.035], rel=1e-15)
    assert after.film == pytest.approx([0.015, 0.0, 0.0], abs=1e-18)
    # Eq. 4 at contact, attractive, and the forces sum to zero (action and reaction)
    assert forces[1] == pytest.approx([2 * np.pi, 0, 0], rel=1e-12)
    assert forces.sum(axis=0) == pytest.approx(np.zeros(3), abs=1e-12)


@pytest.mark.parametrize("rule", ["pressure", "mani"])
def test_pressure_rules_share_alike_without_surface_tension(rule):
    # a review found that at gamma = 0 (eta^coh = 0, forces off) every P_f - P_i was 0, so the
    # pressure rules kept ruptured liquid in the films; the weights scale with gamma, which cancels
    from hmdem.wet.pendular import BridgeModel, pendular_step

    s_c = rupture_distance(0.01, 1.0, np.radians(5.0))
    # chain 0-1-2: bridge 0-1 stretched past rupture, bridge 1-2 touching and intact
    centres = np.array([[0.0, 0, 0], [2.0 + 1.01 * s_c, 0, 0], [4.0 + 1.01 * s_c, 0, 0]])
    liquid = PendularLiquid([[0, 1], [1, 2]], [0.01, 0.01], np.zeros(3))
    runs = [pendular_step(liquid, centres, np.ones(3), BridgeModel(gamma, np.radians(5.0), rule=rule))[0]
            for gamma in (0.0, 0.0728, 1.0)]
    for after in runs:
        # grain 1's half of the broken bridge goes to its intact bridge; grain 0 has none, keeps its half
        assert after.volume == pytest.approx([0.015], rel=1e-12)
        assert after.film == pytest.approx([0.005, 0.0, 0.0], abs=1e-15)


def test_pendular_step_caps_new_bridges_at_their_own_v_max():
    # V_max = 0.057 R^3 of the pair's effective radius (digest §4.4); the rest stays in the films
    from hmdem.wet.pendular import BridgeModel, pendular_step

    r = 61e-6
    centres = np.array([[0.0, 0, 0], [2 * r, 0, 0]])
    liquid = PendularLiquid(np.empty((0, 2)), [], [0.1 * r**3, 0.1 * r**3])
    after, _, _ = pendular_step(liquid, centres, [r, r], BridgeModel(0.0728, 0.0), touching=[[0, 1], [1, 0]])
    assert after.volume == pytest.approx([0.057 * r**3], rel=1e-12)
    assert after.film == pytest.approx([0.0715 * r**3] * 2, rel=1e-12)


def test_dry_pairs_get_no_bridge_and_empty_inputs_pass():
    from hmdem.wet.pendular import BridgeModel, pendular_step

    liquid = PendularLiquid(np.empty((0, 2)), [], [0.0, 0.0])
    after, forces, broken = pendular_step(liquid, [[0.0, 0, 0], [2.0, 0, 0]], [1.0, 1.0], BridgeModel(1.0, 0.0),
                                          touching=[[0, 1]])
    assert len(after.pairs) == 0 and broken == 0 and not forces.any()
    empty = rupture_bridges(liquid, np.zeros(0, bool), [1.0, 1.0], np.empty((0, 3)), v_max=0.057)
    assert len(empty.pairs) == 0 and empty.total == 0
    with pytest.raises(ValueError, match="boolean mask"):
        rupture_bridges(_line_of_grains()[0], [0, 1], np.ones(5), _line_of_grains()[1], v_max=0.057)
    with pytest.raises(ValueError, match="two different grains"):
        form_bridges(PendularLiquid(np.empty((0, 2)), [], [1.0, 1.0]), [[1, 1]], v_max=0.057)


def test_pendular_step_in_the_plane_and_across_a_periodic_boundary():
    # discs in 2D, the pair joined across x = 0 / x = 10: its gap is 0.1, not 5.9
    from hmdem.wet.pendular import BridgeModel, pendular_step

    liquid = PendularLiquid([[0, 1]], [0.03], [0.0, 0.0])
    centres = np.array([[1.05, 5.0], [8.95, 5.0]])
    after, forces, broken = pendular_step(liquid, centres, [1.0, 1.0], BridgeModel(1.0, 0.0), period=[10.0, np.inf])
    assert broken == 0 and forces.shape == (2, 2)
    # grain 0 is pulled towards its partner's image at x = -1.05, i.e. in -x
    assert forces[0] == pytest.approx([-bridge_force(0.1, 0.03, 1.0, 1.0, 0.0), 0.0], rel=1e-9)


@pytest.mark.yade
def test_a_bridge_pulls_a_free_sphere_in_with_its_work():
    # a free sphere released at half Eq. 5's s_c: its kinetic energy in YADE equals the work of
    # Eq. 4 from s0 (quadrature), a check of the force's size, direction and the adapter. YADE's
    # leapfrog is second order, and 442 steps leave ~5e-6 (measured); bound 1e-4
    from scipy.integrate import quad

    from hmdem.dem.spheres import SphereAssembly
    from hmdem.wet.pendular import BridgeModel, pendular_step

    r, gamma, volume = 61e-6, 0.0728, 0.03 * 61e-6**3
    s0 = 0.5 * rupture_distance(volume, r, 0.0)
    scene = SphereAssembly([[0, 0, 0], [2 * r + s0, 0, 0]], [r, r])
    scene.hold(0)
    liquid = PendularLiquid([[0, 1]], [volume], [0.0, 0.0])
    mass, model = scene.masses()[1], BridgeModel(gamma, 0.0)
    gap = s0
    while gap > 0.05 * s0:
        liquid, forces, _ = pendular_step(liquid, scene.positions(), [r, r], model)
        scene.set_external_forces(forces)
        scene.step()
        before, gap = gap, scene.positions()[1, 0] - 2 * r
    # leapfrog's velocity is the half step's: read the work to the step's middle
    work = quad(lambda s: bridge_force(s, volume, r, gamma, 0.0), 0.5 * (before + gap), s0, epsrel=1e-12)[0]
    assert 0.5 * mass * scene.velocities()[1, 0] ** 2 == pytest.approx(work, rel=1e-4)
    assert len(liquid.pairs) == 1 and liquid.volume[0] == volume


def test_film_flow_conserves_liquid_and_runs_down_the_pressure():
    # A9: with a symmetric omega the rates sum to zero (1e-12 absolute, R = gamma = 1, omega = 0.01,
    # the chapter's value); A10: between two bridges on one grain, liquid goes from the higher P
    # (less negative) to the lower, at (R/gamma) omega (P_j - P_i)
    from hmdem.wet.liquid import film_flow_rates

    liquid, unit = _line_of_grains()  # bridges 0-1, 1-2, 2-3, 1-4
    pressure = np.array([-3.0, -1.0, -2.0, -5.0])
    rates = film_flow_rates(liquid, pressure, np.ones(5), 1.0, 0.01)
    # grain 1 joins bridges 0, 1, 3; grain 2 joins 1 and 2
    assert rates == pytest.approx(0.01 * np.array([(-1 + 3) + (-5 + 3), (-3 + 1) + (-5 + 1) + (-2 + 1),
                                                   (-1 + 2), (-3 + 5) + (-1 + 5)]), rel=1e-12)
    assert abs(rates.sum()) < 1e-12
    pair = PendularLiquid([[0, 1], [1, 2]], [0.01, 0.02], np.zeros(3))
    two = film_flow_rates(pair, [-4.0, -2.0], np.ones(3), 1.0, 0.01)
    assert two[0] > 0 > two[1] and two[0] == pytest.approx(0.02, rel=1e-12)
    _, liquid, radii, _, _ = _random_assembly(3)
    rng = np.random.default_rng(3)
    rates = film_flow_rates(liquid, rng.uniform(-10, 0, len(liquid.pairs)), radii, 1.0, 0.01)
    assert abs(rates.sum()) < 1e-12
