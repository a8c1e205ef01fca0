"""Shared fixtures: robots, and data that tests in several folders read, built once per session.

Helpers that build data (random states, motions, logs) are in ``tests/helpers`` (``import helpers``).
"""
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import available_robots


def pytest_addoption(parser):
    parser.addoption("--fault-matrix", action="store_true",
                     help="also run the whole kill-and-resume matrix (tests marked fault_matrix, ~11 min on 2 cores)")


def pytest_collection_modifyitems(config, items):
    """The fault_matrix tests run only with --fault-matrix: deselected otherwise (listed as such)."""
    if config.getoption("--fault-matrix"):
        return
    left_out = [item for item in items if item.get_closest_marker("fault_matrix")]
    if left_out:
        config.hook.pytest_deselected(items=left_out)
        items[:] = [item for item in items if not item.get_closest_marker("fault_matrix")]


@pytest.fixture(scope="session")
def panda():
    return hd.load_robot("panda")


@pytest.fixture(scope="session")
def ur5():
    return hd.load_robot("ur5")


@pytest.fixture(scope="session", params=available_robots())
def described_robot(request):
    """Every robot declared in the robot registry (``hybrid_dyn/resources/robots/``, or ``$HYBRID_DYN_ROBOTS``)
    with a full description (URDF, frames), one at a time: a robot is checked against DART, and by every
    test that takes this fixture, by being declared there."""
    return hd.load_robot(request.param)


@pytest.fixture(scope="session")
def identified_log(panda, tmp_path_factory):
    """An imported-like dataset (no generator_version, no plant): Gaz friction in tau_m, a small tip force;
    the model identified on it and its file: (dataset, IdentifiedModel, path)."""
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.identify import identify

    root = tmp_path_factory.mktemp("ident-hybrids")
    ds = load_dataset(make_synthetic_dataset(root / "d", panda, n_instances=5, n_samples=150, seed=5,
                                             friction=panda.spec.friction("gaz2019"), contact_free_s=0.6))
    assert ds.meta.get("generator_version") is None
    model = identify(ds, "consistent", panda)  # what `hybrid-dyn identify --fit consistent` runs
    return ds, model, model.save(root / "panda_identified.json")


@pytest.fixture(scope="session")
def panda_log(tmp_path_factory):
    """A tiny 7-joint Panda log, imported (10 blocks, split 6/2/2)."""
    from hybrid_dyn.cli import main as cli_main

    from helpers.logs import write_log

    tmp = tmp_path_factory.mktemp("panda-log")
    spec = write_log(tmp / "logs", n=200)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp / "log")]) == 0
    return tmp / "log"
