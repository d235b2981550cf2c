"""Micro-mechanical diagnostics of a coupled run (seed 004 §4.2, Figs. 15-16; digest §12, H7-H8).

Pipe flow resistance R_s = dp / q = 12 eta l / a^3 (the inverse of the Eq. 1 conductance,
Pa s / m^2 per m of depth, reported by the paper in GPa s / m^2), and the lowest total
resistance of a path of pipes from the inflow domain to any outflow domain: the paper finds
that the front follows the lowest path sum, not the lowest single pipe.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from ..flow.diagnostics import image_box_dimension, pattern_scales, rasterize_segments
from ..flow.fluids import FluidPair, conductance
from ..network.network import OUTSIDE, Network, pipes_touching


def pipe_resistance(net: Network, fluids: FluidPair, saturation: np.ndarray, pipes: np.ndarray) -> np.ndarray:
    """R_s of the given (flowing) pipes with the Eq. 4 mixture viscosity of their two domains."""
    a, b = net.pipe_domains[pipes, 0], net.pipe_domains[pipes, 1]
    eta = fluids.pipe_viscosity(saturation[a], saturation[b])
    return 1.0 / conductance(net.pipe_aperture[pipes], eta, net.pipe_length[pipes])


def lowest_path_resistance(net: Network, pipes: np.ndarray, resistance: np.ndarray,
                           sources: np.ndarray, targets: np.ndarray) -> float:
    """Smallest sum of R_s over pipe paths from any source domain to any target domain."""
    n = net.n_domains
    rows = np.r_[net.pipe_domains[pipes, 0], net.pipe_domains[pipes, 1]]
    cols = np.r_[net.pipe_domains[pipes, 1], net.pipe_domains[pipes, 0]]
    weight = np.r_[resistance, resistance]
    # two pipes can join the same pair of domains: keep the smaller resistance (a sparse matrix
    # would add them)
    keys, first = np.unique(rows.astype(np.int64) * n + cols, return_inverse=True)
    smallest = np.full(len(keys), np.inf)
    np.minimum.at(smallest, first, weight)
    graph = coo_matrix((smallest, (keys // n, keys % n)), shape=(n, n)).tocsr()
    dist = dijkstra(graph, indices=np.asarray(sources), min_only=True)
    return float(np.min(dist[np.asarray(targets)]))


def crack_segments(positions: np.ndarray, radii: np.ndarray, pipe_grains: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each grain pair of ``pipe_grains`` (n, 2) drawn as a crack, as DEM fracture maps commonly
    draw a broken bond: a segment across the contact, perpendicular to the line of centres,
    centred midway across the gap (or the overlap), as long as the two grains' mean diameter,
    r1 + r2 (our choice where the seed draws none: decisions #97). Returns (starts, ends), (n, 2)
    each."""
    a, b = np.asarray(pipe_grains).reshape(-1, 2).T
    axis = positions[b] - positions[a]
    distance = np.linalg.norm(axis, axis=1)
    # coincident grains have no direction: nan, which rasterize_segments leaves out
    unit = np.divide(axis, distance[:, None], out=np.full_like(axis, np.nan), where=distance[:, None] > 0)
    middle = positions[a] + unit * (radii[a] + 0.5 * (distance - radii[a] - radii[b]))[:, None]
    across = np.stack([-unit[:, 1], unit[:, 0]], axis=1) * (0.5 * (radii[a] + radii[b]))[:, None]
    return middle - across, middle + across


def fracture_zone_dimension(net: Network, positions: np.ndarray, radii: np.ndarray, opened: np.ndarray) -> float:
    """D_f of the fracture zone (seed 004 App. E, Fig. 25b; digest H5): App. E's box counting, from
    the grain scale to a quarter of the sample (:func:`~hmdem.flow.diagnostics.pattern_scales`), on the
    ``opened`` pipes' contacts drawn as cracks (:func:`crack_segments`); nan with none opened.
    Box counting, not #27's mass-radius reading of the invaded zone: a crack set has no mass
    at its centre once the port's grains are pushed out (decisions #97)."""
    if not np.any(opened):
        return float("nan")
    image, h = rasterize_segments(*crack_segments(positions, radii, net.pipe_grains[opened]), net.extent)
    return image_box_dimension(image, h, *pattern_scales(net))[0]


