"""Where the P-V iteration of a Huang case spends its evaluations (issue 3 diagnosis).

    .venv/bin/python benchmarks/huang_pv_log.py save --case A1 --until 0.0225 --checkpoint runs/a1_ckpt
    .venv/bin/python benchmarks/huang_pv_log.py log --checkpoint runs/a1_ckpt --steps 200 --csv runs/a1_pv.csv
    .venv/bin/python benchmarks/huang_pv_log.py probe --checkpoint runs/a1_ckpt --domains 1433 841

``save`` runs a paper-size case to t = --until and keeps the YADE scene (``O.save``) and the
pickled flow model and state, so that a late stretch of a run (A1 crawls from t ~ 0.023 s, ~45
minutes in) can be studied again in minutes. ``log`` resumes the checkpoint for --steps flow
steps with ``CoupledFlowModel.pv_log`` on, writes every P-V evaluation to CSV and prints which
domains hold the largest mismatch (``--span`` runs a stretch of simulated time instead,
``--dt`` changes the nominal flow step and ``--damping`` YADE's local damping). A resumed run
repeats a straight one to the printed digits (checked on the reduced A1). ``probe`` tests how
smooth the P-V map is at the checkpoint's next step. This is a diagnostic: the checkpoint
format is this script's own.
"""
import argparse
import collections
import csv
import pickle
import sys
import time
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hmdem.coupling.model import CoupledFlowModel, PVEvaluation, replica_for  # noqa: E402
from hmdem.coupling.pockets import PocketNewton, trapped_pockets  # noqa: E402
from hmdem.cli import local_damping, non_negative_int, positive_int  # noqa: E402
from hmdem.coupling.quasi_newton import InterfaceQuasiNewton  # noqa: E402
from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario  # noqa: E402
from hmdem.dem.runs import start_grains  # noqa: E402
from hmdem.dem.assembly import DiscAssembly  # noqa: E402
from hmdem.network.packing import DiscPacking  # noqa: E402

GRAIN_FIELDS = ("radii", "ids", "fixed", "k_n", "k_s", "friction", "_index")


def save(case: str, until: float, checkpoint: Path, packing: Path | None = None) -> None:
    packed = DiscPacking.load(packing) if packing else None
    sc = build_radial_scenario(RADIAL_CASES[case], packing=packed)
    grains = start_grains(sc)
    model = CoupledFlowModel(sc.net, sc.setup, grains, sc.coupling)
    sc.setup.t_max = until
    start = time.perf_counter()
    state, rec = model.run()
    print(f"{case}: {rec.status} at t = {state.t:.6g} s, {rec.steps} steps, {time.perf_counter() - start:.0f} s")
    checkpoint.mkdir(parents=True, exist_ok=True)
    grains._O.save(str(checkpoint / "scene.yade.gz"))
    model.grains = None  # the YADE scene is saved above, not pickled
    with open(checkpoint / "model.pkl", "wb") as f:
        pickle.dump({"model": model, "state": state, "grains": {k: getattr(grains, k) for k in GRAIN_FIELDS}}, f)


def resume(checkpoint: Path):
    from hmdem.yade_env import import_yade

    import_yade()
    from yade import O

    O.load(str(checkpoint / "scene.yade.gz"))
    with open(checkpoint / "model.pkl", "rb") as f:
        data = pickle.load(f)
    grains = object.__new__(DiscAssembly)
    grains._O = O
    grains.friction = 0.6  # checkpoints saved before it was kept: the Huang cases' Coulomb coefficient
    for key, value in data["grains"].items():
        setattr(grains, key, value)
    model = data["model"]
    model.grains = grains
    # a checkpoint saved before pockets.py, or before some of its attributes: fill them in fresh
    fresh = PocketNewton(model.net.n_domains, model.pipe_a, model.pipe_b)
    if not hasattr(model, "pocket_newton"):
        model.pocket_newton = fresh
    for name, value in vars(fresh).items():
        model.pocket_newton.__dict__.setdefault(name, value)
    # a checkpoint saved before contacts' opening times were kept: those already opened get nan
    model.__dict__.setdefault("opened_time", np.where(model.opened, np.nan, np.inf))
    model.__dict__.setdefault("wetted_time", np.where(data["state"].saturation > 0.0, np.nan, np.inf))
    # a checkpoint saved before the replica (decisions #65): give it one, as a new run would have
    model.__dict__.setdefault("_grains_moved", False)
    model.__dict__.setdefault("unbooked_volume", np.zeros_like(model.volume))  # read by one-way "lagged" only
    model.__dict__.setdefault("_last_dt", model.coupling_dt)
    if "replica" not in model.__dict__:
        model.replica = replica_for(grains, model.coupling)
    return model, data["state"]


