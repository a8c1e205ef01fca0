"""One rule for every filter that trades noise against lag, applied to the noise a window measures.

**The rule.** A method's contact-free estimate may carry at most twice the
variance of the force sensor's own noise (the sensor's noise, and as much again
added by the method); within that, the widest bandwidth is taken, since a wider
one lags less behind a changing contact:

    sigma_estimate^2 (bandwidth) <= NOISE_RATIO * sigma_sensor^2,   NOISE_RATIO = 2

sigma_sensor is the white noise of the sensor the method reads its force from
(the base sensor's force axes, or the joint torques), and sigma_estimate is
predicted in closed form from the noises measured on the window
(:func:`measure_window`, the median-based ``white_noise_rms``):

- qdd cutoff (base-wrench, torques-pinv): the qdd estimate's noise through
  m J_com or M(q) may equal the sensor's (``acceleration.auto_qdd_cutoff``);
- observer gain K (base-momentum, momentum-observer): the observer
  r = K (H - H0 - integral(u + r)) passes the input's white noise (sigma_u,
  trapezoid) with variance gain K dt / 2 and the momentum's (sigma_H, from qd
  through m J_com or M) with 2 K^2 / (2 - K dt) (:func:`observer_noise_gains`);
- Kalman force rate (kalman-fusion): the steady-state gain k of the random-walk
  force seen through the primary channel's increment noise sigma_e passes it
  with variance gain k / (2 - k); the largest k within the rule, and the force
  rate that gives it (:func:`kalman_force_rate`; a measured model error, a bias,
  is weighed by the filter but left out of the rule).

Failure modes (what the rule does not know):
- it is relative: it holds the estimate to the sensor's own quality, not to a
  task's error. A quieter force sensor with the same encoders *narrows* the band
  (the encoders' share must shrink with it); noise-free velocities open it fully.
- it sees only white noise: a slow drift, a vibration or a model error on the
  window does not narrow it.
- it knows nothing of the contact: slow contacts would tolerate a narrower band
  (less noise), steps want a wider one. The bench's ``-val`` rows show what a
  band chosen on validation data gains.
- the window must be contact-free and long enough (>= 8 samples; 0.5 s by default).
- noise-free data (a simulation without sensor noise): the force sensors' noise is
  taken as at least FORCE_RESOLUTION (0.01 N or Nm), and the band opens fully.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .acceleration import white_noise_rms

NOISE_RATIO = 2.0  # the estimate's noise variance may be this multiple of the sensor's
TOP_GAIN_DT = 1.0  # observers: K dt up to 1 (the deadbeat observer, a plain trapezoidal difference)
TOP_KALMAN_GAIN = 0.95  # kalman-fusion: the largest steady-state force gain per call
SETTLE_FRACTION = 0.01  # "settled": a start's transient has decayed below 1 %


@dataclass(frozen=True)
class WindowNoise:
    """White noise measured on a (contact-free) window: qd (nv,) [rad/s]; base_force: the base sensor's
    per-axis force noise [N] (None without it); joint_torque (nv,) [Nm] (None without it); q_mean (nv,)
    [rad], the window's mean pose."""

    qd: np.ndarray
    base_force: float | None
    joint_torque: np.ndarray | None
    q_mean: np.ndarray

    @property
    def joint_torque_rms(self) -> float | None:
        return None if self.joint_torque is None else float(np.sqrt(np.mean(self.joint_torque ** 2)))


# The finest noise a force or torque sensor of this class shows [N, Nm]: a window that measures less
# is a simulation without noise, where the second differences see only the motion's smooth residue
# and the rule would compare two round-off figures.
FORCE_RESOLUTION = 0.01
VELOCITY_FLOOR = 1e-9  # rad/s: a positive velocity noise for the filters' variances


