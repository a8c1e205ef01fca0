"""The ways to estimate velocities and accelerations from logged positions, one registry :data:`DERIVATIVE_METHODS`
(an import spec's ``[derivatives] method``, ``derivatives.DerivativeFilter``; what each computes:
``derivatives.differentiate``, by the declared name)."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class DerivativeMethod:
    """A derivative estimator: its name and what it does. local: a sample's derivative depends on a few samples
    around it (``DerivativeFilter.reach`` is finite), so a long segment may be differentiated in blocks."""

    name: str
    summary: str
    local: bool = True


DERIVATIVE_METHODS = Registry("derivative method", UsageError)
DERIVATIVE_METHODS.register(DerivativeMethod("savgol", "Savitzky-Golay: a local polynomial of the window's samples"))
DERIVATIVE_METHODS.register(DerivativeMethod("central", "central differences (one-sided at the ends)"))
DERIVATIVE_METHODS.register(DerivativeMethod(
    "butter", "central differences through a zero-phase Butterworth low-pass (filtfilt: the whole segment)", False))
