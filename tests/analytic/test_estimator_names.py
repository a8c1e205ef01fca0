"""One name per analytic estimator (issue 15, item 5): the bench's names everywhere, the older
spellings accepted where users and saved model files give them."""
import numpy as np
import pytest

from hybrid_dyn import TipForceEstimator
from hybrid_dyn.analytic.estimators import ALIASES, ESTIMATORS, estimator_name
from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.estimator import METHODS
from hybrid_dyn.learn.presets import PRESETS, PRIORS, Preset
from hybrid_dyn.learn.priors import PRIOR_FIELDS, AnalyticPrior


def test_the_names_are_the_bench_rows_names():
    assert set(METHODS) | set(PRIOR_FIELDS) | set(PRIORS[1:]) <= set(ESTIMATORS)
    for name, task in ESTIMATORS.items():  # each estimator is a bench row of its task, under that name
        assert ROWS[name].family == "analytic" and ROWS[name].task == task, name
    assert all(c in ESTIMATORS for c in ALIASES.values())
    with pytest.raises(ValueError, match="unknown estimator method 'kalman'; known: base-wrench"):
        TipForceEstimator.analytic("panda", "kalman")


@pytest.mark.parametrize("old, new", [("base_wrench", "base-wrench"), ("torques", "torques-pinv"),
                                      ("momentum", "momentum-observer"), ("base_momentum", "base-momentum"),
                                      ("kalman_fusion", "kalman-fusion")])
def test_an_old_method_spelling_is_the_same_estimator(old, new, panda):
    a = TipForceEstimator.analytic(panda, old, call_hz=100.0, tare_seconds=0.0)
    b = TipForceEstimator.analytic(panda, new, call_hz=100.0, tare_seconds=0.0)
    assert a.method == b.method == new
    rng = np.random.default_rng(0)
    q0 = np.array(panda.spec.home)
    for k in range(5):
        q, qd = q0 + 0.01 * k, rng.normal(0, 0.1, 7)
        w = panda.base_wrench(q, qd, np.zeros(7))
        kw = dict(t=k / 100.0, tau_J=rng.normal(0, 1.0, 7), base_wrench=w)
        np.testing.assert_array_equal(a.estimate_tip_force(q, qd, **kw), b.estimate_tip_force(q, qd, **kw))


def test_old_prior_spellings_load_and_model_files_keep_them(panda):
    assert AnalyticPrior("basewrench", panda).kind == "base-wrench"
    assert AnalyticPrior("rnea-basewrench", panda).kind == "rnea-bw"
    assert estimator_name("momentum", PRIOR_FIELDS) == "momentum-observer"
    for p in PRESETS.values():
        if p.prior is None:
            continue
        d = p.to_dict()
        assert d["prior"] in ALIASES or d["prior"] == p.prior  # written as model files always spelled it
        assert Preset.from_dict(d) == p == Preset.from_dict({**d, "prior": p.prior})
    assert PRESETS["residual-basewrench"].to_dict()["prior"] == "basewrench"


@pytest.mark.slow  # a tiny training run: ~5 s
def test_a_saved_residual_model_loads_and_predicts_identically(panda, tmp_path):
    import json

    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import TrainConfig, load_model, train_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=3, n_samples=60, seed=2))
    model = train_model(ds, "residual-basewrench", tmp_path / "m",
                        TrainConfig(max_epochs=1, max_batches_per_epoch=2, batch_size=64, progress=False))
    stored = json.loads((tmp_path / "m" / "config.json").read_text())
    assert stored["preset"]["prior"] == "basewrench" and stored["prior"]["kind"] == "basewrench"  # the old spelling
    loaded = load_model(tmp_path / "m")
    assert loaded.preset.prior == "base-wrench"
    test = ds.split("test")
    for a, b in zip(model.predict(test), loaded.predict(test)):
        np.testing.assert_array_equal(a, b)
