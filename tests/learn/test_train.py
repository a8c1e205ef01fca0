"""Learned models: training, residual nets, model files, the fast path, the CLI.

All data are tiny synthetic sets with exact physics (Pinocchio), built here.
"""
import json

import numpy as np
import pytest
import torch
from safetensors.torch import load_file, save_file

import hybrid_dyn as hd
from hybrid_dyn.analytic.tare import TARE_SECONDS, tare_samples
from hybrid_dyn.analytic.tip_force import tip_force_from_base_wrench
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.input_windows import concat_fields
from hybrid_dyn.learn import PRESETS, ModelError, TrainConfig, load_model, train_model
from hybrid_dyn.learn import train as train_mod
from hybrid_dyn.learn.priors import AnalyticPrior

from helpers.resume import assert_same_weights, killed_then_resumed

# torch's forward-mode AD (DeLaN's jvp) loads decompositions through the deprecated torch.jit.script.
pytestmark = [pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning"),
              pytest.mark.usefixtures("one_thread")]

QUICK = dict(batch_size=64, progress=False, num_threads=1)


@pytest.fixture(scope="module")
def friction_set(tmp_path_factory, panda):
    """Tip forces and Gaz friction: every preset has something to learn."""
    path = tmp_path_factory.mktemp("fr") / "ds"
    return load_dataset(make_synthetic_dataset(path, panda, n_instances=5, n_samples=120, seed=1,
                                               friction=panda.spec.friction("gaz2019")))


@pytest.fixture(scope="module")
def exact_set(tmp_path_factory, panda):
    """Tip forces clear of the first 0.5 s, a base-sensor offset of up to 2 N per run, no friction, 0.01 sensor
    noise: the base-wrench method on the tared sensor is exact up to the noise."""
    path = tmp_path_factory.mktemp("ex") / "ds"
    return load_dataset(make_synthetic_dataset(path, panda, n_instances=8, n_samples=150, seed=2, noise=0.01,
                                               base_offset=2.0, contact_free_s=TARE_SECONDS))


def _tared_base_wrench_force(r, f):
    """The base-wrench method after a tare on the first TARE_SECONDS (100 Hz), from the analytic layer alone."""
    n = tare_samples(100.0, TARE_SECONDS)
    w = f["base_wrench"] - (f["base_wrench"][:n] - r.base_wrench(f["q"][:n], f["qd"][:n], f["qdd"][:n])).mean(0)
    return tip_force_from_base_wrench(r, f["q"], f["qd"], f["qdd"], w)


@pytest.fixture(scope="module")
def free_set(tmp_path_factory, panda):
    """No tip forces, no friction, 0.01 sensor noise: RNEA is exact for tau_m up to the noise."""
    path = tmp_path_factory.mktemp("free") / "ds"
    return load_dataset(make_synthetic_dataset(path, panda, n_instances=8, n_samples=150, seed=3, tip_forces=False,
                                               noise=0.01))


@pytest.fixture(scope="module")
def tip11(friction_set, tmp_path_factory):
    return train_model(friction_set, "seed-tip-11", tmp_path_factory.mktemp("m") / "tip11",
                       TrainConfig(max_epochs=2, **QUICK))


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_trains_and_its_loss_falls(name, friction_set, tmp_path):
    model = train_model(friction_set, name, tmp_path / name, TrainConfig(max_epochs=3, max_batches_per_epoch=6, **QUICK))
    losses = [h["train_loss"] for h in model.history]
    assert len(losses) == 3 and all(np.isfinite(losses))
    assert losses[-1] < losses[0], losses
    pred = model.predict(friction_set.split("test"))
    assert [p.shape for p in pred] == [(len(i), 3 if "tip_force" in model.targets else 7) for i in friction_set.split("test")]


