"""The streaming tip-force estimator, :class:`TipForceEstimator`: one sample in, one force out.

Control engineers call :class:`TipForceEstimator` once per tick of a 1 kHz loop::

    est = TipForceEstimator.analytic("panda", method="base-momentum")
    F = est.estimate_tip_force(q, qd, base_wrench=w, t=t)   # (3,) N, base frame
    est.last_status                                         # EstimatorStatus.OK, ...

The analytic methods are defined once, in ``analytic/methods.py`` (what each
reads, its bandwidth and the rule that sets it, its streaming step and batch
run); this module runs them on a stream. What happens in one call:

1. The sample is checked before any state is touched (``estimator/input.py``).
   It is rejected when
   - an argument is not numeric, has the wrong shape, holds NaN/inf, or a
     needed one (base_wrench, tau_J) is missing;
   - it is physically implausible for the robot description (the bounds are
     ``EstimatorConfig`` fields): q more than ``q_margin`` (0.1 rad) outside the
     URDF position limits; |qd| above the velocity limit by more than
     ``qd_margin`` (50 %); |tau_J| above the URDF effort limit by more than
     ``tau_margin`` (50 %); a base-wrench force component above
     ``max_tip_force + 3 m g`` [N] (the arm's weight and up to 2 g of inertial
     load on top of the largest believable contact), or a moment component above
     that times the arm's reach [Nm] (the sum of its joint offsets: no point of
     the arm lies farther from the base);
   - its time breaks the stream: t not increasing, t missing once the stream
     has given t (the first call with t makes a stream timed until ``reset``), or
     a stamp off the stream's clock by more than max(``rate_tolerance`` periods,
     1.5 ``stamp_jitter``). The robot samples on its own clock; a control PC's
     stamps jitter about it (up to 0.5 ms by default), so the estimator follows the
     stamps' grid (slowly, for a drift between the clocks) and runs its filters on
     the nominal period. A wrong ``call_hz`` (a 100 Hz recording fed to a 1 kHz
     estimator errs 10 N) or a lost tick is refused rather than silently
     mis-filtered. A wrong rate is refused at every call; after a gap, the sample
     one period after the refused one resumes the stream: the filters and observers
     restart (a finished tare is kept; the joint-state filter predicts across a gap
     of up to 50 samples) and it warms up anew for the method's settling time.
   A rejected sample raises :class:`EstimatorInputError` (a ``ValueError`` that
   names the argument), or with ``on_bad_input="hold"`` returns the last good
   estimate with ``last_status = INPUT_REJECTED`` (``last_rejection`` says why).
   It never enters the filter, observer, tare, window or time state: the calls
   after it give exactly what they give without it. An untimed stream is checked
   for its rate from its own samples (``RateCheck``: q's increments against
   qd / call_hz): a stream at another rate says "wrong rate".
2. Quantized encoders (``encoder_resolution`` > 0, the robot description's by
   default): q becomes q, qd and qdd through the joint-state Kalman filter
   (``analytic/joint_state.py``); every method reads its q and qd, and the rules
   below get the velocity noise it carries in motion (a still window shows none).
3. The first ``tare_seconds`` of calls are the noise window (nothing may touch
   the arm then; status "warming up"). On it the base sensor is tared
   (``analytic/tare.py``), the sensors' white noise is measured, and the
   method's bandwidth (qdd cutoff, observer gain, Kalman force rate) is chosen by
   the one rule of ``analytic/bandwidth.py`` (a number given in the config
   instead of "auto" is used as is). Without a window (``tare_seconds=0``) the
   rule runs on the sensors' specifications. Every filter design happens when
   the estimator is built, and the close is split over two calls: the window's
   last call checks and measures it, the first call after it picks the bandwidth
   (and the method starts there). The check: a window whose base-sensor residual
   steps or trends by more than ``tare_contact_force`` (or six times its own
   noise), or in which the joint torques (where the method reads them) see such a
   force, is not trusted: a new window starts, status "contact at start-up"
   (``window_problem`` says why). After the window, at a standstill with no
   contact, the tare follows the base sensor's drift (``retare_seconds``).
4. Where the method needs it, qdd is estimated from qd causally, with the
   generator's filter (``analytic/acceleration.py``) at the call rate; the
   window is replayed through the chosen filter, so that it runs as if from the start.
5. The method gives the force. Its transient after a start, a gap, or (for
   kalman-fusion, which takes whichever sensors a call brings) a sensor joining
   or leaving is its settling time: "warming up" until it has passed. A sensor
   absent for up to 5 calls (alternating sensors) is bridged, not a leave. A
   base sensor that joins kalman-fusion after the window is tared when it comes;
   while the joint torques see a force above ``tare_contact_force`` the tare starts
   over (it never tares over a contact), and the filter runs on the torques alone.
6. An estimate above ``max_tip_force`` (500 N) is returned with status
   FORCE_OUT_OF_RANGE ("force out of range") and is not kept as the last good one.
7. Every estimate gets an error bar, ``last_sigma`` (3,) [N] (``analytic/error_bar.py``;
   infinite while there is no estimate); a settled call whose error bar exceeds
   ``max_sigma`` on any axis is "uncertain", not "ok".

Statuses (``last_status``), first match wins: INPUT_REJECTED (this sample was
refused; the last good estimate is returned), FORCE_OUT_OF_RANGE (the estimate
exceeds ``max_tip_force``), WRONG_RATE (an untimed stream whose samples are
spaced unlike 1 / call_hz), NO_SENSOR ("no usable sensor": this call brings
nothing the method can estimate from, e.g. kalman-fusion given only a base
sensor that is not yet tared; the returned force is a prediction), WARMING_UP
(the window, tare, filter or observer still settles) or CONTACT_AT_START (the
same after a window that saw a contact), OUT_OF_RANGE (a learned model's input
lies outside its training range: "input out of training range"), UNCERTAIN
(``last_sigma`` above ``max_sigma``), OK.

A known base-sensor offset can be given with ``set_tare_offset``; ``reset``
tares anew. A tool's load: ``payload=`` at construction or ``set_payload`` between
calls (the model every method subtracts carries it, changed in place within a tick: the estimator runs on).

Threading: an estimator holds per-stream state (filter, window, observer) and
preallocated buffers, so one instance must be used by one thread at a time;
use one estimator per control thread. ``estimate_tip_force()`` (the stateless
batch form, ``estimator/batch.py``) is thread-safe: it keeps one robot model per thread.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit

from ..analytic.acceleration import CausalAccelerationFilter, cutoff_grid, default_qdd_cutoff
from ..analytic.error_bar import ErrorBar, qdd_norm
from ..analytic.joint_state import joint_filter_for, with_joint_state_noise
from ..analytic.kalman import MAX_BRIDGE_CALLS
from ..analytic.method_declaration import spec_noise
from ..analytic.methods import TIP_FORCE_METHODS
from ..analytic.robot import Robot, load_robot, with_payload
from ..analytic.tare import StreamingTare, tare_samples
from ..errors import UsageError
from .config import EstimatorConfig, EstimatorStatus, check_rating, checked_payload, rated_payload
from .consistency import Consistency
from .input import EstimatorInputError, InputGate, RateCheck
from .noise_window import NoiseWindow
from .stream_starts import StreamStarts


# The statuses as plain names for the per-call path: an Enum member looked up on its class costs ~0.3 us.
_OK, _WARMING_UP, _OUT_OF_RANGE, _FORCE_OUT_OF_RANGE, _WRONG_RATE, _NO_SENSOR, _UNCERTAIN, _CONTACT_AT_START = (
    EstimatorStatus.OK, EstimatorStatus.WARMING_UP, EstimatorStatus.OUT_OF_RANGE, EstimatorStatus.FORCE_OUT_OF_RANGE,
    EstimatorStatus.WRONG_RATE, EstimatorStatus.NO_SENSOR, EstimatorStatus.UNCERTAIN, EstimatorStatus.CONTACT_AT_START)
_IMPLAUSIBLE_TARE, _FROZEN_SENSOR, _OFF_TOOL = (
    EstimatorStatus.IMPLAUSIBLE_TARE, EstimatorStatus.FROZEN_SENSOR, EstimatorStatus.OFF_TOOL)
_NO_SIGMA = np.full(3, np.inf)  # no estimate yet (the noise window): an unbounded error bar
# kalman-fusion's sensors in use, by (base sensor in use, joint torques in use)
_ACTIVE = {(False, False): (), (True, False): ("base_wrench",), (False, True): ("tau_J",),
           (True, True): ("base_wrench", "tau_J")}


@njit(cache=True)
def _within(x, bound) -> bool:  # pragma: no cover (compiled)
    """Whether -bound < x_i < bound for every i (a standstill: two numpy reductions cost ten times this)."""
    for i in range(x.shape[0]):
        if not (-bound < x[i] < bound):
            return False
    return True


class TipForceEstimator(StreamStarts):
    """Streaming tip-force estimator; see the module docstring."""

    def __init__(self, robot: Robot, method: str, config: EstimatorConfig | None = None, model=None):
        self.config = c = config or EstimatorConfig()
        if model is None:  # its own model: set_payload changes it in place, and no one else's
            robot = robot.copy()
            if robot.payload is not None:
                check_rating(robot.payload.mass, rated_payload(robot.spec, c), robot.base_name)
        self.robot = robot
        self.model = model
        nv = robot.nv
        if method == "learned":
            self.spec, self._stream = None, None
            sensors = tuple(model.inputs) + tuple(getattr(model.model.prior, "fields", None) or ())
            self._needs_qdd, self._optional = True, frozenset()
        else:
            self.spec = TIP_FORCE_METHODS.lookup(method)
            method = self.spec.name
            self._stream = self.spec.make(robot, float(c.call_hz))  # builds (and compiles) everything it runs
            sensors, self._needs_qdd = self.spec.reads, self.spec.needs_qdd
            self._optional = frozenset(sensors) if self.spec.any_of else frozenset()
        self.method = method
        self._gate = InputGate(robot, c, "base_wrench" in sensors, "tau_J" in sensors, self._optional)
        self._rate = RateCheck(nv, float(c.call_hz), c.rate_tolerance)
        # Quantized encoders: q becomes q, qd (and qdd) through one Kalman filter every method reads
        # (analytic methods only: a learned model reads what its training data recorded).
        self.encoder_resolution = (robot.spec.encoder_resolution if c.encoder_resolution == "auto"
                                   else float(c.encoder_resolution))
        self._joint = None if model is not None else joint_filter_for(
            robot, c.call_hz, self.encoder_resolution, c.joint_filter_bandwidth)
        self._error_bar = ErrorBar(c.call_hz, c.motion_sigma_gain, c.base_drift_rate)
        # The bandwidth: a number in the config, or None for the rule at the window's end.
        value = "auto" if self.spec is None else c.bandwidth(self.spec.parameter)  # by its declaration's name
        self._fixed = None if value == "auto" else float(value)
        if model is not None and c.qdd_cutoff_hz == "auto":
            # The network saw qdd through its training filter: the stream runs it too, a fixed number the
            # config then shows (no rule picks it later: a learned model has no noise window).
            self.config = c = replace(c, qdd_cutoff_hz=model.stream_qdd_cutoff(c.call_hz))
        cutoff = c.qdd_cutoff_hz if c.qdd_cutoff_hz != "auto" else default_qdd_cutoff(c.call_hz)
        self._qdd_cutoff_start = float(cutoff)
        self._qdd_filter = CausalAccelerationFilter(nv, c.call_hz, self._qdd_cutoff_start)
        if self._needs_qdd and self.spec is not None:
            cutoff_grid(float(c.call_hz))  # every design the rule may pick, now
        self._tare = None
        # The noise window: where the method tares, or chooses its bandwidth by the rule.
        n_window = tare_samples(c.call_hz, c.tare_seconds) if self.spec is not None and (
            self.spec.tares or self._fixed is None) else 0
        if self.spec is not None and self.spec.tares and n_window:
            self._tare = StreamingTare(robot, n_window)
        self._window_calls = n_window
        # The noise window's samples, preallocated (a row per call; presence per optional sensor).
        check_torques = self.spec is not None and self.spec.tares and "tau_J" in self.spec.reads
        self._window = NoiseWindow(robot, n_window, check_torques)
        self._check = None if self.spec is None else Consistency(
            robot, c, self._stream, method, "base_wrench" in sensors, "tau_J" in sensors)
        drift = c.base_drift_rate / c.call_hz  # the follower's largest step per call [N], and [Nm] at 0.2 m
        self._follow_step = np.r_[np.full(3, drift), np.full(3, 0.2 * drift)]
        _within(self._follow_step, 1.0)  # compiled (or loaded from numba's cache) now, not in a control cycle
        self.reset()

    # ------------------------------------------------------------ factories
    @classmethod
    def analytic(cls, robot: str | Robot = "panda", method: str = "base-wrench", params=None, payload=None,
                 **config) -> "TipForceEstimator":
        """A model-free estimator: ``method`` is a name of ``analytic.methods.TIP_FORCE_METHODS`` (what each reads:
        its declaration's ``reads``), or an older spelling of one (the registry's ``aliases``, with a warning).
        payload: the tool's load, ``(mass_kg, (x, y, z))`` with its centre of mass [m] in the tool frame (as
        libfranka's ``setLoad``): part of the model every method subtracts (``set_payload`` changes it).
        config: ``EstimatorConfig`` settings, a method's bandwidth parameter by its name (``momentum_gain=50.0``)."""
        method = TIP_FORCE_METHODS.lookup(method).name
        config = EstimatorConfig.from_settings(**config)
        if not isinstance(robot, Robot):
            robot = load_robot(robot, params=params, num_threads=1)
        if payload is not None:
            robot = with_payload(robot, checked_payload(payload, rated_payload(robot.spec, config), robot.base_name))
        return cls(robot, method, config)

    @classmethod
    def load(cls, model_dir, robot: str | None = None, runtime: str = "auto", payload=None,
             **config) -> "TipForceEstimator":
        """An estimator around a trained tip-force model (seed net, residual net, ...).

        The model's analytic part (if any) comes with it. ``robot``: when given,
        a model trained for another robot is refused. ``runtime``: how the network
        runs: "auto" (the faster of onnxruntime and numba, timed at load), "onnx"
        (float32) or "numba" (float64: agrees with the batch form to round-off).
        """
        from ..learn.stream_predictor import StreamingModel

        if payload is not None:
            # A learned model's network learnt the arm it was trained on: a load it never saw is no input it
            # can remove. Refused rather than ignored.
            raise UsageError("payload= is not supported for a learned model yet: train it on data with the tool, "
                             "or use TipForceEstimator.analytic(..., payload=...)")
        model = StreamingModel.load(Path(model_dir), robot=robot, runtime=runtime)
        return cls(model.robot, "learned", EstimatorConfig.from_settings(**config), model=model)

    def set_payload(self, mass_kg: float, com_xyz=(0.0, 0.0, 0.0)) -> None:
        """The tool carries ``mass_kg`` [kg] from now on, its centre of mass at ``com_xyz`` [m] in the tool frame
        (0 kg: none); at most the rated payload (``EstimatorConfig.rated_payload_kg``). Between calls, within
        a tick: the model every method subtracts changes in place (``Robot.set_payload``) and the estimator
        runs on, with no new window. Declare a load when it is picked up or put down: the base sensor's tare
        is its bias, which a load does not change (the sensor and the model gain its weight together), so
        it is kept. A load carried through the tare but declared later is another case: ``reset`` re-tares."""
        if self.model is not None:
            raise UsageError("set_payload is not supported for a learned model yet")
        mass, com = checked_payload((mass_kg, com_xyz), rated_payload(self.robot.spec, self.config),
                                    self.robot.base_name)
        self.robot.set_payload((mass, com) if mass > 0 else None)
        self._stream.model_changed()  # a weight it computed when it was made
        self._gate.model_changed()  # the base-wrench bound (3 m g)

    # --------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget all history (filter, observer, window, tare); the next calls warm up again."""
        self._qdd_filter = CausalAccelerationFilter(self.robot.nv, self.config.call_hz, self._qdd_cutoff_start)
        self.qdd_cutoff_hz = self._qdd_cutoff_start if (self._needs_qdd and self._window_calls == 0) else None
        self._gate.reset()
        self._rate.reset()
        if self._joint is not None:
            self._joint.reset()
        # The joint-state filter starts at rest: in motion its qd and qdd need ~8 / omega to converge, and
        # a tare (or a window check) on them before that absorbs the transient. The window waits for it.
        self._joint_wait = 0 if self._joint is None or self._tare is None else self._joint.settle_calls()
        self._error_bar.reset()
        self.last_sigma = _NO_SIGMA.copy()
        self._motion = 0.0  # this call's joint-acceleration norm [rad/s^2], for the error bar
        self._tared_at = None  # the call at which the base sensor's offset was last set
        self.window_problem = None  # why the last noise window was not trusted (a contact), until one is
        self._still_calls = 0  # consecutive calls at a standstill (the drift-following tare)
        self._fault = None  # the consistency status of this call (``estimator/consistency.py``), or None
        if self._check is not None:
            self._check.reset()
        if self._tare is not None:
            self._tare.reset()
        if self.model is not None:
            self.model.reset()
        if self._stream is not None:
            self._stream.reset()
        self._calls = 0
        self._window.clear()
        self._absent = [-1, -1]  # calls each sensor has been absent from the method (-1: never given)
        self._active = ()  # the sensors the method currently estimates from (kalman-fusion)
        self._base_tared = self._tare is None  # the base wrench may enter the method
        self.bandwidth = None  # the method's bandwidth parameter in use (spec.parameter), once chosen
        if self.spec is None:
            self._warmup_calls = self.model.warmup_calls(self.config.call_hz)
        elif self._window_calls == 0:  # no window: the configured value, or the rule on the specifications
            self.bandwidth = self._stream.close_window(with_joint_state_noise(spec_noise(self.robot), self._joint),
                                                       None, self._fixed)
            self._use_bandwidth()
            self._warmup_calls = 1 + self._stream.settle_calls(self.spec.reads)  # the first call starts it
        else:
            self._warmup_calls = self._window_calls + 1
        self._window_noise = None  # measured by the window's last call, applied by the next
        self._last_good = np.zeros(3)
        self.fusion_noise = None
        self.last_status = EstimatorStatus.WARMING_UP
        self.last_rejection = None  # why the latest rejected sample was refused (hold mode)

    @property
    def _active_tare(self):
        """The tare of the analytic base-wrench method, or of a learned model's base-wrench prior."""
        return self._tare if self._tare is not None else getattr(self.model, "_tare", None)

    @property
    def tare_offset(self) -> np.ndarray | None:
        """The base-sensor offset in use (6,) [N, Nm], or None when this estimator does not tare."""
        tare = self._active_tare
        return None if tare is None else tare.offset.copy()

    def set_tare_offset(self, offset) -> None:
        """Use a known base-sensor offset (6,) [N, Nm] and skip the tare window."""
        tare = self._active_tare
        if tare is None:
            raise ValueError("this estimator does not use the base sensor's tare")
        tare.set_offset(offset)
        self._tared_at = self._calls

    # ---------------------------------------------------------------- call
    def estimate_tip_force(self, q, qd, base_wrench=None, tau_J=None, t=None) -> np.ndarray:
        """One sample in, the tip force (3,) [N] in the base frame out; see ``last_status``."""
        try:
            q, qd, base_wrench, tau_J, t, resumed = self._gate.accept(q, qd, base_wrench, tau_J, t)
        except EstimatorInputError as err:
            if self.config.on_bad_input == "raise":
                raise
            self.last_status = EstimatorStatus.INPUT_REJECTED
            self.last_rejection = str(err)
            return self._last_good.copy()
        if resumed:  # the samples lost, counted on the stream's clock (not by the stamps' own jitter)
            self._restart_dynamics((self._gate.lost_ticks + 1) / self.config.call_hz)
        wrong_rate = False
        if t is not None:
            self._gate.last_t = t
        else:
            wrong_rate = self._rate.update(q, qd)
        if self._joint is not None:
            q, qd, qdd_joint = self._joint.step(q)
            self._motion = qdd_norm(qdd_joint)
            if self._joint_wait:
                self._joint_wait -= 1
                return self._finish(self._last_good, True, wrong_rate, True, estimated=False)
        k = self._calls
        in_window = k < self._window_calls
        tare = self._tare
        taring = tare is not None and not tare.done
        # qdd only where the method (or the window's tare) needs it: the observers need none.
        qdd = self._qdd_filter.step(qd) if (self._needs_qdd or taring) else None
        self._calls += 1
        if self.spec is None:
            return self._finish(*self.model.step(q, qd, qdd, base_wrench, tau_J, t), wrong_rate, True)
        tared = base_wrench
        if tare is not None and base_wrench is not None:
            tared = tare.update(q, qd, qdd, base_wrench)
        if in_window:
            self._window.record(k, q, qd, qdd, base_wrench, tau_J)
            self._stream.window_step(q, qd, qdd, base_wrench, tau_J)
            if self._calls == self._window_calls:  # the window's last call checks it and measures its noise...
                problem = self._window.contact(self._tare, self.config.tare_contact_force, self.config.off_tool_moment)
                if problem is not None:
                    self._restart_window(problem)
                else:
                    self.window_problem = None
                    self._window_noise = self._window.measure(self._joint)
            return self._finish(self._last_good, True, wrong_rate, True, estimated=False)
        if self._window_noise is not None:  # ...and the next one applies the rule: no call does both
            self._close_window(self._window_noise)
            if self.spec.needs_qdd:
                qdd = self._qdd_filter.step(qd)  # this sample through the chosen filter, after the window's replay
        if taring and tau_J is not None and self._last_good.dot(self._last_good) > self.config.tare_contact_force ** 2:
            tare.reset()  # a late tare must not average over a contact the torques see: start over
        if not self._base_tared and tare.done:
            self._base_tared = True
            self._tared_at = self._calls
        w_in = tared if self._base_tared else None
        usable = True
        if self._optional:
            usable = self._track_sensors(w_in is not None, tau_J is not None)
        f = self._stream.step(q, qd, qdd, w_in, tau_J)
        if w_in is not None:
            self._follow_drift(q, qd, base_wrench, f)
        self._judge(q, qd, qdd, w_in, base_wrench, tau_J)
        return self._finish(f, True, wrong_rate, usable)

    def _judge(self, q, qd, qdd, w_in, base_wrench, tau_J) -> None:
        """This call's consistency status (``estimator/consistency.py``), first match: an implausible tare,
        a frozen sensor, a contact off the tool."""
        check, fault = self._check, None
        if w_in is not None and self._tare is not None:
            o = self._tare.offset
            if o[0] * o[0] + o[1] * o[1] + o[2] * o[2] > self.config.max_tare_offset ** 2:
                fault = _IMPLAUSIBLE_TARE
        if check.frozen(base_wrench, tau_J) and fault is None:
            fault = _FROZEN_SENSOR
        if check.check_off_tool(q, qd, qdd, w_in, tau_J) and fault is None:
            fault = _OFF_TOOL
        self._fault = fault

    def _follow_drift(self, q, qd, base_wrench, f) -> None:
        """A base sensor's bias drifts after its tare. While the arm stands still (every joint slower than
        ``standstill_speed`` for ``standstill_seconds``) and the estimate shows no contact (below
        ``tare_contact_force``), the tare follows the sensor with time constant ``retare_seconds``: a
        contact held that still and that small is what it may absorb."""
        c = self.config
        if c.retare_seconds == math.inf:  # told not to follow
            return
        if _within(qd, c.standstill_speed):
            self._still_calls += 1
        else:
            self._still_calls = 0
        if self._still_calls >= c.standstill_seconds * c.call_hz and f.dot(f) < c.tare_contact_force ** 2:
            self._tare.follow(q, base_wrench, 1.0 / (c.retare_seconds * c.call_hz), self._follow_step)
            self._tared_at = self._calls

    def _finish(self, f, in_range, wrong_rate, usable, estimated=True) -> np.ndarray:
        """The status of this call's estimate f, and f (a copy); a force within the bound is kept.
        estimated: f is the method's estimate of this call (not the held one of the noise window)."""
        if self._calls < self._warmup_calls:  # the method's own transient: no error model of it
            estimated = False
            self._error_bar.reset()
        if estimated:
            since = None
            if self._tared_at is not None:
                since = (self._calls - self._tared_at) / self.config.call_hz
            self.last_sigma = self._error_bar.update(f, self._motion, since)
        else:
            self.last_sigma = _NO_SIGMA.copy()
        status = _OK if in_range else _OUT_OF_RANGE
        s0, s1, s2 = self.last_sigma.tolist()  # floats: a numpy max costs a microsecond; NaN still fails
        limit = self.config.max_sigma
        if status is _OK and not (s0 <= limit and s1 <= limit and s2 <= limit):
            status = _UNCERTAIN
        if self._calls < self._warmup_calls:
            status = _WARMING_UP if self.window_problem is None else _CONTACT_AT_START
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
