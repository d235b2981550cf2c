"""Figures and ParaView output of lattice-gas runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hmdem.cli import stop_note

from .flow import FlowResult, box_average
from .lattice import ROW, Geometry
from .studies import CONTINUUM, PAPER_ALPHA, eq11


def velocity_profile(path: Path, channel, result: FlowResult, fit: dict, nu_theory: float) -> None:
    """Row-averaged velocity across the channel against the fitted parabola and the parabola of
    Eq. 6's viscosity with the walls halfway between wall and fluid rows."""
    from hmdem.plots import plt

    geometry = channel.geometry
    rows = np.nonzero(geometry.fluid[:, 0])[0]
    u = result.row_velocity[rows]
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(rows, u, ".", ms=4, label="lattice gas (row means)")
    y = np.linspace(rows.min() - 1, rows.max() + 1, 200)
    ax.plot(y, np.polyval(fit["profile_coefficients"], y), "k-", lw=1, label=f"fitted parabola (R² = {fit['profile_r2']:.4f})")
    f, rho = result.force_applied, result.density
    lo = 0.5
    hi = geometry.shape[0] - 1 - (0.0 if channel.mirrored else 0.5)
    top = 2 * hi - lo if channel.mirrored else hi
    theory = f / (2 * nu_theory * rho) * ((y - lo) * ROW) * ((top - y) * ROW)
    ax.plot(y, theory, "r--", lw=1, label=f"Eq. 2 with ν = {nu_theory:.4f} (Eq. 6)")
    ax.set_xlabel("row")
    ax.set_ylabel("u_x [lattice units / step]")
    ax.legend(fontsize=8)
    ax.set_title(f"Poiseuille: ν fit {fit['viscosity_fit']:.4f}, u_max/u_mean {fit['u_max_over_mean']:.3f}"
                 f"{stop_note(fit['status'], 'finished')}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def flow_rate_against_force(path: Path, rows: list[dict], title: str) -> None:
    """Q_full against the pressure gradient (body force per area), with the line through the
    origin."""
    from hmdem.plots import plt

    dp = np.array([r["pressure_drop_per_length"] for r in rows])
    q = np.array([r["flow_rate_full"] for r in rows])
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(dp, q, "o")
    s = dp @ q / (dp @ dp)
    x = np.linspace(0, dp.max() * 1.1, 20)
    ax.plot(x, s * x, "k-", lw=1, label="through the origin")
    ax.set_xlabel("ΔP / L [lattice units]")
    ax.set_ylabel("Q (full aperture)")
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def velocity_field(path: Path, geometry: Geometry, result: FlowResult, title: str) -> None:
    """Speed in 10 x 10 boxes over the geometry, with streamlines of the box-averaged field."""
    from hmdem.plots import plt

    rho, ux, uy = result.fields.mean()
    fluid = geometry.fluid
    weight = np.where(fluid, rho, 0.0)
    bx, by = box_average(np.nan_to_num(ux), weight, 4), box_average(np.nan_to_num(uy), weight, 4)
    rows = max(1, round(4 / ROW))
    ny, nx = bx.shape
    xs = (np.arange(nx) + 0.5) * 4
    ys = (np.arange(ny) + 0.5) * rows * ROW
    speed = np.hypot(bx, by)
    fig, ax = plt.subplots(figsize=(9, 9 * ny * rows * ROW / (nx * 4) + 1))
    im = ax.pcolormesh(xs, ys, np.ma.masked_invalid(speed), shading="auto", cmap="viridis")
    ax.streamplot(xs, ys, np.nan_to_num(bx), np.nan_to_num(by), color="w", linewidth=0.5, density=1.5,
                  arrowsize=0.5)
    ny_nodes, nx_nodes = geometry.shape
    ax.imshow(np.ma.masked_where(~geometry.solid, np.ones(geometry.shape)), origin="lower", cmap="Greys",
              vmin=0, vmax=2, extent=(0, nx_nodes, -ROW / 2, (ny_nodes - 0.5) * ROW), interpolation="nearest",
              aspect="auto")
    fig.colorbar(im, ax=ax, label="|u| [lattice units / step]", shrink=0.7)
    ax.set_aspect("equal")
    ax.set_xlabel("x [lattice units]")
    ax.set_ylabel("y [lattice units]")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def collapse(path: Path, points: list[dict], alpha: float, alpha_error: float, status: str) -> None:
    """(delta_H/delta_av)^3 against delta_av/(2 y_max) per H, with Eq. 11, the fitted exponent and
    the digest's continuum (lattice-Boltzmann Stokes) values; titled when the study stopped early."""
    from hmdem.plots import plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    markers = {0.3: "o", 0.5: "s", 0.7: "D"}
    for hurst in sorted({p["hurst"] for p in points}):
        sel = [p for p in points if p["hurst"] == hurst]
        ax.plot([p["opening"] for p in sel], [p["phi"] for p in sel], markers.get(hurst, "^"), mfc="none",
                label=f"lattice gas, H = {hurst:g}")
    x = np.linspace(1.05, 2.8, 100)
    ax.plot(x, eq11(x), "k-", lw=1, label=f"Eq. 11, α = {PAPER_ALPHA}")
    ax.plot(x, eq11(x, alpha), "k--", lw=1, label=f"fit α = {alpha:.3f} ± {alpha_error:.3f}")
    for opening, by_h in CONTINUUM.items():
        ax.plot([opening] * len(by_h), list(by_h.values()), "x", color="0.5")
    ax.plot([], [], "x", color="0.5", label="continuum Stokes (digest §6)")
    ax.plot(x, np.ones_like(x), ":", color="0.6", lw=1)
    ax.set_xlabel("δ_av / (2 y_max)")
    ax.set_ylabel("(δ_H / δ_av)³")
    ax.set_ylim(0, 0.6)
    ax.legend(fontsize=7)
    ax.set_title(stop_note(status, "finished").strip(" ()"), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def drag_against_reynolds(path: Path, series: dict[str, list[dict]], status: str) -> None:
    """Delta P / Q normalised by its lowest-Re value, against Re, for each channel (seed 003 Fig. 11);
    titled when the ladder stopped early."""
    from hmdem.plots import plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for label, rows in series.items():
        re = np.array([r["reynolds"] for r in rows])
        resistance = np.array([r["pressure_drop_per_length"] / r["flow_rate_full"] for r in rows])
        ax.plot(re, resistance / resistance[0], "o-", label=label)
    ax.set_xlabel("Re = Q / ν")
    ax.set_ylabel("(ΔP/Q) / (ΔP/Q at the lowest Re)")
    ax.legend(fontsize=8)
    ax.set_title(stop_note(status, "finished").strip(" ()"), fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_field(path: Path, geometry: Geometry, result: FlowResult) -> None:
    """Node points with the time-averaged density and velocity and the node kind (ParaView).
    Solid and mirror nodes get zero velocity: they hold particles caught mid bounce-back, whose
    speeds (up to 1) swamped ParaView's colour range against the fluid's 0.04-0.14 (a new-user
    pass); ``kind`` still tells them apart."""
    import meshio

    x, y = geometry.positions()
    points = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    data = {"kind": (geometry.solid.astype(np.int8) + 2 * geometry.mirror.astype(np.int8)).ravel()}
    if result.fields is not None and result.fields.samples:
        rho, ux, uy = result.fields.mean()
        ux, uy = (np.where(geometry.fluid, np.nan_to_num(u), 0.0) for u in (ux, uy))
        data.update({"density": rho.ravel(), "velocity": np.column_stack([ux.ravel(), uy.ravel(), np.zeros(x.size)])})
    cells = [("vertex", np.arange(len(points)).reshape(-1, 1))]
    meshio.write(path, meshio.Mesh(points, cells, point_data=data))
