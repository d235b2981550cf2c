"""Channels of a study run side by side in worker processes (``lga permeability --workers N``).

Each channel is independent: its own geometry, lattice seed and drives, so a channel gives the
same numbers in a worker as in the main process. The automaton's kernel runs one thread per
lattice below ~1e6 nodes (BENCHMARKS.md), so a study of paper-size channels uses one core per
worker. One process per channel, at most N at a time, spawned (not forked: numba's thread pools
do not survive a fork), widest channel first.

Nothing locked is shared, so a worker killed while it runs cannot hang the others: each writes
its step count to its own slot of a shared array (the progress bar sums them) and reads a
shared stop flag at every progress report. Workers ignore SIGINT and SIGTERM (a batch system
signals every process of a job); while they run, the main process's Ctrl-C or SIGTERM only
raises the flag, and every running worker sends back the drives it finished plus its partial
window, as a serial run keeps them. A worker stops too if the main process is gone. A worker
killed outright (the kernel's out-of-memory killer, say) loses its channel: the others run on,
and the run is then "failed", with the lost channels named. An error in a worker is raised
again in the main process.

A worker inherits its ignored signals through exec, so the main process ignores them while it
starts one: a signal in that window is lost. The window is the fork and exec alone (~ms): the
channel goes to the worker through its pipe afterwards, not in the process's start-up data,
whose write would wait for the new interpreter to read it.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
import traceback

from hmdem.cli import record_interrupt

POLL_SECONDS = 0.5
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _run_channel(conn, slot: int, steps_done, stop) -> None:
    """Worker: receives its job (channel, forcings, plan, density, seed), runs the channel's
    drives and sends ("ok", results, timeseries rows, interrupted) or ("error", traceback) back."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)  # the main process decides when to stop
    parent = os.getppid()

    def report(n: int) -> None:
        steps_done[slot] += n
        if stop.value or os.getppid() != parent:
            raise KeyboardInterrupt

    series = []
    try:
        channel, forcings, plan, density, seed = conn.recv()
        stopped = stop.value != 0
        if not stopped:
            try:
                channel.run(forcings, plan, density, seed, progress=report, timeseries=series)
            except KeyboardInterrupt:
                stopped = True
        message = ("ok", channel.results, series, stopped)
    except Exception:  # noqa: BLE001 - handed to the main process whole
        message = ("error", traceback.format_exc())
    conn.send(message)
    conn.close()


def lost_worker(k, exitcode: int | None) -> str:
    """What became of the worker of the job named (or numbered) ``k``, for the run's status message."""
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:  # a real-time signal has no name
            name = f"signal {-exitcode}"
        hint = " (the out-of-memory killer?)" if -exitcode == signal.SIGKILL else ""
        return f"channel {k}'s worker was killed by {name}{hint}"
    return f"channel {k}'s worker ended (exit code {exitcode}) without sending its results"


def run_in_workers(jobs, workers: int, progress, channel_done=lambda: None,
                   names=None) -> tuple[bool, list[list], list[str]]:
    """Run ``jobs`` = [(channel, forcings, plan, density, seed)] on up to ``workers`` processes
    and set each channel's ``results``; ``progress(steps)`` is called with the steps done since
    its last call and ``channel_done()`` as each channel completes. Returns whether the run was
    interrupted (Ctrl-C or SIGTERM in the main process), each job's timeseries rows in job order,
    and a line for each worker lost (its channel has no results), naming the channel by
    ``names[k]`` (default: its index)."""
    names = list(range(len(jobs))) if names is None else names
    context = multiprocessing.get_context("spawn")
    steps_done = context.RawArray("q", len(jobs))
    stop = context.RawValue("b", 0)
    series = [[] for _ in jobs]

    def cost(k):
        channel, forcings, plan = jobs[k][:3]
        return plan.steps(len(forcings)) * channel.geometry.solid.size

    waiting = sorted(range(len(jobs)), key=cost, reverse=True)
    running = {}  # job index -> (process, connection)
    reported = 0
    stopped_early = False
    lost = []

    def raise_stop(signum, frame):
        record_interrupt(signum)  # the exit status names the signal
        stop.value = 1

    previous = {sig: signal.signal(sig, raise_stop) for sig in STOP_SIGNALS}
    try:
        while waiting or running:
            while waiting and len(running) < workers and not stop.value:
                k = waiting.pop(0)
                conn, worker_end = context.Pipe()
                process = context.Process(target=_run_channel, args=(worker_end, k, steps_done, stop))
                for sig in STOP_SIGNALS:  # ignored from its first instruction (inherited through exec)
                    signal.signal(sig, signal.SIG_IGN)
                try:
                    process.start()
                finally:
                    for sig in STOP_SIGNALS:
                        signal.signal(sig, raise_stop)
                worker_end.close()
                try:
                    conn.send(jobs[k])  # waits for the new interpreter to read it, signals handled
                except OSError:  # it died before reading: the poll below finds it lost
                    pass
                except BaseException:  # the job would not pickle: the worker waits for it in vain
                    process.terminate()
                    process.join()
                    raise
                running[k] = (process, conn)
            if stop.value:
                waiting.clear()
            time.sleep(POLL_SECONDS)
            for k, (process, receive) in list(running.items()):
                alive = process.is_alive()  # before poll: a worker may send and exit in between
                if receive.poll():
                    try:
                        message = receive.recv()
                    except (EOFError, OSError):  # killed: its end of the pipe closed unwritten
                        message = ("lost",)
                elif alive:
                    continue
                else:
                    message = ("lost",)
                process.join()
                del running[k]
                if message[0] == "error":
                    raise RuntimeError(f"channel {names[k]} failed in its worker process:\n{message[1]}")
                if message[0] == "lost":
                    lost.append(lost_worker(names[k], process.exitcode))
                    continue
                _, jobs[k][0].results, series[k], stopped = message
                stopped_early |= stopped  # only when the flag was up or the main process gone
                if not stopped:
                    channel_done()
            total = sum(steps_done)
            progress(total - reported)
            reported = total
        interrupted = stopped_early or stop.value != 0
    finally:
        stop.value = 1  # on an error, the other workers stop at their next report
        for process, _ in running.values():
            process.join(timeout=10)
            if process.is_alive():
                process.terminate()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return interrupted, series, lost
