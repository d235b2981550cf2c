"""ParaView time series (``--snapshots N``, hmdem/snapshots.py)."""

import json
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from hmdem.hele_shaw import main
from hmdem.snapshots import SnapshotRecorder, read_collection as collection


class FakeModel:
    """Front progress from a list, one value per step."""

    def __init__(self, fractions):
        self.fractions = iter(fractions)

    def fraction_done(self, state):
        return next(self.fractions)

    def grain_snapshot(self):
        return {"points": np.zeros((3, 2)), "pipe_aperture": np.ones(2), "pipe_opened": np.array([True, False])}


def test_recorder_keeps_one_snapshot_per_multiple_passed():
    fractions = [0.1, 0.3, 0.3, 0.8, 0.99, 1.0]
    model, recorder = FakeModel(fractions), SnapshotRecorder(4)
    for step, _ in enumerate(fractions):
        state = SimpleNamespace(t=float(step), pressure=np.zeros(2), saturation=np.zeros(2), invasion_time=np.zeros(2))
        recorder(model, state)
    # 0.3 passes 1/4; 0.8 passes 2/4 and 3/4 at once (kept once); 1.0 passes 4/4
    assert [s.t for s in recorder.taken] == [1.0, 3.0, 5.0]
    assert recorder.taken[0].pipe_opened.tolist() == [True, False]  # the grains' fields come along
    with pytest.raises(ValueError):
        SnapshotRecorder(0)


def test_linear_run_writes_the_series_up_to_breakthrough(tmp_path):
    out = tmp_path / "chen"
    assert main(["linear", "--case", "chen", "--snapshots", "4", "--out", str(out), "--quiet"]) == 0
    series = collection(out / "domains.pvd")
    summary = json.loads((out / "summary.json").read_text())
    assert len(series) == 4 and not (out / "contacts.pvd").exists()  # fixed grains: no contact mesh
    times = [t for t, _ in series]
    assert np.all(np.diff(times) > 0) and times[-1] == summary["breakthrough_time_s"]
    invaded = [np.sum(meshio.read(f).cell_data["saturation"][0] >= 1.0) for _, f in series]
    assert np.all(np.diff(invaded) > 0)  # the front advances from one snapshot to the next
    final = meshio.read(out / "domains.vtu")
    np.testing.assert_array_equal(meshio.read(series[-1][1]).cell_data["pressure"][0],
                                  final.cell_data["pressure"][0])
    # each grain centre carries its radius, for ParaView's glyphs (a new-user pass); chen's lattice discs are 0.25 mm
    np.testing.assert_allclose(final.point_data["radius"], np.full(len(final.points), 0.25e-3))


def test_interrupted_run_closes_the_series_with_its_last_state(tmp_path, interrupt_after):
    interrupt_after(20)
    out = tmp_path / "cut"
    assert main(["linear", "--case", "vf", "--snapshots", "10", "--out", str(out), "--quiet"]) == 130
    series = collection(out / "domains.pvd")
    summary = json.loads((out / "summary.json").read_text())
    assert series and series[-1][0] == summary["simulated_time_s"]
    assert all(f.is_file() and f.parent == out / "snapshots" for _, f in series)


@pytest.mark.yade
def test_radial_run_writes_deforming_domains_and_the_contacts(tmp_path):
    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--max-steps", "20", "--snapshots", "1000", "--out", str(out),
                 "--quiet"]) == 0
    domains, contacts = collection(out / "domains.pvd"), collection(out / "contacts.pvd")
    assert len(domains) == len(contacts) >= 2
    assert [t for t, _ in domains] == [t for t, _ in contacts]
    fractures = np.load(out / "fractures.npz")
    first, last = meshio.read(contacts[0][1]), meshio.read(contacts[-1][1])
    # the series ends on the run's final grains, apertures and opened contacts
    np.testing.assert_array_equal(last.points[:, :2], fractures["positions"])
    np.testing.assert_array_equal(last.cell_data["aperture"][0], fractures["aperture"])
    np.testing.assert_array_equal(last.cell_data["opened"][0].astype(bool), fractures["opened"])
    assert np.abs(first.points - last.points).max() > 0.0  # the grains moved between snapshots
    assert meshio.read(domains[-1][1]).points.shape == last.points.shape
    # read back frame by frame: the final saturation is state.npz's, the final apertures fractures.npz's
    from hmdem.coupling.output import fracture_resistance_series
    from hmdem.snapshots import read_series

    n_domains = len(np.load(out / "network.npz")["domain_volume"])
    frames = list(read_series(out, n_domains))
    assert [t for t, *_ in frames] == [t for t, _ in domains]
    t, saturation, aperture, opened = frames[-1]
    np.testing.assert_array_equal(saturation, np.load(out / "state.npz")["saturation"])
    np.testing.assert_array_equal(aperture, fractures["aperture"])
    assert len(fracture_resistance_series(out)) == len(frames)


def test_series_needs_snapshots(tmp_path):
    from hmdem.snapshots import read_series

    with pytest.raises(FileNotFoundError, match="--snapshots"):
        next(read_series(tmp_path, 3))
