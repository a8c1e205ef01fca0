"""The streaming estimator: streaming == batch, bad input, warm-up, threads."""
import dataclasses
import threading

import numpy as np
import pytest

from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.estimator import (
    CausalAccelerationFilter, EstimatorInputError, EstimatorStatus, TipForceEstimator, estimate_tip_force,
)
from hybrid_dyn.sim.sensors import causal_acceleration

RATE = 100.0


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, panda):
    """A recorded instance with noise, friction-free link torques and tip-force bells."""
    path = make_synthetic_dataset(tmp_path_factory.mktemp("est") / "d", panda, n_instances=3, n_samples=300,
                                  record_hz=RATE, noise=0.005, seed=4)
    return load_dataset(path).split("test")[0]


def test_streaming_filter_equals_scipy_lfilter(recorded):
    """The per-call biquad against scipy.signal.lfilter (the generator's offline filter)."""
    filt = CausalAccelerationFilter(7, RATE, 20.0)
    stream = np.stack([filt.step(v) for v in recorded.qd])
    np.testing.assert_allclose(stream, causal_acceleration(recorded.qd, 1.0 / RATE, 20.0), atol=1e-9)


@pytest.mark.parametrize("rate, cutoff", [(100.0, 20.0), (1000.0, 20.0), (1000.0, 449.0), (20.0, 7.3)])
def test_one_filter_serves_the_generator_and_the_stream(rate, cutoff):
    """The generator's batch filter is scipy.signal.lfilter on the backward difference, bit for bit (the
    cached datasets were made by lfilter), and the stream at `rate` is the batch at dt = 1 / rate, bit
    for bit: one kernel, not two filters that agree to round-off."""
    from scipy import signal

    qd = np.cumsum(np.random.default_rng(int(rate)).normal(size=(3000, 7)), axis=0) * 1e-3
    dt = 1.0 / rate
    diff = np.zeros_like(qd)
    diff[1:] = (qd[1:] - qd[:-1]) / dt
    b, a = signal.butter(2, cutoff, fs=1.0 / dt)
    batch = causal_acceleration(qd, dt, cutoff)
    assert np.array_equal(batch, signal.lfilter(b, a, diff, axis=0))
    filt = CausalAccelerationFilter(7, rate, cutoff)
    assert np.array_equal(np.stack([filt.step(v) for v in qd[:1000]]), batch[:1000])
    assert np.array_equal(filt.replay(qd[1000:]), batch[-1])  # the window replay continues the same state
    assert np.array_equal(causal_acceleration(qd[:, 0], dt, cutoff), batch[:, 0])  # one joint's (T,) alone


def test_streaming_base_wrench_equals_batch(recorded):
    # This set has no sensor offset and may push from t = 0: trust the sensor's zero (no tare, no noise
    # window), at the generator's 20 Hz cutoff.
    est = TipForceEstimator.analytic("panda", "base-wrench", call_hz=RATE, tare_seconds=0.0, qdd_cutoff_hz=20.0, encoder_resolution=0.0)
    stream = np.stack([est.estimate_tip_force(recorded.q[k], recorded.qd[k], base_wrench=recorded.base_wrench[k],
                                              t=recorded.t[k]) for k in range(len(recorded))])
    qdd = causal_acceleration(recorded.qd, 1.0 / RATE, 20.0)
    batch = estimate_tip_force(recorded.q, recorded.qd, qdd, base_wrench=recorded.base_wrench)
    np.testing.assert_allclose(stream, batch, atol=1e-6)
    # ...and a real estimate: its error is a fraction of the force (predicting zero would score 100 %).
    # At 100 Hz the causal qdd (delay, differentiated noise) dominates that error; at 1 kHz it shrinks.
    truth = recorded.truth["tip_force"][20:]
    err = np.sqrt(np.mean(np.sum((stream[20:] - truth) ** 2, axis=1)))
    assert err < 0.3 * np.sqrt(np.mean(np.sum(truth**2, axis=1)))


