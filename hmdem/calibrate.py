"""Command line: the mechanical and hydraulic calibration tests of the Huang sample (seed 004 §4.2).

    python -m hmdem.calibrate biaxial [--n N] [--sigma3 PA] [--strain-rate R] [--seed S]
                                      [--contact-stiffness KN] [--friction MU] [--stiffness-ratio R] [--out DIR]
    python -m hmdem.calibrate darcy [--stresses LIST] [--packing FILE] [--contact-stiffness KN] [--out DIR]

biaxial: isotropic compaction to sigma3, then strain-controlled loading to 2.5 % axial strain;
E, nu, peak sigma1 and the Mohr-Coulomb friction angle against the paper's 65.4 MPa, 0.102,
309.6 kPa and 30.8 deg. darcy: network Darcy permeability after compaction to each confining
stress, with Kozeny-Carman, and of a stored packing (default: the shipped Huang sample) against
the paper's 7.43e-13 m^2 at 0.14 MPa. Each writes a run directory atomically (summary.json, a
CSV and a PNG); bad input is one line on stderr, exit status 2, nothing written. Ctrl-C or
SIGTERM writes what is done with status "interrupted" (exit 130 or 143): the Darcy stresses
finished, or the biaxial curve so far once the loading has begun.
"""

from __future__ import annotations

import argparse
import csv
import math
import platform
import sys
import time
from pathlib import Path

from . import __version__
from .cli import (OneLineParser, add_contact_arguments, contact_gap_fraction, dispatch, grain_count, interrupted_status,
                  near_contacts_checked, new_run_directory, number_in, positive_number, read_compacted_packing,
                  seed_value, stop_note)
from .dem.biaxial import FIT_STRAIN
from .network.contact_graph import NEAR_CONTACT_GAP
from .rundir import atomic_run_directory
from .rundir import write_json as write_strict_json

PROG = "python -m hmdem.calibrate"


class _Parser(OneLineParser):
    command = PROG


# the test ends past the window that E and nu are fitted over (an interrupted one may not)
final_strain = number_in(f"an axial strain in ({FIT_STRAIN[1]:g}, 0.5), past the E and nu fit window",
                         lambda v: FIT_STRAIN[1] < v < 0.5)


def stress_list(text: str) -> list[float]:
    """Comma-separated confining stresses [Pa], each > 0."""
    parts = [p.strip() for p in text.split(",")]
    if not text.strip() or any(not p for p in parts):
        raise argparse.ArgumentTypeError(f"must be a comma-separated list of stresses > 0 [Pa], got {text!r}")
    out = []
    for p in parts:
        try:
            out.append(positive_number(p))
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"every stress must be > 0 and finite [Pa], got {p!r}") from None
    return out


def build_parser() -> argparse.ArgumentParser:
    from .coupling.darcy import STRESSES
    from .dem.biaxial import SIGMA3, STRAIN_RATE

    parser = _Parser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    bi = sub.add_parser("biaxial", help="strain-controlled biaxial test (YADE)")
    bi.add_argument("--n", type=grain_count, default=1395, help="number of discs (default 1395)")
    bi.add_argument("--sigma3", type=positive_number, default=SIGMA3, help="confining stress [Pa] (default 1e5)")
    bi.add_argument("--strain-rate", type=positive_number, default=STRAIN_RATE,
                    help=f"axial strain rate [1/s] (default {STRAIN_RATE:g})")
    bi.add_argument("--max-strain", type=final_strain, default=0.025, help="final axial strain (default 0.025)")
    bi.add_argument("--seed", type=seed_value, default=0, help="packing seed (default 0)")
    add_contact_arguments(bi)
    bi.add_argument("--rate-check", action="store_true",
                    help="repeat the loading at half the strain rate on the same sample and report the change")
    bi.add_argument("--out", type=Path, help="run directory to create (default runs/biaxial-<time>-<pid>)")
    bi.add_argument("--quiet", action="store_true", help="no progress bar")

    da = sub.add_parser("darcy", help="network Darcy permeability vs confining stress (YADE)")
    da.add_argument("--stresses", type=stress_list, default=list(STRESSES),
                    help="comma-separated confining stresses [Pa] (default 1e5,1.4e5,5e5,1e6,1.5e6,2.1e6)")
    da.add_argument("--packing", type=Path, help="stored packing .npz to evaluate as well (default: the shipped "
                                                 "Huang sample)")
    da.add_argument("--n", type=grain_count, default=1395, help="discs of the compacted samples (default 1395)")
    da.add_argument("--seed", type=seed_value, default=0, help="packing seed (default 0)")
    add_contact_arguments(da, friction=False)  # the sweep's compactions; a stored packing keeps its own k_n
    da.add_argument("--contact-gap", type=contact_gap_fraction, default=NEAR_CONTACT_GAP,
                    help="grain pairs closer than this fraction of the smaller radius are pipes (default %(default)g, "
                         "the coupled runs'; 0.38 gives the paper's network counts: decisions #73)")
    da.add_argument("--out", type=Path, help="run directory to create (default runs/darcy-<time>-<pid>)")
    da.add_argument("--quiet", action="store_true", help="no progress lines")
    return parser


