"""``python -m hmdem.wet shear``: the plane-shear migration run's command and run directory
(seed 002 §6.2; digest §6.2).

Writes config.toml, summary.json, timeseries.csv (``strain, t, n_bridges, n_ruptures,
v_bridges, v_films, sigma2, wall_s``; n_ruptures since the row before, volumes in m^3, sigma2 in
R^2), profiles.npz (Q(z), grains and mean x-velocity per slab at each output), profile.png, and
ParaView series grains.pvd (points: ``radius``, ``film_volume``) and bridges.pvd (lines:
``volume``, ``force``, ``pressure``) over ``snapshots/``. Ctrl-C or SIGTERM writes the run so
far with status "interrupted" (exit 130 or 143).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import CommandFailed, InputError, interrupted_status, new_run_directory, open_bar, run_record
from ..rundir import atomic_run_directory, write_json, write_rows, write_toml
from ..snapshots import write_collection
from .bridges import rupture_distance
from .liquid import PRESSURE_RULES
from .migration import diffusion_law
from .shear import INITIAL_CUT, TIMESERIES, ShearSettings, diffusion_constant, run_shear, surface_tension
from .young_laplace import MAX_TABLE_ANGLE


class _Bars:
    """tqdm bars on stderr: compaction (DEM steps, plate gap), then shear strain."""

    def __init__(self, strain: float, quiet: bool, every_s: float = 0.25):
        from tqdm import tqdm

        self.tqdm, self.strain, self.quiet, self.every_s, self.last = tqdm, strain, quiet, every_s, 0.0
        self.bar = None

    def _due(self) -> bool:
        now = time.perf_counter()
        if now - self.last < self.every_s:
            return False
        self.last = now
        return True

    def compacting(self, steps, plate_gap, radius):
        if self.quiet or not self._due():
            return
        if self.bar is None:
            self.bar = open_bar(self.tqdm, desc="compaction", unit=" steps", file=sys.stderr)
        self.bar.n = steps
        self.bar.set_postfix_str(f"plate gap {plate_gap / radius:.2f} R")

    def shearing(self, strain):
        if self.quiet or not (self._due() or strain >= self.strain):
            return
        if self.bar is None or self.bar.desc != "shear":
            self.close()
            self.bar = open_bar(self.tqdm, desc="shear", total=round(100 * self.strain, 3), unit="%", file=sys.stderr,
                                bar_format="{desc}: {n:.1f}/{total:.1f} % strain|{bar}| [{elapsed}<{remaining}]")
        self.bar.n = round(100 * min(strain, self.strain), 3)
        self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def check_shear_arguments(args) -> None:
    """Checks that need more than one flag (one line each, exit 2, nothing written)."""
    if args.redistribution in PRESSURE_RULES and math.radians(args.theta) > MAX_TABLE_ANGLE * (1 + 1e-12):
        raise InputError(f"--theta: the {args.redistribution!r} rule reads the Young-Laplace table, built for "
                         f"[0, {math.degrees(MAX_TABLE_ANGLE):g}] degrees, got {args.theta:g}")


def run_shear_command(args, argv, prog: str, launcher: str | None = None) -> int:
    check_shear_arguments(args)
    out = new_run_directory(args.out, "shear")
    from ..dem.shear_cell import ShearCell

    started = time.perf_counter()
    theta = math.radians(args.theta)
    settings = ShearSettings(args.amplitude, args.sigma0, args.cohesion_number, args.strain, theta, args.force_law,
                             args.redistribution, args.inertial_number, args.liquid_every, args.outputs)
    bars = _Bars(args.strain, args.quiet)
    cell = ShearCell(args.n, args.radius, args.pressure, stiffness=args.stiffness, friction=args.friction,
                     seed=args.seed)
    result, compaction_steps = None, None
    try:
        try:
            compaction_steps = cell.compact(lambda steps, gap: bars.compacting(steps, gap, args.radius))
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM before the shear: settings only
            pass
        except RuntimeError as exc:  # the plate never came to rest
            raise CommandFailed(f"{exc}; try fewer --n or another --pressure") from None
        else:
            bars.close()
            try:
                result = run_shear(cell, settings, bars.shearing)
            except ValueError as exc:  # no bridge starts wet
                raise CommandFailed(f"--sigma0: {exc}") from None
    finally:
        bars.close()
    taken = result is not None and len(result.frames) > 0
    status = "interrupted" if result is None else result.status
    gamma = surface_tension(args.cohesion_number, args.pressure, args.radius, theta)
    config = {"run": run_record(prog, argv),
              "cell": {"grains": args.n, "radius_m": args.radius, "polydispersity": cell.polydispersity,
                       "pressure_pa": args.pressure, "stiffness_e_over_p": args.stiffness,
                       "friction": args.friction, "density_kg_m3": cell.density,
                       "plate_side_grains": cell.plate_side, "inertial_number": args.inertial_number,
                       "seed": args.seed, "dem_timestep_s": cell.timestep},
              "liquid": {"amplitude_r3": args.amplitude, "sigma0_r": args.sigma0,
                         "cohesion_number": args.cohesion_number, "surface_tension_n_per_m": gamma,
                         "contact_angle_deg": args.theta, "force_law": args.force_law,
                         "redistribution": args.redistribution, "liquid_every": args.liquid_every,
                         "initial_cut": INITIAL_CUT},
              "shear": {"strain": args.strain, "outputs": args.outputs}}
    if launcher:
        config["launcher"] = {"command": launcher, "python": sys.executable}
    summary = shear_summary(result if taken else None, cell, settings, status, compaction_steps, started)
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        if taken:
            write_rows(tmp / "timeseries.csv", TIMESERIES, [_row(r) for r in result.rows])
            write_profiles(tmp / "profiles.npz", result, args.radius)
            write_paraview(tmp, result)
            plot_profiles(tmp / "profile.png", result, settings, args.radius, status)
    if not taken:
        stage = "compaction" if result is None else "first output"
        print(f"{prog}: interrupted in the {stage}; {out} holds the settings", file=sys.stderr)
        return interrupted_status()
    print(f"sheared to strain {result.frames[-1].strain:.3g}: D = {summary['D_over_R2']:.3g} R^2 "
          f"(the chapter's fit at eta = 0: {summary['D_chapter_over_R2']:.3g} R^2), {result.ruptures} ruptures, "
          f"liquid kept to {result.liquid_volume_defect:.1e}; run directory: {out}")
    return interrupted_status() if status == "interrupted" else 0


def _row(row):
    strain, t, bridges, ruptures, v_bridges, v_films, sigma2, wall = row
    return [f"{strain:.6g}", f"{t:.8g}", bridges, ruptures, f"{v_bridges:.17g}", f"{v_films:.17g}", f"{sigma2:.6g}",
            f"{wall:.3f}"]


def shear_summary(result, cell, settings: ShearSettings, status, compaction_steps, started) -> dict:
    summary = {"status": status, "compaction_steps": compaction_steps,
               "D_chapter_over_R2": float(diffusion_law(settings.amplitude)),
               "inertial_number": settings.inertial_number, "shear_rate_per_s": cell.shear_rate,
               "plate_gap_end_over_r": cell.plate_gap / cell.radius}
    if result is None:
        return {**summary, "wall_time_s": time.perf_counter() - started}
    d, sigma0_2 = diffusion_constant(result)
    s_c = float(rupture_distance(settings.amplitude * cell.radius**3, cell.radius, settings.contact_angle))
    residuals = [f.residual for f in result.frames]
    return {**summary,
            "D_over_R2": d,
            "sigma0_squared_fit_r2": sigma0_2,
            "sigma2_fit_residual": float(np.nanmax(residuals)) if np.isfinite(residuals).any() else math.nan,
            "strain": result.frames[-1].strain,
            "z_wall_over_r": result.z_wall / cell.radius,
            "ruptures": result.ruptures,
            "bridges_start": len(result.frames[0].pairs),
            "bridges_end": len(result.frames[-1].pairs),
            "liquid_volume_defect": result.liquid_volume_defect,
            "max_bridge_volume_over_vmax": result.max_volume_over_vmax,
            "max_gap_over_sc": result.max_gap_over_sc,
            "max_overlap_over_sc": result.max_overlap / s_c,
            "wall_time_s": time.perf_counter() - started}


def write_profiles(path: Path, result, radius: float) -> None:
    frames = result.frames
    np.savez_compressed(path, edges_over_r=result.edges / radius,
                        strain=np.array([f.strain for f in frames]), t=np.array([f.t for f in frames]),
                        q_over_r3=np.array([f.q for f in frames]) / radius**3,
                        grains=np.array([f.count for f in frames]),
                        velocity_over_plate=np.array([f.velocity for f in frames]),
                        sigma2_over_r2=np.array([f.sigma2 for f in frames]),
                        fit_amplitude_over_r3=np.array([f.fit.amplitude if f.fit else np.nan for f in frames]),
                        fit_centre_over_r=np.array([f.fit.centre if f.fit else np.nan for f in frames]),
                        fit_residual=np.array([f.residual for f in frames]))


def write_paraview(directory: Path, result) -> None:
    """snapshots/grains_NNNN.vtu and bridges_NNNN.vtu, indexed by time in grains.pvd and
    bridges.pvd. Each bridge is a line from its first grain to the nearest image of its second."""
    import meshio

    (directory / "snapshots").mkdir()
    grains, bridges = [], []
    for k, f in enumerate(result.frames):
        name = f"snapshots/grains_{k:04d}.vtu"
        meshio.Mesh(f.centres, [("vertex", np.arange(len(f.centres))[:, None])],
                    point_data={"radius": f.grain_radii, "film_volume": f.film}).write(directory / name)
        grains.append((f.t, name))
        ends = f.centres[f.pairs[:, 0]]
        m = len(f.pairs)
        name = f"snapshots/bridges_{k:04d}.vtu"
        meshio.Mesh(np.r_[ends, ends + f.branch].reshape(-1, 3), [("line", np.c_[np.arange(m), np.arange(m) + m])],
                    cell_data={"volume": [f.volume], "force": [f.force], "pressure": [f.pressure]}
                    ).write(directory / name)
        bridges.append((f.t, name))
    write_collection(directory / "grains.pvd", grains)
    write_collection(directory / "bridges.pvd", bridges)


def plot_profiles(path: Path, result, settings: ShearSettings, radius: float, status: str) -> None:
    """Q(z) at a few strains with their Gaussian fits, and sigma^2 against strain with the fitted
    and the chapter's D."""
    from ..cli import stop_note
    from ..plots import plt  # Agg backend, Debian's Axes3D warning silenced

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    middle = 0.5 * (result.edges[1:] + result.edges[:-1]) / radius
    shown = sorted({0, len(result.frames) // 2, len(result.frames) - 1})
    for k in shown:
        f = result.frames[k]
        line, = left.plot(np.where(f.count > 0, f.q, np.nan) / radius**3, middle, "o", ms=3,
                          label=f"strain {f.strain:.2f}, σ² = {f.sigma2:.1f} R²")
        if f.fit is not None:
            z = np.linspace(middle[0], middle[-1], 300)
            left.plot(f.fit.amplitude * np.exp(-(z - f.fit.centre) ** 2 / f.fit.sigma2), z, "-", lw=1,
                      color=line.get_color())
    left.set_xlabel("Q: bridge volume per grain [R³]")
    left.set_ylabel("z / R")
    left.legend(fontsize=8)
    strain = np.array([f.strain for f in result.frames])
    sigma2 = np.array([f.sigma2 for f in result.frames])
    right.plot(strain, sigma2, "ko", ms=4, label="fitted σ²")
    d, s0 = diffusion_constant(result)
    if math.isfinite(d):
        right.plot(strain, s0 + 4 * d * strain, "k-", lw=1, label=f"σ₀² + 4Dγ, D = {d:.3f} R²")
    d_chapter = float(diffusion_law(settings.amplitude))
    right.plot(strain, sigma2[0] + 4 * d_chapter * strain, "r--", lw=1,
               label=f"chapter at η = 0: D = {d_chapter:.3f} R²")
    right.set_xlabel("shear strain γ")
    right.set_ylabel("σ² [R²]")
    right.legend(fontsize=8)
    fig.suptitle(f"plane shear, A = {settings.amplitude:g} R³, η = {settings.cohesion_number:g}"
                 f"{stop_note(status, 'finished')}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
