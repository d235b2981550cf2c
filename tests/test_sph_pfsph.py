"""sph_bridge PF-SPH core (issue 5): kernel, cell lists, density and pair forces (seed 000 digest §2, §7)."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq, minimize_scalar

from sph_bridge.cells import CellGrid
from sph_bridge.kernel import (INTERACTION_RANGE, interaction_shape, lattice_sum, support, wendland,
                               wendland_gradient_over_r)
from sph_bridge.pfsph import accelerations, density, pressure


def test_wendland_kernel_has_unit_integral():
    # digest §7 #1: 21/(2 pi h^3) (1-q)^4 (1+4q) integrates to 1 (the printed (1-q)^3 form to 0.70)
    h = 0.37
    integral = quad(lambda r: 4 * math.pi * r * r * wendland(r, h), 0.0, h, epsabs=1e-13, epsrel=1e-13)[0]
    assert abs(integral - 1.0) < 1e-6


def test_kernel_gradient_is_the_derivative_of_the_kernel():
    # grad_i W_ij = r_ij (1/r) dW/dr: check (1/r) dW/dr against a central difference of W
    h = 1.3
    for r in np.linspace(0.05, 1.25, 13):
        step = 1e-6
        slope = (wendland(r + step, h) - wendland(r - step, h)) / (2 * step)
        assert abs(r * wendland_gradient_over_r(r, h) - slope) < 1e-7 * abs(wendland(0.0, h) / h)
    assert wendland(h, h) == 0.0 and wendland_gradient_over_r(h, h) == 0.0


def test_lattice_density_and_neighbour_count():
    # digest §7 #2, #3: h = 40^(1/3) dx = 3.41995 dx, 170 neighbours within h on a cubic lattice,
    # lattice sum 1.00195 (so bulk density 1.00195 m/dx^3)
    dx = 1e-3
    h = support(dx)
    assert h / dx == pytest.approx(3.41995, abs=5e-6)
    assert lattice_sum(h, dx) == pytest.approx(1.00195, rel=1e-4)
    idx = np.arange(-4, 5)
    i, j, k = np.meshgrid(idx, idx, idx, indexing="ij")
    r = dx * np.sqrt(i**2 + j**2 + k**2)
    assert np.count_nonzero((r > 0) & (r < h)) == 170


def lattice(n, dx):
    axis = (np.arange(n) + 0.5) * dx
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)


def sph_density(pos, mass, h, lo, hi, periodic):
    grid = CellGrid(lo, hi, periodic, h)
    cell, order, start = grid.bin(pos)
    return density(pos, mass, h, cell, order, start, grid.neighbours, grid.shifts, grid.inner)


def test_periodic_lattice_density_is_the_bulk_value_everywhere():
    # a fully periodic 18^3 lattice has no surface: every particle sums to the lattice sum
    dx, n = 1e-3, 18
    h = support(dx)
    pos = lattice(n, dx)
    rho = sph_density(pos, np.full(len(pos), 1000 * dx**3), h, [0, 0, 0], [n * dx] * 3, [True] * 3)
    assert np.allclose(rho, 1000 * lattice_sum(h, dx), rtol=1e-12)


def brute_force_density(pos, mass, h, length, periodic):
    d = pos[:, None, :] - pos[None, :, :]
    for a in range(3):
        if periodic[a]:
            d[:, :, a] -= length[a] * np.round(d[:, :, a] / length[a])
    r = np.sqrt((d**2).sum(-1))
    w = np.vectorize(wendland)(r, h)
    return (w * mass[None, :]).sum(1)


def test_cell_list_density_matches_all_pairs():
    # random particles, periodic along x only, some outside the box along z (edge cells)
    rng = np.random.default_rng(3)
    h = 0.2
    length = np.array([1.0, 0.9, 0.8])
    pos = rng.random((700, 3)) * length
    pos[:20, 2] += 0.15  # beyond hi on a non-periodic axis
    mass = rng.uniform(0.5, 1.5, len(pos))
    periodic = [True, False, False]
    rho = sph_density(pos, mass, h, [0, 0, 0], length, periodic)
    assert np.allclose(rho, brute_force_density(pos, mass, h, length, periodic), rtol=1e-12)


def test_interaction_force_shape():
    # digest §2.7: F(0) = 7 s, sign change at r = 0.675 h, most attractive at 0.862 h with -0.324 s,
    # zero from 2 h
    assert interaction_shape(0.0, 1.0) == 7.0
    assert brentq(lambda r: interaction_shape(r, 1.0), 0.3, 0.8) == pytest.approx(0.675, abs=5e-4)
    well = minimize_scalar(lambda r: interaction_shape(r, 1.0), bounds=(0.7, 1.2), method="bounded")
    assert well.x == pytest.approx(0.862, abs=1e-3) and well.fun == pytest.approx(-0.324, abs=5e-4)
    assert interaction_shape(INTERACTION_RANGE, 1.0) == 0.0


def test_pair_forces_conserve_momentum():
    # digest §7 #4: pressure, viscous and pairwise forces are antisymmetric, so with fluid only
    # and no gravity sum_i m_i a_i = 0 to round-off
    rng = np.random.default_rng(7)
    dx = 1e-3
    h = support(dx)
    pos = lattice(12, dx) + rng.normal(0, 0.1 * dx, (12**3, 3))
    n = len(pos)
    mass = np.full(n, 1000 * dx**3)
    length = np.array([12 * dx] * 3)
    grid = CellGrid([0, 0, 0], length, [False] * 3, h)
    cell, order, start = grid.bin(pos)
    rho = density(pos, mass, h, cell, order, start, grid.neighbours, grid.shifts, grid.inner)
    p = pressure(rho, np.full(n, 1000.0), c0=2.0)
    vel = rng.normal(0, 0.05, (n, 3))
    acc = accelerations(pos, vel, mass, rho, p, np.full(n, 1e-3), np.ones(n, bool), 3e-5, 8e-6, h,
                        np.zeros(3), cell, order, start, grid.neighbours, grid.shifts, grid.forward)
    force = mass[:, None] * acc
    assert np.abs(force.sum(0)).max() < 1e-13 * np.abs(force).sum(0).max()
    assert np.abs(force).sum() > 0  # forces are there to cancel


def brute_force_accelerations(pos, vel, mass, rho, p, mu, fluid, s_ff, s_sf, h, gravity, length, periodic):
    """Eq. 11 over all ordered pairs: the force on each fluid particle from every other particle."""
    d = pos[:, None, :] - pos[None, :, :]
    for a in range(3):
        if periodic[a]:
            d[:, :, a] -= length[a] * np.round(d[:, :, a] / length[a])
    r = np.sqrt((d**2).sum(-1))
    np.fill_diagonal(r, np.inf)
    shape = np.vectorize(interaction_shape)(r, h)
    grad = np.vectorize(wendland_gradient_over_r)(r, h)
    s = np.where(fluid[None, :], s_ff, s_sf)
    p_seen = np.where(fluid[None, :], p[None, :], np.maximum(p[None, :], 0.0))  # a wall only pushes
    f = s * shape / r - mass[:, None] * mass[None, :] * (p[:, None] / rho[:, None] ** 2 + p_seen / rho[None, :] ** 2) * grad
    visc = mass[:, None] * mass[None, :] * (mu[:, None] + mu[None, :]) / (rho[:, None] * rho[None, :]) * grad
    force = (f[..., None] * d).sum(1) + (visc[..., None] * (vel[:, None, :] - vel[None, :, :])).sum(1)
    return np.where(fluid[:, None], force / mass[:, None] + gravity, 0.0)


def test_once_per_pair_forces_match_all_pairs_on_any_thread_count():
    # accelerations() evaluates each pair once and gives its force to both particles: it must
    # equal the sum over all ordered pairs (fluid and wall particles mixed, a wall's pressure
    # clamped, periodic along x, some particles beyond the box along z), and its fixed split into
    # chunks makes 1 and 2 threads agree to the bit
    import numba

    rng = np.random.default_rng(5)
    h = 0.19
    length = np.array([1.0, 0.9, 0.8])
    pos = rng.random((700, 3)) * length
    pos[:20, 2] += 0.15
    n = len(pos)
    fluid = rng.random(n) < 0.7
    mass, rho = rng.uniform(0.5, 1.5, n), rng.uniform(900.0, 1100.0, n)
    p, mu, vel = rng.normal(0.0, 50.0, n), rng.uniform(1e-3, 2e-3, n), rng.normal(0.0, 0.1, (n, 3))
    periodic = [True, False, False]
    gravity = np.array([0.0, 0.0, -9.81])
    grid = CellGrid([0, 0, 0], length, periodic, h, reach=2)
    lists = (*grid.bin(pos), grid.neighbours, grid.shifts, grid.forward)
    expected = brute_force_accelerations(pos, vel, mass, rho, p, mu, fluid, 3e-2, 1e-2, h, gravity, length, periodic)
    runs = []
    for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
        numba.set_num_threads(threads)
        runs.append(accelerations(pos, vel, mass, rho, p, mu, fluid, 3e-2, 1e-2, h, gravity, *lists))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert np.abs(runs[0] - expected).max() < 1e-12 * np.abs(expected).max()
    assert np.array_equal(runs[0], runs[-1])
    assert np.all(runs[0][~fluid] == 0.0) and np.abs(expected[fluid] - gravity).min() > 0


def flat_wall_scene(dx=1e-3, n=12, depth=10):
    """Fluid on the lattice above a 3-layer wall whose nominal surface is z = 0, periodic in x, y."""
    from sph_bridge.geometry import lattice_block, wall_slab

    length = n * dx
    fluid = lattice_block([0, 0, 0], [length, length, depth * dx], dx)
    wall = wall_slab(2, 0.0, +1, [0, 0, 0], [length, length, 0], dx)
    pos = np.concatenate([fluid, wall])
    is_fluid = np.zeros(len(pos), bool)
    is_fluid[: len(fluid)] = True
    grid = CellGrid([0, 0, -3 * dx], [length, length, (depth + 4) * dx], [True, True, False], support(dx), reach=1)
    return pos, is_fluid, grid


def test_proximity_ratio_and_normal_at_a_flat_wall():
    # seed 000 Eq. 21: phi = 0.5 on the nominal surface, 1 from h into the fluid; the normal
    # points into the fluid (+z). A particle pushed 0.3 dx into the wall has phi < 0.5 and
    # bounces back along +z by beta dx (1 - phi/0.5) (Eq. 24). phi = 1 - n_wall/n_bulk
    # (decisions #35), so a first-layer particle at a free surface or contact line, with fluid
    # neighbours missing, still reads its distance from the wall
    from sph_bridge.walls import bounce_back, proximity

    dx = 1e-3
    h = support(dx)
    bulk = lattice_sum(h, dx) / dx**3
    pos, is_fluid, grid = flat_wall_scene(dx)
    probe = np.flatnonzero(is_fluid & (np.abs(pos[:, 0] - 6.5 * dx) < 1e-9) & (np.abs(pos[:, 1] - 6.5 * dx) < 1e-9))
    first = probe[np.argmin(pos[probe, 2])]
    pos[first, 2] = -0.3 * dx
    cell, order, start = grid.bin(pos)
    lists = (cell, order, start, grid.neighbours, grid.shifts, grid.inner)
    mass = np.where(is_fluid, 1000.0, 1200.0) * dx**3
    rho, phi, normal, _ = proximity(pos, mass, is_fluid, h, bulk, *lists)
    assert np.array_equal(rho, density(pos, mass, h, *lists))  # the step's density, from the same pass
    deep = is_fluid & (pos[:, 2] > h + dx)
    assert np.allclose(phi[deep], 1.0)
    assert phi[first] < 0.5
    assert np.allclose(normal[first], [0, 0, 1], atol=1e-12)
    z_before = pos[first, 2]
    vel = np.ones((len(pos), 3))
    assert bounce_back(pos, (vel,), phi, normal, is_fluid, dx).tolist() == [first]
    assert pos[first, 2] - z_before == pytest.approx(dx * (1 - phi[first] / 0.5), rel=1e-12)
    assert np.all(vel[first] == 0) and np.all(vel[probe[1]] == 1)
    # on the nominal surface the wall is the mirror image of a fluid half-lattice, so its number
    # density is half the (half-offset) lattice sum: phi = 0.5 to the lattice sums' difference
    pos[first, 2] = 0.0
    cell, order, start = grid.bin(pos)
    lists = (cell, order, start, grid.neighbours, grid.shifts, grid.inner)
    phi = proximity(pos, mass, is_fluid, h, bulk, *lists)[1]
    k = np.arange(-4, 5)
    i, j, k = np.meshgrid(k, k, k, indexing="ij")
    w = np.vectorize(wendland)(dx * np.sqrt(i**2 + j**2 + (k + 0.5) ** 2), h)
    wall_side = w[k < 0].sum()  # layers at 0.5, 1.5, 2.5 dx behind the surface (3.5 dx is beyond h)
    assert phi[first] == pytest.approx(1.0 - wall_side / bulk, rel=1e-12)
    assert abs(phi[first] - 0.5) < 0.01
    # the same particle alone on the wall (no fluid neighbours: a contact line's extreme) reads
    # the same phi, so it is not bounced
    alone = np.concatenate([pos[first:first + 1], pos[~is_fluid]])
    alone_fluid = np.zeros(len(alone), bool)
    alone_fluid[0] = True
    cell, order, start = grid.bin(alone)
    phi_alone = proximity(alone, np.ones(len(alone)), alone_fluid, h, bulk, cell, order, start, grid.neighbours,
                          grid.shifts, grid.inner)[1]
    assert phi_alone[0] == pytest.approx(phi[first], rel=1e-12)


def test_a_step_with_bounces_sums_the_density_as_a_full_pass_would():
    # a step re-sums the density only within h of the particles that bounced back (and wraps only
    # them): what it ends with is, to the bit, the full sum at the final positions. The box puts
    # a cell boundary at z = -0.2 dx, which the bounced particles cross (-0.4 dx up to above it),
    # so the cells whose particle order changed are among those re-summed
    from sph_bridge.simulation import Simulation, SphParameters

    dx = 1e-3
    pos, is_fluid, grid = flat_wall_scene(dx)
    params = SphParameters(dx=dx, c0=2.0, s_ff=0.0, s_sf=0.0, gravity=(0.0, 0.0, -9.81))
    lo, hi = [0.0, 0.0, -3.7 * dx], [12 * dx, 12 * dx, 13.8 * dx]  # 5 cells of 3.5 dx along z
    sim = Simulation(pos[is_fluid], pos[~is_fluid], params, lo, hi, (True, True, False))
    assert sim.grid.cell_width[2] == pytest.approx(3.5 * dx)
    low = np.flatnonzero(sim.fluid & (sim.pos[:, 2] < dx))[::7]
    sim.vel[low, 2] = -0.9 * dx / sim.dt  # 0.4 dx into the wall in one step: they bounce
    sim.step()
    assert sim.record.bounced == len(low)
    assert np.all(sim.pos[low, 2] > -0.2 * dx)  # back over the boundary they had crossed
    full = density(sim.pos, sim.mass, sim.h, sim.cell, sim.order, sim.start, sim.grid.neighbours, sim.grid.shifts,
                   sim.grid.inner)
    assert np.array_equal(sim.rho[sim.fluid], full[sim.fluid])


def test_wall_particles_mirror_the_fluid_velocity():
    # seed 000 Eq. 25 with a wall at rest: a uniform fluid velocity U gives every wall particle
    # within reach of the fluid -U, so the Morris term sees 2U across the wall (no slip)
    from sph_bridge.walls import wall_state

    dx = 1e-3
    pos, is_fluid, grid = flat_wall_scene(dx)
    vel = np.where(is_fluid[:, None], np.array([0.3, -0.1, 0.0]), 0.0)
    cell, order, start = grid.bin(pos)
    seen, _ = wall_state(pos, vel, np.zeros(len(pos)), np.full(len(pos), 1000.0), is_fluid, np.zeros(3), support(dx),
                         cell, order, start, grid.neighbours, grid.shifts, grid.inner)
    assert np.allclose(seen[~is_fluid], [-0.3, 0.1, 0.0], rtol=1e-12)
    assert np.array_equal(seen[is_fluid], vel[is_fluid])


def test_verlet_steps_conserve_momentum_in_a_periodic_fluid():
    # digest §7 #4: no walls, no gravity, every pair force on (pressure, viscosity, pairwise):
    # total momentum stays at its initial value to round-off over the steps
    from sph_bridge.simulation import Simulation, SphParameters

    dx = 5e-4
    n = 18  # 5 cells of h per periodic length (pairwise force range 2h)
    rng = np.random.default_rng(11)
    fluid = lattice(n, dx) + rng.normal(0, 0.05 * dx, (n**3, 3))
    params = SphParameters(dx=dx, c0=1.5, rho0_fluid=930.0, s_ff=3e-5, s_sf=8e-6, gravity=(0.0, 0.0, 0.0))
    sim = Simulation(fluid, np.zeros((0, 3)), params, [0, 0, 0], [n * dx] * 3, (True, True, True))
    sim.vel[:] = rng.normal(0, 0.02, sim.vel.shape)
    p_start = (sim.mass[:, None] * sim.vel).sum(0)
    scale = (sim.mass[:, None] * np.abs(sim.vel)).sum()
    for _ in range(5):
        sim.step()
    p_end = (sim.mass[:, None] * sim.vel).sum(0)
    assert np.abs(p_end - p_start).max() < 1e-12 * scale
    assert np.abs(sim.acc).max() > 1.0  # the forces are not trivially zero


def test_annealing_kicks_reach_their_thermal_speed_and_carry_no_momentum():
    # decisions #59: with the damping gamma as friction the kicks are an Ornstein-Uhlenbeck step,
    # so each velocity component of a free particle settles to a Gaussian of rms u, whatever
    # gamma dt; their mean is taken out each step, so the total momentum stays 0 to round-off.
    # 1,000 particles 4h apart (no SPH neighbours; they wander ~0.3h), 3,000 components: the
    # sample rms scatters by ~1.3 %, the bound is 5 %
    from sph_bridge.simulation import Simulation, SphParameters

    dx, n, u = 5e-4, 10, 0.15
    params = SphParameters(dx=dx, c0=1.5, gravity=(0.0, 0.0, 0.0), damping=5000.0, anneal=u, seed=3)
    spacing = 4.0 * params.h
    fluid = np.stack(np.meshgrid(*[np.arange(n) * spacing] * 3, indexing="ij"), -1).reshape(-1, 3)
    sim = Simulation(fluid, np.zeros((0, 3)), params, [0, 0, 0], [n * spacing] * 3, (True, True, True))
    sim.anneal_end = math.inf  # hold the kicks at full strength
    for _ in range(100):  # gamma dt = 0.47: 47 relaxation times
        sim.step()
    assert np.abs(sim.acc).max() == 0.0  # the particles are free
    assert np.sqrt((sim.vel**2).mean()) == pytest.approx(u, rel=0.05)
    assert np.abs(sim.vel.sum(axis=0)).max() < 1e-12 * np.abs(sim.vel).sum()


def test_closed_hydrostatic_column():
    # Issue 5 / digest §7 #5: water between two 3-layer walls (periodic sideways, dx = 1 mm,
    # 16 layers, c0 with rho g H = 1 % of rho c0^2), relaxed with velocity damping at twice the
    # fundamental acoustic mode for 3 of its periods. The pressure gradient between the walls
    # must be rho g within 3 % (issue 5) and the density within 3 % of rho0 (Morris et al. 1997,
    # the paper's criterion); no particle may enter a wall. Walls take the fluid's extrapolated
    # pressure (decisions #33); with their own summation density instead the first fluid layer
    # was pulled into the wall at ~100 m/s^2.
    from sph_bridge import cases
    from sph_bridge.simulation import GRAVITY

    dx, layers = 1e-3, 16
    params, t_end = cases.hydrostatic_parameters(dx, layers, GRAVITY)
    sim = cases.channel(dx, layers, params)
    sim.run(t_end)
    result = cases.measure_hydrostatic(sim, layers * dx, GRAVITY).summary
    assert result["gradient_error"] <= 0.03
    assert result["max_density_deviation"] <= 0.03
    assert result["bounced_particles"] == 0


def test_body_force_poiseuille_flow_between_two_walls():
    # Issue 5: plane Poiseuille flow driven by a body force g_x between 3-layer walls with no-slip
    # nominal surfaces at z = 0 and H (Morris viscosity, Eq. 17; wall velocities, Eq. 25):
    # u(z) = g z (H - z) / (2 nu) at steady state, within 5 % of u_max (issue 5). dx = 1 mm,
    # H = 16 mm, nu = 2.6e-3 m^2/s so that the slowest mode decays in tau = H^2/(pi^2 nu) = 10 ms;
    # read at t = 5 tau (transient e^-5 < 1 %).
    from sph_bridge import cases
    from sph_bridge.simulation import stable_step

    dx, layers, g = 1e-3, 16, 0.8
    params, t_end = cases.poiseuille_parameters(dx, layers, g, viscosity=2.6)
    sim = cases.channel(dx, layers, params)
    sim.run(t_end)
    result = cases.measure_poiseuille(sim, layers * dx, g).summary
    assert result["max_profile_error"] <= 0.05
    # the CLI's step bound reads the run's length off the stable step with the body force as the
    # acceleration (sph_bridge/__main__.py check_poiseuille_steps): the run took that many steps
    estimate = t_end / stable_step(params.h, params.c0, g, params.rho0_fluid / params.viscosity)
    assert sim.record.steps == math.ceil(estimate)
    assert result["max_cross_velocity_m_per_s"] <= 0.01 * result["theory_max_velocity_m_per_s"]  # no cross flow


def test_command_line_run_directory_and_bad_input(tmp_path):
    # issue 5 interface: python -m sph_bridge <case> writes config.toml, summary.json,
    # timeseries.csv, a ParaView point cloud and a PNG; bad input is one line naming the
    # parameter, exit status 2, nothing written
    import json
    import subprocess
    import sys

    import meshio

    cmd = [sys.executable, "-m", "sph_bridge"]
    out = tmp_path / "p"
    proc = subprocess.run(cmd + ["poiseuille", "--layers", "8", "--out", str(out), "--quiet"], capture_output=True,
                          text=True)
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in out.iterdir()} == {"config.toml", "summary.json", "timeseries.csv", "particles.vtu",
                                                "profile.png"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["fluid_particles"] == 12 * 12 * 8
    assert summary["max_profile_error"] <= 0.05
    cloud = meshio.read(out / "particles.vtu")
    assert len(cloud.points) == summary["particles"] and "velocity" in cloud.point_data
    # config.toml replays the run and names the versions that ran it, as hmdem's runs do
    import numba
    import tomllib

    from hmdem import __version__
    run = tomllib.loads((out / "config.toml").read_text())["run"]
    assert run["command"].startswith("python -m sph_bridge poiseuille --layers 8")
    assert (run["hmdem_version"], run["numba"], run["numpy"]) == (__version__, numba.__version__, np.__version__)
    for args, name in ((["poiseuille", "--dx", "-1"], "--dx"), (["hydrostatic", "--layers", "4"], "--layers"),
                       (["poiseuille", "--viscosity", "nan"], "--viscosity"),
                       # a new-user pass: 1e300 m/s^2 overflowed to a garbage column with exit 0, and a
                       # Poiseuille run at 1e5 m/s^2 needs 2.2e6 steps (its c0 follows the flow speed)
                       (["hydrostatic", "--gravity", "1e300"], "--gravity"),
                       (["poiseuille", "--gravity", "1e5"], "--gravity"),
                       (["poiseuille", "--viscosity", "1e-6"], "--viscosity")):
        bad = tmp_path / "bad"
        proc = subprocess.run(cmd + args + ["--out", str(bad)], capture_output=True, text=True)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1 and name in lines[0]
        assert not bad.exists()
