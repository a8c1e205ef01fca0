"""Consistency checks of one stream: when the sensors contradict the model, no estimate is ``ok``.

A tip-force method explains whatever its sensor reads beyond the model by one force at the tool. Three
things it cannot explain that way, each a status of its own (``EstimatorStatus``):

- **tare offset implausible**: the tare found a base-sensor offset beyond ``max_tare_offset`` [N]; a sensor
  with its sign flipped, or mounted in another frame, reads twice the arm's weight off (341 N on the Panda);
- **frozen sensor**: a sensor repeats its reading exactly for ``frozen_calls`` calls; a live sensor's noise
  never does;
- **F/T channel clipped**: one base-sensor channel does so at the largest magnitude it has read in the stream
  (its range's end), while the others live: the force beyond the range is lost;
- **contact off the tool**: a force at the tool point p loads the base with the moment p x F and the
  joints with J_v^T F. What the base sensor's external wrench (f, m) leaves in m - p x f, or what the
  joint torques' external part r leaves outside the range of J_v^T (r - J_v^T pinv(J_v^T) r), no tip
  force explains: a push on the elbow, a tare that absorbed a press (once the tool has moved away from
  where it was tared, the press's moment no longer matches), a joint torque sensor with its sign flipped
  (its gravity load is no tip force). Checked every ``CHECK_EVERY`` calls (a Jacobian each time), held
  for ``off_tool_seconds`` before it is said, and cleared by the first check under the bound. The base
  wrench (f, m) is the method's own estimate of the external wrench (base-momentum's observer; base-wrench's
  measured minus model wrench); kalman-fusion estimates the force alone, so the check runs a base momentum
  observer of its own (:class:`SampledObserver`) while the base sensor is in use.
"""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numba import njit

from ..analytic.base_momentum import momentum_and_weight
from ..analytic.tip_force import SINGULAR_REGION


CHECK_EVERY = 8  # calls between two off-tool checks (one Jacobian or model wrench each)
CHECK_GAIN = 100.0  # [1/s] kalman-fusion's observer for the check: base-momentum's rule picks 90-100 on the trust streams


@njit(cache=True)
def _repeat(prev, x) -> bool:  # pragma: no cover (compiled)
    """Whether x equals prev exactly; prev becomes x."""
    same = True
    for i in range(x.shape[0]):
        if x[i] != prev[i]:
            same = False
        prev[i] = x[i]
    return same


@njit(cache=True)
def _clipped(prev, x, counts, peak, calls) -> bool:  # pragma: no cover (compiled)
    """Per channel: count x's exact repeats (prev becomes x) and its largest magnitude so far (peak); whether a
    channel has repeated ``calls`` times at its peak (a nonzero one)."""
    out = False
    for i in range(x.shape[0]):
        a = abs(x[i])
        if a > peak[i]:
            peak[i] = a
        counts[i] = counts[i] + 1 if x[i] == prev[i] else 0
        prev[i] = x[i]
        if counts[i] >= calls and a >= peak[i] and a > 0.0:
            out = True
    return out


