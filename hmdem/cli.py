"""Command-line conventions shared by hmdem's commands: bad input is one line on stderr that
names the parameter and what is allowed (``<command>: --flag: reason``), exit status 2, and
nothing written."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import platform
import re
import shlex
import signal
import sys
import time
from pathlib import Path

from . import rundir
from .network.packing import CONTACT_STIFFNESS, GRAIN_FRICTION
from .rundir import RunDirectoryTaken


class InputError(ValueError):
    """Bad command-line input found after parsing (e.g. a missing file): one line, exit 2."""


class CommandFailed(RuntimeError):
    """A command's work could not give its result (e.g. a compaction that did not settle): one
    line, exit 1, nothing written."""


class OneLineParser(argparse.ArgumentParser):
    """argparse parser whose errors are one line, prefixed by :attr:`command` (set by each CLI)."""

    command = "hmdem"

    def __init__(self, *args, **kwargs):
        # no prefixes of long options: --sigma would be taken for calibrate's --sigma3, where radial
        # has a --sigma of its own, and a prefix that is unique today may not be after a new option
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        # argparse reads "-1e-4" as an option ("expected one argument"); as a number, it reaches
        # the option's own check, which says what is allowed
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message):
        if message.startswith("argument "):
            message = message[len("argument "):]
        self.exit(2, f"{self.command}: {message}\n")


def number_in(allowed: str, accept):
    """argparse type: a finite number for which ``accept(value)`` holds; ``allowed`` words the
    one-line error (e.g. "a number in [0, 1)")."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and accept(value)):
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text!r}")
        return value

    return parse


positive_number = number_in("a finite number > 0", lambda v: v > 0)
non_negative_number = number_in("a finite number >= 0", lambda v: v >= 0)
# a near-contact gap as a fraction of the smaller radius: beyond one radius a pair is no throat
contact_gap_fraction = number_in("a fraction of the smaller radius in [0, 1]", lambda v: 0 <= v <= 1)
local_damping = number_in("a number in [0, 1) (YADE's local damping)", lambda v: 0 <= v < 1)
# the P-V test passes |p_calc - p_trial| <= rtol max |p| + 1 Pa: from rtol = 1 on, any trial does
relative_tolerance = number_in("a number in (0, 1) (a fraction of the largest |p|)", lambda v: 0 < v < 1)


def int_at_least(minimum: int, allowed: str | None = None, maximum: int | None = None):
    """argparse type: an integer >= ``minimum`` (and <= ``maximum``, if given); ``allowed``
    words the one-line error."""
    allowed = allowed or (f"an integer >= {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text!r}")
        return value

    return parse


non_negative_int = int_at_least(0, "a non-negative integer")
# a seed is stored as a 64-bit integer (the packing .npz, TOML's config.toml): a larger one was
# written as a Python object the file's readers refuse (a new-user pass)
seed_value = int_at_least(0, "an integer in [0, 2**63 - 1]", 2**63 - 1)
positive_int = int_at_least(1)
MIN_GRAINS = 50  # fewer discs do not make a packing with a load-bearing interior
# more discs than YADE places and relaxes in reasonable time here (benchmarks/scaling.py goes to
# 20,000); a typo such as --n 1000000000000 would otherwise end in a numpy MemoryError
MAX_GRAINS = 200_000
grain_count = int_at_least(MIN_GRAINS, maximum=MAX_GRAINS)


def add_contact_arguments(parser: argparse.ArgumentParser, *, stiffness: bool = True, friction: bool = True) -> None:
    """The grain-contact parameters of the Huang sample (seed 004 Table 2), shared by the commands
    that build it: ``--contact-stiffness`` (k_n), ``--friction`` (mu) and ``--stiffness-ratio``
    (k_s / k_n). Table 2's values are the defaults; the biaxial test calibrates them (digest §2.3)."""
    if stiffness:
        parser.add_argument("--contact-stiffness", type=positive_number, default=CONTACT_STIFFNESS,
                            help="normal contact stiffness k_n [N/m per m of depth] (default %(default)g, Table 2)")
    if friction:
        parser.add_argument("--friction", type=non_negative_number, default=GRAIN_FRICTION,
                            help="Coulomb friction coefficient of the grain-grain contacts (default %(default)g, "
                                 "Table 2)")
        parser.add_argument("--stiffness-ratio", type=positive_number, default=1.0,
                            help="shear over normal contact stiffness k_s / k_n (default %(default)g, Table 2)")


