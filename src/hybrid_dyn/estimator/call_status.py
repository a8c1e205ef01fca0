"""What a call's estimate is told (a part of ``TipForceEstimator``, working on its state): its status and error
bar (``_finish``), the consistency checks (``_judge``), the base sensor's drift followed at a standstill, and the
sensors kalman-fusion estimates from. Every function here runs once per control cycle: kept cheap (plain names
for the statuses, a compiled standstill test)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..analytic.kalman import MAX_BRIDGE_CALLS
from .config import EstimatorStatus

# The statuses as plain names for the per-call path: an Enum member looked up on its class costs ~0.3 us.
_OK, _WARMING_UP, _OUT_OF_RANGE, _FORCE_OUT_OF_RANGE, _WRONG_RATE, _NO_SENSOR, _UNCERTAIN = (
    EstimatorStatus.OK, EstimatorStatus.WARMING_UP, EstimatorStatus.OUT_OF_RANGE, EstimatorStatus.FORCE_OUT_OF_RANGE,
    EstimatorStatus.WRONG_RATE, EstimatorStatus.NO_SENSOR, EstimatorStatus.UNCERTAIN)
_IMPLAUSIBLE_TARE, _FROZEN_SENSOR, _OFF_TOOL, _NEAR_SINGULARITY, _TORQUE_OFFSET, _CLIPPED, _MODEL = (
    EstimatorStatus.IMPLAUSIBLE_TARE, EstimatorStatus.FROZEN_SENSOR, EstimatorStatus.OFF_TOOL,
    EstimatorStatus.NEAR_SINGULARITY, EstimatorStatus.TORQUE_OFFSET, EstimatorStatus.CLIPPED_CHANNEL,
    EstimatorStatus.MODEL_UNCERTAIN)
# A follower's averaged lag [in drift rate x retare_seconds] within which it verifies its tare: one of time constant
# retare_seconds lags a drift at the stated rate by 1 without noise; its per-call step clipped by the sensor's noise,
# it lagged by 2.6 on the trust bench's standstill; one still catching up after a minute's motion, by 12 and more.
LAG_FACTOR = 4.0


class StandstillLag:
    """A tare follower's lag averaged over one standstill, with time constant n calls from its first call: the
    base sensor's (``_verify_base_tare``) and the joint-torque sensors' (``torque_tare.py``) verify their tare on
    it (:meth:`verified_call`). A call that does not follow the last one starts a new standstill."""

    def __init__(self, size: int):
        self.avg = np.zeros(size)
        self.reset()

    def reset(self) -> None:
        self.avg[:] = 0.0
        self._last, self._count = -2, 0  # the last call that followed; calls followed in a row

    def update(self, lag, calls: int, n: float):
        """Add this call's lag; the average once the standstill has lasted n calls, else None."""
        if calls != self._last + 1:  # a new standstill: its average starts here
            self.avg[:], self._count = lag, 0
        self.avg += (lag - self.avg) / n
        self._last, self._count = calls, self._count + 1
        return self.avg if self._count >= n else None

    @staticmethod
    def verified_call(size: float, calls: int, rate: float, retare_seconds: float, call_hz: float):
        """The call from which a tare whose averaged lag is ``size`` counts as verified (the drift term restarts
        from that lag: ``size`` / ``rate`` seconds back), or None when the lag exceeds LAG_FACTOR x ``rate`` x
        ``retare_seconds`` (a follower still catching up verifies nothing)."""
        if size > LAG_FACTOR * rate * retare_seconds:
            return None
        return calls - size / max(rate, 1e-12) * call_hz
NO_SIGMA = np.full(3, np.inf)  # no estimate yet (the noise window): an unbounded error bar
# kalman-fusion's sensors in use, by (base sensor in use, joint torques in use)
_ACTIVE = {(False, False): (), (True, False): ("base_wrench",), (False, True): ("tau_J",),
           (True, True): ("base_wrench", "tau_J")}


@njit(cache=True)
def within(x, bound) -> bool:  # pragma: no cover (compiled)
    """Whether -bound < x_i < bound for every i (a standstill: two numpy reductions cost ten times this)."""
    for i in range(x.shape[0]):
        if not (-bound < x[i] < bound):
            return False
    return True


