"""The streaming estimator's noise window: the first ``tare_seconds`` of calls, kept to be checked and measured.

What a window holds (a row per call, preallocated: no allocation in a control cycle), whether it may be
trusted (nothing touched the arm: ``contact``), and the white noise it shows (``measure``). The estimator
(``estimator/tip_force_estimator.py``) decides what follows: a refused window starts a new one.
"""
from __future__ import annotations

import numpy as np

from ..analytic.bandwidth import measure_window
from ..analytic.joint_state import with_joint_state_noise
from ..analytic.tare import window_force
from ..analytic.tip_force import tip_force_from_torques


class NoiseWindow:
    """n calls of nv joints. check_torques: also keep the force the joint torques see (a tared method
    that reads them), so that a contact held through the whole window is refused."""

    def __init__(self, robot, n: int, check_torques: bool):
        nv = robot.nv
        self.robot, self.n, self.check_torques = robot, n, check_torques and n > 0
        self.q, self.qd = np.zeros((n, nv)), np.zeros((n, nv))
        self.w, self.tau = np.zeros((n, 6)), np.zeros((n, nv))
        self.has = np.zeros((n, 2), dtype=bool)  # per call: base sensor, joint torques present
        self.force = np.zeros((n, 3))  # the force [N] the joint torques see, per call
        self.held_force = None  # the force [N] the joint torques saw held through the last window checked, if any
        if self.check_torques:  # its first call loads compiled code: now, not in a control cycle
            tip_force_from_torques(robot, np.array(robot.spec.home, float), np.zeros(nv), np.zeros(nv), np.zeros(nv))

    def clear(self) -> None:
        self.has[:] = False

    def record(self, k: int, q, qd, qdd, w, tau) -> None:
        """Call k of the window (its sensors as given: w, tau or None)."""
        self.q[k] = q
        self.qd[k] = qd
        if w is not None:
            self.w[k] = w
            self.has[k, 0] = True
        if tau is not None:
            self.tau[k] = tau
            self.has[k, 1] = True
            if self.check_torques:
                self.force[k] = tip_force_from_torques(self.robot, q, qd, qdd, tau)

    def contact(self, tare, limit: float, moment_limit: float = np.inf, held_limit: float = np.inf,
                torque_limit: float | None = None) -> str | None:
        """Why this window must not be trusted (a contact in it), or None. The base sensor's residual must
        not change between the window's parts (a contact that began or ended in it, a trend:
        ``StreamingTare.residual_change``); the joint torques, where kept, must see no force above ``limit``
        [N] (a contact held through the whole window, which the base sensor alone cannot tell from its
        offset); its moment residual must reveal no force above ``held_limit`` [N] held at the moving tool.
        torque_limit [N]: the joint torques' own limit where the model's calibrated error is larger (else ``limit``).
        """
        if tare is not None and tare.done:
            step = tare.residual_change(limit)
            if step is not None:
                return f"the base sensor's residual changed by {step:.2f} N inside the noise window (limit {limit:g} N)"
            step = tare.moment_change(moment_limit)
            if step is not None:
                return (f"the base sensor's moment residual changed by {step:.2f} Nm inside the noise window (limit "
                        f"{moment_limit:g} Nm): a force held at the tool while it moved")
            seen = tare.held_force(held_limit)
            if seen is not None:
                return (f"the base sensor's moment residual followed the tool's motion as a force held at the tool "
                        f"would (fitted: {seen:.2f} N, limit {held_limit:g} N): a contact, or a tool load the model lacks")
        has = self.has[:, 1]
        limit = limit if torque_limit is None else max(limit, torque_limit)
        # A force the torques see through the window matters where a base sensor is tared on it: with none in
        # the window (kalman-fusion given joint torques alone) nothing is tared, and nothing is checked.
        tares = self.has[:, 0].sum() >= 8
        seen = window_force(self.force[has], limit) if self.check_torques and tares and has.sum() >= 8 else None
        self.held_force = None if seen is None else np.median(self.force[has], axis=0)
        if seen is not None:
            return (f"the joint torques saw {seen:.2f} N at the tool during the noise window "
                    f"(limit {limit:.3g} N): a contact, or a tool load other than the model's (payload= missing, "
                    "or declared but not carried)")
        return None

    def measure(self, joint):
        """The window's white noise (``bandwidth.measure_window``) on the samples each sensor came with;
        qd's at least what the joint-state filter ``joint`` carries in motion (a still window shows none)."""
        has = self.has
        rows = lambda x, i: x[has[:, i]] if has[:, i].sum() >= 8 else None  # noqa: E731
        return with_joint_state_noise(measure_window(self.q, self.qd, rows(self.w, 0), rows(self.tau, 1)), joint)


__all__ = ["NoiseWindow"]
