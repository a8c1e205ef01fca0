"""Hybrids on an identified model, and identification from a log (issue 15, items 2 and 3).

References are independent of the code under test: ``IdentifiedModel.predict_torque``
(the regressor times the identified parameters, plus the friction law) for the
residual prior, ``friction_from_file`` for the friction it adds, and a direct
``identify`` call (what ``hybrid-dyn identify`` runs) for the bench's rows.
"""
import json

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.tip_force import tip_force_from_base_wrench
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.identify import friction_from_file, identify
from hybrid_dyn.learn.priors import AnalyticPrior

TINY_TRAINING = dict(max_epochs=1, max_batches_per_epoch=1, batch_size=64, progress=False, device="cpu", num_threads=1)


@pytest.fixture(scope="module")
def log_like(panda, tmp_path_factory):
    """An imported-like dataset (no generator_version, no plant): Gaz friction in tau_m, a small tip force."""
    root = tmp_path_factory.mktemp("ident-hybrids")
    ds = load_dataset(make_synthetic_dataset(root / "d", panda, n_instances=5, n_samples=150, seed=5,
                                             friction=panda.spec.friction("gaz2019"), contact_free_s=0.6))
    assert ds.meta.get("generator_version") is None
    model = identify(ds, "consistent", panda)  # what `hybrid-dyn identify --method consistent` runs
    return ds, model, model.save(root / "panda_identified.json")


def _fields(inst, prior):
    return {k: inst[k] for k in prior.fields}


def test_torque_priors_on_an_identified_file_add_exactly_its_friction(panda, log_like, tmp_path):
    ds, model, path = log_like
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


def test_tip_force_priors_take_the_identified_inertials_and_no_friction(panda, log_like):
    ds, model, path = log_like
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


def test_nominal_parameter_sets_give_a_rigid_body_prior(panda, log_like):
    """A nominal set, named or by path, with a friction section (gaz2019's) or without: no friction,
    and its description (the cache key) as before."""
    ds, _, _ = log_like
    inst = ds.split("test")[0]
    for params in (None, "gaz2019", panda.spec.param_sets["gaz2019"], panda.spec.param_sets["franka_official"]):
        robot = hd.load_robot("panda", params=params)
        prior = AnalyticPrior("rnea", robot)
        assert prior.friction is None and not {"friction", "params_sha256"} & set(prior.describe())
        np.testing.assert_array_equal(prior.compute(_fields(inst, prior)),
                                      robot.inverse_dynamics(inst.q, inst.qd, inst.qdd))


@pytest.mark.slow  # training and numba compilation: ~8 s
def test_untrained_residual_on_an_identified_file_is_the_identified_model(log_like, tmp_path):
    """Through training, the model file and a fresh load: the prior is rebuilt from the config alone."""
    from hybrid_dyn.data.windows import window_index
    from hybrid_dyn.learn import TrainConfig, load_model, train_model
    from hybrid_dyn.learn.model import ModelError

    ds, model, path = log_like
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


@pytest.mark.slow  # training and numba compilation: ~8 s
def test_bench_identifies_an_imported_log_on_train_and_val_and_scores_on_test(panda, log_like, tmp_path):
    from hybrid_dyn.bench.catalog import select_rows
    from hybrid_dyn.bench.profiles import BenchProfile
    from hybrid_dyn.bench.runner import BenchContext, score_row, train_split_stats

    ds, model, _ = log_like
    profile = BenchProfile(name="t", scenarios=("log",), recipe="plateau", train=TINY_TRAINING, workers=1)
    specs = {s.name: s for s in select_rows(families=("identified",))}
    for name in ("identified-consistent", "base-wrench-identified", "residual-rnea-identified",
                 "residual-rnea-bw-identified"):
        assert profile.applies(specs[name], ds), name
    no_tau = type("D", (), {"fields": [f for f in ds.fields if f != "tau_m"], "meta": ds.meta})()
    assert not profile.applies(specs["base-wrench-identified"], no_tau)  # the fit needs the logged torques
    ctx = BenchContext(profile, "log", ds, panda, tmp_path / "work", tmp_path / "data", log=lambda *a: None)
    norm = train_split_stats(ds)

    row = score_row(specs["identified-consistent"], ctx, norm)
    fitted, file = ctx.cache[("identified", "consistent")]
    n_fit = sum(len(i) for s in ("train", "val") for i in ds.split(s))
    assert fitted.fit["n_samples"] == n_fit  # train + val, never a test sample
    assert file.parent == tmp_path / "work" / "identified" and file.is_file()
    test = ds.split("test")
    err = np.concatenate([model.predict_torque(i.q, i.qd, i.qdd) - i.tau_m for i in test])
    assert row["rmse"] == pytest.approx(np.sqrt(np.mean(err ** 2)), rel=1e-9)

    res = score_row(specs["residual-rnea-identified"], ctx, norm)
    assert res["status"] == "ok" and "friction" in res["inputs"]
    trained = next((tmp_path / "work" / "models").glob("residual-rnea-identified-*"))
    config = json.loads((trained / "config.json").read_text())
    assert config["analytic_params"] == str(file.resolve()) and "friction" in config["prior"]


def test_identified_file_names_of_a_robot_variant_hold_no_brackets(log_like, tmp_path):
    from hybrid_dyn.bench.identified_rows import _identified
    from hybrid_dyn.bench.profiles import BenchProfile
    from hybrid_dyn.bench.runner import BenchContext

    bare = hd.load_robot("panda[tool=none]")
    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", bare, n_instances=3, n_samples=150, tip_forces=False))
    ctx = BenchContext(BenchProfile(name="t", scenarios=("log",)), "log", ds, bare, tmp_path / "work",
                       tmp_path / "data", log=lambda *a: None)
    fitted, file = _identified(ctx, "wls")
    assert not set("[]=;") & set(file.name)
    # Saved and read back as the variant: the bare flange, the hand not restored at its nominal mass.
    inst = ds.split("test")[0]
    np.testing.assert_allclose(fitted.to_robot().inverse_dynamics(inst.q, inst.qd, inst.qdd),
                               fitted.rigid_body_torque(inst.q, inst.qd, inst.qdd), rtol=0, atol=1e-9)
    assert _identified(BenchContext(ctx.profile, "log", ds, bare, tmp_path / "work", tmp_path / "data",
                                    log=lambda *a: None), "wls")[1] == file  # a rerun reads the file back