_last_interrupt = {"signal": signal.SIGINT}  # the signal that stopped the command, for its exit status


def run_record(prog: str, argv, **fields) -> dict:
    """config.toml's [run] table: the command that replays the run and the versions that ran
    it, then ``fields`` (case, seed, ...)."""
    import numpy as np

    from . import __version__

    return {"command": recorded_command(prog, argv), "hmdem_version": __version__,
            "python": platform.python_version(), "numpy": np.__version__, **fields}


def available_cores() -> int:
    """The cores this process may run on: the default (and the most) worker processes of a
    sweep or a lattice-gas study, one single-threaded worker per core."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def worker_count(requested: int, prog: str) -> int:
    """--workers, at most the cores this process may use: more would only share them (100,000
    would start as many processes), and as the numbers do not depend on the count, a recorded
    command from a larger machine still replays, with a warning, rather than being refused."""
    cores = available_cores()
    if requested > cores:
        print(f"{prog}: warning: --workers {requested} on {cores} core(s); running {cores}", file=sys.stderr)
    return min(requested, cores)


def recorded_command(prog: str, argv) -> str:
    """config.toml's command: ``prog`` and the arguments, shell-quoted so that it replays with
    a blank in a path (a review found ' '.join)."""
    return f"{prog} {shlex.join(argv)}"


def open_bar(tqdm, **options):
    """``tqdm(**options)``, which prints its first line at once; an interrupt landing inside that
    print ends the line, so that the one-line message that follows starts on its own."""
    try:
        return tqdm(**options)
    except KeyboardInterrupt:
        sys.stderr.write("\n")
        raise


def stop_note(status: str, end: str) -> str:
    """Title suffix marking a picture of a run that stopped before its ``end`` status
    (breakthrough for a displacement, t_max for single-phase flow, finished for sph_bridge):
    an interrupted, diverged or --max-steps run shows a partial result."""
    return "" if status == end else f" (stopped: {status})"


def record_interrupt(signum: int) -> None:
    """Remember the signal that is stopping the command (a handler calls this before it stops it)."""
    _last_interrupt["signal"] = signum


def _terminate(signum, frame):
    record_interrupt(signum)
    raise KeyboardInterrupt  # SIGTERM stops a run where Ctrl-C would, with the same partial results


@contextlib.contextmanager
def sigterm_as_interrupt():
    """Inside: a SIGTERM stops the run as Ctrl-C does (and the exit status says 143); the
    previous handler is back after. :func:`dispatch` runs every command in it, the YADE sweep
    script its point."""
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupt_reason() -> str:
    """A stopped run's ``status_message``: the signal that stopped it (a new-user pass found the
    message empty; the exit status says the same, 130 or 143)."""
    signum = signal.Signals(int(_last_interrupt["signal"]))
    return "stopped by Ctrl-C (SIGINT)" if signum == signal.SIGINT else f"stopped by {signum.name}"


def interrupted_status() -> int:
    """Exit status of an interrupted command, the shell's 128 + the signal: 130 after Ctrl-C
    (SIGINT), 143 after a batch system's SIGTERM."""
    return 128 + int(_last_interrupt["signal"])


def yade_script_arguments(script: str, doc: str, argv: list[str]) -> None:
    """A script under ``yade -n -x SCRIPT [ARGS]`` gets ARGS in ``sys.argv[1:]``; its parameters
    come from a yade-batch table (``readParamsFromTable``), so ``-h``/``--help`` prints ``doc`` and
    exits 0, and any other argument is one line and exit status 2, before a run starts."""
    if not argv:
        return
    if any(arg in ("-h", "--help") for arg in argv):
        print(doc.strip())
        sys.exit(0)
    print(f"{script}: {argv[0]}: this script takes no flags; its parameters come from a yade-batch "
          f"table (yade -n -x {script} --help), or run the same case with python -m hmdem.hele_shaw", file=sys.stderr)
    sys.exit(2)


