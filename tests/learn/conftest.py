"""Fixtures of the learn tests."""
import pytest
import torch


@pytest.fixture(scope="module")
def one_thread():
    """Tiny batches: one torch thread is faster, and avoids spinning against other jobs on 2 cores. A module
    asks for it with ``pytestmark = pytest.mark.usefixtures("one_thread")``."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
