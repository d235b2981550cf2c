"""``python -m sph_bridge lga {poiseuille,rough,permeability,nonlinear}``: FHP-II lattice-gas
studies of seed 003 with run directories.

    lga poiseuille   [--nx N] [--ny ROWS] [--mirror] [--density RHO] [--g G] [--steps N] [--seed N]
    lga rough        [--nx N] [--ny ROWS] [--hurst H] [--relative-roughness R] [--g G] [--steps N] [--seed N]
    lga permeability [--nx N] [--ny ROWS] [--hurst H ...] [--relative-roughness R ...] [--surfaces N]
                     [--workers N] ...
    lga nonlinear    [--nx N] [--ny ROWS] [--hurst H] [--relative-roughness R] [--steps N] [--seed N]

``--nx`` is the periodic length along the flow. ``--ny`` is the smooth channel's fluid rows
(poiseuille) or the largest asperity y_max in rows (rough studies; seed 003: 90, and 200 for
the nonlinear channel). ``--relative-roughness`` is seed 003's y_max / (delta_av/2), in (0, 1):
delta_av/(2 y_max) = 1.35, 1.7, 2.4 are 0.741, 0.588, 0.417. ``--g`` is the forcing fraction
(default: drives chosen for low Mach numbers); ``--steps`` the averaging steps per drive
(default: 30 slowest-mode relaxation times). Every directory holds config.toml, summary.json,
timeseries.csv, PNG figures and field.vtu (ParaView). Bad input: one line, exit status 2.
Ctrl-C writes what was averaged, with status "interrupted"; a worker process lost (killed) leaves
the other channels whole, with status "failed" and exit status 1.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from hmdem import __version__
from hmdem.cli import (InputError, OneLineParser, available_cores, dispatch, int_at_least, new_run_directory,
                       number_in, seed_value, stop_note, worker_count)
from hmdem.rundir import atomic_run_directory, write_json, write_rows, write_toml

from ..interrupts import exit_status
from ..output import run_table
from . import figures, studies
from .flow import AVERAGE_TIMES
from .lattice import ROW
from .pool import run_in_workers
from .rules import REST_DENSITY, viscosity
from .studies import MAX_AVERAGE_TIMES

PROG = "python -m sph_bridge lga"
PAPER_OPENINGS = (1.35, 1.7, 2.4)  # delta_av/(2 y_max) of the permeability study
POISEUILLE_VELOCITIES = (0.02, 0.04, 0.06)  # mean velocities of the default drives (u_max <= 0.09)
ROUGH_VELOCITIES = (0.005, 0.01)  # mean velocities Q_full/delta_av aimed at: Darcy drives (Re ~ 3-19, decisions #50)
NONLINEAR_REYNOLDS = (20, 50, 80, 115, 150, 180)  # seed 003 §5: Re ~ 20-180
MACH_LIMIT = 0.30  # seed 003 §5: the largest velocity it allowed (digest C17)
MACH_AIM = 0.95 * MACH_LIMIT  # the ladder's last drive aims 5 % under it: aims land within a few %
MIN_PROFILE_R2 = 0.9  # the default drives' parabolas fit to R^2 > 0.999; noise alone gives ~0
# the ladder's strong drives reach 1 % sooner: shorter averaging windows than a linear drive's
NONLINEAR_AVERAGE_TIMES, NONLINEAR_MAX_AVERAGE_TIMES = 10, 100  # slowest-mode relaxation times


class _Parser(OneLineParser):
    command = PROG


fraction = number_in("a number in (0, 1)", lambda v: 0 < v < 1)


def roughness(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be y_max/(delta_av/2) in (0, 1), got {text!r}") from None
    if not 0.0 < value < 1.0:
        hint = f" (delta_av/(2 y_max) = {value:g} is {1 / value:.3f})" if value > 1 else ""
        raise argparse.ArgumentTypeError(f"must be y_max/(delta_av/2) in (0, 1), got {text!r}{hint}")
    return value


density = number_in("particles per node in (0, 7)", lambda v: 0 < v < 7)


def build_parser() -> OneLineParser:
    parser = _Parser(prog=PROG, description="FHP-II lattice-gas flow in smooth and self-affine rough channels "
                                             "(seed 003)")
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    texts = {"poiseuille": "smooth channel (or --mirror half channel): parabola and nu from the Q-dP slope",
             "rough": "one self-affine rough fracture: Q, both force estimators, hydraulic aperture",
             "permeability": "(delta_H/delta_av)^3 against delta_av/(2 y_max) over H and surfaces, Eq. 11 fit",
             "nonlinear": "Delta P/Q against Re in a rough and a smooth channel (seed 003 §5)"}
    for name, text in texts.items():
        p = sub.add_parser(name, help=text, description=text)
        rough = name != "poiseuille"
        p.add_argument("--nx", type=int_at_least(64), default=552 if rough else 600,
                       help="periodic length along the flow in lattice units (default %(default)s" +
                            ("; the rough section nx - 40 must be a power of two)" if rough else ")"))
        p.add_argument("--ny", type=int_at_least(8), default=(200 if name == "nonlinear" else 90) if rough else 100,
                       help=("largest asperity y_max in rows" if rough else "fluid rows") + " (default %(default)s)")
        p.add_argument("--density", type=density, default=REST_DENSITY,
                       help="particles per node (default %(default)s, seed 003)")
        times, most = ((NONLINEAR_AVERAGE_TIMES, NONLINEAR_MAX_AVERAGE_TIMES) if name == "nonlinear"
                       else (AVERAGE_TIMES, MAX_AVERAGE_TIMES))
        p.add_argument("--steps", type=int_at_least(100), help=f"averaging steps per drive (default: {times} "
                                                                 "relaxation times of the slowest viscous mode, "
                                                                 f"extended up to {most} until Q is known to 1 %%)")
        p.add_argument("--seed", type=seed_value, default=0,
                       help="random seed of the lattice and (rough) the first surface (default 0)")
        if name in ("poiseuille", "rough"):
            p.add_argument("--g", type=fraction, help="forcing fraction per step (one drive; default: "
                                                      "a ladder of low-Mach drives)")
        if name == "poiseuille":
            p.add_argument("--mirror", action="store_true", help="half channel under a mirror row (claim C8)")
        if name in ("rough", "nonlinear"):
            p.add_argument("--hurst", type=fraction, default=0.5, help="Hurst exponent H (default 0.5)")
            p.add_argument("--relative-roughness", type=roughness, default=0.625 if name == "nonlinear" else 0.741,
                           help="y_max/(delta_av/2) in (0, 1) (default %(default)s)")
        if name == "permeability":
            p.add_argument("--hurst", type=fraction, action="append", help="Hurst exponent (repeatable; default "
                                                                       "0.3, 0.5, 0.7)")
            p.add_argument("--relative-roughness", type=roughness, action="append",
                           help="y_max/(delta_av/2) (repeatable; default 0.741, 0.588, 0.417)")
            # each surface is a channel per roughness: 1e8 of them planned until killed
            p.add_argument("--surfaces", type=int_at_least(1, maximum=1000), default=2,
                           help="surfaces per H (default 2, at most 1000)")
            p.add_argument("--workers", type=int_at_least(1), default=available_cores(),
                           help="channels run side by side in worker processes, one core each (default: the "
                                "machine's %(default)s cores; more are cut to that, with a warning; the numbers do "
                                "not depend on it)")
        p.add_argument("--out", type=Path, help="run directory (must not exist; default runs/lga-<case>-<time>-<pid>)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


class Progress:
    """A tqdm bar over lattice steps (silent with --quiet), to ``total``, the most the run can
    take (:meth:`~sph_bridge.lga.studies.Plan.most_steps`), so that its ETA is an upper bound: a
    total of the shortest windows sat at 100 % for most of a run whose windows were extended
    for precision (a new-user pass). It fills when the run finishes. With ``channels`` > 1 it
    also counts the finished channels."""

    def __init__(self, args, total: int, channels: int = 0):
        self.bar = None
        self.channels, self.channels_done = channels, 0
        if not args.quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=f"lga {args.command}", unit=" steps", unit_scale=True)
            self.show_channels()

    def __call__(self, steps: int) -> None:
        if self.bar is not None:
            if self.bar.n + steps > self.bar.total:  # an averaging window extended for precision
                self.bar.total = self.bar.n + steps
            self.bar.update(steps)

    def channel_done(self) -> None:
        self.channels_done += 1
        self.show_channels()

    def show_channels(self) -> None:
        if self.bar is not None and self.channels > 1:
            self.bar.set_postfix_str(f"channels {self.channels_done}/{self.channels}")

    def close(self, finished: bool = False) -> None:
        if self.bar is not None:
            if finished:  # windows shorter than the longest they could take: the run is done
                self.bar.total = self.bar.n
            self.bar.refresh()
            self.bar.close()


def run_directory(args, config: dict, summary: dict, timeseries: list, write_figures) -> Path:
    out = args.out_dir
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", {"run": run_table(PROG, args.argv, args.command),
                                         **config})
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", ("step", "drive", "flow_rate", "force_applied_per_node",
                                            "force_friction_per_node"), timeseries)
        write_figures(tmp)
    return out


def run_channels(args, channel_drives, plan_of) -> str:
    """Run each (name, channel, forcings), in turn or on ``args.workers`` processes, under one
    progress bar; returns the status: "interrupted" after Ctrl-C or SIGTERM, else "failed" if a
    worker was lost (``args.status_message`` says which), else "finished"."""
    total = sum(plan_of(ch).most_steps(len(forcings)) for _, ch, forcings in channel_drives)
    bar = Progress(args, total, channels=len(channel_drives))
    jobs = [(channel, forcings, plan_of(channel), args.density, args.seed + k)
            for k, (_, channel, forcings) in enumerate(channel_drives)]
    workers = min(getattr(args, "workers", 1), len(jobs))
    series = [[] for _ in jobs]
    stopped, lost = False, []
    if workers > 1:
        try:
            stopped, series, lost = run_in_workers(jobs, workers, bar, bar.channel_done,
                                                   names=[name for name, _, _ in channel_drives])
        except KeyboardInterrupt:  # before the pool took over the signals: no channel has started
            stopped = True
    else:
        try:
            for k, (channel, *run_args) in enumerate(jobs):
                channel.run(*run_args, progress=bar, timeseries=series[k])
                bar.channel_done()
        except KeyboardInterrupt:
            stopped = True
    warn_imprecise(args.command, [(name, channel) for name, channel, _ in channel_drives])
    args.timeseries = [(s[0], name, *s[1:]) for (name, _, _), rows in zip(channel_drives, series) for s in rows]
    bar.close(finished=not stopped and not lost)
    args.status_message = "; ".join(lost)
    for line in lost:
        print(f"python -m sph_bridge lga: {line}; its channel has no results", file=sys.stderr)
    return "interrupted" if stopped else "failed" if lost else "finished"


def plan_for(args):
    return lambda channel: studies.Plan.for_aperture(channel.aperture, args.steps)


def common_config(args) -> dict:
    return {"lattice": {"nx": args.nx, "ny": args.ny, "density": args.density, "seed": args.seed,
                        "averaging_steps": args.steps or "auto"}}


def warn_imprecise(command: str, channels) -> None:
    """A warning for each (name, channel) with drives whose window reached its longest allowed
    length before Q was known to the precision it aimed at (an interrupted drive is not one)."""
    for name, channel in channels:
        missed = [r for r in channel.results if not r.interrupted and not r.precise]
        if missed:
            errors = [r.relative_error for r in missed if np.isfinite(r.relative_error)]
            known = f"{max(errors):.2%}" if errors else "an unknown error"
            print(f"lga {command}: warning: {len(missed)} of {len(channel.results)} drives of channel {name} ended at their "
                  f"longest averaging window with Q known to {known}, not {missed[0].precision:.0%} "
                  f"(\"precise\": false in summary.json; --steps N fixes a longer window)", file=sys.stderr)


def finish(args, status: str, started: float, summary: dict) -> dict:
    return {"case": args.command, "status": status, "status_message": getattr(args, "status_message", ""),
            "wall_time_s": time.perf_counter() - started, **summary}


# --- poiseuille ---------------------------------------------------------------------------


def run_poiseuille(args) -> int:
    args.out_dir = new_run_directory(args.out, f"lga-{args.command}")
    started = time.perf_counter()
    channel = studies.smooth(args.nx, args.ny, args.mirror)
    forcings = [args.g] if args.g else studies.forcings_for_velocities(POISEUILLE_VELOCITIES, channel.aperture,
                                                                       args.density)
    status = run_channels(args, [("smooth", channel, forcings)], plan_for(args))
    done = [r for r in channel.results if r.averaging_steps > 0]
    channel.results = done
    summary = {"geometry": "half channel under a mirror" if args.mirror else "smooth channel",
               "width": channel.aperture, "fluid_rows": args.ny, "length": args.nx,
               "reynolds_definition": "Re = Q_full / nu (Eq. 6)", "drives": channel.rows()}
    if done:
        summary.update(studies.poiseuille_summary(channel))
        summary["force_mismatch_max"] = max(abs(r.force_mismatch) for r in done)
        summary["u_max"] = max(r.u_max for r in done)
        swamped = not (summary["viscosity_fit"] > 0 and summary["profile_r2"] >= MIN_PROFILE_R2)
        if swamped and status == "finished":  # an interrupted run's last window may just be short
            print(f"lga poiseuille: warning: the flow is lost in the lattice's noise (nu from the slope "
                  f"{summary['viscosity_fit']:.4g}, parabola R^2 {summary['profile_r2']:.3f}): drive harder (--g) or "
                  "average longer (--steps)", file=sys.stderr)
    summary = finish(args, status, started, summary)

    def write(tmp):
        if done:
            figures.velocity_profile(tmp / "profile.png", channel, done[-1], summary, summary["viscosity_eq6"])
            figures.flow_rate_against_force(tmp / "flow_rate.png", summary["drives"],
                                            f"ν from the slope: {summary['viscosity_fit']:.4f} (Eq. 6: "
                                            f"{summary['viscosity_eq6']:.4f}){stop_note(status, 'finished')}")
            figures.write_field(tmp / "field.vtu", channel.geometry, done[-1])

    out = run_directory(args, {**common_config(args), "channel": {"mirror": args.mirror,
                                                                  "forcing": list(forcings)}},
                        summary, args.timeseries, write)
    if done:
        print(f"lga poiseuille: {status}; nu from the Q-dP slope {summary['viscosity_fit']:.4f} (Eq. 6: "
              f"{summary['viscosity_eq6']:.4f}, {100 * summary['viscosity_error']:+.1f} %), profile R^2 "
              f"{summary['profile_r2']:.4f}, u_max/u_mean {summary['u_max_over_mean']:.3f}")
    print(f"run directory: {out}")
    return exit_status(status)


# --- rough ----------------------------------------------------------------------------------


def rough_channel(args, hurst_exponent: float, relative_roughness: float, surface_seed: int):
    try:
        return studies.rough(hurst_exponent, relative_roughness, args.ny, args.nx, surface_seed)
    except ValueError as exc:
        raise InputError(f"--nx: {exc}") from None


def rough_forcings(args, channel) -> list[float]:
    if getattr(args, "g", None):
        return [args.g]
    # a rough channel passes ~Eq. 11's fraction of the smooth channel's flow at the same force
    expected = max(studies.eq11(studies.opening(channel)), 0.05)
    return [g / expected for g in studies.forcings_for_velocities(ROUGH_VELOCITIES, channel.aperture, args.density)]


def rough_row(channel, rows: list[dict], target: float) -> dict:
    d = channel.geometry.description
    phis = [r["phi"] for r in rows]
    out = {"target_relative_roughness": target, "hurst": d["hurst"], "surface_seed": d["surface_seed"], "mean_aperture": d["mean_aperture"],
           "y_max": d["y_max"], "opening": studies.opening(channel),
           "relative_roughness": 1.0 / studies.opening(channel), "entrance_width": d.get("entrance_width"),
           "phi": phis[0], "eq11": studies.eq11(studies.opening(channel)), "drives": rows}
    if len(rows) >= 2:
        forces = [r["force_applied_per_node"] for r in rows]
        q = [r["flow_rate_full"] for r in rows]
        out["darcy_slope_change"] = (q[1] / forces[1]) / (q[0] / forces[0]) - 1.0
        out["darcy_residual"] = studies.through_origin(forces, q)[1]
    return out


def run_rough(args) -> int:
    args.out_dir = new_run_directory(args.out, f"lga-{args.command}")
    started = time.perf_counter()
    channel = rough_channel(args, args.hurst, args.relative_roughness, args.seed)
    forcings = rough_forcings(args, channel)
    status = run_channels(args, [("rough", channel, forcings)], plan_for(args))
    channel.results = [r for r in channel.results if r.averaging_steps > 0]
    rows = channel.rows()
    summary = {"reynolds_definition": "Re = Q_full / nu (Eq. 6)", "mach_limit": MACH_LIMIT}
    if rows:
        summary.update(rough_row(channel, rows, args.relative_roughness))
        summary["force_mismatch_max"] = max(abs(r["force_mismatch"]) for r in rows)
        summary["u_max"] = max(r["u_max"] for r in rows)
    summary = finish(args, status, started, summary)

    def write(tmp):
        np.save(tmp / "profile.npy", channel.geometry.description["profile"])
        if channel.results:
            last = channel.results[-1]
            figures.velocity_field(tmp / "velocity.png", channel.geometry, last,
                                   f"H = {args.hurst:g}, δ_av/(2 y_max) = {studies.opening(channel):.3f}, "
                                   f"Re = {rows[-1]['reynolds']:.1f}{stop_note(status, 'finished')}")
            figures.write_field(tmp / "field.vtu", channel.geometry, last)

    out = run_directory(args, {**common_config(args), "rough": rough_config(args, channel, forcings)},
                        summary, args.timeseries, write)
    if rows:
        print(f"lga rough: {status}; delta_av/(2 y_max) = {summary['opening']:.3f}, (delta_H/delta_av)^3 = "
              f"{summary['phi']:.4f} (Eq. 11: {summary['eq11']:.4f}), applied/friction - 1 = "
              f"{rows[0]['force_mismatch']:+.4f}")
    print(f"run directory: {out}")
    return exit_status(status)


def rough_config(args, channel, forcings) -> dict:
    d = channel.geometry.description
    return {"hurst": d["hurst"], "relative_roughness_target": getattr(args, "relative_roughness", None) or "",
            "surface_seed": d["surface_seed"], "asperity_rows": args.ny, "length": d["length"],
            "flat_sections": d["flat"], "forcing": list(forcings)}


# --- permeability ---------------------------------------------------------------------------


def run_permeability(args) -> int:
    args.out_dir = new_run_directory(args.out, f"lga-{args.command}")  # a bad --out is one line, no warning
    args.workers = worker_count(args.workers, PROG)
    started = time.perf_counter()
    hursts = args.hurst or [0.3, 0.5, 0.7]
    roughnesses = args.relative_roughness or [1.0 / o for o in PAPER_OPENINGS]
    jobs, targets = [], {}
    for h in hursts:
        for s in range(args.surfaces):
            for r in roughnesses:
                channel = rough_channel(args, h, r, args.seed + s)
                jobs.append((f"H{h:g}-s{args.seed + s}-r{r:.3f}", channel, rough_forcings(args, channel)))
                targets[jobs[-1][0]] = r
    status = run_channels(args, jobs, plan_for(args))
    points = []
    for name, channel, _ in jobs:
        channel.results = [r for r in channel.results if r.averaging_steps > 0]
        if channel.results:
            points.append({"name": name, **rough_row(channel, channel.rows(), targets[name])})
    summary = {"reynolds_definition": "Re = Q_full / nu (Eq. 6)", "points": points}
    if len(points) >= 2:
        alpha, alpha_error = studies.fit_alpha([p["opening"] for p in points], [p["phi"] for p in points])
        summary.update({"alpha": alpha, "alpha_error": alpha_error, "paper_alpha": studies.PAPER_ALPHA,
                        "force_mismatch_max": max(abs(d["force_mismatch"]) for p in points for d in p["drives"]),
                        "u_max": max(d["u_max"] for p in points for d in p["drives"])})
        summary["by_opening"] = spread_by_opening(points)
    summary = finish(args, status, started, summary)

    def write(tmp):
        if len(points) >= 2:
            figures.collapse(tmp / "collapse.png", points, summary["alpha"], summary["alpha_error"], status)
        write_rows(tmp / "points.csv", ("name", "hurst", "surface_seed", "opening", "phi", "eq11", "mean_aperture"),
                   [(p["name"], p["hurst"], p["surface_seed"], p["opening"], p["phi"], p["eq11"],
                     p["mean_aperture"]) for p in points])

    out = run_directory(args, {**common_config(args), "study": {
        "hurst": hursts, "relative_roughness": roughnesses, "surfaces": args.surfaces}},
        summary, args.timeseries, write)
    if "alpha" in summary:
        partial = "" if status == "finished" else " (of the channels' drives done so far)"
        print(f"lga permeability: {status}; {len(points)} channels, fitted alpha = {summary['alpha']:.3f} +- "
              f"{summary['alpha_error']:.3f}{partial} (paper {studies.PAPER_ALPHA})")
    else:
        print(f"lga permeability: {status}; {len(points)} channel(s) finished, too few to fit alpha")
    print(f"run directory: {out}")
    return exit_status(status)


def spread_by_opening(points: list[dict]) -> list[dict]:
    """Per target roughness: the mean phi over all H and surfaces and the largest deviation of an
    H's mean from it (claim C10), against Eq. 11 and the continuum values."""
    groups = {}
    for p in points:
        groups.setdefault(p["target_relative_roughness"], []).append(p)
    out = []
    for key, sel in sorted(groups.items(), reverse=True):
        phis = np.array([p["phi"] for p in sel])
        by_h = {}
        for p in sel:
            by_h.setdefault(p["hurst"], []).append(p["phi"])
        h_means = {h: float(np.mean(v)) for h, v in by_h.items()}
        mean = float(phis.mean())
        opening = float(np.mean([p["opening"] for p in sel]))
        entry = {"opening": opening, "phi_mean": mean, "phi_by_hurst": {f"{h:g}": v for h, v in h_means.items()},
                 "hurst_spread": max(abs(v / mean - 1.0) for v in h_means.values()),
                 "eq11": studies.eq11(opening), "ratio_to_eq11": mean / studies.eq11(opening)}
        nearest = min(studies.CONTINUUM, key=lambda k: abs(k - opening))
        if abs(nearest - opening) < 0.05:  # the digest's lattice-Boltzmann Stokes values (§6)
            continuum = studies.CONTINUUM[nearest]
            entry["ratio_to_continuum_by_hurst"] = {f"{h:g}": v / continuum[h] for h, v in h_means.items()
                                                    if h in continuum}
        out.append(entry)
    return out


