"""Physics priors on an identified model: the residual nets' analytic part built
from an identified parameter file (the bench's rows on it: bench/test_identified_rows.py).

References are independent of the code under test: ``IdentifiedModel.predict_torque``
(the regressor times the identified parameters, plus the friction law) for the
residual prior, ``friction_from_file`` for the friction it adds.
"""
import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.tip_force import tip_force_from_base_wrench
from hybrid_dyn.identify import friction_from_file
from hybrid_dyn.learn.priors import AnalyticPrior

TINY_TRAINING = dict(max_epochs=1, max_batches_per_epoch=1, batch_size=64, progress=False, device="cpu", num_threads=1)


def _fields(inst, prior):
    return {k: inst[k] for k in prior.fields}


def test_torque_priors_on_an_identified_file_add_exactly_its_friction(panda, identified_log, tmp_path):
    ds, model, path = identified_log
    robot = hd.load_robot("panda", params=path)
    inst = ds.split("test")[0]
    tau_f = friction_from_file(path)(inst.qd)
    assert np.abs(tau_f).max() > 0.1  # a friction law that matters
    for kind in ("rnea", "rnea-bw"):
        with_f = AnalyticPrior(kind, robot, ds.meta["record_hz"])
        without = AnalyticPrior(kind, robot, ds.meta["record_hz"], friction=None)
        np.testing.assert_allclose(with_f.compute(_fields(inst, with_f)) - without.compute(_fields(inst, without)),
                                   tau_f, rtol=0, atol=1e-12)
        k = 37
        sample = {f: inst[f][k] for f in with_f.fields}
        np.testing.assert_allclose(with_f.single(sample) - without.single(sample), tau_f[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(with_f.single(sample), with_f.compute(_fields(inst, with_f))[k], rtol=0, atol=1e-9)
        # The friction is part of the cache key: the frictionless prior's cache is never read for it.
        assert with_f.describe()["friction"] == json.loads(path.read_text())["friction"]
        cache = tmp_path / kind
        without.compute_instances([inst], cache, ds.checksum)
        np.testing.assert_allclose(with_f.compute_instances([inst], cache, ds.checksum)[0]
                                   - without.compute(_fields(inst, without)), tau_f, rtol=0, atol=1e-12)
    # Untrained, the residual's prior is the identified model: inertials and friction.
    rnea = AnalyticPrior("rnea", robot)
    np.testing.assert_allclose(rnea.compute(_fields(inst, rnea)), model.predict_torque(inst.q, inst.qd, inst.qdd),
                               rtol=0, atol=1e-9)


def test_tip_force_priors_take_the_identified_inertials_and_no_friction(panda, identified_log):
    ds, model, path = identified_log
    robot = hd.load_robot("panda", params=path)
    inst = ds.split("test")[0]
    prior = AnalyticPrior("base-wrench", robot)
    assert prior.friction is None and "friction" not in prior.describe()
    expected = tip_force_from_base_wrench(model.to_robot(), inst.q, inst.qd, inst.qdd, inst.base_wrench)
    np.testing.assert_allclose(prior.compute(_fields(inst, prior)), expected, rtol=0, atol=1e-9)
    nominal = tip_force_from_base_wrench(panda, inst.q, inst.qd, inst.qdd, inst.base_wrench)
    assert np.abs(expected - nominal).max() > 1e-3  # the identified inertials, not the nominal ones
    with pytest.raises(ValueError, match="takes no joint friction"):
        AnalyticPrior("base-wrench", robot, friction=json.loads(path.read_text())["friction"])


def test_nominal_parameter_sets_give_a_rigid_body_prior(panda, identified_log):
    """A nominal set, named or by path, with a friction section (gaz2019's) or without: no friction,
    and its description (the cache key) as before."""
    ds, _, _ = identified_log
    inst = ds.split("test")[0]
    for params in (None, "gaz2019", panda.spec.param_sets["gaz2019"], panda.spec.param_sets["franka_official"]):
        robot = hd.load_robot("panda", params=params)
        prior = AnalyticPrior("rnea", robot)
        assert prior.friction is None and not {"friction", "params_sha256"} & set(prior.describe())
        np.testing.assert_array_equal(prior.compute(_fields(inst, prior)),
                                      robot.inverse_dynamics(inst.q, inst.qd, inst.qdd))


@pytest.mark.slow  # training and numba compilation: ~8 s
def test_untrained_residual_on_an_identified_file_is_the_identified_model(identified_log, tmp_path):
    """Through training, the model file and a fresh load: the prior is rebuilt from the config alone."""
    from hybrid_dyn.data.input_windows import window_index
    from hybrid_dyn.learn import TrainConfig, load_model, train_model
    from hybrid_dyn.learn.trained_model import ModelError

    ds, model, path = identified_log
    own = tmp_path / "identified.json"
    own.write_bytes(path.read_bytes())
    train_model(ds, "residual-rnea", tmp_path / "m", TrainConfig(analytic_params=str(own), **TINY_TRAINING))
    loaded = load_model(tmp_path / "m")
    assert loaded.config["prior"]["friction"] == json.loads(own.read_text())["friction"]
    head = loaded.module.net.head[-1]  # the residual branch as initialised: exactly zero
    head.weight.data.zero_()
    head.bias.data.zero_()
    inst = ds.split("test")[0]
    expected = model.predict_torque(inst.q, inst.qd, inst.qdd)
    x = np.concatenate([np.asarray(inst[f], float) for f in loaded.inputs], axis=1)  # float64, as a control loop
    index = window_index([len(inst)], loaded.window)
    single = np.array([loaded.predict_window(x[index[k]]) for k in range(0, len(inst), 7)])
    np.testing.assert_allclose(single, expected[::7], rtol=0, atol=1e-9)
    np.testing.assert_allclose(loaded.prior.compute(_fields(inst, loaded.prior)), expected, rtol=0, atol=1e-9)
    # The batch path runs the network in float32: equal to its round-off.
    np.testing.assert_allclose(loaded.predict([inst])[0], expected, rtol=0, atol=1e-5 * np.abs(expected).max())
    # The inertials come from the file: a file changed since training is refused, not used.
    doc = json.loads(own.read_text())
    doc["body_parameters"][next(iter(doc["body_parameters"]))][0] += 0.1
    own.write_text(json.dumps(doc))
    with pytest.raises(ModelError, match="trained on the parameter file"):
        load_model(tmp_path / "m").prior
