"""Older spellings of the analytic priors (issue 15, item 5): accepted where presets and saved model
files give them, and a model file written with one loads and predicts as it did."""
import numpy as np
import pytest

from hybrid_dyn.analytic.estimators import ALIASES, estimator_name
from hybrid_dyn.learn.presets import PRESETS, Preset
from hybrid_dyn.learn.priors import PRIOR_FIELDS, AnalyticPrior


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
