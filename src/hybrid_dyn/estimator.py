"""``estimate_tip_force()`` for control code: a streaming estimator, and its batch twin.

Control engineers call :class:`TipForceEstimator` once per tick of a 1 kHz loop::

    est = TipForceEstimator.analytic("panda", method="base-wrench")
    F = est.estimate_tip_force(q, qd, base_wrench=w, t=t)   # (3,) N, base frame
    est.last_status                                         # EstimatorStatus.OK, ...

What happens in one call:
1. ``_accept`` checks the sample before any state is touched (every method
   passes through it). A sample is rejected when
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
     a step off 1/call_hz by more than ``rate_tolerance`` (25 %). The filter and
     the observer are designed for that step, so a wrong ``call_hz`` (a 100 Hz
     recording fed to a 1 kHz estimator errs 10 N) or a gap (a lost tick) is
     refused rather than silently mis-filtered; 25 % lets a loop's jitter through
     and stops any rate off by 2x. A wrong rate is refused at every call; after a
     gap, the sample one period after the refused one resumes the stream: the
     filter and observers restart (a finished tare is kept) and it warms up anew.
   A rejected sample raises :class:`EstimatorInputError` (a ``ValueError`` that
   names the argument), or with ``on_bad_input="hold"`` returns the last good
   estimate with ``last_status = INPUT_REJECTED`` (``last_rejection`` says why).
   It never enters the filter, observer, tare, window or time state: the calls
   after it give exactly what they give without it.
2. Where the method needs it, qdd is estimated from qd causally, with the
   generator's filter (backward difference + 2nd-order Butterworth,
   ``sim/sensors.py``) at the call rate. Its cutoff, with ``qdd_cutoff_hz="auto"``
   (the default), is chosen at the end of the noise window (the first
   ``tare_seconds`` of calls) by :func:`auto_qdd_cutoff`: the highest cutoff at
   which the qdd estimate adds no more noise to the method's input than the
   sensor itself carries; before that, and without a window, 20 Hz. A learned
   model keeps the cutoff it was trained with.
3. The chosen method gives the force: the base-wrench method, the torque
   method, the joint-torque momentum observer, the base momentum observer
   (``base-momentum``: Newton's law for the whole robot, no qdd), the Kalman
   filter that fuses the base sensor and the joint torques (``kalman-fusion``:
   a call may bring either sensor or both), or a learned model (see ``load``).
   The two base-sensor observers start after the tare window, the Kalman filter
   with the sensors' model errors measured on it (``analytic/kalman.py``).
4. An estimate above ``max_tip_force`` (500 N) is returned with status
   FORCE_OUT_OF_RANGE ("out of range") and is not kept as the last good one.

Statuses (``last_status``), first match wins: INPUT_REJECTED (this sample was
refused; the last good estimate is returned), FORCE_OUT_OF_RANGE (the estimate
exceeds ``max_tip_force``), WARMING_UP (the filter, observer, tare or window
still fills), OUT_OF_RANGE (a learned model's input lies outside its training
range: "out of training range"), OK.

The base-wrench method (and a learned model whose analytic part it is) tares
the base sensor on the first ``tare_seconds`` of calls (``analytic/tare.py``):
nothing may touch the arm then, and the status is "warming up". A known
offset can be given instead with ``set_tare_offset``; ``reset`` tares anew.

Threading: an estimator holds per-stream state (filter, window, observer) and
preallocated buffers, so one instance must be used by one thread at a time;
use one estimator per control thread. ``estimate_tip_force()`` (the stateless
batch form) is thread-safe: it keeps one robot model per thread.
"""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np
from numba import njit
from scipy import signal

from .analytic.base_momentum import BaseMomentumObserver
from .analytic.kalman import FusionNoise, KalmanTipForce, noise_from_increments
from .analytic.momentum_observer import MomentumObserver
from .analytic.robot import InputError, Robot, load_robot
from .analytic.tare import TARE_SECONDS, StreamingTare, tare_samples, tared_base_wrench
from .analytic.tip_force import base_wrench_force_core, tip_force_from_base_wrench, tip_force_from_torques
from .analytic.estimators import ALIASES, estimator_name
from .errors import UsageError

