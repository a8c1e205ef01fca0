"""One rule for every filter that trades noise against lag, applied to the noise a window measures.

The detail (what it computes, the equations, why each choice): docs/design/analytic.md, section ``analytic/bandwidth.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import UsageError
from ..registry import Registry
from .acceleration import white_noise_rms

CONTACT_STEP = 0.1  # N per axis and sample: the contact model, the force as a random walk of this step
TOP_GAIN_DT = 1.0  # observers: K dt up to 1 (the deadbeat observer, a plain trapezoidal difference)
SETTLE_FRACTION = 0.01  # "settled": a start's transient has decayed below 1 %


@dataclass(frozen=True)
class WindowNoise:
    """White noise measured on a (contact-free) window: qd (nv,) [rad/s]; base_force: the base sensor's
    per-axis force noise [N] (None without it); joint_torque (nv,) [Nm] (None without it); q_mean (nv,)
    [rad], the window's mean pose."""

    qd: np.ndarray
    base_force: float | None
    joint_torque: np.ndarray | None
    q_mean: np.ndarray

    @property
    def joint_torque_rms(self) -> float | None:
        return None if self.joint_torque is None else float(np.sqrt(np.mean(self.joint_torque ** 2)))


# The finest noise a force or torque sensor of this class shows [N, Nm]: a window that measures less
# is a simulation without noise, where the second differences see only the motion's smooth residue
# and the rule would compare two round-off figures.
FORCE_RESOLUTION = 0.01
VELOCITY_FLOOR = 1e-9  # rad/s: a positive velocity noise for the filters' variances