def fracture_and_side_resistance(pipe_domains: np.ndarray, length: np.ndarray, aperture: np.ndarray,
                                 opened: np.ndarray, closed_at_start: np.ndarray, saturation: np.ndarray,
                                 inlet: np.ndarray, viscosity: float) -> tuple[int, float, float]:
    """Seed 004 §4.2 on B3 (Fig. 16e; digest H8): "the lowest pipe flow resistance inside the
    fracturing zone is only 2.5 GPa s/m2, merely 2 % of the lowest resistance at the sides".
    Returns how many fractures the fluid has reached (opened contacts with invading fluid in
    one of their domains), the lowest R_s (Eq. 27) among them and the lowest among their sides
    (the contacts of the same domains that have stayed closed and that the fluid has reached);
    the injection domains' own pipes are in neither set, the port is not the fracturing zone;
    R_s at one ``viscosity`` so that the two compare apertures and lengths, the compaction the
    paper names as the cause (decisions #67). Per pipe: ``pipe_domains`` (m, 2) with OUTSIDE
    for the outer face, ``length``, ``aperture``, ``opened``, ``closed_at_start``; per domain:
    ``saturation``. nan where a set is empty."""
    inner = (pipe_domains != OUTSIDE).all(axis=1)
    a, b = np.where(inner[:, None], pipe_domains, 0).T
    wetted = inner & ((saturation[a] > 0.0) | (saturation[b] > 0.0))
    at_port = pipes_touching(pipe_domains, inlet)
    fracture = wetted & opened & ~at_port
    in_fracture = np.zeros(len(saturation), bool)
    in_fracture[np.r_[a[fracture], b[fracture]]] = True
    side = wetted & ~at_port & closed_at_start & ~opened & (in_fracture[a] | in_fracture[b])
    resistance = 1.0 / conductance(aperture, np.full(len(aperture), viscosity), length)
    return (int(fracture.sum()), float(resistance[fracture].min()) if fracture.any() else float("nan"),
            float(resistance[side].min()) if side.any() else float("nan"))


def pipe_pore_times(pipe_domains: np.ndarray, domain_time: np.ndarray) -> np.ndarray:
    """(m, 2) a per-domain time (fluid entry, filling) read at each pipe's two domains; inf for
    the outer face."""
    at_pores = domain_time[np.where(pipe_domains == OUTSIDE, 0, pipe_domains)]
    return np.where(pipe_domains == OUTSIDE, np.inf, at_pores)


def fracture_timing(opened: np.ndarray, opened_time: np.ndarray, pipe_domains: np.ndarray,
                    wetted_time: np.ndarray, invasion_time: np.ndarray) -> dict:
    """Masks over the pipes (decisions #48): ``reached``, opened contacts into one of whose two
    domains invading fluid had entered by the end (``wetted_time``, inf: never); ``before_fluid``,
    those of them that opened before fluid entered either domain (a contact opening in the step
    the fluid enters is not); ``in_invaded_zone``, opened contacts whose two domains were both
    filled by the end (``invasion_time``, S = 1)."""
    first_entry = pipe_pore_times(pipe_domains, wetted_time).min(axis=1)
    reached = opened & np.isfinite(first_entry)
    filled = np.isfinite(pipe_pore_times(pipe_domains, invasion_time)).all(axis=1)
    return {"reached": reached, "before_fluid": reached & (opened_time < first_entry),
            "in_invaded_zone": opened & filled}


def fracture_chronology(opened: np.ndarray, opened_time: np.ndarray, pipe_domains: np.ndarray,
                        wetted_time: np.ndarray, invasion_time: np.ndarray) -> dict:
    """Summary keys on when the opened contacts opened relative to the fluid (seed 004 §4.2: B3's
    pressure "creates fractures before fluid infiltration, guiding the fluid to penetrate the
    fracturing domains at later stages"; A3's and B1's fractures "remain within the fluid
    infiltration zone"). ``opened`` and ``opened_time`` per pipe (the end of the accepted step
    at which the contact first counted as opened), ``pipe_domains`` (m, 2) with OUTSIDE for the
    outer face, ``wetted_time`` and ``invasion_time`` per domain: see :func:`fracture_timing`."""
    return chronology_counts(fracture_timing(opened, opened_time, pipe_domains, wetted_time, invasion_time),
                             opened, opened_time)


def chronology_counts(masks: dict, opened: np.ndarray, opened_time: np.ndarray) -> dict:
    """The summary keys of :func:`fracture_chronology` from the masks of :func:`fracture_timing`."""
    times = opened_time[opened]
    return {
        "first_opening_time_s": float(np.nanmin(times)) if np.isfinite(times).any() else float("nan"),
        "n_opened_reached_by_fluid": int(masks["reached"].sum()),
        "n_opened_before_fluid": int(masks["before_fluid"].sum()),
        "n_opened_in_invaded_zone": int(masks["in_invaded_zone"].sum()),
    }