# The analytic methods, by the estimators' one name (analytic/estimators.py; the older spellings
# base_wrench, torques, momentum, base_momentum, kalman_fusion are accepted), and the sensors each
# reads (beyond q, qd). kalman-fusion reads whichever of the two a call brings (at least one), the
# others need all they name.
METHODS = ("base-wrench", "torques-pinv", "momentum-observer", "base-momentum", "kalman-fusion")
METHOD_ALIASES = {a: c for a, c in ALIASES.items() if c in METHODS}
METHOD_SENSORS = {"base-wrench": ("base_wrench",), "torques-pinv": ("tau_J",), "momentum-observer": ("tau_J",),
                  "base-momentum": ("base_wrench",), "kalman-fusion": ("base_wrench", "tau_J")}
NEEDS_QDD = ("base-wrench", "torques-pinv", "learned")  # the others need none (but a tare window does)


class EstimatorInputError(InputError):
    """A sample given to the estimator is unusable: not numeric, wrong shape, NaN/inf, physically
    implausible, or out of step with the stream's time; the message names the argument."""


class EstimatorStatus(str, Enum):
    OK = "ok"
    WARMING_UP = "warming up"            # history not yet long enough (filter / observer / window / tare)
    INPUT_REJECTED = "input rejected"    # this call's sample was bad; the last good estimate was held
    FORCE_OUT_OF_RANGE = "out of range"  # the estimate exceeds EstimatorConfig.max_tip_force
    OUT_OF_RANGE = "out of training range"  # learned model: input outside its training distribution


# The statuses as plain names for the per-call path: an Enum member looked up on its class costs ~0.3 us.
_OK, _WARMING_UP, _OUT_OF_RANGE, _FORCE_OUT_OF_RANGE = (
    EstimatorStatus.OK, EstimatorStatus.WARMING_UP, EstimatorStatus.OUT_OF_RANGE, EstimatorStatus.FORCE_OUT_OF_RANGE)

G = 9.81  # m/s^2, for the base-wrench bound
DEFAULT_QDD_CUTOFF_HZ = 20.0  # the generator's acceleration filter (sim/sensors.py)


@dataclass(frozen=True)
class EstimatorConfig:
    """call_hz: the nominal call rate [Hz] the qdd filter (and observer) are designed for.
    qdd_cutoff_hz: the acceleration filter's cutoff [Hz] (the generator's default).
    on_bad_input: "raise" or "hold".
    momentum_gain: observer bandwidth K [1/s]; its warm-up lasts 5/K s (error < 1 %).
    tare_seconds: base-wrench method: the contact-free start used to tare the
    base sensor [s]; 0 = trust the sensor's zero.

    Plausibility bounds (see the module docstring):
    q_margin: how far q may lie outside the URDF position limits [rad]; encoders
    read a hair past a limit, 0.1 rad (6 deg) is no measurement of this arm.
    qd_margin, tau_margin: the fraction by which |qd| may exceed the velocity
    limit (TOML ``max_velocity``, else the URDF's) and |tau_J| the URDF effort
    limit; the arm's controller stops at the limits, so 50 % more is a fault.
    max_tip_force: bound on the estimate [N]. 500 N is beyond what the Panda's
    87 Nm shoulder can hold 0.2 m from its axis; a larger estimate is a fault
    (a corrupt sensor, a singular pose), not a contact. It also sets the
    base-wrench bound. Raise it for a stronger arm.
    rate_tolerance: the fraction by which a timed stream's step may differ
    from 1 / call_hz.
    fusion_force_rate: kalman-fusion's random-walk intensity of the tip force
    [N/sqrt(s)]: its bandwidth. The bench picks it per scenario on validation
    data (0.3-5 there: slow bells at 100 Hz to 1 ms steps at 1 kHz); 2 is a middle
    that follows a 1 s push without lag and keeps the noise near the sensor's.
    """

    call_hz: float = 1000.0
    qdd_cutoff_hz: float | str = "auto"
    on_bad_input: str = "raise"
    momentum_gain: float = 50.0
    tare_seconds: float = TARE_SECONDS
    q_margin: float = 0.1
    qd_margin: float = 0.5
    tau_margin: float = 0.5
    max_tip_force: float = 500.0
    rate_tolerance: float = 0.25
    fusion_force_rate: float = 2.0

    def __post_init__(self):
        if self.on_bad_input not in ("raise", "hold"):
            raise UsageError(f"on_bad_input must be 'raise' or 'hold', got {self.on_bad_input!r}")
        if not (isinstance(self.call_hz, (int, float)) and self.call_hz > 0):
            raise UsageError(f"call_hz must be > 0 [Hz], got {self.call_hz!r}")
        if self.qdd_cutoff_hz != "auto" and not (isinstance(self.qdd_cutoff_hz, (int, float))
                                                 and 0 < self.qdd_cutoff_hz < 0.5 * self.call_hz):
            raise UsageError(f"qdd_cutoff_hz must be 'auto' or lie in (0, call_hz / 2) [Hz], got {self.qdd_cutoff_hz!r}")
        for name in ("q_margin", "qd_margin", "tau_margin"):
            if not getattr(self, name) >= 0:
                raise UsageError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not self.max_tip_force > 0:
            raise UsageError(f"max_tip_force must be > 0 [N], got {self.max_tip_force!r}")
        if not self.fusion_force_rate > 0:
            raise UsageError(f"fusion_force_rate must be > 0 [N/sqrt(s)], got {self.fusion_force_rate!r}")
        if not 0 < self.rate_tolerance < 1:
            raise UsageError(f"rate_tolerance must lie in (0, 1), got {self.rate_tolerance!r}")


