"""Find and import YADE as a Python module.

Debian 12's ``python3-yade`` installs its modules in ``/usr/lib/x86_64-linux-gnu/yade-double/py``
but the ``/usr/lib/python3/dist-packages/yade`` symlink points to a folder that does not exist.
:func:`import_yade` puts the real folder on ``sys.path`` (``HMDEM_YADE_PATH`` overrides the search)
and imports ``yade``, single-threaded unless asked for more (``threads``, or ``OMP_NUM_THREADS``).
Nothing outside :mod:`hmdem.dem` should call it.
"""

from __future__ import annotations

import contextlib
import glob
import importlib
import io
import os
import sys

from .interrupts import deferred_interrupts

KNOWN_PREFIXES = (
    "/usr/lib/x86_64-linux-gnu/yade-double/py",
    "/usr/lib/aarch64-linux-gnu/yade-double/py",
    "/usr/lib/x86_64-linux-gnu/yade/py",
    "/usr/local/lib/yade/py",
)

FIX_HINT = (
    "YADE is not importable. Install it with `make setup` (Debian: apt-get install yade python3-yade), "
    "run hmdem from the venv made from /usr/bin/python3 with --system-site-packages, "
    "or set HMDEM_YADE_PATH to the folder that holds the 'yade' package."
)


class YadeNotFound(ImportError):
    """Raised when no YADE installation can be imported."""


def candidate_paths() -> list[str]:
    """Folders that may contain the ``yade`` package, most specific first."""
    paths = []
    override = os.environ.get("HMDEM_YADE_PATH")
    if override:
        paths.append(override)
    paths.extend(KNOWN_PREFIXES)
    paths.extend(sorted(glob.glob("/usr/lib/*/yade*/py")))
    return [p for p in dict.fromkeys(paths) if os.path.isdir(os.path.join(p, "yade"))]


def import_yade(threads: int | None = None):
    """Import and return the ``yade`` module, fixing ``sys.path`` for Debian's layout.

    ``threads``: OpenMP threads of YADE's force and integration loops. OpenMP reads them once,
    when YADE loads, so asking for another count after that raises RuntimeError. None keeps
    what the process was started with (``yade -jN``, ``OMP_NUM_THREADS``), else 1.
    Raises :class:`YadeNotFound` with the fix when YADE is absent.
    """
    if "yade" in sys.modules and hasattr(sys.modules["yade"], "O"):
        yade = sys.modules["yade"]
        if threads is not None and yade.O.numThreads != threads:
            raise RuntimeError(f"YADE already runs {yade.O.numThreads} OpenMP thread(s) in this process; "
                               f"{threads} must be asked for before it is first imported")
        return yade
    # one OpenMP thread unless the user asks for more: YADE's parallel force sums are not
    # reproducible bit for bit (the same run on 2 threads ends at other positions each time),
    # and packings must be deterministic for a seed
    if threads is not None:
        os.environ["OMP_NUM_THREADS"] = str(threads)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    for path in candidate_paths():
        if path not in sys.path:
            sys.path.insert(0, path)
        sys.modules.pop("yade", None)  # a failed attempt may have left Debian's broken namespace
        try:
            # YADE prints "Using python version: ..." on import; it says nothing a run needs and
            # would break --quiet (a run prints just its result line), so it is dropped. Ctrl-C and
            # SIGTERM are held through the import: raised inside YADE's boost-python module set-up
            # they aborted the process or left a SystemError traceback (a new-user pass: 13 of 24
            # signals sent in that second); held, they stop the command once YADE is in (an import
            # that hung would then need SIGKILL; none has been seen)
            with contextlib.redirect_stdout(io.StringIO()), deferred_interrupts():
                yade = importlib.import_module("yade")
        except ImportError:
            continue
        if hasattr(yade, "O"):
            return yade
    raise YadeNotFound(FIX_HINT)


def yade_available() -> bool:
    """True when :func:`import_yade` would succeed (imports YADE as a side effect)."""
    try:
        import_yade()
    except YadeNotFound:
        return False
    return True
