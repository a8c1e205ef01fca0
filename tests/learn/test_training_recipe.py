"""The training recipe: the tared sensor reaches the nets, the learning-rate schedule,
and why a run stopped. Tiny synthetic sets with exact physics, built here."""
import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from hybrid_dyn.analytic.tare import TARE_SECONDS
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn import train as train_mod
from hybrid_dyn.learn.presets import PRESETS

from helpers.resume import assert_same_weights, killed_then_resumed

QUICK = dict(batch_size=64, progress=False, num_threads=1)


def _synthetic(path, panda, base_offset):
    return load_dataset(make_synthetic_dataset(path, panda, n_instances=6, n_samples=150, seed=3, noise=0.01,
                                               base_offset=base_offset, contact_free_s=TARE_SECONDS))


@pytest.fixture(scope="module")
def clean_and_biased(tmp_path_factory, panda):
    root = tmp_path_factory.mktemp("bias")
    return _synthetic(root / "clean", panda, 0.0), _synthetic(root / "biased", panda, 2.0)


def test_the_tare_reaches_the_learned_inputs(clean_and_biased, tmp_path):
    """A net trained on a biased, then tared, set is the net trained on the bias-free set; on the raw
    sensor it is not (the offset, up to 2 N per axis and run, is in its inputs)."""
    clean, biased = clean_and_biased
    offsets = [b.base_wrench[0] - c.base_wrench[0] for b, c in zip(biased.split("train"), clean.split("train"))]
    assert np.abs(offsets).max() > 0.5  # the two sets do differ by a per-run offset
    cfg = TrainConfig(max_epochs=4, **QUICK)
    raw = PRESETS.lookup("seed-tip-1").replace(name="seed-tip-1-raw", raw_sensor=True)
    rms = {}
    for label, preset in (("tared", "seed-tip-1"), ("raw", raw)):
        a = train_model(clean, preset, tmp_path / "clean" / label, cfg)
        b = train_model(biased, preset, tmp_path / "biased" / label, cfg)
        assert b.sensor_tare_seconds == (TARE_SECONDS if label == "tared" else 0.0)
        pa = np.concatenate(a.predict(clean.split("test")))
        pb = np.concatenate(b.predict(biased.split("test")))
        rms[label] = float(np.sqrt(np.mean((pa - pb) ** 2)))
    assert rms["tared"] < 1e-3, rms  # the same net, up to float32 rounding of the inputs
    assert rms["raw"] > 0.05, rms


def test_stopped_by_the_epoch_cap_and_by_patience(clean_and_biased, tmp_path):
    clean, _ = clean_and_biased
    capped = train_model(clean, "seed-tip-1", tmp_path / "cap", TrainConfig(max_epochs=2, **QUICK))
    assert capped.config["stopped_by"] == "epoch-cap" and capped.config["epochs"] == 2
    # lr 0.05 without a schedule: the validation loss soon stops improving, and patience 1 stops at once.
    early = train_model(clean, "seed-tip-1", tmp_path / "early",
                        TrainConfig(max_epochs=60, patience=1, lr=0.05, lr_schedule="none", **QUICK))
    h = early.config["history"]
    assert early.config["stopped_by"] == "patience" and len(h) < 60
    best = early.config["best_epoch"]
    assert best == len(h) - 2  # patience 1: the epoch before the last was the best
    assert h[-1]["val_loss"] >= min([early.config["initial_val_loss"]] + [e["val_loss"] for e in h[:-1]])
    assert early.val_loss == (h[best]["val_loss"] if best >= 0 else early.config["initial_val_loss"])


def _expected_rates(history, initial_val, cfg):
    """The plateau rule applied by hand to the recorded validation losses: the rate of each epoch."""
    rates, lr, best, bad = [], cfg.lr, initial_val, 0
    for e in history:
        rates.append(lr)
        if e["val_loss"] < best - max(cfg.min_delta, cfg.min_rel_delta * best):
            best, bad = e["val_loss"], 0
        else:
            bad += 1
            if bad >= cfg.lr_patience:
                lr, bad = max(lr * cfg.lr_factor, cfg.min_lr), 0
    return rates


def test_the_schedule_cuts_the_rate_after_a_plateau_down_to_its_floor(clean_and_biased, tmp_path):
    clean, _ = clean_and_biased
    cfg = TrainConfig(max_epochs=80, patience=80, lr=0.05, lr_factor=0.1, lr_patience=1, min_lr=5e-4, **QUICK)
    model = train_model(clean, "seed-tip-1", tmp_path / "m", cfg)
    h = model.config["history"]
    rates = [e["lr"] for e in h]
    assert rates[0] == cfg.lr and min(rates) < cfg.lr  # a plateau came, and the rate was cut
    np.testing.assert_allclose(rates, _expected_rates(h, model.config["initial_val_loss"], cfg), rtol=1e-12)
    assert model.config["stopped_by"] == "lr-floor" and rates[-1] == pytest.approx(cfg.min_lr)
    assert h[-1]["val_loss"] >= model.val_loss


