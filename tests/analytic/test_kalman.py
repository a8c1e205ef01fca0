"""The fusion Kalman filter (analytic/kalman.py): the textbook gain, the Riccati error prediction,
fusion against single sensors, graceful degradation, streaming against batch."""
import numpy as np
import pytest
from scipy.linalg import solve_discrete_are, solve_discrete_lyapunov

from hybrid_dyn.analytic.kalman import FusionNoise, KalmanTipForce, SteadyStateKalman, momentum_filter

DT = 0.01


def test_steady_state_gain_is_the_textbook_gain():
    A = np.array([[1.0, DT], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q = np.diag([4e-6, 0.36 * DT])
    R = np.array([[2e-6]])
    P = solve_discrete_are(A.T, H.T, Q, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    f = momentum_filter(DT, [4e-6], [2e-6], force_rate=0.6)
    np.testing.assert_allclose(f.K, K, rtol=1e-10)
    np.testing.assert_allclose(f.P, P, rtol=1e-10)
    # ...and the prior covariance is the fixed point of the plain covariance recursion.
    Pk = np.eye(2)
    for _ in range(5000):
        Kk = Pk @ H.T @ np.linalg.inv(H @ Pk @ H.T + R)
        Pk = A @ (np.eye(2) - Kk @ H) @ Pk @ A.T + Q
    np.testing.assert_allclose(f.P, Pk, rtol=1e-8)


def simulate_channels(rng, n, q_sensors, r_sensors, force, force_rate=0.0):
    """The filter's own model per axis: s_c += dt F + w_c, y_c = s_c + v_c; F constant or a random walk."""
    m = len(q_sensors)
    F = force + np.cumsum(force_rate * np.sqrt(DT) * rng.standard_normal(n)) if force_rate else np.full(n, force)
    inc = np.zeros((n, m))
    inc[1:] = DT * F[:-1, None] + np.sqrt(q_sensors) * rng.standard_normal((n - 1, m))
    y = np.cumsum(inc, axis=0) + np.sqrt(r_sensors) * rng.standard_normal((n, m))
    y[0] = 0.0  # the sensors' sums start at zero
    return F, y


def test_error_variance_of_a_constant_force_matches_the_riccati_prediction():
    q, r = [4e-6], [2e-6]
    f = momentum_filter(DT, q, r, force_rate=0.6)
    rng = np.random.default_rng(0)
    F, y = simulate_channels(rng, 60_000, q, r, force=5.0)
    err = f.filter(y)[2000:, -1] - F[2000:]
    # The true system has no force random walk: its error covariance solves the Lyapunov equation
    # of the Riccati gain's error dynamics e_k = (I - K H)(A e_k-1 + w) - K v.
    IKH = np.eye(2) - f.K @ f.H
    Q_true = np.diag(q + [0.0])
    P_pred = solve_discrete_lyapunov(IKH @ f.A, IKH @ Q_true @ IKH.T + f.K @ np.diag(r) @ f.K.T)
    assert abs(err.var() / P_pred[-1, -1] - 1.0) < 0.10, (err.var(), P_pred[-1, -1])
    assert abs(err.mean()) < 3 * np.sqrt(P_pred[-1, -1])
    # On the model it assumes (a random-walk force) the error variance is the filter's P_post.
    F, y = simulate_channels(rng, 60_000, q, r, force=5.0, force_rate=0.6)
    err = f.filter(y)[2000:, -1] - F[2000:]
    assert abs(err.var() / f.P_post[-1, -1] - 1.0) < 0.10, (err.var(), f.P_post[-1, -1])


def test_fusion_beats_each_sensor_alone():
    q, r = [4e-6, 2e-6], [2e-6, 3e-6]
    rng = np.random.default_rng(1)
    F, y = simulate_channels(rng, 40_000, q, r, force=3.0, force_rate=0.6)
    both = momentum_filter(DT, q, r, 0.6).filter(y)[1000:, -1]
    one = momentum_filter(DT, q[:1], r[:1], 0.6).filter(y[:, :1])[1000:, -1]
    two = momentum_filter(DT, q[1:], r[1:], 0.6).filter(y[:, 1:])[1000:, -1]
    def rms(e):
        return float(np.sqrt(np.mean(e**2)))
    e_both, e_one, e_two = rms(both - F[1000:]), rms(one - F[1000:]), rms(two - F[1000:])
    assert e_both < 0.95 * min(e_one, e_two), (e_both, e_one, e_two)


def test_robot_filter_streaming_equals_batch_and_one_sensor_is_the_single_sensor_filter(panda, moving_arm):
    t, q, qd, wrench, force = moving_arm
    tau = panda.inverse_dynamics(q, qd, np.gradient(qd, t, axis=0))  # any torque signal will do here
    q, qd, wrench, tau = q[:150], qd[:150], wrench[:150], tau[:150]
    noise = FusionNoise(force_rate=5.0)
    kf = KalmanTipForce(panda, 1e-3, noise)
    for w_in, tau_in in ((wrench, tau), (wrench, None), (None, tau)):
        batch = kf.run(q, qd, w_in, tau_in)
        kf.reset()
        stream = np.stack([kf.step(q[k], qd[k], None if w_in is None else w_in[k], None if tau_in is None else tau_in[k])
                           for k in range(len(q))])
        np.testing.assert_allclose(stream, batch, atol=1e-9, rtol=0)
    # Base sensor only: a hand-written textbook time-varying filter on the same measurements gives the same
    # force, and its covariance settles to the steady-state (Riccati) one of scipy.
    y = kf.measurements(q, qd, base_wrench=wrench)["base"]
    A, H = np.array([[1.0, 1e-3], [0.0, 1.0]]), np.array([[1.0, 0.0]])
    Q, R = np.diag([kf._qv[0], kf._qv[2]]), np.array([[kf._rv[0]]])
    x, P = np.zeros((2, 3)), np.diag([kf._rv[0], 100.0**2])
    manual = []
    for k in range(len(q)):
        x, P = A @ x, A @ P @ A.T + Q
        if k == 0:  # the sensor anchors: its sum is its prediction, its error its measurement noise
            P[0, :] = P[:, 0] = 0.0
            P[0, 0] = R[0, 0]
        else:
            K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
            x, P = x + K @ (y[k][None, :] - H @ x), (np.eye(2) - K @ H) @ P
        manual.append(x[1])
    np.testing.assert_allclose(kf.run(q, qd, base_wrench=wrench), np.array(manual), atol=1e-9)
    for _ in range(20_000):
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        P = A @ (np.eye(2) - K @ H) @ P @ A.T + Q
    np.testing.assert_allclose(P, solve_discrete_are(A.T, H.T, Q, R), rtol=1e-6)
    # A sensor that drops out mid-run: the other carries on and the output stays finite.
    kf.reset()
    out = [kf.step(q[k], qd[k], wrench[k], tau[k] if k < 50 or k > 80 else None) for k in range(len(q))]
    assert np.isfinite(out).all()
    with pytest.raises(ValueError, match="base_wrench"):
        kf.step(q[0], qd[0], np.full(6, np.nan), None)


def test_fusion_noise_rejects_bad_values():
    with pytest.raises(ValueError, match="force_rate"):
        FusionNoise(force_rate=0.0)
    with pytest.raises(ValueError, match="joint_model"):
        FusionNoise(joint_model=-1.0)
    assert isinstance(momentum_filter(DT, [1e-6], [1e-6], 1.0), SteadyStateKalman)
