"""The liquid bridge between two equal spheres from its Young–Laplace profile (seed 002 Eq. 3).

Digest §4.1. The bridge is axisymmetric about the line of centres and symmetric about the mid
plane, where its neck is. Its meridian, followed by arc length l from the neck, obeys Eq. 3:

    dx/dl = cos(phi),  dy/dl = sin(phi),  dphi/dl = S + cos(phi) / y,

with phi the meridian's slope angle and S = Delta P / gamma the suction (Delta P > 0 when the
liquid is below the gas pressure, the chapter's sign; a cylinder has S = -1/y). The meridian
meets a sphere at the contact angle theta where y = R cos(phi + theta); the filling angle there
is beta = pi/2 - phi - theta, and the gap follows from where that sphere's centre sits. The
bridge pulls the spheres together with

    F = 2 pi gamma y cos(phi) + pi y^2 Delta P,

the same at every cross-section (a first integral of Eq. 3): at the neck, 2 pi gamma y0 +
pi y0^2 Delta P (digest §4.1). Everything here is in units of R = gamma = 1: volumes scale with
R^3, gaps and necks with R, suctions with gamma/R and forces with gamma R.

A neck radius and a suction give one bridge (:func:`profile`, or :func:`meridians` for many at
once). :class:`BridgeTable` turns a grid of them into the suction and force of a bridge of given
volume and gap, as the chapter's tables of Semprebon and Brinkmann did (§4.1). At a fixed gap a
bridge's volume against its neck has a minimum: less liquid cannot span the gap, which is the
rupture distance (the quantity Eq. 5 fits). Of the two bridges holding more, the one with the
wider neck is the stable one; the table keeps that one.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp
from scipy.interpolate import PchipInterpolator, RegularGridInterpolator

from .bridges import rupture_distance

MAX_ARC = 20.0  # longest meridian followed [R]


def _meridian(l, u, suction):
    x, y, phi, volume = u
    c = np.cos(phi)
    return [c, np.sin(phi), suction + c / y, np.pi * y * y * c]


def _bridge_from_contact(neck, suction, x, y, phi, volume_of_revolution, contact_angle):
    """(gap, volume, force, filling angle) from the meridian's state where it meets the sphere."""
    beta = np.pi / 2 - phi - contact_angle
    cap_height = 1.0 - np.cos(beta)  # the sphere's cap inside the bridge's half
    cap = np.pi * cap_height**2 * (3.0 - cap_height) / 3.0
    return (2.0 * (x + np.cos(beta) - 1.0), 2.0 * (volume_of_revolution - cap),
            2 * np.pi * neck + np.pi * neck**2 * suction, beta)


def profile(neck_radius: float, suction: float, contact_angle: float):
    """One bridge with scipy's DOP853 (rtol 1e-11), the reference for :func:`meridians`:
    (gap, volume, force at the neck, filling angle, force where the meridian meets the sphere),
    or None if it does not meet a unit sphere at ``contact_angle`` [rad] before falling back
    to the axis or wetting past the sphere's equator."""
    def meets_sphere(l, u, suction):
        return u[1] - np.cos(u[2] + contact_angle)

    def falls_to_axis(l, u, suction):
        return u[1] - 1e-3 * neck_radius

    meets_sphere.terminal = falls_to_axis.terminal = True
    meets_sphere.direction = 1
    solution = solve_ivp(_meridian, (0.0, MAX_ARC), [0.0, neck_radius, 0.0, 0.0], args=(suction,),
                         events=(meets_sphere, falls_to_axis), method="DOP853", rtol=1e-11, atol=1e-13)
    if solution.t_events[0].size == 0:
        return None
    x, y, phi, volume = solution.y_events[0][0]
    gap, volume, force, beta = _bridge_from_contact(neck_radius, suction, x, y, phi, volume, contact_angle)
    if not 0.0 < beta < np.pi / 2:
        return None
    return gap, volume, force, beta, 2 * np.pi * y * np.cos(phi) + np.pi * y * y * suction