def test_streaming_torques_method_equals_batch(recorded, panda):
    est = TipForceEstimator.analytic(panda, "torques-pinv", call_hz=RATE, qdd_cutoff_hz=20.0, encoder_resolution=0.0)
    stream = np.stack([est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=recorded.tau_J[k])
                       for k in range(len(recorded))])
    qdd = causal_acceleration(recorded.qd, 1.0 / RATE, 20.0)
    from hybrid_dyn.analytic.tip_force import tip_force_from_torques
    np.testing.assert_allclose(stream, tip_force_from_torques(panda, recorded.q, recorded.qd, qdd, recorded.tau_J), atol=1e-6)


def test_warming_up_until_history_suffices(recorded):
    est = TipForceEstimator.analytic("panda", "momentum-observer", call_hz=RATE, momentum_gain=50.0, encoder_resolution=0.0,
                                     max_sigma=1e3)  # max_sigma: these statuses are the warm-up's, not the error bar's (test_error_bar.py)
    statuses = [est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=recorded.tau_J[k]) is not None
                and est.last_status for k in range(15)]
    # The first call starts the observer; then its transient (1 - K dt)^n must fall below 1 %.
    warm = 1 + int(np.ceil(np.log(0.01) / np.log(1.0 - 50.0 / RATE)))
    assert statuses[: warm - 1] == [EstimatorStatus.WARMING_UP] * (warm - 1)
    assert statuses[warm - 1:] == [EstimatorStatus.OK] * (15 - warm + 1)
    est.reset()
    est.estimate_tip_force(recorded.q[0], recorded.qd[0], tau_J=recorded.tau_J[0])
    assert est.last_status is EstimatorStatus.WARMING_UP


BAD_CASES = [
    ("NaN in q", dict(q=np.full(7, np.nan)), "q holds NaN"),
    ("inf in the wrench", dict(base_wrench=np.array([0, 0, np.inf, 0, 0, 0.0])), r"base_wrench holds NaN or inf"),
    ("wrong shape", dict(qd=np.zeros((7, 1))), r"qd must have shape"),
    ("wrong number of joints", dict(q=np.zeros(6)), r"q must have shape \(7,\)"),
    ("missing wrench", dict(base_wrench=None), "needs base_wrench"),
    ("time going backwards", dict(t=0.0), "time must increase"),
    # garbage that used to pass, or to raise a foreign error even in hold mode
    ("absurd velocity", dict(qd=np.full(7, 1e12)), r"qd\[0\] = 1e\+12 rad/s is outside"),
    ("velocity 1e150", dict(qd=np.full(7, 1e150)), r"qd\[0\] = 1e\+150 rad/s is outside"),
    ("q 10 rad past a limit", dict(q=np.array([12.9, 0, 0, -1.5, 0, 1.5, 0])), r"q\[0\] = 12\.9 rad is outside"),
    ("absurd wrench", dict(base_wrench=np.array([0, 0, 1e6, 0, 0, 0.0])), r"base_wrench\[2\] = 1e\+06 N is outside"),
    ("t not a number", dict(t="abc"), "t must be a number"),
    ("ragged q", dict(q=[0.0, 0.1, [0.2, 0.3], 0, 0, 0, 0]), "q must be 7 numbers"),
    ("q a dict", dict(q={"q": np.zeros(7)}), "q must be 7 numbers"),
    ("t missing in a timed stream", dict(t=None), "t is missing"),
    ("a 10x slower rate", dict(t=0.04 + 10 / RATE), "expects 0.01 s"),
]