# --- nonlinear ------------------------------------------------------------------------------


def run_nonlinear(args) -> int:
    """Re ladder in the rough channel and in a smooth half channel of the same mean aperture: the
    first drive is linear, later forcings follow from the measured resistance."""
    args.out_dir = new_run_directory(args.out, f"lga-{args.command}")
    started = time.perf_counter()
    rough = rough_channel(args, args.hurst, args.relative_roughness, args.seed)
    half_rows = max(2, int(round(rough.aperture / 2 / ROW - 0.5)))
    smooth = studies.smooth(args.nx, half_rows, True)

    def plan_of(channel):  # strong drives: a shorter window reaches 1 % sooner
        return studies.Plan.for_aperture(channel.aperture, args.steps, times=NONLINEAR_AVERAGE_TIMES,
                                         max_times=NONLINEAR_MAX_AVERAGE_TIMES)

    total = sum(plan_of(ch).most_steps(len(NONLINEAR_REYNOLDS)) for ch in (rough, smooth))
    bar = Progress(args, total)
    args.timeseries = []
    status = "finished"
    try:
        for name, channel in (("rough", rough), ("smooth", smooth)):
            reynolds_ladder(args, name, channel, plan_of(channel), bar)
    except KeyboardInterrupt:
        status = "interrupted"
    bar.close(finished=status == "finished")
    warn_imprecise(args.command, (("rough", rough), ("smooth", smooth)))
    series = {name: ch.rows() for name, ch in (("rough", rough), ("smooth", smooth)) if ch.results}
    summary = {"reynolds_definition": "Re = Q_full / nu (Eq. 6)", "mach_limit": MACH_LIMIT,
               "rough_opening": studies.opening(rough), "smooth_width": smooth.aperture, "series": series}
    for name, rows in series.items():
        resistance = [r["pressure_drop_per_length"] / r["flow_rate_full"] for r in rows]
        summary[f"{name}_drag_increase"] = max(resistance) / resistance[0] - 1.0
        summary[f"{name}_reynolds_range"] = [rows[0]["reynolds"], rows[-1]["reynolds"]]
        k = max(range(len(rows)), key=lambda i: rows[i]["u_max"])
        summary[f"{name}_u_max"] = rows[k]["u_max"]
        summary[f"{name}_within_mach_limit"] = rows[k]["u_max"] <= MACH_LIMIT
        if rows[k]["u_max"] > MACH_LIMIT:  # later rungs aim under it; the first, at Re 20, is not aimed
            why = (f": too narrow a channel for the first rung, Re {NONLINEAR_REYNOLDS[0]} (a larger --ny widens it)"
                   if k == 0 else f": the rung overshot its aim, u_max {MACH_AIM:.3f}")
            print(f"lga nonlinear: warning: the {name} channel's drive at Re = {rows[k]['reynolds']:.0f} reached "
                  f"u_max = {rows[k]['u_max']:.3f}, past the seed's {MACH_LIMIT} (C17){why}", file=sys.stderr)
    summary = finish(args, status, started, summary)

    def write(tmp):
        if series:
            figures.drag_against_reynolds(tmp / "drag.png", series, status)
        if rough.results:
            figures.velocity_field(tmp / "velocity.png", rough.geometry, rough.results[-1],
                                   f"H = {args.hurst:g}, Re = {series['rough'][-1]['reynolds']:.0f}"
                                   f"{stop_note(status, 'finished')}")
            figures.write_field(tmp / "field.vtu", rough.geometry, rough.results[-1])

    out = run_directory(args, {**common_config(args), "rough": rough_config(args, rough, []),
                               "smooth": {"half_rows": half_rows, "width": smooth.aperture},
                               "ladder": {"reynolds": list(NONLINEAR_REYNOLDS), "mach_aim": MACH_AIM}},
                        summary, args.timeseries, write)
    if "rough_drag_increase" in summary and "smooth_drag_increase" in summary:
        print(f"lga nonlinear: {status}; Delta P/Q rises by {100 * summary['rough_drag_increase']:.1f} % (rough) and "
              f"{100 * summary['smooth_drag_increase']:.1f} % (smooth) over Re "
              f"{summary['rough_reynolds_range'][0]:.0f}-{summary['rough_reynolds_range'][1]:.0f}")
    else:
        print(f"lga nonlinear: {status}; {len(series)} of 2 channels have drives")
    print(f"run directory: {out}")
    return exit_status(status)


