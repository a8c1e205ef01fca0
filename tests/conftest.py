"""Shared fixtures: robots and their DART twins, built once per session.

Helpers that build data (random states, motions, logs) are in ``tests/helpers`` (``import helpers``).
"""
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import available_robots


@pytest.fixture(scope="session")
def panda():
    return hd.load_robot("panda")


@pytest.fixture(scope="session")
def ur5():
    return hd.load_robot("ur5")


@pytest.fixture(scope="session", params=available_robots())
def described_robot(request):
    """Every robot declared in ``robots/`` with a full description (URDF, frames), one at a time: a robot
    is checked against DART, and by every test that takes this fixture, by being declared there."""
    return hd.load_robot(request.param)