def test_presets_match_seed_table_1():
    # (architecture, joint torques, FC layers, neurons, sequence length) from the reference study's Table 1
    table = {1: ("mlp", False, 2, 32, 1), 2: ("mlp", True, 2, 32, 1), 3: ("mlp", True, 2, 16, 1),
             4: ("conv", False, 2, 16, 10), 5: ("conv", False, 2, 16, 5), 6: ("conv", True, 2, 16, 5),
             7: ("lstm", False, 2, 16, 10), 8: ("lstm", True, 2, 16, 10), 9: ("lstm", True, 2, 16, 5),
             10: ("lstm", False, 2, 16, 10), 11: ("lstm", True, 2, 8, 10)}
    for no, (kind, torques, layers, units, window) in table.items():
        p = PRESETS[f"seed-tip-{no}"]
        assert (p.kind, "tau_J" in p.inputs, p.fc_layers, p.fc_units, p.window) == (kind, torques, layers, units, window)
        assert p.targets == ("tip_force",) and set(p.inputs) >= {"base_wrench", "q", "qd", "qdd"}
        assert p.front_units == ((32, 32) if no >= 10 else () if kind == "mlp" else (16,))
    opt = PRESETS["seed-tau-lstm-opt"]
    assert (opt.front_units, opt.fc_layers, opt.fc_units, opt.activation) == ((32, 32), 2, 8, "tanh")
    assert all(PRESETS[n].inputs == ("q", "qd", "qdd") for n in ("seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm"))


@pytest.mark.slow
@pytest.mark.parametrize("name,dataset,prior_fn", [
    ("residual-basewrench", "exact_set", _tared_base_wrench_force),
    ("residual-rnea", "free_set", lambda r, f: r.inverse_dynamics(f["q"], f["qd"], f["qdd"])),
])
def test_residual_net_adds_nothing_where_physics_is_exact(name, dataset, prior_fn, request, tmp_path, panda):
    """Physics is exact on the noise-free truth; the sensors add noise, so the net does get
    gradients (of pure noise) and must not turn them into a correction."""
    ds = request.getfixturevalue(dataset)
    test = ds.split("test")
    model = train_model(ds, name, tmp_path / name, TrainConfig(max_epochs=20, **QUICK))
    y_std = model.module.y_std.double().numpy()
    for inst, pred in zip(test, model.predict(test)):
        # The analytic part, computed independently, is the truth on noise-free data.
        assert np.allclose(prior_fn(panda, inst.truth), inst.truth[model.targets[0]], atol=1e-6)
        net_part = (pred - prior_fn(panda, inst)) / y_std
        assert np.sqrt(np.mean(net_part ** 2)) < 0.05, np.sqrt(np.mean(net_part ** 2))


def test_save_load_predict_is_bit_identical(tip11, friction_set):
    test = friction_set.split("test")
    again = load_model(tip11.path, robot="panda")
    for a, b in zip(tip11.predict(test), again.predict(test)):
        assert np.array_equal(a, b)
    assert again.config == tip11.config and again.n_params == tip11.n_params


def test_predict_window_matches_batched_predict(tip11, friction_set, tmp_path):
    inst = friction_set.split("test")[0]
    pred = tip11.predict([inst])[0]
    assert tip11.sensor_tare_seconds > 0  # predict_window is given the wrench as the net sees it: tared
    x = concat_fields(tip11.sensor_view([inst]), tip11.inputs).astype(np.float64)
    for k in (0, 3, 60, len(inst) - 1):  # edge-padded start, mid-run, end
        rows = np.clip(np.arange(k - tip11.window + 1, k + 1), 0, None)
        np.testing.assert_allclose(tip11.predict_window(x[rows]), pred[k], atol=2e-5 * np.abs(pred).max())
    with pytest.raises(ModelError, match="shape"):
        tip11.predict_window(x[:3])


@pytest.mark.parametrize("name", ["delan-residual", "residual-rnea-bw", "seed-tip-4", "tau-mlp-wide"])
def test_predict_window_matches_batched_predict_other_families(name, friction_set, tmp_path):
    model = train_model(friction_set, name, tmp_path / name, TrainConfig(max_epochs=1, max_batches_per_epoch=3, **QUICK))
    inst = friction_set.split("test")[0]
    pred = model.predict([inst])[0]
    x = concat_fields(model.sensor_view([inst]), model.inputs).astype(np.float64)
    tared = model.prior is not None and model.prior.tare_seconds > 0
    prior = model.prior.compute({f: inst[f] for f in model.prior.fields}) if tared else None
    for k in (0, 40):
        rows = np.clip(np.arange(k - model.window + 1, k + 1), 0, None)
        if tared:  # the tare's offset comes from the run's start, not from the window
            with pytest.raises(ModelError, match="tares the base sensor"):
                model.predict_window(x[rows])
        got = model.predict_window(x[rows], prior=None if prior is None else prior[k])
        np.testing.assert_allclose(got, pred[k], atol=2e-5 * np.abs(pred).max())


