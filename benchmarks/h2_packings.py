"""H1, H2 and H6 over packing realisations and sample sizes (issue 3; decisions #70).

    .venv/bin/python benchmarks/h2_packings.py [--discs 150 300 600] [--seeds 1 2 3 4 5] [--jobs 2]

H2 compares A3's early peak with A1's maximum (paper 0.86 MPa / 0.13 MPa = 6.6, bound [4, 10];
decisions #51), H6 their breakthrough times (20 +- 5) and H1 asks A1 to open no contact. The
tests read them on one packing per size: the CI sample (150 discs, 0.41 mm, seed 1) and the
shipped paper-size one (1,395 discs, seed 0). This compacts a fresh sample per (discs, seed),
side 0.41 mm x sqrt(discs / 150) so that every size has the paper's grain density (1.25 mm for
1,395 discs, as `python -m hmdem.dem.compaction` makes it), runs A3 and
A1 on it to breakthrough with the default coupling, and prints one table row per sample; a run
that stops short of breakthrough says so in its row (its H6 ratio is then of the times reached).
1,395 discs with seed 0 loads the shipped packing instead of compacting it again. Wall time per
sample on one core: ~10 s at 150 discs, ~40 s at 300, ~3 min at 600; at 1,395 A3 takes ~4 min
and A1 14-28 min (its P-V halvings vary with the packing; BENCHMARKS.md).
"""
import argparse
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from md_table import header

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

PAPER_DISCS, CI_SIDE, CI_DISCS = 1395, 0.41e-3, 150


def nominal_side(discs: int) -> float:
    """The CI sample's side scaled to the paper's grain density; 1.25 mm at the paper's size, as
    ``python -m hmdem.dem.compaction`` makes it (so seed N here is that command's --seed N)."""
    return 1.25e-3 if discs == PAPER_DISCS else CI_SIDE * np.sqrt(discs / CI_DISCS)


def sample(discs: int, seed: int):
    """The shipped packing for the paper's size and seed 0, else a fresh compaction."""
    from hmdem.coupling.radial import default_huang_packing_path
    from hmdem.dem.compaction import compact_sample
    from hmdem.network.packing import DiscPacking

    if discs == PAPER_DISCS and seed == 0:
        return DiscPacking.load(default_huang_packing_path())
    return compact_sample(n=discs, size=nominal_side(discs), seed=seed)


def run(discs: int, seed: int) -> str:
    from hmdem.coupling.model import CoupledFlowModel
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario
    from hmdem.dem.runs import start_grains
    from hmdem.flow.diagnostics import early_peak

    start = time.time()
    pk = sample(discs, seed)
    end_time, record, opened = {}, {}, {}
    for case in ("A3", "A1"):
        sc = build_radial_scenario(RADIAL_CASES[case], packing=pk)
        model = CoupledFlowModel(sc.net, sc.setup, start_grains(sc), sc.coupling)
        state, record[case] = model.run()
        end_time[case], opened[case] = state.t, int(model.opened.sum())
    a3_peak = early_peak(*record["A3"].injection_pressure())
    a1_max = record["A1"].peak_injection_pressure
    short = {case: rec.status for case, rec in record.items() if rec.status != "breakthrough"}
    status = "".join(f" ({case} {s})" for case, s in short.items())
    return (f"| {discs} | {pk.box[0] * 1e3:.2f} | {seed} | {a3_peak.pressure / 1e3:.0f} at {a3_peak.time * 1e6:.3g} us"
            f"{'' if a3_peak.fell else ', never fell'} | {a1_max / 1e3:.1f} | {a3_peak.pressure / a1_max:.2f} | "
            f"{end_time['A1'] / end_time['A3']:.1f}{status} | {opened['A1']} | {opened['A3']} | "
            f"{time.time() - start:.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--discs", nargs="+", type=int, default=[150, 300, 600],
                        help="sample sizes in discs (1395: the paper's)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4, 5], help="packing seeds")
    parser.add_argument("--jobs", type=int, default=1, help="samples run side by side (one core each)")
    parser.add_argument("--one", nargs=2, type=int, metavar=("DISCS", "SEED"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:  # a worker: one sample, its row on stdout
        print(run(*args.one), flush=True)
        return
    if min(args.discs) < 50 or min(args.seeds) < 0 or args.jobs < 1:
        parser.error("--discs must be at least 50, --seeds non-negative and --jobs at least 1")
    print(header("discs", "side [mm]", "seed", "A3 early peak [kPa]", "A1 max [kPa]", "H2 ratio", "H6 t_A1/t_A3",
                 "A1 opened", "A3 opened", "wall [s]"))
    samples = [(d, s) for d in args.discs for s in args.seeds]
    failed = 0
    with ThreadPoolExecutor(args.jobs) as pool:  # one process per sample: YADE is one scene a process
        for ok, row in pool.map(worker, samples):
            failed += not ok
            print(row, flush=True)
    if failed:
        sys.exit(f"{failed} of {len(samples)} samples failed")


def worker(sample_key: tuple[int, int]) -> tuple[bool, str]:
    """(success, table row) of one sample, run in its own process."""
    discs, seed = sample_key
    done = subprocess.run([sys.executable, __file__, "--one", str(discs), str(seed)],
                          capture_output=True, text=True)
    rows = [line for line in done.stdout.splitlines() if line.startswith("| ")]
    if done.returncode or not rows:
        last = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        return False, f"| {discs} | | {seed} | failed: {last} | | | | | | |"
    return True, rows[-1]


if __name__ == "__main__":
    main()
