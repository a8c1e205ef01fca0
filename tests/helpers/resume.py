"""Kill a training run right after one of its checkpoints, then resume it: the shared step of the resume tests."""
from __future__ import annotations

import pytest
import torch
from safetensors.torch import load_file

from hybrid_dyn.learn import train_model
from hybrid_dyn.learn import train as train_mod


def killed_then_resumed(monkeypatch, dataset, preset, out_dir, config, kill_after_epoch: int, between=None):
    """Train into ``out_dir``, interrupted right after epoch (or round) ``kill_after_epoch``'s checkpoint,
    then train again with the same arguments: the resumed model. ``between()``, if given, runs after the
    kill and before the resume (to look at what the kill left, or to disturb the process's state)."""
    real_save = train_mod._save_checkpoint

    def save_then_die(out, module, best, opt, info):
        real_save(out, module, best, opt, info)
        if info["epoch"] == kill_after_epoch:
            raise KeyboardInterrupt

    monkeypatch.setattr(train_mod, "_save_checkpoint", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        train_model(dataset, preset, out_dir, config)
    monkeypatch.setattr(train_mod, "_save_checkpoint", real_save)
    if between is not None:
        between()
    return train_model(dataset, preset, out_dir, config)


def assert_same_weights(dir_a, dir_b) -> None:
    a, b = load_file(str(dir_a / "model.safetensors")), load_file(str(dir_b / "model.safetensors"))
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
