"""Joint state from encoders: q, qd and qdd from quantized positions, by one Kalman filter.

A real arm reports q quantized to its encoder's resolution and a velocity the drive makes from it
(libfranka's ``dq``: the difference of the quantized q). At standstill such an encoder reads a
constant; in motion its error is close to uniform in [-res/2, res/2] and white, so the difference
carries noise of about res / dt (0.01 rad/s at 1e-5 rad and 1 kHz): twenty times what a white-noise
model of the same encoder would say, and nothing a window at standstill can measure.

:class:`JointStateFilter` is the textbook answer: per joint, a constant-acceleration model (state
q, qd, qdd; white jerk of spectral density ``s`` [rad^2/s^5]) observed through q with the
quantization's variance res^2 / 12. Its steady-state gain solves the discrete algebraic Riccati
equation once, at construction; a call is one compiled predict-and-correct pass over the joints. The jerk density is set by a bandwidth ``omega`` [rad/s]:
``s = r omega^6`` with r = R dt the measurement's noise density, the corner at which the filter's
position tracking and its measurement noise trade (for a triple integrator the steady-state filter's
closed-loop poles sit at about omega).

:func:`joint_state_noise` predicts, from the same Riccati solution, the white noise the estimate of
qd and qdd carries in motion: what the bandwidth rules of ``bandwidth.py`` use instead of the noise
a standstill window shows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import solve_discrete_are, solve_discrete_lyapunov

# The filter's default bandwidth [rad/s]: 1/omega (~3 ms) is its lag; on the hardware stream of
# benchmarks/tip_force_stream.py (1e-5 rad, 1 kHz) 300 rad/s served the observers best of 80-800.
DEFAULT_OMEGA = 300.0


def quantization_variance(resolution: float) -> float:
    """Variance [rad^2] of a uniform quantization error of step ``resolution`` [rad]: res^2 / 12."""
    return float(resolution) ** 2 / 12.0


def _model(dt: float):
    A = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    Qs = np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6], [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                   [dt ** 3 / 6, dt ** 2 / 2, dt]])  # white jerk of unit density, integrated over dt
    return A, Qs, np.array([[1.0, 0.0, 0.0]])


@dataclass(frozen=True)
class JointStateDesign:
    """One steady-state design: rate [Hz], position measurement variance R [rad^2], bandwidth omega [rad/s];
    the one-step transition A (3, 3) and the steady-state gain (3,) on (q, qd, qdd)."""

    rate_hz: float
    variance: float
    omega: float
    A: np.ndarray
    gain: np.ndarray

    @classmethod
    def solve(cls, rate_hz: float, variance: float, omega: float = DEFAULT_OMEGA) -> "JointStateDesign":
        dt = 1.0 / float(rate_hz)
        A, Qs, H = _model(dt)
        R = max(float(variance), 1e-30)
        s = R * dt * float(omega) ** 6
        # Solved in per-sample units (q, qd dt, qdd dt^2) and per unit R: the raw problem spans 1e-30 to 1.
        T = np.diag([1.0, dt, dt * dt])
        P1 = solve_discrete_are((T @ A @ np.linalg.inv(T)).T, H.T, T @ (s * Qs) @ T / R, np.array([[1.0]]))
        Ti = np.linalg.inv(T)
        P_prior = R * Ti @ P1 @ Ti
        K = (P_prior @ H.T / (H @ P_prior @ H.T + R)).ravel()
        return cls(float(rate_hz), R, float(omega), A, K)


def joint_state_noise(design: JointStateDesign) -> tuple[float, float]:
    """The standard deviation of the filter's qd [rad/s] and qdd [rad/s^2] under its measurement noise
    alone (its posterior covariance with no process noise would be zero, so this runs the filter's
    closed loop on white measurement noise: sum of squared impulse responses)."""
    H = np.array([[1.0, 0.0, 0.0]])
    closed = (np.eye(3) - np.outer(design.gain, H)) @ design.A
    # x_{k+1} = closed x_k + K v_{k+1}: the stationary covariance solves a discrete Lyapunov equation.
    dt = 1.0 / design.rate_hz
    T = np.diag([1.0, dt, dt * dt])  # per-sample units, as in ``solve``
    k = T @ design.gain
    cov = solve_discrete_lyapunov(T @ closed @ np.linalg.inv(T), np.outer(k, k))
    return (float(math.sqrt(design.variance * cov[1, 1])) / dt,
            float(math.sqrt(design.variance * cov[2, 2])) / (dt * dt))


class JointStateFilter:
    """q (nv,) [rad] per call -> (q, qd, qdd) estimates; see the module docstring. ``reset`` starts over
    at the next sample (its q, zero velocity and acceleration)."""

    def __init__(self, nv: int, design: JointStateDesign):
        self.nv, self.design = nv, design
        self._A, self._K = design.A, design.gain[:, None]
        self.qd_noise, self.qdd_noise = joint_state_noise(design)  # [rad/s], [rad/s^2] in motion
        self.x = np.zeros((3, nv))
        self.reset()
        _step(self._A, design.gain, np.zeros((3, nv)), np.zeros(nv), True)  # compile now, not in a control cycle

    def reset(self) -> None:
        self._started = False

    def step(self, q: np.ndarray):
        """One sample q (nv,) [rad] -> views of the estimates (q, qd, qdd), valid until the next call."""
        _step(self._A, self.design.gain, self.x, q, self._started)
        self._started = True
        return self.x[0], self.x[1], self.x[2]

    def settle_calls(self) -> int:
        """Calls from a start (at rest) until a motion's qd and qdd have converged: 8 / omega [s]."""
        return int(math.ceil(8.0 / self.design.omega * self.design.rate_hz))

    def coast(self, steps: int, max_steps: int = 50) -> None:
        """``steps`` samples lost: predict across them, or start over when more than ``max_steps`` were
        (beyond ~50 ms a constant acceleration is no prediction of an arm's motion)."""
        if steps > max_steps or not self._started:
            self.reset()
            return
        for _ in range(max(steps, 0)):
            self.x[:] = self._A @ self.x

    def run(self, q: np.ndarray) -> np.ndarray:
        """``step`` over (n, nv) from a start: (3, n, nv) = q, qd, qdd estimates."""
        self.reset()
        out = np.empty((3,) + np.shape(q))
        for k, row in enumerate(np.asarray(q, float)):
            out[:, k] = np.stack(self.step(row))
        return out


