"""Command line and run-directory contract of ``python -m hmdem.hele_shaw`` (issue 2)."""

import hashlib
import json
import os
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import popen_interruptible
from hmdem.coupling.radial import default_huang_packing_path
from hmdem.hele_shaw import main

CMD = [sys.executable, "-m", "hmdem.hele_shaw"]
DATA = Path(__file__).resolve().parent.parent / "hmdem" / "data"


@pytest.mark.parametrize("module,args,prefix", [
    ("hmdem.calibrate", ["biaxial", "--sigma", "1e5"], "--sigma"),  # --sigma3; radial's --sigma is another option
    ("hmdem.hele_shaw", ["linear", "--visc", "1e-3"], "--visc"),
    ("hmdem.sweep", ["lenormand", "--work", "2"], "--work"),
    ("hmdem.dem.compaction", ["--overw"], "--overw"),
    ("sph_bridge", ["droplet", "--grav", "0"], "--grav"),
    ("sph_bridge", ["lga", "poiseuille", "--mirr"], "--mirr"),
    ("hmdem.wet", ["bridge", "--vol", "1e-15"], "--vol"),
])
def test_a_prefix_of_an_option_is_refused(tmp_path, module, args, prefix):
    # a new-user pass: argparse took --sigma for calibrate's --sigma3, silently. The --out exists,
    # so the old code refused that instead, at once and with another message
    out = tmp_path / ("p.npz" if module == "hmdem.dem.compaction" else "run")
    out.write_text("kept")
    proc = subprocess.run([sys.executable, "-m", module, *args, "--out", str(out)], capture_output=True, text=True,
                          cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and f"unrecognized arguments: {prefix}" in err[0]
    assert list(tmp_path.iterdir()) == [out] and out.read_text() == "kept"


@pytest.mark.parametrize("args,name", [
    (["linear", "--viscosity-ratio", "-1"], "--viscosity-ratio"),
    (["linear", "--viscosity-ratio", "0"], "--viscosity-ratio"),
    (["linear", "--rate", "nan"], "--rate"),
    (["linear", "--mean-aperture", "-0.1"], "--mean-aperture"),
    (["linear", "--ca-star", "inf"], "--ca-star"),
    (["linear", "--dt", "0"], "--dt"),
    (["linear", "--case", "nope"], "--case"),
    (["linear", "--seed", "-3"], "--seed"),
    # single phase: an invading viscosity would be recorded in config.toml and used nowhere
    (["linear", "--case", "darcy", "--viscosity-ratio", "5"], "--viscosity-ratio"),
    (["radial", "--case", "A2"], "--case"),
    (["radial", "--viscosity-ratio", "-5"], "--viscosity-ratio"),
    (["radial", "--ca-star", "nan"], "--ca-star"),
    (["radial", "--dem-cycles", "0"], "--dem-cycles"),
    (["radial", "--threads", "0"], "--threads"),
    (["radial", "--pv-tol", "1"], "--pv-tol"),
    (["radial", "--pv-reuse-steps", "-1"], "--pv-reuse-steps"),
    (["radial", "--pv-max-columns", "0"], "--pv-max-columns"),
    (["radial", "--damping", "1"], "--damping"),
    (["radial", "--grain-density", "0"], "--grain-density"),
    (["radial", "--contact-gap", "-0.1"], "--contact-gap"),
    (["radial", "--friction", "-0.1"], "--friction"),
    (["radial", "--stiffness-ratio", "0"], "--stiffness-ratio"),
    # counts are whole numbers: 1.5 is refused, not cut down to 1
    (["linear", "--max-steps", "1.5"], "--max-steps"),
    (["radial", "--max-steps", "2.7"], "--max-steps"),
    (["radial", "--dem-cycles", "1.5"], "--dem-cycles"),
    (["radial", "--pv-max-iter", "2.5"], "--pv-max-iter"),
    (["radial", "--pv-grow-after", "0.5"], "--pv-grow-after"),
    # a file that is not a packing: one line, before YADE or the run directory
    (["radial", "--packing", __file__], "--packing"),
    (["linear", "--packing", __file__], "--packing"),
    # packings of the other kind (a new-user pass): the Huang sample's 34 um grains under the
    # Lenormand 0.42 mm apertures; an uncompacted packing with no contact forces for Eqs. 13-14;
    # a lattice case takes none; an aperture in the wrong unit
    (["linear", "--packing", str(DATA / "huang_packing.npz")], "--packing"),
    (["radial", "--packing", str(DATA / "lenormand_packing.npz")], "--packing"),
    (["linear", "--case", "chen", "--packing", str(DATA / "lenormand_packing.npz")], "--packing"),
    (["linear", "--mean-aperture", "0.5"], "--mean-aperture"),
    # a new-user pass: a directory; a near-contact gap of 50 radii ran
    (["radial", "--packing", str(DATA)], "--packing"),
    (["radial", "--contact-gap", "1.01"], "--contact-gap"),
    # a new-user pass: M = 1e300 scaled the step to 3e303 s and the plot overflowed at the end;
    # with sd's Ca* it ran for ever with nothing invaded (another pass): M and Ca* keep to the
    # sweep's bounds, where the runs were measured to reach breakthrough (decisions #77, #78)
    (["linear", "--case", "vf", "--viscosity-ratio", "1e300"], "--viscosity-ratio"),
    (["linear", "--case", "sd", "--viscosity-ratio", "1e300"], "--viscosity-ratio"),
    (["linear", "--case", "sd", "--viscosity-ratio", "2e6"], "--viscosity-ratio"),
    (["linear", "--ca-star", "1e5"], "--ca-star"),
    (["radial", "--viscosity-ratio", "1e-7"], "--viscosity-ratio"),
    (["radial", "--ca-star", "1e-11"], "--ca-star"),
    # a new-user pass: --dt 1e200 made the pressure matrix singular (a step never exceeds the
    # time the pores take to fill: vf 44 s, B3 2.5 ms); darcy ran at --ca-star's rate; a seed past
    # 64 bits was written as a Python object into the packing file and into config.toml
    (["linear", "--dt", "1e200"], "--dt"),
    (["radial", "--case", "B3", "--dt", "1"], "--dt"),
    (["linear", "--case", "darcy", "--ca-star", "1e-3"], "--ca-star"),
    (["linear", "--seed", str(2**63)], "--seed"),
])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, args, name):
    out = tmp_path / "run"
    proc = subprocess.run(CMD + args + ["--out", str(out)], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and name in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_packing_contacts_out_of_its_discs_are_named_as_such(tmp_path, capsys):
    # a new-user pass: contacts past the disc count were reported as "not edges of the Delaunay
    # triangulation: a grain sits in the throat"
    from hmdem.network.packing import DiscPacking

    pk = DiscPacking.load(DATA / "lenormand_packing.npz")
    DiscPacking(pk.centres, pk.radii, pk.contacts + len(pk.radii), pk.box, 0).save(tmp_path / "bad.npz")
    assert main(["linear", "--packing", str(tmp_path / "bad.npz"), "--out", str(tmp_path / "run")]) == 2
    assert f"its contacts must be pairs of disc indices from 0 to {len(pk.radii) - 1}" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_a_packing_whose_discs_do_not_touch_is_not_written(tmp_path):
    # a new-user pass: packing --porosity 0.5 wrote 1,188 discs with one contact, exit 0; every
    # run then refused the file. The same grains spread over a box three times as wide: no network
    from hmdem.cli import InputError
    from hmdem.dem.packing import check_network
    from hmdem.network.packing import DiscPacking

    pk = DiscPacking.load(DATA / "lenormand_packing.npz")
    check_network(pk, 0.117)  # the shipped packing has its network
    loose = DiscPacking(3.0 * pk.centres, pk.radii, pk.contacts[:0], (3.0 * pk.box[0], 3.0 * pk.box[1]), 0)
    with pytest.raises(InputError, match=r"^--porosity: at 0\.9 the 1188 discs make 0 contact"):
        check_network(loose, 0.9)


def test_out_through_a_file_is_refused_before_the_run(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert main(["radial", "--case", "B3", "--out", str(tmp_path / "file" / "run")]) == 2
    assert "--out" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["file"]


def test_out_at_a_dangling_link_is_refused_before_the_run(tmp_path, capsys):
    # a new-user pass: a symbolic link to nothing passed the check (Path.exists follows links),
    # the run went to its end, and renaming it onto the link failed with a traceback
    (tmp_path / "link").symlink_to(tmp_path / "nowhere")
    assert main(["linear", "--case", "darcy", "--max-steps", "3", "--out", str(tmp_path / "link")]) == 2
    assert "already exists" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["link"]


def test_out_where_nothing_can_be_written_is_refused_before_the_run(capsys):
    # /proc takes no new directories, for root too: a run must not find that out at its end
    assert main(["linear", "--case", "vf", "--out", "/proc/hmdem-test/run"]) == 2
    assert capsys.readouterr().err.startswith("python -m hmdem.hele_shaw: --out: cannot write under '/proc'")


@pytest.mark.parametrize("value", ["-1e-4", "-2.5E+3", "-.5"])
def test_a_negative_number_in_any_notation_gets_the_options_own_message(value, capsys):
    # argparse takes "-1e-4" for an option ("expected one argument"); the options' checks say
    # what is allowed instead
    with pytest.raises(SystemExit) as exc:
        main(["linear", "--ca-star", value, "--out", "unused"])
    assert exc.value.code == 2
    assert capsys.readouterr().err.strip() == (f"python -m hmdem.hele_shaw: --ca-star: must be a number in "
                                               f"[1e-10, 1e4] (where runs were measured to reach breakthrough), "
                                               f"got {value!r}")


@pytest.mark.parametrize("flags, message", [
    (["--rate", "1e30"], "--rate 1e+30: must give a Ca* (Eq. 24) in [1e-10, 1e4], --ca-star's range; these give 2.14e+30"),
    (["--rate", "1e-300"], "--rate 1e-300: must give a Ca* (Eq. 24) in [1e-10, 1e4]"),
    (["--mean-aperture", "1e-12"], "--mean-aperture: must be a number >= 1e-06 m, got '1e-12'"),
])
def test_rate_and_aperture_keep_ca_star_in_its_range(tmp_path, capsys, flags, message):
    # a new-user pass: --rate went round --ca-star's bounds (1e30: a 4e-36 s step; 1e-300: 6e299 s
    # of nothing), and --mean-aperture 1e-12 gave 1 GPa entry pressures; vf's Ca* is 1.9e-4 at
    # Q = 8.9e-5 m^2/s (Eq. 24), so --rate 1e30 gives 2.14e30
    if flags[0] == "--mean-aperture":  # refused by its argparse type
        with pytest.raises(SystemExit) as exc:
            main(["linear", *flags, "--max-steps", "1", "--out", str(tmp_path / "run")])
        assert exc.value.code == 2
    else:
        assert main(["linear", *flags, "--max-steps", "1", "--out", str(tmp_path / "run")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def test_rate_inside_ca_stars_range_and_single_phase_rates_still_run(tmp_path):
    # the bound is Ca*'s, not the rate's: darcy (one fluid, no Ca*) takes any rate the fill time allows
    assert main(["linear", "--rate", "1e-4", "--max-steps", "1", "--quiet", "--out", str(tmp_path / "vf")]) == 0
    assert main(["linear", "--case", "darcy", "--rate", "1e-9", "--max-steps", "1", "--quiet",
                 "--out", str(tmp_path / "darcy")]) == 0


def test_the_write_check_leaves_nothing(tmp_path):
    # --out's write check makes and removes a probe directory where the run will go
    from hmdem.cli import new_run_directory

    assert new_run_directory(tmp_path / "a" / "run", "x") == tmp_path / "a" / "run"
    assert list(tmp_path.iterdir()) == []


def test_default_run_directories_of_concurrent_runs_differ(tmp_path, monkeypatch):
    # two runs started in the same second without --out must not race for one name
    from hmdem import cli

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cli.time, "strftime", lambda fmt: "20261129-021659")
    names = []
    for pid in (101, 102):
        monkeypatch.setattr(cli.os, "getpid", lambda pid=pid: pid)
        names.append(cli.new_run_directory(None, "darcy"))
    assert names == [Path("runs/darcy-20261129-021659-101"), Path("runs/darcy-20261129-021659-102")]


def test_a_state_file_is_not_taken_for_a_packing(tmp_path, capsys):
    np.savez(tmp_path / "state.npz", pressure=np.zeros(3), saturation=np.zeros(3))
    assert main(["radial", "--packing", str(tmp_path / "state.npz"), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "is not a packing (one holds centres, radii" in err
    # radial needs a compacted sample, so it names only the command that makes one (a new-user pass)
    assert err.rstrip().endswith("write one with python -m hmdem.dem.compaction")
    assert [p.name for p in tmp_path.iterdir()] == ["state.npz"]


def test_an_empty_out_is_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # '' is '.', which exists: the message says what --out wants
    assert main(["linear", "--out", ""]) == 2
    assert capsys.readouterr().err.strip() == "python -m hmdem.hele_shaw: --out: must name a new run directory, got '.'"
    assert list(tmp_path.iterdir()) == []


def test_config_toml_names_the_packing_by_path_and_content(tmp_path):
    # a packing given by --packing is recorded by its absolute path and the SHA-256 of its bytes,
    # so a run can be matched to its sample after the file is moved or regenerated; the command
    # is shell-quoted, so that it replays with blanks in a path (found in review)
    packing = tmp_path / "my sample.npz"
    packing.write_bytes((DATA / "lenormand_packing.npz").read_bytes())
    out = tmp_path / "my run"
    argv = ["linear", "--packing", str(packing), "--max-steps", "1", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    config = tomllib.loads((out / "config.toml").read_text())
    assert config["packing"]["file"] == str(packing.resolve())
    assert config["packing"]["sha256"] == hashlib.sha256(packing.read_bytes()).hexdigest()
    assert shlex.split(config["run"]["command"]) == ["python", "-m", "hmdem.hele_shaw", *argv]


@pytest.mark.parametrize("broken, message", [
    ("nan_centre", "non-finite centre or a radius"),
    ("zero_radius", "non-finite centre or a radius"),
    ("negative_radius", "non-finite centre or a radius"),
    ("two_discs", "at least 3 discs"),
    ("tiny_box", "its discs must lie within its box"),
    ("no_contacts", "0 inflow and 0 outflow domains"),
])
def test_a_packing_no_network_can_be_built_on_is_one_line(tmp_path, capsys, broken, message):
    # a new-user pass: NaN centres, zero radii or a loose packing ended in tracebacks (scipy's
    # Delaunay, the boundary search) and a negative radius or a box 1e-6 m wide ran silently
    from dataclasses import replace

    import numpy as np

    from hmdem.network.packing import DiscPacking

    shipped = DiscPacking.load(DATA / "lenormand_packing.npz")
    centres, radii = shipped.centres.copy(), shipped.radii.copy()
    changes = {
        "nan_centre": lambda: {"centres": np.where(np.arange(len(radii))[:, None] == 5, np.nan, centres)},
        "zero_radius": lambda: {"radii": np.zeros_like(radii)},
        "negative_radius": lambda: {"radii": np.where(np.arange(len(radii)) == 3, -1e-3, radii)},
        "two_discs": lambda: {"centres": centres[:2], "radii": radii[:2], "contacts": np.zeros((0, 2), int)},
        "tiny_box": lambda: {"box": (1e-6, 1e-6)},
        # three discs far apart: no contact, so no domain and no inflow or outflow
        "no_contacts": lambda: {"centres": np.array([[0.01, 0.01], [0.05, 0.01], [0.03, 0.05]]),
                                "radii": np.full(3, 1e-3), "contacts": np.zeros((0, 2), int)},
    }[broken]()
    replace(shipped, **changes).save(tmp_path / "broken.npz")
    assert main(["linear", "--packing", str(tmp_path / "broken.npz"), "--max-steps", "1", "--quiet",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("python -m hmdem.hele_shaw: --packing: ") and message in err[0]
    assert not (tmp_path / "run").exists()


def test_a_packing_that_is_no_regular_file_says_so(tmp_path, capsys):
    # a new-user pass: --packing /dev/null said "no such file" of a file that exists
    assert main(["linear", "--packing", "/dev/null", "--out", str(tmp_path / "run")]) == 2
    assert "--packing: '/dev/null' is not a regular file" in capsys.readouterr().err


def test_a_packing_with_a_grain_in_a_contacts_throat_is_refused(tmp_path, capsys):
    # its network would lose the contact and merge two pores (tests/test_network.py)
    from test_network import throat_packing

    throat_packing().save(tmp_path / "throat.npz")
    assert main(["linear", "--packing", str(tmp_path / "throat.npz"), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "--packing: 1 of its contacts (e.g. grains 0 and 1) is not an edge of the centres' Delaunay" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "run").exists()
    # the same with the pair 0.05 apart, listed only through its throat grains: the run's near
    # contacts (gap up to 0.08 r) add it, past the file's own check (review)
    throat_packing(gap=0.05, listed=((0, 2), (1, 2), (0, 3), (1, 3))).save(tmp_path / "near.npz")
    assert main(["linear", "--packing", str(tmp_path / "near.npz"), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "--packing: with its near contacts, 1 of its contacts (e.g. grains 0 and 1) is not an edge" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "run").exists()


def test_the_nominal_step_follows_the_rate_however_it_is_given():
    # dt x Q_case / Q without --dt, whether Q comes from --ca-star, --viscosity-ratio, --rate or
    # --mean-aperture (a new-user pass: vf at Ca* 1.9e-6 given as its --rate kept dt = 0.05 s
    # and took 20 times the steps); --dt wins
    from hmdem.hele_shaw import build_parser, make_case
    from hmdem.scenario import build_scenario

    def setup(*flags):
        return build_scenario(make_case(build_parser().parse_args(["linear", "--case", "vf", *flags]))).setup

    shipped, slower = setup(), setup("--ca-star", "1.9e-6")
    assert slower.rate == pytest.approx(shipped.rate / 100, rel=1e-12)
    assert slower.dt == pytest.approx(100 * shipped.dt, rel=1e-12)
    assert setup("--rate", repr(float(slower.rate))).dt == pytest.approx(slower.dt, rel=1e-12)
    assert setup("--viscosity-ratio", repr(2 * 1.8e-5)).dt == pytest.approx(2 * shipped.dt, rel=1e-12)
    assert setup("--mean-aperture", "0.84e-3").dt == pytest.approx(shipped.dt / 2, rel=1e-12)
    assert setup("--rate", repr(float(slower.rate)), "--dt", "0.05").dt == 0.05


def test_existing_out_is_refused(tmp_path, capsys):
    (tmp_path / "run").mkdir()
    assert main(["linear", "--out", str(tmp_path / "run")]) == 2
    assert "--out" in capsys.readouterr().err


def resident_memory_mb() -> float:
    """This process's resident memory now [MB], from /proc (VmRSS, in kB)."""
    line = next(l for l in Path("/proc/self/status").read_text().splitlines() if l.startswith("VmRSS:"))
    return int(line.split()[1]) / 1024


def test_run_directory_contract(tmp_path):
    out = tmp_path / "chen"
    resident_before = resident_memory_mb()
    assert main(["linear", "--case", "chen", "--out", str(out), "--quiet"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"config.toml", "summary.json", "timeseries.csv", "network.npz", "state.npz", "pattern.png",
            "pressure.png", "domains.vtu"} <= names
    summary = json.loads((out / "summary.json").read_text())
    for key in ("case", "regime", "fractal_dimension", "breakthrough_time_s", "breakthrough_saturation",
                "peak_injection_pressure_pa", "final_injection_pressure_pa", "injection_energy_j", "steps",
                "wall_time_s"):
        assert key in summary
    assert summary["case"] == "chen" and summary["status"] == "breakthrough"
    # Table 4's memory column: the process's peak, in MB, is at least what it held before the run
    # (a figure in kB or bytes would be 1024 times off)
    assert resident_before <= summary["peak_memory_mb"] < 1024 * resident_before
    config = tomllib.loads((out / "config.toml").read_text())
    assert config["run"]["seed"] == 0 and config["solver"]["dt"] == 0.01 and config["solver"]["inlet"] == "manifold"
    assert "packing" not in config  # a square lattice (App. D.2), no grains' file
    net = np.load(out / "network.npz")
    for key in ("domain_centroid", "domain_volume", "pipe_domains", "pipe_aperture", "pipe_length",
                "pipe_entry_pressure", "inlet_domains", "outlet_domains"):
        assert key in net.files
    assert net["domain_centroid"].shape == (1521, 2) and net["pipe_domains"].shape == (3120, 2)
    state = np.load(out / "state.npz")
    assert state["pressure"].shape == state["saturation"].shape == state["invasion_time"].shape == (1521,)
    invaded = state["saturation"] >= 1
    assert np.all(np.isfinite(state["invasion_time"][invaded])) and np.all(np.isinf(state["invasion_time"][~invaded]))
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[:7] == ["t", "dt", "p_in_mean", "q_in", "q_out", "saturation", "energy"]
    import meshio

    mesh = meshio.read(out / "domains.vtu")
    assert {"pressure", "saturation"} <= set(mesh.cell_data)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial directory left


def test_darcy_run_reports_itself_against_app_d1(tmp_path, capsys):
    # `linear --case darcy` reads its own run against Eqs. 37-38 (U16, tested on the same reading
    # in test_solver.py): k from the steady drop, the largest errors, darcy.png
    out = tmp_path / "darcy"
    assert main(["linear", "--case", "darcy", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (out / "darcy.png").is_file() and summary["darcy_within_u16"]
    errors = [summary[f"darcy_{name}_error"] for name in ("inflow_pressure", "outflow_rate", "profile")]
    assert 0 < max(errors) < 0.05 and summary["darcy_final_t_d"] > 3  # steady at the end: k is read there
    # Eq. 21 on the steady drop (H = the sample's 65 mm side, L = the inlet-outlet distance < H)
    k = summary["darcy_permeability_m2"]
    drop, rate, viscosity = summary["final_injection_pressure_pa"], summary["rate_m3_per_s_per_m"], 1.0
    assert viscosity * 0.9 * 0.065 * rate / (0.065 * drop) < k < viscosity * rate / drop
    assert "within U16's 5 %" in capsys.readouterr().out and summary["darcy_steady"]
    # stopped in the transient (t_D ~ 0.9): k read on its last drop would be too high (1.6e-9), so
    # it is not read, and the command says so
    short = tmp_path / "short"
    assert main(["linear", "--case", "darcy", "--t-max", "1e-3", "--out", str(short), "--quiet"]) == 0
    summary = json.loads((short / "summary.json").read_text())
    assert not summary["darcy_steady"] and not summary["darcy_within_u16"] and not (short / "darcy.png").exists()
    assert summary["darcy_permeability_m2"] is None and summary["darcy_profile_error"] is None
    assert "not steady" in capsys.readouterr().out


def test_an_out_taken_during_the_run_keeps_the_results_beside_it(tmp_path, capsys):
    # another process makes --out while a run runs: the finished run is neither lost nor merged
    # into it, but kept as <out>.unsaved-XXXX, and the error names that directory
    from hmdem.rundir import RunDirectoryTaken, atomic_run_directory

    out = tmp_path / "run"
    with pytest.raises(RunDirectoryTaken, match="unsaved") as taken:
        with atomic_run_directory(out) as tmp:
            (tmp / "summary.json").write_text("{}")
            out.mkdir()
            (out / "theirs.txt").write_text("another run's file")
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("run.unsaved-")]
    assert len(kept) == 1 and str(kept[0]) in str(taken.value) and (kept[0] / "summary.json").exists()
    assert sorted(p.name for p in out.iterdir()) == ["theirs.txt"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no partial directory left
    # through a command: one line naming --out and the kept directory, exit status 2
    import argparse

    from hmdem.cli import dispatch

    def command(args):
        with atomic_run_directory(tmp_path / "second"):
            (tmp_path / "second").mkdir()
            (tmp_path / "second" / "theirs.txt").write_text("")
        return 0

    assert dispatch("prog", argparse.ArgumentParser(), argparse.Namespace(command="run"), {"run": command}) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("prog: --out:") and "second.unsaved-" in lines[0]


def test_a_packing_file_made_during_the_run_is_kept(tmp_path):
    # a packing takes minutes: --out is checked new at the start, and a file another process
    # writes there meanwhile is neither replaced nor lost; the new packing is kept beside it
    from hmdem.rundir import RunDirectoryTaken, replaced_atomically

    out = tmp_path / "packing.npz"
    with pytest.raises(RunDirectoryTaken, match="unsaved") as taken:
        with replaced_atomically(out, keep_existing=True) as tmp:
            tmp.write_text("ours")
            out.write_text("theirs")
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("packing.unsaved-")]
    assert len(kept) == 1 and kept[0].suffix == ".npz" and str(kept[0]) in str(taken.value)
    assert kept[0].read_text() == "ours" and out.read_text() == "theirs"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["packing.npz", kept[0].name])  # no temporary
    fresh = tmp_path / "fresh.npz"
    with replaced_atomically(fresh, keep_existing=True) as tmp:
        tmp.write_text("new")
    assert fresh.read_text() == "new" and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_run_directories_and_replaced_files_follow_the_umask(tmp_path):
    # mkdtemp / mkstemp would leave them private (0o700 / 0o600): a group could not read a run
    import stat

    from hmdem.rundir import atomic_run_directory, write_text_atomic
    from hmdem.sweep.packed import pack_directory, unpack_directory

    umask = os.umask(0o027)
    try:
        with atomic_run_directory(tmp_path / "run") as tmp:
            (tmp / "summary.json").write_text("{}")
        write_text_atomic(tmp_path / "manifest.json", "{}")
        unpack_directory(pack_directory(tmp_path / "run"), tmp_path / "from_a_worker")  # a sweep's Dask path
    finally:
        os.umask(umask)
    assert stat.S_IMODE((tmp_path / "run").stat().st_mode) == 0o750
    assert stat.S_IMODE((tmp_path / "from_a_worker").stat().st_mode) == 0o750
    assert stat.S_IMODE((tmp_path / "manifest.json").stat().st_mode) == 0o640


def test_dispatch_exit_status_names_the_signal_and_restores_the_handler():
    # SIGTERM inside a command: 128 + 15; the handler before dispatch is back afterwards, and
    # the next command's Ctrl-C is 130 again (no signal carried over)
    import argparse
    import signal

    from hmdem.cli import dispatch

    def terminated(args):
        signal.raise_signal(signal.SIGTERM)

    def ctrl_c(args):
        raise KeyboardInterrupt

    before = signal.getsignal(signal.SIGTERM)
    parser, args = argparse.ArgumentParser(), argparse.Namespace(command="run")
    assert dispatch("prog", parser, args, {"run": terminated}) == 143
    assert signal.getsignal(signal.SIGTERM) is before
    assert dispatch("prog", parser, args, {"run": ctrl_c}) == 130


@pytest.mark.parametrize("where", ["hmdem.report.write_vtu", "hmdem.report.summarize"])
def test_a_signal_while_a_finished_run_is_written_keeps_the_run(tmp_path, monkeypatch, capsys, where):
    # a new-user pass: a batch system's SIGTERM (or a Ctrl-C) landing while a finished run was
    # summarised or written threw the whole run away ("the results in progress were not
    # written", no directory). It is now held until the directory is complete: exit 143, the
    # directory whole with the run's own status, and the message names it
    import signal

    import hmdem.report as report

    name = where.rsplit(".", 1)[1]
    original = getattr(report, name)

    def signalled(*args, **kwargs):
        signal.raise_signal(signal.SIGTERM)
        return original(*args, **kwargs)

    monkeypatch.setattr(report, name, signalled)
    out = tmp_path / "run"
    assert main(["linear", "--case", "darcy", "--max-steps", "3", "--quiet", "--out", str(out)]) == 143
    assert f"{str(out)!r} was written whole" in capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text())["status"] == "max_steps"
    assert {"config.toml", "timeseries.csv", "state.npz", "domains.vtu", "pattern.png"} <= {f.name for f in out.iterdir()}
    assert not list(tmp_path.glob(".run.partial-*"))


def test_a_signal_held_on_top_of_an_error_still_names_the_error(capsys):
    # review: a SIGTERM held while a finished run was being renamed was delivered on top of the
    # RunDirectoryTaken that named where the run had been kept, and only "not written" was said
    import argparse
    import signal

    from hmdem.cli import dispatch
    from hmdem.interrupts import deferred_interrupts
    from hmdem.rundir import RunDirectoryTaken

    def taken(args):
        with deferred_interrupts():
            signal.raise_signal(signal.SIGTERM)
            raise RunDirectoryTaken("--out: 'x' was created by another process during the run; this run's "
                                    "results are in 'x.unsaved-1'")

    assert dispatch("prog", argparse.ArgumentParser(), argparse.Namespace(command="run"), {"run": taken}) == 143
    assert "prog: --out: 'x' was created by another process during the run; this run's results are in " \
           "'x.unsaved-1'" in capsys.readouterr().err


def test_interrupt_outside_a_runs_steps_is_one_line_and_status_130(capsys):
    # e.g. Ctrl-C while YADE settles the sample, before the first step: no traceback
    import argparse

    from hmdem.cli import dispatch

    def command(args):
        raise KeyboardInterrupt

    assert dispatch("prog", argparse.ArgumentParser(), argparse.Namespace(command="run"), {"run": command}) == 130
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("prog: interrupted")


def test_interrupted_run_leaves_valid_directory(tmp_path, interrupt_after):
    # Ctrl-C mid-run: the run directory is still complete, with status "interrupted"
    interrupt_after(20)
    out = tmp_path / "cut"
    assert main(["linear", "--case", "vf", "--out", str(out), "--quiet"]) == 130
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] == 20
    # a partial pattern gets no Lenormand regime (decisions #76), though D_f is measured on it
    assert summary["regime"] == "undetermined" and summary["fractal_dimension"] > 0
    assert (out / "pattern.png").stat().st_size > 0


def test_max_steps_cut_linear_run_has_no_regime(tmp_path):
    # `chen --max-steps 3` used to say "viscous fingering" at D_f 0.003 (a new-user pass)
    out = tmp_path / "chen"
    assert main(["linear", "--case", "chen", "--max-steps", "3", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "max_steps" and summary["regime"] == "undetermined"


def test_explicit_scheme_runs_and_agrees_early(tmp_path):
    # seed004 App. C: the explicit reference scheme; over a short window both schemes give the
    # same injection pressure rise (the implicit one with a step 1e3 x larger).
    from hmdem.cases import CASES
    from hmdem.flow.simulation import FlowModel
    from hmdem.scenario import build_scenario

    results = {}
    for scheme, dt in (("explicit", 1.0), ("implicit", 2e-7)):
        sc = build_scenario(CASES["vf"], scheme=scheme)
        sc.setup.dt, sc.setup.t_max = dt, 2e-6
        state, rec = FlowModel(sc.net, sc.setup).run()
        results[scheme] = (rec.rows[-1][2], rec.steps)
    (p_ex, n_ex), (p_im, n_im) = results["explicit"], results["implicit"]
    assert n_ex >= 5 * n_im
    assert p_im == pytest.approx(p_ex, rel=0.05)


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_real_signal_leaves_valid_partial_directory(tmp_path, signal_name):
    # a user's Ctrl-C (SIGINT) or a batch scheduler's SIGTERM mid-run: exit 128 + the signal (the
    # shell's convention: 130, 143) and a complete run directory marked interrupted
    import signal
    import time

    out = tmp_path / "cf1"
    proc = popen_interruptible(CMD + ["linear", "--case", "cf1", "--out", str(out)])
    deadline = time.time() + 60
    while time.time() < deadline:  # wait for the time loop to start (the progress bar shows steps)
        line = proc.stderr.readline()
        if "steps=" in line or proc.poll() is not None:
            break
    time.sleep(1.0)
    proc.send_signal(getattr(signal, signal_name))
    proc.communicate(timeout=120)
    assert proc.returncode == {"SIGINT": 130, "SIGTERM": 143}[signal_name]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] > 0
    assert np.load(out / "state.npz")["pressure"].shape == (summary["n_domains"],)
    assert (out / "domains.vtu").stat().st_size > 0


@pytest.mark.yade
def test_radial_run_directory_contract(tmp_path):
    # a few B3 steps on the shipped Huang sample: the linear contract plus fractures.npz, the
    # force-chain picture and the movable-grain summary keys (issue 3)
    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--max-steps", "12", "--out", str(out), "--quiet"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"config.toml", "summary.json", "timeseries.csv", "network.npz", "state.npz", "pattern.png",
            "pressure.png", "domains.vtu", "fractures.npz", "force_chains.png", "fractures.png"} <= names
    summary = json.loads((out / "summary.json").read_text())
    for key in ("n_opened_contacts", "peak_injection_pressure_pa", "regime", "mean_pv_iterations", "dem_cycles",
                "lowest_path_resistance_gpa_s_per_m2", "dissipated_fraction", "pv_pocket_attempts"):
        assert key in summary
    # Huang's regimes are read at breakthrough; 12 steps is a partial pattern (decisions #76)
    assert summary["status"] == "max_steps" and summary["regime"] == "undetermined"
    assert "fractal_dimension_box_counting" in summary  # App. E's figure beside the sandbox one
    assert 0.0 < summary["fracture_fractal_dimension"] < 2.0  # H5's fracture zone: a few cracks by now
    assert summary["steps"] == 12 and summary["max_mass_balance_error"] < 1e-10
    fractures = np.load(out / "fractures.npz")
    assert fractures["opened"].sum() == summary["n_opened_contacts"]
    # each opened contact has the time it opened, within the run; the others have none. The
    # chronology keys count what the run directory's own arrays say (decisions #48)
    opened, opened_time = fractures["opened"], fractures["opened_time"]
    assert opened.sum() > 0 and np.array_equal(np.isfinite(opened_time), opened)
    assert np.all(opened_time[opened] <= summary["simulated_time_s"])
    assert summary["first_opening_time_s"] == opened_time[opened].min()
    pipe_domains = np.load(out / "network.npz")["pipe_domains"]
    entered = np.where(pipe_domains < 0, np.inf, fractures["pore_wetted_time"][pipe_domains])
    filled = np.where(pipe_domains < 0, np.inf, np.load(out / "state.npz")["invasion_time"][pipe_domains])
    reached = opened & np.isfinite(entered).any(axis=1)
    assert summary["n_opened_reached_by_fluid"] == reached.sum() > 0
    assert summary["n_opened_before_fluid"] == np.sum(reached & (opened_time < entered.min(axis=1)))
    assert summary["n_opened_in_invaded_zone"] == np.sum(opened & np.isfinite(filled).all(axis=1))
    # the fluid's way in through the opened contacts, from the same arrays (decisions #87)
    from hmdem.coupling.micromechanics import fracture_guidance

    guidance = fracture_guidance(opened_time, pipe_domains, fractures["pore_wetted_time"],
                                 np.load(out / "state.npz")["invasion_time"], np.load(out / "network.npz")["inlet_domains"])
    assert {k: summary[k] for k in guidance} == pytest.approx(guidance, nan_ok=True)
    # the port's perimeter is the packing's (decisions #21), not the moved grains'
    net = np.load(out / "network.npz")
    port_edges = net["pipe_grains"][(net["pipe_domains"] == net["inlet_domains"][0]).any(axis=1)]
    start = fractures["initial_positions"]
    assert summary["inlet_domain_perimeter_m"] == pytest.approx(
        np.linalg.norm(start[port_edges[:, 1]] - start[port_edges[:, 0]], axis=1).sum(), rel=1e-12)
    assert fractures["positions"].shape == (1395, 2)
    # each contact's force after settling [N per m], positive for the contacts the sample starts
    # with; they carry the servo's 0.14 MPa: by the virial theorem sum f (r1 + r2) over the
    # grain contacts = 2 A sigma less the walls' share, sigma x perimeter x mean radius (2 % for
    # the servo's 0.5 % tolerance, the settling with friction on, and the wall grains' radii
    # taken as the mean; measured 0.3 %)
    initial, closed = fractures["initial_contact_force"], fractures["initially_closed"]
    assert initial.shape == opened.shape and np.all(initial[closed] > 0.0)
    radii, grains = fractures["radii"], fractures["pipe_grains"]
    width, height = np.load(default_huang_packing_path())["box"]
    virial = np.sum(initial[closed] * (radii[grains[closed, 0]] + radii[grains[closed, 1]]))
    assert virial == pytest.approx(0.14e6 * (2 * width * height - 2 * (width + height) * radii.mean()), rel=0.02)
    # Figs. 15-16's per-step energies (decisions #69): the first step's, and the step at whose end
    # the first contact opened; each step's injection energy is p_in Q dt (Eq. 25)
    series = np.genfromtxt(out / "timeseries.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert summary["first_step_injection_energy_j"] == pytest.approx(
        series["p_in_mean"][0] * summary["rate_m3_per_s_per_m"] * series["dt"][0], rel=1e-12)
    onset = int(np.flatnonzero(series["t"] == summary["first_opening_time_s"])[0])
    assert summary["fracture_onset_injection_pressure_pa"] == series["p_in_mean"][onset]
    assert summary["fracture_onset_residual_energy_j"] == pytest.approx(
        np.diff(series["energy"], prepend=0.0)[onset] - np.diff(series["dissipation"], prepend=0.0)[onset], rel=1e-9)
    assert 0.0 < summary["fracture_onset_dissipated_fraction"] < 1.0
    config = tomllib.loads((out / "config.toml").read_text())
    # the sample is named also when --packing was not given: the shipped file and its bytes
    shipped = Path(default_huang_packing_path())
    assert config["packing"] == {"file": str(shipped.resolve()),
                                 "sha256": hashlib.sha256(shipped.read_bytes()).hexdigest()}
    assert config["coupling"]["one_way"] is False and config["aperture_law"]["residual_aperture"] == 7.53e-6
    # B3's defaults (decisions #55): the skeleton's Newton step, no pocket step
    assert config["coupling"]["pv_skeleton_newton"] is True and config["coupling"]["pv_pocket_newton"] is False
    assert config["coupling"]["pv_reuse_steps"] == 5
    # the count YADE runs with (import_yade: OMP_NUM_THREADS if set, else 1)
    assert config["dem"]["threads"] == int(os.environ.get("OMP_NUM_THREADS", "1"))


@pytest.mark.yade
def test_fixed_port_holds_the_port_grains_and_the_grain_flags_are_recorded(tmp_path):
    # --fixed-port holds the injection domain's grains where the packing put them while B3's
    # pressure (MPa within microseconds) moves their neighbours; --grain-density is recorded
    # with it (decisions #68; its masses and DEM step: test_coupled_run)
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario, port_grains

    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--max-steps", "6", "--fixed-port", "--grain-density", "5300",
                 "--friction", "0.85", "--stiffness-ratio", "0.5", "--out", str(out), "--quiet"]) == 0
    fractures = np.load(out / "fractures.npz")
    port = port_grains(build_radial_scenario(RADIAL_CASES["B3"]).net)
    moved = np.linalg.norm(fractures["positions"] - fractures["initial_positions"], axis=1)
    assert np.all(moved[port] == 0.0) and moved.max() > 1e-7
    config = tomllib.loads((out / "config.toml").read_text())
    assert config["dem"]["fixed_port"] is True and config["dem"]["grain_density_kg_m3"] == 5300.0
    # the contact parameters too; k_n is the shipped packing's (Table 2's: decisions #74)
    assert (config["dem"]["friction"], config["dem"]["stiffness_ratio"]) == (0.85, 0.5)
    assert config["dem"]["contact_stiffness_n_per_m"] == 7.49e7
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fixed_port"] is True and summary["boundary_hold"] == "fixed"
    assert abs(summary["sample_area_strain"]) < 1e-12  # the boundary grains are held: the sample's area with them


@pytest.mark.yade
def test_a_loaded_boundary_yields_along_its_sides_and_is_recorded(tmp_path):
    # --boundary loaded (decisions #86): B3's first microseconds push the boundary grains out
    # along their sides' normals only, the corner grains stay, and the sample's area grows
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario

    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--max-steps", "6", "--boundary", "loaded", "--out", str(out),
                 "--quiet"]) == 0
    fractures = np.load(out / "fractures.npz")
    shift = fractures["positions"] - fractures["initial_positions"]
    sc = build_radial_scenario(RADIAL_CASES["B3"], boundary_hold="loaded")
    normals = sc.boundary_normals
    sides = normals.any(axis=1)
    assert np.all(shift[sc.fixed & ~sides] == 0.0)  # the corners
    # a boundary grain moves along its side's normal, never across it (the settling cycles and
    # the run alike)
    assert np.all(shift[sides, 0] * normals[sides, 1] - shift[sides, 1] * normals[sides, 0] == 0.0)
    assert np.abs(shift[sides]).max() > 0.0
    config = tomllib.loads((out / "config.toml").read_text())["dem"]
    assert config["boundary_hold"] == "loaded" and config["n_pistons"] > 100 and config["n_fixed"] < 40
    summary = json.loads((out / "summary.json").read_text())
    # measured 1.9e-7 by 4.2 us; a held boundary keeps it within round-off (< 1e-12, above)
    assert summary["boundary_hold"] == "loaded" and summary["sample_area_strain"] > 1e-9


@pytest.mark.yade
def test_interrupted_radial_run_keeps_the_last_accepted_grains(tmp_path, monkeypatch):
    # Ctrl-C inside a flow step, just after a trial DEM run: exit 130 and a complete run
    # directory whose grains are the last accepted step's (the domain areas of fractures.npz's
    # positions are network.npz's volumes to round-off), not the trial's
    from hmdem.coupling.geometry import DomainGeometry
    from hmdem.coupling.model import CoupledFlowModel
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario

    calls = {"n": 0}
    original = CoupledFlowModel.move_grains

    def move_then_interrupt(self, *a, **k):
        positions = original(self, *a, **k)
        calls["n"] += 1
        if calls["n"] == 12:
            raise KeyboardInterrupt
        return positions

    monkeypatch.setattr(CoupledFlowModel, "move_grains", move_then_interrupt)
    out = tmp_path / "cut"
    assert main(["radial", "--case", "B3", "--out", str(out), "--quiet"]) == 130
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and 0 < summary["steps"] < 12
    positions = np.load(out / "fractures.npz")["positions"]
    volumes = DomainGeometry(build_radial_scenario(RADIAL_CASES["B3"]).net).volumes(positions)
    np.testing.assert_allclose(volumes, np.load(out / "network.npz")["domain_volume"], rtol=1e-12)


def test_yade_import_holds_an_interrupt_until_yade_is_in(monkeypatch, terminal_sigint):
    # a new-user pass: Ctrl-C or SIGTERM in the second YADE takes to import aborted the process
    # (boost-python set-up raising from a Python handler) or left a SystemError traceback
    import signal
    import types

    import hmdem.yade_env as yade_env

    finished = []

    def importing(name):  # the signal arrives half-way through the import
        signal.raise_signal(signal.SIGINT)
        finished.append(name)
        return types.SimpleNamespace(O=object())

    monkeypatch.delitem(sys.modules, "yade", raising=False)
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setattr(yade_env, "candidate_paths", lambda: ["/nowhere"])
    monkeypatch.setattr(yade_env.importlib, "import_module", importing)
    with pytest.raises(KeyboardInterrupt):
        yade_env.import_yade()
    assert finished == ["yade"]  # delivered once the import was done, not inside it


def test_interrupted_status_message_names_the_signal():
    import signal

    from hmdem.cli import interrupt_reason, record_interrupt

    try:
        record_interrupt(signal.SIGTERM)
        assert interrupt_reason() == "stopped by SIGTERM"
    finally:
        record_interrupt(signal.SIGINT)
    assert interrupt_reason() == "stopped by Ctrl-C (SIGINT)"


@pytest.mark.parametrize("argv, parameter", [
    (["radial", "--case", "A3", "--contact-gap", "1"], "--contact-gap: at 1 "),  # the shipped sample: 144 off
    (["radial", "--case", "A3", "--sigma", "1"], "--sigma: "),  # Σ = 1 m on a 1.25 mm sample
    (["radial", "--case", "A3", "--sigma", "1e-9"], "--sigma: "),
    (["radial", "--case", "A3", "--rate", "1e-30"], "--rate 1e-30: must give a Ca* (Eq. 24) in [1e-10, 1e4]"),
])
def test_radial_names_the_parameter_its_network_or_rate_cannot_take(argv, parameter, tmp_path, capsys):
    # a new-user pass: --contact-gap 1 was blamed on a --packing never given; --sigma 1 ran to
    # 11 GPa and exit status 0
    out = tmp_path / "run"
    assert main([*argv, "--out", str(out), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].split(": ", 1)[1].startswith(parameter)
    assert not out.exists()


def test_one_way_names_the_p_v_flags_it_does_not_use():
    # a new-user pass: --pv-continue --one-way was taken without a word
    from hmdem.hele_shaw import build_parser, unused_with_one_way

    def unused(*flags):
        return unused_with_one_way(build_parser().parse_args(["radial", *flags]))

    assert unused("--one-way", "--pv-continue", "--pv-tol", "1e-2", "--no-replica", "--damping", "0.5") == [
        "--pv-tol", "--no-replica", "--pv-continue"]
    assert unused("--one-way", "--one-way-volume", "lagged", "--dem-cycles", "100") == []
    assert unused("--one-way", "--pv-rewind") == ["--pv-rewind"]
    assert unused("--pv-continue", "--pv-tol", "1e-2") == []  # the two-way model iterates


def test_radial_rate_gives_its_own_ca_star_and_a_run_weeks_long_warns():
    # --rate sets Q instead of Ca* (Eq. 24 then gives Ca*, as for the linear cases); a rate that
    # fills the pores in millions of flow steps warns (a new-user pass: A1 at Ca* 1e-3, 8e6 steps
    # of DEM behind a bar at 0 %)
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario
    from hmdem.hele_shaw import long_fill_warning

    named = build_radial_scenario(RADIAL_CASES["A3"])
    by_rate = build_radial_scenario(RADIAL_CASES["A3"], rate=named.setup.rate)
    assert by_rate.ca_star == pytest.approx(named.ca_star, rel=1e-12)
    assert by_rate.case.title == named.case.title  # the case's own rate changes nothing
    assert long_fill_warning(named) is None and long_fill_warning(build_radial_scenario(RADIAL_CASES["A1"])) is None
    slow = build_radial_scenario(RADIAL_CASES["A1"], ca_star=1e-3)  # ~80 s to fill at 1e-5 s steps
    assert "8e+06 flow steps" in long_fill_warning(slow)
    slow.setup.max_steps = 1000  # a run the user bounded
    assert long_fill_warning(slow) is None


def test_radial_title_says_which_of_the_cases_settings_were_changed():
    # a new-user pass: A3 at M = 1000 (18 cP) was titled "water-glycerol (5 cP)"
    from hmdem.coupling.radial import RADIAL_CASES, build_radial_scenario

    def title(**changes):
        return build_radial_scenario(RADIAL_CASES["A3"], **changes).case.title

    assert title() == "Huang A3: water-glycerol (5 cP) into air, movable grains"
    assert title(viscosity_ratio=1000.0) == "Huang A3: water-glycerol (18 cP) into air, movable grains, with M changed"
    assert title(ca_star=5.0).endswith(", with Ca* changed")


def test_one_way_volume_needs_one_way(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["radial", "--case", "B3", "--one-way-volume", "lagged", "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--one-way-volume" in lines[0]
    assert not out.exists()


@pytest.mark.yade
def test_one_way_volume_reaches_the_run(tmp_path):
    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--one-way", "--one-way-volume", "lagged", "--max-steps", "2",
                 "--out", str(out), "--quiet"]) == 0
    coupling = tomllib.loads((out / "config.toml").read_text())["coupling"]
    assert coupling["one_way"] is True and coupling["one_way_volume"] == "lagged"
    assert json.loads((out / "summary.json").read_text())["one_way_volume"] == "lagged"


@pytest.mark.yade
def test_pocket_newton_reuse_skeleton_damping_and_replica_flags_reach_the_run(tmp_path):
    out = tmp_path / "b3"
    assert main(["radial", "--case", "B3", "--max-steps", "2", "--pocket-newton", "--pv-reuse-steps", "0",
                 "--no-skeleton-newton", "--damping", "0.25", "--no-replica", "--out", str(out), "--quiet"]) == 0
    config = tomllib.loads((out / "config.toml").read_text())
    coupling = config["coupling"]
    assert coupling["pv_pocket_newton"] is True and coupling["pv_reuse_steps"] == 0
    assert coupling["pv_skeleton_newton"] is False
    assert coupling["dem_replica"] is False  # every evaluation in YADE
    assert json.loads((out / "summary.json").read_text())["replica_cycles"] == 0
    assert coupling["dem_damping"] == 0.25 and config["dem"]["damping"] == 0.25  # as YADE's integrator has it


@pytest.mark.yade
def test_b1_runs_with_its_own_pv_settings_unless_the_flags_say_otherwise(tmp_path):
    # decisions.md #52, #56: B1's defaults are a cap of 24, no reuse, no pocket step, 4 secant
    # pairs; flags still win
    own, flagged = tmp_path / "own", tmp_path / "flagged"
    assert main(["radial", "--case", "B1", "--max-steps", "1", "--out", str(own), "--quiet"]) == 0
    assert main(["radial", "--case", "B1", "--max-steps", "1", "--pocket-newton", "--pv-reuse-steps", "5",
                 "--pv-max-iter", "12", "--pv-max-columns", "40", "--out", str(flagged), "--quiet"]) == 0
    keys = ("pv_max_iter", "pv_reuse_steps", "pv_pocket_newton", "pv_max_columns")
    coupling = tomllib.loads((own / "config.toml").read_text())["coupling"]
    assert tuple(coupling[k] for k in keys) == (24, 0, False, 4)
    coupling = tomllib.loads((flagged / "config.toml").read_text())["coupling"]
    assert tuple(coupling[k] for k in keys) == (12, 5, True, 40)


def b3_on_threads(out: Path, threads: int, steps: int) -> None:
    """B3 for ``steps`` steps on ``threads`` OpenMP threads, in a fresh process: OpenMP reads the
    count when YADE loads."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}
    proc = subprocess.run(CMD + ["radial", "--case", "B3", "--max-steps", str(steps), "--threads", str(threads),
                                 "--out", str(out), "--quiet"], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.yade
def test_threads_flag_reaches_yade(tmp_path):
    # 3, not 2, so that OpenMP's own default (one per core, 2 on the CI machine) cannot pass for it
    b3_on_threads(tmp_path / "b3", 3, 2)
    assert tomllib.loads((tmp_path / "b3" / "config.toml").read_text())["dem"]["threads"] == 3


@pytest.mark.yade
def test_many_threads_do_not_abort_yades_collider(tmp_path):
    # YADE 2023.02's parallel insertion sort read past its bounds list at 63 chunks on the
    # paper-size sample, and Debian's build aborted within B3's first 10 steps, with no run directory
    # (hmdem.dem.discs.collider_threads); the collider now gets at most 40 of the 64 threads
    b3_on_threads(tmp_path / "b3", 64, 10)
    assert json.loads((tmp_path / "b3" / "summary.json").read_text())["steps"] == 10


def test_pressure_beyond_the_constant_bulk_modulus_range_is_flagged(tmp_path, capsys):
    # decisions #31: a constant K (seed 004's linear equation of state) is accurate to p/K = 0.1.
    # The paper's own vf case pushes its invading air (K = 0.14 MPa) to a peak inlet pressure of
    # 59.5 kPa: the air-filled domains next to the inlet reach p/K = 0.42, flagged in
    # summary.json and on stderr (no domain can exceed the inlet pressure over K_air).
    # The chen case (K = 2000 MPa for both fluids) stays far below.
    vf = tmp_path / "vf"
    assert main(["linear", "--case", "vf", "--out", str(vf), "--quiet"]) == 0
    s = json.loads((vf / "summary.json").read_text())
    assert 0.1 < s["peak_compression"] <= s["peak_injection_pressure_pa"] / 0.14e6
    assert s["weakly_compressible"] is False
    err = capsys.readouterr().err
    assert "warning" in err and "0.42 of its fluid's bulk modulus" in err
    chen = tmp_path / "chen"
    assert main(["linear", "--case", "chen", "--out", str(chen), "--quiet"]) == 0
    s = json.loads((chen / "summary.json").read_text())
    assert s["weakly_compressible"] is True and s["peak_compression"] < 1e-3
    assert "warning" not in capsys.readouterr().err


def test_config_toml_leaves_unset_values_out(tmp_path):
    # TOML has no null: an unset option (None) is left out, not written as the string "None"
    from hmdem.rundir import write_toml

    write_toml(tmp_path / "c.toml", {"coupling": {"dem_cycles_per_step": None, "pv_rtol": 1e-3, "note": "None?"}})
    assert tomllib.loads((tmp_path / "c.toml").read_text()) == {"coupling": {"pv_rtol": 1e-3, "note": "None?"}}


@pytest.mark.parametrize("threads, load, warned", [(None, 1.9, False), (1, 1.9, False), (2, 0.2, False),
                                                   (2, 1.0, True), (4, 0.0, True)])
def test_threads_beyond_the_idle_cores_are_warned_of(monkeypatch, threads, load, warned):
    # a new-user pass: --threads 2 beside another run on 2 vCPUs took 50-52 s for 10 B3 steps
    # against 3.5 s on one thread; the run says so before it starts
    import hmdem.hele_shaw as hs

    monkeypatch.setattr(hs.os, "getloadavg", lambda: (load, load, load))
    monkeypatch.setattr(hs.os, "cpu_count", lambda: 2)
    warning = hs.busy_cores_warning(threads)
    assert (warning is not None) == warned
    if warned:
        assert f"--threads {threads}" in warning and "--threads 1" in warning


@pytest.mark.parametrize("flags, title", [
    ([], "Case 1 viscous fingering: air into oil"),
    (["--viscosity-ratio", "1e-3", "--ca-star", "1e-5"], "Case 1 viscous fingering: air into oil, with M and Ca* changed"),
    (["--rate", "1e-6", "--mean-aperture", "0.3e-3"],
     "Case 1 viscous fingering: air into oil, with the rate and the mean aperture changed"),
])
def test_pictures_say_which_of_the_cases_settings_were_changed(flags, title):
    # a new-user pass: vf at M = 1e-3, Ca* = 1e-5 was still titled "viscous fingering: air into
    # oil" over a capillary-fingering pattern of a 1 mPa s invader
    from hmdem.hele_shaw import build_parser, make_case
    from hmdem.report import case_title

    assert case_title(make_case(build_parser().parse_args(["linear", "--case", "vf", *flags]))) == title


def test_table_columns_on_stderr_name_each_flag_a_column_set():
    # radial_injection.py's stderr (a new-user pass): a flag a yade-batch column became is named
    # by its column as well, whole flags only; a flag no column set is left as written
    import io

    from hmdem.cli import TableColumnsOnStderr

    sink = io.StringIO()
    stream = TableColumnsOnStderr(sink, {"--dt": "dt", "--viscosity-ratio": "viscosityRatio"})
    text = "--dt: bad; --dt=3 --dtx --dt-cap --viscosity-ratio, --damping\n"
    assert stream.write(text) == len(text)
    stream.writelines(["--dt\n"])
    assert sink.getvalue() == ("dt (--dt): bad; dt (--dt)=3 --dtx --dt-cap viscosityRatio (--viscosity-ratio), "
                               "--damping\ndt (--dt)\n")
    # no column set a flag: everything as written
    plain = io.StringIO()
    TableColumnsOnStderr(plain, {}).write("--dt: bad\n")
    assert plain.getvalue() == "--dt: bad\n"