def measure_window(q, qd, base_wrench=None, tau_J=None) -> WindowNoise:
    """The noise of a window's samples (n, ...) with n >= 8 (``white_noise_rms``), the force and torque
    sensors' at least FORCE_RESOLUTION; a sensor not given is None."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    if len(q) < 8:
        raise ValueError(f"the noise window needs at least 8 samples, got {len(q)}")
    nv = qd.shape[1]
    # Inputs with the same samples go through one white_noise_rms (one median: a control call closes the window).
    parts = [qd]
    w = None if base_wrench is None else np.asarray(base_wrench, float)[:, :3]
    tau = None if tau_J is None else np.asarray(tau_J, float)
    for x in (w, tau):
        if x is not None and len(x) == len(qd):
            parts.append(x)
    rms = white_noise_rms(np.hstack(parts) if len(parts) > 1 else qd)
    s_qd, rest = rms[:nv], rms[nv:]
    base = s_tau = None
    if w is not None:
        s_w, rest = (rest[:3], rest[3:]) if len(w) == len(qd) else (white_noise_rms(w), rest)
        base = max(FORCE_RESOLUTION, float(np.sqrt(np.mean(s_w**2))))
    if tau is not None:
        s_tau = np.maximum(FORCE_RESOLUTION, rest if len(tau) == len(qd) else white_noise_rms(tau))
    return WindowNoise(np.maximum(VELOCITY_FLOOR, s_qd), base, s_tau, q.mean(axis=0))


def observer_noise_gains(gain, dt: float):
    """(from the input, from the momentum): the momentum observer's variance gains for white noise on
    its input u (the sensor's force or torque, per sample) [1] and on its momentum H [1/s^2].

    r_k = K (a_k - dt S_k-1), a = H - H0 - trapezoid(u): with c = K dt and a = 1 - c,
    u -> r is -c (1 + z^-1) / 2 / (1 - a z^-1), whose squared impulse response sums to c / 2;
    H -> r is K (1 - z^-1) / (1 - a z^-1), summing to 2 K^2 / (2 - c).
    """
    c = np.asarray(gain, float) * dt
    return c / 2.0, 2.0 * np.asarray(gain, float) ** 2 / (2.0 - c)


def observer_gain_grid(rate_hz: float) -> np.ndarray:
    """The gains [1/s] the rule chooses from: 1/s up to K dt = TOP_GAIN_DT."""
    return np.geomspace(1.0, TOP_GAIN_DT * rate_hz, 64)


def contact_rate(dt: float) -> float:
    """The contact model's random-walk intensity [N/sqrt(s)] at sample time dt [s]: CONTACT_STEP / sqrt(dt)."""
    return CONTACT_STEP / math.sqrt(dt)


def lag_variance(gain, dt: float) -> np.ndarray:
    """[N^2] A first-order filter's error on the contact model (a random walk of step CONTACT_STEP per
    sample): CONTACT_STEP^2 a^2 / (1 - a^2) with a = 1 - K dt (0 at K dt = 1)."""
    a = 1.0 - np.asarray(gain, float) * dt
    return CONTACT_STEP**2 * a * a / np.maximum(1.0 - a * a, 1e-300)


def observer_gain(rate_hz: float, s_input: float, s_momentum: float, force_scale: float = 1.0):
    """The rule for an observer: (K [1/s], its predicted contact-free noise [N]) minimising
    noise^2 + lag^2 on the grid, with noise^2 = force_scale^2 (s_input^2 g_u(K) + s_momentum^2 g_H(K));
    force_scale maps the observer's quantity to the tip force (1 for a force; for joint torques the
    RMS gain of pinv(J_v^T))."""
    grid = observer_gain_grid(rate_hz)
    dt = 1.0 / rate_hz
    g_u, g_h = observer_noise_gains(grid, dt)
    noise2 = force_scale**2 * (s_input**2 * g_u + s_momentum**2 * g_h)
    i = int(np.argmin(noise2 + lag_variance(grid, dt)))
    return float(grid[i]), float(np.sqrt(noise2[i]))


def observer_settle_calls(gain: float, dt: float) -> int:
    """Calls until a start's transient (1 - K dt)^n is below SETTLE_FRACTION."""
    c = min(gain * dt, 1.0)
    return 1 if c >= 1.0 else int(math.ceil(math.log(SETTLE_FRACTION) / math.log(1.0 - c)))


def random_walk_gain(force_rate: float, dt: float, s_e2: float) -> float:
    """The steady-state gain k of the scalar Kalman filter of a random walk of intensity force_rate
    [N/sqrt(s)] seen once per dt through white noise of variance s_e2 [N^2]: with lambda = Q / R,
    p = (lambda + sqrt(lambda^2 + 4 lambda)) / 2 and k = p / (1 + p)."""
    lam = force_rate**2 * dt / max(s_e2, 1e-300)
    p = 0.5 * (lam + math.sqrt(lam * lam + 4.0 * lam))
    return p / (1.0 + p)


def kalman_settle_calls(k: float) -> int:
    """Calls until a start's transient (1 - k)^n is below SETTLE_FRACTION."""
    return 1 if k >= 1.0 else int(math.ceil(math.log(SETTLE_FRACTION) / math.log(1.0 - k)))


# ------------------------------------------------- the bandwidth parameters
def no_grid(rate_hz: float) -> tuple:
    """A parameter the bench does not choose on validation (its methods have no ``-val`` row)."""
    return ()


@dataclass(frozen=True)
class BandwidthParameter:
    """One bandwidth parameter of the estimator methods: the knob that trades noise against lag.

    name: its setting's key (an ``EstimatorConfig`` field or key of ``EstimatorConfig.bandwidths``, a keyword
    of ``TipForceEstimator.analytic``); unit: its physical unit; meaning: what it is, in a phrase.
    val_grid(rate_hz [Hz]) -> the values the bench's ``-val`` row chooses from at that rate.
    default: "auto" (the rule above, on the noise window) or a number. below_nyquist: a value must lie
    below half the call rate (a filter's cutoff [Hz]); else any positive number is a setting."""

    name: str
    unit: str
    meaning: str
    val_grid: Callable[[float], tuple] = no_grid
    default: float | str = "auto"
    below_nyquist: bool = False

    def check(self, value, call_hz: float) -> None:
        """Refuse (UsageError, naming the parameter and its unit) a value that is no setting of it."""
        number = isinstance(value, (int, float))
        if self.below_nyquist:
            if value != "auto" and not (number and 0 < value < 0.5 * call_hz):
                raise UsageError(f"{self.name} must be 'auto' or lie in (0, call_hz / 2) [{self.unit}], got {value!r}")
        elif value != "auto" and not (number and value > 0):
            raise UsageError(f"{self.name} must be 'auto' or > 0 [{self.unit}], got {value!r}")


BANDWIDTHS = Registry("bandwidth parameter", UsageError)  # name -> BandwidthParameter


def observer_gains(rate_hz: float) -> tuple:
    """The observer gains [1/s] the bench's ``-val`` rows choose from: up to K dt = 1."""
    return tuple(k for k in (5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0) if k / rate_hz <= 1.0)


def force_rates(rate_hz: float) -> tuple:
    """The Kalman force rates [N/sqrt(s)] the bench's ``-val`` rows choose from."""
    return (0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0)


QDD_CUTOFF = BANDWIDTHS.register(BandwidthParameter(
    "qdd_cutoff_hz", "Hz", "the qdd filter's cutoff (the rule's noise side: acceleration.auto_qdd_cutoff)",
    below_nyquist=True))
MOMENTUM_GAIN = BANDWIDTHS.register(BandwidthParameter(
    "momentum_gain", "1/s", "a momentum observer's gain K (observer_gain)", observer_gains))
FUSION_FORCE_RATE = BANDWIDTHS.register(BandwidthParameter(
    "fusion_force_rate", "N/sqrt(s)", "the Kalman filter's random-walk intensity of the tip force (contact_rate)",
    force_rates))