@njit(cache=True)
def _step(A, K, x, q, started):  # pragma: no cover (compiled)
    """x = A x, then x += K (q - x[0]), per joint; a start takes q with zero velocity and acceleration."""
    for j in range(q.shape[0]):
        if not started:
            x[0, j], x[1, j], x[2, j] = q[j], 0.0, 0.0
            continue
        p0 = A[0, 0] * x[0, j] + A[0, 1] * x[1, j] + A[0, 2] * x[2, j]
        p1 = A[1, 1] * x[1, j] + A[1, 2] * x[2, j]
        p2 = A[2, 2] * x[2, j]
        e = q[j] - p0
        x[0, j], x[1, j], x[2, j] = p0 + K[0] * e, p1 + K[1] * e, p2 + K[2] * e


def joint_filter_for(robot, rate_hz: float, resolution: float, bandwidth="auto") -> JointStateFilter | None:
    """The joint-state filter for encoders of ``resolution`` [rad] at ``rate_hz`` [Hz] (None for exact
    encoders, resolution 0); ``bandwidth`` [rad/s] or "auto" (DEFAULT_OMEGA)."""
    if not resolution > 0:
        return None
    omega = DEFAULT_OMEGA if bandwidth == "auto" else float(bandwidth)
    return JointStateFilter(robot.nv, JointStateDesign.solve(rate_hz, quantization_variance(resolution), omega))


def with_joint_state_noise(noise, joint: JointStateFilter | None):
    """A window's measured noise (``bandwidth.WindowNoise``) with qd's raised to what ``joint``'s estimate
    carries in motion: a quantized encoder at standstill reads a constant, so the window alone would
    promise noise-free velocities and the bandwidth rules would open wide."""
    if joint is None:
        return noise
    from dataclasses import replace

    return replace(noise, qd=np.maximum(noise.qd, joint.qd_noise))


__all__ = ["joint_filter_for", "with_joint_state_noise", "DEFAULT_OMEGA", "JointStateDesign", "JointStateFilter", "joint_state_noise", "quantization_variance"]
