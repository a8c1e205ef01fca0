"""The streaming tip-force estimator, :class:`TipForceEstimator`: one sample in, one force out.

What one call does (the input checks, the noise window, the bandwidth, the statuses, threading):
docs/estimator.md. The per-call status and error bar: ``call_status.py``; the (re)starts: ``stream_starts.py``.
"""
from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..analytic.acceleration import CausalAccelerationFilter, cutoff_grid, default_qdd_cutoff
from ..analytic.error_bar import ErrorBar
from ..analytic.joint_state import joint_filter_for, with_joint_state_noise
from ..analytic.method_declaration import spec_noise
from ..analytic.methods import DEFAULT_METHOD, TIP_FORCE_METHODS
from ..analytic.robot import Robot, load_robot, with_payload
from ..analytic.tip_force import MAX_DAMPING, SINGULAR_REGION, damped_solve3
from ..analytic.tare import StreamingTare, tare_samples
from ..description.spec import resolve_encoder_resolution
from ..errors import UsageError
from .call_status import NO_SIGMA, CallStatus, StandstillLag, within
from .config import MAX_SIGMA, EstimatorConfig, EstimatorStatus, check_rating, checked_payload, rated_payload
from .calibration import Calibration, ModelError
from .consistency import Consistency
from .model_term import StatedModelError, inertial_uncertainty
from .input import EstimatorInputError, InputGate, RateCheck
from .noise_window import NoiseWindow
from .stream_starts import StreamStarts
from .torque_model import JointTorqueModel
from .torque_tare import TorqueTare


FOLLOW_RATE_FACTOR = 2.0  # the drift follower's fastest pace, in multiples of the sensor's stated drift rate
GRID_CHECK_SECONDS = 10.0  # [s]: how long q is checked against the declared encoders' grid


class EncoderModelWarning(UserWarning):
    """The stream's q does not fit the declared encoder model (``TipForceEstimator.encoder_mismatch``)."""