def provenance(argv) -> dict:
    return {"hmdem_version": __version__, "python": platform.python_version(), "argv": list(argv)}


def write_json(path: Path, data: dict) -> None:
    write_strict_json(path, data, default=float)


# --------------------------------------------------------------------------------------- biaxial

class _BiaxialProgress:
    """tqdm bars: compaction (cycles, wall stress) then loading (axial strain)."""

    def __init__(self, max_strain: float, every_s: float = 0.25):
        from tqdm import tqdm

        from .dem.compaction import CompactionBar

        self.tqdm, self.max_strain, self.every_s, self.last = tqdm, max_strain, every_s, 0.0
        self.compact = CompactionBar(every_s)
        self.loading = None

    def load(self, ea, s1, s3):
        if self.loading is None:
            from .cli import open_bar

            self.compact.close()
            self.loading = open_bar(self.tqdm, total=round(100 * self.max_strain, 3), unit="%", desc="loading",
                                    file=sys.stderr,
                                    bar_format="{desc}: {n:.2f}/{total:.2f} %|{bar}| [{elapsed}<{remaining}{postfix}]")
        now = time.perf_counter()
        if now - self.last >= self.every_s or ea >= self.max_strain:
            self.last = now
            self.loading.n = round(100 * min(ea, self.max_strain), 3)
            self.loading.set_postfix_str(f"sigma1 {s1 / 1e3:.1f} kPa, sigma3 {s3 / 1e3:.1f} kPa")

    def close(self):
        self.compact.close()
        if self.loading is not None:
            self.loading.close()
            self.loading = None


def plot_biaxial(path: Path, res, status: str) -> None:
    from .plots import plt

    ea = 100 * res.strain_axial
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 5.2))
    a1.plot(ea, res.sigma1 / 1e3, label=r"$\sigma_1$")
    a1.plot(ea, res.sigma3 / 1e3, label=r"$\sigma_3$")
    a1.plot(ea, res.deviator / 1e3, label=r"$\sigma_1-\sigma_3$", lw=0.8)
    lo, hi = res.fit_strain
    a1.axvspan(100 * lo, 100 * hi, color="0.85", zorder=0, label="E, nu fit range")
    if math.isfinite(res.young_modulus):  # an interrupted curve may stop short of the fit window
        x = ea[ea <= 100 * 4 * hi] / 100
        a1.plot(100 * x, res.young_modulus * x / 1e3, "k--", lw=0.8,
                label=f"E = {res.young_modulus / 1e6:.1f} MPa (paper 65.4)")
    a1.axhline(309.6, color="r", lw=0.6, ls=":", label=r"paper peak $\sigma_1$ 309.6 kPa (phi 30.8 deg)")
    if math.isfinite(res.peak_sigma1):
        a1.plot([100 * res.strain_at_peak], [res.peak_sigma1 / 1e3], "ro", ms=4,
                label=f"peak {res.peak_sigma1 / 1e3:.1f} kPa, phi = {res.friction_angle:.1f} deg")
    a1.set_xlabel("axial strain [%]")
    a1.set_ylabel("stress [kPa]")
    a1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)  # below: no curve hidden
    stopped = stop_note(status, "finished")
    if res.interrupted_in == "compaction":
        stopped = " (stopped in the compaction: no curve)"
    a1.set_title(f"biaxial test, {res.n_grains} discs, sigma3 = {res.sigma3_target / 1e3:g} kPa{stopped}", fontsize=9)
    a2.plot(ea, 100 * res.strain_volumetric, label="volumetric (area) strain")
    a2.plot(ea, 100 * res.strain_lateral, label="lateral strain")
    nu_label = (f"nu fit: nu = {res.poisson_ratio:.3f} (paper 0.102)" if math.isfinite(res.poisson_ratio)
                else "nu fit window (not reached)")
    a2.axvspan(100 * lo, 100 * hi, color="0.85", zorder=0, label=nu_label)
    a2.axhline(0, color="k", lw=0.5)
    a2.set_xlabel("axial strain [%]")
    a2.set_ylabel("strain [%] (compression > 0)")
    a2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def against(name: str, value: float, form: str, unit: str, error: float, target: float) -> str:
    """'name = value unit (error vs target)', or 'name = n/a' for a value an interrupted curve
    did not reach (NaN)."""
    if not math.isfinite(value):
        return f"{name} = n/a"
    return f"{name} = {value:{form}}{unit} ({error:+.1%} vs {target:g})"


