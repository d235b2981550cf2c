"""``phase_diagram.png``: the regime of every (M, Ca*) point of a sweep as a coloured field,
D_f written on each, with Lenormand's experiments as seed 004 reproduces them and the
crossover lines of :mod:`.boundaries`."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np

from ..flow.fluids import WEAK_COMPRESSION
from .table import NO_RESULT

REGIME_COLOURS = {
    "capillary fingering": "#f4a259",
    "viscous fingering": "#5b8fd9",
    "stable displacement": "#6abf69",
}
OTHER_COLOUR = "#cccccc"
# Lenormand, Touboul & Zarcone (1988) experiments as matched by seed 004 (§4.1, Table 1):
# (M, Ca*, regime observed)
LENORMAND_EXPERIMENTS = [(1.8e-5, 1.9e-4, "viscous fingering"), (1.8e-5, 3.1e-7, "capillary fingering"),
                         (101.8, 38.6, "stable displacement"), (101.8, 2.4e-3, "capillary fingering")]
LENORMAND_L_OVER_A = 150e-3 / 0.35e-3  # their micromodel: Ca = Ca* / 428.6 (digest §10.3)


def cell_edges(values: np.ndarray) -> np.ndarray:
    """Edges midway between sorted grid values (half a spacing beyond the ends; width 1 alone)."""
    if len(values) == 1:
        return np.array([values[0] - 0.5, values[0] + 0.5])
    mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([[2 * values[0] - mid[0]], mid, [2 * values[-1] - mid[-1]]])


def point_summary(rows: list[dict]) -> dict:
    """(log_m, log_ca_star) -> (majority regime or 'failed', mean D_f, runs, failed runs,
    largest p/K)."""
    groups: dict = {}
    for r in rows:
        key = (round(float(r["log_m"]), 6), round(float(r["log_ca_star"]), 6))
        groups.setdefault(key, []).append(r)
    out = {}
    for key, group in groups.items():
        ok = [r for r in group if r.get("status") not in NO_RESULT]
        regimes = Counter(r.get("regime") for r in ok)
        regime = regimes.most_common(1)[0][0] if ok else "failed"
        d_f = [float(r["fractal_dimension"]) for r in ok if r.get("fractal_dimension") not in (None, "")
               and math.isfinite(float(r["fractal_dimension"]))]
        compression = [float(r["peak_compression"]) for r in ok if r.get("peak_compression") not in (None, "")]
        out[key] = (regime, float(np.mean(d_f)) if d_f else math.nan, len(group), len(group) - len(ok),
                    max(compression, default=math.nan))
    return out


def plot_phase_diagram(path: Path, rows: list[dict], crossover: float | None = None,
                       planned: list[tuple[float, float]] | None = None) -> None:
    """Write the diagram; ``crossover``: Ca*_c at M >= 1 (:func:`.boundaries.capillary_crossover`);
    ``planned``: a sweep's runs as (log M, log Ca*), one per seed, so that a sweep stopped part-way
    shows its points not yet run as such (they took the finished cells' room, a new-user pass)."""
    from matplotlib.patches import Patch, Rectangle
    from matplotlib.patheffects import withStroke

    from ..plots import plt  # Agg backend, Debian's Axes3D warning silenced

    points = point_summary(rows)
    not_run = {(round(float(m), 6), round(float(c), 6)) for m, c in planned or ()} - set(points)
    flagged = [p[4] for p in points.values() if p[4] > WEAK_COMPRESSION]  # peak p/K beyond the constant-K range
    stars = [(math.log10(m), math.log10(c), regime) for m, c, regime in LENORMAND_EXPERIMENTS]
    fig, ax = plt.subplots(figsize=(8.5, 6.5))
    if points or not_run:
        ms = np.array(sorted({k[0] for k in points} | {k[0] for k in not_run}))
        cs = np.array(sorted({k[1] for k in points} | {k[1] for k in not_run}))
        m_edges, c_edges = cell_edges(ms), cell_edges(cs)

        def cell(m, c, **style):
            """Draw the grid cell of (m, c); its indices (i, j) in the edge arrays."""
            i, j = np.searchsorted(ms, m), np.searchsorted(cs, c)
            ax.add_patch(Rectangle((m_edges[i], c_edges[j]), m_edges[i + 1] - m_edges[i], c_edges[j + 1] - c_edges[j],
                                   **style))
            return i, j

        for m, c in not_run:
            cell(m, c, facecolor="white", edgecolor="lightgrey", hatch="..")
            ax.text(m, c, "not run", ha="center", va="center", fontsize=8, color="grey", zorder=3)
        for (m, c), (regime, d_f, n, failed, compression) in points.items():
            i, j = cell(m, c, facecolor=REGIME_COLOURS.get(regime, OTHER_COLOUR), edgecolor="white",
                        hatch="//" if regime == "failed" else None)
            label = "failed" if regime == "failed" else f"D$_f$ {d_f:.2f}" if math.isfinite(d_f) else "D$_f$ n/a"
            if failed and regime != "failed":
                label += f"\n{failed}/{n} failed"
            if compression > WEAK_COMPRESSION:
                label += f"\np/K {compression:.2f} !"
            x0, x1, y0, y1 = m_edges[i], m_edges[i + 1], c_edges[j], c_edges[j + 1]
            # a star in the cell: the label moves to the half of the cell the star is not in
            star_y = [y for x, y, _ in stars if x0 <= x < x1 and y0 <= y < y1]
            y = c if not star_y else c - 0.25 * (y1 - y0) if star_y[0] > c else c + 0.25 * (y1 - y0)
            ax.text(m, y, label, ha="center", va="center", fontsize=8, zorder=3,  # readable over the lines
                    bbox={"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.55, "edgecolor": "none"})
        x_lim, y_lim = (m_edges[0], m_edges[-1]), (c_edges[0], c_edges[-1])
    else:
        x_lim, y_lim = (-5.0, 2.0), (-8.0, 2.0)
    for m, c, regime in stars:
        # a white ring: a star on a cell of its own colour would look hollow without it
        ax.plot(m, c, marker="*", ms=14, color=REGIME_COLOURS[regime], mec="black", zorder=4,
                path_effects=[withStroke(linewidth=3, foreground="white")])
    if crossover is not None:
        x = np.linspace(min(x_lim[0], -6), max(x_lim[1], 3), 200)
        y = math.log10(crossover) + np.minimum(x, 0.0)
        ax.plot(x, y, "k--", lw=1.2)
        ax.plot([0.0, 0.0], [math.log10(crossover), y_lim[1] + 1], "k:", lw=1.2)
    ax.set_xlim(*x_lim)
    ax.set_ylim(*y_lim)
    ax.set_xlabel("log$_{10}$ M  (M = η$_{inv}$ / η$_{def}$)")
    ax.set_ylabel("log$_{10}$ Ca*  (seed 004 Eq. 24)")
    ratios = [float(r["ca"]) / float(r["ca_star"]) for r in rows if r.get("ca") not in (None, "")
              and math.isfinite(float(r["ca"]))]
    if ratios:
        shift = math.log10(float(np.median(ratios)))
        right = ax.secondary_yaxis("right", functions=(lambda y: y + shift, lambda y: y - shift))
        right.set_ylabel(f"log$_{{10}}$ Ca = Ca* ā / L  (this sample: Ca* / {1 / 10 ** shift:.1f})")
    handles = [Patch(color=c, label=name) for name, c in REGIME_COLOURS.items()]
    handles.append(Patch(facecolor=OTHER_COLOUR, hatch="//", label="failed / other"))
    if not_run:
        handles.append(Patch(facecolor="white", edgecolor="lightgrey", hatch="..", label="not run (sweep stopped)"))
    if flagged:
        handles.append(plt.Line2D([], [], ls="", label=f"'p/K {max(flagged):.2f} !': peak pressure / bulk modulus "
                                  f"beyond {WEAK_COMPRESSION}, the constant-K range"))
    handles.append(plt.Line2D([], [], marker="*", ls="", ms=12, color="grey", mec="black",
                              label=f"Lenormand et al. (1988) experiments at Ca* = {LENORMAND_L_OVER_A:.1f} Ca "
                                    "(their L / ā, seed 004 §4.1),\ncoloured by the regime they observed"))
    if crossover is not None:
        handles.append(plt.Line2D([], [], color="black", ls="--",
                                  label=f"viscous = 10 x capillary spread (Darcy; Ca*$_c$ = {crossover:.3g} at M ≥ 1)"))
        handles.append(plt.Line2D([], [], color="black", ls=":", label="M = 1 (Saffman-Taylor)"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    # Ca* (Eq. 24) scales Ca by each sample's L / ā: the right axis converts with this sample's,
    # the stars sit where Lenormand's micromodel (150 mm / 0.35 mm) puts its experiments
    runs = f"{len(rows)} of {len(planned)} runs" if planned and len(rows) < len(planned) else f"{len(rows)} runs"
    ax.set_title(f"Lenormand phase diagram: {runs}, regime by majority over seeds", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