class TipForceEstimator(CallStatus, StreamStarts):
    """Streaming tip-force estimator: what one call does, docs/estimator.md."""

    def __init__(self, robot: Robot, method: str, config: EstimatorConfig | None = None, model=None,
                 torque_model: JointTorqueModel | None = None, calibration: Calibration | None = None):
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
        calibrated = self._use_model(torque_model, calibration)
        self._gate = InputGate(robot, c, "base_wrench" in sensors, "tau_J" in sensors, self._optional)
        self._rate = RateCheck(nv, float(c.call_hz), c.rate_tolerance)
        self._prev_arrays = (np.zeros(nv), np.zeros(nv), np.zeros(6), np.zeros(nv))
        # Quantized encoders: q becomes q, qd (and qdd) through one Kalman filter every method reads
        # (analytic methods only: a learned model reads what its training data recorded).
        self.encoder_resolution = resolve_encoder_resolution(c.encoder_resolution, robot.spec)
        self._joint = None if model is not None else joint_filter_for(
            robot, c.call_hz, self.encoder_resolution, c.joint_filter_bandwidth)
        # Quantized encoders put q on a grid of the resolution; a q off it is the arm's own (unquantized q, its own
        # qd): checked over the first GRID_CHECK_SECONDS, then told and read as given (``_check_encoder_grid``).
        self._grid_checks = 0 if self._joint is None else int(GRID_CHECK_SECONDS * c.call_hz)
        self.encoder_mismatch = None
        # The motion term stands in for the model's error; a calibrated model term replaces it.
        self._error_bar = ErrorBar(c.call_hz, 0.0 if calibrated else c.motion_sigma_gain, c.base_drift_rate)
        # The bandwidth: a number in the config (or the calibration's), or None for the rule at the window's end.
        value = "auto" if self.spec is None else c.bandwidth(self.spec.parameter)  # by its declaration's name
        if value == "auto" and calibrated is not None:
            value = calibrated.bandwidth
            self.spec.bandwidth.check(value, float(c.call_hz))  # a file's number, as a config's would be
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
        # A method on the joint torques tares their offsets in its window (``torque_tare.py``; a fixed bandwidth has
        # none, and starts at once); kalman-fusion checks first that its torques see no force there (the window).
        reads_torques = self.spec is not None and "tau_J" in self.spec.reads
        self._tau_tare = TorqueTare(robot, c.max_torque_offset, c.torque_drift_rate, c.standstill_speed, c.call_hz) \
            if reads_torques and n_window else None
        if self.spec is not None and self.spec.tares and n_window:
            self._tare = StreamingTare(robot, n_window)
        self._window_calls = n_window
        # The noise window's samples, preallocated (a row per call; presence per optional sensor).
        check_torques = self.spec is not None and self.spec.tares and "tau_J" in self.spec.reads
        self._window = NoiseWindow(robot, n_window, check_torques)
        self._check = None if self.spec is None else Consistency(
            robot, c, self._stream, method, "base_wrench" in sensors, "tau_J" in sensors, self._model_error)
        # The follower's largest step per call [N], and [Nm] at 0.2 m: twice the stated drift, so that it catches up
        # with a drift at that rate (at once the rate, it stayed behind by what it lost before it locked on: 0.24-0.6 N
        # over ten minutes), while a contact that builds faster is still not tared away.
        drift = FOLLOW_RATE_FACTOR * c.base_drift_rate / c.call_hz
        self._follow_step = np.r_[np.full(3, drift), np.full(3, 0.2 * drift)]
        within(self._follow_step, 1.0)  # compiled (or loaded from numba's cache) now, not in a control cycle
        damped_solve3(np.eye(3), np.zeros(3), SINGULAR_REGION, MAX_DAMPING)  # the first estimate's solve, likewise
        self.reset()

    def _use_model(self, torque_model, calibration):
        """The torque model beyond the rigid body (friction, springs, a learned residual), taken from tau_J, and
        the error bar's model term calibrated on the user's log (``estimator/calibration.py``); returns this
        method's calibrated settings (None without a calibration)."""
        self.torque_model, self.calibration = torque_model, calibration
        self._model_error, max_sigma, calibrated = None, self.config.max_sigma, None
        if calibration is not None:
            if self.spec is None or "tau_J" not in self.spec.reads:
                raise UsageError(f"a calibration applies to the joint-torque methods, not {self.method!r}")
            digest = None if torque_model is None else torque_model.digest
            calibrated = calibration.check_for(self.robot, digest, self.method)
            self._model_error = ModelError(self.robot, calibrated)
            max_sigma = calibrated.max_sigma if max_sigma == "auto" else max_sigma
        elif self.spec is not None:
            self._model_error = self._stated_model_error()
        self.max_sigma = MAX_SIGMA if max_sigma == "auto" else float(max_sigma)
        # qdd filtered for the calibrated term's law (the stated term reads whichever qdd the call has)
        self._model_qdd = calibrated is not None or (torque_model is not None and torque_model.needs_qdd)
        return calibrated

    def _stated_model_error(self):
        """The model term of what the description and the payload state (``model_term.py``), or None where they
        state nothing (a payload's sigma counts only while one is declared, so it is kept for ``set_payload``)."""
        c, reads = self.config, self.spec.reads
        inertial = inertial_uncertainty(c.inertial_uncertainty, self.robot.spec)
        if inertial == 0.0 and c.payload_uncertainty_kg == 0.0:
            return None
        kind = "fusion" if "base_wrench" in reads and "tau_J" in reads else "base" if "base_wrench" in reads \
            else "torques"
        return StatedModelError(self.robot, kind, float(inertial), float(c.payload_uncertainty_kg))

    # ------------------------------------------------------------ factories
    @classmethod
    def analytic(cls, robot: str | Robot = "panda", method: str = DEFAULT_METHOD, params=None, payload=None,
                 calibration=None, torque_model="params", residual=None, **config) -> "TipForceEstimator":
        """A model-free estimator: ``method`` is a name of ``analytic.methods.TIP_FORCE_METHODS`` (what each reads:
        its declaration's ``reads``), or an older spelling of one (the registry's ``aliases``, with a warning).
        payload: the tool's load, ``(mass_kg, (x, y, z))`` with its centre of mass [m] in the tool frame (as
        libfranka's ``setLoad``): part of the model every method subtracts (``set_payload`` changes it).
        params: a parameter set's name, or a file; an identified file (``hybrid-dyn identify``) gives its
        inertials, and its friction and declared springs, which are taken from tau_J (``torque_model.py``).
        calibration: a :class:`Calibration` or its file (``hybrid-dyn calibrate``): the error bar's model term,
        the bandwidth and max_sigma calibrated on the user's own log for this torque model.
        torque_model: what tau_J holds beyond the rigid body, where not the params file's: a
        :class:`JointTorqueModel`, or None for nothing.
        residual: a hybrid: the folder of a residual GP fitted on the params file (``gp-residual-identified``),
        its correction added to the torque model.
        config: ``EstimatorConfig`` settings, a method's bandwidth parameter by its name (``momentum_gain=50.0``)."""
        method = TIP_FORCE_METHODS.lookup(method).name
        config = EstimatorConfig.from_settings(**config)
        if not isinstance(robot, Robot):
            robot = load_robot(robot, params=params, num_threads=1)
        if isinstance(torque_model, str) and torque_model == "params":
            torque_model = None if params is None else JointTorqueModel.from_params(params, robot)
        if residual is not None:
            if torque_model is None:
                raise UsageError("residual= corrects an identified model: give its file as params=")
            torque_model = torque_model.with_residual_gp(residual, robot)
        if payload is not None:
            robot = with_payload(robot, checked_payload(payload, rated_payload(robot.spec, config), robot.base_name))
        if calibration is not None and not isinstance(calibration, Calibration):
            calibration = Calibration.load(calibration)
        return cls(robot, method, config, torque_model=torque_model, calibration=calibration)

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
        self._model_sigma = None  # the error bar's model term at this call [N], where calibrated
        self._tau_sigma = None  # the error bar's torque-offset drift term at this call [N] (``torque_tare.py``)
        if self._tau_tare is not None:
            self._tau_tare.reset()
        if self._model_error is not None:
            self._model_error.reset()
        self.last_sigma = NO_SIGMA.copy()
        self._motion = 0.0  # this call's joint-acceleration norm [rad/s^2], for the error bar
        self._tared_at = None  # the call at which the base sensor's offset was last set
        self.window_problem = None  # why the last noise window was not trusted (a contact), until one is
        self.window_status = EstimatorStatus.CONTACT_AT_START  # what the warm-up says while window_problem stands
        self._windows = 0  # noise windows ended since the reset
        self._start_level = None  # the contact-free start's base residual [N], where a contact began in its window
        self._still_calls = 0  # consecutive calls at a standstill (the drift-following tare)
        self._base_lag = StandstillLag(3)  # the base follower's force lag [N], averaged over this standstill
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
        self._prev = None  # the last accepted sample (q, qd, base_wrench, tau_J, t): a short gap's start
        self.fusion_noise = None
        self.last_status = EstimatorStatus.WARMING_UP
        self.last_rejection = None  # why the latest rejected sample was refused (hold mode)

    @property
    def last_t(self) -> float | None:
        """The stamp of the last accepted sample [s] (None: none yet, or an untimed stream)."""
        return self._gate.last_t

    def continues(self, t: float) -> bool:
        """Whether a sample stamped t [s] goes on this stream: after its last accepted stamp, within a gap it
        bridges. A replay that starts a recording's next piece calls ``reset`` where it does not."""
        last = self._gate.last_t
        return last is not None and 0 < t - last <= self.config.bridge_seconds + 1.5 / self.config.call_hz

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
            q, qd, base_wrench, tau_J, t, lost = self._gate.accept(q, qd, base_wrench, tau_J, t)
        except EstimatorInputError as err:
            if self.config.on_bad_input == "raise":
                raise
            self.last_status = EstimatorStatus.INPUT_REJECTED
            self.last_rejection = str(err)
            return self._last_good.copy()
        if lost:  # a gap: bridged when short (its samples interpolated), else the dynamics restart
            if lost <= self._gate.bridge_ticks and self._prev is not None:
                self._bridge(lost, q, qd, base_wrench, tau_J, t)
            else:
                self._restart_dynamics((lost + 1) / self.config.call_hz)
        f = self._step(q, qd, base_wrench, tau_J, t)
        self._keep_sample(q, qd, base_wrench, tau_J, t)
        return f

    def _keep_sample(self, q, qd, base_wrench, tau_J, t) -> None:
        """Copy the accepted sample (the gate's arrays are overwritten by the next call): a gap's start."""
        q0, qd0, w0, tau0 = self._prev_arrays
        q0[:], qd0[:] = q, qd
        if base_wrench is not None:
            w0[:] = base_wrench
        if tau_J is not None:
            tau0[:] = tau_J
        self._prev = (q0, qd0, None if base_wrench is None else w0, None if tau_J is None else tau0, t)

    def _bridge(self, lost: int, q, qd, base_wrench, tau_J, t) -> None:
        """The ``lost`` ticks of a short gap, as the straight line from the last accepted sample to this one,
        through every step a sample takes (their estimates unseen): the filters and observers run on as
        though nothing were lost, with no new warm-up. A sensor absent at either end stays absent."""
        q0, qd0, w0, tau0, t0 = self._prev
        status, checks = self.last_status, self._grid_checks
        self._grid_checks = 0  # an interpolated q lies off the encoders' grid by construction: not checked
        for i in range(1, lost + 1):
            a = i / (lost + 1)
            self._step(q0 + a * (q - q0), qd0 + a * (qd - qd0),
                       None if w0 is None or base_wrench is None else w0 + a * (base_wrench - w0),
                       None if tau0 is None or tau_J is None else tau0 + a * (tau_J - tau0),
                       None if t is None else t0 + a * (t - t0))
        self.last_status, self._grid_checks = status, checks

    def _check_encoder_grid(self, q) -> None:
        """A q off the declared encoders' grid (by more than a thousandth of a count) is no quantized encoder's:
        the arm reports q and qd of its own, which the joint-state filter would only blur (a real Panda's log
        read nine times the phantom through it). Warned once (``EncoderModelWarning``, ``encoder_mismatch``),
        and q and qd are read as given from this call on."""
        self._grid_checks -= 1
        u = q / self.encoder_resolution
        off = np.abs(u - np.round(u))
        j = int(np.argmax(off))
        if off[j] <= 1e-3:
            return
        self.encoder_mismatch = (
            f"q[{j}] = {q[j]!r} rad lies {off[j]:.3f} counts off the grid of the declared encoder resolution "
            f"{self.encoder_resolution:g} rad: the arm reports q and qd of its own (libfranka's dq, KUKA's FRI, "
            "Baxter's joint_states); they are read as given from here on (encoder_resolution=0 says so from the start)")
        warnings.warn(self.encoder_mismatch, EncoderModelWarning, stacklevel=4)
        self._joint, self._grid_checks, self._joint_wait, self._motion = None, 0, 0, 0.0
        self.encoder_resolution = 0.0

    def _step(self, q, qd, base_wrench, tau_J, t) -> np.ndarray:
        """One accepted sample through the joint filter, the window and the method: the estimate, its status."""
        if t is not None:
            self._gate.last_t = t
            wrong_rate = self._gate.wrong_rate
        else:
            wrong_rate = self._rate.update(q, qd)
        if self._grid_checks:
            self._check_encoder_grid(q)
        self._qdd_joint = None
        if self._joint is not None:
            q, qd, qdd_joint = self._joint.step(q)
            self._qdd_joint = qdd_joint
            self._motion = self._error_bar.motion(qdd_joint, self._needs_qdd)
            if self._joint_wait:
                self._joint_wait -= 1
                return self._finish(self._last_good, True, wrong_rate, True, estimated=False)
        k = self._calls
        in_window = k < self._window_calls
        tare = self._tare
        taring = tare is not None and not tare.done
        # qdd only where the method (the window's tare, the model term) needs it: the observers need none.
        tau_tare = self._tau_tare
        qdd = self._qdd_filter.step(qd) if (self._needs_qdd or taring or self._model_qdd) else None
        tau_raw = tau_J
        if tau_J is not None and self.torque_model is not None:  # what the rigid body and a force explain
            tau_J = tau_J - self.torque_model.extra_torque(q, qd, qdd)
        tau_untared = tau_J
        if tau_tare is not None and tau_J is not None:
            if in_window:
                tau_tare.record(q, qd, tau_J)
            else:
                tau_J = tau_J - tau_tare.offset
                self._tau_sigma = tau_tare.drift_sigma(q, self._calls)
        if self._model_error is not None:  # the stated term reads the joint-state filter's qdd where no other is run
            self._model_sigma = self._model_error.update(q, qd, qdd if qdd is not None else self._qdd_joint)
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
                self._end_window()
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
        if tau_tare is not None and tau_J is not None:  # kalman-fusion follows both on one standstill
            self._follow_torque_offset(q, qd, tau_untared, f, counted=w_in is not None)
        self._judge(q, qd, qdd, w_in, base_wrench, tau_J, tau_raw)
        return self._finish(f, True, wrong_rate, usable)
