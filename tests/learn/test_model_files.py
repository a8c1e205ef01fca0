"""Model files and training runs: tensor digest, reproducible bytes, dropout resume,
train's arguments, robot and width checks before training, one run per folder, foreign folders.

Tiny synthetic Panda sets built here; every training run is one or a few epochs of a few batches.
"""
import json
import shutil
import struct

import numpy as np
import pytest
import torch
from safetensors.torch import load_file, save_file

import hybrid_dyn as hd
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.errors import OutputPathError, UsageError
from hybrid_dyn.learn import ModelError, TrainConfig, load_model, train_model
from hybrid_dyn.learn import train as train_mod
from hybrid_dyn.learn.trained_model import config_digest
from hybrid_dyn.outputs import output_lock

from helpers.resume import killed_then_resumed

pytestmark = pytest.mark.usefixtures("one_thread")

QUICK = dict(batch_size=32, progress=False, num_threads=1)


@pytest.fixture(scope="module")
def ds_path(tmp_path_factory, panda):
    return make_synthetic_dataset(tmp_path_factory.mktemp("mf") / "ds", panda, n_instances=5, n_samples=60, seed=4)


@pytest.fixture(scope="module")
def tip1(ds_path, tmp_path_factory):
    cfg = TrainConfig(max_epochs=2, max_batches_per_epoch=3, **QUICK)
    return train_model(load_dataset(ds_path), "seed-tip-1", tmp_path_factory.mktemp("m") / "tip1", cfg), cfg


def _flip_bit(path, tensor: str, byte: int, bit: int) -> None:
    """Flip one bit of a tensor's data in a safetensors file, in place (header untouched)."""
    raw = bytearray(path.read_bytes())
    n = struct.unpack("<Q", raw[:8])[0]
    start = 8 + n + json.loads(raw[8:8 + n])[tensor]["data_offsets"][0]
    raw[start + byte] ^= 1 << bit
    path.write_bytes(bytes(raw))


def test_a_flipped_bit_in_the_tensors_is_refused_by_every_loader(tip1, ds_path, tmp_path):
    model, cfg = tip1
    bad = tmp_path / "tip1"
    shutil.copytree(model.path, bad)
    _flip_bit(bad / "model.safetensors", "y_std", 3, 5)  # an exponent bit of y_std[0] (float32, little-endian)
    assert not torch.equal(load_file(str(bad / "model.safetensors"))["y_std"], model.module.y_std)
    with pytest.raises(ModelError, match=r"model\.safetensors: its tensors do not match"):
        load_model(bad)
    with pytest.raises(ModelError, match="tensors do not match"):
        hd.TipForceEstimator.load(bad)  # the streaming path
    with pytest.raises(ModelError, match="tensors do not match"):  # the bench's reuse of a trained model
        train_model(load_dataset(ds_path), "seed-tip-1", bad, cfg)
    from hybrid_dyn.cli import main

    assert main(["predict", "--model", str(bad), "--data", str(ds_path)]) == 2


def test_a_model_file_older_than_the_tensor_digest_is_refused(tip1, tmp_path):
    model, _ = tip1
    old = tmp_path / "old"
    shutil.copytree(model.path, old)
    cfg = json.loads((old / "config.json").read_text())
    # Format 1 wrote two plain metadata keys and no tensor digest.
    save_file(load_file(str(old / "model.safetensors")), str(old / "model.safetensors"),
              metadata={"format": "hybrid_dyn.model", "config_sha256": config_digest(cfg)})
    with pytest.raises(ModelError, match="predates the tensor digest.*retrain"):
        load_model(old)


def test_two_identical_runs_write_byte_identical_model_files(tip1, ds_path, tmp_path):
    model, cfg = tip1
    again = train_model(load_dataset(ds_path), "seed-tip-1", tmp_path / "again", cfg)
    for name in ("model.safetensors", "config.json"):
        assert (model.path / name).read_bytes() == (again.path / name).read_bytes(), name
    assert np.isfinite(again.train_seconds) and again.train_seconds > 0  # kept, outside the digest (timing.json)