@pytest.mark.parametrize("weight_decay", [0.0, 0.5])  # Adam, and AdamW with its two parameter groups
def test_resume_mid_schedule_is_bit_identical(clean_and_biased, tmp_path, monkeypatch, weight_decay):
    clean, _ = clean_and_biased
    cfg = TrainConfig(max_epochs=8, patience=20, lr=0.05, lr_factor=0.3, lr_patience=1, min_lr=1e-5,
                      weight_decay=weight_decay, **QUICK)
    straight = train_model(clean, "seed-tip-7", tmp_path / "a", cfg)
    rates = [e["lr"] for e in straight.config["history"]]
    cut = next(i for i, r in enumerate(rates) if r < cfg.lr)  # the first epoch at a cut rate
    assert cut < len(rates) - 1, rates  # the kill below falls after a cut, with epochs still to run

    resumed = killed_then_resumed(monkeypatch, clean, "seed-tip-7", tmp_path / "b", cfg, cut)
    assert_same_weights(tmp_path / "a", tmp_path / "b")
    assert resumed.config["history"] == straight.config["history"]
    assert resumed.config["stopped_by"] == straight.config["stopped_by"]


def test_recurrent_gradients_are_clipped(clean_and_biased, tmp_path, monkeypatch):
    clean, _ = clean_and_biased
    norms = []
    real = torch.nn.utils.clip_grad_norm_

    def spy(params, max_norm, *a, **k):
        norms.append(max_norm)
        return real(params, max_norm, *a, **k)

    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", spy)
    train_model(clean, "seed-tip-7", tmp_path / "lstm", TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK))
    assert norms == [1.0, 1.0]
    train_model(clean, "seed-tip-1", tmp_path / "mlp", TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK))
    assert norms == [1.0, 1.0]  # an MLP is not clipped
    seed = TrainConfig.recipe("seed-study", max_epochs=1, max_batches_per_epoch=2, **QUICK)
    assert (seed.lr_schedule, seed.patience, seed.grad_clip) == ("none", 5, None)
    train_model(clean, "seed-tip-7", tmp_path / "seed", seed)
    assert norms == [1.0, 1.0]  # the reference study's recipe clips nothing


def test_weight_decay_is_decoupled_and_spares_biases_and_physical_parameters():
    """AdamW's identity: with a zero gradient Adam's step is zero, so one step leaves each decayed weight
    at w (1 - lr x weight_decay); biases and 1-D physical parameters (DeLaN's friction) stay put."""
    torch.manual_seed(0)
    module = torch.nn.Sequential(torch.nn.Linear(3, 4), torch.nn.Linear(4, 2))
    module.register_parameter("friction", torch.nn.Parameter(torch.rand(7) + 0.5))
    before = {k: v.detach().clone() for k, v in module.named_parameters()}
    cfg = TrainConfig(lr=1e-2, weight_decay=3.0, progress=False)
    opt = train_mod._optimizer(module, cfg)
    for p in module.parameters():
        p.grad = torch.zeros_like(p)
    opt.step()
    for k, p in module.named_parameters():
        expected = before[k] * (1 - cfg.lr * cfg.weight_decay) if p.ndim >= 2 else before[k]
        torch.testing.assert_close(p.detach(), expected, rtol=1e-6, atol=0.0)
    assert isinstance(train_mod._optimizer(module, TrainConfig(progress=False)), torch.optim.Adam)


def test_weight_decay_reaches_training_and_only_its_runs_change_fingerprint(clean_and_biased, tmp_path):
    clean, _ = clean_and_biased
    plain, decayed = TrainConfig(max_epochs=3, **QUICK), TrainConfig(max_epochs=3, weight_decay=30.0, **QUICK)
    assert "weight_decay" not in plain.fingerprint_fields()  # runs from before the field keep their fingerprint
    assert decayed.fingerprint_fields()["weight_decay"] == 30.0
    norms = {}
    for label, cfg in (("plain", plain), ("decayed", decayed)):
        state = load_file(str(train_model(clean, "seed-tip-1", tmp_path / label, cfg).path / "model.safetensors"))
        norms[label] = sum(float(v.norm() ** 2) for k, v in state.items() if v.ndim >= 2 and "weight" in k)
    assert norms["decayed"] < 0.9 * norms["plain"], norms
    with pytest.raises(Exception, match="weight_decay"):
        TrainConfig(weight_decay=-1.0)
