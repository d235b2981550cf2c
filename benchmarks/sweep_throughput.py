"""Sweep throughput on this machine (issue 4 benchmark): runs per hour with 1 and 2 Dask
workers, the scaling efficiency, and Dask's overhead over plain sequential execution.

    .venv/bin/python benchmarks/sweep_throughput.py [--log-m=-5:2:2] [--log-ca=-6:0:4] [--out DIR]

The same points (default 2 x 4 on the shipped packing, runs of 7-50 s) are run three times
into fresh sweep directories: sequentially in this process without Dask (``run_point`` in a
loop), through ``python -m hmdem.sweep lenormand --workers 1`` and ``--workers 2``. Dask's
overhead is (T_dask,1 - T_seq) / T_seq; efficiency is T_dask,1 / (2 T_dask,2). Prints the
Markdown rows for BENCHMARKS.md. Run it on an otherwise idle machine.
"""
import argparse
import platform
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from hmdem.sweep.__main__ import main as sweep_main  # noqa: E402
from hmdem.sweep.grid import lenormand_points, parse_axis  # noqa: E402
from hmdem.sweep.runner import run_point  # noqa: E402
from md_table import header  # noqa: E402


def timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--log-m", default="-5:2:2")
    ap.add_argument("--log-ca", default="-6:0:4")
    ap.add_argument("--out", type=Path, default=Path("runs/bench-sweep"))
    args = ap.parse_args()
    points = lenormand_points(parse_axis(args.log_m), parse_axis(args.log_ca), 1)
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)

    def sequential():
        for p in points:
            run_point(p, args.out / "sequential" / p.run_id)

    def dask(workers):
        code = sweep_main(["lenormand", f"--log-m={args.log_m}", f"--log-ca={args.log_ca}", "--workers",
                           str(workers), "--out", str(args.out / f"dask{workers}"), "--quiet"])
        assert code == 0, f"sweep with {workers} workers failed"

    t_seq = timed(sequential)
    t1 = timed(lambda: dask(1))
    t2 = timed(lambda: dask(2))
    n = len(points)
    print(f"machine: {platform.node()} ({platform.machine()}), Python {platform.python_version()}; "
          f"{n} runs ({args.log_m} x {args.log_ca})")
    print(header("execution", "wall [s]", "runs per hour", "vs sequential"))
    for name, t in (("sequential, no Dask", t_seq), ("Dask, 1 worker", t1), ("Dask, 2 workers", t2)):
        print(f"| {name} | {t:.1f} | {3600 * n / t:.0f} | {t_seq / t:.2f}x |")
    print(f"Dask overhead (1 worker vs sequential): {100 * (t1 - t_seq) / t_seq:+.1f} %; "
          f"scaling efficiency 1 -> 2 workers: {100 * t1 / (2 * t2):.0f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
