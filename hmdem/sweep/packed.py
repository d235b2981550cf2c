"""Run directories as bytes: a worker runs a point into its own scratch space and sends the
whole run directory back, so a Dask cluster needs no file system shared with the client and
only the client ever writes into the sweep directory."""

from __future__ import annotations

import glob
import io
import os
import shutil
import socket
import tarfile
import tempfile
from pathlib import Path

from ..rundir import partial_directory
from .grid import SweepPoint
from .runner import cli_arguments, run_point


def pack_directory(path: Path) -> bytes:
    """The files of a directory as an uncompressed tar (PNG and npz are compressed already)."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as tar:
        for item in sorted(Path(path).iterdir()):
            tar.add(item, arcname=item.name)
    return buffer.getvalue()


def unpack_directory(data: bytes, final: Path) -> None:
    """Extract ``data`` to a temporary sibling of ``final``, then rename it to ``final``."""
    final = Path(final)
    tmp = partial_directory(final)
    try:
        with tarfile.open(fileobj=io.BytesIO(data)) as tar:
            members = tar.getmembers()
            for member in members:  # a run directory is flat: plain files with plain names
                if not member.isfile() or Path(member.name).name != member.name or member.name.startswith("."):
                    raise ValueError(f"unexpected entry {member.name!r} in a packed run directory")
            tar.extractall(tmp, members=members)
        if final.exists():  # a stale directory of an interrupted run
            shutil.rmtree(final)
        os.replace(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


SCRATCH_PREFIX = "hmdem-sweep-"  # then the host, the worker's process id and tempfile's letters


def host_scratch_prefix() -> str:
    """The scratch directories' prefix on this host (no '-' in the host's name, so that the
    process id after it reads back unambiguously)."""
    return f"{SCRATCH_PREFIX}{socket.gethostname().replace('-', '_')}-"


def scratch_prefix(pid: int | None = None) -> str:
    """The prefix of the scratch directories of ``pid`` (default this process) on this host."""
    return f"{host_scratch_prefix()}{os.getpid() if pid is None else pid}-"


def remove_orphaned_scratch(root: Path | None = None) -> None:
    """Remove this user's scratch directories of workers on this host no longer running: a sweep
    stopped by Ctrl-C ends its workers mid-run, before they clean up (a new-user pass found two
    per stop). Process ids mean nothing across hosts or containers that share the directory, so
    other hosts' directories are left alone."""
    prefix = host_scratch_prefix()
    for scratch in Path(root or tempfile.gettempdir()).glob(f"{glob.escape(prefix)}*-*"):
        pid = scratch.name[len(prefix):].split("-")[0]
        try:
            mine = scratch.lstat().st_uid == os.getuid()
        except OSError:
            continue
        if mine and pid.isdigit() and not process_running(int(pid)):
            shutil.rmtree(scratch, ignore_errors=True)


def process_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        return True
    return True


def run_packed(point: SweepPoint, packing: bytes | None = None, packing_name: str | None = None,
               shown_as: str | None = None) -> tuple[dict, bytes]:
    """Run ``point`` in a scratch directory (``packing``: the bytes of a packing .npz, None for
    the shipped one, ``packing_name`` its path on the client, ``shown_as`` the run directory on
    the client, which its warnings name); its summary and the packed run directory, whose
    config.toml records the command as run from the sweep directory."""
    remove_orphaned_scratch()
    with tempfile.TemporaryDirectory(prefix=scratch_prefix()) as scratch:
        packing_path = None
        if packing is not None:
            packing_path = Path(scratch) / "packing.npz"
            packing_path.write_bytes(packing)
        out = Path(scratch) / point.run_id
        recorded = cli_arguments(point, Path("runs") / point.run_id, packing_name)
        summary = run_point(point, out, packing_path, recorded, recorded_packing=packing_name,
                            shown_as=shown_as or str(Path("runs") / point.run_id))
        return summary, pack_directory(out)
