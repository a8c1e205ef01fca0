"""The per-sample tip-force methods that read qdd, their bandwidth the qdd filter's cutoff [Hz]:
``base-wrench`` (the base sensor's wrench minus the model's) and ``torques-pinv`` (F = pinv(J_v^T) (ID - tau_J))."""
from __future__ import annotations

import numpy as np

from .acceleration import cutoff_grid, cutoff_index, filter_settle_calls, qdd_noise_per_gain
from .bandwidth import WindowNoise
from .method_declaration import TIP_FORCE_METHODS, Method, MethodStream
from .tip_force import base_wrench_force_core, tip_force_from_base_wrench, tip_force_from_torques


class QddMethod(MethodStream):
    """A per-sample method whose bandwidth is the qdd filter's cutoff [Hz] (the estimator's filter)."""

    sensor_input = "base_wrench"  # the input whose noise the qdd estimate's noise is weighed against

    def sensor_noise(self, noise: WindowNoise) -> float:
        return noise.base_force

    def choose(self, noise):
        per_gain = qdd_noise_per_gain(self.robot, noise.q_mean, noise.qd, self.sensor_input, self.data)
        return float(cutoff_grid(self.rate_hz)[0][cutoff_index(self.rate_hz, per_gain, self.sensor_noise(noise))])

    def settle_calls(self, sensors=()) -> int:
        grid, _, _, settle = cutoff_grid(self.rate_hz)
        hit = np.flatnonzero(np.isclose(grid, self.value, rtol=1e-12))
        return int(settle[hit[0]]) if len(hit) else filter_settle_calls(self.rate_hz, self.value)


class BaseWrench(QddMethod):
    def step(self, q, qd, qdd, w, tau):
        return base_wrench_force_core(self.robot, q, qd, qdd, w)

    def batch(self, q, qd, qdd, w, tau):
        return tip_force_from_base_wrench(self.robot, q, qd, qdd, w)


class TorquesPinv(QddMethod):
    sensor_input = "tau_J"

    def sensor_noise(self, noise):
        return noise.joint_torque_rms

    def step(self, q, qd, qdd, w, tau):
        return tip_force_from_torques(self.robot, q, qd, qdd, tau)

    def batch(self, q, qd, qdd, w, tau):
        return tip_force_from_torques(self.robot, q, qd, qdd, tau)


TIP_FORCE_METHODS.register(Method(
    "base-wrench", "the base sensor's wrench minus the model's (needs qdd)", reads=("base_wrench",), any_of=False,
    needs_qdd=True, tares=True, parameter="qdd_cutoff_hz", make=BaseWrench, bench_rows=False, residual_prior=True))
TIP_FORCE_METHODS.alias("basewrench", "base-wrench", "the residual priors' old spelling")
TIP_FORCE_METHODS.alias("base_wrench", "base-wrench", "TipForceEstimator's old spelling")
TIP_FORCE_METHODS.register(Method(
    "torques-pinv", "F = pinv(J_v^T) (ID(q, qd, qdd) - tau_J)", reads=("tau_J",), any_of=False, needs_qdd=True,
    tares=False, parameter="qdd_cutoff_hz", make=TorquesPinv, bench_rows=False))
TIP_FORCE_METHODS.alias("torques", "torques-pinv")