@pytest.mark.parametrize("label, change, message", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_input_raises_a_value_error(recorded, label, change, message):
    est = TipForceEstimator.analytic("panda", "base-wrench", call_hz=RATE, encoder_resolution=0.0)
    k = 5
    for i in range(k):
        est.estimate_tip_force(recorded.q[i], recorded.qd[i], base_wrench=recorded.base_wrench[i], t=recorded.t[i])
    sample = dict(q=recorded.q[k], qd=recorded.qd[k], base_wrench=recorded.base_wrench[k], t=recorded.t[k])
    sample.update(change)
    with pytest.raises(EstimatorInputError, match=message) as info:
        est.estimate_tip_force(**sample)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("label, change, message", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_input_holds_and_leaves_history_untouched(recorded, label, change, message):
    def run(bad_at=None):
        est = TipForceEstimator.analytic("panda", "base-wrench", call_hz=RATE, on_bad_input="hold", encoder_resolution=0.0)
        out, statuses = [], []
        for i in range(12):
            if i == bad_at:
                sample = dict(q=recorded.q[i], qd=recorded.qd[i], base_wrench=recorded.base_wrench[i], t=recorded.t[i])
                sample.update(change)
                held = est.estimate_tip_force(**sample)
                statuses.append(est.last_status)
                np.testing.assert_array_equal(held, out[-1])  # the last good estimate
            out.append(est.estimate_tip_force(recorded.q[i], recorded.qd[i], base_wrench=recorded.base_wrench[i],
                                              t=recorded.t[i]))
        return np.stack(out), statuses

    clean, _ = run()
    with_bad, statuses = run(bad_at=6)
    assert statuses == [EstimatorStatus.INPUT_REJECTED]
    np.testing.assert_array_equal(with_bad, clean)  # the rejected sample left no trace


def test_batch_form_is_thread_safe(recorded):
    qdd = causal_acceleration(recorded.qd, 1.0 / RATE, 20.0)
    expected = estimate_tip_force(recorded.q, recorded.qd, qdd, base_wrench=recorded.base_wrench)
    results, errors = {}, []

    def worker(i):
        try:
            for _ in range(5):
                results[i] = estimate_tip_force(recorded.q, recorded.qd, qdd, base_wrench=recorded.base_wrench)
        except Exception as err:  # pragma: no cover - reported below
            errors.append(err)

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(4)]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert not errors
    for r in results.values():
        np.testing.assert_array_equal(r, expected)


def test_unknown_method():
    with pytest.raises(ValueError, match="unknown estimator method 'kalman'"):
        TipForceEstimator.analytic("panda", "kalman", encoder_resolution=0.0)


def test_auto_cutoff_replays_the_noise_window_then_equals_the_batch_filter(recorded, panda):
    """With qdd_cutoff_hz="auto" the cutoff is chosen at the end of the noise window, and the
    filter behaves as if it had run at that cutoff from the start (the generator's offline filter)."""
    est = TipForceEstimator.analytic(panda, "torques-pinv", call_hz=RATE, tare_seconds=0.5, encoder_resolution=0.0)
    stream = np.stack([est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=recorded.tau_J[k])
                       for k in range(len(recorded))])
    fc = est.qdd_cutoff_hz
    assert 5.0 <= fc <= 0.45 * RATE and fc != 20.0
    from hybrid_dyn.analytic.tip_force import tip_force_from_torques
    qdd = causal_acceleration(recorded.qd, 1.0 / RATE, fc)
    np.testing.assert_allclose(stream[50:], tip_force_from_torques(panda, recorded.q, recorded.qd, qdd,
                                                                   recorded.tau_J)[50:], atol=1e-6)


def test_qdd_noise_gain_matches_a_monte_carlo_of_the_generators_filter():
    from hybrid_dyn.estimator import qdd_noise_gain

    rng = np.random.default_rng(1)
    qd = rng.standard_normal((200_000, 1))  # unit white noise on qd
    for rate, fc in ((1000.0, 20.0), (1000.0, 150.0), (100.0, 20.0)):
        qdd = causal_acceleration(qd, 1.0 / rate, fc)[1000:]  # past the start-up transient
        assert np.var(qdd) == pytest.approx(qdd_noise_gain(rate, fc), rel=0.03)