def test_single_sample_priors_match_batched_analytic_functions(friction_set, panda):
    inst = friction_set.split("train")[0]
    jv = panda.tip_jacobian(inst.q)[:, :3, :]
    f_bw = tip_force_from_base_wrench(panda, inst.q, inst.qd, inst.qdd, inst.base_wrench)
    expected = {"rnea": panda.inverse_dynamics(inst.q, inst.qd, inst.qdd), "base-wrench": f_bw,
                "rnea-bw": panda.inverse_dynamics(inst.q, inst.qd, inst.qdd) - np.einsum("nij,ni->nj", jv, f_bw)}
    for kind, ref in expected.items():
        prior = AnalyticPrior(kind, panda)
        np.testing.assert_allclose(prior.compute({k: inst[k] for k in prior.fields}), ref, atol=1e-9)
        for k in (0, 57):
            np.testing.assert_allclose(prior.single({f: inst[f][k] for f in prior.fields}), ref[k], atol=1e-9)


def test_analytic_part_is_cached_per_dataset(friction_set, panda, tmp_path):
    prior = AnalyticPrior("base-wrench", panda)
    insts = friction_set.split("val")
    first = prior.compute_instances(insts, tmp_path, friction_set.checksum)
    files = list(tmp_path.glob("prior-base-wrench-*.h5"))  # the canonical name
    assert len(files) == 1 and not list(tmp_path.glob("prior-basewrench-*"))
    prior.compute = None  # a second call must not compute: it reads the cache
    second = prior.compute_instances(insts, tmp_path, friction_set.checksum)
    for a, b in zip(first, second):
        assert np.array_equal(a, b)
    # A cache written before model format 3 (the older spelling in its name, the same key) is found, renamed.
    older = files[0].with_name(files[0].name.replace("prior-base-wrench-", "prior-basewrench-"))
    files[0].rename(older)
    third = prior.compute_instances(insts, tmp_path, friction_set.checksum)  # prior.compute is None: read, not made
    assert all(np.array_equal(a, b) for a, b in zip(first, third))
    assert files[0].is_file() and not older.exists()
    # Another robot parameter set is another cache entry.
    other = AnalyticPrior("base-wrench", hd.load_robot("panda", params="franka_official"))
    other.compute_instances(insts, tmp_path, friction_set.checksum)
    assert len(list(tmp_path.glob("prior-base-wrench-*.h5"))) == 2


def test_training_is_deterministic_and_resumes_after_a_kill(friction_set, tmp_path, monkeypatch):
    cfg = TrainConfig(max_epochs=3, max_batches_per_epoch=4, patience=10, **QUICK)
    straight = train_model(friction_set, "seed-tip-7", tmp_path / "a", cfg)

    def a_checkpoint_and_no_model():
        assert (tmp_path / "b" / "checkpoint.safetensors").is_file() and not (tmp_path / "b" / "config.json").exists()

    # killed right after epoch 2's checkpoint
    resumed = killed_then_resumed(monkeypatch, friction_set, "seed-tip-7", tmp_path / "b", cfg, kill_after_epoch=1,
                                  between=a_checkpoint_and_no_model)
    assert_same_weights(tmp_path / "a", tmp_path / "b")
    strip = lambda h: [{k: v for k, v in e.items()} for e in h]  # noqa: E731
    assert strip(resumed.history) == strip(straight.history)
    assert not (tmp_path / "b" / "checkpoint.json").exists()
    # A finished model of the same run is reused, not retrained.
    mtime = (tmp_path / "a" / "model.safetensors").stat().st_mtime_ns
    assert train_model(friction_set, "seed-tip-7", tmp_path / "a", cfg).val_loss == straight.val_loss
    assert (tmp_path / "a" / "model.safetensors").stat().st_mtime_ns == mtime
    # Another run into the same directory is refused, nothing overwritten.
    with pytest.raises(ModelError, match="another run"):
        train_model(friction_set, "seed-tip-8", tmp_path / "a", cfg)


