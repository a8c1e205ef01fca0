"""Sensor models: the causal acceleration estimate.

A real arm measures no joint acceleration; controllers differentiate the
measured velocity and low-pass the result. We do the same at the control rate:
a backward difference of the measured qd, then a 2nd-order Butterworth
low-pass, both causal (each output uses only present and past samples), then
the caller keeps every ``decimation``-th sample. Running the causal filter over
a stored signal gives exactly what an online filter would have given: the
generator and the streaming estimator run one kernel
(``analytic/acceleration.py``, re-exported here).

The price is a delay (about 1/(2 pi f_c) * 1.4 s, ~11 ms at 20 Hz) and
residual noise; both are part of what learned models must cope with.
"""
from __future__ import annotations

from ..analytic.acceleration import causal_acceleration

__all__ = ["causal_acceleration"]
