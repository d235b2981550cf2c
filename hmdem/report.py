"""Write a complete run directory from a finished (or interrupted) flow run."""

from __future__ import annotations

import hashlib
import resource
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .cli import run_record, stop_note
from .flow.diagnostics import (classify_regime, early_peak, fractal_dimension, grain_diameter,
                               mass_radius_dimension, pattern_scales, regime_at_breakthrough)
from .flow.fluids import WEAK_COMPRESSION
from .plots import plot_pattern, plot_pressure
from .rundir import atomic_run_directory, write_json, write_rows, write_toml
from .snapshots import domain_mesh, take, write_series


def pattern_fractal_dimension(sc, state) -> float:
    """D_f of the invaded domains, box sizes from the grain scale to a quarter of the sample."""
    return fractal_dimension(sc.net, state.saturation >= 0.5, *pattern_scales(sc.net))[0]


def radial_pattern_dimension(sc, state) -> float:
    """D_f of a radial pattern: mass-radius dimension about the injection domain, from one grain
    diameter to half the pattern's reach (box counting reads a filled disc as < 1.9 here)."""
    net = sc.net
    centre = net.domain_centroid[net.inlet_domains].mean(axis=0)
    return mass_radius_dimension(net, state.saturation >= 0.5, centre, grain_diameter(net))[0]


def dimension_note(d_f: float | None) -> str:
    """D_f as titles and the closing line give it; none is read on a pattern too small for two
    box sizes, or on none (nan, or null as summary.json writes it)."""
    return f"D_f = {d_f:.3f}" if d_f is not None and np.isfinite(d_f) else "no D_f (pattern too small)"


