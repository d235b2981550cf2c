"""Holding Ctrl-C (SIGINT) and SIGTERM while something must finish whole: an accepted time step
(:class:`hmdem.flow.simulation.FlowModel`) or the writing of a run directory
(:func:`hmdem.rundir.atomic_run_directory`)."""

from __future__ import annotations

import contextlib
import signal
import threading


@contextlib.contextmanager
def deferred_interrupts():
    """Hold Ctrl-C (SIGINT) and SIGTERM until the block ends, then deliver them to the handlers
    that were there, so that an accepted step updates the state, the records and the grains
    together, and a run directory is written whole: an interrupt that landed half-way left a
    run directory whose state was a step ahead of its last time-series row (found in review),
    and one during the writing lost a finished run (a new-user pass). A model whose steps move
    something it cannot take back (``FlowModel.whole_steps``) holds them through the whole step.
    Blocks may nest: the inner one's held signals go to the outer one's hold. Held signals are
    delivered also when the block raised (a caller may catch that and go on; FlowModel.run reads
    a failure beneath the interrupt; dispatch names it). Outside the main thread, where handlers
    cannot be set, the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held, previous = [], {}
    stop_signals = {signal.SIGINT, signal.SIGTERM}
    try:  # a handler is recorded before it is replaced, so that finally puts back every one replaced
        for sig in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(sig)
            if handler is not None:  # None: set from C, left alone
                previous[sig] = handler
                signal.signal(sig, lambda signum, frame: held.append(signum))
        yield
    finally:
        # blocked while the handlers go back, so that none lands between two of them
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, stop_signals)
        try:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        for signum in held:  # also when the block raised: the interrupt still ends the run
            signal.raise_signal(signum)