def read_yade_table(script: str, read_params, **defaults) -> None:
    """``read_params`` (YADE's ``utils.readParamsFromTable``) with ``defaults``, for a script
    under yade-batch: a column the script does not know, or a value YADE cannot evaluate (it
    evaluates each as Python: a string without quotes is a NameError or a SyntaxError), is one
    line on stderr and exit status 2, before a run."""
    try:
        read_params(noTableOk=True, **defaults)
    except (NameError, SyntaxError) as exc:
        print(f"{script}: table: {exc} (its columns: {', '.join(defaults)}; strings in quotes)", file=sys.stderr)
        sys.exit(2)


class TableColumnsOnStderr:
    """``sys.stderr`` for a YADE script whose table columns become CLI flags: each such flag in
    what the command writes is named by its column as well, ``--dt`` as ``dt (--dt)``, so that
    an error names the column the user wrote (a new-user pass: a bad ``viscosityRatio`` was
    reported as ``--viscosity-ratio``). Flags given through the ``flags`` column appear as written
    there, and are left alone when no column sets them."""

    def __init__(self, stream, columns: dict[str, str]):
        self._stream = stream
        self._columns = columns  # flag -> column
        # longest first, and whole flags only: --dt must not match inside --dtx
        flags = sorted(columns, key=len, reverse=True)
        self._pattern = re.compile("(?<![\\w-])(" + "|".join(re.escape(f) for f in flags) + ")(?![\\w-])")

    def write(self, text: str) -> int:
        named = text
        if self._columns:  # with none, the pattern would be an empty group matching everywhere
            named = self._pattern.sub(lambda m: f"{self._columns[m.group(1)]} ({m.group(1)})", text)
        self._stream.write(named)
        return len(text)  # what the caller wrote, as a text stream counts it

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name):  # flush, isatty, fileno, encoding: the terminal's own
        return getattr(self._stream, name)


def dispatch(prog: str, parser: argparse.ArgumentParser, args, commands: dict) -> int:
    """Run ``commands[args.command](args)``: a batch system's SIGTERM (or kill) ends it like
    Ctrl-C (exit status :func:`interrupted_status`), an :class:`InputError` is one line on stderr
    and exit status 2, and so is an ``--out`` that another process took during the run
    (:class:`~hmdem.rundir.RunDirectoryTaken`); a :class:`CommandFailed` is one line and exit
    status 1. The SIGTERM handler is the command's only:
    the previous one is back when it returns."""
    written = len(rundir.completed)
    with sigterm_as_interrupt():
        try:
            if args.command in commands:
                return commands[args.command](args)
        except (InputError, RunDirectoryTaken) as exc:
            print(f"{prog}: {exc}", file=sys.stderr)
            return 2
        except CommandFailed as exc:
            print(f"{prog}: {exc}", file=sys.stderr)
            return 1
        except KeyboardInterrupt as exc:  # a run's time steps catch their own; this one came outside them
            if isinstance(exc.__context__, (InputError, RunDirectoryTaken, CommandFailed)):
                # a signal held through a block that raised one of these is delivered on top of it
                print(f"{prog}: {exc.__context__}", file=sys.stderr)
            if len(rundir.completed) > written:  # held while a run directory was written (atomic_run_directory)
                print(f"{prog}: interrupted; {str(rundir.completed[-1])!r} was written whole before it stopped",
                      file=sys.stderr)
            else:
                print(f"{prog}: interrupted; the results in progress were not written", file=sys.stderr)
            return interrupted_status()
        finally:
            _last_interrupt["signal"] = signal.SIGINT  # the next command starts from Ctrl-C's status
    parser.print_help()
    return 2


@contextlib.contextmanager
def near_contacts_checked(contact_gap: float | None = None):
    """The network's near contacts (gap up to the case's contact gap) off the Delaunay
    triangulation, and a network with no inflow or outflow domains, which the packing file's
    own checks cannot see: one line about --packing, or about --contact-gap when it was given
    (a new-user pass: --contact-gap 1 on the shipped sample was blamed on a --packing never given)."""
    from .network.boundaries import NoBoundaryDomains
    from .network.contact_graph import ContactsOffTriangulation

    try:
        yield
    except ContactsOffTriangulation as exc:
        if contact_gap is not None:
            raise InputError(f"--contact-gap: at {contact_gap:g} the packing's near contacts become pipes, and "
                             f"{exc}; a smaller gap leaves them out") from None
        raise InputError(f"--packing: with its near contacts, {exc}") from None
    except NoBoundaryDomains as exc:
        raise InputError(f"--packing: {exc}") from None


