"""TipForceEstimator around trained models: streaming == batch, decimation, refusal of other robots."""
import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.tare import TARE_SECONDS, tare_samples
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.estimator import EstimatorStatus, TipForceEstimator, estimate_tip_force
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn.trained_model import ModelError
from hybrid_dyn.learn.stream_predictor import StreamingModel
from hybrid_dyn.sim.sensors import causal_acceleration

RATE = 100.0


@pytest.fixture(scope="module")
def trained(tmp_path_factory, panda):
    root = tmp_path_factory.mktemp("learned")
    ds = load_dataset(make_synthetic_dataset(root / "d", panda, n_instances=4, n_samples=120, record_hz=RATE,
                                             noise=0.002, friction=panda.spec.friction(), seed=2))
    cfg = TrainConfig(max_epochs=1, max_batches_per_epoch=3, progress=False)
    dirs = {p: root / p for p in ("seed-tip-11", "residual-basewrench", "residual-momentum", "residual-base-momentum")}
    for preset, d in dirs.items():
        train_model(ds, preset, d, cfg)
    return ds, dirs


@pytest.mark.parametrize("preset", ["seed-tip-11", "residual-basewrench", "residual-momentum", "residual-base-momentum"])
def test_streaming_equals_batch(trained, preset):
    ds, dirs = trained
    inst = ds.split("test")[0]
    est = TipForceEstimator.load(dirs[preset], robot="panda", call_hz=RATE, runtime="numba")
    stream, statuses = [], []
    for k in range(len(inst)):
        stream.append(est.estimate_tip_force(inst.q[k], inst.qd[k], base_wrench=inst.base_wrench[k],
                                             tau_J=inst.tau_J[k], t=inst.t[k]))
        statuses.append(est.last_status)
    qdd = causal_acceleration(inst.qd, 1.0 / RATE, est.config.qdd_cutoff_hz)
    batch = estimate_tip_force(inst.q, inst.qd, qdd, base_wrench=inst.base_wrench, tau_J=inst.tau_J, model=dirs[preset])
    # Every model that reads the base sensor tares it on the first TARE_SECONDS: causally, with the mean so
    # far, where the batch form knows the whole window's mean. Once the net's window holds only samples
    # after the tare window, the two must agree.
    reads_sensor = preset != "residual-momentum"
    assert (est.tare_offset is not None) == reads_sensor
    start = tare_samples(RATE, TARE_SECONDS) + est.model.window - 1 if reads_sensor else 0
    np.testing.assert_allclose(np.stack(stream)[start:], batch[start:], atol=1e-6)
    # Warming up exactly until the window holds real samples only (and the observer settled).
    warm = est._warmup_calls
    assert warm >= 10
    assert all(s is EstimatorStatus.WARMING_UP for s in statuses[: warm - 1])
    assert all(s is not EstimatorStatus.WARMING_UP for s in statuses[warm - 1:])


def test_faster_calls_keep_the_training_spacing(trained):
    """Called at 3x the training rate, the window still holds samples 1/RATE apart."""
    ds, dirs = trained
    inst = ds.split("test")[0]
    reference = StreamingModel.load(dirs["seed-tip-11"], call_hz=RATE, runtime="numba")
    fast = StreamingModel.load(dirs["seed-tip-11"], call_hz=3 * RATE, runtime="numba")
    for m in (reference, fast):  # a known offset: the tare window (which the in-between samples would enter) is skipped
        m._tare.set_offset(np.zeros(6))
    for k in range(40):
        s = dict(q=inst.q[k], qd=inst.qd[k], qdd=inst.qdd[k], base_wrench=inst.base_wrench[k], tau_J=inst.tau_J[k], t=None)
        f_ref, _ = reference.step(**s)
        if k > 0:  # two in-between samples (say, a faster loop) that must not enter the training-rate window
            for alpha in (1 / 3, 2 / 3):
                mid = {n: (1 - alpha) * getattr(inst, n)[k - 1] + alpha * getattr(inst, n)[k]
                       for n in ("q", "qd", "qdd", "base_wrench", "tau_J")}
                fast.step(**mid, t=None)
        f_fast, _ = fast.step(**s)
        np.testing.assert_allclose(f_fast, f_ref, atol=1e-9)


def test_model_for_another_robot_is_refused(trained):
    _, dirs = trained
    with pytest.raises(ModelError, match="ur5|robot"):
        TipForceEstimator.load(dirs["seed-tip-11"], robot="ur5")


