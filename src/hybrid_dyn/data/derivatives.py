"""Velocities and accelerations from logged joint positions or velocities.

The detail (what it computes, the equations, why each choice): docs/design/data.md, section ``data/derivatives.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from ..errors import UsageError
from .derivative_methods import DERIVATIVE_METHODS


@dataclass
class DerivativeFilter:
    """How derivatives are estimated (docs/design/data.md, ``data/derivatives.py``).

    ``window_s`` [s] and ``polyorder`` for ``savgol``; ``cutoff_hz`` [Hz] and
    ``order`` for ``butter``.
    """

    method: str = "savgol"
    window_s: float = 0.11
    polyorder: int = 3
    cutoff_hz: float = 10.0
    order: int = 4

    def __post_init__(self):
        DERIVATIVE_METHODS.lookup(self.method)  # an unknown one is refused, naming the known ones
        from .logs.spec_checks import is_number

        if not all(is_number(v) for v in (self.window_s, self.cutoff_hz)) or not all(
                is_number(v, integer=True) for v in (self.polyorder, self.order)):  # "abc" or nan: a traceback before
            raise UsageError(f"derivative filter parameters must be numbers (polyorder and order integers): {self}")
        if self.window_s <= 0 or self.cutoff_hz <= 0 or self.polyorder < 2 or self.order < 1:
            raise UsageError(f"derivative filter parameters out of range: {self}")

    def window_samples(self, dt: float) -> int:
        """The Savitzky-Golay window in samples at step ``dt`` [s]: odd, > polyorder."""
        n = int(round(self.window_s / dt))
        n = max(n, self.polyorder + 2)
        return n + 1 if n % 2 == 0 else n

    def min_samples(self, dt: float) -> int:
        """The shortest segment this filter can differentiate twice."""
        if self.method == "savgol":
            return self.window_samples(dt)
        if self.method == "butter":
            return 3 * (self.order + 1) + 1  # filtfilt's default pad length + 1
        return 3

    def reach(self, dt: float) -> int | None:
        """Samples on each side of a sample that its derivative depends on (savgol: half the window; central:
        1, taken as 2 for the one-sided ends of a block); None for ``butter``: filtfilt reaches the whole
        segment. A block of a segment differentiated with this margin on each side is exact inside it."""
        if self.method == "savgol":
            return self.window_samples(dt) // 2
        return 2 if self.method == "central" else None

    def to_dict(self) -> dict:
        return {"method": self.method, "window_s": self.window_s, "polyorder": self.polyorder,
                "cutoff_hz": self.cutoff_hz, "order": self.order}


def differentiate(x: np.ndarray, t: np.ndarray, flt: DerivativeFilter, deriv: int = 1,
                  x_next: np.ndarray | None = None, dt: float | None = None) -> np.ndarray:
    """The ``deriv``-th (1 or 2) time derivative of ``x`` (T, n) sampled at times ``t`` (T,) [s].

    ``x_next`` (n,): the sample after the last one, if the log has it (``central`` uses it). ``dt`` [s]:
    the segment's median step when ``x`` is a block of it (default: the median step of ``t``).
    """
    x = np.asarray(x, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if x.ndim != 2 or t.shape != (len(x),):
        raise ValueError(f"differentiate needs x (T, n) and t (T,), got {x.shape} and {t.shape}")
    if deriv not in (1, 2):
        raise ValueError(f"deriv must be 1 or 2, got {deriv}")
    dt = _step(t) if dt is None else dt
    if len(x) < flt.min_samples(dt):
        raise ValueError(f"segment of {len(x)} samples is too short for the {flt.method} filter "
                         f"(needs {flt.min_samples(dt)})")
    if flt.method == "savgol":
        window = flt.window_samples(dt)
        return signal.savgol_filter(x, window, flt.polyorder, deriv=deriv, delta=dt, axis=0, mode="interp")
    out = _central(x, t, x_next)
    if deriv == 2:
        out = _central(out, t, None)
    if flt.method == "butter":
        nyquist = 0.5 / dt
        if flt.cutoff_hz >= nyquist:
            raise UsageError(f"butter cutoff {flt.cutoff_hz} Hz is not below the Nyquist frequency {nyquist:.1f} Hz")
        b, a = signal.butter(flt.order, flt.cutoff_hz / nyquist)
        # Filter the difference quotient, not the signal: the filter commutes with d/dt, and the
        # odd-extension padding then keeps the derivative's own value and slope at the ends.
        padlen = min(len(out) - 1, int(round(2.0 / (flt.cutoff_hz * dt))))
        out = signal.filtfilt(b, a, out, axis=0, padtype="odd", padlen=padlen)
    return out


def _central(x: np.ndarray, t: np.ndarray, x_next: np.ndarray | None) -> np.ndarray:
    if x_next is not None:
        # One more sample at the end, one median step later: the last row gets a central difference.
        t_ext = np.append(t, t[-1] + _step(t))
        return np.gradient(np.vstack([x, x_next[None, :]]), t_ext, axis=0, edge_order=2)[:-1]
    return np.gradient(x, t, axis=0, edge_order=2)


def _step(t: np.ndarray) -> float:
    return float(np.median(np.diff(t))) if len(t) > 1 else 1.0
