"""Parameter sweeps (issue 4): grids, Dask execution, resume, failures, collect, yade-batch.

The runs here use a 144-disc triangular packing (~1 s per run); the 5 x 6 grid on the default
packing is a `make validate` check (tests/test_sweep_full.py)."""

import csv
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import popen_interruptible
from hmdem.network.packing import DiscPacking
from hmdem.sweep.__main__ import main as sweep_main
from hmdem.sweep.grid import Axis, SweepPoint, lenormand_points, lenormand_spec, parse_axis
from hmdem.sweep.manifest import Manifest
from hmdem.sweep.packed import run_packed
from hmdem.sweep.table import TIMING_COLUMNS

ROOT = Path(__file__).resolve().parent.parent
GRID = ["--log-m", "-4:2:2", "--log-ca", "-6:1:2"]  # one point in each corner of the diagram


def tiny_packing(nx=12, ny=12, r=1e-3, seed=0) -> DiscPacking:
    """Discs on a triangular lattice (spacing 2r), radii shrunk by up to 4 %: every lattice
    neighbour pair is a contact, so the network is the lattice's (planar, connected)."""
    rng = np.random.default_rng(seed)
    s = 2 * r
    xy = np.array([[(i + 0.5 * (j % 2)) * s + r, j * s * np.sqrt(3) / 2 + r] for j in range(ny) for i in range(nx)])
    radii = r * (1 - 0.04 * rng.random(len(xy)))
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    i, j = np.nonzero(np.triu(d < 1.01 * s, 1))
    box = (nx * s + r, (ny - 1) * s * np.sqrt(3) / 2 + 2 * r)
    return DiscPacking(xy, radii, np.stack([i, j], 1), box, seed)


@pytest.fixture(scope="module")
def packing(tmp_path_factory):
    path = tmp_path_factory.mktemp("packing") / "tiny.npz"
    tiny_packing().save(path)
    return path


def read_table(path: Path, drop=TIMING_COLUMNS) -> list[dict]:
    with open(path) as f:
        return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]


@pytest.fixture(scope="module")
def reference(packing, tmp_path_factory):
    """An uninterrupted 2 x 2 sweep on the embedded Dask LocalCluster (2 workers)."""
    out = tmp_path_factory.mktemp("sweeps") / "reference"
    code = sweep_main(["lenormand", *GRID, "--workers", "2", "--packing", str(packing), "--out", str(out), "--quiet"])
    return code, out


# ---- grids and input checks ----------------------------------------------------------------
def test_axis_spec_gives_evenly_spaced_values_with_both_ends():
    np.testing.assert_allclose(parse_axis("-5:2:5").values(), [-5, -3.25, -1.5, 0.25, 2])
    assert parse_axis("3:3:1").values().tolist() == [3.0]
    points = lenormand_points(parse_axis("-1:1:2"), parse_axis("0:0:1"), seeds=3)
    assert len(points) == 6 and [p.seed for p in points] == [0, 1, 2, 0, 1, 2]
    assert len({p.run_id for p in points}) == 6


@pytest.mark.parametrize("flags, named", [
    (["--log-m", "1:2"], "--log-m"),
    (["--log-m", "-5:2:0"], "--log-m"),
    (["--log-ca", "a:b:3"], "--log-ca"),
    (["--log-ca", "1:1:3"], "--log-ca"),
    (["--log-ca", "0:inf:3"], "--log-ca"),
    # beyond where the runs reach breakthrough (decisions #77, #78): 400 overflowed M to inf with
    # a traceback, 10 gave points that never finished
    (["--log-ca", "400:401:2"], "--log-ca"),
    (["--log-ca", "10:11:2"], "--log-ca"),
    (["--log-ca", "-11:-8:2"], "--log-ca"),
    (["--log-m", "-7:0:2"], "--log-m"),
    (["--packing", str(Path(__file__).resolve().parent.parent / "hmdem" / "data" / "huang_packing.npz")],
     "--packing"),  # 34 um grains under 0.42 mm apertures
    (["--seeds", "0"], "--seeds"),
    (["--workers", "-1"], "--workers"),
    (["--workers", "0"], "--workers"),
    # a new-user pass (decisions #84): 1e9 seeds spent minutes planning 3e10 runs
    (["--seeds", "1000000000"], "--seeds"),
    (["--log-m", "-5:5:1000", "--log-ca", "-8:2:1000"], "--log-m"),
    (["--scheduler", "notanaddress"], "--scheduler"),  # before the sweep directory is made
    # a new-user pass: points 5e-5 apart shared a run directory (ids resolve 1e-4 in log10)
    (["--log-m", "0:0.0001:3"], "--log-m"),
    (["--scheduler", "foo://host:1"], "--scheduler"),
])
def test_invalid_grid_specs_are_rejected_in_one_line(flags, named, tmp_path):
    out = tmp_path / "sweep"
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "lenormand", *flags, "--out", str(out)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m hmdem.sweep: ") and named in lines[0]
    assert not out.exists()  # nothing written