def run_biaxial_command(args, argv) -> int:
    from .dem.biaxial import MAX_STRAIN, load_biaxial, run_biaxial
    from .dem.compaction import check_confining_stress

    check_confining_stress("--sigma3", [args.sigma3], args.contact_stiffness)
    out = new_run_directory(args.out, args.command)
    t0 = time.perf_counter()
    bar = None if args.quiet else _BiaxialProgress(args.max_strain)
    try:  # an interrupt returns what is done: no curve in the compaction, the curve so far in the loading
        res = run_biaxial(args.n, args.sigma3, args.strain_rate, args.seed, args.max_strain,
                          k_n=args.contact_stiffness, ks_over_kn=args.stiffness_ratio, friction=args.friction,
                          progress=None if bar is None else bar.load,
                          compaction_progress=None if bar is None else bar.compact)
    finally:
        if bar is not None:
            bar.close()
    summary = res.summary()
    if args.rate_check and res.status == "finished":
        try:
            half = load_biaxial(res.packing, args.sigma3, 0.5 * args.strain_rate, args.max_strain,
                                friction=args.friction, ks_over_kn=args.stiffness_ratio,
                                progress=None if bar is None else bar.load)
        finally:
            if bar is not None:
                bar.close()
        summary["status"] = half.status
        if half.status == "interrupted":
            summary["interrupted_in"] = "rate check"
        summary["rate_check"] = {"status": half.status, "strain_rate_per_s": half.strain_rate,
                                 "max_axial_strain": float(half.strain_axial[-1]) if len(half.strain_axial) else 0.0,
                                 "loading_seconds": half.loading_seconds}
        if half.status == "finished":  # a partial curve's peak is not comparable with the full one's
            summary["rate_check"].update({
                "peak_sigma1_pa": half.peak_sigma1,
                "young_modulus_pa": half.young_modulus,
                "poisson_ratio": half.poisson_ratio,
                "friction_angle_deg": half.friction_angle,
                "peak_relative_change": (half.peak_sigma1 - res.peak_sigma1) / res.peak_sigma1,
                "young_modulus_relative_change": (half.young_modulus - res.young_modulus) / res.young_modulus,
            })
    summary["wall_seconds"] = time.perf_counter() - t0
    summary["default_max_strain"] = MAX_STRAIN
    summary.update(provenance(argv))
    with atomic_run_directory(out) as tmp:
        write_json(tmp / "summary.json", summary)
        with open(tmp / "timeseries.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["cycles", "time_s", "axial_strain", "lateral_strain", "volumetric_strain",
                        "sigma1_pa", "sigma3_pa", "deviator_pa"])
            for row in zip(res.cycles, res.time, res.strain_axial, res.strain_lateral, res.strain_volumetric,
                           res.sigma1, res.sigma3, res.deviator):
                w.writerow([int(row[0])] + [f"{v:.9g}" for v in row[1:]])
        plot_biaxial(tmp / "biaxial.png", res, res.status)  # the full-rate curve's own status
    if res.interrupted_in == "compaction":
        print(f"{PROG}: interrupted in the compaction to sigma3, before the loading: {out} holds the settings "
              f"and no curve", file=sys.stderr)
    elif res.status == "interrupted":
        print(f"{PROG}: interrupted in the loading at axial strain {summary['max_axial_strain']:.3%}; the curve so "
              f"far and what it gives (NaN where it did not get far enough) are in {out}", file=sys.stderr)
    elif summary["status"] == "interrupted":
        print(f"{PROG}: interrupted in the half-rate check at axial strain "
              f"{summary['rate_check']['max_axial_strain']:.3%}; the full-rate test is complete in {out}, without "
              f"the check's comparison", file=sys.stderr)
    err = summary["relative_errors"]
    print(f"{against('E', res.young_modulus / 1e6, '.2f', ' MPa', err['young_modulus_pa'], 65.4)}, "
          f"{against('nu', res.poisson_ratio, '.3f', '', err['poisson_ratio'], 0.102)}, "
          f"{against('peak sigma1', res.peak_sigma1 / 1e3, '.1f', ' kPa', err['peak_sigma1_pa'], 309.6)}, "
          f"{against('phi', res.friction_angle, '.2f', ' deg', err['friction_angle_deg'], 30.8)}; "
          f"max |sigma3 - target| = "
          f"{f'{res.max_sigma3_deviation:.2%}' if math.isfinite(res.max_sigma3_deviation) else 'n/a'}")
    if "peak_relative_change" in summary.get("rate_check", {}):
        print(f"half strain rate: peak sigma1 changes by {summary['rate_check']['peak_relative_change']:+.2%}")
    print(f"run directory: {out} ({summary['wall_seconds']:.0f} s)")
    return interrupted_status() if summary["status"] == "interrupted" else 0


