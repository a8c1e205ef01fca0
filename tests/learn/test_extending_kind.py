"""Extending the toolkit by a network kind (docs/extending.md, "A network kind"): the toy kind below is
declared in one place, and training, saving, loading and the fast path find it through the registry."""
import numpy as np
import pytest
import torch
from torch import nn

from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.input_windows import concat_fields
from hybrid_dyn.errors import UsageError
from hybrid_dyn.learn import TrainConfig, load_model, train_model
from hybrid_dyn.learn.kinds import NETWORK_KINDS, NetworkKind, search_fc, single_net
from hybrid_dyn.learn.nets import fc_head
from hybrid_dyn.learn.presets import Preset


class WindowMeanNet(nn.Module):
    """The toy: the window's mean over time, then FC layers (a net kind needs a ``head``)."""

    def __init__(self, n_in, n_out, fc_layers, fc_units, activation):
        super().__init__()
        self.head = fc_head(n_in, fc_layers, fc_units, n_out, activation)

    def forward(self, x):  # x: standardized window (B, L, F)
        return self.head(x.mean(1))


# The one declaration of the toy kind: everything training, the fast path, tuning and the bench read.
WINDOW_MEAN = NetworkKind(
    "window-mean", "the window's mean over time, then FC layers (a test's toy)",
    build=single_net(lambda p, n_in, n_out: WindowMeanNet(n_in, n_out, p.fc_layers, p.fc_units, p.activation)),
    fast=lambda parts: (lambda x: x.mean(0)),  # float64 front: window (L, F) -> the head's input
    clips_gradients=False, cost_rank=0, search=search_fc, budget_steps=200, sequence=True, needs_front=False)


@pytest.fixture
def window_mean():
    kind = NETWORK_KINDS.register(WINDOW_MEAN)
    yield kind
    NETWORK_KINDS.unregister(kind.name)
    assert kind.name not in NETWORK_KINDS


def test_a_new_kind_trains_saves_and_loads_with_the_same_predictions(window_mean, panda, tmp_path):
    data = load_dataset(make_synthetic_dataset(tmp_path / "data", panda, n_instances=6, n_samples=100, seed=11))
    preset = Preset("toy-window-mean", "window-mean", ("q", "qd", "qdd"), ("tau_m",), window=5, fc_layers=1,
                    fc_units=8)
    torch.manual_seed(0)
    model = train_model(data, preset, tmp_path / "model",
                        TrainConfig(max_epochs=2, max_batches_per_epoch=3, progress=False, num_threads=1))
    assert isinstance(model.module.net, WindowMeanNet) and model.config["preset"]["kind"] == "window-mean"
    run = data.split("test")[0]
    before = model.predict([run])[0]

    model.save(tmp_path / "copy")
    for folder in (tmp_path / "model", tmp_path / "copy"):
        loaded = load_model(folder)
        assert isinstance(loaded.module.net, WindowMeanNet)
        np.testing.assert_array_equal(loaded.predict([run])[0], before)

    x = concat_fields([run], loaded.inputs).astype(np.float64)  # the declared fast path, one window
    np.testing.assert_allclose(loaded.predict_window(x[10:15]), before[14], rtol=1e-5, atol=1e-5)


def test_an_unknown_kind_is_refused_naming_the_known_ones(window_mean):
    with pytest.raises(UsageError, match="unknown network kind 'gru'; known: mlp, conv, lstm, delan, window-mean"):
        NETWORK_KINDS.lookup("gru")
    with pytest.raises(ValueError, match="kind must be one of") as err:  # a preset of it, refused when made
        Preset("toy", "gru", ("q",), ("tau_m",))
    assert all(repr(name) in str(err.value) for name in ("mlp", "conv", "lstm", "delan", "window-mean"))


def test_a_preset_of_a_plugins_kind_loads_the_plugin_first(monkeypatch):
    """A model file's preset naming a kind a plugin declares (a fresh process: nothing loaded it yet)."""
    from types import SimpleNamespace

    from hybrid_dyn import plugins

    entry = SimpleNamespace(name="kinds", value="pkg.kinds", load=lambda: NETWORK_KINDS.register(WINDOW_MEAN))
    monkeypatch.setattr(plugins.importlib.metadata, "entry_points", lambda group: [entry])
    monkeypatch.setattr(plugins, "LOADED", {})
    monkeypatch.setitem(plugins._state, "scanned", False)
    try:
        preset = Preset("toy", "window-mean", ("q",), ("tau_m",), window=5)  # as a model file's preset is read
        assert preset.kind == "window-mean" and plugins.LOADED == {"kinds": "pkg.kinds"}
    finally:
        if "window-mean" in NETWORK_KINDS:
            NETWORK_KINDS.unregister("window-mean")
