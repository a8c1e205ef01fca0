"""Network kinds declared once: a kind's pieces live in one declaration
(learn/kinds.py), a kind missing one is refused there, and a toy kind declared in
this file alone trains, resumes its budget, runs its fast path and is tuned."""
import numpy as np
import optuna
import pytest
import torch
from torch import nn

from hybrid_dyn.bench.training_queue import epoch_cost_rank
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.input_windows import concat_fields
from hybrid_dyn.learn import TrainConfig, load_model, train_model
from hybrid_dyn.learn import kinds
from hybrid_dyn.learn import train as train_mod
from hybrid_dyn.learn.kinds import NetworkKind, search_fc, single_net
from hybrid_dyn.learn.nets import fc_head
from hybrid_dyn.learn.presets import PRESETS, Preset
from hybrid_dyn.learn.tune import suggest_preset


class FlatNet(nn.Module):
    """The toy: the whole window flattened into the FC head (no front layer)."""

    def __init__(self, n_in, n_out, window, fc_layers, fc_units, activation):
        super().__init__()
        self.head = fc_head(n_in * window, fc_layers, fc_units, n_out, activation)

    def forward(self, x):
        return self.head(x.flatten(1))


def _flat(p, n_in, n_out):
    return FlatNet(n_in, n_out, p.window, p.fc_layers, p.fc_units, p.activation)


# Everything about the toy kind, in one place.
FLAT = dict(description="the window flattened into FC layers (a test's toy)", build=single_net(_flat),
            fast=lambda parts: (lambda x: x.ravel()),  # row-major, as torch's flatten(1) of (B, L, F)
            clips_gradients=True, cost_rank=5, search=search_fc, budget_steps=300, sequence=True, needs_front=False)


@pytest.fixture
def flat_kind():
    kind = kinds.NETWORK_KINDS.register(NetworkKind("flat", **FLAT))
    yield kind
    kinds.NETWORK_KINDS.unregister("flat")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, panda):
    root = tmp_path_factory.mktemp("kinds")
    return load_dataset(make_synthetic_dataset(root / "d", panda, n_instances=6, n_samples=150, seed=5))


@pytest.mark.parametrize("piece", ["build", "fast", "clips_gradients", "cost_rank", "search", "budget_steps",
                                   "sequence", "needs_front"])
def test_a_kind_missing_a_piece_is_refused_when_declared(piece):
    with pytest.raises(ValueError, match=f"network kind 'flat' lacks: {piece} "):
        NetworkKind("flat", **{**FLAT, piece: None})
    assert "flat" not in kinds.NETWORK_KINDS


def test_a_piece_of_the_wrong_sort_is_refused_when_declared():
    with pytest.raises(ValueError, match="budget_steps must be"):
        NetworkKind("flat", **{**FLAT, "budget_steps": 0})
    with pytest.raises(ValueError, match="clips_gradients must be"):
        NetworkKind("flat", **{**FLAT, "clips_gradients": "yes"})
    with pytest.raises(ValueError, match="declared twice"):
        kinds.NETWORK_KINDS.register(NetworkKind("lstm", **FLAT))


def test_every_consumer_reads_the_declaration(flat_kind):
    preset = Preset("toy-flat", "flat", ("q", "qd", "qdd"), ("tau_m",), window=4, fc_units=8)
    assert "flat" in kinds.NETWORK_KINDS
    assert TrainConfig.recipe("budget").for_preset(preset).budget_steps == 300
    assert train_mod._is_recurrent(preset)  # clips_gradients=True: training clips it
    assert epoch_cost_rank(preset)[0] == -5  # queued before DeLaN (rank 2)
    assert sorted([preset] + list(PRESETS.values()), key=epoch_cost_rank)[0] is preset
    trial = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0)).ask()
    tuned = suggest_preset(trial, preset)
    assert set(trial.params) == {"fc_layers", "fc_units", "activation"}  # the declared search space
    assert (tuned.fc_layers, tuned.fc_units, tuned.activation) == tuple(trial.params[k] for k in
                                                                         ("fc_layers", "fc_units", "activation"))


def test_a_preset_is_held_to_its_kinds_declared_rules():
    with pytest.raises(ValueError, match="kind must be one of"):
        Preset("toy", "gru", ("q",), ("tau_m",))
    kinds.NETWORK_KINDS.register(NetworkKind("flat-front", **{**FLAT, "needs_front": True, "sequence": False}))
    try:
        with pytest.raises(ValueError, match="flat-front needs front_units"):
            Preset("toy", "flat-front", ("q",), ("tau_m",), front_units=())
        with pytest.raises(ValueError, match="flat-front sees the current sample only"):
            Preset("toy", "flat-front", ("q",), ("tau_m",), window=4, front_units=(8,))
        with pytest.raises(ValueError, match="residual_kind must be one of"):
            Preset("toy", "delan", ("q", "qd", "qdd"), ("tau_m",), window=4, residual_kind="delan")
    finally:
        kinds.NETWORK_KINDS.unregister("flat-front")


def test_a_declared_kind_trains_and_runs_its_fast_path(flat_kind, tiny, tmp_path):
    preset = Preset("toy-flat", "flat", ("q", "qd", "qdd"), ("tau_m",), window=4, fc_units=16)
    cfg = TrainConfig.recipe("budget", budget_evals=5, batch_size=64, progress=False, num_threads=1)
    model = train_model(tiny, preset, tmp_path / "m", cfg)
    assert model.config["train_config"]["budget_steps"] == 300  # the kind's budget
    assert model.config["stopped_by"] == "budget" and len(model.config["history"]) == 5
    h = model.config["history"]
    assert h[-1]["train_loss"] < 0.2 * h[0]["train_loss"]  # it learned (this tiny set's val runs differ too much)
    assert isinstance(model.module.net, FlatNet)
    again = load_model(tmp_path / "m")  # loads through the registry too
    inst = tiny.split("test")[0]
    pred = again.predict([inst])[0]
    x = concat_fields([inst], again.inputs).astype(np.float64)
    for k in (0, 2, 50, len(inst) - 1):  # the fast float64 path against the batched torch path
        rows = np.clip(np.arange(k - 3, k + 1), 0, None)
        np.testing.assert_allclose(again.predict_window(x[rows]), pred[k], atol=2e-5 * np.abs(pred).max())


def test_the_built_in_kinds_keep_their_modules_and_order():
    """What the if-chains said, now read from the declarations (the bench's training queue, clipping)."""
    order = sorted(PRESETS, key=epoch_cost_rank)
    assert order[0] == "delan-residual" and order[1:3] == ["delan", "delan-friction"]
    mlps = [n for n in order if PRESETS[n].kind == "mlp"]
    assert order[-len(mlps):] == mlps  # the MLPs last
    assert {n for n, p in PRESETS.items() if train_mod._is_recurrent(p)} == \
        {n for n, p in PRESETS.items() if "lstm" in (p.kind, p.residual_kind)}
    torch.manual_seed(0)
    assert kinds.build_net("conv", 5, 3, 10, (4,), 1, 8, "relu").kind == "conv"
    with pytest.raises(ValueError, match="not a single network"):
        kinds.build_net("delan", 5, 3, 1, (), 1, 8, "relu")