# ----------------------------------------------------------------------------------------- darcy

def plot_permeability(path: Path, rows: list[dict], packing_row: dict | None, status: str) -> None:
    from .coupling.darcy import PAPER_PERMEABILITY, PAPER_STRESS
    from .plots import plt

    fig, ax = plt.subplots(figsize=(6.4, 4.5))
    if rows:
        s = [r["confining_stress"] / 1e6 for r in rows]
        ax.plot(s, [r["permeability"] for r in rows], "o-", label="network Darcy (Eq. 13 apertures)")
        ax.plot(s, [r["kozeny_carman"] for r in rows], "s--", label="Kozeny-Carman (Eq. 20, Eq. 22 porosity)")
    if packing_row is not None:
        ax.plot([packing_row["confining_stress"] / 1e6], [packing_row["permeability"]], "k^",
                label="stored packing")
    ax.plot([PAPER_STRESS / 1e6], [PAPER_PERMEABILITY], "r*", ms=10, label="paper: 7.43e-13 m$^2$ at 0.14 MPa")
    ax.set_yscale("log")
    ax.set_xlabel("confining stress [MPa]")
    ax.set_ylabel("permeability [m$^2$]")
    ax.set_title(f"Darcy permeability against confining stress{stop_note(status, 'finished')}", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


CSV_KEYS = ("target_stress", "confining_stress", "permeability", "kozeny_carman", "porosity_2d", "porosity_3d",
            "mean_diameter", "mean_aperture", "mean_contact_force", "n_domains", "n_pipes", "n_closed_pipes",
            "length", "height", "balance_error", "seconds")


def run_darcy_command(args, argv) -> int:
    from .coupling.apertures import ApertureLaw
    from .coupling.darcy import PAPER_PERMEABILITY, PAPER_STRESS
    from .coupling.radial import default_huang_packing_path
    from .dem.compaction import CompactionBar, check_confining_stress
    from .dem.runs import permeability_sweep, stored_permeability
    from .network.contact_graph import ContactsOffTriangulation

    check_confining_stress("--stresses", args.stresses, args.contact_stiffness)
    path = args.packing or Path(str(default_huang_packing_path()))
    packing = read_compacted_packing(path)
    out = new_run_directory(args.out, args.command)
    t0 = time.perf_counter()
    law = ApertureLaw()
    # the stored sample's network first (no DEM): a --contact-gap its near contacts cannot take is
    # one line before minutes of compaction (a new-user pass: a traceback after them)
    given_gap = None if args.contact_gap == NEAR_CONTACT_GAP else args.contact_gap
    with near_contacts_checked(given_gap):
        stored = stored_permeability(packing, law, args.contact_gap)

    sweep = []  # the stresses done, kept as they finish
    bar = None if args.quiet else CompactionBar()

    def say(k, stress, res):
        sweep.append(res)
        if bar is not None:
            bar.close()  # the next compaction opens a fresh one below this line
            print(f"[{k + 1}/{len(args.stresses)}] {stress / 1e6:g} MPa: k = {res.permeability:.4g} m^2, "
                  f"KC = {res.kozeny_carman:.4g} m^2, porosity {res.porosity_2d:.4f}, "
                  f"{res.extra['seconds']:.0f} s", file=sys.stderr, flush=True)

    status, message = "finished", ""
    try:
        permeability_sweep(args.stresses, args.n, args.seed, k_n=args.contact_stiffness, law=law,
                           contact_gap=args.contact_gap, progress=say, compaction_progress=bar)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the stresses done, and the stored packing (no DEM)
        status = "interrupted"
    except ContactsOffTriangulation as exc:  # a freshly compacted sample the gap cannot take: keep what is done
        status = "failed"
        message = (f"the sample compacted to {args.stresses[len(sweep)] / 1e6:g} MPa (--n {args.n}, --seed "
                   f"{args.seed}) has no network at --contact-gap {args.contact_gap:g}: {exc}")
    finally:
        if bar is not None:
            bar.close()
    if status != "finished":
        print(f"{PROG}: {'interrupted' if status == 'interrupted' else message} after {len(sweep)} of "
              f"{len(args.stresses)} stresses; writing those", file=sys.stderr)
    rows = [r.row() for r in sweep]
    for r in rows:
        r["ratio_to_kozeny_carman"] = r["permeability"] / r["kozeny_carman"]
    stored_row = stored.row()
    stored_row["path"] = str(path)
    stored_row["contact_stiffness_n_per_m"] = packing.contact_stiffness  # the file's, not --contact-stiffness
    stored_row["relative_error_vs_paper"] = (stored.permeability - PAPER_PERMEABILITY) / PAPER_PERMEABILITY
    stored_row["ratio_to_kozeny_carman"] = stored.permeability / stored.kozeny_carman
    at_paper = [r for r in rows if abs(r["target_stress"] - PAPER_STRESS) <= 1e-9 * PAPER_STRESS]
    summary = {
        "status": status,
        "status_message": message,
        "stresses_pa": list(args.stresses),
        "n_grains": args.n,
        "seed": args.seed,
        "results": rows,
        "stored_packing": stored_row,
        "paper_permeability_m2": PAPER_PERMEABILITY,
        "paper_stress_pa": PAPER_STRESS,
        "sweep_permeability_at_paper_stress_m2": at_paper[0]["permeability"] if at_paper else None,
        "sweep_relative_error_vs_paper": ((at_paper[0]["permeability"] - PAPER_PERMEABILITY) / PAPER_PERMEABILITY
                                          if at_paper else None),
        "aperture_law": {"residual_aperture_m": law.residual_aperture, "half_aperture_force_n_per_m":
                         law.half_aperture_force, "fracture_multiplier": law.fracture_multiplier},
        "contact_gap": args.contact_gap,
        "contact_stiffness_n_per_m": args.contact_stiffness,  # of the sweep's compactions
        "definition": "k = eta L Q / (H dP); L = distance between the mean centroids of the inflow and outflow "
                      "domains, H = y extent of the grain centres; Kozeny-Carman with d = mean diameter and the "
                      "Eq. 22 3D porosity of the box-area 2D porosity",
        "wall_seconds": time.perf_counter() - t0,
    }
    summary.update(provenance(argv))
    with atomic_run_directory(out) as tmp:
        write_json(tmp / "summary.json", summary)
        with open(tmp / "permeability.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["source", *CSV_KEYS, "ratio_to_kozeny_carman"])
            for r in rows:
                w.writerow(["sweep"] + [_fmt(r.get(k)) for k in CSV_KEYS] + [_fmt(r["ratio_to_kozeny_carman"])])
            w.writerow(["stored_packing"] + [_fmt(stored_row.get(k)) for k in CSV_KEYS]
                       + [_fmt(stored_row["ratio_to_kozeny_carman"])])
        plot_permeability(tmp / "permeability.png", rows, stored_row, status)
    for r in rows:
        print(f"{r['confining_stress'] / 1e6:7.3f} MPa: k = {r['permeability']:.3e} m^2, KC = {r['kozeny_carman']:.3e}"
              f" (k/KC = {r['ratio_to_kozeny_carman']:.3f}), porosity {r['porosity_2d']:.4f}")
    print(f"stored packing ({stored.confining_stress / 1e6:.3f} MPa): k = {stored.permeability:.3e} m^2, "
          f"{stored_row['relative_error_vs_paper']:+.1%} vs the paper's 7.43e-13")
    print(f"run directory: {out} ({summary['wall_seconds']:.0f} s)")
    return {"interrupted": interrupted_status(), "failed": 1}.get(status, 0)


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, (int,)) or (hasattr(v, "dtype") and v.dtype.kind in "iu"):
        return str(int(v))
    return f"{float(v):.9g}"


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    return dispatch(PROG, parser, args, {"biaxial": lambda a: run_biaxial_command(a, argv),
                                         "darcy": lambda a: run_darcy_command(a, argv)})


if __name__ == "__main__":
    raise SystemExit(main())
