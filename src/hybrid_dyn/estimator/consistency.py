"""Consistency checks of one stream: when the sensors contradict the model, no estimate is ``ok``.

A tip-force method explains whatever its sensor reads beyond the model by one force at the tool. Three
things it cannot explain that way, each a status of its own (``EstimatorStatus``):

- **tare offset implausible**: the tare found a base-sensor offset beyond ``max_tare_offset`` [N]; a sensor
  with its sign flipped, or mounted in another frame, reads twice the arm's weight off (341 N on the Panda);
- **frozen sensor**: a sensor repeats its reading exactly for ``frozen_calls`` calls; a live sensor's noise
  never does;
- **contact off the tool**: a force at the tool point p loads the base with the moment p x F and the
  joints with J_v^T F. What the base sensor's external wrench (f, m) leaves in m - p x f, or what the
  joint torques' external part r leaves outside the range of J_v^T (r - J_v^T pinv(J_v^T) r), no tip
  force explains: a push on the elbow, a tare that absorbed a press (once the tool has moved away from
  where it was tared, the press's moment no longer matches), a joint torque sensor with its sign flipped
  (its gravity load is no tip force). Checked every ``CHECK_EVERY`` calls (a Jacobian each time), held
  for ``off_tool_seconds`` before it is said, and cleared by the first check under the bound.
"""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numba import njit

CHECK_EVERY = 8  # calls between two off-tool checks (one Jacobian or model wrench each)


@njit(cache=True)
def _repeat(prev, x) -> bool:  # pragma: no cover (compiled)
    """Whether x equals prev exactly; prev becomes x."""
    same = True
    for i in range(x.shape[0]):
        if x[i] != prev[i]:
            same = False
        prev[i] = x[i]
    return same


class Consistency:
    """Per-stream state of the checks; ``fault`` holds the status name of the current fault, or None."""

    def __init__(self, robot, config, stream, method: str, reads_base: bool, reads_tau: bool):
        self.robot, self.config, self._stream, self.method = robot, config, stream, method
        self._reads_base, self._reads_tau = reads_base, reads_tau
        self._prev_w, self._prev_tau = np.full(6, np.nan), np.full(robot.nv, np.nan)
        self._frozen_calls = config.frozen_calls
        self._data = robot.model.createData()
        self._hold = max(1, int(round(config.off_tool_seconds * config.call_hz / CHECK_EVERY)))
        _repeat(np.zeros(1), np.zeros(1))  # compile now
        self.reset()

    def reset(self) -> None:
        self._repeats_w = self._repeats_tau = 0
        self._over = 0
        self._k = CHECK_EVERY - 1  # the first call checks
        self.off_tool = False
        self.unexplained = 0.0  # the latest check's unexplained part [Nm]

    def frozen(self, base_wrench, tau_J) -> bool:
        """Count this call's exact repeats per sensor; True while one has repeated ``frozen_calls`` times."""
        out = False  # written out per sensor: this runs every call
        if base_wrench is not None and self._reads_base:
            self._repeats_w = self._repeats_w + 1 if _repeat(self._prev_w, base_wrench) else 0
            out = self._repeats_w >= self._frozen_calls
        if tau_J is not None and self._reads_tau:
            self._repeats_tau = self._repeats_tau + 1 if _repeat(self._prev_tau, tau_J) else 0
            out = out or self._repeats_tau >= self._frozen_calls
        return out

    def check_off_tool(self, q, qd, qdd, w_tared, tau) -> bool:
        """Every CHECK_EVERY calls, the part of the loads no tool force explains; returns ``off_tool``."""
        self._k += 1
        if self._k < CHECK_EVERY:
            return self.off_tool
        self._k = 0
        value, bound = self._unexplained(q, qd, qdd, w_tared, tau)
        if value is None:
            return self.off_tool
        self.unexplained = value
        self._over = self._over + 1 if value > bound else 0
        # Held for off_tool_seconds (a contact's edge passes); four times the bound is no edge: at once.
        self.off_tool = self._over >= self._hold or value > 4.0 * bound
        return self.off_tool

    def _unexplained(self, q, qd, qdd, w_tared, tau):
        r, c = self.robot, self.config
        m = self.method
        if m == "base-momentum":
            wrench = self._stream.observer.wrench
        elif m == "base-wrench" and w_tared is not None:
            wrench = r._root_from_sensor @ w_tared - r.rnea_ff_single(q, qd, qdd)[:6]
        elif m == "momentum-observer":
            return self._torque_part(q, self._stream.observer.residual), c.off_tool_torque
        elif m == "torques-pinv" and tau is not None:
            return self._torque_part(q, r.rnea_ff_single(q, qd, qdd)[6:] - tau), c.off_tool_torque
        else:
            return None, None
        # m - p x f in Python floats: np.cross and np.linalg.norm cost more than the rest at this size.
        px, py, pz = r.tip_position_single(q).tolist()
        fx, fy, fz, mx, my, mz = wrench.tolist()
        ex, ey, ez = mx - (py * fz - pz * fy), my - (pz * fx - px * fz), mz - (px * fy - py * fx)
        return math.sqrt(ex * ex + ey * ey + ez * ez), c.off_tool_moment

    def _torque_part(self, q, residual) -> float:
        """|r - J_v^T pinv(J_v^T) r| [Nm]: the external joint torques no tool force explains."""
        r = self.robot
        jv = pin.computeFrameJacobian(r.model, self._data, q, r.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        f = np.linalg.lstsq(jv.T, residual, rcond=None)[0]
        return float(np.linalg.norm(residual - jv.T @ f))


__all__ = ["CHECK_EVERY", "Consistency"]
