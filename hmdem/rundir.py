"""Run directories: written under a temporary name and renamed when complete.

Contents (issue 2 contract): config.toml, summary.json, timeseries.csv, network.npz, state.npz,
pattern.png, pressure.png and domains.vtu (ParaView); with --snapshots, domains.pvd (and for
moving grains contacts.pvd) over snapshots/*.vtu (hmdem/snapshots.py). A crash never leaves a half-written
directory under the final name; a Ctrl-C'd run is still written, with status "interrupted".
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .interrupts import deferred_interrupts


def toml_value(v) -> str:
    if hasattr(v, "item") and not isinstance(v, (list, tuple)):  # numpy scalars
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        if isinstance(v, float) and not math.isfinite(v):
            return "inf" if v > 0 else ("-inf" if v < 0 else "nan")
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return json.dumps(str(v))


def write_toml(path: Path, sections: dict[str, dict]) -> None:
    """Minimal TOML writer for flat sections of scalars (tomllib reads it back). TOML has no
    null: a value left unset (None) is left out."""
    lines = []
    for name, table in sections.items():
        lines.append(f"[{name}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in table.items() if v is not None]
        lines.append("")
    path.write_text("\n".join(lines))


def json_safe(obj):
    """Replace non-finite floats by null so summary.json is strict JSON."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


UNSAVED = ".unsaved-"  # in the name of a finished run kept beside an --out another process took


class RunDirectoryTaken(OSError):
    """The run directory appeared while the run ran (another process made it); the results were
    kept under a sibling name, which the message gives."""


def current_umask() -> int:
    """The process's umask, read from /proc where it can be (setting it to read it back would
    briefly change it for every thread, e.g. a Dask client's)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def umask_mode(base: int) -> int:
    """``base`` (0o777 for a directory, 0o666 for a file) under the process's umask: the mode
    ``mkdir`` or ``open`` would give. ``mkdtemp`` and ``mkstemp`` make private 0o700 / 0o600
    entries, which would hide a run from the rest of a research group."""
    return base & ~current_umask()


def partial_directory(final: Path) -> Path:
    """A new empty sibling of ``final`` to fill before renaming it to ``final``: hidden
    (``.<name>.partial-XXXX``, which sweeps do not read as runs), with the umask's mode."""
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.partial-", dir=final.parent))
    try:
        os.chmod(tmp, umask_mode(0o777))
    except BaseException:
        tmp.rmdir()
        raise
    return tmp


# run directories this process completed, newest last: a command stopped by a signal held
# while it wrote one names it (hmdem.cli.dispatch)
completed: list[Path] = []


@contextmanager
def atomic_run_directory(final: Path):
    """Yield a temporary sibling directory; rename it to ``final`` when the block completes.

    Ctrl-C and SIGTERM are held while the block writes and delivered once the directory is
    complete (:func:`~hmdem.interrupts.deferred_interrupts`): a signal at the end of a long run
    stops the command, but the run it finished is kept. Raises :class:`RunDirectoryTaken` when
    ``final`` was made meanwhile and holds something: the finished run is then renamed
    ``<final>.unsaved-XXXX`` rather than lost or merged (a sweep does not read it as a run)."""
    final = Path(final)
    with deferred_interrupts():
        tmp = partial_directory(final)
        try:
            yield tmp
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        try:
            os.replace(tmp, final)
        except OSError:
            if not final.exists():  # not a directory or a file standing at ``final``: another failure
                raise
            raise set_aside(tmp, final, final.with_name(f"{final.name}{UNSAVED}{tmp.name.rsplit('-', 1)[-1]}")) from None
        completed.append(final)


def set_aside(tmp: Path, final: Path, kept: Path) -> RunDirectoryTaken:
    """Move a finished ``tmp`` to ``kept``, beside the ``final`` another process made meanwhile;
    returns the error to raise, which names both."""
    os.replace(tmp, kept)
    return RunDirectoryTaken(f"--out: {str(final)!r} was created by another process during the run; this "
                             f"run's results are in {str(kept)!r}")


@contextmanager
def replaced_atomically(path: Path, keep_existing: bool = False):
    """Yield a temporary sibling of ``path`` (same suffix) to write; rename it onto ``path`` when
    the block completes: a reader (or a kill) sees the old content or the new, never a part.

    ``keep_existing``: a ``path`` that another process made while the block ran is not replaced;
    the new file is kept as ``<stem>.unsaved-XXXX<suffix>`` and :class:`RunDirectoryTaken` names
    it (a hard link publishes the file only where nothing stands)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        os.chmod(tmp, umask_mode(0o666))
        yield Path(tmp)
        if keep_existing:
            publish_new(Path(tmp), path)
        else:
            os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def publish_new(tmp: Path, path: Path) -> None:
    """Rename ``tmp`` to ``path`` unless ``path`` exists by then; else keep it beside ``path``
    and raise :class:`RunDirectoryTaken`."""
    try:
        os.link(tmp, path)  # fails where anything stands at path: no window between check and write
        tmp.unlink()
        return
    except FileExistsError:
        pass
    except OSError:  # a file system without hard links: check, then rename
        if not path.exists():
            os.replace(tmp, path)
            return
    raise set_aside(tmp, path, path.with_name(f"{path.stem}{UNSAVED}{tmp.stem.rsplit('.', 1)[-1]}{path.suffix}"))


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through :func:`replaced_atomically`."""
    with replaced_atomically(path) as tmp:
        tmp.write_text(text)


def write_json(path: Path, data: dict, default=None) -> None:
    """Strict JSON (non-finite floats as null), indented; ``default`` as for :func:`json.dumps`."""
    Path(path).write_text(json.dumps(json_safe(data), indent=2, default=default) + "\n")


def write_rows(path: Path, columns, rows) -> None:
    """A CSV file: a header of ``columns``, then ``rows`` (timeseries.csv)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        w.writerows(rows)
