"""The Gaussian-process family (hybrid_dyn.learn.gp) against scikit-learn, its files, a 1-D toy.

Tiny data built here: a 2-joint CSV log imported as 5 blocks of 24 samples, and a noisy 1-D
function. scikit-learn's GaussianProcessRegressor is the independent reference of the
prediction: the toolkit predicts from stored arrays with its own kernel code.
"""
from __future__ import annotations

import json
import struct
import warnings

import numpy as np
import pytest

from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.errors import OutputPathError
from hybrid_dyn.learn.gp import GPConfig, GPHyperparameters, condition_gp, fit_gp_hyperparameters, load_gp, train_gp
from hybrid_dyn.learn.trained_model import ModelError

sklearn_gp = pytest.importorskip("sklearn.gaussian_process")
kernels = pytest.importorskip("sklearn.gaussian_process.kernels")

ALL_ROWS = GPConfig(hyper_rows=10**6, rows=10**6)  # more than the set has: every training row, in order


def two_joint_log(path, n: int = 120, hz: float = 50.0):
    """A CSV log of a 2-joint arm (no description: a data-only set) with smooth torques:
    tau1 = 2 qdd1 + 5 cos q1 + 0.3 qd1, tau2 = 0.5 qdd2 + 1.5 cos(q1 + q2) [Nm], plus 0.01 Nm of white noise."""
    t = np.arange(n) / hz
    w = np.array([0.7, 1.3])
    q = np.stack([0.8 * np.sin(w[0] * t), 0.5 * np.sin(w[1] * t + 1.0)], axis=1)
    qd = np.stack([0.8 * w[0] * np.cos(w[0] * t), 0.5 * w[1] * np.cos(w[1] * t + 1.0)], axis=1)
    qdd = -q * w**2
    tau = np.stack([2 * qdd[:, 0] + 5 * np.cos(q[:, 0]) + 0.3 * qd[:, 0],
                    0.5 * qdd[:, 1] + 1.5 * np.cos(q[:, 0] + q[:, 1])], axis=1)
    tau += np.random.default_rng(1).normal(0, 0.01, tau.shape)  # a sensor's noise: the GP's white term fits it
    header = "t,q1,q2,qd1,qd2,qdd1,qdd2,tau1,tau2"
    np.savetxt(path, np.column_stack([t, q, qd, qdd, tau]), delimiter=",", header=header, comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    """Five contiguous blocks of the log: 3 train / 1 val / 1 test, 24 samples each."""
    root = tmp_path_factory.mktemp("gp")
    cols = {k: [f"{k if k != 'tau_m' else 'tau'}{j}" for j in (1, 2)] for k in ("q", "qd", "qdd", "tau_m")}
    report = import_log(two_joint_log(root / "log.csv"), root / "ds", name="toy-2dof", time="t", columns=cols,
                        trajectories="blocks", n_blocks=5)
    return load_dataset(report.path)


def _xy(instances):
    return (np.concatenate([np.concatenate([i.q, i.qd, i.qdd], axis=1) for i in instances]),
            np.concatenate([i.tau_m for i in instances]))


@pytest.fixture(scope="module")
def fitted(ds, tmp_path_factory):
    assert [len(ds.split(s)) for s in ("train", "val", "test")] == [3, 1, 1]
    return train_gp(ds, tmp_path_factory.mktemp("gpm") / "gp", ALL_ROWS)


def test_the_loaded_model_predicts_what_sklearn_predicts(ds, fitted):
    """One GP per joint, conditioned by scikit-learn directly on the standardized training split with the
    fitted hyperparameters, predicts the test split as the toolkit's loaded file does, to 1e-8 Nm; and the
    fitted hyperparameters are a maximum of the marginal likelihood at least as high as scikit-learn's own
    optimizer reaches from its start (gp_marginal keeps the better of that start and l = sqrt(d))."""
    x, y = _xy(ds.split("train"))
    xte, _ = _xy(ds.split("test"))
    mx, sx = x.mean(0), x.std(0) + 1e-9  # the documented standardization (GPConfig)
    expect = np.empty((len(xte), y.shape[1]))
    t = fitted.tensors
    for j in range(y.shape[1]):
        k = (kernels.ConstantKernel(1.0, (1e-2, 1e2)) * kernels.RBF(np.ones(x.shape[1]), (1e-2, 1e3))
             + kernels.WhiteKernel(1e-2, (1e-6, 1.0)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # sklearn's bound warnings are not what this test checks
            ref = sklearn_gp.GaussianProcessRegressor(k, normalize_y=True).fit((x - mx) / sx, y[:, j])
        # The optimum: never below scikit-learn's (its objective is checked to 1e-9 in the next test).
        assert fitted.config["log_marginal_likelihood"][j] >= ref.log_marginal_likelihood_value_ - 1e-8 * abs(
            ref.log_marginal_likelihood_value_)
        mine = (kernels.ConstantKernel(t["constant"][j], "fixed") * kernels.RBF(t["length_scale"][j], "fixed")
                + kernels.WhiteKernel(t["noise_level"][j], "fixed"))
        cond = sklearn_gp.GaussianProcessRegressor(mine, optimizer=None, normalize_y=True).fit((x - mx) / sx, y[:, j])
        expect[:, j] = cond.predict((xte - mx) / sx)
    got = np.concatenate(fitted.predict(ds.split("test")))
    np.testing.assert_allclose(got, expect, rtol=0, atol=1e-8)
    assert fitted.config["n_rows"] == len(x) and fitted.path is not None


def test_the_marginal_likelihood_and_its_gradient_are_sklearns(ds):
    """gp_marginal's objective is scikit-learn's log marginal likelihood and gradient for the GP
    family's kernel, at the start, at random points within the bounds and on standardized targets."""
    from hybrid_dyn.learn.gp_marginal import log_marginal_likelihood

    x, y = _xy(ds.split("train"))
    z = (x - x.mean(0)) / (x.std(0) + 1e-9)
    rng = np.random.default_rng(3)
    k = (kernels.ConstantKernel(1.0, (1e-2, 1e2)) * kernels.RBF(np.ones(x.shape[1]), (1e-2, 1e3))
         + kernels.WhiteKernel(1e-2, (1e-6, 1.0)))
    for j in range(y.shape[1]):
        ref = sklearn_gp.GaussianProcessRegressor(k, optimizer=None, normalize_y=True).fit(z, y[:, j])
        ys = (y[:, j] - y[:, j].mean()) / y[:, j].std()
        for theta in [k.theta] + [rng.uniform(k.bounds[:, 0], k.bounds[:, 1]) for _ in range(4)]:
            want, want_grad = ref.log_marginal_likelihood(theta, eval_gradient=True)
            got, got_grad = log_marginal_likelihood(theta, z, ys)
            assert got == pytest.approx(want, rel=1e-9)
            # The gradient holds K^-1: at a noise level near its 1e-6 bound K is near singular and both sums
            # round differently (1.5e-6 relative seen); a wrong term would be off by O(1).
            np.testing.assert_allclose(got_grad, want_grad, rtol=1e-5, atol=1e-10 * np.abs(want_grad).max())


def test_save_load_predict_is_bit_identical_and_the_fit_is_deterministic(ds, tmp_path):
    cfg = GPConfig(hyper_rows=40, rows=50, seed=7)  # subsets of the 72 training rows
    x, y = _xy(ds.split("train"))
    xte, _ = _xy(ds.split("test"))
    # Two runs with the same seed write byte-identical files.
    a, b = train_gp(ds, tmp_path / "r1", cfg), train_gp(ds, tmp_path / "r2", cfg)
    for name in ("model.safetensors", "config.json"):
        assert (tmp_path / "r1" / name).read_bytes() == (tmp_path / "r2" / name).read_bytes()
    assert a.config["n_rows"] == 50
    # In memory, conditioned on a's hyperparameters: a's tensors; saved and loaded, the same predictions, bit for bit.
    hyper = GPHyperparameters(a.tensors["constant"], a.tensors["length_scale"], a.tensors["noise_level"], [])
    mem = condition_gp(x, y, hyper, cfg)
    for k, v in mem.tensors.items():
        np.testing.assert_array_equal(v, a.tensors[k])
    mem.save(tmp_path / "mem")
    np.testing.assert_array_equal(load_gp(tmp_path / "mem").predict_rows(xte), mem.predict_rows(xte))
    np.testing.assert_array_equal(a.predict_rows(xte), mem.predict_rows(xte))
    # Another seed conditions on other rows.
    other = condition_gp(x, y, hyper, GPConfig(hyper_rows=40, rows=50, seed=8))
    assert not np.array_equal(other.tensors["z_train"], a.tensors["z_train"])
    # A finished folder of the same run is reused; of another run, refused before any work.
    assert train_gp(ds, tmp_path / "r1", cfg).config == b.config
    with pytest.raises(ModelError, match="another run"):
        train_gp(ds, tmp_path / "r1", GPConfig(hyper_rows=40, rows=50, seed=8))


def _flip_byte(path, tensor: str, byte: int) -> None:
    raw = bytearray(path.read_bytes())
    n = struct.unpack("<Q", raw[:8])[0]
    raw[8 + n + json.loads(raw[8:8 + n])[tensor]["data_offsets"][0] + byte] ^= 0x01
    path.write_bytes(bytes(raw))


def test_a_corrupt_edited_or_foreign_file_is_refused(fitted, tmp_path):
    import shutil

    for name, edit, message in [
        ("flip", lambda d: _flip_byte(d / "model.safetensors", "alpha", 3), "do not match the sha256"),
        ("config", lambda d: (d / "config.json").write_text(
            (d / "config.json").read_text().replace('"seed": 0', '"seed": 1')), "does not match the tensors"),
        ("torch", lambda d: (d / "config.json").write_text(json.dumps({"format": "hybrid_dyn.model"})),
         "is not a GP model"),
        ("truncated", lambda d: (d / "model.safetensors").write_bytes((d / "model.safetensors").read_bytes()[:100]),
         "corrupt"),
    ]:
        d = tmp_path / name
        shutil.copytree(fitted.path, d)
        load_gp(d)  # the copy itself is fine
        edit(d)
        with pytest.raises(ModelError, match=message):
            load_gp(d)


@pytest.mark.parametrize("version", ["1", None, True])
def test_a_non_integer_format_version_is_one_error_not_a_traceback(fitted, tmp_path, version):
    """A format_version of "1" or null in config.json was a TypeError."""
    import shutil

    d = tmp_path / "gp"
    shutil.copytree(fitted.path, d)
    doc = json.loads((d / "config.json").read_text())
    (d / "config.json").write_text(json.dumps({**doc, "format_version": version}))
    with pytest.raises(ModelError, match=f"format_version must be an integer, got {version!r}"):
        load_gp(d)


def test_timing_json_of_another_gp_is_not_read_as_this_ones(fitted, ds, tmp_path):
    """A GP's timing.json is bound to its config, as the nets' is: another fit's
    timing file copied in gives no training time, not the other fit's."""
    import shutil

    other = train_gp(ds, tmp_path / "other", GPConfig(hyper_rows=10, rows=10))
    assert np.isfinite(other.train_seconds) and np.isfinite(fitted.train_seconds)
    d = tmp_path / "gp"
    shutil.copytree(fitted.path, d)
    shutil.copy(other.path / "timing.json", d / "timing.json")
    assert np.isnan(load_gp(d).train_seconds)  # unknown, not the other fit's
    assert load_gp(fitted.path).train_seconds == fitted.train_seconds


def test_an_output_folder_it_did_not_write_is_left_alone(ds, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    with pytest.raises(OutputPathError, match="notes.txt"):
        train_gp(ds, out, GPConfig(hyper_rows=10, rows=10))
    assert (out / "notes.txt").read_text() == "keep me" and sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_a_1d_toy_function_is_fit_within_its_noise():
    """y = sin(2x) + N(0, 0.1^2) on 150 points of [-3, 3]: the posterior mean is closer to sin(2x)
    than the noise, and the fitted white-noise level is the true one."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-3, 3, (150, 1))
    y = np.sin(2 * x[:, 0]) + rng.normal(0, 0.1, 150)
    cfg = GPConfig(hyper_rows=150, rows=150)
    model = condition_gp(x, y, fit_gp_hyperparameters(x, y, cfg), cfg)
    grid = np.linspace(-2.8, 2.8, 200)[:, None]
    err = model.predict_rows(grid)[:, 0] - np.sin(2 * grid[:, 0])
    assert np.sqrt(np.mean(err ** 2)) < 0.05  # half the noise's standard deviation
    noise_std = np.sqrt(model.tensors["noise_level"][0]) * model.tensors["y_std"][0]  # back to y's units
    assert 0.08 < noise_std < 0.12


@pytest.mark.slow
def test_the_gp_row_in_a_bench_scores_what_the_model_predicts(tmp_path, panda, monkeypatch):
    """The bench's `gp` row, declared once (bench/learned_rows.py), runs on any dataset with joint torques;
    its RMSE is the RMSE of the saved model's own predictions on the test split."""
    import functools

    import hybrid_dyn.learn.gp as gp_module
    from hybrid_dyn.bench.profiles import profile_for_data
    from hybrid_dyn.bench.results import read_results
    from hybrid_dyn.bench.runner import run_bench
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.learn.gp import load_gp

    ds = load_dataset(make_synthetic_dataset(tmp_path / "ds", panda, n_instances=5, n_samples=80, seed=4,
                                             friction=panda.spec.friction("gaz2019"), tip_forces=False))
    # Hyperparameters fitted on 60 rows: the bench's path is under test here, not the fit (tested above).
    monkeypatch.setattr(gp_module, "GPConfig", functools.partial(gp_module.GPConfig, hyper_rows=60))
    profile = profile_for_data([ds.path], families=(), rows=("gp",), workers=1)
    rows = run_bench(profile, tmp_path / "report", work_root=tmp_path / "runs", log=lambda *_: None)
    (row,) = [r for r in rows if r["model"] == "gp"]
    assert row["status"] == "ok" and row["family"] == "gp", row
    (model_dir,) = list((tmp_path / "runs").rglob("models/gp"))
    model = load_gp(model_dir)
    test = ds.split("test")
    err = np.concatenate(model.predict(test)) - np.concatenate([i.tau_m for i in test])
    assert float(row["rmse"]) == pytest.approx(float(np.sqrt(np.mean(err ** 2))), rel=1e-9)
    csv_row = [r for r in read_results(tmp_path / "report" / "results.csv") if r["model"] == "gp"]
    assert len(csv_row) == 1 and csv_row[0]["family"] == "gp"
    assert "gp" in (tmp_path / "report" / "joint_torque.md").read_text()
