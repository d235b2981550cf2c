"""Running the open points of a sweep on Dask: an embedded LocalCluster sized to the machine,
or an existing scheduler (``tcp://host:8786``) whose workers need only ``pip install hmdem``.

Each point is one task (:func:`.packed.run_packed`); the client unpacks each finished run
directory into the sweep directory and updates the manifest, so a killed sweep loses only the
runs in flight. A task whose worker dies is resubmitted by the Dask scheduler (up to its
``allowed-failures``), then recorded as failed with the error text, like a run that raised.
"""

from __future__ import annotations

import sys
import time
import traceback
from pathlib import Path

from ..cli import available_cores
from .manifest import DONE, FAILED, Manifest
from .packed import run_packed, unpack_directory


def error_text(exc: BaseException) -> str:
    """One line naming the exception, plus the innermost frame when there is a traceback."""
    text = f"{type(exc).__name__}: {exc}".strip()
    frames = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else []
    if frames:
        last = frames[-1]
        text += f" (at {Path(last.filename).name}:{last.lineno} in {last.name})"
    return text


class SweepProgress:
    """tqdm bar over all runs of the sweep: done / failed / this invocation's still to run, with tqdm's ETA."""

    def __init__(self, manifest: Manifest, enabled: bool = True):
        self.manifest = manifest
        self.to_run = len(manifest.todo())  # this invocation's runs (failed ones again) not yet back
        self.bar = None
        if enabled:
            from tqdm import tqdm

            counts = manifest.counts()
            self.bar = tqdm(total=len(manifest.runs), initial=counts[DONE], unit="run", desc="sweep",
                            file=sys.stderr, smoothing=0.1)
            self.update()

    def update(self, returned: str | None = None) -> None:
        """Refresh the counts; ``returned``: the id of a run that came back, done or failed (the
        bar advances for a done one)."""
        if self.bar is None:
            return
        step = 0
        if returned is not None:
            self.to_run -= 1
            step = int(self.manifest.runs[returned]["status"] == DONE)
        c = self.manifest.counts()
        # a failed run is retried when the command is run again: once back, it is not "to run"
        self.bar.set_postfix_str(f"done={c[DONE]}, failed={c[FAILED]}, to run={self.to_run}", refresh=False)
        self.bar.update(step)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


# Worker settings of the embedded cluster. Dask's nanny exports MALLOC_TRIM_THRESHOLD_=65536 to
# its workers, which switches off glibc's dynamic mmap threshold: every large numpy temporary is
# then mapped and unmapped afresh, and the runs took ~25 % longer than in a plain process (4
# points: 48-51 s against 38-39 s). Its statistical profiler samples the running task every
# 10 ms (~4 %). The single-thread BLAS settings are Dask's own defaults, kept.
LOCAL_WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ": {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
    "distributed.worker.profile.enabled": False,
}


def start_client(workers: int | None, scheduler: str | None):
    """(client, cluster): a client of ``scheduler`` or of a fresh LocalCluster (cluster None then)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler, timeout="30s"), None
    with dask.config.set(LOCAL_WORKER_CONFIG):
        cluster = LocalCluster(n_workers=workers or available_cores(), threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=50,  # errors: in the manifest
                               # Ctrl-C is the client's alone; the user's own preloads are kept
                               preload=[*dask.config.get("distributed.worker.preload", []),
                                        "hmdem.sweep.worker_setup"])
    return Client(cluster), cluster


def run_sweep(manifest: Manifest, packing: Path | None = None, workers: int | None = None,
              scheduler: str | None = None, progress: bool = True, runner=run_packed) -> dict:
    """Run every pending or failed point of ``manifest``; returns the final counts.

    ``runner(point, packing_bytes, packing_name, shown_as) -> (summary, packed run directory)`` is the
    task (tests substitute one that crashes its worker)."""
    todo = manifest.todo()
    if not todo:
        SweepProgress(manifest, progress).close()
        return manifest.counts()
    from distributed import as_completed

    packing_bytes = Path(packing).read_bytes() if packing else None
    packing_name = str(Path(packing).resolve()) if packing else None  # recorded: valid from anywhere
    client, cluster = start_client(workers, scheduler)
    # after the client: a scheduler that cannot be reached is one line, with no bar after it
    bar = SweepProgress(manifest, progress)
    try:
        futures = {}
        for point in todo:
            key = f"hmdem-{point.run_id}-{manifest.runs[point.run_id]['attempts']}-{time.time_ns()}"
            shown_as = str(manifest.run_dir(point.run_id))  # where the client keeps it: its warnings name this
            futures[client.submit(runner, point, packing_bytes, packing_name, shown_as, key=key, pure=False)] = point
        for future in as_completed(futures):
            point = futures[future]
            try:
                summary, packed = future.result()
                unpack_directory(packed, manifest.run_dir(point.run_id))
                manifest.finished(point.run_id, None)
            except Exception as exc:  # the run raised, or its worker died too often
                manifest.finished(point.run_id, error_text(exc))
            bar.update(point.run_id)
    finally:
        bar.close()
        client.close()
        if cluster is not None:
            cluster.close()
    return manifest.counts()