class Consistency:
    """Per-stream state of the checks; ``fault`` holds the status name of the current fault, or None."""

    def __init__(self, robot, config, stream, method: str, reads_base: bool, reads_tau: bool, model_error=None):
        self.robot, self.config, self._stream, self.method = robot, config, stream, method
        self._model_error = model_error  # a calibrated model term: its part outside range(J_v^T) widens the bound
        self._reads_base, self._reads_tau = reads_base, reads_tau
        self._prev_w, self._prev_tau = np.full(6, np.nan), np.full(robot.nv, np.nan)
        self._channels = (np.full(6, np.nan), np.zeros(6, np.int64), np.zeros(6))  # last value, repeats, peak
        self._frozen_calls = config.frozen_calls
        self._data = robot.model.createData()
        self._hold = max(1, int(round(config.off_tool_seconds * config.call_hz / CHECK_EVERY)))
        self._observer = None
        if method == "kalman-fusion" and reads_base:
            # K T <= 0.8 between samples (T = CHECK_EVERY calls): the sampled recursion's pole 1 - K T stays in
            # (0, 1) at any rate (at 1 kHz, CHECK_GAIN itself; a 20 Hz log, 2 /s).
            gain = min(CHECK_GAIN, 0.8 * config.call_hz / CHECK_EVERY)
            self._observer = SampledObserver(robot, gain, 1.0 / config.call_hz)
        _repeat(np.zeros(1), np.zeros(1))  # compile now
        _clipped(np.zeros(1), np.zeros(1), np.zeros(1, np.int64), np.zeros(1), 1)
        self.reset()

    def reset(self) -> None:
        self._repeats_w = self._repeats_tau = 0
        self.clipped = False  # a base-sensor channel clipped at this call
        prev, counts, peak = self._channels
        prev[:], counts[:], peak[:] = np.nan, 0, 0.0
        self._over = 0
        self._k = CHECK_EVERY - 1  # the first call checks
        self.off_tool = False
        self.singular = False  # the latest check's pose lies in the damped solve's region (joint torques only)
        self.unexplained = 0.0  # the latest check's unexplained part [Nm]
        self.restart_observer()

    def restart_observer(self) -> None:
        """kalman-fusion's observer for the check starts again (a start, a gap, the base sensor absent)."""
        if self._observer is not None:
            self._observer.reset()

    def frozen(self, base_wrench, tau_J) -> bool:
        """Count this call's exact repeats per sensor; True while one has repeated ``frozen_calls`` times. Sets
        ``clipped``: a base-sensor channel repeats at its peak."""
        out = False  # written out per sensor: this runs every call
        if base_wrench is not None and self._reads_base:
            self._repeats_w = self._repeats_w + 1 if _repeat(self._prev_w, base_wrench) else 0
            out = self._repeats_w >= self._frozen_calls
            self.clipped = _clipped(*self._channels[:1], base_wrench, *self._channels[1:], self._frozen_calls)
        if tau_J is not None and self._reads_tau:
            self._repeats_tau = self._repeats_tau + 1 if _repeat(self._prev_tau, tau_J) else 0
            out = out or self._repeats_tau >= self._frozen_calls
        return out

    def check_off_tool(self, q, qd, qdd, w_tared, tau) -> bool:
        """Every CHECK_EVERY calls, the part of the loads no tool force explains; returns ``off_tool``."""
        observer = self._observer
        if observer is not None:  # integrates the sensor every call
            if w_tared is None:
                observer.reset()
            else:
                observer.add(w_tared)
        self._k += 1
        if self._k < CHECK_EVERY:
            return self.off_tool
        self._k = 0
        if observer is not None and w_tared is not None:
            observer.sample(q, qd, w_tared)
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
            return self._torque_part(q, self._stream.observer.residual), self._torque_bound()
        elif m == "torques-pinv" and tau is not None:
            return self._torque_part(q, r.rnea_ff_single(q, qd, qdd)[6:] - tau), self._torque_bound()
        elif self._observer is not None and self._observer.settled:
            wrench = self._observer.wrench
        else:
            return None, None
        # m - p x f in Python floats: np.cross and np.linalg.norm cost more than the rest at this size.
        px, py, pz = r.tip_position_single(q).tolist()
        fx, fy, fz, mx, my, mz = wrench.tolist()
        ex, ey, ez = mx - (py * fz - pz * fy), my - (pz * fx - px * fz), mz - (px * fy - py * fx)
        return math.sqrt(ex * ex + ey * ey + ez * ez), c.off_tool_moment

    def _torque_bound(self) -> float:
        """The off-tool bound on the joint torques [Nm]: the config's, or the calibrated model error's part
        outside range(J_v^T) where that is larger (the model's own misfit is no contact)."""
        bound = self.config.off_tool_torque
        if self._model_error is not None:
            bound = max(bound, self._model_error.off_tool_bound)
        return bound

    def _torque_part(self, q, residual) -> float:
        """|r - J_v^T pinv(J_v^T) r| [Nm]: the external joint torques no tool force explains. Sets ``singular``:
        whether J_v's least singular value lies inside the damped solve's region (``tip_force.SINGULAR_REGION``),
        where a force along the weak direction is read shrunk."""
        r = self.robot
        jv = pin.computeFrameJacobian(r.model, self._data, q, r.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        f, _, _, sv = np.linalg.lstsq(jv.T, residual, rcond=None)
        self.singular = bool(sv[-1] < SINGULAR_REGION)
        return float(np.linalg.norm(residual - jv.T @ f))



class SampledObserver:
    """The base momentum observer of ``analytic/base_momentum.py`` (r' = K (W_ext - r) about the root origin,
    W_ext the external wrench [N, Nm], root axes) for the off-tool check of a method that keeps no moment,
    sampled at the checks: the momentum H = [h; L_O] and the weight's wrench at the samples, the sensor
    (called every dt [s]) integrated every call (a running sum C: the trapezoid over an interval is
    dt (C_b - C_a + (w_a - w_b) / 2)). Per call one in-place sum; the dynamics once per sample."""

    def __init__(self, robot, gain: float, dt: float):
        self.robot, self.gain, self.dt = robot, float(gain), float(dt)
        self._data = robot.model_ff.createData()
        self._qff, self._vff = robot._qff.copy(), np.zeros(robot.model_ff.nv)
        self._R = np.ascontiguousarray(robot._root_from_sensor)
        self._C = np.zeros(6)  # the sum of the sensor's wrench over the calls [N, Nm]
        # rows: H(0), the integral, C and w at the last sample, the weight's wrench there, the estimate r
        self._state = np.zeros((6, 6))
        _sample_step(self._state.copy(), np.zeros(6), np.zeros(3), np.zeros(3), self._R, self._C, self._C, 1.0,
                     1, 1.0, True)  # compiled now, not in a control cycle
        self.reset()

    def reset(self) -> None:
        self._samples = 0
        self._C[:] = 0.0
        self._calls = 0
        self._elapsed = 0.0  # time since the first sample [s]
        self._state[:] = 0.0

    @property
    def wrench(self) -> np.ndarray:
        """The external wrench estimate r (6,) [N, Nm] at the last sample, root axes."""
        return self._state[5]

    @property
    def settled(self) -> bool:
        """Past 5 / K since the first sample (the transient below 1 %)."""
        return self._elapsed * self.gain > 5.0

    def add(self, w) -> None:
        self._C += w
        self._calls += 1

    def sample(self, q, qd, w) -> None:
        """A sample at this call (after ``add`` of its w)."""
        r = self.robot
        self._qff[7:] = q
        self._vff[6:] = qd
        hg = pin.computeCentroidalMomentum(r.model_ff, self._data, self._qff, self._vff).vector
        mg = r.total_mass * r.model_ff.gravity.linear  # the weight [N], a payload's included
        _sample_step(self._state, hg, self._data.com[0], mg, self._R, self._C, w, self.dt, self._calls, self.gain,
                     self._samples == 0)
        if self._samples:
            self._elapsed += self._calls * self.dt
        self._calls = 0
        self._samples += 1


@njit(cache=True)
def _sample_step(state, hg, c, mg, R, C, w, dt, calls, gain, first):  # pragma: no cover (compiled)
    """One sample of :class:`SampledObserver`: H = [h; L_com + c x h], W_grav = [m g; c x m g]; the
    integral gains R (the sensor's trapezoid) + the weight's trapezoid + the last r over the interval."""
    H, grav = momentum_and_weight(hg, c, mg)
    if first:
        state[0, :] = H
        state[1, :] = 0.0
        state[5, :] = 0.0
    else:
        period = calls * dt
        for i in range(6):
            acc = 0.0
            for k in range(6):
                acc += R[i, k] * dt * (C[k] - state[2, k] + 0.5 * (state[3, k] - w[k]))
            state[1, i] += acc + 0.5 * period * (grav[i] + state[4, i]) + period * state[5, i]
        for i in range(6):
            state[5, i] = gain * (H[i] - state[0, i] - state[1, i])
    state[2, :] = C
    state[3, :] = w
    state[4, :] = grav

__all__ = ["CHECK_EVERY", "Consistency", "SampledObserver"]