@pytest.mark.parametrize("out", ["a_file", "a_file/sweep", "/proc/hmdem-test/sweep"])
def test_an_out_that_cannot_be_a_sweep_directory_is_one_line(out, tmp_path):
    (tmp_path / "a_file").write_text("x")
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "lenormand", "--out", out],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("python -m hmdem.sweep: --out: ")
    assert [p.name for p in tmp_path.iterdir()] == ["a_file"] and (tmp_path / "a_file").read_text() == "x"


def test_an_unreachable_scheduler_is_one_line_and_keeps_the_sweep_directory(tmp_path):
    # README: a scheduler that cannot be reached in 30 s ends the command with one line, exit
    # status 1, and the sweep directory (nothing run yet) is kept for a re-run; with its
    # progress bar on, as a user runs it, no bar line follows the message (a new-user pass)
    out = tmp_path / "sweep"
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "lenormand", "--log-m", "-5:2:2", "--log-ca", "-8:2:2",
                           "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("python -m hmdem.sweep: --scheduler: ") and "kept for a re-run" in last
    assert "Traceback" not in proc.stderr
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert len(runs) == 4 and all(r["status"] == "pending" for r in runs.values())


def test_workers_beyond_the_cores_run_on_the_cores_with_a_warning(tmp_path, capsys, monkeypatch):
    # a new-user pass (decisions #84): 100,000 workers broke the embedded cluster's start with a
    # traceback. Refusing them (as then) also refused the reference sweep's --workers 2 on a one-core
    # machine and a command recorded on a larger one; the runs do not depend on the count (lga's too)
    from hmdem import cli
    from hmdem.sweep import execute

    given = []
    monkeypatch.setattr(cli, "available_cores", lambda: 1)
    monkeypatch.setattr(execute, "run_sweep", lambda manifest, packing, workers, *rest, **kw: given.append(workers)
                        or manifest.counts())
    assert sweep_main(["lenormand", *GRID, "--workers", "100000", "--out", str(tmp_path / "s"), "--quiet"]) == 0
    assert given == [1]
    assert "python -m hmdem.sweep: warning: --workers 100000 on 1 core(s); running 1" in capsys.readouterr().err


def test_a_sweep_directory_cannot_be_resumed_with_another_grid(tmp_path):
    points = lenormand_points(Axis(0, 0, 1), Axis(0, 0, 1), 1)
    Manifest.open(tmp_path, {"log_m": "0:0:1"}, points)
    with pytest.raises(ValueError, match="different sweep"):
        Manifest.open(tmp_path, {"log_m": "0:1:2"}, points)