class CausalAccelerationFilter:
    """Streaming twin of ``sim.sensors.causal_acceleration``: per call one qd in, one qdd out.

    Backward difference, then a 2nd-order Butterworth low-pass in transposed
    direct form II. Both are linear, so one step is a single (4 x 4) @ (4 x nv)
    product on the stacked [qd; qd_prev; z1; z2], done by one compiled call
    (:func:`_filter_step`). Starts at rest (zero state), like a generated
    instance: the first call's difference is zero.
    """

    def __init__(self, nv: int, rate_hz: float, cutoff_hz: float):
        b, a = signal.butter(2, cutoff_hz, fs=rate_hz)
        b0, b1, b2 = b / a[0]
        _, a1, a2 = a / a[0]
        r = rate_hz  # x = r (qd - qd_prev)
        # y = b0 x + z1;  z1' = b1 x - a1 y + z2;  z2' = b2 x - a2 y;  qd_prev' = qd
        self._step_matrix = np.array([
            [b0 * r, -b0 * r, 1.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [(b1 - a1 * b0) * r, -(b1 - a1 * b0) * r, -a1, 1.0],
            [(b2 - a2 * b0) * r, -(b2 - a2 * b0) * r, -a2, 0.0],
        ])
        self.nv = nv
        self._state = np.zeros((4, nv))  # rows: qd (input slot), qd_prev, z1, z2
        self.reset()
        _filter_step(self._step_matrix, self._state.copy(), np.zeros(nv), False)  # compile now, not in a control call

    def reset(self) -> None:
        self._state[:] = 0.0
        self._started = False

    def step(self, qd: np.ndarray) -> np.ndarray:
        """One validated qd (nv,) [rad/s] in, a fresh qdd (nv,) [rad/s^2] out."""
        out = _filter_step(self._step_matrix, self._state, np.asarray(qd, dtype=float), self._started)
        self._started = True
        return out


@njit(cache=True)
def _filter_step(step_matrix, state, qd, started):  # pragma: no cover (compiled)
    """``CausalAccelerationFilter.step``: state[0] = qd (state[1] too on the first call: a zero first
    difference), then [qdd; state[1:]] = step_matrix @ state, column by column. Compiled, since the
    numpy form (an assignment, a 4 x 4 product and a copy) cost ~5 us a call."""
    nv = qd.shape[0]
    out = np.empty(nv)
    for j in range(nv):
        state[0, j] = qd[j]
        if not started:
            state[1, j] = qd[j]
        s0, s1, s2, s3 = state[0, j], state[1, j], state[2, j], state[3, j]
        m = step_matrix
        out[j] = m[0, 0] * s0 + m[0, 1] * s1 + m[0, 2] * s2 + m[0, 3] * s3
        for i in range(1, 4):
            state[i, j] = m[i, 0] * s0 + m[i, 1] * s1 + m[i, 2] * s2 + m[i, 3] * s3
    return out


def white_noise_rms(x: np.ndarray) -> np.ndarray:
    """Per-column RMS [unit of x] of the white noise on a smooth signal (N, k), from its second differences.

    For white noise of variance s^2, x[k+1] - 2 x[k] + x[k-1] has variance 6 s^2;
    a smooth signal adds only its third derivative times dt^2 (1e-7 of it at 1 kHz).
    The median of the squares (over 0.4549, the median of chi^2 with 1 dof) keeps a
    contact's single jump from inflating the estimate.
    """
    x = np.asarray(x, float)
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    return np.sqrt(np.median(d2**2, axis=0) / 0.4549 / 6.0)


def qdd_noise_gain(rate_hz: float, cutoff_hz: float) -> float:
    """Variance gain [1/s^2] from white noise on qd to the causal qdd estimate (difference + Butterworth)."""
    b, a = signal.butter(2, cutoff_hz, fs=rate_hz)
    n = int(max(64, 20 * rate_hz / cutoff_hz))  # the impulse response has decayed by then
    impulse = np.zeros(n)
    impulse[0] = 1.0
    h = signal.lfilter(b, a, rate_hz * np.diff(impulse, prepend=0.0))
    return float(np.sum(h**2))


def auto_qdd_cutoff(robot: Robot, rate_hz: float, q, qd, sensor, kind: str) -> float:
    """The acceleration filter's cutoff [Hz] chosen from noise measured on a window of samples.

    The rule: **the qdd estimate may add no more noise to the method's input than
    the sensor itself carries.** A higher cutoff lags less (the 2nd-order
    Butterworth delays by ~0.23 / f_c s, 11 ms at 20 Hz), so the highest cutoff on
    a grid from 5 Hz to 0.45 x rate that obeys the rule is taken:

    - base wrench (``kind="base_wrench"``): the force rows of the model wrench move
      with qdd through m J_com(q), so the qdd noise enters as
      m J_com diag(g s_qd^2) J_com^T; its per-axis RMS must not exceed the base
      sensor's per-axis force noise;
    - joint torques (``kind="tau_J"``): it enters as M(q) diag(g s_qd^2) M(q); its
      per-joint RMS must not exceed the torque sensors'.

    s_qd, the sensors' noise: :func:`white_noise_rms` on the window (the arm may
    move); g: :func:`qdd_noise_gain`; J_com and M at the window's mean pose.
    Noise-free data get the top of the grid.
    """
    q, qd, sensor = (np.asarray(x, float) for x in (q, qd, sensor))
    if len(q) < 8:
        raise InputError(f"the noise window needs at least 8 samples, got {len(q)}")
    s_qd = white_noise_rms(qd)
    q_mean = q.mean(axis=0)
    if kind == "base_wrench":
        s_sensor = float(np.sqrt(np.mean(white_noise_rms(sensor[:, :3]) ** 2)))
        import pinocchio as pin

        m_jcom = robot.total_mass * pin.jacobianCenterOfMass(robot.model, robot.model.createData(), q_mean)
        mapping, n_out = m_jcom, 3
    elif kind == "tau_J":
        s_sensor = float(np.sqrt(np.mean(white_noise_rms(sensor) ** 2)))
        mapping, n_out = robot.mass_matrix(q_mean), robot.nv
    else:
        raise ValueError(f"kind must be 'base_wrench' or 'tau_J', got {kind!r}")
    # RMS of the mapped noise per unit of g: sqrt(tr(A diag(s^2) A^T) / n_out).
    per_gain = float(np.sqrt(np.sum((mapping * s_qd) ** 2) / n_out))
    grid, gains = cutoff_grid(rate_hz)
    admissible = grid[np.sqrt(gains) * per_gain <= s_sensor]
    return float(admissible[-1]) if len(admissible) else float(grid[0])


@functools.lru_cache(maxsize=8)
def cutoff_grid(rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The cutoffs auto_qdd_cutoff chooses from [Hz] (5 Hz to 0.45 x rate) and their noise gains [1/s^2]:
    computed once per rate (the estimator does it when it is built, not in a control call)."""
    grid = np.geomspace(5.0, 0.45 * rate_hz, 48)
    return grid, np.array([qdd_noise_gain(rate_hz, float(fc)) for fc in grid])


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


class TipForceEstimator:
    """Streaming tip-force estimator; see the module docstring."""

    def __init__(self, robot: Robot, method: str, config: EstimatorConfig | None = None, model=None):
        self.robot = robot
        if method != "learned":
            method = estimator_name(method, METHODS, "estimator method")
        self.method = method
        self.config = config or EstimatorConfig()
        self.model = model
        c = self.config
        nv, dt = robot.nv, 1.0 / c.call_hz
        # "auto": a learned model keeps the cutoff it was trained with (load passes it); an analytic
        # method starts at the generator's 20 Hz and picks its own after the noise window.
        self._auto_cutoff = c.qdd_cutoff_hz == "auto"
        self._needs_qdd = method in NEEDS_QDD
        self._qdd_filter = CausalAccelerationFilter(nv, c.call_hz, DEFAULT_QDD_CUTOFF_HZ if self._auto_cutoff
                                                    else c.qdd_cutoff_hz)
        self.qdd_cutoff_hz = None if self._auto_cutoff else float(c.qdd_cutoff_hz)  # the cutoff in use [Hz]
        if self._auto_cutoff and method in NEEDS_QDD:
            cutoff_grid(float(c.call_hz))  # now, not in the call that closes the noise window
        self._observer = (MomentumObserver(robot, gain=c.momentum_gain, dt=dt) if method == "momentum-observer" else
                          BaseMomentumObserver(robot, gain=c.momentum_gain, dt=dt) if method == "base-momentum"
                          else None)
        # A learned model needs its network's inputs and its analytic prior's.
        model_fields = () if model is None else tuple(model.inputs) + tuple(
            getattr(model.model.prior, "fields", None) or ())
        sensors = METHOD_SENSORS.get(method, ())
        self._needs_wrench = "base_wrench" in sensors or "base_wrench" in model_fields
        self._needs_tau = "tau_J" in sensors or "tau_J" in model_fields
        # kalman-fusion degrades to the sensor a call brings; every other method needs all it reads.
        self._optional = frozenset(sensors) if method == "kalman-fusion" else frozenset()
        self._build_gate()
        self._tare = None
        if method in ("base-wrench", "base-momentum", "kalman-fusion") and c.tare_seconds > 0:
            self._tare = StreamingTare(robot, tare_samples(c.call_hz, c.tare_seconds))
        # The first tare_seconds of calls are the noise window: the tare's, the Kalman filter's
        # model errors and the automatic qdd cutoff are all measured on it (module docstring).
        self._window_calls = tare_samples(c.call_hz, c.tare_seconds) if (
            self._tare is not None or (self._auto_cutoff and method in NEEDS_QDD)) else 0
        self._observer_calls = int(math.ceil(5.0 / c.momentum_gain * c.call_hz))  # 5/K s: error < 1 %
        if method == "momentum-observer":
            self._warmup_calls = self._observer_calls
        elif method == "base-momentum":
            # The observer starts when the tare is done, so no pre-tare offset lingers in it.
            self._warmup_calls = self._window_calls + self._observer_calls
        elif method == "kalman-fusion":
            self._warmup_calls = self._window_calls + 1  # raised to the filter's settling once it is built
        elif self._window_calls:
            self._warmup_calls = max(2, self._window_calls)
        elif model is not None:
            self._warmup_calls = model.warmup_calls(c.call_hz)
        else:
            self._warmup_calls = 2  # the backward difference needs one previous qd
        self._warmup_initial = self._warmup_calls
        self._spec_noise = FusionNoise(force_rate=c.fusion_force_rate)
        self.reset()

    # ------------------------------------------------------------ factories
    @classmethod
    def analytic(cls, robot: str | Robot = "panda", method: str = "base-wrench", params=None,
                 **config) -> "TipForceEstimator":
        """A model-free estimator: method "base-wrench", "torques-pinv" (needs tau_J), "momentum-observer"
        (needs tau_J), "base-momentum" (needs base_wrench) or "kalman-fusion" (base_wrench, tau_J or both
        per call): the estimators' one name (``analytic/estimators.py``); the older spellings
        (``METHOD_ALIASES``: "base_wrench", "torques", "momentum", "base_momentum", "kalman_fusion") mean the same."""
        method = estimator_name(method, METHODS, "estimator method")
        if not isinstance(robot, Robot):
            robot = load_robot(robot, params=params, num_threads=1)
        return cls(robot, method, EstimatorConfig(**config))

    @classmethod
    def load(cls, model_dir, robot: str | None = None, runtime: str = "auto", **config) -> "TipForceEstimator":
        """An estimator around a trained tip-force model (seed net, residual net, ...).

        The model's analytic part (if any) comes with it. ``robot``: when given,
        a model trained for another robot is refused. ``runtime``: how the network
        runs: "auto" (the faster of onnxruntime and numba, timed at load), "onnx"
        (float32) or "numba" (float64: agrees with the batch form to round-off).
        """
        from .learn.streaming import StreamingModel

        model = StreamingModel.load(Path(model_dir), robot=robot, runtime=runtime)
        if config.get("qdd_cutoff_hz", "auto") == "auto":  # the network saw qdd through its training filter
            config = {**config, "qdd_cutoff_hz": model.qdd_cutoff_hz}
        cfg = EstimatorConfig(**config)
        return cls(model.robot, "learned", cfg, model=model)

    # --------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget all history (filter, observer, window, tare); the next calls warm up again."""
        if self._auto_cutoff:
            self._qdd_filter = CausalAccelerationFilter(self.robot.nv, self.config.call_hz, DEFAULT_QDD_CUTOFF_HZ)
            self.qdd_cutoff_hz = None
        self._kalman = None
        self._reset_dynamics()
        if self._tare is not None:
            self._tare.reset()
        self._calls = 0
        self._warmup_calls = self._warmup_initial
        self._probe = None  # kalman-fusion in the noise window: a specifications-only filter whose sums give
        self._probe_sums = []  # ... the sensors' increments call by call (no batch pass at the window's end)
        if self.method == "kalman-fusion":
            if self._tare is None:
                self._build_kalman(self._spec_noise)  # no noise window: the sensors' specifications
            else:
                self._probe = KalmanTipForce(self.robot, 1.0 / self.config.call_hz, self._spec_noise)
        self._window = []  # the noise window's samples (q, qd, raw base_wrench, tau_J)
        self._last_t = None  # set by the first call with t: from then on the stream is timed
        self._gap_t = None  # t of a sample refused for its step: the stream may resume from it
        self._last_good = np.zeros(3)
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

    # ---------------------------------------------------------------- call
    def _build_gate(self) -> None:
        """Precompute the plausibility box [lo, hi] of every value a call brings (module docstring).

        All needed inputs are copied into one preallocated vector x and checked
        at once, with no allocation, by the compiled :func:`_gate`: a value is
        inside when u = (x - lo) / (hi - lo) lies in [0, 1); NaN and inf make u
        NaN (or inf), so they fail too. An unbounded value (no limit in the
        description) gets lo = 1/(hi - lo) = 0: u = 0 when finite.
        """
        r, c, nv = self.robot, self.config, self.robot.nv
        v_max = np.asarray(r.spec.max_velocity or r.model.velocityLimit, float)
        tau_max = np.asarray(r.model.effortLimit, float)
        # Base wrench: the arm's weight, up to 2 g of inertial load, and the largest believable
        # contact; moments through the arm's reach (the sum of its joint and tool offsets:
        # by the triangle inequality no point of the chain lies farther from the base).
        force = c.max_tip_force + 3.0 * r.total_mass * G
        reach = sum(float(np.linalg.norm(r.model.jointPlacements[i].translation)) for i in range(1, r.model.njoints))
        reach += float(np.linalg.norm(r.model.frames[r.tool_frame_id].placement.translation))
        reach += float(np.linalg.norm(r._root_M_sensor.translation))
        boxes = [("q", 0, r.q_lower - c.q_margin, r.q_upper + c.q_margin, "rad",
                  f"the position limits +- {c.q_margin:g} rad"),
                 ("qd", 1, -v_max * (1 + c.qd_margin), v_max * (1 + c.qd_margin), "rad/s",
                  f"the velocity limits + {100 * c.qd_margin:g} %")]
        if self._needs_wrench:
            w = np.r_[np.full(3, force), np.full(3, force * reach)]
            boxes.append(("base_wrench", 2, -w, w, "N, Nm",
                          f"max_tip_force + 3 m g = {force:.0f} N per force axis, x reach {reach:.2f} m per moment axis"))
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
        self._period_tol = c.rate_tolerance * self._period
        self._max_force_sq = c.max_tip_force ** 2

    def _accept(self, q, qd, base_wrench, tau_J, t):
        """Check one sample before it touches any state (every method passes here).

        Returns (q, qd, base_wrench, tau_J, t): the arrays as float views of the
        preallocated sample vector (None where this estimator does not use them),
        t as a float or None. Raises EstimatorInputError naming the argument.
        """
        # The fast path: float64 1-D arrays go straight into the compiled gate (copy-in and box check in
        # one call); anything else (lists, other dtypes, wrong shapes, None) is converted and named by
        # _converted, then gated the same way. An input the estimator does not read is never looked at.
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
            raise EstimatorInputError(self._implausible())
        if self._optional and base_wrench is None and tau_J is None:
            raise EstimatorInputError("kalman-fusion needs base_wrench (6,) [N, Nm], tau_J (nv,) [Nm] or both")
        resumed = False
        if t is None:
            if self._last_t is not None:
                raise EstimatorInputError(f"t is missing, but this stream gave t before (last t = {self._last_t} s): "
                                          "once a stream is timed every call needs t; reset() starts anew")
        else:
            try:
                t = float(t)
            except (TypeError, ValueError):
                raise EstimatorInputError(f"t must be a number [s], got a {type(t).__name__}: {t!r:.60}") from None
            if not math.isfinite(t):
                raise EstimatorInputError(f"t must be finite, got {t}")
            if self._last_t is not None:
                dt = t - self._last_t
                if dt <= 0:
                    raise EstimatorInputError(f"time must increase: t={t} after t={self._last_t}")
                if abs(dt - self._period) > self._period_tol:
                    # One period after a sample refused for its step, the stream has resumed on
                    # rate after a gap: accept it and warm up anew. A wrong rate never gets here.
                    if self._gap_t is not None and abs(t - self._gap_t - self._period) <= self._period_tol:
                        resumed = True
                    else:
                        self._gap_t = t
                        raise EstimatorInputError(
                            f"t={t} s steps {dt:.6g} s from the last accepted sample, but call_hz="
                            f"{self.config.call_hz:g} expects {self._period:.6g} s +- "
                            f"{100 * self.config.rate_tolerance:g} %: a wrong call_hz, or a gap in the stream "
                            "(it resumes one period after this sample)")
        self._gap_t = None
        q, qd, views_w, views_tau = self._views
        if self._optional:  # an absent sensor stays None
            return q, qd, None if base_wrench is None else views_w, None if tau_J is None else views_tau, t, resumed
        return q, qd, views_w, views_tau, t, resumed

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

    def estimate_tip_force(self, q, qd, base_wrench=None, tau_J=None, t=None) -> np.ndarray:
        """One sample in, the tip force (3,) [N] in the base frame out; see ``last_status``."""
        try:
            q, qd, base_wrench, tau_J, t, resumed = self._accept(q, qd, base_wrench, tau_J, t)
        except EstimatorInputError as err:
            if self.config.on_bad_input == "raise":
                raise
            self.last_status = EstimatorStatus.INPUT_REJECTED
            self.last_rejection = str(err)
            return self._last_good.copy()
        if resumed:
            self._restart_dynamics()
        if t is not None:
            self._last_t = t
        in_window = self._calls < self._window_calls
        # qdd only where a method (or the noise window, or an unfinished tare) needs it: the observers need none.
        taring = self._tare is not None and not self._tare.done
        qdd = self._qdd_filter.step(qd) if (self._needs_qdd or in_window or taring) else None
        self._calls += 1
        if in_window and self._auto_cutoff and self._needs_qdd:
            self._window.append((q.copy(), qd.copy(), None if base_wrench is None else base_wrench.copy(),
                                 None if tau_J is None else tau_J.copy()))
        status = _OK
        tared = base_wrench
        if self._tare is not None and base_wrench is not None:
            tared = self._tare.update(q, qd, qdd, base_wrench)
        if in_window and self._probe is not None:
            # The raw wrench (the tare's offset is still moving): its final offset o is added back at the
            # window's end, exactly, since an increment is linear in it: d_tared = d_raw + R o dt.
            self._probe.step_unchecked(q, qd, base_wrench, tau_J)
            self._probe_sums.append((self._probe.sums.copy(), base_wrench is not None, tau_J is not None))
        if in_window and self._calls == self._window_calls:
            self._close_window()
        # The inputs are validated above: call the unchecked cores.
        if self.method == "base-wrench":
            f = base_wrench_force_core(self.robot, q, qd, qdd, tared)
        elif self.method == "torques-pinv":
            f = tip_force_from_torques(self.robot, q, qd, qdd, tau_J)
        elif self.method == "momentum-observer":
            f = self._observer.force(q, self._observer.step_unchecked(q, qd, tau_J))
        elif self.method == "base-momentum":
            # Stepped from the first sample after the tare window: a running offset would linger as e^-Kt.
            f = self._last_good if in_window else self._observer.force(q, self._observer.step_unchecked(q, qd, tared))
        elif self.method == "kalman-fusion":
            # The base sensor enters the filter only once it is tared (a sensor absent from the window tares late).
            w = tared if self._tare is None or self._tare.done else None
            f = self._last_good if self._kalman is None or in_window else self._kalman.step_unchecked(q, qd, w, tau_J)
        else:
            f, in_range = self.model.step(q, qd, qdd, base_wrench, tau_J, t)
            if not in_range:
                status = _OUT_OF_RANGE
        if self._calls < self._warmup_calls:
            status = _WARMING_UP
        if not f.dot(f) <= self._max_force_sq:  # NaN compares False: flagged too
            status = _FORCE_OUT_OF_RANGE  # returned, but never held as the last good estimate
        else:
            self._last_good = f
        self.last_status = status
        return f.copy()

    # ------------------------------------------------------- noise window
    def _close_window(self) -> None:
        """End of the noise window: pick the qdd cutoff, build the Kalman filter (once per stream)."""
        window = self._window
        self._window = []
        if self._auto_cutoff and self.method in NEEDS_QDD:
            q = np.array([x[0] for x in window])
            qd = np.array([x[1] for x in window])
            signal_ = np.array([x[2] if self.method == "base-wrench" else x[3] for x in window])
            self.qdd_cutoff_hz = auto_qdd_cutoff(self.robot, self.config.call_hz, q, qd, signal_,
                                                 "base_wrench" if self.method == "base-wrench" else "tau_J")
            # Replay the window through the new filter, so its state is as if it had run from the start.
            self._qdd_filter = CausalAccelerationFilter(self.robot.nv, self.config.call_hz, self.qdd_cutoff_hz)
            for x in window:
                self._qdd_filter.step(x[1])
        if self._probe is not None:
            # Each sensor's increments: the growth of its sum between consecutive calls that both had it.
            increments = {}
            for row, name in ((0, "base"), (1, "joint")):
                inc = [b[0][row] - a[0][row] for a, b in zip(self._probe_sums, self._probe_sums[1:])
                       if a[1 + row] and b[1 + row]]
                if len(inc) >= 2:
                    increments[name] = np.array(inc)
            if "base" in increments and self._tare is not None:
                increments["base"] = increments["base"] + (self.robot._root_from_sensor[:3] @ self._tare.offset
                                                           ) / self.config.call_hz
            self._probe, self._probe_sums = None, []
            self._build_kalman(noise_from_increments(self.robot, 1.0 / self.config.call_hz, increments,
                                                     self._spec_noise))

    def _build_kalman(self, noise: FusionNoise) -> None:
        self._kalman = KalmanTipForce(self.robot, 1.0 / self.config.call_hz, noise)
        self.fusion_noise = noise
        # Warm up until the fused filter's transient is below 1 % (its slowest closed-loop mode).
        rho = max(abs(np.linalg.eigvals(self._kalman.filters[("base", "joint")].closed_loop)))
        settle = int(math.ceil(math.log(0.01) / math.log(rho))) if 0 < rho < 1 else 1
        self._warmup_calls = self._calls + settle

    def _reset_dynamics(self) -> None:
        """The qdd filter, the observers and a learned model's window back to rest."""
        self._qdd_filter.reset()
        for part in (self._observer, self._kalman, self.model):
            if part is not None:
                part.reset()

    def _restart_dynamics(self) -> None:
        """After a gap in a timed stream: the filter and observers restart; a finished tare is kept."""
        self._reset_dynamics()
        self._warmup_calls = max(self._warmup_calls, self._calls + self._warmup_initial - self._window_calls)


# ------------------------------------------------------------------ batch form
_thread_local = threading.local()


def _robot_for_thread(name: str) -> Robot:
    robots = getattr(_thread_local, "robots", None)
    if robots is None:
        robots = _thread_local.robots = {}
    if name not in robots:
        robots[name] = load_robot(name, num_threads=1)
    return robots[name]


def estimate_tip_force(q, qd, qdd, base_wrench=None, tau_J=None, model=None, robot: str = "panda",
                       tare_samples: int = 0) -> np.ndarray:
    """Stateless batch tip-force estimate (N, 3) [N] for offline use.

    model=None: the analytic base-wrench method (needs base_wrench (N, 6));
    tare_samples > 0 tares the base sensor on that many contact-free first
    samples (``analytic/tare.py``), as the streaming estimator does.
    model: a trained model directory (or a loaded model); its inputs decide
    which of base_wrench / tau_J are needed. Thread-safe.
    """
    if model is None:
        if base_wrench is None:
            raise InputError("the analytic base-wrench method needs base_wrench (N, 6)")
        r = _robot_for_thread(robot)
        if tare_samples > 0:
            base_wrench = tared_base_wrench(r, np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd),
                                            np.atleast_2d(base_wrench), tare_samples)
        return tip_force_from_base_wrench(r, q, qd, qdd, base_wrench)
    from .learn.streaming import StreamingModel

    m = model if isinstance(model, StreamingModel) else StreamingModel.load(Path(model))
    return m.predict_arrays(q, qd, qdd, base_wrench, tau_J)
