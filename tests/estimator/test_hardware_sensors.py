"""The estimator on sensors as hardware has them: quantized encoders, a touch during start-up,
stamp jitter, a drifting base sensor, a tool's load, and the error bar on every call.

References are independent of the code under test: the textbook Riccati recursion iterated by hand, a
Monte Carlo run of the filter, the DART plant (``sim.stream``), a stream built twice with and without
jitter, a base wrench from Pinocchio's own model at a fixed pose.
"""
import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.joint_state import (JointStateDesign, JointStateFilter, joint_state_noise,
                                             quantization_variance)
from hybrid_dyn.errors import UsageError
from hybrid_dyn.estimator import EstimatorStatus, TipForceEstimator
from hybrid_dyn.sim.sensors import EncoderModel, ForceTorqueModel, HardwareSensors
from hybrid_dyn.sim.stream import StreamConfig, Touch, simulate_stream

HZ = 1000.0
RES = 1e-5


# ------------------------------------------------------------------ the joint-state filter
def test_the_filter_gain_is_the_textbook_riccati_recursion_at_its_fixed_point():
    """The design solves the DARE in scaled units; the plain recursion P <- A P A' + Q - A P H'(H P H' + R)^-1 H P A'
    iterated from a large P in the model's own units reaches the same gain."""
    d = JointStateDesign.solve(HZ, quantization_variance(RES), 300.0)
    dt = 1.0 / HZ
    A = np.array([[1, dt, dt * dt / 2], [0, 1, dt], [0, 0, 1]])
    Q = d.variance * dt * 300.0**6 * np.array([[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                                                [dt**3 / 6, dt**2 / 2, dt]])
    P = np.diag([1e-6, 1e-2, 1e2])
    for _ in range(20000):
        S = P[0, 0] + d.variance
        P = A @ (P - np.outer(P[:, 0], P[0]) / S) @ A.T + Q
    K = P[:, 0] / (P[0, 0] + d.variance)
    np.testing.assert_allclose(d.gain, K, rtol=1e-6)


# The stream is the model's own (no model error): the error bar's stated model term (estimator/model_term.py) has
# nothing to carry here, and these tests are about other things.
EXACT_MODEL = {"inertial_uncertainty": 0.0, "payload_uncertainty_kg": 0.0}


def test_the_predicted_velocity_noise_is_what_the_filter_shows_on_white_noise():
    """joint_state_noise (a Lyapunov equation) against a Monte Carlo run on uniform quantization-like noise."""
    d = JointStateDesign.solve(HZ, quantization_variance(RES), 300.0)
    rng = np.random.default_rng(0)
    q = rng.uniform(-RES / 2, RES / 2, (40000, 4))
    _, qd, qdd = JointStateFilter(4, d).run(q)
    s_qd, s_qdd = joint_state_noise(d)
    np.testing.assert_allclose(qd[2000:].std(), s_qd, rtol=0.03)
    np.testing.assert_allclose(qdd[2000:].std(), s_qdd, rtol=0.03)


def test_the_filter_follows_a_polynomial_motion_without_error():
    """A constant-acceleration model tracks a quadratic q exactly once its start has decayed."""
    d = JointStateDesign.solve(HZ, quantization_variance(RES), 300.0)
    t = np.arange(3000) / HZ
    q = (0.1 + 0.4 * t + 0.75 * t**2)[:, None] * np.ones(2)
    qh, qdh, qddh = JointStateFilter(2, d).run(q)
    np.testing.assert_allclose(qdh[-1], 0.4 + 1.5 * t[-1], rtol=1e-6)
    np.testing.assert_allclose(qddh[-1], 1.5, rtol=1e-5)


# ------------------------------------------------------------------ streams from the DART plant
@pytest.fixture(scope="module")
def panda():
    return hd.load_robot("panda", num_threads=1)


QUANTIZED = HardwareSensors(EncoderModel(RES, "difference"), ForceTorqueModel(force_drift=0.0, torque_drift=0.0))


def run(est, r, n0=0, reads=("base_wrench",)):
    out, sig, status = [], [], []
    for k in range(n0, len(r.t)):
        out.append(est.estimate_tip_force(r.q[k], r.qd[k], base_wrench=r.base_wrench[k] if "base_wrench" in reads else None,
                                          tau_J=r.tau_J[k] if "tau_J" in reads else None, t=r.t[k]))
        sig.append(est.last_sigma.copy())
        status.append(est.last_status)
    return np.array(out), np.array(sig), status


def test_quantized_encoders_read_through_the_joint_filter_not_their_difference(panda):
    """The drive's qd (the difference of a 1e-5 rad encoder) fed as exact velocity errs tens of newtons; the
    default (the description's resolution, the joint-state filter) brings base-momentum near the sensor."""
    s = simulate_stream(panda, StreamConfig(seconds=4.0, sensors=QUANTIZED), seed=3)
    err = {}
    for label, res in (("default", "auto"), ("as exact", 0.0)):
        est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ, encoder_resolution=res)
        f, _, _ = run(est, s.readings)
        err[label] = np.sqrt(np.mean(np.sum((f[500:] - s.tip_force[500:]) ** 2, axis=1)))
    assert est.encoder_resolution == 0.0 and panda.spec.encoder_resolution == RES
    assert err["as exact"] > 5.0 and err["default"] < 1.5 and err["default"] < err["as exact"] / 5, err


