"""Run directory of a coupled (movable-grain) run: the linear contract plus the fracture map,
the contact force network and the micro-mechanical summary keys (issue 3)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ..flow.diagnostics import regime_at_breakthrough
from ..flow.fluids import FluidPair
from ..cli import stop_note
from ..plots import plot_force_chains, plot_fracture_chronology
from ..report import dimension_note, pattern_fractal_dimension, radial_pattern_dimension, write_run
from ..snapshots import read_series
from .geometry import contact_gaps
from .micromechanics import (chronology_counts, energy_partition, fracture_and_side_resistance, fracture_guidance,
                             fracture_timing, fracture_zone_dimension, lowest_path_resistance,
                             pipe_resistance)
from .radial import classify_radial_regime, domain_perimeter

GPA = 1e9


def fracture_resistance_series(run: Path) -> list[tuple[float, int, float, float]]:
    """Per ParaView snapshot of a radial run directory (``--snapshots``): time, how many opened
    contacts the fluid has reached, and the lowest R_s of those fractures and of their sides
    (:func:`~hmdem.coupling.micromechanics.fracture_and_side_resistance`; digest H8)."""
    import tomllib

    net = np.load(run / "network.npz")
    closed_at_start = np.load(run / "fractures.npz")["initially_closed"]
    fluids = FluidPair(**tomllib.loads((run / "config.toml").read_text())["fluids"])
    pipe_domains, length = net["pipe_domains"], net["pipe_length"]
    return [(t, *fracture_and_side_resistance(pipe_domains, length, aperture, opened, closed_at_start, saturation,
                                              net["inlet_domains"], fluids.viscosity_inv))
            for t, saturation, aperture, opened in read_series(run, len(net["domain_volume"]))]


def write_radial_run(out: Path, sc, model, state, rec, argv, snapshots=None, packing=None,
                     launcher: str | None = None) -> dict:
    """The radial run directory (:func:`~hmdem.report.write_run` plus the fracture map, force
    chains and micro-mechanical keys). ``launcher``: the YADE launcher that called the CLI, if
    one did; config.toml's [launcher] names it beside the CLI command it ran."""
    grains, net = model.grains, sc.net
    positions = model.positions
    initial_positions = sc.packing.centres.copy()
    # D_f on the reference configuration: a rearranged sample can fold triangles over each other.
    # The regime reads the mass-radius dimension; App. E's box counting is reported beside it
    d_f = d_box = float("nan")
    if state.invaded.any():
        d_f, d_box = radial_pattern_dimension(sc, state), pattern_fractal_dimension(sc, state)
    # H5's second figure: the fracture zone's D_f, its cracks where they opened in the packing
    d_fracture = fracture_zone_dimension(net, initial_positions, grains.radii, model.opened)
    # the packing's own port perimeter (decisions #21), before the network takes the moved grains
    inlet_perimeter = domain_perimeter(net, int(net.inlet_domains[0]))
    # draw and export the deformed sample
    net.points = positions
    net.domain_centroid = model.geometry.centroids(positions)
    pairs, forces = grains.contact_forces()
    opened = model.opened
    g = net.pipe_grains
    gap = contact_gaps(positions, grains.radii, g)
    cr = model.coupling_record
    # R_s on the final apertures and saturations (Figs. 15-16 report them in GPa s / m^2)
    resistance = pipe_resistance(net, sc.setup.fluids, state.saturation, model.pipes)
    path = lowest_path_resistance(net, model.pipes, resistance, net.inlet_domains, net.outlet_domains)
    timing = fracture_timing(opened, model.opened_time, net.pipe_domains, model.wetted_time, state.invasion_time)
    chronology = chronology_counts(timing, opened, model.opened_time)
    extra = {
        "regime": regime_at_breakthrough(rec.status, classify_radial_regime(int(opened.sum()), d_f)),
        "fractal_dimension": d_f,
        "fractal_dimension_box_counting": d_box,
        "fracture_fractal_dimension": d_fracture,
        "n_opened_contacts": int(opened.sum()),
        "n_open_contacts_at_end": int(model.open_now.sum()),
        "n_detached_contacts": int(model.detached.sum()),
        **chronology,
        # from the fluid's side: did it go in through the opened contacts (decisions #87)
        **fracture_guidance(model.opened_time, net.pipe_domains, model.wetted_time, state.invasion_time,
                            net.inlet_domains),
        "opening_gap_m": model.opening_gap,
        "n_floored_domains": int(model.floored.sum()),
        "n_initial_contacts": int(model.initially_closed.sum()),
        "mean_pipe_resistance_gpa_s_per_m2": float(np.mean(resistance)) / GPA,
        "lowest_path_resistance_gpa_s_per_m2": path / GPA,
        "dissipated_fraction": rec.dissipated_energy / rec.injection_energy if rec.injection_energy else float("nan"),
        # Figs. 15-16: one step's energies, with the port still air-filled and as the first contact opens
        **energy_partition(*rec.step_energies(), chronology["first_opening_time_s"]),
        "max_grain_displacement_m": float(np.linalg.norm(positions - initial_positions, axis=1).max()),
        "mean_pv_iterations": float(np.mean(cr.pv_iterations)) if cr.pv_iterations else 0.0,
        "max_pv_iterations": int(max(cr.pv_iterations)) if cr.pv_iterations else 0,
        "unconverged_pv_steps": cr.unconverged_steps,
        "pv_dt_halvings": cr.dt_halvings,
        "pv_pocket_attempts": cr.pocket_attempts,
        "dem_wall_fraction": cr.dem_seconds / rec.wall_time if rec.wall_time else float("nan"),
        "rewind_wall_fraction": cr.rewind_seconds / rec.wall_time if rec.wall_time else float("nan"),
        "dem_cycles": cr.dem_cycles,
        "dem_cycles_per_step": cr.dem_cycles / max(rec.steps, 1),
        # the P-V iteration on the numba replica, YADE confirming its pressures (decisions #65)
        "replica_wall_fraction": cr.replica_seconds / rec.wall_time if rec.wall_time else float("nan"),
        "replica_cycles": cr.replica_cycles,
        "replica_cycles_per_step": cr.replica_cycles / max(rec.steps, 1),
        "replica_confirmations": cr.confirmations,
        "replica_confirmations_failed": cr.confirmations_failed,
        "one_way": sc.coupling.one_way,
        "one_way_volume": sc.coupling.one_way_volume,
        "fixed_port": sc.fixed_port,
        "boundary_hold": sc.boundary_hold,
        # the sample's area (the polygon of its boundary grains, = the domains' signed areas
        # summed) against its start: 0 with a fixed boundary, > 0 where a loaded one yields
        "sample_area_strain": float(model.geometry.volumes(positions).sum()
                                    / model.geometry.volumes(initial_positions).sum() - 1.0),
        "sigma_m": sc.sigma,
        "inlet_domain_perimeter_m": inlet_perimeter,
        "confining_stress_pa": sc.packing.confining_stress,
    }

    stopped = stop_note(rec.status, "breakthrough")
    fracture_note = f"; fracture zone {dimension_note(d_fracture)}" if opened.any() else ""

    def files(tmp: Path) -> None:
        np.savez_compressed(tmp / "fractures.npz", opened=opened, open_at_end=model.open_now, detached=model.detached,
                            max_gap=model.max_gap, opened_time=model.opened_time,
                            initial_contact_force=model.initial_force,
                            pore_wetted_time=model.wetted_time,
                            pipe_grains=g, gap=gap,
                            aperture=net.pipe_aperture, initially_closed=model.initially_closed,
                            positions=positions, initial_positions=initial_positions, radii=grains.radii,
                            contact_pairs=pairs, contact_forces=forces)
        plot_force_chains(tmp / "force_chains.png", positions, grains.radii, pairs, forces,
                          f"{sc.case.name}: contact forces at t = {state.t:.4g} s "
                          f"({int(opened.sum())} opened contacts in red on pattern.png){stopped}",
                          fixed=grains.fixed)
        plot_fracture_chronology(tmp / "fractures.png", net, state.saturation, grains.radii, positions[g[opened]],
                                 model.opened_time[opened], timing["reached"][opened], timing["before_fluid"][opened],
                                 f"{sc.case.name}: {int(opened.sum())} opened contacts by t = {state.t:.4g} s"
                                 f"{fracture_note}\n"
                                 f"{chronology['n_opened_reached_by_fluid']} reached by the fluid, "
                                 f"{chronology['n_opened_before_fluid']} of them opened before it came;\n"
                                 f"{chronology['n_opened_in_invaded_zone']} inside the invaded zone{stopped}")

    config = {"coupling": {k: v for k, v in vars(sc.coupling).items() if k != "aperture_law"},
              "aperture_law": vars(sc.coupling.aperture_law),
              "dem": {"timestep_s": grains.timestep, "stable_timestep_s": sc.coupling.stable_dem_step,
                      "n_grains": len(grains.radii), "n_fixed": int(np.sum(grains.fixed)),
                      # boundary grains released along one axis (--boundary loaded)
                      "n_pistons": int(np.sum(~grains.fixed & ~grains.free_dofs.all(axis=1))),
                      "threads": grains.threads,
                      "damping": grains.damping, "grain_density_kg_m3": sc.grain_density,
                      "contact_stiffness_n_per_m": grains.k_n, "stiffness_ratio": grains.k_s / grains.k_n,
                      "friction": grains.friction, "fixed_port": sc.fixed_port,
                      "boundary_hold": sc.boundary_hold}}
    if launcher:
        config["launcher"] = {"command": launcher, "python": sys.executable}
    overlay = positions[g[opened]]
    return write_run(out, sc, model, state, rec, seed=0, argv=argv, summary_extra=extra, extra_files=files,
                     overlay=overlay, config_extra=config, snapshots=snapshots,
                     packing=packing)