@njit(cache=True)
def _derivatives(y, phi, suction):
    c = math.cos(phi)
    return c, math.sin(phi), suction + c / y, math.pi * y * y * c


@njit(cache=True)
def _rk4(x, y, phi, v, h, suction):
    """One classical Runge–Kutta step of the meridian (Eq. 3) along arc length h."""
    a1, b1, c1, d1 = _derivatives(y, phi, suction)
    a2, b2, c2, d2 = _derivatives(y + 0.5 * h * b1, phi + 0.5 * h * c1, suction)
    a3, b3, c3, d3 = _derivatives(y + 0.5 * h * b2, phi + 0.5 * h * c2, suction)
    a4, b4, c4, d4 = _derivatives(y + h * b3, phi + h * c3, suction)
    return (x + h * (a1 + 2 * a2 + 2 * a3 + a4) / 6, y + h * (b1 + 2 * b2 + 2 * b3 + b4) / 6,
            phi + h * (c1 + 2 * c2 + 2 * c3 + c4) / 6, v + h * (d1 + 2 * d2 + 2 * d3 + d4) / 6)


@njit(cache=True)
def _contact_state(neck, suction, contact_angle, turn, max_x):
    """Integrate from the neck with steps turning the meridian by at most ``turn`` rad (and at most
    20 ``turn`` times its radius long) until it meets the sphere; the crossing is found by secant
    steps on the last step's length. Returns (x, y, phi, volume), or NaNs when the meridian
    falls to the axis or passes x = ``max_x`` first (the gap would exceed 2 max_x - 2)."""
    x, y, phi, v = 0.0, neck, 0.0, 0.0
    g = y - math.cos(phi + contact_angle)
    if g >= 0.0:  # a neck this wide meets no sphere from inside: no bridge
        return math.nan, math.nan, math.nan, math.nan
    arc = 0.0
    while arc < MAX_ARC and x < max_x:
        h = min(20.0 * turn * y, turn / max(abs(suction + math.cos(phi) / y), 1e-12))
        x1, y1, phi1, v1 = _rk4(x, y, phi, v, h, suction)
        g1 = y1 - math.cos(phi1 + contact_angle)
        if y1 < 1e-3 * neck:
            break
        if g1 >= 0.0:  # met the sphere within this step: secant on the step's fraction
            lo, glo, hi, ghi = 0.0, g, 1.0, g1
            for _ in range(60):
                t = lo - glo * (hi - lo) / (ghi - glo)
                xt, yt, pt, vt = _rk4(x, y, phi, v, t * h, suction)
                gt = yt - math.cos(pt + contact_angle)
                if abs(gt) < 1e-15:
                    break
                if gt < 0.0:
                    lo, glo = t, gt
                else:
                    hi, ghi = t, gt
            return xt, yt, pt, vt
        x, y, phi, v, g = x1, y1, phi1, v1, g1
        arc += h
    return math.nan, math.nan, math.nan, math.nan


@njit(cache=True)
def _meridians(necks, suctions, contact_angle, turn, max_x, out):
    for k in range(necks.size):
        x, y, phi, v = _contact_state(necks[k], suctions[k], contact_angle, turn, max_x)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = x, y, phi, v


def meridians(necks, suctions, contact_angle: float, turn: float = 2e-3, max_gap: float = 2 * MAX_ARC):
    """Many bridges at once (numba, RK4): arrays (gap, volume, force, filling angle), NaN where
    the meridian does not meet the sphere with 0 < beta < pi/2, or only past ``max_gap``.
    ``turn``: the largest turn of the meridian per step [rad]; 2e-3 agrees with :func:`profile`
    to ~1e-8."""
    necks, suctions = np.broadcast_arrays(np.asarray(necks, float), np.asarray(suctions, float))
    state = np.empty((necks.size, 4))
    _meridians(necks.ravel(), suctions.ravel(), float(contact_angle), float(turn), 1.0 + 0.5 * max_gap, state)
    x, y, phi, volume = (state[:, i].reshape(necks.shape) for i in range(4))
    gap, volume, force, beta = _bridge_from_contact(necks, suctions, x, y, phi, volume, contact_angle)
    bad = ~((beta > 0) & (beta < np.pi / 2))
    return tuple(np.where(bad, np.nan, a) for a in (gap, volume, force, beta))