def log(checkpoint: Path, steps: int, out_csv: Path, pocket_newton: bool | None = None,
        reuse_steps: int | None = None, max_iter: int | None = None, rtol: float | None = None,
        dt: float | None = None, span: float | None = None, skeleton_newton: bool | None = None,
        max_columns: int | None = None, damping: float | None = None) -> None:
    model, state = resume(checkpoint)
    if damping is not None:  # YADE's local damping from here on, as radial --damping sets it for a run
        model.coupling.dem_damping = model.grains.damping = damping
    if skeleton_newton is not None:
        model.coupling.pv_skeleton_newton = skeleton_newton
    if dt is not None:  # the nominal flow step, as radial --dt sets it
        model.setup.dt = dt
        model.coupling_dt = min(model.coupling_dt, dt)
    if rtol is not None:
        model.coupling.pv_rtol = rtol
    if pocket_newton is not None:
        model.coupling.pv_pocket_newton = pocket_newton
    if max_iter is not None:
        model.coupling.pv_max_iter = max_iter
    if max_columns is not None:
        model.coupling.pv_max_columns = model.quasi_newton.max_columns = max_columns
    if reuse_steps is not None:  # a fresh IQN (the checkpoint's keeps the pairs of its last steps)
        model.coupling.pv_reuse_steps = reuse_steps
        model.quasi_newton = InterfaceQuasiNewton(reuse_steps=reuse_steps, max_columns=model.coupling.pv_max_columns)
    model.pv_log = []
    pockets = np.zeros(model.net.n_domains, bool)
    pockets[trapped_pockets(state.invaded, state.saturation, model.pipe_a, model.pipe_b)] = True
    record = model.coupling_record  # cumulative: pickled with the run
    t0, halvings0, dem0, rewind0 = state.t, record.dt_halvings, record.dem_seconds, record.rewind_seconds
    replica0 = record.replica_seconds  # a class default (0) in checkpoints saved before the replica
    model.setup.t_max = np.inf if span is None else state.t + span
    model.setup.max_steps = steps if span is None else 10**9
    start = time.perf_counter()
    state, rec = model.run(state)
    attempts = model.pv_log
    with open(out_csv, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([fl.name for fl in fields(PVEvaluation)])
        writer.writerows(asdict(a).values() for a in attempts)
    print(f"t {t0:.6g} -> {state.t:.6g} s: {rec.steps} steps, {len(attempts)} evaluations, "
          f"{record.dt_halvings - halvings0} halvings, {time.perf_counter() - start:.0f} s "
          f"(DEM {record.dem_seconds - dem0:.0f} s, replica {record.replica_seconds - replica0:.0f} s, "
          f"DEM saves and rewinds {record.rewind_seconds - rewind0:.0f} s)")
    unconverged = [a for a in attempts if a.mismatch_over_tolerance > 1.0]
    worst = collections.Counter(a.worst_domain for a in unconverged)
    print(f"{len(unconverged)} evaluations above tolerance; the domains holding the largest mismatch:")
    for domain, count in worst.most_common(6):
        kind = "trapped pocket" if pockets[domain] else ("invaded" if state.invaded[domain] else "front")
        print(f"  domain {domain}: {count} ({count / len(unconverged):.0%}), {kind}, saturation "
              f"{state.saturation[domain]:.2f}, p {state.pressure[domain]:.0f} Pa, mixture modulus "
              f"{model.fluids.mixture_bulk_modulus(state.saturation[domain:domain + 1])[0] / 1e6:.0f} MPa")
    share = sum(c for d, c in worst.items() if pockets[d]) / max(len(unconverged), 1)
    print(f"trapped pockets at the start: {int(pockets.sum())}; their share of the worst mismatches: {share:.0%}")


def probe(checkpoint: Path, domains: list[int], deltas: list[float], dt_cap: float | None = None,
          dem_cycles: int | None = None) -> None:
    """How smooth is the P-V map p_trial -> p_calc at the checkpoint's next step? H is evaluated
    at the predictor's p0 and at p0 +- delta on one domain at a time (DEM rewound each time);
    a smooth map gives (H(p0 + d e_i) - H(p0)) / d independent of d and of its sign."""
    from hmdem.flow.simulation import FlowModel

    model, state = resume(checkpoint)
    model.setup.t_max = np.inf
    if dt_cap is not None:
        model.coupling_dt = dt_cap
    if dem_cycles is not None:
        model.coupling.dem_cycles_per_step = dem_cycles
    model.volume_change[:] = 0.0
    model._predicting = model.coupling.pv_predictor
    sol, _, dt, limiter = FlowModel.implicit_step(model, state, np.zeros(len(model.pipes), bool))
    model._predicting = False
    g, orient, pc = model.pipe_properties(state)
    model._rewind(save=True)

    def evaluate(p):
        calc, _ = model._pv_evaluation(state, dt, model.move_grains(p, dt), g, orient, pc, sol.blocked)
        model._rewind()
        return calc.pressure

    p0 = sol.pressure
    h0 = evaluate(p0)
    tolerance = model.coupling.pv_rtol * np.abs(h0).max() + model.coupling.pv_atol
    print(f"t = {state.t:.6g} s, dt = {dt:.3g} s ({limiter}); |H(p0) - p0| = {np.abs(h0 - p0).max():.4g} Pa, "
          f"tolerance {tolerance:.4g} Pa; the same p0 again differs by {np.abs(evaluate(p0) - h0).max():.3g} Pa")
    print("domain  delta [Pa]  dH_i/dp_i  largest |H - H(p0)| [Pa] (where)")
    for domain in domains:
        for delta in [s * d for d in deltas for s in (1.0, -1.0)]:
            p = p0.copy()
            p[domain] += delta
            change = evaluate(p) - h0
            worst = int(np.argmax(np.abs(change)))
            print(f"{domain:6d} {delta:11.4g} {change[domain] / delta:10.3f}  {change[worst]:10.4g} ({worst})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    s = sub.add_parser("save")
    s.add_argument("--case", choices=sorted(RADIAL_CASES), default="A1")
    s.add_argument("--until", type=float, required=True, help="simulated time of the checkpoint [s]")
    s.add_argument("--checkpoint", type=Path, required=True)
    s.add_argument("--packing", type=Path, help="packing .npz (hmdem.dem.compaction; default: the shipped one)")
    g = sub.add_parser("log")
    g.add_argument("--checkpoint", type=Path, required=True)
    g.add_argument("--steps", type=int, default=200)
    g.add_argument("--csv", type=Path, required=True)
    g.add_argument("--pocket-newton", action=argparse.BooleanOptionalAction, default=None,
                   help="the scalar Newton step on trapped pockets on or off (default: as checkpointed)")
    g.add_argument("--pv-reuse-steps", type=non_negative_int,
                   help="IQN reuses the secant pairs of this many earlier steps; given, IQN starts afresh "
                        "without the checkpoint's pairs (default: as checkpointed, pairs kept)")
    g.add_argument("--pv-max-iter", type=positive_int, help="P-V iteration cap per attempt (default: as checkpointed)")
    g.add_argument("--pv-max-columns", type=positive_int,
                   help="secant pairs the IQN update fits at most (default: as checkpointed)")
    g.add_argument("--pv-tol", type=float, help="relative P-V tolerance (default: as checkpointed)")
    g.add_argument("--dt", type=float, help="nominal flow step, as radial --dt (default: as checkpointed)")
    g.add_argument("--skeleton-newton", action=argparse.BooleanOptionalAction, default=None,
                   help="precondition IQN with the linearised skeleton's Newton step (default: as checkpointed)")
    g.add_argument("--damping", type=local_damping,
                   help="YADE local damping from the checkpoint on (default: as checkpointed)")
    g.add_argument("--span", type=float, help="run this much simulated time [s] instead of --steps steps")
    b = sub.add_parser("probe", help=probe.__doc__.split("\n")[0])
    b.add_argument("--checkpoint", type=Path, required=True)
    b.add_argument("--domains", type=int, nargs="+", required=True)
    b.add_argument("--deltas", type=float, nargs="+", default=[1.0, 10.0, 100.0, 1000.0, 10000.0],
                   help="pressure changes [Pa], each tried with both signs")
    b.add_argument("--dt", type=float, help="cap on the flow step (default: the checkpoint's cap)")
    b.add_argument("--dem-cycles", type=positive_int, help="DEM cycles per flow step (default: the stable DEM step)")
    args = parser.parse_args()
    if args.command == "save":
        save(args.case, args.until, args.checkpoint, args.packing)
    elif args.command == "log":
        log(args.checkpoint, args.steps, args.csv, args.pocket_newton, args.pv_reuse_steps, args.pv_max_iter,
            args.pv_tol, args.dt, args.span, args.skeleton_newton, args.pv_max_columns, args.damping)
    else:
        probe(args.checkpoint, args.domains, args.deltas, args.dt, args.dem_cycles)


if __name__ == "__main__":
    main()
