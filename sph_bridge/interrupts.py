"""Ctrl-C (or a batch system's SIGTERM, which the commands turn into one) during a run: the
run stops and its directory is written with status "interrupted", exit status 130."""

from __future__ import annotations

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
    return {"finished": 0, "interrupted": 130}.get(status, 1)
