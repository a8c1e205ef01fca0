"""The on-disk dataset format: round trip, checksums, corruption, windows."""
import json

import h5py
import numpy as np
import pytest

from hybrid_dyn.data import DatasetError, load_dataset, split_by_instance
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.input_windows import window_index


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


def _edited_copy(src, dst, edit):
    """A copy of dataset ``src`` at ``dst`` whose manifest dict ``edit`` changes in place."""
    import shutil
    shutil.copytree(src, dst)
    meta = json.loads((dst / "manifest.json").read_text())
    edit(meta)
    (dst / "manifest.json").write_text(json.dumps(meta))
    return dst


@pytest.mark.parametrize("edit, match", [
    (lambda m: m["splits"]["test"].append(m["splits"]["train"][0]), r"in both 'train' and 'test'"),
    (lambda m: m["splits"]["val"].append(m["splits"]["val"][0]), r"is twice"),
    (lambda m: m["instances"].append(dict(m["instances"][0])), r"listed twice"),
], ids=["train-test-overlap", "repeated-in-split", "repeated-instance"])
def test_overlapping_or_repeated_splits_are_refused(tiny, tmp_path, edit, match):
    bad = _edited_copy(tiny, tmp_path / "bad", edit)
    with pytest.raises(DatasetError, match=match):
        load_dataset(bad)


@pytest.mark.parametrize("edit, match", [
    (lambda m: m["instances"][1].pop("sha256"), r"instances\[1\] \(inst_00001\) lacks 'sha256'"),
    (lambda m: m["instances"][0].update(n_samples="50"), r"'n_samples' must be int"),
    (lambda m: m.update(splits=[["inst_00000"]]), r"'splits' must map"),
    (lambda m: m["splits"].pop("val"), r"'splits' lacks 'val'"),
    (lambda m: m["splits"].update(train="inst_00000"), r"split 'train' must be a list"),
    (lambda m: m.update(instances={"inst_00000": {}}), r"'instances' must be a list"),
    (lambda m: m["instances"].__setitem__(0, "inst_00000"), r"instances\[0\] must be a record"),
], ids=["no-sha256", "n_samples-str", "splits-list", "no-val", "split-str", "instances-dict", "record-str"])
def test_structural_manifest_errors_name_the_key(tiny, tmp_path, edit, match):
    bad = _edited_copy(tiny, tmp_path / "bad", edit)
    with pytest.raises(DatasetError, match=match):
        load_dataset(bad)


@pytest.mark.parametrize("file", ["../outside.h5", "instances/../../outside.h5", "/tmp/outside.h5",
                                  "..\\outside.h5"])
def test_instance_files_are_confined_to_the_dataset(tiny, tmp_path, file):
    import shutil
    # The escaping target exists and has the right checksum: only the path is wrong.
    shutil.copyfile(tiny / "instances" / "inst_00000.h5", tmp_path / "outside.h5")
    bad = _edited_copy(tiny, tmp_path / "ds" / "bad", lambda m: m["instances"][0].update(file=file))
    with pytest.raises(DatasetError, match=r"inst_00000.*must be a relative path inside the dataset folder"):
        load_dataset(bad)


def test_instance_attrs_must_match_the_manifest(tiny, tmp_path):
    """A file of another scenario or config, its checksum re-recorded, is refused on opening."""
    from hybrid_dyn.data.dataset import write_instance

    def stamped(m):
        m["scenario"], m["config_hash"] = "paper-ext", "aaaa"

    ds_dir = _edited_copy(tiny, tmp_path / "ds", stamped)
    meta = json.loads((ds_dir / "manifest.json").read_text())
    src = load_dataset(tiny).instances["inst_00003"]
    fields = {k: src[k] for k in src.fields}
    for attrs, match in (({"scenario": "paper-ext", "config_hash": "aaaa"}, None),
                         ({"scenario": "mismatch-ext", "config_hash": "aaaa"}, r"scenario 'mismatch-ext', the manifest 'paper-ext'"),
                         ({"scenario": "paper-ext", "config_hash": "bbbb"}, r"config_hash 'bbbb', the manifest 'aaaa'")):
        sha = write_instance(ds_dir / "instances" / "inst_00003.h5", fields, attrs=attrs)
        meta["instances"][3]["sha256"] = sha
        (ds_dir / "manifest.json").write_text(json.dumps(meta))
        inst = load_dataset(ds_dir).instances["inst_00003"]
        if match is None:
            np.testing.assert_array_equal(inst.q, src.q)
        else:
            with pytest.raises(DatasetError, match=r"inst_00003.*inst_00003\.h5 has " + match):
                inst.q
