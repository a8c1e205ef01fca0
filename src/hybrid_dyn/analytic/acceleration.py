"""The causal joint-acceleration estimate of a stream, and its cutoff chosen from the data.

qdd is estimated from qd as a real arm's controller does it: a backward
difference, then a 2nd-order Butterworth low-pass, both causal. One compiled
kernel serves the generator (:func:`causal_acceleration` over a recorded run,
re-exported by ``sim/sensors.py``) and the streaming estimator
(:class:`CausalAccelerationFilter`, one call per sample).
Its cutoff trades noise against lag; :func:`auto_qdd_cutoff` picks it by the
bandwidth rule of ``analytic/bandwidth.py`` from the noise measured on a window.

Every filter design (``scipy.signal.butter``) happens in :func:`cutoff_grid`,
once per rate, when an estimator is built: a stream that changes its cutoff
takes a precomputed design (:meth:`CausalAccelerationFilter.from_design`), so
no control call designs a filter.
"""
from __future__ import annotations

import functools

import numpy as np
from numba import njit
from scipy import signal

from .robot import InputError, Robot

DEFAULT_QDD_CUTOFF_HZ = 20.0  # the generator's acceleration filter [Hz] (GeneratorConfig.qdd_cutoff_hz)
TOP_CUTOFF_FRACTION = 0.45  # the highest cutoff any filter here is designed at, as a fraction of the rate


def default_qdd_cutoff(rate_hz: float) -> float:
    """The acceleration filter's cutoff [Hz] before a method's bandwidth is chosen (the noise window):
    DEFAULT_QDD_CUTOFF_HZ, or 0.45 x the rate where that is not below the Nyquist frequency (a 20 Hz
    log, as the reference study's, has no 20 Hz filter)."""
    return min(DEFAULT_QDD_CUTOFF_HZ, TOP_CUTOFF_FRACTION * float(rate_hz))


