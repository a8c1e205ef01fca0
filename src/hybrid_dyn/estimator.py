"""``estimate_tip_force()`` for control code: a streaming estimator, and its batch twin.

Control engineers call :class:`TipForceEstimator` once per tick of a 1 kHz loop::

    est = TipForceEstimator.analytic("panda", method="base_wrench")
    F = est.estimate_tip_force(q, qd, base_wrench=w, t=t)   # (3,) N, base frame
    est.last_status                                         # EstimatorStatus.OK, ...

What happens in one call:
1. The inputs are checked (shape, NaN/inf, monotonic time). A bad sample raises
   :class:`EstimatorInputError` (a ``ValueError``), or with
   ``on_bad_input="hold"`` returns the last good estimate and sets
   ``last_status = INPUT_REJECTED``. Garbage is never returned silently, and a
   rejected sample does not enter the estimator's history.
2. qdd is estimated from qd causally, with the generator's filter (backward
   difference + 2nd-order Butterworth, ``sim/sensors.py``) at the call rate.
3. The chosen method gives the force: the base-wrench method, the torque
   method, the momentum observer, or a learned model (see ``load``).

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

import math
import threading
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

import numpy as np
from scipy import signal

from .analytic.momentum_observer import MomentumObserver
from .analytic.robot import InputError, Robot, load_robot
from .analytic.tare import TARE_SECONDS, StreamingTare, tare_samples, tared_base_wrench
from .analytic.tip_force import base_wrench_force_core, tip_force_from_base_wrench, tip_force_from_torques

METHODS = ("base_wrench", "torques", "momentum")


class EstimatorInputError(InputError):
    """A sample given to the estimator is unusable: wrong shape, NaN/inf, time going backwards."""


class EstimatorStatus(str, Enum):
    OK = "ok"
    WARMING_UP = "warming up"            # history not yet long enough (filter / observer / window)
    INPUT_REJECTED = "input rejected"    # this call's sample was bad; the last good estimate was held
    OUT_OF_RANGE = "out of training range"  # learned model: input outside its training distribution


@dataclass(frozen=True)
class EstimatorConfig:
    """call_hz: the nominal call rate [Hz] the qdd filter (and observer) are designed for.
    qdd_cutoff_hz: the acceleration filter's cutoff [Hz] (the generator's default).
    on_bad_input: "raise" or "hold".
    momentum_gain: observer bandwidth K [1/s]; its warm-up lasts 5/K s (error < 1 %).
    tare_seconds: base-wrench method: the contact-free start used to tare the
    base sensor [s]; 0 = trust the sensor's zero.
    """

    call_hz: float = 1000.0
    qdd_cutoff_hz: float = 20.0
    on_bad_input: str = "raise"
    momentum_gain: float = 50.0
    tare_seconds: float = TARE_SECONDS

    def __post_init__(self):
        if self.on_bad_input not in ("raise", "hold"):
            raise ValueError(f"on_bad_input must be 'raise' or 'hold', got {self.on_bad_input!r}")
        if self.call_hz <= 0 or not (0 < self.qdd_cutoff_hz < 0.5 * self.call_hz):
            raise ValueError("need call_hz > 0 and 0 < qdd_cutoff_hz < call_hz / 2")


class CausalAccelerationFilter:
    """Streaming twin of ``sim.sensors.causal_acceleration``: per call one qd in, one qdd out.

    Backward difference, then a 2nd-order Butterworth low-pass in transposed
    direct form II. Both are linear, so one step is a single (4 x 4) @ (4 x nv)
    product on the stacked [qd; qd_prev; z1; z2]: one numpy call instead of a
    dozen at control-loop sizes. Starts at rest (zero state), like a generated
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

    def reset(self) -> None:
        self._state[:] = 0.0
        self._started = False

    def step(self, qd: np.ndarray) -> np.ndarray:
        state = self._state
        state[0] = qd
        if not self._started:
            state[1] = qd  # zero first difference
            self._started = True
        out = self._step_matrix @ state
        state[1:] = out[1:]
        return out[0]