def test_white_noise_rms_ignores_a_smooth_motion():
    from hybrid_dyn.estimator import white_noise_rms

    rng = np.random.default_rng(2)
    t = np.arange(2000) / 1000.0
    x = np.stack([np.sin(3 * t), 0.5 * t**2], axis=1) + np.array([1e-3, 0.2]) * rng.standard_normal((2000, 2))
    np.testing.assert_allclose(white_noise_rms(x), [1e-3, 0.2], rtol=0.08)


def test_auto_cutoff_rises_as_the_velocity_noise_falls(panda):
    """The rule trades lag for noise: quieter encoders let the filter open up."""
    from hybrid_dyn.estimator import auto_qdd_cutoff

    rng = np.random.default_rng(3)
    q = np.tile(panda.spec.home, (500, 1))
    w = 0.2 * rng.standard_normal((500, 6))
    cutoffs = [auto_qdd_cutoff(panda, 1000.0, q, s * rng.standard_normal((500, 7)), w, "base_wrench")
               for s in (5e-3, 5e-4, 5e-5, 0.0)]
    assert cutoffs == sorted(cutoffs) and cutoffs[0] < cutoffs[-1] and cutoffs[-1] == pytest.approx(450.0)


def _window_tared(panda, inst, n):
    """The batch tare the streaming estimator does on its first n calls (qdd: the 20 Hz causal filter)."""
    from hybrid_dyn.analytic.tare import tared_base_wrench

    qdd = causal_acceleration(inst.qd, 1.0 / RATE, 20.0)
    return tared_base_wrench(panda, inst.q, inst.qd, qdd, inst.base_wrench, n)


def test_streaming_base_momentum_equals_the_batch_observer_after_the_tare(recorded, panda):
    from hybrid_dyn.analytic.base_momentum import BaseMomentumObserver

    est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=RATE, tare_seconds=0.5, momentum_gain=20.0,
                                     encoder_resolution=0.0, max_sigma=1e3)  # statuses of the warm-up, not of the error bar
    stream, statuses = [], []
    for k in range(len(recorded)):
        stream.append(est.estimate_tip_force(recorded.q[k], recorded.qd[k], base_wrench=recorded.base_wrench[k],
                                             t=recorded.t[k]))
        statuses.append(est.last_status)
    w = _window_tared(panda, recorded, 50)
    batch = BaseMomentumObserver(panda, gain=20.0, dt=1.0 / RATE).run(recorded.q[50:], recorded.qd[50:], w[50:])[0]
    np.testing.assert_allclose(np.stack(stream)[50:], batch, atol=1e-9)
    # The tare window, its first step, then the observer's transient (1 - K dt)^n below 1 %, warm up.
    settle = int(np.ceil(np.log(0.01) / np.log(1.0 - 20.0 / RATE)))  # 21 calls
    n = 50 + settle
    assert set(statuses[:n]) == {EstimatorStatus.WARMING_UP} and set(statuses[n:]) == {EstimatorStatus.OK}


@pytest.mark.parametrize("with_torques", [True, False], ids=["both sensors", "base sensor only"])
def test_streaming_kalman_fusion_equals_the_batch_filter(recorded, panda, with_torques):
    """Noise and force rate from the tare window, then the filter; without tau_J it is the base-only filter."""
    from hybrid_dyn.analytic.bandwidth import measure_window
    from hybrid_dyn.analytic.kalman import KalmanTipForce, increment_stats, window_fusion_noise

    est = TipForceEstimator.analytic(panda, "kalman-fusion", call_hz=RATE, tare_seconds=0.5, encoder_resolution=0.0)
    tau = recorded.tau_J if with_torques else [None] * len(recorded)
    stream = np.stack([est.estimate_tip_force(recorded.q[k], recorded.qd[k], base_wrench=recorded.base_wrench[k],
                                              tau_J=tau[k], t=recorded.t[k]) for k in range(len(recorded))])
    w = _window_tared(panda, recorded, 50)
    tau_arr = recorded.tau_J if with_torques else None
    dt = 1.0 / RATE
    win_tau = None if tau_arr is None else tau_arr[:50]
    # The batch: the window's increments as arrays, on the wrench tared with the whole window's offset.
    y = KalmanTipForce(panda, dt).measurements(recorded.q[:50], recorded.qd[:50], w[:50], win_tau)
    noise = window_fusion_noise(panda, dt, measure_window(recorded.q[:50], recorded.qd[:50], recorded.base_wrench[:50],
                                                          win_tau),
                                increment_stats({c: np.diff(v, axis=0) for c, v in y.items()}))
    # The stream accumulates the window's increments call by call, on the raw wrench, and shifts them by
    # the tare's offset at the end; the batch sums them at once.
    assert dataclasses.asdict(est.fusion_noise) == pytest.approx(dataclasses.asdict(noise), rel=1e-9)
    batch = KalmanTipForce(panda, dt, noise).run(recorded.q[50:], recorded.qd[50:], w[50:],
                                                 None if tau_arr is None else tau_arr[50:])
    np.testing.assert_allclose(stream[50:], batch, atol=1e-9)


