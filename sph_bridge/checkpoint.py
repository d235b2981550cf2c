"""Checkpoints of long runs: a droplet relaxation (``droplet --checkpoint DIR``) or a calibration
(``calibrate --checkpoint DIR``). A droplet run that was killed,
stopped or ran out of its batch slot goes on from its last shape sample when the same command
is given again (with a new ``--out``), and ends where a straight run would (the particles, the
step, the random stream of the annealing kicks and the samples taken are restored exactly).

``DIR/state.npz`` is replaced atomically after every sample; the ParaView frames taken so far
sit beside it as ``particles_NNNN.vtu``, and ``progress.json`` says how far the run has got
(simulated time, steps, samples, the last shape, wall time) for a look while it runs. The run
writing a checkpoint holds a lock on it (``.lock``), and a second run on it is refused. A
checkpoint belongs to one drop and one relaxation protocol: its :func:`key` is stored and a
command with another is refused.

A calibration's checkpoint (``calibrate --checkpoint DIR``) is coarser: ``DIR/trials.json``
holds its targets and the trials finished so far, replaced after each; the same command given
again takes them as measured (:func:`sph_bridge.calibrate.calibrate`'s ``replay``) and runs on
from the trial that was cut, under the same lock.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import socket
import sys
import time
import zipfile
from dataclasses import asdict, astuple, fields
from pathlib import Path

import numpy as np

from hmdem.rundir import json_safe, replaced_atomically, write_text_atomic

from . import droplet
from .droplet import DropShape
from .output import write_particles
from .simulation import Simulation

STATE = "state.npz"
PROGRESS = "progress.json"
LOCK = ".lock"  # held (flock) by the run that writes the checkpoint
# the next step reads pos, vel, acc and dt; the summary, the shape reading and the frames the rest
ARRAYS = ("pos", "vel", "acc", "rho", "pressure", "number_density")


class CheckpointError(ValueError):
    """The directory is not a checkpoint of this run (another drop, protocol or calibration), or
    another run holds it."""


def key(sim: Simulation, t_min: float, volume: float, ridge: bool, start_height: float | None) -> str:
    """What a checkpoint must match: the drop's parameters (damping included), its volume and
    geometry (down to the particle count and the box, which the plate's size sets), its minimum
    relaxation and the relaxation protocol's constants (a code change between the pieces of a
    run would otherwise mix two protocols or two set-ups)."""
    protocol = {name: getattr(droplet, name) for name in ("SAMPLES", "SETTLE_WINDOW", "SETTLED", "MAX_EXTENSION",
                                                         "ANNEAL_FRACTION")}
    box = [sim.grid.lo.tolist(), (sim.grid.lo + sim.grid.length).tolist()]
    return json.dumps({"parameters": asdict(sim.params), "volume_m3": volume, "ridge": ridge,
                       "start_height_m": start_height, "t_min_s": t_min, "protocol": protocol,
                       "particles": len(sim.pos), "fluid_particles": int(sim.fluid.sum()), "box_m": box},
                      sort_keys=True)


def check_directory(directory: Path, out: Path, state: str = STATE) -> None:
    """Refuse a directory that is neither new nor a checkpoint whose saved state is the file
    ``state`` (its files would be overwritten), or one at or inside the run directory (which is
    written whole at the end). Frames and hidden files (the lock, a temporary state) without a
    state are a checkpoint killed before its first save."""
    directory, out = Path(directory).resolve(), Path(out).resolve()
    if directory == out or out in directory.parents:
        raise CheckpointError(f"{str(directory)!r} lies in the run directory --out; give one outside it")
    if directory.exists() and not directory.is_dir():
        raise CheckpointError(f"{str(directory)!r} is a file; give a directory (new or a checkpoint's)")
    if directory.is_dir() and not (directory / state).exists() and any(
            not (p.name.startswith(".") or p.name.startswith("particles_")) for p in directory.iterdir()):
        raise CheckpointError(f"{str(directory)!r} holds files but no {state}; give a new directory or a checkpoint's")


def hold(directory: Path):
    """Create ``directory`` if needed and lock it for this process (released when the returned
    file is closed or the process ends): two runs on one checkpoint would do the same work twice
    over and write over each other, so the second is refused. Where the file system has no locks (some
    cluster mounts) or the lock file cannot be made, the run goes on unlocked with a warning
    (returns None)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    try:
        lock = open(directory / LOCK, "a+")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.seek(0)
            holder = lock.read().strip() or "another process"
            lock.close()
            raise
    except BlockingIOError:
        raise CheckpointError(f"{str(directory)!r} is being written by a running sph_bridge run ({holder}); wait for it "
                              "or stop it") from None
    except OSError as exc:
        print(f"warning: {str(directory)!r} is not locked against a second run ({exc.strerror})", file=sys.stderr)
        return None
    lock.truncate(0)
    lock.write(f"pid {os.getpid()} on {socket.gethostname()}\n")
    lock.flush()
    return lock