class BridgeTable:
    """Suction and force of the stable bridge of volume V at gap s between equal spheres at one
    contact angle (units R = gamma = 1), interpolated from a grid of meridians; and the rupture
    distance, where the least volume that spans a gap equals V.

    Built from ``n_necks`` neck radii (geometric, 0.02 to 0.75 R) times ``n_suctions`` values of
    S y0 in (-1, 40], read onto ``n_gaps`` gaps in [0, ``max_gap``] (quadratically spaced) and
    ``n_volumes`` volumes in [5e-4, 0.1] R^3 (geometric); smaller bridges need necks below the
    grid's. Made for contact angles up to 5 degrees, the chapter's: at 10 degrees the grid misses
    the least volume at s = 0.3 R by half (0.0217 against 0.0145 R^3 solved neck by neck), as the
    first-contact bridges of narrow necks end steeply in the suction. Volumes outside the table,
    and gaps past Eq. 5's rupture distance, read NaN; gaps between the table's reach and Eq. 5's
    read the last bridge the table has.
    """

    def __init__(self, contact_angle: float, n_necks: int = 160, n_suctions: int = 400, n_gaps: int = 161,
                 n_volumes: int = 161, max_gap: float = 0.8):
        self.contact_angle = float(contact_angle)
        necks = np.geomspace(0.02, min(0.75, 0.99 * np.cos(contact_angle)), n_necks)
        ratio = -1.0 + np.geomspace(1e-4, 41.0, n_suctions)  # S y0; -1 is a cylinder
        suctions = ratio[None, :] / necks[:, None]
        gap, volume, force, _ = meridians(necks[:, None], suctions, contact_angle, max_gap=max_gap)
        self.gaps = max_gap * np.linspace(0.0, 1.0, n_gaps) ** 2  # small bridges part at small gaps
        self.volumes = np.geomspace(5e-4, 0.1, n_volumes)
        # each neck's bridges read at the table's gaps (the gap falls as the suction grows)
        on_gaps = np.full((3, n_necks, n_gaps), np.nan)
        for j in range(n_necks):
            ok = np.flatnonzero(np.isfinite(gap[j]) & (volume[j] > 0))[::-1]  # the gap grows as the suction falls
            ok = ok[np.r_[True, np.diff(gap[j, ok]) > 0]]
            ok = ok[np.maximum.accumulate(gap[j, ok]) == gap[j, ok]]
            if len(ok) < 4:
                continue
            g = gap[j, ok]
            inside = (self.gaps >= g[0]) & (self.gaps <= g[-1])
            log_volume = np.log(np.where(volume[j] > 0, volume[j], 1.0))  # only ok's are read
            for q, values in enumerate((log_volume, suctions[j], force[j])):
                on_gaps[q, j, inside] = PchipInterpolator(g, values[ok])(self.gaps[inside])
        on_gaps[0] = np.exp(on_gaps[0])
        # each gap's stable branch (necks wider than the least volume's) read at the table's volumes
        self.suction_table = np.full((n_volumes, n_gaps), np.nan)
        self.force_table = np.full((n_volumes, n_gaps), np.nan)
        self.neck_table = np.full((n_volumes, n_gaps), np.nan)
        self.least_volume = np.full(n_gaps, np.nan)
        for k in range(n_gaps):
            v = on_gaps[0, :, k]
            ok = np.isfinite(v)
            if ok.sum() < 3:
                continue
            first = np.flatnonzero(ok)[np.argmin(v[ok])]
            at_edge = first == np.flatnonzero(ok)[0]  # the least volume needs a narrower neck than the grid's
            branch = np.arange(first, n_necks)
            branch = branch[np.isfinite(v[branch])]
            vb = v[branch]
            if np.any(np.diff(vb) <= 0):  # the branch must be monotone to be inverted
                branch = branch[: np.argmax(np.diff(vb) <= 0) + 1]
                vb = v[branch]
            self.least_volume[k] = np.nan if at_edge else vb[0]
            inside = (self.volumes >= vb[0]) & (self.volumes <= vb[-1])
            if len(branch) < 2:
                continue
            for table, values in ((self.suction_table, on_gaps[1, :, k]), (self.force_table, on_gaps[2, :, k]),
                                  (self.neck_table, necks)):
                table[inside, k] = PchipInterpolator(np.log(vb), values[branch])(np.log(self.volumes[inside]))
        # the widest gap each volume's row reaches, so that queries up to Eq. 5's s_c (a few % past
        # the Young-Laplace rupture at theta > 0) read the last bridge that exists
        reached = np.isfinite(self.suction_table)
        last = np.where(reached.any(axis=1), reached.shape[1] - 1 - np.argmax(reached[:, ::-1], axis=1), -1)
        self.widest_gap = np.where(last >= 0, self.gaps[np.maximum(last, 0)], np.nan)
        # queries stop at the widest gap; past it the interpolators hold the row's last value, so
        # that a NaN beside a node does not spoil the node (linear weights of 0 times NaN)
        filled = np.maximum.accumulate(np.where(reached, np.arange(n_gaps), 0), axis=1)
        rows = np.arange(n_volumes)[:, None]
        axes = (np.log(self.volumes), self.gaps)
        self._suction, self._force, self._neck = (
            RegularGridInterpolator(axes, table[rows, filled], bounds_error=False)
            for table in (self.suction_table, self.force_table, self.neck_table))

    def _at(self, interpolator, volume, gap):
        volume, gap = np.broadcast_arrays(np.asarray(volume, float), np.asarray(gap, float))
        # the widest gap both neighbouring rows reach: the interpolation reads both
        upper = np.clip(np.searchsorted(self.volumes, volume), 1, len(self.volumes) - 1)
        widest = np.fmin(self.widest_gap[upper - 1], self.widest_gap[upper])
        parted = gap > rupture_distance(volume, 1.0, self.contact_angle) * (1 + 1e-9)  # Eq. 5
        gap = np.clip(gap, 0.0, widest)
        values = interpolator(np.stack([np.log(volume), gap], axis=-1)).reshape(volume.shape)
        return np.where(parted, np.nan, values)[()]

    def suction(self, volume, gap):
        """S = Delta P R / gamma (> 0: the liquid below the gas pressure). An overlap reads as s = 0,
        and a gap past the table's reach for that volume, up to Eq. 5's rupture, as the widest gap
        it reaches; volumes outside [5e-4, 0.1] R^3 and gaps past Eq. 5 give NaN."""
        return self._at(self._suction, volume, gap)

    def force(self, volume, gap):
        """F / (gamma R), attractive."""
        return self._at(self._force, volume, gap)

    def neck(self, volume, gap):
        """The neck radius y0 / R."""
        return self._at(self._neck, volume, gap)

    def rupture_distance(self, volume):
        """s_c / R: the gap whose least spanning volume is V (compare Eq. 5)."""
        ok = np.isfinite(self.least_volume)
        return np.interp(volume, self.least_volume[ok], self.gaps[ok], left=np.nan, right=np.nan)


MAX_TABLE_ANGLE = math.radians(5.0)  # BridgeTable's grid resolves rupture up to here (decisions #102)


@functools.lru_cache(maxsize=8)
def bridge_table(contact_angle: float) -> BridgeTable:
    """The :class:`BridgeTable` at this contact angle [rad], at most 5 degrees, built once per
    process (~5 s)."""
    if not 0.0 <= contact_angle <= MAX_TABLE_ANGLE * (1 + 1e-12):
        raise ValueError(f"the Young-Laplace table is made for contact angles in [0, 5] degrees, "
                         f"not {math.degrees(contact_angle):g}")
    return BridgeTable(contact_angle)
