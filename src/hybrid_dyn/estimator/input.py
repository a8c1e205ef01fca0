"""The streaming estimator's input gate: every sample is checked before it touches any state.

:class:`InputGate` holds the plausibility box of every value a call brings and the
stream's time (docs/estimator.md states the rules);
:class:`RateCheck` tells an untimed stream that runs at another rate than
``call_hz`` from its own samples (q's increments against qd / call_hz).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..analytic.robot import InputError, Robot

G = 9.81  # m/s^2, for the base-wrench bound
RATE_STEPS = 10  # the steps over which a timed stream's share of gaps is averaged (a wrong rate: most are gaps)
PERIOD_STEPS = 200  # and its period (a real Panda's PC stamps: over ten steps, 276 calls averaged beyond 1.25 ms)


class EstimatorInputError(InputError):
    """A sample given to the estimator is unusable: not numeric, wrong shape, NaN/inf, physically
    implausible, or out of step with the stream's time; the message names the argument."""


# _gate's answers: the sample is inside its box; an input is not a float64 1-D array of its length;
# a value lies outside its box (or is NaN / inf).
GATE_INSIDE, GATE_WRONG_LENGTH, GATE_OUTSIDE = 0, 1, 2
_VEC = "float64[::1]"


@njit(f"int64({_VEC}, {_VEC}, {_VEC}, int64[:, ::1], {_VEC}, {_VEC}, {_VEC}, {_VEC})", cache=True)
def _gate(sample, lo, inv_width, slots, q, qd, base_wrench, tau_J):  # pragma: no cover (compiled)
    """Copy one call's inputs into ``sample`` and check every value against its box (``_build_gate``).

    slots[k] = (start in sample, length) of input k (q, qd, base_wrench, tau_J); start -1: not read.
    The explicit signature means no argument of another type compiles anything: the dispatcher
    raises TypeError instead, and ``_accept`` converts on its slow path.
    """
    inputs = (q, qd, base_wrench, tau_J)
    for k in range(4):
        start, size = slots[k, 0], slots[k, 1]
        if start < 0:
            continue
        x = inputs[k]
        if x.shape[0] != size:
            return GATE_WRONG_LENGTH
        for j in range(size):
            sample[start + j] = x[j]
    for i in range(sample.shape[0]):
        u = (sample[i] - lo[i]) * inv_width[i]
        if not (u >= 0.0 and u < 1.0):  # NaN compares False: outside too
            return GATE_OUTSIDE
    return GATE_INSIDE


