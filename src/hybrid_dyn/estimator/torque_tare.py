"""The joint-torque sensors' offsets: tared in the noise window, followed at a standstill, bounded in the error bar.

A real arm's link-side torque sensors read tau_J = tau + o + drift t: a per-joint offset o [Nm] and a slow drift
[Nm/s]. A tip-force method reads o as an external torque: the part of o outside range(J_v^T) as a contact off the
tool, the part inside as a force pinv(J_v^T) o at the tool. So the joint-torque methods tare o in the start-up
window, as the base-sensor methods tare the base sensor:

- **the window** averages, on every ``CHECK_EVERY``-th call at a standstill, the residual b = tau_J - g(q): at
  a standstill no acceleration filter's lag enters it (in motion the model's error would be tared in; a window
  with under half its samples still tares nothing, as before). An offset beyond ``max_torque_offset`` on some
  joint is a contact held at the tool when a tool force at the window's pose explains it (the window is not
  trusted), else no sensor's offset (a flipped sign): the status says ``torque sensor offset`` from then on.
- **at a standstill** with no contact (the base tare's rule) the offset follows the residual with time constant
  ``retare_seconds``, at most twice ``torque_drift_rate``; it is verified once the follower's lag (averaged over
  ``retare_seconds``) is within what that rate leaves (a follower still catching up verifies nothing);
- **the error bar** carries the offset's drift since it was last verified: each joint at most
  ``torque_drift_rate`` x the time, through pinv(J_v^T): the worst case (every joint's drift adding up) is
  2 sigma. A call "uncertain" only by that term says ``torque sensor offset``: re-verify the offsets (a standstill).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .call_status import StandstillLag, within
from .consistency import CHECK_EVERY


def pinv_jv_t(robot, data, q) -> tuple[np.ndarray, np.ndarray]:
    """(J_v (3, nv) [m/rad], pinv(J_v^T) (3, nv) [1/m]) of the tool point at q (inf where J_v is singular)."""
    jv = pin.computeFrameJacobian(robot.model, data, q, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    try:
        return jv, np.linalg.solve(jv @ jv.T, jv)
    except np.linalg.LinAlgError:
        return jv, np.full(jv.shape, np.inf)


class TorqueTare:
    """One stream's joint-torque offsets (module docstring). max_offset [Nm], drift_rate [Nm/s per joint],
    standstill_speed [rad/s], call_hz [Hz]."""

    def __init__(self, robot, max_offset: float, drift_rate: float, standstill_speed: float, call_hz: float):
        self.robot, self.max_offset, self.drift_rate = robot, float(max_offset), float(drift_rate)
        self.standstill_speed, self.call_hz = float(standstill_speed), float(call_hz)
        self._data = robot.model.createData()
        self._data_g = robot.model.createData()
        nv = robot.nv
        # the residuals b [Nm], Jacobians J_v [m/rad] and poses q [rad] summed
        self._sums = (np.zeros(nv), np.zeros((3, nv)), np.zeros(nv))
        self.held, self.held_force = None, None  # why an earlier window was not trusted (a force held at the tool)
        self.offset = np.zeros(nv)
        self._lag = StandstillLag(nv)  # the follower's lag [Nm], averaged over retare_seconds
        self.sigma = np.zeros(3)  # the drift term [N] per axis, at the latest check
        self.reset()

    def reset(self, keep_held: bool = False) -> None:
        """A new window: nothing summed, no offset. keep_held: the stream goes on after a window that saw a force
        held at the tool (``held``): a later window must see it gone, not move through it."""
        if not keep_held:
            self.held, self.held_force = None, None  # (the force [N] behind ``held``)
        self.pose = None  # the window's mean still pose [rad], where the offsets were tared
        for s in self._sums:
            s[:] = 0.0
        self._n = self._recorded = 0
        self._k = CHECK_EVERY - 1
        self._lag.reset()
        self.offset[:] = 0.0
        self.found = None  # the offset the window found [Nm], once it closed
        self.implausible = False  # found beyond max_offset on some joint
        self._verified = None  # the call at which the offset was last set or verified
        self._row = np.zeros(3)  # |row i of pinv(J_v^T)| [1/m], at the latest check

    def record(self, q, qd, tau) -> None:
        """A window call: every CHECK_EVERY-th at a standstill adds its residual tau - g(q) and Jacobian."""
        self._k += 1
        if self._k < CHECK_EVERY:
            return
        self._k = 0
        self._recorded += 1
        if not within(qd, self.standstill_speed):
            return
        sb, sj, sq = self._sums
        sb += tau - pin.computeGeneralizedGravity(self.robot.model, self._data_g, q)
        sj += pinv_jv_t(self.robot, self._data, q)[0]
        sq += q
        self._n += 1

    def close(self, calls: int) -> str | None:
        """The window's end: why it is not trusted (a contact held at the tool), or None: the offset found
        (``found``; ``implausible`` beyond the bound) is tared from call ``calls`` on. A window mostly in
        motion finds none: the offsets stay 0, their drift counted from here."""
        self._verified = calls
        n = self._n
        if n < 8 or 2 * n < self._recorded:
            # Nothing measured here: after a window that saw a force held, this one does not show it gone.
            return None if self.held is None else self.held + " (a later window moved: not seen to end)"
        sb, sj, sq = self._sums
        found = sb / n
        if np.abs(found).max() > self.max_offset:
            # Beyond any sensor's offset: a force held at the tool through a still window, if a tool force at the
            # window's mean pose explains it (no offset beyond the bound left outside range(J_v^T)); else the
            # sensors (a flipped sign).
            jt = sj.T / n
            held = np.linalg.lstsq(jt, found, rcond=None)[0]
            if np.abs(found - jt @ held).max() <= self.max_offset:
                self.held_force = held
                self.held = (f"the joint torques saw {np.linalg.norm(held):.2f} N at the tool during the noise window, "
                             f"beyond what a torque sensor's offset ({self.max_offset:g} Nm) explains: a contact, or a "
                             "load the model lacks")
                return self.held
        self.held, self.held_force = None, None
        self.found = found
        self.implausible = bool(np.abs(found).max() > self.max_offset)
        if not self.implausible:
            self.offset[:] = self.found
            self.pose = sq / n
        return None

    def follow(self, q, tau, calls: int, retare_seconds: float) -> None:
        """A standstill call with no contact: the offset follows tau - g(q) [Nm] with time constant
        retare_seconds [s], at most twice the stated drift per call; verified once its averaged lag is within
        LAG_FACTOR x what the stated drift leaves behind a follower of that time constant: the drift term restarts
        from that lag."""
        if self._verified is None or self.implausible:
            return
        lag = tau - pin.computeGeneralizedGravity(self.robot.model, self._data_g, q) - self.offset
        n = retare_seconds * self.call_hz
        step = 2.0 * self.drift_rate / self.call_hz
        self.offset += np.clip(lag / n, -step, step)
        avg = self._lag.update(lag, calls, n)
        if avg is None:
            return
        at = StandstillLag.verified_call(float(np.abs(avg).max()), calls, self.drift_rate, retare_seconds, self.call_hz)
        if at is not None:
            self._verified = max(self._verified, at)

    def drift_sigma(self, q, calls: int) -> np.ndarray:
        """The drift term (3,) [N] at this call: drift_rate x seconds since verified through pinv(J_v^T) (a new
        pinv every CHECK_EVERY calls)."""
        if self._verified is None:
            return self.sigma
        self._k += 1
        if self._k >= CHECK_EVERY:
            self._k = 0
            _, p = pinv_jv_t(self.robot, self._data, q)
            self._row = 0.5 * np.abs(p).sum(axis=1)  # the worst case, every joint at the rate, is 2 sigma
        self.sigma = self._row * (self.drift_rate * (calls - self._verified) / self.call_hz)
        return self.sigma


__all__ = ["TorqueTare", "pinv_jv_t"]
