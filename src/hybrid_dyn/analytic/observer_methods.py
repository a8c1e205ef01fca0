"""The momentum observers as tip-force methods, gain K [1/s] by the rule: ``momentum-observer`` (on the joint
torque sensors, ``momentum_observer.py``) and ``base-momentum`` (on the base sensor, ``base_momentum.py``)."""
from __future__ import annotations

import numpy as np

from .acceleration import qdd_noise_per_gain
from .bandwidth import observer_gain, observer_settle_calls
from .base_momentum import BaseMomentumObserver
from .method_declaration import TIP_FORCE_METHODS, Method, MethodStream
from .momentum_observer import MomentumObserver


class ObserverMethod(MethodStream):
    """A momentum observer (``cls``) stepped on one sensor (``sensor``: "w" or "tau"), gain K by the rule."""

    cls = sensor = None

    def __init__(self, robot, rate_hz):
        super().__init__(robot, rate_hz)
        self.observer = self.cls(robot, gain=1.0, dt=self.dt)

    def configure(self, value):
        self.observer.gain = np.broadcast_to(float(value), np.shape(self.observer.gain)).copy() \
            if np.ndim(self.observer.gain) else float(value)
        super().configure(value)

    def reset(self):
        self.observer.reset()

    def step(self, q, qd, qdd, w, tau):
        return self.observer.force(q, self.observer.step_unchecked(q, qd, w if self.sensor == "w" else tau))

    def batch(self, q, qd, qdd, w, tau):
        return self.cls(self.robot, gain=self.value, dt=self.dt).run(q, qd, w if self.sensor == "w" else tau)[0]

    def settle_calls(self, sensors=()):
        return observer_settle_calls(self.value, self.dt)


class MomentumObserverMethod(ObserverMethod):
    """The joint-torque momentum observer: K by the rule on the torque sensors' and p = M qd's noise."""

    cls, sensor = MomentumObserver, "tau"

    def choose(self, noise):
        # The residual's joint-space noise mapped to the tip force by P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v
        # at the window's pose: per axis, tr(P diag(s_tau^2) P^T) / 3 from the torque sensors and
        # tr(P M diag(s_qd^2) M P^T) / 3 from the momentum p = M qd.
        import pinocchio as pin

        r, data = self.robot, self.data
        jv = pin.computeFrameJacobian(r.model, data, noise.q_mean, r.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        P = np.linalg.solve(jv @ jv.T, jv)
        M = pin.crba(r.model, data, noise.q_mean)
        M = np.triu(M) + np.triu(M, 1).T
        s_in = np.sqrt(np.sum((P * noise.joint_torque) ** 2) / 3.0)
        s_mom = np.sqrt(np.sum((P @ M * noise.qd) ** 2) / 3.0)
        self.value, self.predicted_noise = observer_gain(self.rate_hz, s_in, s_mom)
        return self.value


class BaseMomentumMethod(ObserverMethod):
    """The base momentum observer: K by the rule on the base sensor's and h = m J_com qd's noise."""

    cls, sensor = BaseMomentumObserver, "w"

    def model_changed(self):
        self.observer.model_changed()

    def choose(self, noise):
        self.value, self.predicted_noise = observer_gain(
            self.rate_hz, noise.base_force, qdd_noise_per_gain(self.robot, noise.q_mean, noise.qd, "base_wrench", self.data))
        return self.value



TIP_FORCE_METHODS.register(Method(
    "momentum-observer", "the joint-torque momentum observer (no qdd)", reads=("tau_J",), any_of=False,
    needs_qdd=False, tares=False, parameter="momentum_gain", make=MomentumObserverMethod, residual_prior=True))
TIP_FORCE_METHODS.alias("momentum", "momentum-observer")
TIP_FORCE_METHODS.register(Method(
    "base-momentum", "the whole robot's momentum against the base sensor (no qdd)", reads=("base_wrench",),
    any_of=False, needs_qdd=False, tares=True, parameter="momentum_gain", make=BaseMomentumMethod,
    residual_prior=True))
TIP_FORCE_METHODS.alias("base_momentum", "base-momentum")