class InputGate:
    """The plausibility box and the time checks of one stream (docs/estimator.md, step 1)."""

    def __init__(self, robot: Robot, config, needs_wrench: bool, needs_tau: bool, optional=frozenset()):
        self.robot, self.config = robot, config
        self._needs_wrench, self._needs_tau, self._optional = needs_wrench, needs_tau, frozenset(optional)
        self._build()
        self.reset()

    def reset(self) -> None:
        """A new stream: untimed until its first call with t."""
        self.last_t = None  # set by the first call with t: from then on the stream is timed
        self._seen_t = None  # the latest stamp ahead of the stream's: accepted, or of a call refused since
        self._calls_since = 0  # calls since the last accepted sample, this one included (each a tick)
        self._stamps = 0  # accepted stamps
        self._clock = None  # the robot's clock as the stamps show it: the stamp of the last accepted tick [s]
        self._gap_share = 0.0  # the running share of short gaps among the recent steps (a wrong rate: most are)
        self._mean_step = self._period  # the running mean of the accepted steps per tick [s]
        self.wrong_rate = False  # that mean lies beyond rate_tolerance of the period: another rate than call_hz
        self.lost_ticks = 0  # ticks lost before the latest accepted sample

    def model_changed(self) -> None:
        """The robot's model changed in place (a payload): its weight bounds the base wrench anew (the
        rows of that box only: a rebuild of the gate costs a tick's share)."""
        if not self._needs_wrench:
            return
        start, n = self._gate_slots[2]
        w, why = self._wrench_box()
        self._lo[start:start + n], self._hi[start:start + n] = -w, w
        self._box_lo[start:start + n], self._box_inv_width[start:start + n] = -w, 0.5 / w
        self._slots = [slot[:4] + (why,) + slot[5:] if slot[0] == "base_wrench" else slot for slot in self._slots]

    def _wrench_box(self) -> tuple:
        """The base wrench's bound (6,) [N, Nm] and why: the arm's weight, up to 2 g of inertial load, and the
        largest believable contact; moments through the arm's reach (the sum of its joint and tool offsets:
        by the triangle inequality no point of the chain lies farther from the base)."""
        r, c = self.robot, self.config
        force = c.max_tip_force + 3.0 * r.total_mass * G
        w = np.r_[np.full(3, force), np.full(3, force * self._reach)]
        return w, f"max_tip_force + 3 m g = {force:.0f} N per force axis, x reach {self._reach:.2f} m per moment axis"

    def _build(self) -> None:
        """Precompute the plausibility box [lo, hi] of every value a call brings (module docstring).

        All needed inputs are copied into one preallocated vector x and checked
        at once, with no allocation, by the compiled :func:`_gate`: a value is
        inside when u = (x - lo) / (hi - lo) lies in [0, 1); NaN and inf make u
        NaN (or inf), so they fail too. An unbounded value (no limit in the
        description) gets lo = 1/(hi - lo) = 0: u = 0 when finite.
        """
        r, c = self.robot, self.config
        v_max = np.asarray(r.spec.max_velocity or r.model.velocityLimit, float)
        tau_max = np.asarray(r.model.effortLimit, float)
        reach = sum(float(np.linalg.norm(r.model.jointPlacements[i].translation)) for i in range(1, r.model.njoints))
        reach += float(np.linalg.norm(r.model.frames[r.tool_frame_id].placement.translation))
        self._reach = reach + float(np.linalg.norm(r._root_M_sensor.translation))
        boxes = [("q", 0, r.q_lower - c.q_margin, r.q_upper + c.q_margin, "rad",
                  f"the position limits +- {c.q_margin:g} rad"),
                 ("qd", 1, -v_max * (1 + c.qd_margin), v_max * (1 + c.qd_margin), "rad/s",
                  f"the velocity limits + {100 * c.qd_margin:g} %")]
        if self._needs_wrench:
            w, why = self._wrench_box()
            boxes.append(("base_wrench", 2, -w, w, "N, Nm", why))
        if self._needs_tau:
            boxes.append(("tau_J", 3, -tau_max * (1 + c.tau_margin), tau_max * (1 + c.tau_margin), "Nm",
                          f"the effort limits + {100 * c.tau_margin:g} %"))
        lo = np.concatenate([b[2] for b in boxes])
        hi = np.concatenate([b[3] for b in boxes])
        width = hi - lo
        bounded = np.isfinite(width) & (width > 0)
        self._lo, self._hi = lo, hi
        self._box_lo = np.where(bounded, lo, 0.0)
        self._box_inv_width = np.where(bounded, 1.0 / np.where(bounded, width, 1.0), 0.0)
        self._sample = np.empty(len(lo))  # the accepted sample: q, qd[, base_wrench][, tau_J]
        self._slots, start = [], 0
        self._gate_slots = np.full((4, 2), -1, dtype=np.int64)  # per input (q, qd, base_wrench, tau_J): start, size
        self._absent = [None] * 4  # kalman-fusion's stand-in for a sensor a call lacks: zeros, inside its box
        for name, index, b_lo, _, unit, why in boxes:
            n = len(b_lo)
            self._slots.append((name, index, self._sample[start:start + n], unit, why, start))
            self._gate_slots[index] = start, n
            if name in self._optional:
                self._absent[index] = np.zeros(n)  # every box is symmetric about 0
            start += n
        views = [None] * 4  # q, qd, base_wrench, tau_J: what _accept hands on
        for _, index, view, *_ in self._slots:
            views[index] = view
        self._views = tuple(views)
        self._unused = np.zeros(0)  # the gate's argument for an input this estimator does not read
        self._period = 1.0 / c.call_hz
        # A step this far from the period is the stamps' jitter (a PC's), never a lost tick.
        self._period_tol = min(max(c.rate_tolerance * self._period, 1.5 * c.stamp_jitter), 0.9 * self._period)
        self._jitter = c.stamp_jitter
        self.bridge_ticks = int(c.bridge_seconds * c.call_hz)  # the longest gap accepted at once, and bridged [ticks]
        self._max_force_sq = c.max_tip_force ** 2

    def accept(self, q, qd, base_wrench, tau_J, t):
        """Check one sample before it touches any state (every method passes here).

        Returns (q, qd, base_wrench, tau_J, t, lost): the arrays as float views of the
        preallocated sample vector (None where this estimator does not use them),
        t as a float or None, lost: the ticks lost before this sample (a gap). Raises
        EstimatorInputError naming the argument. ``last_t`` is the caller's to advance.
        """
        # The fast path: float64 1-D arrays go straight into the compiled gate (copy-in and box check in
        # one call); anything else (lists, other dtypes, wrong shapes, None) is converted and named by
        # _converted, then gated the same way. An input the estimator does not read is never looked at.
        self._calls_since += 1  # every call is a tick of the caller's loop, refused or not
        w = base_wrench if self._needs_wrench else self._unused
        tau = tau_J if self._needs_tau else self._unused
        if self._optional:
            w = self._absent[2] if w is None else w
            tau = self._absent[3] if tau is None else tau
        try:
            code = _gate(self._sample, self._box_lo, self._box_inv_width, self._gate_slots, q, qd, w, tau)
        except (TypeError, ValueError):  # no compiled signature matches these arguments
            code = GATE_WRONG_LENGTH
        if code == GATE_WRONG_LENGTH:
            code = _gate(self._sample, self._box_lo, self._box_inv_width, self._gate_slots,
                         *self._converted(q, qd, base_wrench, tau_J))
        if code != GATE_INSIDE:  # NaN and inf fail the box too
            self.saw_stamp(t)
            raise EstimatorInputError(self._implausible())
        if self._optional and base_wrench is None and tau_J is None:
            self.saw_stamp(t)
            raise EstimatorInputError("kalman-fusion needs base_wrench (6,) [N, Nm], tau_J (nv,) [Nm] or both")
        lost = 0
        if t is None:
            if self.last_t is not None:
                raise EstimatorInputError(f"t is missing, but this stream gave t before (last t = {self.last_t} s): "
                                          "once a stream is timed every call needs t; reset() starts anew")
        else:
            try:
                if isinstance(t, (str, bytes)):
                    raise TypeError(t)
                t = float(t)
            except (TypeError, ValueError, OverflowError):
                raise EstimatorInputError(f"t must be a number [s], got a {type(t).__name__}: {t!r:.60}") from None
            if not math.isfinite(t):
                raise EstimatorInputError(f"t must be finite, got {t}")
            lost = self._on_clock(t)
        self._calls_since = 0
        q, qd, views_w, views_tau = self._views
        if self._optional:  # an absent sensor stays None
            return q, qd, None if base_wrench is None else views_w, None if tau_J is None else views_tau, t, lost
        return q, qd, views_w, views_tau, t, lost

    def _on_clock(self, t: float) -> int:
        """Place stamp t on the stream; returns the ticks lost before it (0: the next tick).

        Stamps come in two kinds, and both are accepted. A simulator's or a driver's jitter about the robot's
        clock: the stamp lies within ``_period_tol`` of the next tick of a clock that follows the stamps
        slowly (each moves it by 1 / n, at least 1 %). A logging PC's, as on a real Panda's 1 kHz log: steps of
        0.7-1.8 ms that wander by milliseconds about any fixed clock, where the step from the last accepted
        stamp lies within ``_period_tol`` of the period. Either makes the stamp the next tick.

        A longer step spans round(step / period) ticks. It is accepted when what came between explains it: the
        stamp of the call before lies one period before it (that call was refused for its values, or was a gap's
        end), or no call between brought a stamp ahead and there were as many calls as ticks (a sample refused
        for a stamp of its own): one bad sample costs one sample. It is accepted at once as a short gap (its lost
        ticks within ``bridge_seconds``; the estimator bridges them) while such gaps are a minority of the recent
        steps (over ``RATE_STEPS``): a PC-stamped log streams with no refusal. Else it is refused: a longer gap's
        end (the next call confirms it and the estimator restarts), a stray stamp, or a stream at another rate,
        whose every step spans several ticks and which so never goes on. A stray stamp ahead within a short gap is
        taken for one: the samples after it that lie before it are then refused until the stream passes it. A
        stamp before the last accepted one, or too early for the next tick, is refused.

        A stream whose steps average another period than call_hz's (by over ``rate_tolerance``, over
        ``PERIOD_STEPS``: a 2 kHz or a 600 Hz stream, each of whose steps lies within the tolerance of one period)
        is ``wrong_rate``, which the estimator's status says."""
        if self.last_t is None:
            self._stamps, self._clock, self._seen_t, self._gap_share = 1, t, t, 0.0
            self._mean_step = self._period
            return 0
        T, tol = self._period, self._period_tol
        step = t - self.last_t
        off = t - (self._clock + T)  # from the clock's next tick
        gap = False  # a short gap accepted at once (not explained by refused calls): counted in the gap share
        if abs(step - T) <= tol or abs(off) <= tol:
            ticks = 1
        elif step <= -2.0 * self._jitter or (self._jitter == 0 and step <= 0):
            raise EstimatorInputError(f"time must increase: t={t} after t={self.last_t}")
        elif step < T:
            raise EstimatorInputError(
                f"t={t} s steps {step:.6g} s from the last accepted sample, and call_hz={self.config.call_hz:g} "
                f"expects {T:.6g} s (stamps within +-{tol:.3g} s): a stamp too early for the next tick")
        else:
            ticks = max(2, round(step / T))  # by the step: a PC's stamps wander off any slow clock
            seen, self._seen_t = self._seen_t, t
            between = (0 < t - seen <= T + tol) if seen != self.last_t else ticks <= self._calls_since
            share = self._gap_share + (1.0 - self._gap_share) / min(self._stamps, RATE_STEPS)
            short = ticks - 1 <= self.bridge_ticks and share <= 0.5
            if not (between or short):
                raise EstimatorInputError(
                    f"t={t} s steps {step:.6g} s from the last accepted sample, and call_hz={self.config.call_hz:g} "
                    f"expects {T:.6g} s (stamps within +-{tol:.3g} s): a wrong call_hz, a stray stamp, or a gap "
                    "(the stream goes on when the next stamp lies one period after this one)")
            if not between:
                gap = True
        self._seen_t = t
        a = 1.0 / min(self._stamps, RATE_STEPS)
        self._gap_share += a * (float(gap) - self._gap_share)
        # the stream's period as its stamps show it, over long enough for a PC's uneven steps to average out
        self._mean_step += (step / ticks - self._mean_step) / min(self._stamps, PERIOD_STEPS)
        self._stamps += 1
        self.wrong_rate = self._stamps > RATE_STEPS and abs(self._mean_step / T - 1.0) > self.config.rate_tolerance
        self._clock += ticks * T
        self._clock += max(1.0 / self._stamps, 0.01) * min(max(t - self._clock, -tol), tol)
        self.lost_ticks = ticks - 1
        return ticks - 1

    def saw_stamp(self, t) -> None:
        """A call refused for its values brought stamp t: when it lies ahead of the last accepted one, the next
        stamp one period after it is the next tick (that sample was lost, not the clock)."""
        try:
            t = float(t) if isinstance(t, (int, float)) else None
        except OverflowError:  # an int beyond any float: no stamp
            t = None
        if self.last_t is not None and t is not None and math.isfinite(t) and t > self.last_t:
            self._seen_t = t

    def _converted(self, q, qd, base_wrench, tau_J) -> list:
        """_accept's slow path: each input this estimator reads as a fresh float64 array of its shape
        (a copy, so contiguous and writable whatever was given), or EstimatorInputError naming it."""
        given = [q, qd, base_wrench, tau_J]
        out = [self._unused] * 4
        for name, index, view, unit, *_ in self._slots:
            x = given[index]
            if x is None:
                if name in self._optional:  # kalman-fusion: this call lacks the sensor
                    out[index] = self._absent[index]
                    continue
                raise EstimatorInputError(f"this estimator needs {name} ({view.size},) [{unit}]")
            try:
                x = np.array(x, dtype=float)
            except (TypeError, ValueError) as err:
                raise EstimatorInputError(f"{name} must be {view.size} numbers [{unit}], got a "
                                          f"{type(x).__name__}: {err}") from None
            if x.shape != view.shape:
                raise EstimatorInputError(f"{name} must have shape ({view.size},), got {x.shape}")
            out[index] = x
        return out

    def _implausible(self) -> str:
        """The message for a sample outside its box (the slow path: only on rejection)."""
        x, lo, hi = self._sample, self._lo, self._hi
        bad = int(np.flatnonzero(~((x >= lo) & (x < hi)))[0])
        for name, _, view, unit, why, start in self._slots:
            if start <= bad < start + view.size:
                j = bad - start
                if not math.isfinite(x[bad]):
                    return f"{name} holds NaN or inf: {name}[{j}] = {x[bad]}"
                if name == "base_wrench":
                    unit = "N" if j < 3 else "Nm"
                return (f"{name}[{j}] = {x[bad]:.6g} {unit} is outside [{lo[bad]:.6g}, {hi[bad]:.6g}] "
                        f"({why}; robot {self.robot.name!r})")
        raise AssertionError("no value outside its box")  # pragma: no cover