def test_out_of_range_is_flagged(trained):
    ds, dirs = trained
    inst = ds.split("train")[0]
    est = TipForceEstimator.load(dirs["residual-basewrench"], call_hz=RATE)
    n = est._warmup_calls  # past the tare window (0.5 s)
    for k in range(n):
        est.estimate_tip_force(inst.q[k], inst.qd[k], base_wrench=inst.base_wrench[k])
    assert est.last_status is EstimatorStatus.OK
    w = inst.base_wrench[n].copy()
    # A load no training sample came near (training wrenches vary by a few N), yet a believable
    # one: 5000 N would now be refused as input (above the estimator's base-wrench bound).
    w[2] += 300.0
    f = est.estimate_tip_force(inst.q[n], inst.qd[n], base_wrench=w)
    assert est.last_status is EstimatorStatus.OUT_OF_RANGE and np.isfinite(f).all()


def test_slower_calls_than_training_are_refused(trained):
    """Called at 50 Hz, a model trained at 100 Hz would see windows twice as long as in training
    (it was once accepted with stride 1); 150 Hz is no integer multiple either."""
    _, dirs = trained
    for hz in (0.5 * RATE, 1.5 * RATE):
        with pytest.raises(ModelError, match="training rate 100 Hz or an integer multiple"):
            TipForceEstimator.load(dirs["seed-tip-11"], call_hz=hz, runtime="numba")


@pytest.mark.parametrize("preset", ["seed-tip-11", "residual-basewrench"])
def test_onnx_runtime_agrees_with_batch_to_float32(trained, preset):
    """The onnxruntime path computes the network in float32: within 1e-4 N of the float64 batch form
    (forces of a few N, float32 epsilon 1.2e-7, through a 2-layer LSTM)."""
    ds, dirs = trained
    inst = ds.split("test")[0]
    est = TipForceEstimator.load(dirs[preset], call_hz=RATE, runtime="onnx")
    assert est.model.runtime == "onnx"
    stream = np.stack([est.estimate_tip_force(inst.q[k], inst.qd[k], base_wrench=inst.base_wrench[k],
                                              tau_J=inst.tau_J[k]) for k in range(len(inst))])
    qdd = causal_acceleration(inst.qd, 1.0 / RATE, est.config.qdd_cutoff_hz)
    batch = estimate_tip_force(inst.q, inst.qd, qdd, base_wrench=inst.base_wrench, tau_J=inst.tau_J, model=dirs[preset])
    start = tare_samples(RATE, TARE_SECONDS) + est.model.window - 1  # see test_streaming_equals_batch
    np.testing.assert_allclose(stream[start:], batch[start:], atol=1e-4)


@pytest.mark.slow  # simulates two tiny 20 Hz datasets with DART and trains a net on each
@pytest.mark.parametrize("qdd_source", ["exact", "filter"])
def test_a_stream_at_the_models_rate_runs_its_training_qdd_or_is_refused_naming_why(tmp_path, qdd_source):
    """seed-sim records at 20 Hz. With the simulator's exact qdd (its own data), a 20 Hz stream has no
    filter to match and uses its own causal estimate (0.45 x the rate). With qdd through the generator's
    20 Hz filter at 1 kHz, a 20 Hz stream (Nyquist 10 Hz) cannot run that filter: refused, naming both,
    unless the user picks a cutoff."""
    from hybrid_dyn.analytic.acceleration import default_qdd_cutoff
    from hybrid_dyn.sim.generator import generate_dataset
    from hybrid_dyn.sim.generator_config import PulseConfig
    from hybrid_dyn.sim.scenarios import scenario_config

    cfg = scenario_config("seed-sim", "quick", n_instances=3, trajectories=(1, 1), standstill=0.3,
                          speed_scale=(0.5, 0.6), seed=2, pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)),
                          qdd_source=qdd_source)
    ds = load_dataset(generate_dataset(cfg, tmp_path / "d", workers=1, progress=False))
    train_model(ds, "seed-tip-11", tmp_path / "m", TrainConfig(max_epochs=1, max_batches_per_epoch=2, progress=False))
    if qdd_source == "exact":
        est = TipForceEstimator.load(tmp_path / "m", call_hz=20.0, runtime="numba")
        assert est.config.qdd_cutoff_hz == default_qdd_cutoff(20.0) == 9.0
        return
    with pytest.raises(hd.errors.UsageError, match=r"20 Hz filter .* call_hz=20 Hz .* Nyquist frequency is 10 Hz"):
        TipForceEstimator.load(tmp_path / "m", call_hz=20.0, runtime="numba")
    est = TipForceEstimator.load(tmp_path / "m", call_hz=20.0, runtime="numba", qdd_cutoff_hz=9.0)
    assert est.config.qdd_cutoff_hz == 9.0