def test_a_touch_inside_the_window_is_not_tared_and_the_status_says_so(panda):
    """6 N for 0.2 s inside the first window: the window is refused ("contact at start-up"), a clean one follows,
    and after it the estimate is right; taring over the touch used to leave 2.4 N for good."""
    cfg = StreamConfig(seconds=3.0, sensors=QUANTIZED, contacts=None,
                       touches=(Touch(0.2, 6.0, 0.2, direction=(1.0, 0.0, -0.5)),))
    s = simulate_stream(panda, cfg, seed=4)
    est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ, **EXACT_MODEL)
    f, _, status = run(est, s.readings)
    assert EstimatorStatus.CONTACT_AT_START in status[500:1000]
    assert "inside the noise window" in (est.window_problem or "") or est.window_problem is None
    ok = np.array([x is EstimatorStatus.OK for x in status])
    assert not ok[:1000].any() and ok[1500:].mean() > 0.9
    assert np.abs(f[1500:][ok[1500:]]).max() < 1.0  # nothing touches the arm after 0.4 s


def test_a_press_held_through_the_window_is_seen_by_the_joint_torques(panda):
    """10 N from t = 0 for 1.5 s: the base sensor alone cannot tell it from its offset, the joint torques can:
    kalman-fusion refuses every window the press lies in and tares after it."""
    cfg = StreamConfig(seconds=4.0, sensors=QUANTIZED, contacts=None,
                       touches=(Touch(0.0, 10.0, 1.5, direction=(0.3, 0.2, -1.0)),))
    s = simulate_stream(panda, cfg, seed=5)
    est = TipForceEstimator.analytic(panda, "kalman-fusion", call_hz=HZ, **EXACT_MODEL)
    f, _, status = run(est, s.readings, reads=("base_wrench", "tau_J"))
    ok = np.array([x is EstimatorStatus.OK for x in status])
    assert not ok[:1500].any() and EstimatorStatus.CONTACT_AT_START in status[500:1500]
    assert ok[-1000:].mean() > 0.9
    assert np.abs(f[-1000:][ok[-1000:]]).max() < 1.0  # released: the tare did not keep the press