def peak_memory_mb() -> float:
    """The largest resident memory this process has had so far [MB] (Linux ``ru_maxrss``, in kB):
    seed 004's Table 4 gives its runs' memory. In a process that ran several runs (a sweep
    worker, pytest) it covers the earlier ones too."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def summarize(sc, model, state, rec, d_f: float | None = None) -> dict:
    """The summary.json keys; ``d_f`` if already measured (a coupled run measures it on the
    reference configuration)."""
    net, fluids = sc.net, sc.setup.fluids
    times, pressures = rec.injection_pressure()
    p_in = pressures if rec.rows else np.zeros(1)
    early = early_peak(times, pressures)
    volume = net.domain_volume
    saturation = float(np.sum(state.saturation * volume) / np.sum(volume))
    entry = np.abs(fluids.entry_pressure(net.pipe_aperture[model.pipes]))
    two_phase = sc.setup.two_phase
    if d_f is None:
        d_f = pattern_fractal_dimension(sc, state) if two_phase and state.invaded.any() else float("nan")
    regime = "single phase"
    if two_phase:
        regime = regime_at_breakthrough(rec.status, classify_regime(d_f, float(np.median(p_in)), float(np.std(entry))))
    return {
        "case": sc.case.name,
        "status": rec.status,
        "status_message": rec.message,
        "regime": regime,
        "fractal_dimension": d_f,
        "breakthrough_time_s": rec.breakthrough_time,
        "breakthrough_saturation": saturation if rec.status == "breakthrough" else float("nan"),
        "final_saturation": saturation,
        "peak_injection_pressure_pa": rec.peak_injection_pressure,
        "early_peak_injection_pressure_pa": early.pressure,
        "early_peak_time_s": early.time,
        "early_peak_fell": early.fell,
        "peak_compression": rec.peak_compression,
        "weakly_compressible": rec.peak_compression <= WEAK_COMPRESSION,
        "final_injection_pressure_pa": float(p_in[-1]),
        "median_injection_pressure_pa": float(np.median(p_in)),
        "median_entry_pressure_pa": float(np.median(entry)),
        "entry_pressure_spread_pa": float(np.std(entry)),
        "injection_energy_j": rec.injection_energy,
        "dissipated_energy_j": rec.dissipated_energy,
        "steps": rec.steps,
        "eq18_steps": rec.eq18_steps,
        "eq19_steps": rec.eq19_steps,
        "eq19_bisected_steps": rec.eq19_bisected_steps,
        "linear_solves": rec.solves,
        "unsettled_active_sets": rec.unsettled_solves,
        "max_mass_balance_error": rec.max_mass_balance_error,
        "run_mass_balance_error": rec.run_mass_balance_error(sc.setup.rate, state.t),
        "simulated_time_s": state.t,
        "wall_time_s": rec.wall_time,
        "peak_memory_mb": peak_memory_mb(),
        "ca_star": sc.ca_star,
        "rate_m3_per_s_per_m": sc.setup.rate,
        "viscosity_ratio": fluids.viscosity_ratio,
        "n_domains": net.n_domains,
        "n_pipes": net.n_pipes,
        "n_inlet_domains": len(net.inlet_domains),
        "n_outlet_domains": len(net.outlet_domains),
        "n_invaded_domains": int(state.invaded.sum()),
    }


def packing_record(path, name: str | None = None) -> dict:
    """config.toml's [packing]: ``name`` (default: the file's absolute path; a sweep worker reads
    a scratch copy of the client's file) and the SHA-256 of the file's bytes."""
    path = Path(path)
    return {"file": name or str(path.resolve()), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}


def write_run(out: Path, sc, model, state, rec, seed: int, argv, summary_extra: dict | None = None,
              extra_files=None, overlay=None, config_extra: dict | None = None, snapshots=None,
              packing: dict | None = None) -> dict:
    """Write every file of the run directory into a temporary folder, then rename it to ``out``.

    Couplings add to the contract: ``summary_extra`` (keys added to or replacing the summary's),
    ``extra_files(tmp)`` writes further files, ``overlay`` (k, 2, 2) segments drawn in red on
    the pattern (e.g. opened contacts), ``config_extra`` more config.toml tables.
    ``snapshots`` (a list of :class:`~hmdem.snapshots.Snapshot`, or None): the ParaView time
    series, closed by the final state (hmdem/snapshots.py). ``packing``: config.toml's [packing]
    (:func:`packing_record`, taken when the run read its grains, so that a file moved or
    regenerated during the run neither loses the run nor names other bytes).
    """
    extra = summary_extra or {}
    summary = summarize(sc, model, state, rec, extra.get("fractal_dimension"))
    summary.update(extra)
    net = sc.net
    setup = {k: v for k, v in asdict(sc.setup).items() if k != "fluids"}
    config = {
        "run": run_record("python -m hmdem.hele_shaw", argv, case=sc.case.name, seed=seed),
        "case": {"title": sc.case.title, "geometry": sc.case.geometry, "ca_star": sc.ca_star,
                 "mean_aperture_m": sc.case.mean_aperture, "aperture_spread": sc.case.aperture_spread,
                 "contact_gap": sc.case.contact_gap, "sigma_m": sc.sigma, "length_m": sc.length},
        "fluids": asdict(sc.setup.fluids),
        "solver": setup,
        **(config_extra or {}),
    }
    if packing is not None:
        config["packing"] = packing
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", rec.columns, rec.rows)
        arrays = net.arrays()
        arrays["pipe_entry_pressure"] = sc.setup.fluids.entry_pressure(net.pipe_aperture)
        np.savez_compressed(tmp / "network.npz", **arrays)
        np.savez_compressed(tmp / "state.npz", pressure=state.pressure, saturation=state.saturation,
                            invasion_time=state.invasion_time, t=state.t)
        stopped = stop_note(rec.status, "breakthrough" if sc.setup.two_phase else "t_max")
        title = f"{case_title(sc.case)}\nCa* = {sc.ca_star:.3g}, M = {sc.setup.fluids.viscosity_ratio:.3g}, t = {state.t:.4g} s, " \
                f"{summary['regime']}, {dimension_note(summary['fractal_dimension'])}" + (f"\n{stopped.strip()}" if stopped else "")
        single_phase = None if sc.setup.two_phase else "single phase: nothing invades\n(the pressure field is in pressure.png)"
        plot_pattern(tmp / "pattern.png", net, state.saturation, title, sc.packing_radii, overlay, note=single_phase)
        marked = {"time": summary["early_peak_time_s"], "pressure": summary["early_peak_injection_pressure_pa"]}
        plot_pressure(tmp / "pressure.png", net, state.pressure, *rec.injection_pressure(),
                      f"{sc.case.name}: mean injection pressure{stopped}", marked if summary["early_peak_fell"] else None)
        write_vtu(tmp / "domains.vtu", net, state, sc.packing_radii)
        if snapshots is not None:
            # the final state closes the series as the files above have it (a run stopped inside
            # a step that keeps no snapshot holds a trial's grains at the last step's time)
            write_series(tmp, net, [s for s in snapshots if s.t != state.t] + [take(model, state)],
                         sc.packing_radii)
        if extra_files is not None:
            extra_files(tmp)
    return summary


def case_title(case) -> str:
    """The named case's title, saying which of its settings the command line changed: a vf run
    at M = 1e-3 is no longer "air into oil", nor the paper's viscous fingering (a new-user pass)."""
    from .cases import CASES

    named = CASES.get(case.name)
    if named is None:
        return case.title
    changed = [what for what, differs in (
        ("M", case.fluids.viscosity_inv != named.fluids.viscosity_inv),
        ("Ca*", case.ca_star != named.ca_star), ("the rate", case.rate != named.rate),
        ("the mean aperture", case.mean_aperture != named.mean_aperture)) if differs]
    if not changed:
        return case.title
    listed = changed[0] if len(changed) == 1 else f"{', '.join(changed[:-1])} and {changed[-1]}"
    return f"{case.title}, with {listed} changed"


def write_vtu(path: Path, net, state, radii=None) -> None:
    """Domain polygons (as their triangles) with pressure, saturation and invasion time for
    ParaView, on the grain centres (with their ``radii``, m)."""
    domain_mesh(net, net.points, state.pressure, state.saturation, state.invasion_time, radii).write(path)