def new_run_directory(out: Path | None, name: str) -> Path:
    """``--out`` or ``runs/<name>-<time>-<pid>``; refuses an existing directory (runs never
    overwrite) and a path through a file, before any work is done. The process id keeps two
    runs started in the same second (a shell loop, a batch array) from taking the same name."""
    if out is not None and Path(out) == Path("."):  # also --out '' (an empty path is '.')
        raise InputError(f"--out: must name a new run directory, got {str(out)!r}")
    out = out or Path("runs") / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}"
    if exists(out):
        raise InputError(f"--out: {str(out)!r} already exists; choose a new run directory")
    check_out_parent(out)
    return out


def dangling_link(path: Path) -> bool:
    """A symbolic link to nothing: ``exists`` sees it, but nothing can be written through it."""
    return Path(path).is_symlink() and not Path(path).exists()


def check_out_parent(out: Path) -> None:
    """An :class:`InputError` when ``--out`` would go through a file or where nothing can be
    written (tried with an empty directory, removed at once); its missing directories are made
    when the results are written, so a long run cannot fail there at its end."""
    ancestor = Path(out).absolute().parent
    while not exists(ancestor):
        ancestor = ancestor.parent
    if dangling_link(ancestor):
        raise InputError(f"--out: {str(ancestor)!r} is a symbolic link to nothing")
    if not ancestor.is_dir():
        raise InputError(f"--out: {str(ancestor)!r} is a file, not a directory")
    probe = ancestor / f".hmdem-write-check-{os.getpid()}-{time.monotonic_ns()}"
    try:
        try:
            os.mkdir(probe)
        except OSError as exc:
            raise InputError(f"--out: cannot write under {str(ancestor)!r} ({exc.strerror})") from None
    finally:  # also after an interrupt between the two calls
        with contextlib.suppress(OSError):
            os.rmdir(probe)


def check_packing_out(parser: argparse.ArgumentParser, out: Path, overwrite: bool) -> None:
    """A packing command's ``--out``: an .npz file (numpy would append the suffix, and the file
    would not be the one named), not a directory, new unless ``overwrite``, somewhere writable;
    otherwise ``parser.error`` (one line, exit 2)."""
    if out.suffix != ".npz":
        parser.error(f"--out: must end in .npz, got {str(out)!r}")
    if out.is_dir():
        parser.error(f"--out: {str(out)!r} is a directory; name the packing file to write")
    if out.exists() and not overwrite:  # a packing is minutes of work
        parser.error(f"--out: {str(out)!r} already exists; choose a new file or add --overwrite")
    try:
        check_out_parent(out)
    except InputError as exc:
        parser.error(str(exc))


def exists(path: Path) -> bool:
    """Whether anything stands at ``path``, a dangling symbolic link too (the finished run could
    not be renamed onto it: a new-user pass); a directory the user may not search is an --out error."""
    try:
        Path(path).lstat()
        return True
    except (FileNotFoundError, NotADirectoryError):
        return False
    except PermissionError:
        raise InputError(f"--out: {str(path)!r} cannot be reached (permission denied)") from None


def read_packing(path: Path, maker: str = "python -m hmdem.dem.packing or hmdem.dem.compaction"):
    """The ``--packing`` file as a :class:`~hmdem.network.packing.DiscPacking`; a missing or
    unreadable file is an :class:`InputError` (``maker``: the command its message suggests)."""
    from .network.contact_graph import ContactsOffTriangulation, check_packing_contacts
    from .network.packing import DiscPacking

    if Path(path).is_dir():
        raise InputError(f"--packing: {str(path)!r} is a directory; give a packing .npz file")
    if not Path(path).is_file():
        raise InputError(f"--packing: {str(path)!r} is not a regular file" if Path(path).exists()
                         else f"--packing: no such file {str(path)!r}")
    try:
        packing = DiscPacking.load(path)
    except KeyError:  # an npz of something else, e.g. a run directory's state.npz
        raise InputError(f"--packing: {str(path)!r} is not a packing (one holds centres, radii, contacts, box, "
                         f"seed); write one with {maker}") from None
    except Exception as exc:  # not an npz at all
        raise InputError(f"--packing: cannot read a packing from {str(path)!r} ({type(exc).__name__})") from None
    check_packing_grains(path, packing)
    try:  # the near contacts a run adds are checked where its network is built (ContactsOffTriangulation)
        check_packing_contacts(packing.centres, packing.contacts)
    except ContactsOffTriangulation as exc:
        raise InputError(f"--packing: {exc}") from None
    return packing