def test_jittered_stamps_are_used_not_refused_and_change_nothing(panda):
    """Stamps off the robot's clock by 0.2 ms (sigma, clipped at 0.5 ms): every call accepted, and the estimate
    equals the same stream's with exact stamps (the filters run on the robot's period)."""
    rng = np.random.default_rng(6)
    n = 3000
    q = np.array(panda.spec.home) + 0.05 * np.sin(np.arange(n)[:, None] / HZ * np.linspace(1, 3, 7))
    qd = np.gradient(q, 1 / HZ, axis=0)
    w = panda.base_wrench(q, qd, np.gradient(qd, 1 / HZ, axis=0)) + rng.normal(0, 0.2, (n, 6))
    t = np.arange(n) / HZ
    jitter = np.clip(rng.normal(0, 2e-4, n), -5e-4, 5e-4)
    outs = []
    for stamps in (t, t + jitter):
        est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ, on_bad_input="hold")
        outs.append([est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], t=stamps[k]) for k in range(n)])
        assert est.last_status is not EstimatorStatus.INPUT_REJECTED
    np.testing.assert_array_equal(outs[0], outs[1])
    # A lost tick is no jitter: it is a short gap, bridged (its tick interpolated in) with no refusal and no
    # warm-up, and the estimate goes on within a hair of the stream that lost nothing.
    est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ, on_bad_input="hold")
    kept = [k for k in range(n) if k != 1500]
    f, status = {}, {}
    for k in kept:
        f[k] = est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], t=t[k])
        status[k] = est.last_status
    assert status[1499] is EstimatorStatus.OK and est._gate._stamps == n - 1
    assert all(status[k] is EstimatorStatus.OK for k in range(1501, n))
    after = np.array([f[k] - outs[0][k] for k in range(1501, 1600)])
    # the interpolated sample stands in for one with 0.2 N of noise: at most that much difference, then its decay
    assert np.abs(after).max() < 0.2 and np.abs(after[-1]).max() < 1e-3, np.abs(after).max(axis=1)


def test_a_drifting_base_sensor_is_followed_at_standstill(panda):
    """The arm holds still, nothing touches it, the base sensor's bias drifts by 0.05 N/s for 40 s, the rate the
    sensor is declared with (base_drift_rate): the tare follows it (the error stays under 0.5 N); with the
    follower's time constant beyond the run it reaches 2 N."""
    rng = np.random.default_rng(7)
    n = 40000
    q = np.tile(panda.spec.home, (n, 1))
    w0 = panda.base_wrench(q[:1], np.zeros((1, 7)), np.zeros((1, 7)))[0]
    drift = 0.05 * np.arange(n)[:, None] / HZ * np.r_[0.6, 0.0, 0.8, 0, 0, 0]
    w = w0 + 1.0 + drift + rng.normal(0, 0.2, (n, 6)) * np.r_[1, 1, 1, 0.05, 0.05, 0.05]
    last = {}
    for label, tau in (("followed", 2.0), ("not followed", float("inf"))):
        est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ, retare_seconds=tau, base_drift_rate=0.05)
        for k in range(n):
            f = est.estimate_tip_force(q[k], np.zeros(7), base_wrench=w[k], t=k / HZ)
        last[label] = np.linalg.norm(f)
    assert last["followed"] < 0.5 and last["not followed"] > 1.5, last


def test_a_contact_building_slowly_at_standstill_is_not_tared_away(panda):
    """A force ramping at 0.3 N/s to 3 N at a standstill, held, released: the follower moves no faster than the
    sensor's stated drift (0.025 N/s), so the held force reads within 0.5 N and after the release no ok call
    reads more than 0.5 N (the ground truth: the model's own base wrench with the tip force)."""
    rng = np.random.default_rng(8)
    n = 18000
    t = np.arange(n) / HZ
    q = np.tile(panda.spec.home, (n, 1))
    mag = np.interp(t, [0, 1.0, 11.0, 14.0, 14.001, 18.0], [0, 0, 3.0, 3.0, 0, 0])
    f_true = mag[:, None] * np.array([0.6, 0.0, -0.8])
    w = panda.base_wrench(q, np.zeros_like(q), np.zeros_like(q), tip_force=f_true) + 1.0
    w = w + rng.normal(0, 0.2, (n, 6)) * np.r_[1, 1, 1, 0.05, 0.05, 0.05]
    est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ)
    err, ok = np.empty(n), np.empty(n, bool)
    for k in range(n):
        f = est.estimate_tip_force(q[k], np.zeros(7), base_wrench=w[k], t=t[k])
        err[k], ok[k] = np.linalg.norm(f - f_true[k]), est.last_status is EstimatorStatus.OK
    held, after = (t > 12.0) & (t < 14.0), t > 14.2
    assert err[held].max() < 0.5 and ok[held].mean() > 0.9, (err[held].max(), ok[held].mean())
    assert err[after & ok].max() < 0.5 and ok[after].mean() > 0.9