@pytest.mark.slow
def test_sigkilled_training_resumes_to_the_same_model(friction_set, tmp_path):
    """A real kill -9 of `hybrid-dyn train` mid-run; the rerun resumes from the last checkpoint."""
    import os
    import signal
    import subprocess
    import sys
    import time

    args = ["--max-epochs", "40", "--batch-size", "16", "--threads", "1", "--quiet"]
    cfg = TrainConfig.recipe("plateau", max_epochs=40, batch_size=16, progress=False, num_threads=1)  # the CLI's
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "hybrid_dyn.cli", "train", "--data", str(friction_set.path),
                             "--preset", "seed-tip-5", "--out", str(out)] + args)
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        ck = out / "checkpoint.json"
        if ck.is_file() and json.loads(ck.read_text() or "{}").get("epoch", -1) >= 1:
            os.kill(proc.pid, signal.SIGKILL)
            break
        time.sleep(0.05)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "training ended before it could be killed"
    assert not (out / "config.json").exists()
    resumed = train_model(friction_set, "seed-tip-5", out, cfg)
    straight = train_model(friction_set, "seed-tip-5", tmp_path / "straight", cfg)
    a, b = load_file(str(out / "model.safetensors")), load_file(str(tmp_path / "straight" / "model.safetensors"))
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert resumed.history == straight.history


def test_tampered_config_is_refused(tip11, tmp_path):
    import shutil

    d = tmp_path / "m"
    shutil.copytree(tip11.path, d)
    cfg = json.loads((d / "config.json").read_text())
    cfg["window"] = 5
    (d / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(ModelError, match="tampered"):
        load_model(d)


def test_unknown_or_other_robot_is_refused(tip11, friction_set, tmp_path):
    import shutil

    from hybrid_dyn.learn.trained_model import file_metadata

    with pytest.raises(ModelError, match="not 'ur5'"):
        load_model(tip11.path, robot="ur5")

    def relabel(src, d):
        shutil.copytree(src, d)
        cfg = json.loads((d / "config.json").read_text())
        cfg["robot"] = "r2d2"
        # Re-sign it properly: the robot check must stand on its own, not on the digest.
        tensors = load_file(str(d / "model.safetensors"))
        save_file(tensors, str(d / "model.safetensors"), metadata=file_metadata(cfg, tensors))
        (d / "config.json").write_text(json.dumps(cfg))
        return d

    # A data-only model needs no description of its robot: it loads under any name.
    tau = train_model(friction_set, "seed-tau-mlp", tmp_path / "tau",
                      TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK))
    assert load_model(relabel(tau.path, tmp_path / "m"), robot="r2d2").config["robot"] == "r2d2"
    # A net on the tared base sensor does: the tare subtracts the robot's model wrench.
    with pytest.raises(ModelError, match="sensor tare"):
        load_model(relabel(tip11.path, tmp_path / "m11"), robot="r2d2")
    # One with an analytic part does.
    res = train_model(friction_set, "residual-basewrench", tmp_path / "res",
                      TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK))
    with pytest.raises(ModelError, match="description of robot 'r2d2'"):
        load_model(relabel(res.path, tmp_path / "res-r2d2"))


def test_inputs_the_model_was_not_trained_on_are_refused(tip11, tmp_path, ur5):
    ds = load_dataset(make_synthetic_dataset(tmp_path / "ur5", ur5, n_instances=3, n_samples=30))
    with pytest.raises(ModelError, match="columns"):
        tip11.predict(ds.split("test"))