def test_kalman_fusion_needs_one_sensor_at_least(panda):
    est = TipForceEstimator.analytic(panda, "kalman-fusion", call_hz=RATE, encoder_resolution=0.0)
    with pytest.raises(EstimatorInputError, match="needs base_wrench .* tau_J .* or both"):
        est.estimate_tip_force(panda.spec.home, np.zeros(7))


def test_a_short_gap_is_bridged_and_a_long_one_warms_up_anew(recorded):
    """Two lost ticks: a short gap, bridged: no refusal, no warm-up, and the estimate goes on within a hair of
    the stream that lost nothing. A gap beyond bridge_seconds: the sample after it is refused (a gap, or a stray
    stamp?), the next confirms it and restarts the method: the resumed stream equals a new one started there."""
    def make():
        return TipForceEstimator.analytic("panda", "momentum-observer", call_hz=RATE, momentum_gain=50.0,
                                          on_bad_input="hold", encoder_resolution=0.0, max_sigma=1e3,
                                          bridge_seconds=0.05)
    tau = recorded.tau_J
    whole, est = make(), make()
    f_whole = [whole.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k]) for k in range(80)]
    for k in range(40):
        est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k])
    assert est.last_status is EstimatorStatus.OK
    for k in range(42, 80):  # ticks 40, 41 lost  # the interpolated ticks' error decays at the observer's rate, 50 /s
        f = est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k])
        assert est.last_status is EstimatorStatus.OK
        if k >= 70:
            np.testing.assert_allclose(f, f_whole[k], atol=0.05)
    gap = int(0.05 * RATE) + 2  # beyond bridge_seconds
    assert 43 + gap + 30 < len(recorded.t)
    est = make()
    for k in range(40):
        est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k])
    k0 = 40 + gap
    est.estimate_tip_force(recorded.q[k0], recorded.qd[k0], tau_J=tau[k0], t=recorded.t[k0])
    assert est.last_status is EstimatorStatus.INPUT_REJECTED
    est.estimate_tip_force(recorded.q[k0 + 1], recorded.qd[k0 + 1], tau_J=tau[k0 + 1], t=recorded.t[k0 + 1])
    assert est.last_status is EstimatorStatus.WARMING_UP
    fresh = make()
    for k in range(k0 + 1, k0 + 30):  # the resumed stream equals a new one started at tick k0 + 1
        a = est.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k]) if k > k0 + 1 else None
        b = fresh.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k])
        if a is not None:
            np.testing.assert_array_equal(a, b)
            assert est.last_status == fresh.last_status
    # A wrong rate never resumes: every step of a 2x slower stream is refused.
    slow = TipForceEstimator.analytic("panda", "momentum-observer", call_hz=RATE, on_bad_input="hold", encoder_resolution=0.0)
    for k in range(0, 40, 2):
        slow.estimate_tip_force(recorded.q[k], recorded.qd[k], tau_J=tau[k], t=recorded.t[k])
    assert slow.last_status is EstimatorStatus.INPUT_REJECTED