class TipForceEstimator:
    """Streaming tip-force estimator; see the module docstring."""

    def __init__(self, robot: Robot, method: str, config: EstimatorConfig | None = None, model=None):
        self.robot = robot
        self.method = method
        self.config = config or EstimatorConfig()
        self.model = model
        nv = robot.nv
        self._qdd_filter = CausalAccelerationFilter(nv, self.config.call_hz, self.config.qdd_cutoff_hz)
        self._observer = MomentumObserver(robot, gain=self.config.momentum_gain, dt=1.0 / self.config.call_hz) \
            if method == "momentum" else None
        self._needs_wrench = method == "base_wrench" or (model is not None and "base_wrench" in model.inputs)
        self._needs_tau = method in ("torques", "momentum") or (model is not None and "tau_J" in model.inputs)
        self._tare = None
        if method == "base_wrench" and self.config.tare_seconds > 0:
            self._tare = StreamingTare(robot, tare_samples(self.config.call_hz, self.config.tare_seconds))
        if method == "momentum":
            self._warmup_calls = int(math.ceil(5.0 / self.config.momentum_gain * self.config.call_hz))
        elif self._tare is not None:
            self._warmup_calls = max(2, self._tare.n_calls)
        elif model is not None:
            self._warmup_calls = model.warmup_calls(self.config.call_hz)
        else:
            self._warmup_calls = 2  # the backward difference needs one previous qd
        self.reset()

    # ------------------------------------------------------------ factories
    @classmethod
    def analytic(cls, robot: str | Robot = "panda", method: str = "base_wrench", params=None,
                 **config) -> "TipForceEstimator":
        """A model-free estimator: method "base_wrench", "torques" (needs tau_J) or "momentum" (needs tau_J)."""
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
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
        cfg = EstimatorConfig(**{"qdd_cutoff_hz": model.qdd_cutoff_hz, **config})
        return cls(model.robot, "learned", cfg, model=model)

    # --------------------------------------------------------------- state
    def reset(self) -> None:
        """Forget all history (filter, observer, window); the next calls warm up again."""
        self._qdd_filter.reset()
        if self._observer is not None:
            self._observer.reset()
        if self.model is not None:
            self.model.reset()
        if self._tare is not None:
            self._tare.reset()
        self._calls = 0
        self._last_t = None
        self._last_good = np.zeros(3)
        self.last_status = EstimatorStatus.WARMING_UP

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
    def _check(self, q, qd, base_wrench, tau_J, t):
        r = self.robot
        try:
            q = r._single(q, "q")
            qd = r._single(qd, "qd")
            if self._needs_wrench:
                if base_wrench is None:
                    raise InputError("this estimator needs base_wrench (6,) [N, Nm]")
                base_wrench = np.asarray(base_wrench, dtype=float)
                if base_wrench.shape != (6,) or not math.isfinite(base_wrench.dot(base_wrench)):
                    raise InputError(f"base_wrench must be 6 finite values, got {base_wrench!r}")
            if self._needs_tau:
                if tau_J is None:
                    raise InputError(f"this estimator needs tau_J ({r.nv},) [Nm]")
                tau_J = r._single(tau_J, "tau_J")
            if t is not None:
                t = float(t)
                if not math.isfinite(t):
                    raise InputError(f"t must be finite, got {t}")
                if self._last_t is not None and t <= self._last_t:
                    raise InputError(f"time must increase: t={t} after t={self._last_t}")
        except InputError as err:
            raise EstimatorInputError(str(err)) from None
        return q, qd, base_wrench, tau_J, t

    def estimate_tip_force(self, q, qd, base_wrench=None, tau_J=None, t=None) -> np.ndarray:
        """One sample in, the tip force (3,) [N] in the base frame out; see ``last_status``."""
        try:
            q, qd, base_wrench, tau_J, t = self._check(q, qd, base_wrench, tau_J, t)
        except EstimatorInputError:
            if self.config.on_bad_input == "raise":
                raise
            self.last_status = EstimatorStatus.INPUT_REJECTED
            return self._last_good.copy()
        self._last_t = t
        # The observer needs no acceleration: skip the filter on that path.
        qdd = None if self.method == "momentum" else self._qdd_filter.step(qd)
        self._calls += 1
        status = EstimatorStatus.OK
        # The inputs are validated above: call the unchecked cores.
        if self.method == "base_wrench":
            if self._tare is not None:
                base_wrench = self._tare.update(q, qd, qdd, base_wrench)
            f = base_wrench_force_core(self.robot, q, qd, qdd, base_wrench)
        elif self.method == "torques":
            f = tip_force_from_torques(self.robot, q, qd, qdd, tau_J)
        elif self.method == "momentum":
            f = self._observer.force(q, self._observer.step_unchecked(q, qd, tau_J))
        else:
            f, in_range = self.model.step(q, qd, qdd, base_wrench, tau_J, t)
            if not in_range:
                status = EstimatorStatus.OUT_OF_RANGE
        if self._calls < self._warmup_calls:
            status = EstimatorStatus.WARMING_UP
        self.last_status = status
        self._last_good = f
        return f.copy()


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
