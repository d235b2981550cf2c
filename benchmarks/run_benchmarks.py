"""Speed of the fixed-grain cases and implicit-vs-explicit efficiency (issue 2 targets).

    .venv/bin/python benchmarks/run_benchmarks.py [--cases vf cf1 sd cf2] [--explicit-seconds 20]
Prints a Markdown table for BENCHMARKS.md.
"""
import argparse
import platform
import time

from hmdem.cases import CASES
from hmdem.flow.simulation import FlowModel
from hmdem.scenario import build_scenario


def run(name, scheme="implicit", **changes):
    sc = build_scenario(CASES[name], scheme=scheme)
    for k, v in changes.items():
        setattr(sc.setup, k, v)
    t0 = time.process_time()
    state, rec = FlowModel(sc.net, sc.setup).run()
    return state, rec, time.process_time() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["vf", "cf1", "sd", "cf2"])
    ap.add_argument("--explicit-steps", type=int, default=20000)
    args = ap.parse_args()
    print(f"machine: {platform.node()} {platform.processor() or platform.machine()}, python {platform.python_version()}")
    print("| case | status | simulated t [s] | steps | solves | wall [s] | CPU [s] |")
    print("|---|---|---|---|---|---|---|")
    rates = {}
    for name in args.cases:
        state, rec, cpu = run(name)
        rates[name] = state.t / cpu
        print(f"| {name} | {rec.status} | {state.t:.4g} | {rec.steps} | {rec.solves} | {rec.wall_time:.1f} | {cpu:.1f} |")
    if "vf" in rates:
        # explicit reference (Eqs. 29-30): its step is set by the stiffest domain, so measure it both
        # at the start (oil only) and from the implicit state at t = 5 s (air cluster present)
        _, rec, cpu = run("vf", scheme="explicit", dt=1.0, max_steps=args.explicit_steps)
        early = rec.rows[-1][0] / cpu
        mid_state, _, _ = run("vf", t_max=5.0)
        t0 = mid_state.t
        sc = build_scenario(CASES["vf"], scheme="explicit")
        sc.setup.dt, sc.setup.max_steps = 1.0, args.explicit_steps
        c0 = time.process_time()
        state, rec = FlowModel(sc.net, sc.setup).run(mid_state)
        mid = (state.t - t0) / (time.process_time() - c0)
        print(f"\nvf simulated seconds per CPU second: implicit {rates['vf']:.3g} (whole run); explicit {early:.3g} "
              f"at the start, {mid:.3g} from t = 5 s ({args.explicit_steps} steps, dt ~ {(state.t - t0) / rec.steps:.2g} s); "
              f"ratio {rates['vf'] / early:.3g} / {rates['vf'] / mid:.3g}")


if __name__ == "__main__":
    main()
