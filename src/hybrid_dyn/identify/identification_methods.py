"""The identification methods, one registry :data:`IDENTIFICATION_METHODS` (``identify(data, method=name)``, the
``identify --fit`` CLI). What each fits is ``identified_model._fit_by_method``'s, by the declared name."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class IdentificationMethod:
    """A way to fit inertial and friction parameters to motor torques: its name and what it does (the CLI's help).
    consistent: its bodies are physically consistent by construction (a constrained fit, CasADi/IPOPT)."""

    name: str
    summary: str
    consistent: bool = False


IDENTIFICATION_METHODS = Registry("identification method", UsageError)
IDENTIFICATION_METHODS.register(IdentificationMethod("ols", "ordinary least squares on the base parameters"))
IDENTIFICATION_METHODS.register(IdentificationMethod("wls", "least squares weighted by each joint's residual noise"))
IDENTIFICATION_METHODS.register(IdentificationMethod(
    "consistent", "weighted least squares with physically consistent bodies, towards the nominal ones", True))
IDENTIFICATION_METHODS.register(IdentificationMethod(
    "sigmoid-friction", "consistent bodies with the sigmoid (Gaz 2019) friction law", True))
