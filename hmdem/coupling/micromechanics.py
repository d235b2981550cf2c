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

from ..flow.fluids import FluidPair, conductance
from ..network.network import Network


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


def fluid_arrival(pipe_domains: np.ndarray, invasion_time: np.ndarray) -> np.ndarray:
    """(m, 2) invasion times of each pipe's two domains; inf for the outer face (-1) and for
    domains not invaded."""
    return np.r_[invasion_time, np.inf][pipe_domains]


def opened_ahead_of_fluid(opened_time: np.ndarray, pipe_domains: np.ndarray, invasion_time: np.ndarray) -> np.ndarray:
    """Pipes whose contact opened before either of their two domains was invaded."""
    return opened_time < fluid_arrival(pipe_domains, invasion_time).min(axis=1)


def fracture_chronology(opened_time: np.ndarray, pipe_domains: np.ndarray, invasion_time: np.ndarray) -> dict:
    """When the opened contacts opened relative to the fluid (seed 004 §4.2: in B3 "fractures
    [form] before fluid infiltration ... guiding the fluid"; in A3 and B1 they "remain within
    the fluid infiltration zone"; decisions #48).

    ``opened_time`` per pipe (inf: never opened), ``pipe_domains`` (m, 2) with -1 for the outer
    face, ``invasion_time`` per domain (inf: not invaded). A contact opened *ahead of the fluid*
    when it opened before either of its two domains was invaded; it lies *in the invaded zone*
    when both of its domains are invaded at the end."""
    opened = np.isfinite(opened_time)
    arrival = fluid_arrival(pipe_domains, invasion_time)
    return {
        "first_opening_time_s": float(opened_time[opened].min()) if opened.any() else float("nan"),
        "n_opened_ahead_of_fluid": int(np.sum(opened_ahead_of_fluid(opened_time, pipe_domains, invasion_time))),
        "n_opened_in_invaded_zone": int(np.sum(opened & np.isfinite(arrival).all(axis=1))),
    }
