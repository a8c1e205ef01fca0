"""The bandwidth chosen from the data (analytic/bandwidth.py), on synthetic streams of known noise.

- the window measures the noise it was given;
- the rule widens the band when a noise drops and narrows it when it grows (monotone, every registered method:
  the filters' band, the qdd methods' cutoff);
- on a contact-free stream an observer's estimate noise is the noise the rule predicted for its choice.
"""
import numpy as np
import pytest
from scipy.signal import lfilter

from hybrid_dyn.analytic.bandwidth import CONTACT_STEP, contact_rate, lag_variance, measure_window, observer_gain
from hybrid_dyn.analytic.kalman_method import KalmanFusionMethod
from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS
from hybrid_dyn.analytic.observer_methods import ObserverMethod
from hybrid_dyn.estimator import TipForceEstimator

HZ = 1000.0


def quiet_stream(robot, n, s_qd, s_force, s_tau, seed=0, moving=True):
    """Contact-free rigid-body samples (a slow motion about home, or the arm at rest) with white noise of
    known size on qd [rad/s], the base sensor's forces [N] (moments: 5 % of it [Nm]) and tau_J [Nm]."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / HZ
    amp, w = rng.uniform(0.05, 0.15, robot.nv) * moving, rng.uniform(0.3, 1.0, robot.nv)
    q = np.array(robot.spec.home) + amp * np.sin(w * t[:, None])
    qd = amp * w * np.cos(w * t[:, None])
    qdd = -amp * w**2 * np.sin(w * t[:, None])
    wrench = robot.base_wrench(q, qd, qdd) + rng.normal(0, 1, (n, 6)) * s_force * np.r_[np.ones(3), np.full(3, 0.05)]
    tau = robot.inverse_dynamics(q, qd, qdd) + rng.normal(0, s_tau, (n, robot.nv))
    return t, q, qd + rng.normal(0, s_qd, qd.shape), wrench, tau


def test_the_window_measures_the_noise_it_was_given(panda):
    for s_qd, s_force, s_tau in ((1e-4, 0.05, 0.02), (5e-4, 0.2, 0.05), (2e-3, 1.0, 0.2)):
        t, q, qd, w, tau = quiet_stream(panda, 500, s_qd, s_force, s_tau)
        noise = measure_window(q, qd, w, tau)
        assert noise.qd == pytest.approx(np.full(7, s_qd), rel=0.2)
        assert noise.base_force == pytest.approx(s_force, rel=0.1)
        assert noise.joint_torque_rms == pytest.approx(s_tau, rel=0.1)


def bandwidth(robot, method, s_qd, s_force, s_tau):
    """The method's bandwidth chosen on a 0.5 s window of that noise, as the estimator chooses it; for
    kalman-fusion, the bandwidth [1/s] of its steady-state force gain k per call with both sensors (its force
    rate is the model's): the first-order filter with pole 1 - k, -ln(1 - k) / dt."""
    t, q, qd, w, tau = quiet_stream(robot, 500, s_qd, s_force, s_tau, seed=1)
    stream = TIP_FORCE_METHODS[method].make(robot, HZ)
    noise = measure_window(q, qd, w, tau)
    if isinstance(stream, KalmanFusionMethod):
        stream.close_window(noise, None)
        return -np.log(1.0 - stream.kalman.gains[("base", "joint")]) * HZ
    return stream.choose(noise)


FILTERS = [m.name for m in TIP_FORCE_METHODS.where(needs_qdd=False)]  # filters with state: a band to narrow
QDD_METHODS = [m.name for m in TIP_FORCE_METHODS.where(needs_qdd=True)]  # per sample: the qdd filter's cutoff
# The observers' rule states the noise it predicts for the gain it picks.
OBSERVERS = [m.name for m in TIP_FORCE_METHODS.values() if isinstance(m.make, type) and issubclass(m.make, ObserverMethod)]


@pytest.mark.parametrize("method", FILTERS)
def test_the_band_narrows_as_any_noise_grows(method, panda):
    """Each noise in turn, the others fixed: a monotone answer, and a change across the range."""
    # Quiet encoders while a force sensor's noise moves (else the velocity noise decides the band).
    base = dict(s_qd=2e-5, s_force=0.1, s_tau=0.03)
    for name, levels in (("s_qd", (2e-5, 1e-4, 3e-4, 1e-3, 3e-3)), ("s_force", (0.02, 0.05, 0.1, 0.3, 1.0)),
                         ("s_tau", (0.005, 0.02, 0.05, 0.2, 0.5))):
        reads = TIP_FORCE_METHODS[method].reads
        if name == "s_force" and "base_wrench" not in reads or name == "s_tau" and "tau_J" not in reads:
            continue  # a sensor the method does not read
        bands = [bandwidth(panda, method, **dict(base, **{name: v})) for v in levels]
        assert all(a >= b for a, b in zip(bands, bands[1:])), (method, name, bands)
        assert bands[0] > 1.5 * bands[-1], (method, name, bands)


@pytest.mark.parametrize("method", QDD_METHODS)
def test_the_qdd_cutoff_narrows_as_the_velocity_noise_grows(method, panda):
    """The qdd methods pass the contact unfiltered; their cutoff follows the qd noise against the sensor's."""
    bands = [bandwidth(panda, method, s_qd, 0.2, 0.05) for s_qd in (2e-5, 1e-4, 5e-4, 2e-3)]
    assert all(a >= b for a, b in zip(bands, bands[1:])) and bands[0] > 2 * bands[-1], bands


def test_the_rule_is_the_minimum_of_noise_and_lag():
    """observer_gain against a brute-force minimum of the stated error on a fine grid."""
    dt = 1.0 / HZ
    for s_in, s_mom in ((0.05, 0.0), (0.2, 1.45e-3), (0.05, 5e-4), (1.0, 3e-3)):
        k, noise = observer_gain(HZ, s_in, s_mom)
        fine = np.geomspace(1.0, HZ, 20000)
        err = s_in**2 * fine * dt / 2 + s_mom**2 * 2 * fine**2 / (2 - fine * dt) + lag_variance(fine, dt)
        best = fine[np.argmin(err)]
        assert abs(np.log(k / best)) < np.log(HZ) / 63 + 1e-9  # within one step of the rule's 64-point grid
        assert noise == pytest.approx(np.sqrt(s_in**2 * k * dt / 2 + s_mom**2 * 2 * k**2 / (2 - k * dt)))
    assert lag_variance(np.array([HZ]), dt)[0] == 0.0
    # The lag side is the textbook one: a first-order filter on a random walk of per-sample step s, by
    # simulation (its steady error variance s^2 a^2 / (1 - a^2)).
    rng = np.random.default_rng(0)
    walk = np.cumsum(CONTACT_STEP * rng.standard_normal(400_000))
    for k in (30.0, 300.0):
        a = 1.0 - k * dt
        err = lfilter([1.0 - a], [1.0, -a], walk) - walk
        assert np.mean(err[1000:] ** 2) == pytest.approx(lag_variance(np.array([k]), dt)[0], rel=0.1)
    assert contact_rate(1e-3) == pytest.approx(CONTACT_STEP / np.sqrt(1e-3))


@pytest.mark.parametrize("method", OBSERVERS)
@pytest.mark.parametrize("levels", [(1e-4, 0.05, 0.02), (5e-4, 0.2, 0.05)], ids=["quiet", "generator"])
def test_contact_free_estimate_noise_is_what_the_rule_predicts(method, levels, panda):
    """The estimator with its defaults on a contact-free stream (the arm at rest): the estimate's noise per
    axis after the window and the settling is the rule's predicted noise for the band it chose."""
    t, q, qd, w, tau = quiet_stream(panda, 6000, *levels, seed=2, moving=False)
    est = TipForceEstimator.analytic(panda, method, call_hz=HZ, encoder_resolution=0.0)
    out = np.stack([est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], tau_J=tau[k], t=t[k]) for k in range(len(t))])
    measured = float(np.sqrt(np.mean(out[1000:] ** 2)))  # RMS over axes; the true force is 0
    predicted = est._stream.predicted_noise
    assert measured == pytest.approx(predicted, rel=0.15), (est.bandwidth, measured, predicted)
