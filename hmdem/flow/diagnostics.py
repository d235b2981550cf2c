"""Pattern diagnostics: rasterised invasion pattern, box-counting fractal dimension (seed 004
App. E) and the regime label."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from matplotlib.tri import Triangulation

from ..network.network import OUTSIDE, Network


def rasterize_domains(net: Network, domain_mask: np.ndarray, pixels: int = 512) -> tuple[np.ndarray, float]:
    """Binary image (pixels x pixels over the network extent) of the domains where mask is True.

    Every domain is a union of triangles of the centre triangulation, so a pixel belongs to a
    domain through the triangle that contains its centre. Returns (image, pixel size in m).
    """
    x0, x1, y0, y1 = net.extent
    size = max(x1 - x0, y1 - y0)
    h = size / pixels
    xs = x0 + (np.arange(pixels) + 0.5) * h
    ys = y0 + (np.arange(pixels) + 0.5) * h
    X, Y = np.meshgrid(xs, ys)
    tri = Triangulation(net.points[:, 0], net.points[:, 1], net.triangles)
    t = tri.get_trifinder()(X.ravel(), Y.ravel())
    dom = np.where(t >= 0, net.triangle_domain[np.maximum(t, 0)], OUTSIDE)
    inside = dom != OUTSIDE
    img = np.zeros(X.size, bool)
    img[inside] = domain_mask[dom[inside]]
    return img.reshape(pixels, pixels), h


def grain_diameter(net: Network) -> float:
    """The median pipe length r1 + r2: the smallest scale of the pattern dimensions."""
    return float(np.median(net.pipe_length))


def pattern_scales(net: Network) -> tuple[float, float]:
    """The box sizes App. E's counting spans on a network [m]: the grain scale to a quarter of
    the sample (its longer side)."""
    x0, x1, y0, y1 = net.extent
    return grain_diameter(net), max(x1 - x0, y1 - y0) / 4


def box_counts(image: np.ndarray, sizes) -> np.ndarray:
    """Number of s x s boxes holding at least one set pixel, for each box size s (pixels)."""
    counts = []
    for s in sizes:
        n = -(-image.shape[0] // s) * s
        padded = np.zeros((n, n), bool)
        padded[: image.shape[0], : image.shape[1]] = image
        blocks = padded.reshape(n // s, s, n // s, s).any(axis=(1, 3))
        counts.append(int(blocks.sum()))
    return np.asarray(counts)


def fractal_dimension(net: Network, domain_mask: np.ndarray, smallest: float, largest: float,
                      pixels: int = 512, n_scales: int = 8) -> tuple[float, np.ndarray, np.ndarray]:
    """Box-counting dimension D_f = -d log N / d log s (seed 004 Eq. 39 with the digest's sign fix).

    Local slopes between consecutive box sizes from ``smallest`` to ``largest`` (in metres:
    grain scale to a fraction of the sample) are averaged, the paper's "local fractal
    dimension". Returns (D_f, box sizes in m, counts).
    """
    image, h = rasterize_domains(net, domain_mask, pixels)
    return image_box_dimension(image, h, smallest, largest, n_scales)


def image_box_dimension(image: np.ndarray, h: float, smallest: float, largest: float,
                        n_scales: int = 8) -> tuple[float, np.ndarray, np.ndarray]:
    """App. E's box counting on a binary image of pixel size ``h``: the mean local slope of
    -log N(s) over ``n_scales`` log-spaced box sizes s from ``smallest`` to ``largest`` [m].
    Returns (D_f, box sizes in m, counts)."""
    sizes = np.unique(np.round(np.geomspace(smallest / h, largest / h, n_scales)).astype(int))
    sizes = sizes[sizes >= 1]
    counts = box_counts(image, sizes)
    return -mean_log_slope(sizes, counts), sizes * h, counts


def rasterize_segments(starts: np.ndarray, ends: np.ndarray, extent, pixels: int = 512) -> tuple[np.ndarray, float]:
    """Binary image (pixels x pixels over ``extent`` = (x0, x1, y0, y1), square pixels as
    :func:`rasterize_domains`) of straight segments from ``starts`` to ``ends`` (n, 2), each a
    one-pixel line sampled at a quarter of a pixel. Returns (image, pixel size in m)."""
    x0, x1, y0, y1 = extent
    h = max(x1 - x0, y1 - y0) / pixels
    image = np.zeros((pixels, pixels), bool)
    starts, ends = np.asarray(starts, float).reshape(-1, 2), np.asarray(ends, float).reshape(-1, 2)
    drawn = np.isfinite(starts).all(axis=1) & np.isfinite(ends).all(axis=1)  # no direction: no segment
    starts, ends = starts[drawn], ends[drawn]
    if len(starts) == 0:
        return image, h
    samples = int(np.ceil(4 * np.max(np.linalg.norm(ends - starts, axis=1)) / h)) + 2
    along = np.linspace(0.0, 1.0, samples)[None, :, None]
    points = (starts[:, None, :] + along * (ends - starts)[:, None, :]).reshape(-1, 2)
    col, row = np.floor((points - (x0, y0)) / h).astype(int).T
    inside = (col >= 0) & (col < pixels) & (row >= 0) & (row < pixels)
    image[row[inside], col[inside]] = True
    return image, h


def mean_log_slope(scale: np.ndarray, count: np.ndarray) -> float:
    """Mean of the local slopes d log(count) / d log(scale) over the non-zero counts (the
    paper's "local fractal dimension" averaging); nan with fewer than two."""
    ok = count > 0
    if ok.sum() < 2:
        return float("nan")
    return float(np.mean(np.diff(np.log(count[ok])) / np.diff(np.log(scale[ok]))))


def mass_radius_dimension(net: Network, domain_mask: np.ndarray, centre, smallest: float,
                          pixels: int = 512, n_scales: int = 8) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass-radius (sandbox) dimension of a pattern grown from ``centre``: M(r) ~ r^D, M the
    pattern area within r of the centre (docs/decisions.md #27).

    For a radial injection the pattern is a finite object a few grain sizes across, and box
    counting over the ~1.5 decades between a grain and the sample is biased low by the
    pattern's edge: a perfectly filled disc of the front radius reads 1.53-1.86 on the Huang
    sample. M(r) of a filled disc is pi r^2 for every r inside it, so the sandbox dimension of
    a compact front is 2 and that of fingers is lower. Radii from ``smallest`` to half the
    pattern's largest distance from the centre, log-spaced; D is the mean local slope, as for
    :func:`fractal_dimension`. Returns (D, radii in m, pixel counts).
    """
    image, h = rasterize_domains(net, domain_mask, pixels)
    x0, _, y0, _ = net.extent
    rows, cols = np.nonzero(image)
    distance = np.hypot(x0 + (cols + 0.5) * h - centre[0], y0 + (rows + 0.5) * h - centre[1])
    if len(distance) == 0 or 0.5 * distance.max() <= smallest:
        return float("nan"), np.zeros(0), np.zeros(0, int)
    radii = np.geomspace(smallest, 0.5 * distance.max(), n_scales)
    mass = np.searchsorted(np.sort(distance), radii, side="right")
    return mean_log_slope(radii, mass), radii, mass


VISCOUS_TO_CAPILLARY_THRESHOLD = 10.0
UNDETERMINED = "undetermined"


def regime_at_breakthrough(status: str, regime: str) -> str:
    """A regime is read on the pattern at breakthrough (Lenormand's and Huang's both are); a run
    stopped before it (interrupted, ``--max-steps``, ``--t-max``, diverged) holds a partial
    pattern, so its regime is "undetermined" (docs/decisions.md #76)."""
    return regime if status == "breakthrough" else UNDETERMINED


def classify_regime(fractal_dim: float, injection_pressure_median: float, entry_pressure_spread: float) -> str:
    """Lenormand regime from the run itself, never from its inputs (docs/decisions.md).

    A compact pattern (D_f >= 1.90, digest L3) is stable displacement. Otherwise what selects
    the next invaded pipe decides: the disorder of the capillary thresholds (capillary
    fingering) when the driving pressure stays within a few times the spread (standard
    deviation) of the entry pressures |p_c|, the viscous pressure field (viscous fingering)
    when it exceeds 10x that spread. Uniform thresholds (a regular lattice) have no spread, so
    the viscous field always selects.
    """
    if not np.isfinite(fractal_dim):
        return UNDETERMINED
    if fractal_dim >= 1.90:
        return "stable displacement"
    if injection_pressure_median < VISCOUS_TO_CAPILLARY_THRESHOLD * entry_pressure_spread:
        return "capillary fingering"
    return "viscous fingering"


EARLY_PEAK_POINTS = 200  # t_end / 200: the same count as H10's grid in the paper-size tests
EARLY_PEAK_FALL = 0.02  # a fall below 98 % of the running peak ends the early peak (H10's drop size)


class EarlyPeak(NamedTuple):
    pressure: float  # Pa
    time: float  # s
    fell: bool  # the curve fell after it (False: the overall peak of a curve that never fell)


def early_peak(times, pressure, points: int = EARLY_PEAK_POINTS, fall: float = EARLY_PEAK_FALL) -> EarlyPeak:
    """The injection pressure's early peak.

    Seed 004 §4.2 (Fig. 14) quotes A3's pressure as "peaks at 0.86 MPa ... initiating fractures"
    followed by "a drop in injection pressure" and a later rise, and compares B3's peak with "the
    early peak in A3", so a run's early peak is the largest pressure before the curve first falls
    more than ``fall`` x |running maximum| below its running maximum. The fall is looked for in
    the curve's means over ``points`` equal intervals of the run (single steps dip when a pore
    fills and its meniscus jumps), so the grid scales with the run's length; the value and time
    are the largest recorded step up to the end of the interval that fell. A curve that never
    falls gives its overall peak with ``fell`` False. Non-finite samples are left out.
    """
    t, p = np.asarray(times, float), np.asarray(pressure, float)
    finite = np.isfinite(t) & np.isfinite(p)
    t, p = t[finite], p[finite]
    if len(t) == 0:
        return EarlyPeak(float("nan"), float("nan"), False)
    # time integral of the piecewise-linear curve, held at p[0] from t = 0
    t0, p0 = np.r_[0.0, t], np.r_[p[0], p]
    integral = np.r_[0.0, np.cumsum(0.5 * (p0[1:] + p0[:-1]) * np.diff(t0))]
    edges = np.linspace(0.0, t[-1], points + 1)
    width = np.diff(edges)
    means = np.diff(np.interp(edges, t0, integral)) / np.where(width > 0, width, 1.0)
    running = np.maximum.accumulate(means)
    falls = np.flatnonzero(means < running - fall * np.abs(running))
    before = t <= edges[falls[0] + 1] if len(falls) else np.ones(len(t), bool)
    k = int(np.argmax(np.where(before, p, -np.inf)))
    return EarlyPeak(float(p[k]), float(t[k]), bool(len(falls)))
