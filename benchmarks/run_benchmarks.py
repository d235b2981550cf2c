"""Speed of the fixed-grain cases and implicit-vs-explicit efficiency (issue 2 targets).

    .venv/bin/python benchmarks/run_benchmarks.py [--cases vf cf1 sd cf2] [--explicit-seconds 20]
Prints a Markdown table for BENCHMARKS.md.
"""
import argparse
import copy
import platform
import time

from hmdem.cases import CASES
from hmdem.flow.fluids import explicit_critical_step
from hmdem.flow.simulation import FlowModel
from hmdem.scenario import build_scenario
from md_table import header


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
    print(header("case", "status", "simulated t [s]", "steps", "solves", "wall [s]", "CPU [s]"))
    rates = {}
    for name in args.cases:
        state, rec, cpu = run(name)
        rates[name] = state.t / cpu
        print(f"| {name} | {rec.status} | {state.t:.4g} | {rec.steps} | {rec.solves} | {rec.wall_time:.1f} | {cpu:.1f} |")
    if "vf" in rates:
        # explicit reference (Eqs. 29-30). Its step is at most the network's own stability bound
        # (Gershgorin), set by the stiffest domain, so measure it at the start (oil only) and from
        # the implicit state at t = 5 s (air cluster present); then at the step of Eq. 30, which
        # is what the paper's explicit runs used (App. C, Table 6: 6.0e-10 s).
        _, rec, cpu = run("vf", scheme="explicit", dt=1.0, max_steps=args.explicit_steps)
        early = rec.rows[-1][0] / cpu
        mid_state, _, _ = run("vf", t_max=5.0)
        sc = build_scenario(CASES["vf"], scheme="explicit")
        eq30 = explicit_critical_step(sc.setup.fluids)
        mid = {}
        for label, dt in (("own bound", 1.0), ("Eq. 30", eq30)):
            sc.setup.dt, sc.setup.max_steps = dt, args.explicit_steps
            c0 = time.process_time()
            state, rec = FlowModel(sc.net, sc.setup).run(copy.deepcopy(mid_state))
            mid[label] = ((state.t - mid_state.t) / (time.process_time() - c0), (state.t - mid_state.t) / rec.steps)
        print(f"\nvf simulated seconds per CPU second: implicit {rates['vf']:.3g} (whole run)")
        print("| explicit run | dt [s] | rate | implicit / explicit |\n|---|---|---|---|")
        print(f"| own bound, from t = 0 | - | {early:.3g} | {rates['vf'] / early:.3g} |")
        for label, (rate, dt) in mid.items():
            print(f"| {label}, from t = 5 s | {dt:.2g} | {rate:.3g} | {rates['vf'] / rate:.3g} |")

if __name__ == "__main__":
    main()
