"""Sensor models: the causal acceleration estimate.

A real arm measures no joint acceleration; controllers differentiate the
measured velocity and low-pass the result. We do the same at the control rate:
a backward difference of the measured qd, then a 2nd-order Butterworth
low-pass, both causal (each output uses only present and past samples), then
the caller keeps every ``decimation``-th sample. Running the causal filter over
a stored signal gives exactly what an online filter would have given.

The price is a delay (about 1/(2 pi f_c) * 1.4 s, ~11 ms at 20 Hz) and
residual noise; both are part of what learned models must cope with.
"""
from __future__ import annotations

import numpy as np
from scipy import signal


def causal_acceleration(qd_measured: np.ndarray, dt: float, cutoff_hz: float = 20.0) -> np.ndarray:
    """qdd estimate [rad/s^2] (T, nv) from measured qd [rad/s] (T, nv) sampled every ``dt`` [s].

    The signal is assumed to start at rest (zero initial filter state), as every
    generated instance does.
    """
    qd = np.asarray(qd_measured, float)
    diff = np.zeros_like(qd)
    diff[1:] = (qd[1:] - qd[:-1]) / dt
    b, a = signal.butter(2, cutoff_hz, fs=1.0 / dt)
    return signal.lfilter(b, a, diff, axis=0)
