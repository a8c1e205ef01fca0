"""The error bar on every call: ``TipForceEstimator.last_sigma``, the predicted 1-sigma error per axis [N].

The detail (what it computes, the equations, why each choice): docs/design/analytic.md, section ``analytic/error_bar.py``.
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
# The motion term of a method that reads qdd, after a start or stop at ~1 rad/s (its qdd filter's lag had stayed
# in the estimate for 17-26 ms after the acceleration changed, at ok with 2-3 N off): |qdd| plus LAG_WEIGHT x the gap between qdd's running
# means over LAG_FAST and LAG_SLOW seconds (what a lagging filter still misses), the largest value held,
# decaying with time constant 2 LAG_SLOW.
LAG_FAST, LAG_SLOW, LAG_WEIGHT = 0.001, 0.025, 3.0


class ErrorBar:
    """Per-stream state of the error model; ``update`` once per estimate (docs/design/analytic.md, ``analytic/error_bar.py``)."""

    def __init__(self, rate_hz: float, motion_gain: float = MOTION_GAIN, drift_rate: float = DRIFT_RATE):
        dt = 1.0 / float(rate_hz)
        self.a_fast, self.a_slow = min(1.0, dt / FAST_SECONDS), min(1.0, dt / SLOW_SECONDS)
        self.dt, self.motion_gain, self.drift_rate = dt, float(motion_gain), float(drift_rate)
        self.mean, self.var = np.zeros(3), np.zeros(3)
        self._qdd = None  # qdd's running means over LAG_FAST and LAG_SLOW (2, nv) [rad/s^2], from the first motion
        self._decay = math.exp(-dt / (2.0 * LAG_SLOW))
        self.reset()
        _update(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), 0.5, 0.5, True, 0.0)  # compile now

    def reset(self) -> None:
        """A start (or a gap): the running means begin again at the next estimate."""
        self._started = False
        self._held = 0.0  # the motion term's input [rad/s^2], held
        self._motion_started = False

    def motion(self, qdd, lag: bool = True) -> float:
        """The motion term's input [rad/s^2] at this call; qdd (nv,) [rad/s^2] or None. lag: the method reads a
        filtered qdd, whose lag the term carries (LAG_WEIGHT's comment); else |qdd| alone."""
        if qdd is None:
            return 0.0
        if not lag:
            return qdd_norm(qdd)
        if not self._motion_started:
            if self._qdd is None or self._qdd.shape[1] != len(qdd):
                self._qdd = np.zeros((2, len(qdd)))
            self._qdd[:] = qdd
            self._motion_started = True
        m = self._qdd
        m[0] += (qdd - m[0]) * min(1.0, self.dt / LAG_FAST)
        m[1] += (qdd - m[1]) * min(1.0, self.dt / LAG_SLOW)
        self._held = max(qdd_norm(qdd) + LAG_WEIGHT * qdd_norm(m[0] - m[1]), self._held * self._decay)
        return self._held

    def update(self, f: np.ndarray, qdd_norm: float, seconds_since_tare: float | None) -> np.ndarray:
        """The 1-sigma error per axis (3,) [N] of estimate f (3,) [N]; qdd_norm [rad/s^2]: the norm of
        the joints' filtered acceleration (``motion``'s); seconds_since_tare: None for a method without a tared sensor."""
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
    """One sample of the running mean and noise variance per axis, and the sigma (docs/design/analytic.md)."""
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


__all__ = ["DRIFT_RATE", "LAG_WEIGHT", "ErrorBar", "MOTION_GAIN", "qdd_norm"]
