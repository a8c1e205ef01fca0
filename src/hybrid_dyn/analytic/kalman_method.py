"""Both sensors fused by a Kalman filter (``kalman.py``) as the tip-force method ``kalman-fusion``: the noise
and the force rate measured on the noise window; a call may bring either sensor or both."""
from __future__ import annotations

import numpy as np

from .kalman import SENSORS, KalmanTipForce, channel_factors, increment_stats, window_fusion_noise
from .method_declaration import TIP_FORCE_METHODS, Method, MethodStream

SENSOR_NAMES = {"base_wrench": "base", "tau_J": "joint"}  # an input's name -> the Kalman filter's channel


class KalmanFusionMethod(MethodStream):
    """Both sensors fused (``kalman.py``): the noise and the force rate measured on the window."""

    def __init__(self, robot, rate_hz):
        super().__init__(robot, rate_hz)
        self.kalman = KalmanTipForce(robot, self.dt)
        self._factors = channel_factors(robot)
        self._R3 = robot._root_from_sensor[:3]

    def _apply(self, noise, fixed):
        from dataclasses import replace

        self.kalman.configure(noise if fixed is None else replace(noise, force_rate=float(fixed)))
        self.value = self.kalman.noise.force_rate
        return self.value

    def choose(self, noise):  # the contact model's force rate (the measured noise sets the gain)
        return window_fusion_noise(self.robot, self.dt, noise, np.zeros((2, 8)), factors=self._factors).force_rate

    def configure(self, value):
        from dataclasses import replace

        self._apply(replace(self.kalman.noise, force_rate=float(value)), None)

    def reset(self):
        self.kalman.reset()

    def model_changed(self):
        self.kalman.model_changed()

    def window_step(self, q, qd, qdd, w_raw, tau):
        self.kalman.step_unchecked(q, qd, w_raw, tau)  # its increment sums measure the model errors

    def close_window(self, noise, tare_offset, fixed=None):
        shift = None if tare_offset is None else (self._R3 @ tare_offset) * self.dt
        return self._apply(window_fusion_noise(self.robot, self.dt, noise, self.kalman.stats.copy(), shift,
                                               self._factors), fixed)

    def fit_window(self, q, qd, qdd, w_tared, tau, noise, fixed=None):
        y = self.kalman.measurements(q, qd, w_tared, tau)
        stats = increment_stats({c: np.diff(v, axis=0) for c, v in y.items()})
        return self._apply(window_fusion_noise(self.robot, self.dt, noise, stats, None, self._factors), fixed)

    def step(self, q, qd, qdd, w, tau):
        return self.kalman.step_unchecked(q, qd, w, tau)

    def batch(self, q, qd, qdd, w, tau):
        return self.kalman.run(q, qd, w, tau)

    def settle_calls(self, sensors=SENSORS):
        return self.kalman.settle_calls(tuple(SENSOR_NAMES.get(s, s) for s in sensors))


TIP_FORCE_METHODS.register(Method(
    "kalman-fusion", "both sensors fused by a Kalman filter (a call may bring either or both)",
    reads=("base_wrench", "tau_J"), any_of=True, needs_qdd=False, tares=True, parameter="fusion_force_rate",
    make=KalmanFusionMethod))
TIP_FORCE_METHODS.alias("kalman_fusion", "kalman-fusion")
