"""Generalized-momentum observer (De Luca & Mattone 2005).

With p = M(q) qd the generalized momentum, the dynamics
M qdd + C qd + g = tau + tau_ext give p' = tau + tau_ext + C^T qd - g.
The observer residual

    r(t) = K [ p(t) - p(0) - integral_0^t (tau + C^T qd - g + r) ds ]

obeys r' = K (tau_ext - r): a first-order filter of the external joint torque
with bandwidth K [1/s], needing no joint acceleration. The tip force follows
from r = J_v^T F by damped least squares.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import pinocchio as pin

from .robot import InputError, Robot, as_batch
from .tip_force import MAX_DAMPING, SINGULAR_REGION, damped_force_from_joint_torques, damped_force_single


class MomentumObserver:
    """Streaming momentum observer on a :class:`Robot`.

    gain: K [1/s], scalar or per joint. dt: sample time [s].
    friction: optional callable qd -> friction torque [Nm] consumed in the
    joints; when given, the observer is fed motor torques and subtracts it.
    The integral uses the trapezoidal rule.
    """

    def __init__(self, robot: Robot, gain=50.0, dt: float = 1e-3,
                 friction: Callable[[np.ndarray], np.ndarray] | None = None):
        if dt <= 0:
            raise ValueError(f"dt must be positive, got {dt}")
        self.robot = robot
        self.gain = np.broadcast_to(np.asarray(gain, dtype=float), (robot.nv,)).copy()
        if (self.gain <= 0).any():
            raise ValueError("gain must be positive")
        self.dt = float(dt)
        self.friction = friction
        self._data = robot.model.createData()
        self._data_g = robot.model.createData()
        self._data_c = robot.model.createData()
        self._zero = np.zeros(robot.nv)
        self._half_dt = 0.5 * self.dt
        self.reset()

    def reset(self) -> None:
        """Forget the history; the next step re-initialises p(0)."""
        self._p0 = None
        self._integral = np.zeros(self.robot.nv)
        self._last_integrand = None
        self.residual = np.zeros(self.robot.nv)

    def _dynamics_terms(self, q, qd):
        """Pinocchio's terms behind beta and p: (g [Nm], M qd + g [N m s], C (nv, nv)). M qd + g is
        RNEA with v = 0, a = qd, which avoids forming and symmetrising M."""
        model = self.robot.model
        # One Data per quantity: each function returns a view into its Data, so no copies.
        g = pin.computeGeneralizedGravity(model, self._data_g, q)
        m_qd_g = pin.rnea(model, self._data, q, self._zero, qd)
        return g, m_qd_g, pin.computeCoriolisMatrix(model, self._data_c, q, qd)

    def _beta_and_p(self, q, qd):
        """(C^T qd - g, p = M qd)."""
        g, m_qd_g, C = self._dynamics_terms(q, qd)
        return qd @ C - g, m_qd_g - g

    def step(self, q, qd, tau) -> np.ndarray:
        """Advance one sample; returns the external joint torque estimate r [Nm] (nv,)."""
        q = self.robot._single(q, "q")
        qd = self.robot._single(qd, "qd")
        tau = self.robot._single(tau, "tau")
        return self.step_unchecked(q, qd, tau)

    def step_unchecked(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``step`` for inputs already validated as finite (nv,) float arrays."""
        if self.friction is not None:
            tau = tau - self.friction(qd)
        beta, p = self._beta_and_p(q, qd)
        if self._p0 is None:
            self._p0 = p
            self._last_integrand = tau + beta
            return self.residual.copy()
        integrand = tau + beta
        # Trapezoid on the model terms; the residual term uses the last estimate.
        self._integral += (integrand + self._last_integrand) * self._half_dt + self.residual * self.dt
        self._last_integrand = integrand
        self.residual = self.gain * (p - self._p0 - self._integral)  # a fresh array: safe to hand out
        return self.residual

    def force(self, q, residual: np.ndarray | None = None) -> np.ndarray:
        """Tip force [N] (3,) explaining the residual through J_v^T."""
        r = self.residual if residual is None else residual
        robot = self.robot
        jv = pin.computeFrameJacobian(robot.model, self._data, q, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        return damped_force_single(jv, r, SINGULAR_REGION, MAX_DAMPING)

    def step_force(self, q, qd, tau) -> np.ndarray:
        """One step, returning the tip force estimate [N] (3,)."""
        r = self.step(q, qd, tau)
        return self.force(q, r)

    def run(self, q, qd, tau) -> tuple[np.ndarray, np.ndarray]:
        """Run over a trajectory sampled every ``dt``: (tip forces (N, 3) [N], residuals (N, nv) [Nm]).

        Starts from a reset, so r(0) = 0 and the first 5/K seconds are transient.
        """
        q, _ = as_batch(q, "q", self.robot.nv)
        qd, _ = as_batch(qd, "qd", self.robot.nv)
        tau, _ = as_batch(tau, "tau", self.robot.nv)
        if not (len(q) == len(qd) == len(tau)):
            raise InputError("q, qd, tau have different lengths")
        self.reset()
        res = np.stack([self.step(q[i], qd[i], tau[i]) for i in range(len(q))])
        jv = self.robot._tip_jacobians(q)[:, :3, :]
        return damped_force_from_joint_torques(jv, res, SINGULAR_REGION, MAX_DAMPING), res