def check_packing_grains(path: Path, packing) -> None:
    """An :class:`InputError` for grains no network can be built on: a packing holds at least 3
    discs with finite centres and radii > 0, all within its box (widened by a grain diameter,
    since boundary grains overlap the walls). A new-user pass found NaN centres and a 3-disc
    file ending in tracebacks, and a negative radius and a box 1e-6 m wide running silently."""
    import numpy as np

    centres, radii = np.asarray(packing.centres, float), np.asarray(packing.radii, float)
    name = f"--packing: {str(path)!r}"
    if radii.ndim != 1 or centres.shape != (len(radii), 2) or len(radii) < 3:
        raise InputError(f"{name} must hold at least 3 discs, centres (n, 2) and radii (n,); "
                         f"got centres {centres.shape} and radii {radii.shape}")
    if not (np.isfinite(centres).all() and np.isfinite(radii).all() and (radii > 0).all()):
        raise InputError(f"{name} has discs with a non-finite centre or a radius that is not a finite number > 0")
    box = np.asarray(packing.box, float).ravel()
    if box.shape != (2,):
        raise InputError(f"{name}: its box must be two numbers (width, height) in m, got {box.size}")
    width, height = (float(v) for v in box)
    margin = 2.0 * float(radii.max())
    if not (math.isfinite(width) and math.isfinite(height) and width > 0 and height > 0) or (
            centres.min(axis=0) < -margin).any() or centres[:, 0].max() > width + margin \
            or centres[:, 1].max() > height + margin:
        raise InputError(f"{name}: its discs must lie within its box (0-{width:g} m x 0-{height:g} m, "
                         f"give or take a grain diameter); they span x {centres[:, 0].min():g}-{centres[:, 0].max():g} m, "
                         f"y {centres[:, 1].min():g}-{centres[:, 1].max():g} m")
    contacts = np.asarray(packing.contacts)
    if not contacts.size:
        return
    if contacts.ndim != 2 or contacts.shape[1] != 2 or contacts.dtype.kind not in "iu":
        raise InputError(f"{name}: its contacts must be (k, 2) integer disc indices, got {contacts.dtype} "
                         f"{contacts.shape}")
    if contacts.min() < 0 or contacts.max() >= len(radii):  # a new-user pass: reported as off the triangulation
        raise InputError(f"{name}: its contacts must be pairs of disc indices from 0 to {len(radii) - 1}; they run "
                         f"from {contacts.min()} to {contacts.max()}")


def read_compacted_packing(path: Path):
    """:func:`read_packing`, refusing a packing no servo compacted: Eqs. 13-14 open the Huang
    sample's apertures from the contact forces a compacted sample carries (its confining stress)."""
    packing = read_packing(path, maker="python -m hmdem.dem.compaction")
    if not packing.confining_stress > 0:
        raise InputError(f"--packing: {str(path)!r} records no confining stress, so it is not a "
                         "compacted sample; make one with python -m hmdem.dem.compaction")
    return packing


def check_aperture_fits_grains(mean_aperture: float, radii, aperture_given: bool, can_set: bool = True) -> None:
    """An :class:`InputError` when the mean pipe aperture is wider than the median grain: a
    throat between two discs is no wider than a disc (the Lenormand sample has 0.42 mm
    against 2 mm, Chen's lattice 0.25 against 0.5 mm). It catches a --mean-aperture in the
    wrong unit and a packing of the Huang sample's 34 um grains in a linear run. ``can_set``:
    the command has a --mean-aperture (the message suggests it)."""
    import numpy as np

    diameter = 2.0 * float(np.median(radii))
    if mean_aperture <= diameter:
        return
    if aperture_given:
        raise InputError(f"--mean-aperture: must not exceed the grains' median diameter {diameter:.4g} m, "
                         f"got {mean_aperture:g}")
    raise InputError(f"--packing: its median grain diameter {diameter:.4g} m is narrower than the mean aperture "
                     f"{mean_aperture:g} m; use coarser grains" + (" or a --mean-aperture below it" if can_set else ""))