def test_a_packing_with_no_network_is_refused_before_the_sweep_directory(tmp_path, capsys):
    # a new-user pass: a packing whose discs do not touch made a sweep directory of 12 failed points
    pk = tiny_packing()
    loose = DiscPacking(3.0 * pk.centres, pk.radii, pk.contacts[:0], (3.0 * pk.box[0], 3.0 * pk.box[1]), 0)
    loose.save(tmp_path / "loose.npz")
    out = tmp_path / "sweep"
    assert sweep_main(["lenormand", *GRID, "--packing", str(tmp_path / "loose.npz"), "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--packing: its network has 0 inflow and 0 outflow domains" in lines[0]
    assert not out.exists()


def test_a_sweep_is_resumed_on_its_packing_bytes_not_its_packing_name(tmp_path, capsys, monkeypatch):
    # a new-user pass: a packing file replaced under the same name was resumed into the same
    # sweep (runs on two samples in one table), while the shipped file named explicitly was
    # refused as "a different sweep"; the manifest now holds the bytes' SHA-256
    from dataclasses import replace

    import hmdem.sweep.execute as execute
    from hmdem.cases import default_packing_path
    from hmdem.network.packing import DiscPacking
    from hmdem.report import packing_record
    from hmdem.sweep.__main__ import main as sweep_main

    monkeypatch.setattr(execute, "run_sweep", lambda manifest, *args, **kwargs: manifest.counts())
    log_m, log_ca = parse_axis("2:2:1"), parse_axis("0:0:1")
    grid = ["lenormand", "--log-m", "2:2:1", "--log-ca", "0:0:1", "--quiet"]

    def started(out, packing):  # the manifest of a sweep begun on ``packing``'s bytes
        Manifest.open(out, lenormand_spec(log_m, log_ca, 1, packing_record(packing)["sha256"]),
                      lenormand_points(log_m, log_ca, 1))

    packing = tmp_path / "p.npz"
    packing.write_bytes(default_packing_path().read_bytes())
    started(tmp_path / "mine", packing)
    shipped = DiscPacking.load(packing)
    replace(shipped, seed=shipped.seed + 1).save(packing)  # other bytes under the same name
    assert sweep_main([*grid, "--packing", str(packing), "--out", str(tmp_path / "mine")]) == 2
    err = capsys.readouterr().err
    assert "holds a different sweep (packing_sha256 " in err and "same grid, seeds and packing" in err
    started(tmp_path / "shipped", default_packing_path())  # begun without --packing
    assert sweep_main([*grid, "--packing", str(default_packing_path()), "--out", str(tmp_path / "shipped")]) == 0


def test_a_sweep_started_before_packings_were_recorded_by_their_bytes_resumes(tmp_path):
    # review: a manifest written before the SHA-256 (its spec named the packing, or None for the
    # shipped one) was refused as "a different sweep" by the same command; it resumes when its
    # finished runs name the same bytes, and is refused, naming why, when they do not
    log_m, log_ca = parse_axis("2:2:1"), parse_axis("0:2:2")
    points = lenormand_points(log_m, log_ca, 1)
    spec = lenormand_spec(log_m, log_ca, 1, "a" * 64)
    legacy = {k: v for k, v in spec.items() if k != "packing_sha256"} | {"packing": None}
    Manifest.open(tmp_path, legacy, points)  # a sweep directory as the older version left it
    run = tmp_path / "runs" / points[0].run_id
    run.mkdir(parents=True)
    (run / "config.toml").write_text('[packing]\nsha256 = "' + "a" * 64 + '"\n')
    assert Manifest.open(tmp_path, spec, points).spec == spec
    assert json.loads((tmp_path / "manifest.json").read_text())["spec"] == spec  # saved as this version writes it
    other = tmp_path / "other"
    Manifest.open(other, legacy, points)
    (other / "runs" / points[0].run_id).mkdir(parents=True)
    (other / "runs" / points[0].run_id / "config.toml").write_text('[packing]\nsha256 = "' + "b" * 64 + '"\n')
    with pytest.raises(ValueError, match="packing_sha256 other bytes"):
        Manifest.open(other, spec, points)


# ---- Dask, resume, failures ----------------------------------------------------------------
def test_dask_local_sweep_runs_every_point_into_its_run_directory(reference):
    code, out = reference
    assert code == 0
    rows = read_table(out / "sweep.csv")
    assert len(rows) == 4 and {r["status"] for r in rows} == {"breakthrough"}
    # each point keeps the single-run contract and records the command that reproduces it
    for row in rows:
        run = out / row["run"]
        for name in ("config.toml", "summary.json", "timeseries.csv", "network.npz", "state.npz",
                     "pattern.png", "pressure.png", "domains.vtu"):
            assert (run / name).is_file(), name
        assert "linear --case sd --viscosity-ratio" in (run / "config.toml").read_text()
    # regimes come from the runs: the low-Ca* corners are capillary fingering
    low = [r for r in rows if float(r["log_ca_star"]) < 0]
    assert {r["regime"] for r in low} == {"capillary fingering"}
    assert (out / "phase_diagram.png").stat().st_size > 10_000
    manifest = json.loads((out / "manifest.json").read_text())
    assert {r["status"] for r in manifest["runs"].values()} == {"done"}


def test_scheduler_address_runs_the_same_sweep_on_an_existing_cluster(reference, packing, tmp_path, capsys):
    # --scheduler: the same runs on a cluster started elsewhere (here a LocalCluster of this
    # process; its workers get the packing as bytes and send run directories back). --workers
    # has no say there, and says so (a new-user pass: it was ignored without a word)
    from distributed import LocalCluster

    out = tmp_path / "sweep"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        code = sweep_main(["lenormand", *GRID, "--scheduler", cluster.scheduler_address, "--packing", str(packing),
                           "--workers", "3", "--out", str(out), "--quiet"])
    assert code == 0
    assert "warning: --workers 3 is not used with --scheduler" in capsys.readouterr().err
    assert read_table(out / "sweep.csv") == read_table(reference[1] / "sweep.csv")


def crash_first_attempt(point, packing, packing_name, shown_as):
    """Kill the worker process the first time the M = 100, Ca* = 10 point runs."""
    marker = Path(os.environ["HMDEM_TEST_MARKER"])
    if point.log_m > 0 and point.log_ca_star > 0 and not marker.exists():
        marker.write_text("crashed once")
        os._exit(1)
    return run_packed(point, packing, packing_name, shown_as)


def fail_at_low_m(point, packing, packing_name, shown_as):
    if point.log_m < 0 and point.log_ca_star > 0:
        raise RuntimeError("simulated failure at log M < 0")
    return run_packed(point, packing, packing_name, shown_as)


def open_manifest(out, packing):
    """The manifest the CLI opens for GRID on ``packing`` (so a later CLI run resumes it)."""
    from hmdem.report import packing_record

    log_m, log_ca = parse_axis("-4:2:2"), parse_axis("-6:1:2")
    return Manifest.open(out, lenormand_spec(log_m, log_ca, 1, packing_record(packing)["sha256"]),
                         lenormand_points(log_m, log_ca, 1))


@pytest.fixture
def by_value():
    """Ship this module's runner functions to the Dask workers by value (they cannot import it)."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    yield
    cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


def test_embedded_workers_leave_ctrl_c_to_the_sweep():
    # a terminal's Ctrl-C reaches every process of the group; a worker that took it printed
    # asyncio's KeyboardInterrupt traceback (1 of 3 tries with 9 points). Workers ignore SIGINT
    # and the sweep's own process, which keeps its handler, stops the run (hmdem/sweep/worker_setup.py)
    from hmdem.sweep.execute import start_client

    # as from a terminal: a shell's background job (CI's) starts with SIGINT ignored, and its
    # workers would inherit that without the preload
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        client, cluster = start_client(1, None)
        try:
            assert client.submit(signal.getsignal, signal.SIGINT, pure=False).result() == signal.SIG_IGN
            assert client.submit(signal.getsignal, signal.SIGTERM, pure=False).result() != signal.SIG_IGN
        finally:
            client.close()
            cluster.close()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the sweep's own is kept
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_worker_crash_is_retried_and_gives_the_same_table(reference, packing, tmp_path, monkeypatch, by_value):
    from hmdem.sweep.__main__ import write_tables
    from hmdem.sweep.execute import run_sweep

    marker = tmp_path / "crashed"
    monkeypatch.setenv("HMDEM_TEST_MARKER", str(marker))  # LocalCluster workers inherit the environment
    out = tmp_path / "sweep"
    manifest = open_manifest(out, packing)
    counts = run_sweep(manifest, packing, workers=2, progress=False, runner=crash_first_attempt)
    assert marker.exists()  # the worker did die
    assert counts["done"] == 4 and counts["failed"] == 0
    write_tables(out)
    assert read_table(out / "sweep.csv") == read_table(reference[1] / "sweep.csv")


def test_a_failing_run_is_recorded_without_stopping_the_others_and_retried(reference, packing, tmp_path, by_value):
    from hmdem.sweep.__main__ import write_tables
    from hmdem.sweep.execute import run_sweep

    out = tmp_path / "sweep"
    manifest = open_manifest(out, packing)
    counts = run_sweep(manifest, packing, workers=2, progress=False, runner=fail_at_low_m)
    assert counts == {"pending": 0, "done": 3, "failed": 1}
    failed = [r for r in manifest.runs.values() if r["status"] == "failed"]
    assert failed[0]["error"].startswith("RuntimeError: simulated failure at log M < 0")
    assert not (out / "runs" / SweepPoint(-4.0, 1.0, 0).run_id).exists()  # nothing half-written
    write_tables(out)
    rows = read_table(out / "sweep.csv")
    assert [r["status"] for r in rows].count("failed") == 1
    assert "simulated failure" in next(r["error"] for r in rows if r["status"] == "failed")
    # the same command again retries only the failed run, which now succeeds
    manifest = open_manifest(out, packing)
    assert [p.run_id for p in manifest.todo()] == [SweepPoint(-4.0, 1.0, 0).run_id]
    counts = run_sweep(manifest, packing, workers=1, progress=False)
    assert counts["done"] == 4 and manifest.runs[SweepPoint(-4.0, 1.0, 0).run_id]["attempts"] == 2
    write_tables(out)
    assert read_table(out / "sweep.csv") == read_table(reference[1] / "sweep.csv")


def test_an_interrupted_sweep_finishes_with_the_same_table(reference, packing, tmp_path):
    out = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "hmdem.sweep", "lenormand", *GRID, "--workers", "1", "--packing", str(packing),
           "--out", str(out), "--quiet"]
    proc = popen_interruptible(cmd)
    deadline = time.time() + 300
    while time.time() < deadline:  # stop it once the first run is in and before the last
        runs = out / "runs"
        if runs.is_dir() and len([p for p in runs.iterdir() if not p.name.startswith(".")]) >= 1:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr[-2000:]
    partial = read_table(out / "sweep.csv")
    assert 1 <= len(partial) < 4
    assert json.loads((out / "manifest.json").read_text())["spec"]["log_m"] == "-4:2:2"  # valid manifest
    # the same command again finishes the sweep; the table equals the uninterrupted one
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert read_table(out / "sweep.csv") == read_table(reference[1] / "sweep.csv")
    # each ran once: runs submitted but stopped before they came back are no attempt (a new-user pass)
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert [r["attempts"] for r in runs.values()] == [1, 1, 1, 1]


def test_run_point_takes_only_its_own_run_directory(packing, tmp_path):
    # the YADE script's out (default runs/lenormand-batch/<run id>, the id without the packing):
    # a finished run of this point is its result; another point's run, a run on other packing
    # bytes, or a directory of other files is refused and left as it is (a new-user pass: a cf1
    # run was reported as the point's, and a directory of other files was wiped)
    import shutil
    import tomllib

    from hmdem.sweep.runner import NotThisPoint, run_point

    point, out = SweepPoint(2.0, 2.0, 0), tmp_path / "run"
    first = run_point(point, out, str(packing))
    assert run_point(point, out, str(packing)) == first  # the finished run is the result
    assert tomllib.loads((out / "config.toml").read_text())["packing"]["file"] == str(packing.resolve())
    other_bytes = tmp_path / "other.npz"
    tiny_packing(seed=1).save(other_bytes)
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "notes.txt").write_text("keep")
    shutil.copytree(out, tmp_path / "copy")
    for other, where, pk in ((SweepPoint(2.0, 1.0, 0), out, packing), (SweepPoint(2.0, 2.0, 1), out, packing),
                             (point, out, other_bytes), (point, precious, packing)):
        with pytest.raises(NotThisPoint, match="exists and is not a run of point"):
            run_point(other, where, str(pk))
    assert (precious / "notes.txt").read_text() == "keep"
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in (tmp_path / "copy").iterdir())
    # the point's command with other options, cut short here, is not its result (review)
    from hmdem.hele_shaw import main as run_main
    from hmdem.sweep.runner import cli_arguments

    cut = tmp_path / "cut"
    assert run_main(cli_arguments(point, cut, str(packing)) + ["--max-steps", "3"]) == 0
    with pytest.raises(NotThisPoint):
        run_point(point, cut, str(packing))
    # a run written before config.toml had [packing] is matched by the file its command names
    config = (tmp_path / "copy" / "config.toml").read_text()
    (tmp_path / "copy" / "config.toml").write_text(config[:config.index("[packing]")])
    assert run_point(point, tmp_path / "copy", str(packing)) == first
    # a table's packing that is not there is named as such, before anything is hashed
    from hmdem.cli import InputError

    with pytest.raises(InputError, match="--packing: no such file"):
        run_point(point, out, str(tmp_path / "missing.npz"))


def test_a_sweep_run_names_the_packing_the_client_gave(packing):
    # a worker runs on a scratch copy of the packing; config.toml names the client's file (by
    # absolute path, as the recorded command does) with the bytes' SHA-256
    import hashlib
    import io
    import tarfile
    import tomllib

    summary, packed = run_packed(SweepPoint(2.0, 2.0, 0), packing.read_bytes(), str(packing))
    with tarfile.open(fileobj=io.BytesIO(packed)) as tar:
        config = tomllib.loads(tar.extractfile("config.toml").read().decode())
    assert config["packing"] == {"file": str(packing), "sha256": hashlib.sha256(packing.read_bytes()).hexdigest()}
    assert f"--packing {packing}" in config["run"]["command"]


# ---- yade-batch ----------------------------------------------------------------------------
@pytest.mark.yade
def test_yade_batch_runs_the_shipped_table_and_collect_aggregates_it(packing, tmp_path):
    # the first and last rows of the shipped 5 x 6 table (capillary fingering at low M and Ca*,
    # stable displacement at high M and Ca* on the default packing), on the tiny packing
    lines = (ROOT / "yade_scripts" / "lenormand.table").read_text().splitlines()
    rows = [ln for ln in lines if ln.strip() and not ln.startswith("#")]
    header, body = rows[0], rows[1:]
    assert len(body) == 30
    table = tmp_path / "reduced.table"
    table.write_text(f"{header} packing\n" + "".join(f"{r} '{packing}'\n" for r in (body[0], body[-1])))
    proc = subprocess.run(["yade-batch", "--job-threads", "1", "-j", "2", "--log", str(tmp_path / "@.log"),
                           str(table), str(ROOT / "yade_scripts" / "hele_shaw_linear.py")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-2000:]
    batch = tmp_path / "runs" / "lenormand-batch"
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "collect", str(batch)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    collected = read_table(batch / "sweep.csv")
    assert [(float(r["log_m"]), float(r["log_ca_star"])) for r in collected] == [(-5.0, -8.0), (2.0, 2.0)]
    assert collected[0]["regime"] == "capillary fingering"
    assert (batch / "phase_diagram.png").is_file()


@pytest.mark.yade
def test_yade_script_says_when_it_takes_an_earlier_run(packing, tmp_path):
    # a new-user pass: a point whose out held its finished run printed the usual result line,
    # as if it had run (in 0 s)
    (tmp_path / "p.table").write_text(f"description logM logCa seed packing out\n"
                                      f"p 2 2 0 '{packing}' '{tmp_path / 'run'}'\n")
    env = {**os.environ, "YADE_BATCH": f"{tmp_path / 'p.table'}:2"}  # as yade-batch starts a job
    lines = []
    for _ in range(2):
        proc = subprocess.run(["yade", "-n", "-x", str(ROOT / "yade_scripts" / "hele_shaw_linear.py")],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        lines.append(proc.stdout.strip().splitlines()[-1])
    point = SweepPoint(2.0, 2.0, 0).run_id
    assert lines[0].startswith(f"{point}: breakthrough, ")
    assert lines[1] == lines[0].replace(f"{point}: ", f"{point}: taken from its earlier run: ", 1)


@pytest.mark.yade
def test_yade_script_refused_packing_is_one_line_exit_2(tmp_path):
    # a table row whose packing the linear run refuses (the Huang sample's 34 um grains under
    # 0.42 mm apertures): yade-batch logs one line and status 2, not a traceback
    huang = ROOT / "hmdem" / "data" / "huang_packing.npz"
    (tmp_path / "bad.table").write_text(f"description logM logCa seed packing out\n"
                                        f"huang 2 1 0 '{huang}' '{tmp_path / 'run'}'\n")
    env = {**os.environ, "YADE_BATCH": f"{tmp_path / 'bad.table'}:2"}  # as yade-batch starts a job
    proc = subprocess.run(["yade", "-n", "-x", str(ROOT / "yade_scripts" / "hele_shaw_linear.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    assert "hele_shaw_linear.py: --packing: its median grain diameter" in proc.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.yade
@pytest.mark.parametrize("column, value, allowed", [("logM", "9", "[-6, 6]"), ("logCa", "-12", "[-10, 4]"),
                                                    ("logM", "'two'", "[-6, 6]")])
def test_yade_script_keeps_to_the_sweeps_bounds(tmp_path, column, value, allowed):
    # the sweep refuses log M 9; the YADE script ran it (a new-user pass)
    (tmp_path / "bad.table").write_text(f"description {column} out\nbad {value} '{tmp_path / 'run'}'\n")
    env = {**os.environ, "YADE_BATCH": f"{tmp_path / 'bad.table'}:2"}
    proc = subprocess.run(["yade", "-n", "-x", str(ROOT / "yade_scripts" / "hele_shaw_linear.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert f"hele_shaw_linear.py: table: {column} must be a number in {allowed}, got {value}" in proc.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.yade
@pytest.mark.parametrize("value", ["-1", "2.5", "1e30"])
def test_yade_script_seed_is_a_64_bit_integer(tmp_path, value):
    # a new-user pass: seed -1 was reported as the CLI's --seed, not the table's column
    (tmp_path / "bad.table").write_text(f"description seed out\nbad {value} '{tmp_path / 'run'}'\n")
    env = {**os.environ, "YADE_BATCH": f"{tmp_path / 'bad.table'}:2"}
    proc = subprocess.run(["yade", "-n", "-x", str(ROOT / "yade_scripts" / "hele_shaw_linear.py")], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "hele_shaw_linear.py: table: seed must be an integer in [0, 2**63 - 1]" in proc.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.yade
@pytest.mark.parametrize("signum, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_yade_script_interrupted_exits_128_plus_signal_with_one_line_and_a_valid_directory(signum, status, tmp_path):
    # Ctrl-C or a batch system's SIGTERM to `yade -n -x yade_scripts/hele_shaw_linear.py` (the
    # default point takes ~20 s): the run's own status (yade-batch logs it), one line naming the
    # run, and the run directory written with status "interrupted" (it used to end in a
    # RuntimeError traceback, and SIGTERM killed it with nothing written)
    proc = popen_interruptible(["yade", "-n", "-x", str(ROOT / "yade_scripts" / "hele_shaw_linear.py")], cwd=tmp_path)
    seen = ""
    while "Running script" not in seen and proc.poll() is None:
        seen += proc.stderr.read(1)
    time.sleep(3.0)
    proc.send_signal(signum)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == status, err[-2000:]
    assert "Traceback" not in err
    (run,) = (tmp_path / "runs" / "lenormand-batch").iterdir()
    # the run's status_message names the signal (2026-12-01)
    reason = "Ctrl-C (SIGINT)" if signum == signal.SIGINT else "SIGTERM"
    assert f"run {run.name} ended with exit status {status}: stopped by {reason}; run directory" in err
    assert json.loads((run / "summary.json").read_text())["status"] == "interrupted"


def test_collect_rejects_a_directory_without_runs(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "collect", str(tmp_path)], capture_output=True,
                          text=True)
    assert proc.returncode == 2 and "no run directories" in proc.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.mark.parametrize("name, says", [("a_file", "'a_file' is a file, not a directory"),
                                         ("nothing", "no such directory 'nothing'")])
def test_collect_names_what_its_dir_is(name, says, tmp_path):
    # a new-user pass: `collect README.md` said "no such directory" of a file that exists
    (tmp_path / "a_file").write_text("x")
    proc = subprocess.run([sys.executable, "-m", "hmdem.sweep", "collect", name], capture_output=True, text=True,
                          cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.strip() == f"python -m hmdem.sweep: dir: {says}"


def test_collect_takes_only_lenormand_runs_and_writes_nothing_without_one(tmp_path, capsys):
    # a new-user pass: collect on a radial run directory wrote sweep.csv and phase_diagram.png
    # into it. Lattice (chen) and single-phase (darcy) runs are no point of Lenormand's diagram
    from hmdem.hele_shaw import main as run_main

    for case in ("vf", "chen", "darcy"):
        assert run_main(["linear", "--case", case, "--max-steps", "2", "--out", str(tmp_path / case), "--quiet"]) == 0
    # a run directory written before decisions #76 kept the regime of its partial pattern
    summary_path = tmp_path / "vf" / "summary.json"
    summary_path.write_text(json.dumps({**json.loads(summary_path.read_text()), "regime": "viscous fingering"}))
    assert sweep_main(["collect", str(tmp_path)]) == 0
    rows = read_table(tmp_path / "sweep.csv")
    assert [(r["run"], r["status"], r["regime"]) for r in rows] == [("vf", "max_steps", "undetermined")]
    assert "2 other run directories left out" in capsys.readouterr().err
    # a run directory itself, a Lenormand one too (a second new-user pass: collect runs/cf1 wrote
    # its tables among the run's files), is refused with nothing written
    for case in ("chen", "vf"):
        before = sorted(p.name for p in (tmp_path / case).iterdir())
        assert sweep_main(["collect", str(tmp_path / case)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "is a run directory; give the directory that holds the runs" in err[0]
        assert sorted(p.name for p in (tmp_path / case).iterdir()) == before


def test_collect_warns_when_its_runs_are_more_than_one_sweep(tmp_path, capsys):
    # a new-user pass: `collect runs` merged five sweeps, one point four times (one of them on
    # another packing), and drew them as seeds of one sweep without a word
    import shutil

    from hmdem.hele_shaw import main as run_main

    assert run_main(["linear", "--case", "vf", "--max-steps", "2", "--out", str(tmp_path / "a" / "vf"), "--quiet"]) == 0
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    assert sweep_main(["collect", str(tmp_path / "a")]) == 0
    assert "warning" not in capsys.readouterr().err
    assert sweep_main(["collect", str(tmp_path)]) == 0
    assert "warning: log M -4.74473, log Ca* -3.72125, seed 0 is in both a/vf and b/vf" in capsys.readouterr().err
    rows = read_table(tmp_path / "sweep.csv")
    assert len(rows) == 2 and rows[0]["packing_sha256"] == hashlib.sha256(
        (Path(__file__).resolve().parent.parent / "hmdem" / "data" / "lenormand_packing.npz").read_bytes()).hexdigest()


def test_runs_kept_aside_and_partial_writes_are_not_read_as_runs(tmp_path):
    # a run kept as <out>.unsaved-XXXX (another process took its name, hmdem.rundir) or still
    # being written (.NAME.partial-XXXX) is no row of the sweep table: its point has its run
    from hmdem.sweep.table import run_directories

    for name in ("M-1_Ca-2_s0", "M-1_Ca-2_s0.unsaved-ab12", ".M-1_Ca-3_s0.partial-cd34"):
        (tmp_path / name).mkdir()
        for f in ("summary.json", "config.toml"):
            (tmp_path / name / f).write_text("")
    assert run_directories(tmp_path) == [tmp_path / "M-1_Ca-2_s0"]


def test_a_stopped_sweeps_diagram_shows_its_points_not_run(tmp_path, monkeypatch):
    # a new-user pass: after Ctrl-C at 19 of 90 runs the diagram read "19 runs", its finished
    # cells stretched over the grid points that never ran
    import importlib

    importlib.import_module("hmdem.plots")  # first: it silences Debian's Axes3D warning
    import matplotlib.figure

    from hmdem.sweep.phase_diagram import plot_phase_diagram

    saved = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, path, **kw: saved.append(fig))
    rows = [{"log_m": m, "log_ca_star": c, "status": "breakthrough", "regime": "capillary fingering",
             "fractal_dimension": 1.8, "peak_compression": 0.01, "ca": "", "ca_star": 10.0 ** c}
            for m, c in ((-5.0, -8.0), (-5.0, -6.0))]
    planned = [(m, c) for m in (-5.0, 2.0) for c in (-8.0, -6.0)]
    plot_phase_diagram(tmp_path / "d.png", rows, None, planned)
    ax = saved[0].axes[0]
    assert ax.get_title().startswith("Lenormand phase diagram: 2 of 4 runs")
    assert sorted(t.get_position() for t in ax.texts if t.get_text() == "not run") == [(2.0, -8.0), (2.0, -6.0)]
    assert ax.get_xlim() == (-8.5, 5.5)  # cells half a spacing beyond both planned columns
    # `collect` on a sweep directory takes the plan from its manifest (review); yade-batch's has none
    from hmdem.sweep.manifest import planned_runs

    points = lenormand_points(parse_axis("-5:2:2"), parse_axis("-8:-6:2"), seeds=2)
    Manifest.open(tmp_path / "sweep", {"log_m": "-5:2:2"}, points)
    assert sorted(planned_runs(tmp_path / "sweep")) == sorted([(p.log_m, p.log_ca_star) for p in points])
    assert len(points) == 8 and planned_runs(tmp_path) is None


def test_a_workers_warnings_name_the_run_directory_in_the_sweep(packing, capsys):
    # a new-user pass: the p/K warning of a sweep point named the worker's scratch copy
    # (/tmp/hmdem-sweep-.../<run id>), gone by the time it was read. M = 1e-5, Ca* = 10 on the
    # tiny packing reaches p/K 0.55 in about a second
    point = SweepPoint(-5.0, 1.0, 0)
    kept = f"runs/lenormand/runs/{point.run_id}"  # the client's run directory
    summary, _ = run_packed(point, packing.read_bytes(), str(packing), shown_as=kept)
    assert not summary["weakly_compressible"]
    err = capsys.readouterr().err
    assert f"warning: {kept}: a domain's pressure" in err and "hmdem-sweep-" not in err


def test_scratch_directories_of_stopped_workers_are_removed(tmp_path):
    # a new-user pass: each Ctrl-C of a sweep left its workers' scratch directories in /tmp
    import subprocess as sp

    from hmdem.sweep.packed import SCRATCH_PREFIX, remove_orphaned_scratch, scratch_prefix

    ended = int(sp.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                       text=True).stdout)
    gone, alive = tmp_path / f"{scratch_prefix(ended)}abc", tmp_path / f"{scratch_prefix()}def"
    # not ours to judge: no process id; another host's (process ids mean nothing there)
    others = [tmp_path / f"{SCRATCH_PREFIX}oldstyle", tmp_path / f"{SCRATCH_PREFIX}otherhost-{ended}-ghi"]
    for d in (gone, alive, *others):
        (d / "run").mkdir(parents=True)
    remove_orphaned_scratch(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name] + [d.name for d in others])
