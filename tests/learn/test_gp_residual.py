"""The semiparametric GP: an identified model plus a sparse GP on its residual.

The logs are built here: Panda joint sines whose torque is an identified model's prediction
plus a residual written down in closed form, so the residual the GP must find is known. The
references are that closed form and ``IdentifiedModel.predict_torque`` of the file loaded
on its own.
"""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.identify import identify
from hybrid_dyn.identify.identified_model import IdentifiedModel
from hybrid_dyn.learn.gp import load_gp
from hybrid_dyn.learn.gp_residual import GPResidualConfig, load_gp_residual, train_gp_residual
from hybrid_dyn.learn.trained_model import ModelError

NV = 7
SMALL = GPResidualConfig(hyper_rows=200, inducing=300, length_scale_factors=(1.0, 2.0), noise_factors=(1.0, 10.0))


def smooth_residual(q: np.ndarray) -> np.ndarray:
    """A known smooth residual [Nm] (N, 7) of the joint positions: what the GP must recover."""
    j = np.arange(NV)
    return 0.8 * np.sin(1.5 * q + j) + 0.4 * np.cos(q[:, [1]] - 0.5 * j)


@pytest.fixture(scope="module")
def prior(panda, tmp_path_factory):
    """An identified parameter file of the Panda (OLS on an exact synthetic log with Gaz friction)."""
    root = tmp_path_factory.mktemp("gp-residual")
    ds = load_dataset(make_synthetic_dataset(root / "ident", panda, n_instances=4, n_samples=200, seed=3,
                                             friction=panda.spec.friction("gaz2019"), tip_forces=False))
    path = identify(ds, "ols", panda).save(root / "identified.json")
    return IdentifiedModel.load(path, robot=panda), path


def panda_log(path, model, panda, residual, n=3000, hz=50.0, seed=0):
    """A CSV log of Panda joint sines (within its limits); tau = the identified model + residual(q) [Nm]."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / hz
    lo, hi = np.maximum(panda.q_lower, -np.pi) + 0.3, np.minimum(panda.q_upper, np.pi) - 0.3
    centre, amp = (lo + hi) / 2, 0.45 * (hi - lo)
    w, p = 2 * np.pi * rng.uniform(0.1, 0.3, NV), rng.uniform(0, 2 * np.pi, NV)
    q = centre + amp * np.sin(w * t[:, None] + p)
    qd, qdd = amp * w * np.cos(w * t[:, None] + p), -amp * w**2 * np.sin(w * t[:, None] + p)
    tau = model.predict_torque(q, qd, qdd) + residual(q)
    names = ["t"] + [f"{k}{j}" for k in ("q", "qd", "qdd", "tau") for j in range(1, NV + 1)]
    np.savetxt(path, np.column_stack([t, q, qd, qdd, tau]), delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")
    return path


def import_panda_log(csv, out, n_blocks=12, **split):
    cols = {k: [f"{c}{j}" for j in range(1, NV + 1)] for k, c in (("q", "q"), ("qd", "qd"), ("qdd", "qdd"),
                                                                      ("tau_m", "tau"))}
    return load_dataset(import_log(csv, out, name="panda-log", robot="panda", time="t", columns=cols,
                                   trajectories="blocks", n_blocks=n_blocks, **split).path)


@pytest.mark.slow  # sklearn's marginal-likelihood fits: ~10-20 s
def test_zero_residual_is_the_identified_model(panda, prior, tmp_path):
    """A log the identified model explains exactly: every joint keeps the prior, and the semiparametric
    model, saved and loaded, predicts what the parameter file alone predicts, to 1e-9 Nm."""
    model, path = prior
    ds = import_panda_log(panda_log(tmp_path / "log.csv", model, panda, lambda q: np.zeros_like(q), n=900),
                          tmp_path / "ds")
    # max_rows: the sparse fit reads 400 of the training rows (the choice on val sees them all).
    fitted = train_gp_residual(ds, path, tmp_path / "m", dataclasses.replace(SMALL, max_rows=400), robot=panda)
    assert fitted.kept_prior == [True] * NV
    assert fitted.config["n_train_samples"] == 400 < sum(len(i) for i in ds.split("train"))
    loaded = load_gp_residual(tmp_path / "m", robot=panda)
    alone = IdentifiedModel.load(path, robot=panda)
    for inst in ds.split("test") + ds.split("train")[:1]:
        expected = alone.predict_torque(inst.q, inst.qd, inst.qdd)
        assert np.abs(expected).max() > 1.0  # a prior that is not itself zero
        np.testing.assert_allclose(loaded.predict([inst])[0], expected, rtol=0, atol=1e-9)
        x = np.concatenate([inst.q, inst.qd, inst.qdd], axis=1)[::50]
        np.testing.assert_allclose(loaded.predict_rows(x), expected[::50], rtol=0, atol=1e-9)
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == ["config.json", "model.safetensors", "timing.json"]


@pytest.mark.slow  # sklearn's marginal-likelihood fits: ~10-20 s
def test_a_known_smooth_residual_is_recovered(panda, prior, tmp_path):
    model, path = prior
    ds = import_panda_log(panda_log(tmp_path / "log.csv", model, panda, smooth_residual), tmp_path / "ds")
    fitted = train_gp_residual(ds, path, tmp_path / "m", SMALL, robot=panda)
    assert fitted.kept_prior == [False] * NV
    test = ds.split("test")
    found = np.concatenate([p - model.predict_torque(i.q, i.qd, i.qdd) for p, i in zip(fitted.predict(test), test)])
    truth = np.concatenate([smooth_residual(i.q) for i in test])
    err = np.sqrt(np.mean((found - truth) ** 2, axis=0))
    size = np.sqrt(np.mean(truth ** 2, axis=0))
    assert (err < 0.1 * size).all(), (err, size)  # each joint's residual, on held-out samples, within 10 %
    # Chosen on val: the recorded validation error is below the prior's on every joint.
    assert all(c["val_mse"] < 0.05 * c["val_mse_prior"] for c in fitted.config["selection"])
    # The file is a GP folder of the residual: a plain GP loader refuses it (it would predict the residual only).
    with pytest.raises(ModelError, match="load_gp_residual"):
        load_gp(tmp_path / "m")
    config = json.loads((tmp_path / "m" / "config.json").read_text())
    assert config["prior"]["params"] == str(path.resolve()) and config["n_inducing"] == SMALL.inducing


@pytest.mark.slow  # sklearn's marginal-likelihood fits: ~10-20 s
def test_a_residual_that_does_not_hold_on_validation_keeps_the_prior(panda, prior, tmp_path):
    """Train blocks carry a residual, the validation and test blocks do not: the GP fits it on train,
    it only hurts on validation, so every joint keeps the prior and the test predictions are the prior's."""
    model, path = prior
    with_r = panda_log(tmp_path / "a.csv", model, panda, smooth_residual, n=1200, seed=0)
    without = [panda_log(tmp_path / f"{n}.csv", model, panda, lambda q: np.zeros_like(q), n=1200, seed=0)
               for n in ("b", "c")]
    cols = {k: [f"{c}{j}" for j in range(1, NV + 1)] for k, c in (("q", "q"), ("qd", "qd"), ("qdd", "qdd"),
                                                                      ("tau_m", "tau"))}
    ds = load_dataset(import_log([with_r, *without], tmp_path / "ds", name="two", robot="panda", time="t",
                                 columns=cols, trajectories="tables", split_by="list",
                                 split_lists={"train": ["a"], "val": ["b"], "test": ["c"]}).path)
    fitted = train_gp_residual(ds, path, tmp_path / "m", SMALL, robot=panda)
    assert fitted.kept_prior == [True] * NV
    inst = ds.split("val")[0]
    np.testing.assert_allclose(fitted.predict([inst])[0], model.predict_torque(inst.q, inst.qd, inst.qdd),
                               rtol=0, atol=1e-9)