def filling_order(invasion_time: np.ndarray, inlet: np.ndarray,
                  pipe_domains: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each domain's filling time (``invasion_time``, inf: never filled) with the port's set to
    -1, so that it counts as filled first, plus one entry, never filled, at which the returned
    copy of ``pipe_domains`` points its ends on the outer face (OUTSIDE)."""
    t = np.append(invasion_time, np.inf)
    t[inlet] = -1.0
    return t, np.where(pipe_domains == OUTSIDE, len(invasion_time), pipe_domains)


def fracture_guidance(opened_time: np.ndarray, pipe_domains: np.ndarray, wetted_time: np.ndarray,
                      invasion_time: np.ndarray, inlet: np.ndarray) -> dict:
    """Summary keys on whether the fluid went in through the opened contacts (seed 004 §4.2: B3's
    pressure "creates fractures before fluid infiltration, guiding the fluid to penetrate the
    fracturing domains"; decisions #87). A filled domain's feeding pipes join it to neighbours
    filled earlier, the port counting as filled first:
    ``fracture_fed_fraction``, of the filled domains (the port left out), those fed through a
    contact that opened before the fluid first entered the domain, from a neighbour already
    filled then;
    ``feeding_pipes_opened_fraction``, of the feeding pipes, those whose contact had opened by
    the time their domain filled;
    ``front_pipes_opened_fraction``, the control: at each time a domain filled, the other pipes
    then on the front (one domain filled before, the other not yet), those opened by then,
    pooled over those times. They are what the fluid could have gone in through instead.
    Pipes on the outer face carry no flow and count in neither set.
    Per pipe ``opened_time`` (inf: never opened) and ``pipe_domains`` (m, 2) with OUTSIDE for
    the outer face; per domain ``wetted_time`` (fluid first entered) and ``invasion_time``
    (filled, S = 1); ``inlet`` the port's domains. nan where a set is empty."""
    t, ends = filling_order(invasion_time, inlet, pipe_domains)
    a, b = ends.T
    first, second = np.minimum(t[a], t[b]), np.maximum(t[a], t[b])
    # feeding pipes: one domain filled after the other (none on the outer face: its end never fills)
    pipe = np.flatnonzero(np.isfinite(second) & (first < second))
    later = t[a[pipe]] > t[b[pipe]]
    fed, feeder = np.where(later, a[pipe], b[pipe]), np.where(later, b[pipe], a[pipe])
    filled = np.flatnonzero(np.isfinite(t[:-1]) & (t[:-1] >= 0.0))
    came_through = (opened_time[pipe] < wetted_time[fed]) & (t[feeder] < wetted_time[fed])
    guided = np.isin(filled, fed[came_through])
    # the control, time-matched: a pipe is on the front between its two domains' filling times
    # (open interval); count the filling times inside it, and those at or after its opening
    events = np.unique(t[fed])
    front = (pipe_domains != OUTSIDE).all(axis=1) & np.isfinite(first) & (first < second)
    start = np.searchsorted(events, first[front], "right")
    end = np.searchsorted(events, second[front], "left")
    since_opened = np.maximum(start, np.searchsorted(events, opened_time[front], "left"))
    on_front, opened_on_front = np.maximum(end - start, 0).sum(), np.maximum(end - since_opened, 0).sum()

    def fraction(count, total) -> float:
        return float(count / total) if total else float("nan")

    return {"fracture_fed_fraction": fraction(guided.sum(), guided.size),
            "feeding_pipes_opened_fraction": fraction(np.sum(opened_time[pipe] <= t[fed]), pipe.size),
            "front_pipes_opened_fraction": fraction(opened_on_front, on_front)}


STEP_ENERGY_KEYS = ("time_s", "step_s", "injection_pressure_pa", "injection_energy_j", "residual_energy_j",
                    "dissipated_fraction")


def energy_partition(times: np.ndarray, steps: np.ndarray, injection_pressure: np.ndarray, injected: np.ndarray,
                     dissipated: np.ndarray, onset_time: float) -> dict:
    """Summary keys for the per-step energy partition of seed 004 Figs. 15-16 (Eqs. 25-26;
    digest H7): the injection energy dE_in = p_in Q dt of one step, the residual energy
    dE_f = dE_in - dE_v left for compressing the fluid and moving the grains, and the
    dissipated fraction dE_v / dE_in, at two steps the paper reads (decisions #69):
    ``first_step_*``, the first step, with the port still holding air (A3: 5.1 kPa, 2.5 uJ,
    28 % dissipated); ``fracture_onset_*``, the step at whose end the first contact counted as
    opened (``onset_time``; A3: 393.4 kPa, 194.5 uJ, 86 %, dE_f 27.4 uJ; B3: 4076.1 kPa,
    dE_f 134.7 uJ). The paper's are full 8e-7 s steps; ``*_step_s`` says how long ours was.
    Per recorded step: ``times`` (its end), ``steps`` (its length), ``injection_pressure``,
    ``injected`` and ``dissipated`` [J per m of depth]. nan (null in summary.json) where there
    is no such step."""
    t, nan = np.asarray(times, float), float("nan")
    later = np.flatnonzero(t >= onset_time) if np.isfinite(onset_time) else []
    keys = {}
    for name, k in (("first_step", 0 if len(t) else None), ("fracture_onset", later[0] if len(later) else None)):
        values = (nan,) * len(STEP_ENERGY_KEYS)
        if k is not None:
            e_in, e_v = float(injected[k]), float(dissipated[k])
            values = (float(t[k]), float(steps[k]), float(injection_pressure[k]), e_in, e_in - e_v,
                      e_v / e_in if e_in > 0 else nan)
        keys |= {f"{name}_{key}": value for key, value in zip(STEP_ENERGY_KEYS, values)}
    return keys
