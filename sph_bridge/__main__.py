"""``python -m sph_bridge {hydrostatic,poiseuille}``: PF-SPH validation cases with run directories.

    python -m sph_bridge hydrostatic [--dx M] [--layers N] [--gravity G] [--out DIR]
    python -m sph_bridge poiseuille  [--dx M] [--layers N] [--gravity G] [--viscosity MU] [--out DIR]

Both put water between two 3-layer walls, periodic sideways (``sph_bridge.cases``). A run
directory holds config.toml, summary.json (measured against theory, particles, steps, wall
time), timeseries.csv, profile.png (the measured profile over the analytical one) and
particles.vtu (ParaView point cloud). Bad input: one line, exit status 2, nothing written.
Ctrl-C stops the run and writes the directory with status "interrupted".
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from hmdem.cli import OneLineParser, dispatch, int_at_least, new_run_directory, positive_number
from hmdem.rundir import atomic_run_directory, write_json, write_rows, write_toml

from . import cases

PROG = "python -m sph_bridge"
MIN_LAYERS = 8  # the channel must hold a full kernel (h = 3.42 dx) from each wall


class _Parser(OneLineParser):
    command = PROG


def build_parser() -> OneLineParser:
    parser = _Parser(prog=PROG, description="PF-SPH validation cases (seed 000)")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    for name, text in (("hydrostatic", "water at rest between two walls under gravity: dP/dz = rho g"),
                       ("poiseuille", "body-force flow between two walls: the parabolic profile")):
        p = sub.add_parser(name, help=text, description=text)
        p.add_argument("--dx", type=positive_number, default=1e-3, help="particle spacing [m] (default 1e-3)")
        p.add_argument("--layers", type=int_at_least(MIN_LAYERS), default=16,
                       help=f"channel width in particle layers (>= {MIN_LAYERS}, default 16)")
        p.add_argument("--gravity", type=positive_number, default=cases.DEFAULT_GRAVITY[name],
                       help=f"body force per mass [m/s^2] (default {cases.DEFAULT_GRAVITY[name]}; "
                            + ("downward" if name == "hydrostatic" else "along the channel") + ")")
        if name == "poiseuille":
            p.add_argument("--viscosity", type=positive_number, default=2.6,
                           help="dynamic viscosity [Pa s] (default 2.6: the flow settles in ~0.05 s)")
        p.add_argument("--out", type=Path, help="run directory (must not exist; default runs/<case>-<time>)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def run_case(args) -> int:
    out = new_run_directory(args.out, args.command)
    height = args.layers * args.dx
    if args.command == "hydrostatic":
        params, t_end = cases.hydrostatic_parameters(args.dx, args.layers, args.gravity)
    else:
        params, t_end = cases.poiseuille_parameters(args.dx, args.layers, args.gravity, args.viscosity)
    sim = cases.channel(args.dx, args.layers, params)
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=t_end, desc=args.command, unit="s", bar_format="{l_bar}{bar}| {n:.4f}/{total:.4f} s [{elapsed}<{remaining}]")
    status = "finished"
    try:
        sim.run(t_end, record_every=t_end / 200, progress=None if bar is None else lambda s: bar.update(s.t - bar.n))
    except KeyboardInterrupt:
        status = "interrupted"
    if bar is not None:
        bar.close()
    measure = cases.measure_hydrostatic if args.command == "hydrostatic" else cases.measure_poiseuille
    result = measure(sim, height, args.gravity)
    summary = {"case": args.command, "status": status, **result.summary, "particles": len(sim.pos),
               "fluid_particles": int(sim.fluid.sum()), "steps": sim.record.steps, "simulated_time_s": sim.t,
               "wall_time_s": time.perf_counter() - sim.wall_start}
    write_run(out, args, sim, summary, result.profile)
    print(f"{args.command}: {status} after {sim.record.steps} steps; "
          + ", ".join(f"{k} = {v:.4g}" for k, v in result.summary.items() if isinstance(v, float)))
    print(f"run directory: {out}")
    return 130 if status == "interrupted" else 0


def write_run(out: Path, args, sim, summary: dict, profile) -> None:
    import meshio

    from hmdem.plots import plt

    config = {"run": {"command": f"{PROG} " + " ".join(args.argv), "case": args.command},
              "geometry": {"dx_m": args.dx, "layers": args.layers, "side_cells": cases.SIDE_CELLS},
              "parameters": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(sim.params).items()}}
    with atomic_run_directory(out) as tmp:
        write_toml(tmp / "config.toml", config)
        write_json(tmp / "summary.json", summary)
        write_rows(tmp / "timeseries.csv", sim.record.columns, sim.record.rows)
        points = sim.pos
        cells = [("vertex", np.arange(len(points)).reshape(-1, 1))]
        meshio.write(tmp / "particles.vtu", meshio.Mesh(points, cells, point_data={
            "velocity": sim.vel, "pressure": sim.pressure, "density": sim.rho, "fluid": sim.fluid.astype(np.int8)}))
        z, measured, zt, theory, label = profile
        fig, ax = plt.subplots(figsize=(5, 4))
        ax.plot(measured, z * 1e3, ".", ms=2, alpha=0.4, label="particles")
        ax.plot(theory, zt * 1e3, "k-", label="theory")
        ax.set_xlabel(label)
        ax.set_ylabel("z [mm]")
        ax.legend()
        ax.set_title(f"{args.command}: {summary['steps']} steps, {summary['fluid_particles']} fluid particles")
        fig.tight_layout()
        fig.savefig(tmp / "profile.png", dpi=120)
        plt.close(fig)


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # recorded in config.toml
    return dispatch(PROG, parser, args, {"hydrostatic": run_case, "poiseuille": run_case})


if __name__ == "__main__":
    raise SystemExit(main())
