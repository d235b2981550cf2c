"""YADE's cost per DEM cycle on the Huang sample against its OpenMP thread count (issue 3).

    .venv/bin/python benchmarks/dem_threads.py [--threads 1 2] [--cycles 2000] [--repeats 2]

Each (thread count, repeat) runs in a fresh process (OpenMP reads the count once, when YADE
loads): the shipped Huang sample is settled as ``radial`` does it (``start_grains``), a fixed
push is applied to 50 grains, and ``--cycles`` cycles are timed four times; then one snapshot
(``save_state``/``restore_state``, the P-V rewind) is timed. The positions' digest after all
cycles tells whether repeats at the same count end bit for bit at the same place.
"""
import argparse
import hashlib
import json
import platform
import subprocess
import sys
import time
from pathlib import Path
from md_table import header

ROOT = Path(__file__).resolve().parents[1]


def measure(threads: int, cycles: int) -> dict:
    """One process's figures (called in the child)."""
    sys.path.insert(0, str(ROOT))
    import numpy as np

    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario
    from hmdem.dem.runs import start_grains

    grains = start_grains(build_radial_scenario(RADIAL_CASES["A1"]), threads=threads)
    push = np.zeros((len(grains.radii), 2))
    push[:50, 0] = 1.0  # N per m: enough to move grains, so the sums differ if their order does
    grains.set_external_forces(push)
    per_cycle = []
    for _ in range(4):
        start = time.perf_counter()
        grains.run(cycles)
        per_cycle.append((time.perf_counter() - start) / cycles)
    digest = hashlib.md5(grains.positions().tobytes()).hexdigest()
    start = time.perf_counter()
    grains.save_state()
    saved = time.perf_counter()
    grains.restore_state()
    return {"threads": grains.threads, "ms_per_cycle": [1e3 * t for t in per_cycle], "digest": digest,
            "save_ms": 1e3 * (saved - start), "restore_ms": 1e3 * (time.perf_counter() - saved)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--cycles", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        print(json.dumps(measure(args.child, args.cycles)))
        return
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}; "
          f"{args.cycles} cycles x 4 per process")
    print(header("threads", "ms per DEM cycle (min-max)", "snapshot save / restore [ms]", "positions digest"))
    for threads in args.threads:
        for _ in range(args.repeats):
            proc = subprocess.run([sys.executable, __file__, "--child", str(threads), "--cycles", str(args.cycles)],
                                  capture_output=True, text=True)
            if proc.returncode != 0:
                sys.exit(f"dem_threads.py: the {threads}-thread process failed:\n{proc.stderr}")
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            print(f"| {r['threads']} | {min(r['ms_per_cycle']):.3f}-{max(r['ms_per_cycle']):.3f} | "
                  f"{r['save_ms']:.0f} / {r['restore_ms']:.0f} | {r['digest'][:12]} |")


if __name__ == "__main__":
    main()
