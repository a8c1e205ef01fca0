"""The error bar on every call: ``TipForceEstimator.last_sigma``, the predicted 1-sigma error per axis [N].

A tip-force estimate errs for four reasons, each with a term (per axis, added in quadrature):

- **noise**: the sensors' noise through the method's filter, measured on the estimate itself: the
  variance of its deviation from a 20 ms running mean, averaged over ~1 s (a deviation beyond 3 sigma
  enters clipped: it is a transient, the lag term's), times NOISE_GAIN;
- **lag**: a filter that has not caught up with a change. While the estimate moves, it differs from
  its own 20 ms running mean by about what it still lacks: that difference, less the LAG_NOISE_SIGMAS
  sigma of it that noise explains, is the term;
- **motion**: the model's inertial terms read the joints' acceleration through the joint-state filter
  (``analytic/joint_state.py``), which lags the arm's own accelerations: ``motion_gain`` [N per
  rad/s^2] times the norm of the filtered qdd. On the hardware stream of
  ``benchmarks/tip_force_stream.py`` (1e-5 rad encoders, the filter at 300 rad/s) the error of every
  method grows by 0.1-0.15 N per axis per rad/s^2 of joint acceleration. Without the filter (exact
  encoders, a learned model) the term is 0: nothing lags the arm's accelerations but what the lag
  term sees;
- **drift**: a base sensor's bias moves after its tare: ``drift_rate`` [N/s] (the sensor's stated rate,
  ``description.sensor_noise.SENSOR_DRIFT``) times the time since the tare was last verified (set, or
  followed at a standstill with no contact).

Calibration: NOISE_GAIN = 1.3, LAG_NOISE_SIGMAS = 1 and motion_gain = 0.1 were chosen on streams of
``benchmarks/tip_force_stream.py`` that its table does not use (seeds 200-201 of ``hardware``, 202
of ``step-15``): there 97 % or more of the ``ok`` calls of base-momentum, kalman-fusion,
momentum-observer and base-wrench lay within 2 sigma on every axis, with 82-94 % of the calls ``ok``.
The benchmark reports the coverage on its own seeds (100 on).

The status says ``uncertain`` while any axis's sigma exceeds ``EstimatorConfig.max_sigma``;
``benchmarks/tip_force_stream.py`` reports how many ``ok`` calls lie within 2 sigma on every axis.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..description.sensor_noise import SENSOR_DRIFT

FAST_SECONDS = 0.02  # the running mean the lag and noise terms are taken against [s]
SLOW_SECONDS = 1.0   # the noise term's averaging time [s]
LAG_NOISE_SIGMAS = 1.0  # a deviation within this many noise sigmas is noise, not lag
NOISE_GAIN = 1.3  # the noise term's factor over the measured deviation variance
NOISE_FLOOR = 0.05   # [N]: the noise term's least step, so that it can grow from a noise-free start
MOTION_GAIN = 0.1    # [N per rad/s^2]: the motion term's default (EstimatorConfig.motion_sigma_gain)
DRIFT_RATE = SENSOR_DRIFT.base_force  # [N/s]: the drift term's default (EstimatorConfig.base_drift_rate)


class ErrorBar:
    """Per-stream state of the error model; ``update`` once per estimate (see the module docstring)."""

    def __init__(self, rate_hz: float, motion_gain: float = MOTION_GAIN, drift_rate: float = DRIFT_RATE):
        dt = 1.0 / float(rate_hz)
        self.a_fast, self.a_slow = min(1.0, dt / FAST_SECONDS), min(1.0, dt / SLOW_SECONDS)
        self.dt, self.motion_gain, self.drift_rate = dt, float(motion_gain), float(drift_rate)
        self.mean, self.var = np.zeros(3), np.zeros(3)
        self.reset()
        _update(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), 0.5, 0.5, True, 0.0)  # compile now

    def reset(self) -> None:
        """A start (or a gap): the running means begin again at the next estimate."""
        self._started = False

    def update(self, f: np.ndarray, qdd_norm: float, seconds_since_tare: float | None) -> np.ndarray:
        """The 1-sigma error per axis (3,) [N] of estimate f (3,) [N]; qdd_norm [rad/s^2]: the norm of
        the joints' filtered acceleration; seconds_since_tare: None for a method without a tared sensor."""
        if not self._started:
            self.mean[:] = f
            self.var[:] = 0.0
            self._n = 0
            self._started = True
        self._n += 1
        extra = (self.motion_gain * qdd_norm) ** 2
        if seconds_since_tare is not None:
            extra += (self.drift_rate * seconds_since_tare) ** 2
        out = np.empty(3)
        _update(self.mean, self.var, out, f, self.a_fast, max(self.a_slow, 1.0 / self._n), self._n > 20, extra)
        return out


@njit(cache=True)
def _update(mean, var, out, f, a_fast, a_slow, clip, extra):  # pragma: no cover (compiled)
    """One sample of the running mean and noise variance per axis, and the sigma (module docstring)."""
    for i in range(3):
        dev = f[i] - mean[i]  # against the mean before this sample: white noise shows at least its variance
        mean[i] += a_fast * dev
        d2 = dev * dev
        if clip:  # noise only: a deviation beyond 3 sigma is a transient (the lag term's)
            d2 = min(d2, 9.0 * var[i] + NOISE_FLOOR * NOISE_FLOOR)
        var[i] += a_slow * (d2 - var[i])  # a plain mean until 1 / n < a_slow
        lag = max(abs(dev) - LAG_NOISE_SIGMAS * math.sqrt(var[i]), 0.0)  # what noise does not explain
        out[i] = math.sqrt(NOISE_GAIN * NOISE_GAIN * var[i] + lag * lag + extra)


def qdd_norm(qdd) -> float:
    """The Euclidean norm of a joint acceleration (nv,) [rad/s^2], 0 for None."""
    return 0.0 if qdd is None else math.sqrt(float(qdd.dot(qdd)))


__all__ = ["DRIFT_RATE", "ErrorBar", "MOTION_GAIN", "qdd_norm"]