def test_dropout_training_resumes_to_byte_identical_model(ds_path, tmp_path, monkeypatch):
    """tau-mlp-wide draws dropout masks from torch's generator: its state must travel in the checkpoint."""
    ds = load_dataset(ds_path)
    cfg = TrainConfig(max_epochs=3, max_batches_per_epoch=3, patience=10, **QUICK)
    straight = train_model(ds, "tau-mlp-wide", tmp_path / "a", cfg)

    def disturb_the_global_generator():  # whatever the process did in between must not matter
        torch.manual_seed(12345)
        torch.rand(100)

    # killed right after epoch 1's checkpoint
    resumed = killed_then_resumed(monkeypatch, ds, "tau-mlp-wide", tmp_path / "b", cfg, kill_after_epoch=0,
                                  between=disturb_the_global_generator)
    assert resumed.history == straight.history
    for name in ("model.safetensors", "config.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


@pytest.mark.parametrize("field,value", [
    ("max_epochs", 0), ("patience", 0), ("batch_size", -1), ("batch_size", 0), ("device", "gpu"),
    ("num_threads", -2), ("num_threads", 0), ("max_batches_per_epoch", 0), ("seed", -1), ("lr", 0.0),
    ("lr", float("nan")), ("batch_size", 2.5), ("batch_size", True), ("tare_seconds", -0.5),
])
def test_train_config_refuses_values_out_of_range(field, value):
    with pytest.raises(UsageError, match=field):
        TrainConfig(**{field: value})


@pytest.mark.parametrize("args,flag", [
    (["--max-epochs", "0"], "--max-epochs"), (["--patience", "0"], "--patience"), (["--batch-size", "-1"], "--batch-size"),
    (["--batch-size", "0"], "--batch-size"), (["--device", "gpu"], "--device"), (["--threads", "-2"], "--threads"),
    (["--device", "cuda:99"], "CUDA device"),
])
def test_cli_train_refuses_bad_arguments_in_one_line_before_any_work(args, flag, ds_path, tmp_path, capsys):
    from hybrid_dyn.cli import main

    out = tmp_path / "m"
    assert main(["train", "--data", str(ds_path), "--preset", "seed-tip-1", "--out", str(out), "--quiet"] + args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and flag in err and err.count("\n") == 1, err
    assert not out.exists()


def _relabelled(ds_path, robot: str):
    ds = load_dataset(ds_path)
    ds.meta["robot"] = robot  # in memory only: the files stay the Panda's
    return ds


def test_robot_and_widths_are_checked_before_training(ds_path, tmp_path):
    # 7-joint data labelled as the 6-joint UR5: refused before anything is written.
    with pytest.raises(ModelError, match=r"'ur5' \(6 joints\)"):
        train_model(_relabelled(ds_path, "ur5"), "seed-tip-1", tmp_path / "ur5", TrainConfig(max_epochs=1, **QUICK))
    assert not (tmp_path / "ur5").exists()
    # A model with an analytic part needs the robot's description: refused before training.
    with pytest.raises(ModelError, match="needs a description of robot 'r2d2'"):
        train_model(_relabelled(ds_path, "r2d2"), "residual-basewrench", tmp_path / "res",
                    TrainConfig(max_epochs=1, **QUICK))
    assert not (tmp_path / "res").exists()
    # So does a net on the tared base sensor (the tare subtracts the robot's model wrench).
    with pytest.raises(ModelError, match="tared with the model of robot 'r2d2'"):
        train_model(_relabelled(ds_path, "r2d2"), "seed-tip-1", tmp_path / "tip", TrainConfig(max_epochs=1, **QUICK))
    assert not (tmp_path / "tip").exists()


def test_a_data_only_model_of_an_unnamed_arm_trains_and_loads(ds_path, tmp_path):
    cfg = TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK)
    model = train_model(_relabelled(ds_path, "r2d2"), "seed-tau-mlp", tmp_path / "m", cfg)
    again = load_model(tmp_path / "m", robot="r2d2")
    assert again.config["robot"] == "r2d2" and again.val_loss == model.val_loss
    with pytest.raises(ModelError, match="'r2d2', not 'panda'"):
        load_model(tmp_path / "m", robot="panda")


def test_a_second_run_into_a_folder_in_use_is_refused(ds_path, tmp_path):
    out = tmp_path / "m"
    with output_lock(out, "model folder"):  # another run holds it (flock: per open file, so in-process too)
        with pytest.raises(OutputPathError, match="being written by another run"):
            train_model(load_dataset(ds_path), "seed-tip-1", out, TrainConfig(max_epochs=1, seed=1, **QUICK))
    assert not (out / "config.json").exists()


@pytest.mark.parametrize("files", [
    {"model.safetensors": b"not ours", "checkpoint.json": b'{"step": 3}'},
    {"notes.txt": b"my notes"},
    {"checkpoint.json": b"{"},
])
def test_a_folder_the_toolkit_did_not_write_is_left_alone(files, ds_path, tmp_path):
    out = tmp_path / "m"
    out.mkdir()
    for name, data in files.items():
        (out / name).write_bytes(data)
    with pytest.raises(OutputPathError, match=f"refusing to replace {out}"):
        train_model(load_dataset(ds_path), "seed-tip-1", out, TrainConfig(max_epochs=1, **QUICK))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == files


def test_an_empty_folder_or_a_killed_runs_leftovers_are_fine(ds_path, tmp_path, monkeypatch):
    ds = load_dataset(ds_path)
    cfg = TrainConfig(max_epochs=2, max_batches_per_epoch=2, **QUICK)
    (tmp_path / "empty").mkdir()
    assert train_model(ds, "residual-basewrench", tmp_path / "empty", cfg).val_loss > 0
    real_save = train_mod._save_checkpoint

    def save_then_die(out_dir, module, best, opt, info):
        real_save(out_dir, module, best, opt, info)
        (out_dir / "model.safetensors.partial").write_bytes(b"torn")  # a temporary a kill left behind
        raise KeyboardInterrupt

    monkeypatch.setattr(train_mod, "_save_checkpoint", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        train_model(ds, "residual-basewrench", tmp_path / "killed", cfg)
    assert list((tmp_path / "killed" / "analytic_cache").glob("prior-base-wrench-*.h5"))
    monkeypatch.setattr(train_mod, "_save_checkpoint", real_save)
    resumed = train_model(ds, "residual-basewrench", tmp_path / "killed", cfg)
    assert (tmp_path / "killed" / "model.safetensors").read_bytes() == \
        (tmp_path / "empty" / "model.safetensors").read_bytes()
    assert resumed.history == load_model(tmp_path / "empty").history
