"""Speed and outcome of the Huang movable-grain cases at paper size (issue 3 benchmark).

    .venv/bin/python benchmarks/huang.py [--cases A1 A3 B1 B3] [--out runs/bench] [--extra ARGS]
    .venv/bin/python benchmarks/huang.py --collect runs/bench      # table from finished runs

Each case runs as ``python -m hmdem.hele_shaw radial --case X --out DIR/X`` (one process per
case, one after the other); the Markdown table for BENCHMARKS.md is read from the run
directories' summary.json: wall time, flow steps, DEM cycles per step, P-V iterations per
step, step halvings, where the wall time goes, and the physics figures.
"""
import argparse
import json
import platform
import subprocess
import sys
from pathlib import Path

from md_table import header

COLUMNS = ("case", "status", "t [s]", "wall [s]", "steps", "DEM cycles/step", "P-V it./step", "halvings",
           "DEM %", "rewind %", "memory [MB]", "peak p_in [Pa]", "opened", "open at end", "detached", "D_f", "regime")


def percent(fraction: float) -> str:
    return "-" if fraction != fraction else f"{100 * fraction:.0f}"  # nan: not recorded


def row(summary: dict) -> list:
    s = summary
    return [s["case"], s["status"], f"{s['simulated_time_s']:.4g}", f"{s['wall_time_s']:.0f}", s["steps"],
            f"{s['dem_cycles_per_step']:.0f}", f"{s['mean_pv_iterations']:.2f}", s.get("pv_dt_halvings", "-"),
            percent(s.get("dem_wall_fraction", float("nan"))), percent(s.get("rewind_wall_fraction", float("nan"))),
            f"{s['peak_memory_mb']:.0f}" if "peak_memory_mb" in s else "-",  # recorded since 2026-12-01
            f"{s['peak_injection_pressure_pa']:.3g}", s["n_opened_contacts"], s.get("n_open_contacts_at_end", "-"),
            s.get("n_detached_contacts", "-"),
            "-" if s["fractal_dimension"] is None else f"{s['fractal_dimension']:.3f}", s["regime"]]


def table(out: Path, cases) -> str:
    lines = [header(*COLUMNS)]
    for case in cases:
        path = out / case / "summary.json"
        if path.is_file():
            lines.append("| " + " | ".join(str(v) for v in row(json.loads(path.read_text()))) + " |")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["A1", "A3", "B1", "B3"])
    ap.add_argument("--out", type=Path, default=Path("runs/bench"))
    ap.add_argument("--collect", type=Path, help="only tabulate the runs in this directory")
    ap.add_argument("--extra", default="", help="more radial flags, e.g. '--dt 5e-6'")
    args = ap.parse_args()
    if args.collect is None:
        args.out.mkdir(parents=True, exist_ok=True)
        for case in args.cases:
            cmd = [sys.executable, "-m", "hmdem.hele_shaw", "radial", "--case", case, "--out", str(args.out / case),
                   "--quiet", *args.extra.split()]
            print(" ".join(cmd), flush=True)
            subprocess.run(cmd, check=False)
    print(f"machine: {platform.node()} {platform.machine()}, python {platform.python_version()}")
    print(table(args.collect or args.out, args.cases))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
