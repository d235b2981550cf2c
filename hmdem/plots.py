"""Figures of a run: the invasion pattern and the pressure (field and injection history)."""

from __future__ import annotations

import warnings

import matplotlib

matplotlib.use("Agg")
warnings.filterwarnings("ignore", message="Unable to import Axes3D")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.cm import ScalarMappable  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from .network.network import OUTSIDE, Network  # noqa: E402


def _domain_triangulation(net: Network, values: np.ndarray):
    inside = net.triangle_domain != OUTSIDE
    tri = Triangulation(net.points[:, 0] * 1e3, net.points[:, 1] * 1e3, net.triangles[inside])
    return tri, values[net.triangle_domain[inside]]


def _grains(ax, net: Network, radii):
    if radii is None:
        return
    circles = [Circle((x * 1e3, y * 1e3), r * 1e3) for (x, y), r in zip(net.points, radii)]
    ax.add_collection(PatchCollection(circles, facecolor="none", edgecolor="0.6", linewidth=0.2))


def _finish_sample_plane(fig, ax, path, title: str, autoscale: bool = True) -> None:
    """Equal axes in mm, the title, and the figure written to ``path`` and closed."""
    ax.set_aspect("equal")
    if autoscale:
        ax.autoscale_view()
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    fig.suptitle(title, fontsize=9)  # over the whole figure: a long title clears the colour bar
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_pattern(path, net: Network, saturation: np.ndarray, title: str, radii=None, overlay=None,
                 note: str | None = None) -> None:
    """Invaded domains drawn as polygons (union of their triangles), coloured by saturation;
    ``overlay``: segments (k, 2, 2) [m] drawn in red (opened contacts of a coupled run);
    ``note``: a line written across the sample (a single-phase run, where nothing invades)."""
    tri, s = _domain_triangulation(net, saturation)
    fig, ax = plt.subplots(figsize=(6.4, 6))
    pc = ax.tripcolor(tri, facecolors=s, cmap="Blues", vmin=0, vmax=1, edgecolors="none")
    _grains(ax, net, radii)
    if overlay is not None and len(overlay):
        ax.add_collection(LineCollection(np.asarray(overlay) * 1e3, colors="tab:red", linewidths=1.2,
                                         label=f"opened contacts ({len(overlay)})"))
    # the inflow marker is ringed in white: a radial run's single port sits on the dark invaded zone
    for ids, marker, colour, label in ((net.inlet_domains, "o", "tab:green", "inflow"),
                                       (net.outlet_domains, ".", "tab:purple", "outflow")):
        c = net.domain_centroid[ids] * 1e3
        ax.plot(c[:, 0], c[:, 1], marker, ls="none", color=colour, ms=4 if marker == "o" else 3,
                mec="white" if marker == "o" else colour, mew=0.7, label=label)
    fig.colorbar(pc, ax=ax, label="invading saturation S")
    ax.legend(loc="upper right", fontsize=7)
    if note:
        ax.text(0.5, 0.5, note, transform=ax.transAxes, ha="center", va="center", fontsize=9,
                bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "0.6"})
    _finish_sample_plane(fig, ax, path, title, autoscale=False)


PRESSURE_UNITS = (("GPa", 1e9), ("MPa", 1e6), ("kPa", 1e3), ("Pa", 1.0))


def pressure_unit(largest: float) -> tuple[str, float]:
    """The unit in which ``largest`` (Pa, magnitude) reads as 1 to 999: kPa ticks at GPa
    pressures (a sweep's compressed air) were seven digits long."""
    for name, factor in PRESSURE_UNITS:
        if abs(largest) >= factor:
            return name, factor
    return PRESSURE_UNITS[-1]


