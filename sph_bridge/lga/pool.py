"""Channels of a study run side by side in worker processes (``lga permeability --workers N``).

Each channel is independent: its own geometry, lattice seed and drives, so a channel gives the
same numbers in a worker as in the main process. The automaton's kernel runs one thread per
lattice below ~1e6 nodes (BENCHMARKS.md), so a study of paper-size channels uses one core per
worker. One process per channel, at most N at a time, spawned (not forked: numba's thread pools
do not survive a fork). Nothing locked is shared, so a worker killed while it runs cannot hang
the others: each writes its step count to its own slot of a shared array (the progress bar sums
them) and reads a shared stop flag at every progress report. Workers ignore SIGINT; on Ctrl-C
(or SIGTERM to the main process) the main process raises the flag and every running worker
sends back the drives it finished plus its partial window, as a serial run keeps them. A worker
killed outright loses its channel; the others are kept and the run is "interrupted".
"""

from __future__ import annotations

import multiprocessing
import signal
import time

POLL_SECONDS = 0.5


def _run_channel(conn, slot: int, steps_done, stop, channel, forcings, plan, density: float, seed: int) -> None:
    """Worker: one channel's drives; sends (results, timeseries rows, interrupted) back."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the main process decides when to stop

    def report(n: int) -> None:
        steps_done[slot] += n
        if stop.value:
            raise KeyboardInterrupt

    series = []
    stopped = stop.value != 0
    if not stopped:
        try:
            channel.run(forcings, plan, density, seed, progress=report, timeseries=series)
        except KeyboardInterrupt:
            stopped = True
    conn.send((channel.results, series, stopped))
    conn.close()


def run_in_workers(jobs, workers: int, progress) -> tuple[bool, list[list]]:
    """Run ``jobs`` = [(channel, forcings, plan, density, seed)] on up to ``workers`` processes
    and set each channel's ``results``; ``progress(steps)`` is called with the steps done since
    its last call. Returns whether the run was interrupted (Ctrl-C or SIGTERM in the main process,
    or a worker lost) and each job's timeseries rows, in job order."""
    context = multiprocessing.get_context("spawn")
    steps_done = context.RawArray("q", len(jobs))
    stop = context.RawValue("b", 0)
    series = [[] for _ in jobs]
    # longest first, so the widest channel does not start last (cost ~ planned steps x nodes)
    def cost(k):
        channel, forcings, plan = jobs[k][:3]
        return plan.steps(len(forcings)) * channel.geometry.solid.size

    waiting = sorted(range(len(jobs)), key=cost, reverse=True)
    running = {}  # job index -> (process, connection)
    reported = 0
    interrupted = False
    while waiting or running:
        try:
            while waiting and len(running) < workers and not stop.value:
                k = waiting.pop(0)
                receive, send = context.Pipe(duplex=False)
                process = context.Process(target=_run_channel, args=(send, k, steps_done, stop, *jobs[k]))
                process.start()
                send.close()
                running[k] = (process, receive)
            if stop.value:
                waiting.clear()
            time.sleep(POLL_SECONDS)
            for k, (process, receive) in list(running.items()):
                if not receive.poll():
                    if process.is_alive():
                        continue
                    interrupted = True  # died without a word
                else:
                    try:
                        results, series[k], stopped = receive.recv()
                        jobs[k][0].results = results
                        interrupted |= stopped
                    except EOFError:  # killed: its end of the pipe closed unwritten
                        interrupted = True
                process.join()
                del running[k]
            total = sum(steps_done)
            progress(total - reported)
            reported = total
        except KeyboardInterrupt:
            interrupted = True
            stop.value = 1  # running workers return what they have at their next report
    return interrupted, series
