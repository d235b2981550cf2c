"""YADE is really there: the disc adapter reproduces digest §15.1 and a packing step runs."""

import numpy as np
import pytest

from hmdem.yade_env import import_yade


@pytest.mark.yade
def test_disc_materials_give_constant_stiffness_and_disc_mass():
    import_yade()
    from yade import O

    from hmdem.dem.discs import add_disc, disc_material

    O.reset()
    ids = []
    for x, r in ((0.0, 13e-6), (34.6e-6, 21.6e-6)):
        mat = O.materials.append(disc_material(r, 7.49e7, 1.0, 0.6, 2650.0))
        ids.append(add_disc(x, 0.0, r, mat))
    for i, r in zip(ids, (13e-6, 21.6e-6)):
        b = O.bodies[i]
        assert b.state.mass == pytest.approx(2650 * np.pi * r**2 * 1.0, rel=1e-12)  # disc mass, 1 m thick
        assert b.state.inertia[0] == pytest.approx(0.5 * b.state.mass * r**2, rel=1e-12)
    # k_n = 2 E1 R1 E2 R2 / (E1 R1 + E2 R2) = k for any radius pair (digest §15.1)
    e1r1 = O.materials[O.bodies[ids[0]].material.id].young * 13e-6
    e2r2 = O.materials[O.bodies[ids[1]].material.id].young * 21.6e-6
    assert 2 * e1r1 * e2r2 / (e1r1 + e2r2) == pytest.approx(7.49e7, rel=1e-12)
    O.reset()


@pytest.mark.yade
def test_yade_generates_a_small_planar_packing():
    from hmdem.dem.packing import generate_packing
    from hmdem.network import build_contact_network

    pk = generate_packing(n=150, box=(0.02, 0.02), mean_radius=0.8e-3, porosity=0.15, seed=7,
                          growth_stages=20, cycles_per_stage=200, relax_cycles=1000)
    assert len(pk.radii) == 150
    assert pk.porosity == pytest.approx(0.15, abs=1e-9)  # radii are set from the porosity
    assert np.all((pk.centres > 0) & (pk.centres < 0.02))  # the walls held
    net = build_contact_network(pk.centres, pk.radii, pk.contacts)
    assert net.euler_characteristic() == 2 and net.n_domains > 100


@pytest.mark.yade
def test_shipped_packing_is_reproduced_by_its_command(tmp_path):
    # `make packing` (python -m hmdem.dem.packing, seed 0) regenerates the shipped file exactly
    from hmdem.dem.packing import main
    from hmdem.scenario import load_packing

    out = tmp_path / "p.npz"
    assert main(["--out", str(out)]) == 0
    new, shipped = load_packing(out), load_packing()
    np.testing.assert_array_equal(new.centres, shipped.centres)
    np.testing.assert_array_equal(new.contacts, shipped.contacts)


@pytest.mark.parametrize("args,flag", [
    (["--n", "0"], "--n"),
    (["--size", "-1"], "--size"),
    (["--porosity", "-0.1"], "--porosity"),
    (["--porosity", "0.05"], "--porosity"),  # denser than the hexagonal packing's 0.0931
    (["--spread", "1"], "--spread"),
    (["--mean-radius", "0.01"], "--mean-radius"),  # 12 discs in the 65 mm box
    (["--mean-radius", "1e-7"], "--mean-radius"),  # 1.2e11 discs: a numpy MemoryError before
    (["--n", "1000000000000"], "--n"),
    (["--n", "100", "--mean-radius", "1e-3"], "--mean-radius"),
    (["--seed", "-1"], "--seed"),
    (["--out", "p"], "--out"),  # numpy would write p.npz
    (["--out", "kept.npz"], "--out"),  # exists, no --overwrite
])
def test_packing_bad_input_is_one_line_exit_2_nothing_written(tmp_path, monkeypatch, capsys, args, flag):
    # a new-user pass: these gave numpy tracebacks, or were accepted (--porosity -0.1)
    from hmdem.dem.packing import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "kept.npz").write_bytes(b"keep")
    with pytest.raises(SystemExit) as exc:
        main(args if "--out" in args else [*args, "--out", "p.npz"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"python -m hmdem.dem.packing: {flag}")
    assert [p.name for p in tmp_path.iterdir()] == ["kept.npz"] and (tmp_path / "kept.npz").read_bytes() == b"keep"


def test_mean_radius_gives_the_shipped_packings_count():
    # n = (1 - porosity) W^2 / (pi r^2 (1 + spread^2 / 3)), E[r^2] of radii r U[1 - spread, 1 + spread]
    from hmdem.dem.packing import grain_count_for
    from hmdem.scenario import load_packing

    pk = load_packing()
    assert grain_count_for(pk.radii.mean(), 0.05, pk.porosity, pk.box[0]) == len(pk.radii) == 1188


@pytest.mark.yade
def test_shipped_huang_sample_is_reproduced_by_its_command(tmp_path):
    # `make huang-packing` (python -m hmdem.dem.compaction, seed 0) regenerates the shipped file
    from hmdem.coupling.radial import default_huang_packing_path
    from hmdem.dem.compaction import main
    from hmdem.network.packing import DiscPacking

    out = tmp_path / "h.npz"
    assert main(["--out", str(out)]) == 0
    new, shipped = DiscPacking.load(out), DiscPacking.load(default_huang_packing_path())
    np.testing.assert_array_equal(new.centres, shipped.centres)
    np.testing.assert_array_equal(new.fixed, shipped.fixed)
    assert shipped.confining_stress == pytest.approx(0.14e6, rel=0.005)
    assert len(shipped.radii) == 1395 and shipped.radii.min() >= 13e-6 and shipped.radii.max() <= 21.6e-6


@pytest.mark.yade
def test_thread_count_cannot_change_once_yade_runs():
    # OpenMP reads OMP_NUM_THREADS once, when YADE loads: asking for another count later must
    # fail loudly rather than run silently on the old one
    yade = import_yade()
    running = yade.O.numThreads
    assert import_yade(running) is yade
    with pytest.raises(RuntimeError, match="OpenMP thread"):
        import_yade(running + 1)


def test_collider_threads_keep_every_chunk_inside_the_bounds_list():
    # the paper-size sample's 1,395 discs have 2,790 bounds per axis. At 41 chunks of
    # 2790 // 41 + 1 = 69 the last starts at 40 x 69 = 2,760, 30 bounds from the end: under
    # half a chunk. At 40 chunks of 70 it starts at 2,730, 60 from the end. 63 chunks of 45
    # start the last at 2,790, the end itself (what aborted: test_cli.py)
    from hmdem.dem.discs import collider_threads

    assert collider_threads(1395, 64) == 40
    assert collider_threads(1395, 40) == 40
    assert collider_threads(1395, 2) == 2
    assert collider_threads(1395, 1) == 1
    # 2,000 bounds: 35 chunks of 58 leave the last 28, under half of 58; 34 of 59 leave 53
    assert collider_threads(1000, 64) == 34


@pytest.mark.yade
def test_a_compaction_that_does_not_settle_says_so():
    # the servo ran its whole cycle budget and wrote the sample as it stood (a new-user pass:
    # --stress 1 gave a packing with 0 Pa on every wall); 100 cycles cannot bring 50 loose
    # discs to 0.14 MPa
    from hmdem.dem.compaction import CompactionNotSettled, compact_sample

    with pytest.raises(CompactionNotSettled, match="did not settle at 140000 Pa within 100 cycles"):
        compact_sample(50, 4e-4, max_cycles=100)