def frame_path(directory: Path, index: int) -> Path:
    """Where a checkpoint keeps frame ``index`` (the run directory's name for it)."""
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
                 shapes=np.array([astuple(s) for s in shapes], float).reshape(-1, len(fields(DropShape))),
                 rows=np.array(rows, float).reshape(len(rows), -1),
                 frame_times=np.array(frame_times, float))
    last = asdict(shapes[-1]) if shapes else {}
    write_text_atomic(directory / PROGRESS, json.dumps(json_safe({
        "simulated_time_s": sim.t, "steps": sim.record.steps, "shape_samples": len(shapes),
        "frames": len(frame_times), "wall_time_s": round(time.perf_counter() - sim.wall_start, 1),
        "height_m": last.get("height"), "width_m": last.get("width"),
        "contact_angle_deg": last.get("contact_angle_deg")}), indent=2) + "\n")


def restore(directory: Path, key: str, sim: Simulation):
    """Load ``DIR/state.npz`` into ``sim`` (built afresh for the same drop) and return the shape
    samples, rows and frame times taken so far; None when the directory holds no checkpoint.
    Raises :class:`CheckpointError` for a checkpoint of another drop or protocol, or one that
    cannot be read."""
    path = Path(directory) / STATE
    if not path.exists():
        return None
    try:
        with np.load(path) as data:
            if str(data["key"]) != key:
                raise CheckpointError(f"{str(directory)!r} holds the relaxation of another drop or protocol "
                                      "(parameters, volume, geometry or code); give the command it was started "
                                      "with or a new directory")
            for name in ARRAYS:
                setattr(sim, name, data[name].copy())
            sim.t, sim.dt, elapsed = (float(v) for v in data["clock"])
            sim.record.steps, sim.record.bounced = (int(v) for v in data["counts"])
            sim.rng.bit_generator.state = json.loads(str(data["rng"]))
            shapes = [DropShape(*map(float, row)) for row in data["shapes"]]
            rows = [tuple(map(float, row)) for row in data["rows"]]
            frame_times = [float(t) for t in data["frame_times"]]
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        if isinstance(exc, CheckpointError):
            raise
        raise CheckpointError(f"{str(path)!r} cannot be read ({exc.__class__.__name__}: {exc})") from None
    # the summary's wall time counts every piece up to its last checkpoint
    sim.wall_start = time.perf_counter() - elapsed
    sim._bin()
    return shapes, rows, frame_times


TRIALS = "trials.json"  # a calibration's checkpoint: its targets and the trials run so far


def save_trials(directory: Path, targets: dict, trials: list) -> None:
    """Replace ``DIR/trials.json`` atomically with the calibration's targets and its trials
    (:class:`sph_bridge.calibrate.Trial`); floats round-trip exactly through JSON."""
    text = json.dumps(json_safe({"targets": targets, "trials": [asdict(t) for t in trials]}), indent=2)
    write_text_atomic(Path(directory) / TRIALS, text + "\n")


def restore_trials(directory: Path, targets: dict) -> list:
    """The trials a calibration with these ``targets`` (its protocol's constants included) saved
    in ``DIR`` (empty for a new directory). Raises :class:`CheckpointError` for another
    calibration's, or an unreadable, file."""
    from .calibrate import Trial

    def unsafe(v):  # json_safe's nulls back to NaN
        return math.nan if v is None else tuple(map(unsafe, v)) if isinstance(v, list) else v

    path = Path(directory) / TRIALS
    if not path.exists():
        return []
    try:
        saved = json.loads(path.read_text())
        # trials saved before ridges_unsettled was recorded: unknown (NaN), not "all settled"
        trials = [Trial(**{k: unsafe(v) for k, v in {"ridges_unsettled": None, **t}.items()})
                  for t in saved["trials"]]
        stored = saved["targets"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CheckpointError(f"{str(path)!r} cannot be read ({exc.__class__.__name__}: {exc})") from None
    if stored != json_safe(targets):
        differ = ", ".join(f"{k} {stored.get(k)!r} (now {v!r})" for k, v in json_safe(targets).items()
                           if stored.get(k) != v)
        raise CheckpointError(f"{str(directory)!r} is the checkpoint of another calibration: {differ}")
    return trials
