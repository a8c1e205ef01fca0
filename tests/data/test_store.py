"""Datasets in fsspec stores: generation into a file:// URL from worker processes and into
memory://, resumed after a corrupt instance, and fetched to a local folder for training."""
import fsspec
import pytest

from hybrid_dyn.data import DatasetError, load_dataset
from hybrid_dyn.data.store import fetch_dataset
from hybrid_dyn.sim.executors import ProcessExecutor, SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.generator_config import PulseConfig
from hybrid_dyn.sim.scenarios import scenario_config

from helpers.files import dir_bytes
from helpers.messages import says

TINY = dict(n_instances=3, trajectories=(1, 1), standstill=0.2, speed_scale=(0.5, 0.6),
            pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


@pytest.fixture(scope="module")
def tiny_reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "ds"
    generate_dataset(scenario_config("paper-ext", "quick", seed=1, **TINY), out, executor=SerialExecutor(), progress=False)
    return out


def test_file_url_store_with_processes_equals_local_directory(tiny_reference, tmp_path):
    """Through fsspec (file:// URL: the code path of any remote store) from two worker processes."""
    url = f"file://{tmp_path / 'remote'}"
    assert generate_dataset(scenario_config("paper-ext", "quick", seed=1, **TINY), url,
                            executor=ProcessExecutor(2), progress=False) == url
    assert dir_bytes(tmp_path / "remote") == dir_bytes(tiny_reference)


def test_memory_store_resume_and_fetch(tiny_reference, tmp_path):
    cfg = scenario_config("paper-ext", "quick", seed=1, **TINY)
    url = "memory://hybrid-dyn-test/ds"
    fs = fsspec.filesystem("memory")
    try:
        generate_dataset(cfg, url, executor=SerialExecutor(), progress=False)
        ref = dir_bytes(tiny_reference)
        for rel, data in ref.items():
            assert fs.cat_file(f"/hybrid-dyn-test/ds/{rel}") == data, rel
        # A corrupt instance in the store is named and regenerated; the others are kept.
        fs.pipe_file("/hybrid-dyn-test/ds/instances/inst_00001.h5", b"truncated")
        messages = []
        generate_dataset(cfg, url, executor=SerialExecutor(), progress=False, log=messages.append)
        assert len(messages) == 1 and says(messages[0], "regenerating", "inst_00001", "checksum"), messages
        assert fs.cat_file("/hybrid-dyn-test/ds/instances/inst_00001.h5") == ref["instances/inst_00001.h5"]
        # Training reads local files: a URL is refused by name, and fetch_dataset copies it.
        with pytest.raises(DatasetError, match="is a URL"):
            load_dataset(url)
        local = fetch_dataset(url, tmp_path / "copy")
        assert load_dataset(local).checksum == load_dataset(tiny_reference).checksum
    finally:
        fs.rm("/hybrid-dyn-test", recursive=True)