def butterworth(dt: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The 2nd-order Butterworth low-pass (b, a) at a sample step dt [s] (the one filter design)."""
    b, a = signal.butter(2, cutoff_hz, fs=1.0 / dt)
    return b / a[0], a / a[0]


def causal_acceleration(qd_measured: np.ndarray, dt: float, cutoff_hz: float = DEFAULT_QDD_CUTOFF_HZ) -> np.ndarray:
    """qdd estimate [rad/s^2] (T, nv) from measured qd [rad/s] (T, nv) sampled every ``dt`` [s].

    The signal is assumed to start at rest (zero initial filter state), as every
    generated instance does. The same kernel as the stream's (:class:`CausalAccelerationFilter`),
    run over every row: bit for bit what ``scipy.signal.lfilter`` gives on the difference
    (``tests/estimator/test_streaming.py`` holds it to that).
    """
    qd = np.asarray(qd_measured, float)
    rows = np.ascontiguousarray(qd.reshape(len(qd), -1))  # one joint's (T,) too
    b, a = butterworth(dt, cutoff_hz)
    out = np.empty_like(rows)
    if len(rows):
        _filter_run(b, a, float(dt), np.zeros((3, rows.shape[1])), rows, False, out)
    return out.reshape(qd.shape)


class CausalAccelerationFilter:
    """The causal acceleration estimate of a stream: per call one qd in, one qdd out.

    Backward difference, then a 2nd-order Butterworth low-pass in transposed
    direct form II, in one compiled call (:func:`_filter_step`): the kernel of
    :func:`causal_acceleration`, so a stream at rate r gives what the batch form
    gives at dt = 1 / r, bit for bit. Starts at rest (zero state), like a
    generated instance: the first call's difference is zero.
    """

    def __init__(self, nv: int, rate_hz: float, cutoff_hz: float, design: tuple | None = None):
        self.dt = 1.0 / float(rate_hz)
        self._b, self._a = butterworth(self.dt, cutoff_hz) if design is None else design
        self.nv = nv
        self.cutoff_hz = float(cutoff_hz)
        self._state = np.zeros((3, nv))  # rows: qd_prev, z1, z2
        self.reset()
        # Compile now, not in a control call.
        _filter_step(self._b, self._a, self.dt, self._state.copy(), np.zeros(nv), False)
        _filter_run(self._b, self._a, self.dt, self._state.copy(), np.zeros((1, nv)), False, np.zeros((1, nv)))

    @classmethod
    def from_design(cls, nv: int, rate_hz: float, index: int) -> "CausalAccelerationFilter":
        """The filter at ``cutoff_grid(rate_hz)[0][index]``, from the precomputed design (no design now)."""
        grid, _, designs, _ = cutoff_grid(float(rate_hz))
        return cls(nv, rate_hz, float(grid[index]), designs[index])

    def reset(self) -> None:
        self._state[:] = 0.0
        self._started = False

    def step(self, qd: np.ndarray) -> np.ndarray:
        """One validated qd (nv,) [rad/s] in, a fresh qdd (nv,) [rad/s^2] out."""
        out = _filter_step(self._b, self._a, self.dt, self._state, np.asarray(qd, dtype=float), self._started)
        self._started = True
        return out

    def replay(self, qd: np.ndarray) -> np.ndarray | None:
        """Step through rows of qd (n, nv) in one compiled call (a window's replay); returns the last qdd."""
        if not len(qd):
            return None
        qd = np.ascontiguousarray(qd, dtype=float)
        out = np.empty_like(qd)
        _filter_run(self._b, self._a, self.dt, self._state, qd, self._started, out)
        self._started = True
        return out[-1]


@njit(cache=True, inline="always")
def _filter_sample(b, a, dt, state, j, qd, first):  # pragma: no cover (compiled)
    """One sample of joint j: x = (qd - qd_prev) / dt (0 on the first), then transposed direct form II,
    in scipy.signal.lfilter's order of operations (so the two agree bit for bit). Returns qdd."""
    x = 0.0 if first else (qd - state[0, j]) / dt
    y = state[1, j] + b[0] * x
    state[1, j] = state[2, j] + x * b[1] - y * a[1]
    state[2, j] = x * b[2] - y * a[2]
    state[0, j] = qd
    return y


@njit(cache=True)
def _filter_step(b, a, dt, state, qd, started):  # pragma: no cover (compiled)
    """``CausalAccelerationFilter.step``: one row. Compiled, since the numpy form cost ~5 us a call."""
    nv = qd.shape[0]
    out = np.empty(nv)
    for j in range(nv):
        out[j] = _filter_sample(b, a, dt, state, j, qd[j], not started)
    return out


@njit(cache=True)
def _filter_run(b, a, dt, state, qd_rows, started, out):  # pragma: no cover (compiled)
    """``_filter_step`` over the rows of qd_rows (n, nv) into out (n, nv): a batch, or a window's replay."""
    for k in range(qd_rows.shape[0]):
        first = not (started or k > 0)
        for j in range(qd_rows.shape[1]):
            out[k, j] = _filter_sample(b, a, dt, state, j, qd_rows[k, j], first)
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
    sq = np.ascontiguousarray((d2 * d2).T)  # one row per column: np.partition along rows is ~4x np.median's speed
    m = sq.shape[1]
    if m % 2:
        med = np.partition(sq, m // 2, axis=1)[:, m // 2]
    else:  # the median of an even count: the mean of the two middle values, as np.median
        part = np.partition(sq, m // 2, axis=1)  # one kth: partitioning at two costs 4x more
        med = 0.5 * (part[:, : m // 2].max(axis=1) + part[:, m // 2])
    return np.sqrt(med / 0.4549 / 6.0)


def qdd_noise_gain(rate_hz: float, cutoff_hz: float) -> float:
    """Variance gain [1/s^2] from white noise on qd to the causal qdd estimate (difference + Butterworth)."""
    b, a = signal.butter(2, cutoff_hz, fs=rate_hz)
    n = int(max(64, 20 * rate_hz / cutoff_hz))  # the impulse response has decayed by then
    impulse = np.zeros(n)
    impulse[0] = 1.0
    h = signal.lfilter(b, a, rate_hz * np.diff(impulse, prepend=0.0))
    return float(np.sum(h**2))


def filter_settle_calls(rate_hz: float, cutoff_hz: float) -> int:
    """Calls until the filter's impulse response stays below 1 % of its peak (its transient after a restart)."""
    b, a = signal.butter(2, cutoff_hz, fs=rate_hz)
    n = int(max(64, 20 * rate_hz / cutoff_hz))
    impulse = np.zeros(n)
    impulse[0] = 1.0
    h = np.abs(signal.lfilter(b, a, impulse))
    return int(np.flatnonzero(h > 0.01 * h.max())[-1]) + 2  # + the difference's previous sample


@functools.lru_cache(maxsize=8)
def cutoff_grid(rate_hz: float) -> tuple[np.ndarray, np.ndarray, tuple, np.ndarray]:
    """The cutoffs auto_qdd_cutoff chooses from [Hz] (5 Hz to 0.45 x rate), their noise gains [1/s^2],
    their filter designs ((b, a) at dt = 1 / rate) and settling times [calls]: computed once per rate, when an
    estimator is built, never in a control call."""
    grid = np.geomspace(5.0, TOP_CUTOFF_FRACTION * rate_hz, 48)
    gains = np.array([qdd_noise_gain(rate_hz, float(fc)) for fc in grid])
    designs = tuple(butterworth(1.0 / rate_hz, float(fc)) for fc in grid)
    settle = np.array([filter_settle_calls(rate_hz, float(fc)) for fc in grid])
    return grid, gains, designs, settle


def qdd_noise_per_gain(robot: Robot, q_mean, s_qd, kind: str, data=None) -> float:
    """RMS [N or Nm] per unit of qdd noise gain that qd noise s_qd (nv,) [rad/s] puts into the method's
    input: through m J_com (``base_wrench``, per force axis) or M(q) (``tau_J``, per joint), at q_mean.
    data: a Pinocchio Data of robot.model to use (one is made without it)."""
    import pinocchio as pin

    data = robot.model.createData() if data is None else data
    if kind == "base_wrench":
        mapping = robot.total_mass * pin.jacobianCenterOfMass(robot.model, data, q_mean)
    elif kind == "tau_J":
        mapping = pin.crba(robot.model, data, q_mean)
        mapping = np.triu(mapping) + np.triu(mapping, 1).T  # crba fills the upper triangle
    else:
        raise ValueError(f"kind must be 'base_wrench' or 'tau_J', got {kind!r}")
    return float(np.sqrt(np.sum((mapping * np.asarray(s_qd)) ** 2) / len(mapping)))


def cutoff_index(rate_hz: float, per_gain: float, s_sensor: float) -> int:
    """The bandwidth rule for the qdd cutoff: the index of the highest grid cutoff at which the qdd
    estimate's noise sqrt(g) per_gain is at most the sensor's own s_sensor (then the method's input
    carries at most twice the sensor's noise variance); the lowest cutoff when none qualifies."""
    _, gains, _, _ = cutoff_grid(float(rate_hz))
    ok = np.flatnonzero(np.sqrt(gains) * per_gain <= s_sensor)
    return int(ok[-1]) if len(ok) else 0


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
    if kind not in ("base_wrench", "tau_J"):
        raise ValueError(f"kind must be 'base_wrench' or 'tau_J', got {kind!r}")
    s_sensor = float(np.sqrt(np.mean(white_noise_rms(sensor[:, :3] if kind == "base_wrench" else sensor) ** 2)))
    per_gain = qdd_noise_per_gain(robot, q.mean(axis=0), white_noise_rms(qd), kind)
    return float(cutoff_grid(float(rate_hz))[0][cutoff_index(rate_hz, per_gain, s_sensor)])
