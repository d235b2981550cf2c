"""ParaView time series of a run (``--snapshots N``).

The domains are kept at the moments the front has covered 1/N, 2/N, ... of its way to the
outflow (single-phase runs: of t_max), and the run's final state closes the series. With moving
grains each snapshot keeps the grain centres, so the polygons deform in ParaView, and the pipes
between grain pairs are written as lines carrying their aperture and whether the contact has
opened (the fractures, seed 004 Eq. 14). The run directory gets ``domains.pvd`` (and
``contacts.pvd``) indexing ``snapshots/*.vtu`` by simulated time: open the .pvd in ParaView.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np


@dataclass(frozen=True)
class Snapshot:
    """The fields a snapshot writes; ``points`` and the pipe fields only where grains move."""

    t: float
    pressure: np.ndarray
    saturation: np.ndarray
    invasion_time: np.ndarray
    points: np.ndarray | None = None  # grain centres (n, 2)
    pipe_aperture: np.ndarray | None = None  # per pipe [m]
    pipe_opened: np.ndarray | None = None  # per pipe: the contact has opened (bool)


class SnapshotRecorder:
    """Progress callback (``model.run(progress=...)``) keeping ``count`` snapshots as the run
    advances: one each time the front's progress (or t / t_max) passes the next multiple of
    1 / count. A step that passes several multiples at once is kept once."""

    def __init__(self, count: int):
        if count < 1:
            raise ValueError(f"snapshot count must be >= 1, got {count}")
        self.count = count
        self.taken: list[Snapshot] = []
        self._next = 1  # the multiple of 1 / count the next snapshot waits for

    def __call__(self, model, state) -> None:
        reached = math.floor(model.fraction_done(state) * self.count + 1e-9)  # multiples of 1 / count passed
        if reached >= self._next:
            self.taken.append(take(model, state))
            self._next = reached + 1


def take(model, state) -> Snapshot:
    """A snapshot of the flow state (copies); a model with moving grains adds its
    ``grain_snapshot()`` fields (grain centres, pipe apertures, opened contacts)."""
    grains = model.grain_snapshot() if hasattr(model, "grain_snapshot") else {}
    return Snapshot(state.t, state.pressure.copy(), state.saturation.copy(), state.invasion_time.copy(), **grains)


def grain_radii(radii) -> dict:
    """Point data giving each grain centre its ``radius`` [m], so that ParaView can draw the discs
    (a Glyph filter: sphere, scaled by radius); none where the network has no grains."""
    return {} if radii is None else {"radius": np.asarray(radii, float)}


def domain_mesh(net, points: np.ndarray, pressure, saturation, invasion_time, radii=None):
    """meshio mesh of the domain polygons (as their triangles) with pressure, saturation and
    invasion time (-1 where not invaded) per cell, on the grain centres ``points``."""
    import meshio

    from .network.network import OUTSIDE

    inside = net.triangle_domain != OUTSIDE
    domain = net.triangle_domain[inside]
    t_inv = np.where(np.isfinite(invasion_time), invasion_time, -1.0)
    return meshio.Mesh(np.c_[points, np.zeros(len(points))], [("triangle", net.triangles[inside])],
                       cell_data={"pressure": [pressure[domain]], "saturation": [saturation[domain]],
                                  "invasion_time": [t_inv[domain]], "domain": [domain]},
                       point_data=grain_radii(radii))


def pipe_mesh(net, points: np.ndarray, aperture: np.ndarray, opened: np.ndarray, radii=None):
    """meshio mesh of the pipes as lines between their two grains, with aperture and opened."""
    import meshio

    return meshio.Mesh(np.c_[points, np.zeros(len(points))], [("line", net.pipe_grains)],
                       cell_data={"aperture": [aperture], "opened": [opened.astype(np.int8)]},
                       point_data=grain_radii(radii))


def write_collection(path: Path, entries: list[tuple[float, str]]) -> None:
    """ParaView collection (.pvd): data files by time, paths relative to the .pvd."""
    lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "  <Collection>"]
    lines += [f"    <DataSet timestep={quoteattr(repr(float(t)))} part=\"0\" file={quoteattr(name)}/>"
              for t, name in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    path.write_text("\n".join(lines))


def write_series(directory: Path, net, snapshots: list[Snapshot], radii=None) -> None:
    """``snapshots/domains_NNNN.vtu`` (and ``contacts_NNNN.vtu``) with their .pvd collections;
    ``radii``: the grains' (m), written with their centres."""
    folder = directory / "snapshots"
    folder.mkdir()
    domains, contacts = [], []
    for k, snap in enumerate(snapshots):
        points = net.points if snap.points is None else snap.points
        name = f"snapshots/domains_{k:04d}.vtu"
        domain_mesh(net, points, snap.pressure, snap.saturation, snap.invasion_time, radii).write(directory / name)
        domains.append((snap.t, name))
        if snap.pipe_aperture is not None:
            name = f"snapshots/contacts_{k:04d}.vtu"
            pipe_mesh(net, points, snap.pipe_aperture, snap.pipe_opened, radii).write(directory / name)
            contacts.append((snap.t, name))
    write_collection(directory / "domains.pvd", domains)
    if contacts:
        write_collection(directory / "contacts.pvd", contacts)


def read_collection(path: Path) -> list[tuple[float, Path]]:
    """(time, data file) of each entry of a .pvd collection written by :func:`write_collection`."""
    entries = re.findall(r'timestep="([^"]+)" part="0" file="([^"]+)"', path.read_text())
    return [(float(t), path.parent / name) for t, name in entries]


def read_series(run: Path, n_domains: int):
    """The snapshots of a run directory, oldest first: (t, saturation per domain, and with moving
    grains the pipes' apertures and opened contacts, else None and None)."""
    import meshio

    if not (run / "domains.pvd").is_file():
        raise FileNotFoundError(f"{run}: no domains.pvd (run with --snapshots N)")
    domains = read_collection(run / "domains.pvd")
    contacts = read_collection(run / "contacts.pvd") if (run / "contacts.pvd").is_file() else [(None, None)] * len(domains)
    if len(contacts) != len(domains):
        raise ValueError(f"{run}: contacts.pvd has {len(contacts)} frames, domains.pvd {len(domains)}")
    for (t, name), (_, pipes_name) in zip(domains, contacts):
        cells = meshio.read(name).cell_data
        saturation = np.zeros(n_domains)
        saturation[cells["domain"][0]] = cells["saturation"][0]
        aperture = opened = None
        if pipes_name is not None:
            pipes = meshio.read(pipes_name).cell_data
            aperture, opened = pipes["aperture"][0], pipes["opened"][0].astype(bool)
        yield t, saturation, aperture, opened
