"""The budgeted recipe: a fixed number of optimizer steps, a warm-up, a cosine decay to zero,
batches from the whole pool, and a resume that is bit-identical. Tiny synthetic sets, built here."""
import math

import numpy as np
import pytest

from hybrid_dyn.analytic.tare import TARE_SECONDS
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.errors import UsageError
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn import train as train_mod
from hybrid_dyn.learn.kinds import NETWORK_KINDS
from hybrid_dyn.learn.presets import PRESETS

from helpers.resume import assert_same_weights, killed_then_resumed

QUICK = dict(batch_size=64, progress=False, num_threads=1)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory, panda):
    root = tmp_path_factory.mktemp("budget")
    return load_dataset(make_synthetic_dataset(root / "d", panda, n_instances=6, n_samples=150, seed=3, noise=0.01,
                                               contact_free_s=TARE_SECONDS))


def test_the_schedule_warms_up_then_decays_to_zero():
    cfg = TrainConfig.recipe("budget", budget_steps=1000, warmup_fraction=0.1)
    assert cfg.batch_size == 1024 and cfg.lr == pytest.approx(2e-3)
    lr = [train_mod.budget_lr(cfg, s) for s in range(1000)]
    assert lr[0] == pytest.approx(cfg.lr / 100)  # step 0 of a 100-step warm-up
    assert lr[99] == pytest.approx(cfg.lr)  # the last warm-up step reaches the rate
    assert lr[100] == pytest.approx(cfg.lr)  # the cosine starts at the top
    assert lr[550] == pytest.approx(cfg.lr / 2)  # half-way through the decay
    assert 0 < lr[-1] < 1e-4 * cfg.lr  # the last step trains at almost nothing: the rate ends at zero
    assert np.all(np.diff(lr[:100]) > 0) and np.all(np.diff(lr[100:]) < 0)
    # cos(pi x progress): the closed form at one more point
    assert lr[325] == pytest.approx(cfg.lr * 0.5 * (1 + math.cos(math.pi * 225 / 900)))


def test_a_budgeted_run_spends_its_steps_on_the_whole_pool(tiny, tmp_path, monkeypatch):
    seen = []
    real = train_mod._batches

    def spy(ws, idx, device):
        if len(ws) == n_train[0]:
            seen.append(idx.copy())
        return real(ws, idx, device)

    n_train = [None]
    real_fit = train_mod._fit

    def fit(module, opt, preset, config, ds, ws_train, *a):
        n_train[0] = len(ws_train)
        return real_fit(module, opt, preset, config, ds, ws_train, *a)

    monkeypatch.setattr(train_mod, "_batches", spy)
    monkeypatch.setattr(train_mod, "_fit", fit)
    cfg = TrainConfig.recipe("budget", budget_steps=50, budget_evals=5, **QUICK)
    model = train_model(tiny, "seed-tip-1", tmp_path / "m", cfg)
    h = model.config["history"]
    assert model.config["stopped_by"] == "budget" and len(h) == 5
    assert model.config["train_config"]["budget_steps"] == 50
    assert len(seen) == 50  # exactly the budget's optimizer steps
    # every training sample is drawn, epoch after epoch (no sample left out of the pool)
    n = n_train[0]
    per_epoch = -(-n // 64)
    assert 50 > per_epoch
    assert set(np.concatenate(seen[:per_epoch]).tolist()) == set(range(n))
    assert h[-1]["lr"] < 0.01 * cfg.lr  # the last round ran at the tail of the cosine
    assert model.val_loss == min([model.config["initial_val_loss"]] + [e["val_loss"] for e in h])


def test_the_budget_comes_from_the_network_kind_and_is_in_the_fingerprint():
    cfg = TrainConfig.recipe("budget")
    for name in ("seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm", "delan-friction"):
        preset = PRESETS.lookup(name)
        assert cfg.for_preset(preset).budget_steps == NETWORK_KINDS[preset.kind].budget_steps
    a = cfg.for_preset(PRESETS.lookup("delan")).fingerprint_fields()
    b = TrainConfig.recipe("budget", budget_steps=3).fingerprint_fields()
    assert a["budget_steps"] != b["budget_steps"]
    # an epoch recipe's fingerprint does not carry the budget's fields (older runs stay valid)
    assert "budget_steps" not in TrainConfig().fingerprint_fields()
    with pytest.raises(UsageError, match="warmup_fraction"):
        TrainConfig.recipe("budget", warmup_fraction=1.0)
    assert all(k.budget_steps > 0 for k in NETWORK_KINDS.values())  # a network kind without a budget could not train under it


def test_resume_mid_budget_is_bit_identical(tiny, tmp_path, monkeypatch):
    cfg = TrainConfig.recipe("budget", budget_steps=40, budget_evals=8, warmup_fraction=0.2, **QUICK)
    straight = train_model(tiny, "seed-tip-7", tmp_path / "a", cfg)
    # killed mid-budget: after the warm-up, rounds still to run
    resumed = killed_then_resumed(monkeypatch, tiny, "seed-tip-7", tmp_path / "b", cfg, 3)
    assert_same_weights(tmp_path / "a", tmp_path / "b")
    assert resumed.config["history"] == straight.config["history"]
    assert resumed.config["stopped_by"] == "budget"


def test_budget_patience_ends_the_run_on_the_whole_runs_rounds(tiny, tmp_path):
    """A budgeted run with budget_patience P is the whole run cut after P idle rounds: the rounds it ran
    equal the whole run's first rounds (the schedule stays the whole budget's), and it keeps the whole
    run's best weights when the best round came before the cut."""
    whole_cfg = TrainConfig.recipe("budget", budget_steps=60, budget_evals=12, **QUICK)
    whole = train_model(tiny, "seed-tip-7", tmp_path / "whole", whole_cfg)
    h = whole.config["history"]
    best, idle, cut = whole.config["initial_val_loss"], 0, None
    for i, e in enumerate(h):  # where patience 2 must stop, read off the whole run's validation curve
        if e["val_loss"] < best - 1e-4 * abs(best):
            best, idle = e["val_loss"], 0
        else:
            idle += 1
            if idle >= 2 and cut is None:
                cut = i
    assert cut is not None and cut + 1 < len(h), "the tiny run must plateau for this test to say anything"
    short = train_model(tiny, "seed-tip-7", tmp_path / "short",
                        TrainConfig.recipe("budget", budget_steps=60, budget_evals=12, budget_patience=2, **QUICK))
    assert short.config["stopped_by"] == "patience"
    assert short.config["history"] == h[:cut + 1]
    if whole.config["best_epoch"] <= cut:
        assert_same_weights(tmp_path / "whole", tmp_path / "short")
    assert "budget_patience" not in whole_cfg.fingerprint_fields()  # older runs keep their models
    with pytest.raises(UsageError, match="budget-patience"):
        TrainConfig.recipe("budget", budget_patience=0)
