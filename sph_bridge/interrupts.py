"""Ctrl-C (or a batch system's SIGTERM, which the commands turn into one) during a run: the
run stops and its directory is written with status "interrupted", exit status 130 (Ctrl-C) or
143 (SIGTERM)."""

from __future__ import annotations

from hmdem.cli import interrupted_status

STOP = (KeyboardInterrupt, SystemError)  # what a Ctrl-C can surface as (see :func:`interrupted`)


def interrupted(exc: BaseException) -> bool:
    """A KeyboardInterrupt, or an error whose cause chain holds one (a Ctrl-C landing inside a
    numba call comes out as SystemError)."""
    while exc is not None:
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def exit_status(status: str) -> int:
    if status == "interrupted":
        return interrupted_status()
    return 0 if status == "finished" else 1
