"""The on-disk dataset format: round trip, checksums, corruption, windows."""
import json

import h5py
import numpy as np
import pytest

from hybrid_dyn.data import DatasetError, load_dataset, split_by_instance
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.windows import window_index


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, panda):
    return make_synthetic_dataset(tmp_path_factory.mktemp("ds") / "tiny", panda, n_instances=5, n_samples=50)


def test_round_trip_and_splits(tiny, panda):
    ds = load_dataset(tiny)
    names = [i.name for s in ("train", "val", "test") for i in ds.split(s)]
    assert sorted(names) == [f"inst_{k:05d}" for k in range(5)]  # each instance in exactly one split
    inst = ds.split("test")[0]
    assert inst.q.shape == (50, 7) and inst.base_wrench.shape == (50, 6) and inst.t.shape == (50,)
    # The file opens without this toolkit, and the physics in it is consistent:
    with h5py.File(inst.path) as f:
        np.testing.assert_array_equal(f["q"][()], inst.q)
    np.testing.assert_allclose(panda.base_wrench(inst.q, inst.qd, inst.qdd, inst.tip_force), inst.base_wrench, atol=1e-9)


def test_split_is_64_16_20_and_seeded():
    names = [f"i{k}" for k in range(100)]
    s = split_by_instance(names, seed=3)
    assert (len(s["train"]), len(s["val"]), len(s["test"])) == (64, 16, 20)
    assert s == split_by_instance(list(reversed(names)), seed=3)
    assert s != split_by_instance(names, seed=4)


def test_corrupt_instance_is_named(tiny, tmp_path):
    import shutil
    bad = tmp_path / "bad"
    shutil.copytree(tiny, bad)
    victim = sorted((bad / "instances").glob("*.h5"))[2]
    victim.write_bytes(victim.read_bytes()[:500])  # truncated, as by a crash
    with pytest.raises(DatasetError, match="inst_00002.*checksum"):
        load_dataset(bad)
    victim.unlink()
    with pytest.raises(DatasetError, match="inst_00002.*missing"):
        load_dataset(bad)


def test_missing_or_corrupt_manifest(tmp_path):
    with pytest.raises(DatasetError, match="not a directory"):
        load_dataset(tmp_path / "nope")
    (tmp_path / "d").mkdir()
    with pytest.raises(DatasetError, match="no manifest.json"):
        load_dataset(tmp_path / "d")
    (tmp_path / "d" / "manifest.json").write_text('{"format": "hybrid_dyn.dataset", "instan')
    with pytest.raises(DatasetError, match="corrupt"):
        load_dataset(tmp_path / "d")


def test_windows_are_edge_padded_and_never_cross_instances():
    idx = window_index([3, 4], length=3)
    expected = [[0, 0, 0], [0, 0, 1], [0, 1, 2], [3, 3, 3], [3, 3, 4], [3, 4, 5], [4, 5, 6]]
    assert idx.tolist() == expected


def test_windowed_split_gathers_the_right_rows(tiny):
    ds = load_dataset(tiny)
    ws = ds.windows("train", 5, inputs=["q", "qd"], targets=["tau_m"])
    insts = ds.split("train")
    assert len(ws) == sum(len(i) for i in insts)
    x, y = ws[np.array([0, 10, len(insts[0])])]
    assert x.shape == (3, 5, 14) and y.shape == (3, 7)
    np.testing.assert_allclose(x[1, -1, :7], insts[0].q[10], rtol=1e-6)
    np.testing.assert_allclose(x[1, 0, :7], insts[0].q[6], rtol=1e-6)
    np.testing.assert_allclose(x[2, 0, :7], insts[1].q[0], rtol=1e-6)  # padded with instance 1's first sample
    np.testing.assert_allclose(y[1], insts[0].tau_m[10], rtol=1e-6)
