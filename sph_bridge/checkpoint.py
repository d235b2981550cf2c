"""Checkpoints of a droplet relaxation (``droplet --checkpoint DIR``): a run that was killed,
stopped or ran out of its batch slot goes on from its last shape sample when the same command
is given again, and ends where a straight run would (the particles, the step, the random
stream of the annealing kicks and the samples taken are restored exactly).

``DIR/state.npz`` is replaced atomically after every sample; the ParaView frames taken so far
sit beside it as ``particles_NNNN.vtu``. A checkpoint belongs to one drop: its parameters and
geometry are stored as ``key`` and a command with others is refused.
"""

from __future__ import annotations

import json
import time
from dataclasses import astuple
from pathlib import Path

import numpy as np

from hmdem.rundir import replaced_atomically

from .droplet import DropShape
from .output import write_particles
from .simulation import Simulation

STATE = "state.npz"
ARRAYS = ("pos", "vel", "acc", "rho", "pressure", "number_density")  # what the next step reads


class CheckpointMismatch(ValueError):
    """The checkpoint directory holds a relaxation of another drop or another size."""


def frame_path(directory: Path, index: int) -> Path:
    return Path(directory) / f"particles_{index:04d}.vtu"


def save_frame(directory: Path, index: int, state: tuple) -> Path:
    """Write frame ``index`` (a :func:`~sph_bridge.output.particle_state`) beside the state, whole or not at all."""
    path = frame_path(directory, index)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(path) as tmp:
        write_particles(tmp, state)
    return path


def save(directory: Path, key: str, sim: Simulation, shapes: list[DropShape], rows: list[tuple],
         frame_times: list[float]) -> None:
    """Write ``state.npz`` through a temporary file and a rename: a kill leaves the previous
    checkpoint or this one, never a part."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(directory / STATE) as tmp:
        np.savez(tmp, key=key, **{name: getattr(sim, name) for name in ARRAYS},
                 clock=np.array([sim.t, sim.dt, time.perf_counter() - sim.wall_start]),
                 counts=np.array([sim.record.steps, sim.record.bounced]),
                 rng=json.dumps(sim.rng.bit_generator.state),
                 shapes=np.array([astuple(s) for s in shapes], float).reshape(-1, len(DropShape.__dataclass_fields__)),
                 rows=np.array(rows, float).reshape(len(rows), -1),
                 frame_times=np.array(frame_times, float))


def restore(directory: Path, key: str, sim: Simulation):
    """Load ``DIR/state.npz`` into ``sim`` (built afresh for the same drop) and return the shape
    samples, rows and frame times taken so far; None when the directory holds no checkpoint.
    Raises :class:`CheckpointMismatch` for a checkpoint of another drop."""
    path = Path(directory) / STATE
    if not path.exists():
        return None
    with np.load(path) as data:
        if str(data["key"]) != key:
            raise CheckpointMismatch(f"{str(directory)!r} holds the relaxation of another drop (parameters, "
                                     "volume or geometry); give the command it was started with or a new directory")
        if len(data["pos"]) != len(sim.pos):
            raise CheckpointMismatch(f"{str(directory)!r} holds {len(data['pos'])} particles, this drop "
                                     f"{len(sim.pos)}")
        for name in ARRAYS:
            setattr(sim, name, data[name].copy())
        sim.t, sim.dt, elapsed = (float(v) for v in data["clock"])
        sim.record.steps, sim.record.bounced = (int(v) for v in data["counts"])
        sim.rng.bit_generator.state = json.loads(str(data["rng"]))
        shapes = [DropShape(*map(float, row)) for row in data["shapes"]]
        rows = [tuple(map(float, row)) for row in data["rows"]]
        frame_times = [float(t) for t in data["frame_times"]]
    sim.wall_start = time.perf_counter() - elapsed  # the summary's wall time counts every piece
    sim._bin()
    return shapes, rows, frame_times
