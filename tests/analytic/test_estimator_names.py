"""One name per analytic estimator: the bench's names everywhere, the older spellings accepted where
users give them, with a warning (the priors' and model files' spellings: learn/test_prior_names.py)."""
import warnings

import numpy as np
import pytest

from hybrid_dyn import TipForceEstimator
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS, residual_prior_names
from hybrid_dyn.analytic.torque_models import TORQUE_MODELS
from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.deprecation import DeprecatedNameWarning
from hybrid_dyn.learn.priors import PRIOR_FIELDS


def test_the_names_are_the_bench_rows_names():
    estimators = {**{n: "tip_force" for n in TIP_FORCE_METHODS}, **{n: "joint_torque" for n in TORQUE_MODELS}}
    assert len(estimators) == len(TIP_FORCE_METHODS) + len(TORQUE_MODELS)  # one namespace: no name in both
    assert set(PRIOR_FIELDS) | set(residual_prior_names()) <= set(estimators)
    for name, task in estimators.items():  # each estimator is a bench row of its task, under that name
        assert ROWS[name].family == "analytic" and ROWS[name].task == task, name
    for registry in (TIP_FORCE_METHODS, TORQUE_MODELS):
        assert all(new in registry for new, _ in registry.aliases.values())
    with pytest.raises(ValueError, match="unknown estimator method 'kalman'") as err:
        TipForceEstimator.analytic("panda", "kalman", encoder_resolution=0.0)
    assert all(name in str(err.value) for name in TIP_FORCE_METHODS)  # and it lists the methods there are


@pytest.mark.parametrize("old, new", [("base_wrench", "base-wrench"), ("torques", "torques-pinv"),
                                      ("momentum", "momentum-observer"), ("base_momentum", "base-momentum"),
                                      ("kalman_fusion", "kalman-fusion")])
def test_an_old_method_spelling_is_the_same_estimator(old, new, panda):
    with pytest.warns(DeprecatedNameWarning, match=f"estimator method '{old}' is deprecated: use '{new}'"):
        a = TipForceEstimator.analytic(panda, old, call_hz=100.0, tare_seconds=0.0, encoder_resolution=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecatedNameWarning)  # the canonical name is silent
        b = TipForceEstimator.analytic(panda, new, call_hz=100.0, tare_seconds=0.0, encoder_resolution=0.0)
    assert a.method == b.method == new
    rng = np.random.default_rng(0)
    q0 = np.array(panda.spec.home)
    for k in range(5):
        q, qd = q0 + 0.01 * k, rng.normal(0, 0.1, 7)
        w = panda.base_wrench(q, qd, np.zeros(7))
        kw = dict(t=k / 100.0, tau_J=rng.normal(0, 1.0, 7), base_wrench=w)
        np.testing.assert_array_equal(a.estimate_tip_force(q, qd, **kw), b.estimate_tip_force(q, qd, **kw))