def field_scale(pressure: np.ndarray) -> tuple[str, float, float, float | None, bool]:
    """The pressure map's colour scale: (unit, Pa per unit, low, top or None for the full range,
    whether the scale is cut below the maximum). A few isolated domains (trapped, compressed
    pockets) would squeeze the field into the bottom of the scale, so it ends at the 99.5th
    percentile of the domains, and the unit follows the scale, not those few (a 30 kPa field
    with three 2 GPa pockets reads in kPa, the title naming the maximum)."""
    top_pa = float(np.percentile(pressure, 99.5))
    low_pa = min(float(np.min(pressure)), top_pa)
    unit, factor = pressure_unit(max(abs(low_pa), abs(top_pa)))
    top, low = top_pa / factor, low_pa / factor
    # cut only where the scale ends below the maximum (top == low: the full range, vmax None)
    cut = float(np.max(pressure)) / factor > top + 1e-9 * abs(top) + 1e-12 and top > low
    return unit, factor, low, top if top > low else None, cut


def plot_pressure(path, net: Network, pressure: np.ndarray, times, p_in, title: str, early_peak=None) -> None:
    """Final pressure field and the mean injection pressure against time, each in the unit of
    its own scale; ``early_peak`` ({"time": s, "pressure": Pa}) is marked when given."""
    tri, p = _domain_triangulation(net, pressure)
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4.6))
    field_unit, field_factor, low, top, cut = field_scale(np.asarray(pressure, dtype=float))
    pc = a0.tripcolor(tri, facecolors=p / field_factor, cmap="viridis", edgecolors="none", vmin=low, vmax=top)
    fig.colorbar(pc, ax=a0, label=f"p [{field_unit}]", extend="max" if cut else "neither")
    a0.set_aspect("equal")
    a0.set_xlabel("x [mm]")
    a0.set_ylabel("y [mm]")
    largest = float(np.max(pressure))
    largest_unit, largest_factor = pressure_unit(largest)
    clipped = (f" (scale ends at the 99.5th percentile; max {largest / largest_factor:.4g} {largest_unit})"
               if cut else "")
    a0.set_title(f"final pressure{clipped}", fontsize=9)
    p_in = np.asarray(p_in, dtype=float)
    curve_unit, curve_factor = pressure_unit(float(np.max(np.abs(p_in))) if len(p_in) else 0.0)
    a1.plot(times, p_in / curve_factor, lw=1)
    if early_peak is not None:
        a1.plot([early_peak["time"]], [early_peak["pressure"] / curve_factor], "o", mfc="none", color="C3",
                label="early peak")
        a1.legend(fontsize=8, loc="lower right")
    a1.set_xlabel("t [s]")
    a1.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3))  # B3's 0.00025 s ticks crowded the axis
    a1.set_ylabel(f"mean injection pressure [{curve_unit}]")
    a1.set_title(title, fontsize=9)
    a1.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_force_chains(path, positions: np.ndarray, radii: np.ndarray, pairs: np.ndarray, forces: np.ndarray,
                      title: str, fixed=None) -> None:
    """Contact force network: a line between the centres of each contact, width and shade by force."""
    fig, ax = plt.subplots(figsize=(6.4, 6))
    circles = [Circle((x * 1e3, y * 1e3), r * 1e3) for (x, y), r in zip(positions, radii)]
    face = np.where(fixed, "0.75", "none") if fixed is not None and len(fixed) else "none"
    ax.add_collection(PatchCollection(circles, facecolor=face, edgecolor="0.7", linewidth=0.2))
    if len(pairs):
        scale = forces / max(forces.max(), 1e-300)
        segments = positions[pairs] * 1e3
        lc = LineCollection(segments, linewidths=0.3 + 2.5 * scale, cmap="inferno_r", array=forces)
        ax.add_collection(lc)
        fig.colorbar(lc, ax=ax, label="normal contact force [N per m]")
    _finish_sample_plane(fig, ax, path, title)