def measure_window(q, qd, base_wrench=None, tau_J=None) -> WindowNoise:
    """The noise of a window's samples (n, ...) with n >= 8 (``white_noise_rms``), the force and torque
    sensors' at least FORCE_RESOLUTION; a sensor not given is None."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    if len(q) < 8:
        raise ValueError(f"the noise window needs at least 8 samples, got {len(q)}")
    base = None
    if base_wrench is not None:
        base = max(FORCE_RESOLUTION, float(np.sqrt(np.mean(white_noise_rms(np.asarray(base_wrench, float)[:, :3]) ** 2))))
    tau = None if tau_J is None else np.maximum(FORCE_RESOLUTION, white_noise_rms(np.asarray(tau_J, float)))
    return WindowNoise(np.maximum(VELOCITY_FLOOR, white_noise_rms(qd)), base, tau, q.mean(axis=0))


def observer_noise_gains(gain, dt: float):
    """(from the input, from the momentum): the momentum observer's variance gains for white noise on
    its input u (the sensor's force or torque, per sample) [1] and on its momentum H [1/s^2].

    r_k = K (a_k - dt S_k-1), a = H - H0 - trapezoid(u): with c = K dt and a = 1 - c,
    u -> r is -c (1 + z^-1) / 2 / (1 - a z^-1), whose squared impulse response sums to c / 2;
    H -> r is K (1 - z^-1) / (1 - a z^-1), summing to 2 K^2 / (2 - c).
    """
    c = np.asarray(gain, float) * dt
    return c / 2.0, 2.0 * np.asarray(gain, float) ** 2 / (2.0 - c)


def observer_gain_grid(rate_hz: float) -> np.ndarray:
    """The gains [1/s] the rule chooses from: 1/s up to K dt = TOP_GAIN_DT."""
    return np.geomspace(1.0, TOP_GAIN_DT * rate_hz, 64)


def observer_gain(rate_hz: float, s_input: float, s_momentum: float, s_sensor: float) -> float:
    """The rule for an observer: the largest grid gain K [1/s] whose predicted noise
    s_input^2 g_u(K) + s_momentum^2 g_H(K) is at most NOISE_RATIO s_sensor^2 (the smallest without one)."""
    grid = observer_gain_grid(rate_hz)
    g_u, g_h = observer_noise_gains(grid, 1.0 / rate_hz)
    ok = np.flatnonzero(s_input**2 * g_u + s_momentum**2 * g_h <= NOISE_RATIO * s_sensor**2)
    return float(grid[ok[-1]] if len(ok) else grid[0])


def observer_settle_calls(gain: float, dt: float) -> int:
    """Calls until a start's transient (1 - K dt)^n is below SETTLE_FRACTION."""
    c = min(gain * dt, 1.0)
    return 1 if c >= 1.0 else int(math.ceil(math.log(SETTLE_FRACTION) / math.log(1.0 - c)))


def random_walk_gain(force_rate: float, dt: float, s_e2: float) -> float:
    """The steady-state gain k of the scalar Kalman filter of a random walk of intensity force_rate
    [N/sqrt(s)] seen once per dt through white noise of variance s_e2 [N^2]: with lambda = Q / R,
    p = (lambda + sqrt(lambda^2 + 4 lambda)) / 2 and k = p / (1 + p)."""
    lam = force_rate**2 * dt / max(s_e2, 1e-300)
    p = 0.5 * (lam + math.sqrt(lam * lam + 4.0 * lam))
    return p / (1.0 + p)


def kalman_gain(s_e2: float, s_sensor: float) -> float:
    """The rule for the fusion filter's steady-state force gain per call: the largest k whose pass of
    the white increment noise s_e2 [N^2] (the momentum increments over dt, as a force),
    k / (2 - k) s_e2, is at most NOISE_RATIO s_sensor^2: k = 2 r / (1 + r), r = NOISE_RATIO s_sensor^2
    / s_e2, capped at TOP_KALMAN_GAIN."""
    r = NOISE_RATIO * s_sensor**2 / max(s_e2, 1e-300)
    return max(1e-6, min(TOP_KALMAN_GAIN, 2.0 * r / (1.0 + r)))


def kalman_force_rate(dt: float, s_e2: float, s_sensor: float, s_e2_model: float | None = None) -> float:
    """The force rate [N/sqrt(s)] that gives the filter ``kalman_gain(s_e2, s_sensor)`` when the filter
    weighs the increments with variance s_e2_model [N^2] (its white noise plus model errors; default
    s_e2): lambda = k^2 / (1 - k) inverts ``random_walk_gain``. A model error (a bias) is left out of
    the rule: narrowing the band would not remove it."""
    k = kalman_gain(s_e2, s_sensor)
    return math.sqrt(k * k / (1.0 - k) * max(s_e2 if s_e2_model is None else s_e2_model, 1e-300) / dt)


def kalman_settle_calls(k: float) -> int:
    """Calls until a start's transient (1 - k)^n is below SETTLE_FRACTION."""
    return 1 if k >= 1.0 else int(math.ceil(math.log(SETTLE_FRACTION) / math.log(1.0 - k)))
