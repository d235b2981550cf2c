import signal
import subprocess
import sys

import numpy as np
import pytest

from hmdem.cases import CASES
from hmdem.flow.simulation import FlowModel
from hmdem.scenario import build_scenario


@pytest.fixture
def terminal_sigint():
    """SIGINT handled in this process as from a terminal (KeyboardInterrupt) for one test: under
    ``make test &`` it is inherited ignored (see :func:`popen_interruptible`), and a held Ctrl-C
    is then rightly delivered to that ignoring handler. The previous disposition is restored."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def popen_interruptible(cmd, **kwargs):
    """``subprocess.Popen(cmd)`` whose child handles SIGINT as from a terminal (KeyboardInterrupt).

    A non-interactive shell starts background jobs with SIGINT ignored, and an ignored signal
    is inherited: under ``make test &`` the child would never see the test's SIGINT and a
    Ctrl-C test would fail (or pass) for the wrong reason. Restoring the default disposition
    before exec lets Python install its handler."""
    for stream in ("stdout", "stderr"):
        kwargs.setdefault(stream, subprocess.PIPE)
    return subprocess.Popen(cmd, text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
                            **kwargs)


def sigterm_once_stderr_shows(args, text):
    """Run ``python -m ARGS``, send SIGTERM once its stderr shows ``text`` (the command is under
    way, its handler in place) and return (exit status, whole stderr)."""
    proc = popen_interruptible([sys.executable, "-m", *args], stdout=subprocess.DEVNULL)
    seen = ""
    while text not in seen and proc.poll() is None:
        seen += proc.stderr.read(1)
    proc.send_signal(signal.SIGTERM)
    rest = proc.communicate(timeout=120)[1]
    return proc.returncode, seen + rest


def run_case(name, **setup_changes):
    sc = build_scenario(CASES[name])
    for k, v in setup_changes.items():
        setattr(sc.setup, k, v)
    model = FlowModel(sc.net, sc.setup)
    state, rec = model.run()
    return sc, model, state, rec


@pytest.fixture(scope="session")
def vf_run():
    return run_case("vf")


@pytest.fixture(scope="session")
def cf1_run():
    return run_case("cf1")


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def interrupt_after(monkeypatch):
    """``interrupt_after(n)``: a Ctrl-C (KeyboardInterrupt) at the end of ``FlowModel._accept`` of
    the n-th step: right after it for fixed grains (a coupled model's own _accept would still
    have its part to do)."""
    from hmdem.flow import simulation

    def install(steps: int) -> None:
        calls = {"n": 0}
        original = simulation.FlowModel._accept

        def accept_then_interrupt(self, *a, **k):
            original(self, *a, **k)
            calls["n"] += 1
            if calls["n"] == steps:
                raise KeyboardInterrupt

        monkeypatch.setattr(simulation.FlowModel, "_accept", accept_then_interrupt)

    return install
