"""Channel geometries on the triangular lattice (seed 003 §3 and §4.2; digest §2.2).

Wall positions: a bounce-back wall's no-slip plane lies halfway between its last solid row and
the first fluid row; a mirror row is itself the symmetry plane (a particle spends one step on it
and leaves as from its mirror image). So a flat channel of W fluid rows between two walls is
W sqrt(3)/2 wide, and a half channel of W fluid rows under a mirror is (W + 1/2) sqrt(3)/2 to its
symmetry plane (decisions #40).
"""

from __future__ import annotations

import math

import numpy as np

from .lattice import ROW, Geometry, node_positions

FLAT_SECTION = 20  # lattice units of smooth wall before and after the rough section (seed 003 §4.2)


def smooth_channel(length: int, rows: int) -> Geometry:
    """``rows`` fluid rows between two bounce-back walls: the Poiseuille test of seed 003 §3
    (600 long, 100 rows)."""
    solid = np.zeros((rows + 2, length), dtype=bool)
    solid[0] = solid[-1] = True
    return Geometry(solid, np.zeros_like(solid), description={
        "kind": "smooth", "length": length, "fluid_rows": rows, "width": rows * ROW})


def half_channel(length: int, rows: int) -> Geometry:
    """``rows`` fluid rows over a flat bounce-back wall under a mirror row: half of a smooth
    channel of full width 2 (rows + 1/2) sqrt(3)/2 (digest claim C8)."""
    solid = np.zeros((rows + 2, length), dtype=bool)
    mirror = np.zeros_like(solid)
    solid[0] = True
    mirror[-1] = True
    return Geometry(solid, mirror, description={
        "kind": "half", "length": length, "fluid_rows": rows, "width": 2 * (rows + 0.5) * ROW})


def rough_channel(profile: np.ndarray, rough_length: int, largest_asperity: float, half_aperture: float,
                  flat: int = FLAT_SECTION) -> Geometry:
    """A self-affine bottom wall under a mirror (seed 003 Fig. 8).

    ``profile`` holds heights at ``len(profile)`` equally spaced points over the rough section of
    ``rough_length`` (a midpoint-displacement profile, whose ends are equal); smooth sections of
    ``flat`` units continue it at its end height before and after, so the wall is continuous
    across the periodic length ``rough_length + 2 flat``. The mean plane is the wall's mean over
    that whole length, and the wall is scaled so that its highest point stands
    ``largest_asperity`` (y_max) above it. A node is solid where it lies on or below the wall. The
    mirror row is the one nearest to the mean plane plus ``half_aperture`` (= delta_av / 2); the
    realised mean aperture is measured from the fluid area (:func:`apertures`)."""
    length = rough_length + 2 * flat
    stations = np.linspace(0.0, rough_length, len(profile))

    def wall_at(x):
        return np.interp(x - flat, stations, profile, left=profile[0], right=profile[-1])

    samples = wall_at(np.arange(0.0, length, 0.5))  # both row parities' node positions
    mean = samples.mean()
    scale = largest_asperity / (samples.max() - mean)
    lowest = (samples.min() - mean) * scale
    base = -lowest + 1.5 * ROW  # the mean plane's height: the deepest valley stays above row 0
    mirror_row = int(round((base + half_aperture) / ROW))
    x, y = node_positions(mirror_row + 1, length)
    solid = y <= base + (wall_at(x) - mean) * scale
    solid[0] = True
    mirror = np.zeros_like(solid)
    mirror[mirror_row] = True
    geometry = Geometry(solid, mirror)
    geometry.description = {"kind": "rough", "length": length, "rough_length": rough_length, "flat": flat,
                            "mean_plane": base, "mirror_row": mirror_row, "y_max": largest_asperity,
                            "flat_height": float((profile[0] - mean) * scale)}
    geometry.description.update(apertures(geometry))
    return geometry


def apertures(geometry: Geometry) -> dict:
    """delta_av = 2 x (fluid area per unit length + the mirror's half row), and the width of the
    smooth entrance (from its first fluid row's lower half-row to the mirror)."""
    ny, nx = geometry.shape
    fluid = geometry.fluid
    half = (fluid.sum() / nx + 0.5) * ROW
    out = {"mean_aperture": 2.0 * half}
    flat = geometry.description.get("flat", 0)
    if flat:
        column = fluid[:, : max(1, flat // 2)]
        out["entrance_width"] = float((column.sum(axis=0).mean() + 0.5) * ROW)
    return out


def relative_aperture(geometry: Geometry) -> float:
    """delta_av / (2 y_max): the inverse of seed 003's relative roughness."""
    d = geometry.description
    return d["mean_aperture"] / (2.0 * d["y_max"]) if d.get("y_max") else math.inf