class CallStatus:
    """The estimator's per-call status steps (a mixin of ``TipForceEstimator``)."""

    def _judge(self, q, qd, qdd, w_in, base_wrench, tau_J, tau_raw=None) -> None:
        """This call's consistency status (``estimator/consistency.py``), first match: an implausible tare,
        a frozen sensor (on the sensor's own reading ``tau_raw``), a clipped base-sensor channel, a joint-torque offset beyond its bound
        (``torque_tare.py``: it also shows as a contact off the tool),
        a contact off the tool (on tau_J less the torque model's terms beyond the rigid body)."""
        check, fault = self._check, None
        if w_in is not None and self._tare is not None and self._tare.found is not None:
            # The offset the window found: a flipped sign or a wrong frame shows there. The drift followed since
            # is bounded by the sensor's stated rate, and over an hour is no implausible tare.
            o, bound = self._tare.found, self.config.max_tare_offset
            size2 = o[0] * o[0] + o[1] * o[1] + o[2] * o[2]
            if size2 > bound * bound and self._model_error is not None:
                bound += 3.0 * self._model_error.weight_sigma()  # and the model's weight, as far as it is stated
            if size2 > bound * bound:
                fault = _IMPLAUSIBLE_TARE
        if check.frozen(base_wrench, tau_J if tau_raw is None else tau_raw) and fault is None:
            fault = _FROZEN_SENSOR
        if check.clipped and fault is None:  # a clipped channel's lost force also shows as a contact off the tool
            fault = _CLIPPED
        if self._tau_tare is not None and self._tau_tare.implausible and fault is None:
            fault = _TORQUE_OFFSET
        if check.check_off_tool(q, qd, qdd, w_in, tau_J) and fault is None:
            fault = _OFF_TOOL
        weak = self._model_error is not None and self._model_error.weak
        if (check.singular or (tau_J is not None and weak)) and fault is None:
            fault = _NEAR_SINGULARITY  # (the model term's check: kalman-fusion's torques shrink the weak direction too)
        self._fault = fault

    def _follow_drift(self, q, qd, base_wrench, f) -> None:
        """A base sensor's bias drifts after its tare. While the arm stands still (every joint slower than
        ``standstill_speed`` for ``standstill_seconds``) and the estimate shows no contact (below
        ``tare_contact_force``), the tare follows the sensor with time constant ``retare_seconds``: a
        contact held that still and that small is what it may absorb."""
        c = self.config
        if self._still_and_free(qd, f):
            lag = self._tare.follow(q, base_wrench, 1.0 / (c.retare_seconds * c.call_hz), self._follow_step)
            self._verify_base_tare(lag[:3])

    def _verify_base_tare(self, lag) -> None:
        """The follower's force lag [N] averaged over this standstill (time constant retare_seconds, from its
        first call): once it has run that long, a lag within LAG_FACTOR x base_drift_rate x retare_seconds
        verifies the tare: the error bar's drift term restarts from that lag, not from 0. A follower still catching
        up (after a long motion, or a contact that builds as slowly as a drift) verifies nothing: its drift term
        goes on."""
        c = self.config
        avg = self._base_lag.update(lag, self._calls, c.retare_seconds * c.call_hz)
        if avg is None:
            return
        at = StandstillLag.verified_call(math.sqrt(float(avg.dot(avg))), self._calls, c.base_drift_rate,
                                         c.retare_seconds, c.call_hz)
        if at is not None:
            self._tared_at = at

    def _follow_torque_offset(self, q, qd, tau, f, counted: bool = False) -> None:
        """The joint-torque offsets follow the sensors (tau [Nm], before their tare) as the base sensor's tare
        does, on the same standstill (``torque_tare.py``); counted: the base follower counted this call's
        standstill already."""
        if self._still_and_free(qd, f, counted):
            self._tau_tare.follow(q, tau, self._calls, self.config.retare_seconds)

    def _still_and_free(self, qd, f, counted: bool = False) -> bool:
        """Whether a tare may follow its sensor at this call: following not switched off, every joint slower than
        ``standstill_speed`` [rad/s] for ``standstill_seconds`` [s], the estimate f below ``tare_contact_force`` [N].
        counted: this call's standstill was counted already (a second follower on the same call)."""
        c = self.config
        if c.retare_seconds == math.inf:  # told not to follow
            return False
        if not counted:
            self._still_calls = self._still_calls + 1 if within(qd, c.standstill_speed) else 0
        return self._still_calls >= c.standstill_seconds * c.call_hz and f.dot(f) < c.tare_contact_force ** 2

    def _finish(self, f, in_range, wrong_rate, usable, estimated=True) -> np.ndarray:
        """The status of this call's estimate f, and f (a copy); a force within the bound is kept.
        estimated: f is the method's estimate of this call (not the held one of the noise window)."""
        if self._calls < self._warmup_calls:  # the method's own transient: no error model of it
            estimated = False
            self._error_bar.reset()
        measured = 0.0  # the largest sigma of the sensors' own terms (noise, lag, motion, the base sensor's drift) [N]
        if estimated:
            since = None
            if self._tared_at is not None:
                since = (self._calls - self._tared_at) / self.config.call_hz
            self.last_sigma = self._error_bar.update(f, self._motion, since)
            # (np.hypot and max of a list: one ufunc call each, not four; this runs every control cycle)
            if self._model_sigma is not None or self._tau_sigma is not None:
                measured = max(self.last_sigma.tolist())
            if self._model_sigma is not None:  # the model's error, independent of the sensors'
                self.last_sigma = np.hypot(self.last_sigma, self._model_sigma)
            if self._tau_sigma is not None:  # the joint-torque offsets' drift since verified, likewise independent
                self.last_sigma = np.hypot(self.last_sigma, self._tau_sigma)
        else:
            self.last_sigma = NO_SIGMA.copy()
        status = _OK if in_range else _OUT_OF_RANGE
        s0, s1, s2 = self.last_sigma.tolist()  # floats: a numpy max costs a microsecond; NaN still fails
        limit = self.max_sigma
        if status is _OK and not (s0 <= limit and s1 <= limit and s2 <= limit):
            status = self._uncertain_cause(measured, limit) if estimated else _UNCERTAIN
        if self._calls < self._warmup_calls:
            status = _WARMING_UP if self.window_problem is None else self.window_status
        if self._fault is not None and estimated:
            status = self._fault
        if not usable:
            status = _NO_SENSOR
        if wrong_rate:
            status = _WRONG_RATE
        if not f.dot(f) <= self.config.max_tip_force ** 2:  # NaN compares False: flagged too
            status = _FORCE_OUT_OF_RANGE  # returned, but never held as the last good estimate
        else:
            self._last_good = f
        self.last_status = status
        return f.copy()

    def _uncertain_cause(self, measured: float, limit: float):
        """Why a call's sigma exceeds ``limit`` [N]: the larger of the two terms beyond the sensors' own, where those
        (``measured``) are within the bound and it is at least half of it: the joint-torque offsets' drift since
        verified (``torque sensor offset``: a standstill re-verifies them) or the model's stated or calibrated error
        (``model uncertain``; ``near a singularity`` where J_v's weak direction makes it); else ``uncertain``."""
        if measured > limit:
            return _UNCERTAIN
        drift = 0.0 if self._tau_sigma is None else max(self._tau_sigma.tolist())
        model = 0.0 if self._model_sigma is None else max(self._model_sigma.tolist())
        if max(drift, model) < 0.5 * limit:
            return _UNCERTAIN
        if drift >= model:
            return _TORQUE_OFFSET
        return _NEAR_SINGULARITY if self._model_error is not None and self._model_error.weak else _MODEL

    def _track_sensors(self, has_base: bool, has_joint: bool) -> bool:
        """kalman-fusion: which sensors the filter estimates from. A sensor back within
        MAX_BRIDGE_CALLS is bridged; one that joins or leaves beyond that restarts the warm-up for the
        new set's settling time. Returns whether any sensor is usable now."""
        absent = self._absent  # written out per sensor: this runs every call
        if has_base:
            absent[0] = 0
        elif absent[0] >= 0:
            absent[0] += 1
        if has_joint:
            absent[1] = 0
        elif absent[1] >= 0:
            absent[1] += 1
        active = _ACTIVE[0 <= absent[0] <= MAX_BRIDGE_CALLS, 0 <= absent[1] <= MAX_BRIDGE_CALLS]
        if active != self._active:
            self._active = active
            if active:
                self._warmup_calls = max(self._warmup_calls, self._calls + self._stream.settle_calls(active))
        return bool(active)


__all__ = ["CallStatus"]