def test_a_declared_payload_is_removed_by_the_joint_torque_methods(panda):
    """DART carries a 0.5 kg load 5 cm past the tool point: momentum-observer, told of it (payload=), sees no
    force; not told, it sees the load's weight (~4.9 N)."""
    load = (0.5, (0.0, 0.0, 0.05))
    s = simulate_stream(panda, StreamConfig(seconds=3.0, sensors=QUANTIZED, contacts=None, payload=load), seed=8)
    err = {}
    for label, payload in (("declared", load), ("unknown", None)):
        est = TipForceEstimator.analytic(panda, "momentum-observer", call_hz=HZ, payload=payload)
        f, _, _ = run(est, s.readings, reads=("tau_J",))
        err[label] = np.sqrt(np.mean(np.sum(f[1000:] ** 2, axis=1)))
    assert err["declared"] < 1.0 and 4.0 < err["unknown"] < 6.0, err
    est.set_payload(*load)
    assert est.robot.payload.mass == 0.5  # in place, running on (tests/estimator/test_payload.py)
    for bad in ((-1.0, (0, 0, 0)), (500.0, (0, 0, 0)), (0.5, (0, 0, 5.0)), ("x", 1)):
        with pytest.raises(UsageError, match="payload"):
            TipForceEstimator.analytic(panda, "base-momentum", payload=bad)


def test_the_error_bar_covers_the_ok_calls(panda):
    """At least 90 % of the ok calls lie within 2 sigma on every axis, and no ok call errs by more than 4 N."""
    s = simulate_stream(panda, StreamConfig(seconds=6.0, sensors=QUANTIZED), seed=9)
    est = TipForceEstimator.analytic(panda, "base-momentum", call_hz=HZ)
    f, sig, status = run(est, s.readings)
    ok = np.array([x is EstimatorStatus.OK for x in status])
    err = np.abs(f - s.tip_force)
    assert ok.mean() > 0.7
    assert np.all(err[ok] <= 2 * sig[ok], axis=1).mean() >= 0.9
    assert np.all(sig[ok].max(axis=1) <= est.max_sigma)
    assert np.isinf(sig[:500]).all()  # the window: no estimate, no error bar


def test_the_batch_run_is_the_estimator_with_its_window_check_and_error_bar(panda):
    """run_batch (the bench's rows) against the streaming estimator on a stream with a touch in the first
    window: the same window (the second), the same forces and the same error bar, call for call."""
    from hybrid_dyn.analytic.batch_run import run_batch

    cfg = StreamConfig(seconds=2.5, sensors=QUANTIZED, contacts=None,
                       touches=(Touch(0.2, 6.0, 0.2, direction=(1.0, 0.0, -0.5)), Touch(1.6, 8.0, 0.5, rise=0.01)))
    r = simulate_stream(panda, cfg, seed=10).readings
    for method in ("base-momentum", "base-wrench"):
        # as run_batch, whose error bar carries the sensors' terms and no stated model term
        est = TipForceEstimator.analytic(panda, method, call_hz=HZ, retare_seconds=float("inf"), **EXACT_MODEL)
        f, sig, status = run(est, r)
        fb, used, sb = run_batch(method, panda, HZ, r.q, r.qd, r.base_wrench, with_sigma=True)
        assert used == pytest.approx(est.bandwidth)
        np.testing.assert_allclose(fb[1001:], f[1001:], atol=1e-7)
        settled = np.isfinite(sig).all(axis=1)
        np.testing.assert_array_equal(settled, np.isfinite(sb).all(axis=1))
        np.testing.assert_allclose(sb[settled], sig[settled], atol=1e-7)