def plot_fracture_chronology(path, net: Network, saturation: np.ndarray, radii, segments: np.ndarray,
                             opened_time: np.ndarray, reached: np.ndarray, before_fluid: np.ndarray,
                             title: str) -> None:
    """Opened contacts (``segments`` (k, 2, 2) [m]) coloured by the time they opened, over the
    invaded pattern (grey by saturation): solid where invading fluid entered one of the
    contact's pores after it opened, dotted where the fluid was there first, dashed where it
    never came (``reached``, ``before_fluid``: the masks of fracture_timing)."""
    tri, s = _domain_triangulation(net, saturation)
    fig, ax = plt.subplots(figsize=(6.4, 6))
    ax.tripcolor(tri, facecolors=s, cmap="Greys", vmin=0, vmax=2.5, edgecolors="none")
    _grains(ax, net, radii)
    if len(segments):
        t_max = float(np.nanmax(opened_time))
        unit, factor = ("ms", 1e3) if t_max >= 1e-3 else ("µs", 1e6)
        t_scaled = np.asarray(opened_time) * factor
        norm = Normalize(vmin=0.0, vmax=max(t_max * factor, 1e-12))
        styles = ((before_fluid, "solid", "opened, then the fluid came"),
                  (reached & ~before_fluid, "dotted", "the fluid came first"),
                  (~reached, "dashed", "the fluid never came"))
        for mask, style, label in styles:
            if mask.any():
                lc = LineCollection(np.asarray(segments)[mask] * 1e3, cmap="viridis", norm=norm, linewidths=1.4,
                                    linestyles=style, label=f"{label} ({int(mask.sum())})")
                lc.set_array(t_scaled[mask])
                ax.add_collection(lc)
        fig.colorbar(ScalarMappable(norm=norm, cmap="viridis"), ax=ax, label=f"opened at t [{unit}]")
        ax.legend(loc="upper right", fontsize=7)
    _finish_sample_plane(fig, ax, path, title)


def plot_darcy_transient(path, test) -> None:
    """A darcy run against seed 004 App. D.1 (a :class:`hmdem.flow.darcy_transient.DarcyTest`):
    injection pressure and outflow against t_D with Eqs. 37-38, and the final profile."""
    from .flow.darcy_transient import U16_TOLERANCE, series

    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4.2))
    # gauge pressures are positive, p_D = -p k H / (eta L Q) is not: the curves compare p / dP with -p_D
    t_d = np.geomspace(float(test.t_d[0]), float(test.t_d[-1]), 400)
    a0.semilogx(test.t_d, test.inflow_pressure, lw=1.5, color="C0", label="p_in / ΔP, run")
    a0.semilogx(t_d, -series(0.0, t_d)[0], "k--", lw=1, label="−p_D(0, t_D), Eq. 37")
    a0.semilogx(test.t_d, test.outflow_rate, lw=1.5, color="C1", label="q_out / Q, run")
    a0.semilogx(t_d, series(1.0, t_d)[1], "k:", lw=1, label="q_D(1, t_D), Eq. 38")
    a0.set_xlabel("t_D")
    a0.set_ylabel("dimensionless")
    a0.set_title(f"largest errors: p_in {test.inflow_pressure_error:.1%}, q_out {test.outflow_rate_error:.1%} "
                 f"(U16: < {U16_TOLERANCE:.0%})", fontsize=9)
    a0.legend(fontsize=8, loc="upper left")
    a0.grid(alpha=0.3)
    x_d = np.linspace(0.0, 1.0, 200)
    a1.plot(test.profile_x_d, test.profile, "o", color="C0", label="p / ΔP, run (mean per bin)")
    a1.plot(x_d, -series(x_d, test.t_d[-1])[0], "k--", lw=1, label=f"−p_D(x_D, {test.t_d[-1]:.3g}), Eq. 37")
    a1.set_xlabel("x_D")
    a1.set_ylabel("dimensionless pressure")
    a1.set_title(f"final profile: largest error {test.profile_error:.1%}; k = {test.permeability:.4g} m², "
                 f"c_v = {test.storage_fraction:.3f}", fontsize=9)
    a1.legend(fontsize=8)
    a1.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