def test_nan_in_data_is_refused_by_name(tip11, tmp_path, panda):
    from hybrid_dyn.data import write_instance

    ds_path = make_synthetic_dataset(tmp_path / "ds", panda, n_instances=3, n_samples=40)
    ds = load_dataset(ds_path)
    inst = ds.split("test")[0]
    fields = {k: np.array(inst[k]) for k in inst.fields}
    fields["qd"][7, 2] = np.nan
    write_instance(tmp_path / "bad.h5", fields)
    bad = type(inst)("bad", tmp_path / "bad.h5", inst.fields, len(inst))
    with pytest.raises(ModelError, match="bad: field qd holds NaN"):
        tip11.predict([bad])


def test_bad_dataset_or_preset_is_refused(friction_set, tmp_path):
    with pytest.raises(ValueError, match="unknown preset"):
        train_model(friction_set, "seed-tip-12", tmp_path / "x")
    with pytest.raises(ModelError, match="not a finished model"):
        load_model(tmp_path)


def test_cli_train_predict_and_tune(friction_set, tmp_path, capsys):
    from hybrid_dyn.cli import main

    common = ["--max-epochs", "2", "--batch-size", "64", "--max-batches-per-epoch", "3", "--quiet", "--threads", "1"]
    assert main(["train", "--data", str(friction_set.path), "--preset", "seed-tau-mlp", "--out", str(tmp_path / "m")] + common) == 0
    assert main(["predict", "--model", str(tmp_path / "m"), "--data", str(friction_set.path),
                 "--save", str(tmp_path / "p.h5")]) == 0
    out = capsys.readouterr().out
    result = json.loads(out[out.index("{"):])
    assert result["preset"] == "seed-tau-mlp" and len(result["rmse_per_component"]) == 7
    assert (tmp_path / "p.h5").is_file()
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    assert main(["tune", "--data", str(friction_set.path), "--preset", "seed-tau-lstm", "--trials", "2",
                 "--out", str(tmp_path / "tune"), "--storage", storage] + common) == 0
    best = json.loads((tmp_path / "tune" / "best.json").read_text())
    assert best["n_trials"] == 2 and set(best["best_params"]) == {"lstm_layers", "lstm_units", "fc_layers", "fc_units", "activation"}
    # The study lives in the given RDB: a rerun adds trials to it.
    assert main(["tune", "--data", str(friction_set.path), "--preset", "seed-tau-lstm", "--trials", "1",
                 "--out", str(tmp_path / "tune"), "--storage", storage] + common) == 0
    assert json.loads((tmp_path / "tune" / "best.json").read_text())["n_trials"] == 3


def test_dropout_acts_in_training_only(friction_set, tmp_path):
    """tau-mlp-wide drops hidden units while training (two forward passes differ) and never when predicting."""
    model = train_model(friction_set, "tau-mlp-wide", tmp_path / "w", TrainConfig(max_epochs=1, max_batches_per_epoch=2, **QUICK))
    drops = [m for m in model.module.net.modules() if isinstance(m, torch.nn.Dropout)]
    assert [d.p for d in drops] == [0.2, 0.2]
    x = torch.randn(64, 1, 21)
    model.module.net.train()
    assert not torch.equal(model.module.net(x), model.module.net(x))
    model.module.net.eval()
    assert torch.equal(model.module.net(x), model.module.net(x))
    inst = friction_set.split("test")[0]
    np.testing.assert_array_equal(model.predict([inst])[0], model.predict([inst])[0])


def test_a_residual_net_trains_on_the_callers_thread_count(friction_set, tmp_path, monkeypatch):
    """Pinocchio's parallel RNEA, which computes the residual's prior, sets OpenMP's thread count for the
    process, and torch's count is OpenMP's. The net must still train on the caller's count (the bench's
    workers ask for one thread each), and the caller must get its count back."""
    seen = []
    fit = train_mod._fit
    monkeypatch.setattr(train_mod, "_fit", lambda *a, **k: (seen.append(torch.get_num_threads()), fit(*a, **k))[1])
    cfg = TrainConfig(max_epochs=1, max_batches_per_epoch=2, batch_size=64, progress=False)  # num_threads: the caller's
    torch.set_num_threads(1)  # what the bench's workers ask for
    train_model(friction_set, "residual-rnea", tmp_path / "m", cfg)
    assert seen == [1]
    assert torch.get_num_threads() == 1