def test_prior_file_changed_after_the_fit_is_refused(panda, prior, tmp_path):
    model, path = prior
    own = tmp_path / "identified.json"
    own.write_bytes(path.read_bytes())
    ds = import_panda_log(panda_log(tmp_path / "log.csv", model, panda, smooth_residual, n=900), tmp_path / "ds")
    train_gp_residual(ds, own, tmp_path / "m", SMALL, robot=panda)
    doc = json.loads(own.read_text())
    doc["body_parameters"][next(iter(doc["body_parameters"]))][0] += 0.1
    own.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match="changed since the fit"):
        load_gp_residual(tmp_path / "m", robot=panda)


def test_validation_choice_is_the_fitted_models_own_error_in_any_block_size(monkeypatch):
    """The candidates' validation MSE is accumulated in blocks (a paper-size validation split would not fit
    whole): the recorded MSE of the chosen candidate equals the saved model's own error on the validation
    rows (gp.GPModel.predict_rows, another code path), and blocks of 7 rows choose what one block does."""
    from hybrid_dyn.learn import gp_residual
    from hybrid_dyn.learn.gp import GPHyperparameters, GPModel

    rng = np.random.default_rng(0)
    x, xv = rng.uniform(-1, 1, (400, 3)), rng.uniform(-1, 1, (150, 3))
    f = lambda a: np.stack([np.sin(2 * a[:, 0]) + a[:, 1] ** 2, np.cos(a[:, 2])], axis=1)  # noqa: E731
    r, rv = f(x) + 0.01 * rng.standard_normal((400, 2)), f(xv)
    hyper = GPHyperparameters(np.ones(2), np.full((2, 3), 0.8), np.full(2, 1e-3), [])
    config = GPResidualConfig(inducing=60, noise_factors=(1.0, 100.0), length_scale_factors=(0.5, 1.0))
    tensors, choice = gp_residual.fit_sparse_residual(x, r, xv, rv, config, hyper=hyper)
    own = np.mean((GPModel(tensors, {}).predict_rows(xv) - rv) ** 2, axis=0)
    np.testing.assert_allclose([c["val_mse"] for c in choice], own, rtol=1e-9)
    assert all(not c["kept_prior"] and c["val_mse"] < 0.05 * c["val_mse_prior"] for c in choice)
    monkeypatch.setattr(gp_residual, "CHUNK", 7)
    small, small_choice = gp_residual.fit_sparse_residual(x, r, xv, rv, config, hyper=hyper)
    assert [(c["length_scale_factor"], c["noise_factor"]) for c in small_choice] == \
        [(c["length_scale_factor"], c["noise_factor"]) for c in choice]
    np.testing.assert_allclose(small["alpha"], tensors["alpha"], rtol=1e-9, atol=1e-12)
