"""Preloaded into each worker of the embedded Dask cluster (``LocalCluster(preload=...)``).

Ctrl-C in a terminal sends SIGINT to the whole process group, the cluster's worker processes
included. The sweep's own process handles it (a valid manifest, the table of what finished,
exit 130) and then shuts the workers down; a worker that took the signal itself printed
asyncio's KeyboardInterrupt traceback. Workers therefore ignore SIGINT; SIGTERM still ends them.
"""

import signal


def dask_setup(worker) -> None:
    """Called by Dask in the worker process's main thread when the worker starts."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
