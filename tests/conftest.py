import numpy as np
import pytest

from hmdem.cases import CASES
from hmdem.flow.simulation import FlowModel
from hmdem.scenario import build_scenario


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
