"""Older spellings of the analytic priors: accepted where presets and saved model
files give them, with a warning; model files write the canonical names, training fingerprints
keep the older spellings, and a format-2 model file loads, is reused and upgrades."""
import json
import warnings

import numpy as np
import pytest

from hybrid_dyn.analytic.methods import estimator_name, residual_prior_names
from hybrid_dyn.deprecation import DeprecatedNameWarning
from hybrid_dyn.learn.presets import PRESETS, PRIOR_FINGERPRINT_SPELLING, Preset, prior_fingerprint_spelling
from hybrid_dyn.learn.priors import PRIOR_FIELDS, AnalyticPrior

# run_fingerprint of two presets on dataset checksum "0" * 64, by the code before the rename (commit cbc35cb).
FINGERPRINT_RESIDUAL_BASEWRENCH_BUDGET = "fb30e3664d773567556a7f5052ef5b81b5da713cdc814440f28f3cb333724462"
FINGERPRINT_RESIDUAL_RNEA_BW_PLATEAU = "80fecbb86c5ca00189d2694f3feec06e17031b06b1e08017bc00fa6ec74b08f1"


def test_old_prior_spellings_warn_and_model_files_write_the_canonical_names(panda):
    for old, new in (("basewrench", "base-wrench"), ("rnea-basewrench", "rnea-bw"), ("momentum", "momentum-observer")):
        with pytest.warns(DeprecatedNameWarning, match=f"'{old}' is deprecated: use '{new}'"):
            assert estimator_name(old, PRIOR_FIELDS) == new
    with pytest.warns(DeprecatedNameWarning, match="'basewrench' is deprecated"):
        assert AnalyticPrior("basewrench", panda).kind == "base-wrench"
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecatedNameWarning)
        for p in PRESETS.values():  # the declared presets use the canonical names: no warning on import or load
            d = p.to_dict()
            assert d["prior"] is None or d["prior"] in residual_prior_names()  # written by the canonical name
            assert Preset.from_dict(d) == p
    d = PRESETS["residual-basewrench"].to_dict()
    assert d["prior"] == "base-wrench"
    with pytest.warns(DeprecatedNameWarning):  # a dict of the older spelling: the same preset, with a warning
        assert Preset.from_dict({**d, "prior": "basewrench"}) == PRESETS["residual-basewrench"]


def test_fingerprints_keep_the_spellings_every_cached_run_was_keyed_by():
    """Training fingerprints hash the preset with the older spellings, so a model trained before the rename is
    still this run's. The hex digests were computed by the code before the rename."""
    from hybrid_dyn.learn.train import TrainConfig, run_fingerprint

    assert PRESETS["residual-basewrench"].fingerprint_dict()["prior"] == "basewrench"
    assert PRESETS["residual-momentum"].fingerprint_dict()["prior"] == "momentum"
    assert PRESETS["residual-rnea-bw"].fingerprint_dict()["prior"] == "rnea-basewrench"
    assert set(PRIOR_FINGERPRINT_SPELLING) <= set(residual_prior_names())
    budget = TrainConfig.recipe("budget")
    assert run_fingerprint(PRESETS["residual-basewrench"], budget.for_preset(PRESETS["residual-basewrench"]),
                           "0" * 64) == FINGERPRINT_RESIDUAL_BASEWRENCH_BUDGET
    assert run_fingerprint(PRESETS["residual-rnea-bw"], TrainConfig(), "0" * 64) == FINGERPRINT_RESIDUAL_RNEA_BW_PLATEAU


@pytest.mark.slow  # a tiny training run: ~5 s
def test_a_saved_residual_model_loads_and_predicts_identically(panda, tmp_path):
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import TrainConfig, load_model, train_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=3, n_samples=60, seed=2))
    model = train_model(ds, "residual-basewrench", tmp_path / "m",
                        TrainConfig(max_epochs=1, max_batches_per_epoch=2, batch_size=64, progress=False))
    stored = json.loads((tmp_path / "m" / "config.json").read_text())
    assert stored["format_version"] == 3
    assert stored["preset"]["prior"] == "base-wrench" and stored["prior"]["kind"] == "base-wrench"  # canonical
    assert list((tmp_path / "m" / "analytic_cache").glob("prior-base-wrench-*.h5"))  # the cache file too
    loaded = load_model(tmp_path / "m")
    assert loaded.preset.prior == "base-wrench"
    test = ds.split("test")
    for a, b in zip(model.predict(test), loaded.predict(test)):
        np.testing.assert_array_equal(a, b)


def _as_format_2(src, dst):
    """A copy of model folder ``src`` as format 2 wrote it: the older spellings, every digest matching."""
    import shutil

    from hybrid_dyn.learn.trained_model import save_model

    shutil.copytree(src, dst)
    model = __import__("hybrid_dyn.learn", fromlist=["load_model"]).load_model(dst)
    config = json.loads((dst / "config.json").read_text())
    config["format_version"] = 2
    config["preset"]["prior"] = prior_fingerprint_spelling(config["preset"]["prior"])
    config["prior"]["kind"] = prior_fingerprint_spelling(config["prior"]["kind"])
    save_model(model.module, config, dst, train_seconds=1.5)
    return config


@pytest.mark.slow  # a tiny training run: ~5 s
def test_a_format_2_model_loads_with_a_warning_and_is_reused(panda, tmp_path):
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn import TrainConfig, load_model, train_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=3, n_samples=60, seed=2))
    cfg = TrainConfig(max_epochs=1, max_batches_per_epoch=2, batch_size=64, progress=False)
    fresh = train_model(ds, "residual-momentum", tmp_path / "m", cfg)
    old = _as_format_2(tmp_path / "m", tmp_path / "old")
    assert old["preset"]["prior"] == "momentum" and old["prior"]["kind"] == "momentum"
    with pytest.warns(DeprecatedNameWarning, match=r"'momentum'.*'momentum-observer'"):
        loaded = load_model(tmp_path / "old")
    assert loaded.preset.prior == "momentum-observer" and loaded.prior.kind == "momentum-observer"
    test = ds.split("test")
    for a, b in zip(fresh.predict(test), loaded.predict(test)):
        np.testing.assert_array_equal(a, b)
    # A training run of the same preset, config and data finds the old file its own (the fingerprint did not move).
    with pytest.warns(DeprecatedNameWarning):
        assert train_model(ds, "residual-momentum", tmp_path / "old", cfg).config["fingerprint"] == \
            fresh.config["fingerprint"]
