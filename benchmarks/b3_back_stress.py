"""What B3's injection pressure follows after its early peak: the dry skeleton's compaction (digest H4).

    .venv/bin/python benchmarks/b3_back_stress.py RUN_DIR [RUN_DIR ...] [--frames]

Reads radial run directories written with ``--snapshots N``. Domain volumes are centre-polygon
areas (digest §3.3) and the hull grains are fixed, so the room the invaded domains gain as the
grains move (the cavity) is taken from the dry domains: their area strain is the compaction of
the dry skeleton. From the trough after the early peak to breakthrough, the injection pressure
is fitted by least squares against that strain, p_in = p0 + M strain, and, for the reading of
a viscous invaded zone (BENCHMARKS.md, "Where B3's injected volume goes"), against ln of the
invaded domains' starting area (its slope given per unit ln R, R the zone's equivalent radius).
M is compared with the sample's biaxial E (``python -m hmdem.calibrate biaxial``).
``--frames`` prints each snapshot, with the sample's area: a run with ``--boundary loaded``
(decisions #86) has no fixed hull, its dry domains can grow, and its row gives no fit; its
frames still read. A second or two per directory.
"""
import argparse
import tomllib
from pathlib import Path

import meshio
import numpy as np

from b3_volume_split import starting_geometry  # a sibling script (benchmarks/ is the script's own folder)
from hmdem.coupling.model import VOLUME_FLOOR
from hmdem.snapshots import read_collection
from md_table import header


def frames(run: Path) -> np.ndarray:
    """Per snapshot: t, p_in (the mean over the inlet domains, as timeseries.csv's p_in_mean), the
    dry skeleton's area strain (compaction positive), the invaded domains' starting area, the
    sample's area strain (growth positive: 0 with the hull fixed) and the number of polygons
    squeezed to 1 % of their starting area or turned inside out (model.py's VOLUME_FLOOR)."""
    net, fractures = np.load(run / "network.npz"), np.load(run / "fractures.npz")
    start = fractures["initial_positions"]
    geometry = starting_geometry(net, start)
    v0 = geometry.volumes(start)
    n = len(v0)
    rows = []
    for t, name in read_collection(run / "domains.pvd"):
        mesh = meshio.read(name)
        cells = mesh.cell_data
        saturation, pressure = np.zeros(n), np.zeros(n)
        saturation[cells["domain"][0]] = cells["saturation"][0]
        pressure[cells["domain"][0]] = cells["pressure"][0]
        dry = saturation == 0
        v = geometry.volumes(mesh.points[:, :2])
        strain = (v0[dry] - v[dry]).sum() / v0[dry].sum()
        rows.append((t, pressure[net["inlet_domains"]].mean(), strain, v0[~dry].sum(), v.sum() / v0.sum() - 1.0,
                     np.sum(v <= VOLUME_FLOOR * v0)))
    return np.array(rows)


def fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least squares y = a + b x: a, b and the coefficient of determination."""
    design = np.c_[np.ones_like(x), x]
    (a, b), *_ = np.linalg.lstsq(design, y, rcond=None)
    return a, b, 1.0 - (y - design @ (a, b)).var() / y.var()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="radial run directories with snapshots")
    parser.add_argument("--frames", action="store_true", help="print each snapshot")
    args = parser.parse_args()
    print(header("run", "k_n [N/m]", "t_f [s]", "trough p_in [MPa] at [us]", "p_in at t_f [MPa]",
                 "dry compaction at t_f", "p0 [MPa]", "M [MPa]", "R²",
                 "against ln(invaded area): R², slope per unit ln R [MPa]"))
    for run in args.runs:
        r = frames(run)
        dem = tomllib.loads((run / "config.toml").read_text())["dem"]
        stiffness = dem["contact_stiffness_n_per_m"]
        after_peak = r[:, 0] > 5e-6  # the early peak is the port's filling, in the first few us
        trough = int(np.argmin(np.where(after_peak, r[:, 1], np.inf)))
        t, p, strain, invaded = r[trough:, :4].T
        p0, modulus, r2 = fit(strain, p)
        _, per_ln_area, r2_log = fit(np.log(invaded), p)
        if args.frames:
            for row in r:
                print(f"  {row[0] * 1e6:7.1f} us  p_in {row[1] / 1e6:6.2f} MPa  dry compaction {row[2]:6.2%}  "
                      f"invaded {row[3] * 1e6:.4f} mm²  sample area {row[4]:+.2%}  floored {row[5]:.0f}")
        if dem.get("boundary_hold", "fixed") != "fixed":
            print(f"| {run} | {stiffness:.3g} | {r[-1, 0]:.3g} | boundary {dem['boundary_hold']}: no fixed hull, "
                  "no fit |||||||", flush=True)
            continue
        print(f"| {run} | {stiffness:.3g} | {r[-1, 0]:.3g} | {p[0] / 1e6:.2f} at "
              f"{t[0] * 1e6:.0f} | {p[-1] / 1e6:.2f} | {strain[-1]:.2%} | {p0 / 1e6:.2f} | {modulus / 1e6:.1f} | "
              f"{r2:.3f} | {r2_log:.3f}, {2 * per_ln_area / 1e6:.2f} |", flush=True)  # ln area = 2 ln R


if __name__ == "__main__":
    main()
