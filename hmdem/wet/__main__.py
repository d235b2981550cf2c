"""Command line: pendular liquid bridges on YADE spheres (seed 002 §3.2).

    python -m hmdem.wet bridge [--radius R] [--volume V] [--gamma G] [--theta DEG]
                               [--force-law {chapter,willett}] [--resolution N] [--out DIR]
    python -m hmdem.wet table [--theta DEG] [--out DIR]
    python -m hmdem.wet shear [--amplitude A] [--sigma0 S] [--cohesion-number ETA] [--strain G] [--n N]
                              [--pressure P] [--theta DEG] [--redistribution RULE] [--seed K] [--out DIR] ...

bridge: two equal spheres, touching; a bridge of volume V forms from their films (§4.4) and the
second sphere is pulled away at a constant speed, s_c/N per DEM step, until the bridge ruptures
(Eq. 5) and its liquid goes back to the films (§4.5). The force YADE applied to the held sphere
is logged against Eq. 4 at every step. Writes a run directory atomically: config.toml,
summary.json, timeseries.csv and force.png. Bad input is one line on stderr, exit status 2,
nothing written.

table: the Young-Laplace bridges (Eq. 3) between equal spheres at one contact angle, as suction,
force and neck against volume and gap (units R = gamma = 1) in bridge_table.npz; the rupture
distance against Eq. 5 in summary.json; Eq. 4's two laws against the table in eq4.png.

shear: liquid migration in a periodic plane-shear cell (§6.2): see hmdem.wet.shear_output.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ..cli import (InputError, OneLineParser, dispatch, int_at_least, new_run_directory, number_in, positive_number,
                   run_record)
from ..rundir import atomic_run_directory, write_json, write_rows, write_toml
from .bridges import V_MAX_OVER_R3, bridge_force, max_bridge_volume, rupture_distance
from .liquid import REDISTRIBUTION_RULES, PendularLiquid
from .pendular import BridgeModel, pendular_step
from .shear_output import run_shear_command

PROG = "python -m hmdem.wet"
TIMESERIES = ("t", "gap", "force", "force_eq4", "volume", "film_volume")


class _Parser(OneLineParser):
    command = PROG


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    b = sub.add_parser("bridge", help="pull two spheres apart until their liquid bridge ruptures")
    b.add_argument("--radius", type=positive_number, default=61e-6,
                   help="sphere radius R [m] (default %(default)g, the split cell's mean, §2.1)")
    b.add_argument("--volume", type=positive_number, default=None,
                   help=f"bridge volume V [m^3], at most V_max = {V_MAX_OVER_R3} R^3 (default 0.03 R^3)")
    b.add_argument("--gamma", type=positive_number, default=0.0728,
                   help="surface tension [N/m] (default %(default)g, water, §2.1)")
    b.add_argument("--theta", type=number_in("an angle in [0, 90) degrees", lambda v: 0 <= v < 90), default=5.0,
                   help="contact angle [deg] (default %(default)g, the chapter's from Sec. 4.2 on)")
    b.add_argument("--force-law", choices=("chapter", "willett"), default="chapter",
                   help="Eq. 4's linear coefficient: 1 as printed (chapter, default) or 2.1 (Willett 2000, "
                        "YADE's Willett_analytic); docs/decisions.md #98")
    b.add_argument("--resolution", type=int_at_least(10, maximum=1_000_000), default=400,
                   help="DEM steps for the pull to cover s_c (default %(default)s)")
    b.add_argument("--out", type=Path, default=None, help="run directory (default runs/bridge-<time>-<pid>)")
    t = sub.add_parser("table", help="the Young-Laplace bridge table (Eq. 3) at one contact angle, against Eqs. 4-5")
    t.add_argument("--theta", type=number_in("an angle in [0, 5] degrees", lambda v: 0 <= v <= 5), default=5.0,
                   help="contact angle [deg], up to the chapter's 5 (default %(default)g; decisions #102)")
    t.add_argument("--out", type=Path, default=None, help="run directory (default runs/table-<time>-<pid>)")
    add_shear_parser(sub)
    return parser


def add_shear_parser(sub) -> None:
    s = sub.add_parser("shear", help="liquid migration in a sheared periodic packing (plane shear, Sec. 6.2)")
    s.add_argument("--amplitude", type=number_in(f"a volume in (0, {V_MAX_OVER_R3}] R^3",
                                                 lambda v: 0 < v <= V_MAX_OVER_R3), default=0.01,
                   help="A: the largest initial bridge volume [R^3] (default %(default)g)")
    s.add_argument("--sigma0", type=number_in("a width in [0.5, 1000] R", lambda v: 0.5 <= v <= 1000), default=4.0,
                   help="sigma_0: the initial profile's width [R], at least half a slab (default %(default)g)")
    s.add_argument("--cohesion-number", type=number_in("a number >= 0", lambda v: v >= 0), default=0.0,
                   help="eta = 2 pi R gamma cos(theta) / (P R^2); 0 (default) leaves the forces off")
    s.add_argument("--strain", type=number_in("a strain in (0, 1000]", lambda v: 0 < v <= 1000), default=2.0,
                   help="total shear strain (default %(default)g)")
    s.add_argument("--n", type=int_at_least(64, maximum=200_000), default=800, help="grains (default %(default)s)")
    s.add_argument("--radius", type=number_in("a radius in [1e-7, 1] m", lambda v: 1e-7 <= v <= 1), default=1e-3,
                   help="mean grain radius R [m] (default %(default)g)")
    s.add_argument("--pressure", type=number_in("a pressure in [1, 1e9] Pa", lambda v: 1 <= v <= 1e9), default=1e4,
                   help="plate pressure P [Pa] (default %(default)g)")
    s.add_argument("--stiffness", type=number_in("a ratio in [100, 1e7]", lambda v: 100 <= v <= 1e7), default=2e3,
                   help="Young's modulus over P, sets the overlaps (default %(default)g)")
    s.add_argument("--friction", type=number_in("a coefficient in [0, 10]", lambda v: 0 <= v <= 10), default=0.3,
                   help="grain friction coefficient (default %(default)g, the chapter's, Sec. 7.3)")
    s.add_argument("--inertial-number", type=number_in("a number in (0, 0.5]", lambda v: 0 < v <= 0.5),
                   default=0.01, help="I = shear rate x 2R sqrt(density/P) (default %(default)g)")
    s.add_argument("--theta", type=number_in("an angle in [0, 90) degrees", lambda v: 0 <= v < 90), default=5.0,
                   help="contact angle [deg] (default %(default)g)")
    s.add_argument("--force-law", choices=("chapter", "willett"), default="chapter", help="Eq. 4's coefficient")
    s.add_argument("--redistribution", choices=REDISTRIBUTION_RULES, default="equal",
                   help="rupture rule (default equal, rule a as in Mani et al. 2013)")
    s.add_argument("--liquid-every", type=int_at_least(1, maximum=10_000), default=1,
                   help="DEM steps per liquid step (default %(default)s)")
    s.add_argument("--outputs", type=int_at_least(3, maximum=10_000), default=20,
                   help="profiles and ParaView frames over the strain (default %(default)s)")
    s.add_argument("--seed", type=int_at_least(0), default=0, help="packing seed (default %(default)s)")
    s.add_argument("--out", type=Path, default=None, help="run directory (default runs/shear-<time>-<pid>)")
    s.add_argument("--quiet", action="store_true", help="no progress bars")


def run_bridge(args, argv) -> int:
    radius = args.radius
    volume = 0.03 * radius**3 if args.volume is None else args.volume
    if volume > max_bridge_volume(radius) * (1 + 1e-12):
        raise InputError(f"--volume: must be at most V_max = {V_MAX_OVER_R3} R^3 = {max_bridge_volume(radius):.4g} m^3 "
                         f"for --radius {radius:g}, got {volume:g}")
    theta = np.radians(args.theta)
    s_c = float(rupture_distance(volume, radius, theta))
    if s_c / args.resolution < 1e6 * np.spacing(2 * radius):  # the pull's steps must move the sphere
        raise InputError(f"--volume: V = {volume:g} m^3 gives a rupture distance of {s_c:.3g} m, too small to "
                         f"pull over {args.resolution} steps at R = {radius:g} m; at least {1e-9 * radius**3:.3g} m^3")
    out = new_run_directory(args.out, "bridge")
    from ..dem.spheres import SphereAssembly

    started = time.perf_counter()
    model = BridgeModel(args.gamma, theta, args.force_law)
    radii = np.full(2, radius)
    scene = SphereAssembly([[0.0, 0.0, 0.0], [2 * radius, 0.0, 0.0]], radii)
    travel = s_c / args.resolution  # per DEM step
    scene.hold(0)
    scene.drive(1, (travel / scene.timestep, 0.0, 0.0))
    liquid = PendularLiquid(np.empty((0, 2)), [], np.full(2, volume / 2))
    rows, rupture_gap, rupture_step, touching = [], None, None, [[0, 1]]
    # pull on past the rupture by a fifth of s_c, to show the force gone
    while rupture_step is None or len(rows) < rupture_step + args.resolution // 5:
        centres = scene.positions()
        gap = float(np.linalg.norm(centres[1] - centres[0]) - 2 * radius)
        liquid, forces, broken = pendular_step(liquid, centres, radii, model, touching)
        touching = None
        if broken and rupture_step is None:
            rupture_gap, rupture_step = gap, len(rows)
        t = scene.time  # the step from t applies the force of the gap at t
        scene.set_external_forces(forces)
        scene.step()
        held = scene.total_forces()[0, 0]  # the bridge pulls the held sphere towards +x
        v = float(liquid.volume.sum())
        expected = float(bridge_force(gap, v, radius, args.gamma, theta, args.force_law)) if len(liquid.pairs) else 0.0
        rows.append((t, gap, held, expected, v, float(liquid.film.sum())))
        if len(rows) > 3 * args.resolution:  # Eq. 5's s_c is the pull's own target: a bug if passed 3 times
            raise RuntimeError(f"no rupture by gap {gap:.4g} m against s_c = {s_c:.4g} m")
    data = np.array(rows)
    bridged = data[:, 4] > 0
    error = np.abs(data[bridged, 2] - data[bridged, 3]) / data[bridged, 3]
    summary = {
        "rupture_gap_m": rupture_gap,
        "s_c_eq5_m": s_c,
        "rupture_overshoot_over_travel": (rupture_gap - s_c) / travel,
        "peak_force_n": float(data[:, 2].max()),
        "contact_force_eq4_n": float(bridge_force(0.0, volume, radius, args.gamma, theta)),
        "max_force_rel_error": float(error.max()),
        "force_after_rupture_n": float(np.abs(data[~bridged, 2]).max()),
        "liquid_volume_defect": float(np.abs(data[:, 4] + data[:, 5] - volume).max() / volume),
        "steps": len(rows),
        "dem_timestep_s": scene.timestep,
        "wall_time_s": time.perf_counter() - started,
    }
    config = {"run": run_record(PROG, argv),
              "bridge": {"radius_m": radius, "volume_m3": volume, "surface_tension_n_per_m": args.gamma,
                         "contact_angle_deg": args.theta, "force_law": args.force_law,
                         "resolution": args.resolution, "pull_speed_m_per_s": travel / scene.timestep}}
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", TIMESERIES, [[f"{x:.10g}" for x in r] for r in rows])
        plot_pull(tmp / "force.png", data, s_c, args)
    print(f"ruptured at s = {rupture_gap:.4g} m (Eq. 5: {s_c:.4g} m); Eq. 4 followed within "
          f"{summary['max_force_rel_error']:.1e}; run directory: {out}")
    return 0


def run_table(args, argv) -> int:
    out = new_run_directory(args.out, "table")
    from .young_laplace import bridge_table

    started = time.perf_counter()
    theta = np.radians(args.theta)
    table = bridge_table(float(theta))
    checks = [0.001, 0.01, 0.03, V_MAX_OVER_R3]
    rupture = {f"{v:g}": {"young_laplace": float(table.rupture_distance(v)),
                          "eq5": float(rupture_distance(v, 1.0, theta))} for v in checks}
    summary = {"contact_angle_deg": args.theta, "rupture_distance_over_r": rupture,
               "eq5_over_young_laplace_max": max(r["eq5"] / r["young_laplace"] for r in rupture.values()),
               "eq5_over_young_laplace_min": min(r["eq5"] / r["young_laplace"] for r in rupture.values()),
               "wall_time_s": time.perf_counter() - started}
    config = {"run": run_record(PROG, argv), "table": {"contact_angle_deg": args.theta}}
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        np.savez_compressed(tmp / "bridge_table.npz", volume_over_r3=table.volumes, gap_over_r=table.gaps,
                            suction=table.suction_table, force=table.force_table, neck=table.neck_table,
                            least_volume_over_r3=table.least_volume, contact_angle_deg=args.theta)
        plot_table(tmp / "eq4.png", table, checks[1:], args.theta)
    print(f"Young-Laplace table at {args.theta:g} deg; Eq. 5 over its rupture distance: "
          f"{summary['eq5_over_young_laplace_min']:.3f}-{summary['eq5_over_young_laplace_max']:.3f}; "
          f"run directory: {out}")
    return 0


def plot_table(path: Path, table, volumes, theta_deg: float) -> None:
    """Eq. 4's two laws against the Young-Laplace force, F / (gamma R) against s / R."""
    from ..plots import plt  # Agg backend, Debian's Axes3D warning silenced

    theta = np.radians(theta_deg)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for v, colour in zip(volumes, ("tab:blue", "tab:orange", "tab:green")):
        s_yl = np.linspace(0.0, float(table.rupture_distance(v)), 200)
        ax.plot(s_yl, table.force(v, s_yl), color=colour, lw=2.2, label=f"Young–Laplace, V = {v:g} R³")
        s = np.linspace(0.0, float(rupture_distance(v, 1.0, theta)), 200)  # Eq. 4 up to Eq. 5's rupture
        first = v == volumes[0]
        ax.plot(s, bridge_force(s, v, 1.0, 1.0, theta), "--", color=colour, lw=1,
                label="Eq. 4, chapter" if first else None)
        ax.plot(s, bridge_force(s, v, 1.0, 1.0, theta, "willett"), ":", color=colour, lw=1.3,
                label="Eq. 4, Willett" if first else None)
        ax.axvline(table.rupture_distance(v), color=colour, lw=0.6)
    ax.set_xlabel("gap s / R (thin lines: Young–Laplace rupture)")
    ax.set_ylabel("bridge force F / (γR)")
    ax.set_title(f"θ = {theta_deg:g}°")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_pull(path: Path, data: np.ndarray, s_c: float, args) -> None:
    """Force on the held sphere against the gap, with Eq. 4 and Eq. 5's rupture distance."""
    from ..plots import plt  # Agg backend, Debian's Axes3D warning silenced

    fig, ax = plt.subplots(figsize=(5.5, 4))
    gap = data[:, 1] / args.radius
    cut = np.argmax(data[:, 4] == 0)  # the first row after the rupture: the force drops there, not gradually
    gap, force, eq4 = (np.insert(a, cut, np.nan) for a in (gap, data[:, 2] * 1e6, data[:, 3] * 1e6))
    ax.plot(gap, force, lw=2.5, color="0.7", label="YADE (applied)")
    ax.plot(gap, eq4, "k--", lw=1, label=f"Eq. 4 ({args.force_law})")
    ax.axvline(s_c / args.radius, color="tab:red", lw=1, label="Eq. 5: $s_c$")
    ax.set_xlabel("gap s / R")
    ax.set_ylabel("bridge force [µN]")
    ax.set_title(f"R = {args.radius:g} m, V = {data[0, 4] + data[0, 5]:.3g} m$^3$, θ = {args.theta:g}°")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None, launcher: str | None = None) -> int:
    """The command line; ``launcher`` names a YADE launcher calling it (config.toml's [launcher])."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    return dispatch(PROG, parser, args, {"bridge": lambda a: run_bridge(a, argv),
                                         "table": lambda a: run_table(a, argv),
                                         "shear": lambda a: run_shear_command(a, argv, PROG, launcher)})


if __name__ == "__main__":
    raise SystemExit(main())