class RateCheck:
    """Is an untimed stream called at ``call_hz``? Judged from its own samples.

    Over blocks of ``block`` calls, q's increments dq_k = q_k - q_k-1 are fitted by
    ratio * dt (qd_k + qd_k-1) / 2 (the trapezoid, exact for a quadratic path) with
    dt = 1 / call_hz: a stream at call_hz gives ratio 1, one at half the rate 2. A
    block is judged only when the fit's standard error is below ``resolution``
    (the arm moved enough for the encoders' noise); a judged block sets
    ``wrong`` when |ratio - 1| exceeds the tolerance, and clears it otherwise.
    """

    def __init__(self, nv: int, call_hz: float, tolerance: float, block: int = 100, resolution: float = 0.05):
        self.dt, self.tolerance, self.block, self.resolution = 1.0 / call_hz, tolerance, block, resolution
        self._acc = np.zeros(4)  # sum dq.v, sum v.v, sum dq.dq, count
        self._last = np.zeros((2, nv))
        self.reset()
        _rate_step(self._acc.copy(), self._last.copy(), np.zeros(nv), np.zeros(nv), self.dt, False)

    def reset(self) -> None:
        self._acc[:] = 0.0
        self._started = False
        self.wrong = False
        self.ratio = None  # the last judged block's ratio

    def update(self, q, qd) -> bool:
        """One accepted sample; returns ``wrong``."""
        _rate_step(self._acc, self._last, q, qd, self.dt, self._started)
        self._started = True
        if self._acc[3] >= self.block:
            s_dv, s_vv, s_dd, n = self._acc
            if s_vv > 0:
                ratio = s_dv / s_vv
                residual = max(s_dd - ratio * s_dv, 0.0) / max(n * len(q) - 1, 1)
                if math.sqrt(residual / s_vv) < self.resolution:
                    self.ratio = ratio
                    self.wrong = abs(ratio - 1.0) > self.tolerance
            self._acc[:] = 0.0
        return self.wrong


@njit(cache=True)
def _rate_step(acc, last, q, qd, dt, started):  # pragma: no cover (compiled)
    """RateCheck's sums: dq = q - q_prev against v = dt (qd + qd_prev) / 2."""
    if started:
        for j in range(q.shape[0]):
            dq = q[j] - last[0, j]
            v = 0.5 * dt * (qd[j] + last[1, j])
            acc[0] += dq * v
            acc[1] += v * v
            acc[2] += dq * dq
        acc[3] += 1.0
    for j in range(q.shape[0]):
        last[0, j] = q[j]
        last[1, j] = qd[j]