def reynolds_ladder(args, name, channel, plan, bar) -> None:
    """Drives aimed at each Re of :data:`NONLINEAR_REYNOLDS`, appended to ``channel.results`` as
    they finish (a KeyboardInterrupt keeps those, and the partial window if it averaged). Each
    forcing follows from the drives before it (:func:`studies.next_rung`); an aim whose u_max
    would pass :data:`MACH_AIM` is replaced by the Re at that velocity, and that drive is the last."""
    from .flow import drive
    from .lattice import Lattice

    lattice = Lattice(channel.geometry, density=args.density, seed=args.seed)
    nu = viscosity(args.density)
    aim = NONLINEAR_REYNOLDS[0]
    g = studies.forcings_for_velocities([aim * nu / channel.aperture], channel.aperture, args.density)[0]
    g /= max(studies.eq11(studies.opening(channel)), 0.05) if name == "rough" else 1.0
    for k, target in enumerate(NONLINEAR_REYNOLDS):
        series = []
        try:
            result = drive(lattice, g, plan.spinup if k == 0 else plan.spinup // 2, plan.average, progress=bar,
                           timeseries=series, precision=plan.precision, max_average=plan.max_average)
        finally:
            args.timeseries += [(s[0], f"{name}-Re{aim:.0f}", *s[1:]) for s in series]
        if result.averaging_steps > 0:
            channel.results.append(result)
        if result.interrupted:
            raise KeyboardInterrupt
        if aim < target or k + 1 == len(NONLINEAR_REYNOLDS):
            break  # the last aim, or one held at the Mach bound (C17)
        rung = studies.next_rung(channel.rows(), NONLINEAR_REYNOLDS[k + 1], MACH_AIM)
        if rung is None:
            last = channel.rows()[-1]
            why = (f"its u_max, {last['u_max']:.3f}, is within 2 % of the aim {MACH_AIM:.3f} or past it"
                   if last["u_max"] >= MACH_AIM / 1.02  # next_rung's bound on the Re the limit allows
                   else f"it is already within 2 % of the next aim, Re {NONLINEAR_REYNOLDS[k + 1]}, or past it")
            print(f"lga nonlinear: {name} ladder stops at Re = {last['reynolds']:.0f} ({why})")
            break
        g, aim = rung
        if aim < NONLINEAR_REYNOLDS[k + 1]:
            print(f"lga nonlinear: {name} ladder aims at Re = {aim:.0f} instead of {NONLINEAR_REYNOLDS[k + 1]} "
                  f"to keep u_max near {MACH_AIM} (C17: u <= {MACH_LIMIT})")


# lattice sites nx x ny may span: --ny 1e8 asked numpy for 56 GiB for one of its boolean masks
# (a byte a site) and --nx 1e8 allocated until it was killed; a rough channel holds a few times
# ny rows (2 y_max + delta_av)
MAX_SITES = 20_000_000


def main(argv) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(argv)
    if getattr(args, "nx", None) is not None and args.nx * args.ny > MAX_SITES:
        parser.exit(2, f"{PROG}: --nx, --ny: must span at most {MAX_SITES:,} sites (nx x ny), got "
                       f"{args.nx * args.ny:,}\n")
    return dispatch(PROG, parser, args, {"poiseuille": run_poiseuille, "rough": run_rough,
                                         "permeability": run_permeability, "nonlinear": run_nonlinear})

