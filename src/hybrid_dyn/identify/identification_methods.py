"""The identification methods, one registry :data:`IDENTIFICATION_METHODS` (``identify(data, method=name)``, the
``identify --fit`` CLI). What each fits is ``identified_model._fit_by_method``'s, by the declared name."""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class IdentificationMethod:
    """A way to fit inertial and friction parameters to motor torques: its name, the friction law it fits
    ("linear": fv qd + fc tanh(qd / eps) + fo; "sigmoid": Gaz 2019's), whether its bodies are physically consistent
    by construction (a constrained fit, CasADi/IPOPT), and what it does (the CLI's help)."""

    name: str
    friction: str
    consistent: bool
    summary: str


IDENTIFICATION_METHODS = Registry("identification method", UsageError)
for _method in (
    IdentificationMethod("ols", "linear", False, "ordinary least squares on the base parameters"),
    IdentificationMethod("wls", "linear", False, "least squares weighted by each joint's residual noise"),
    IdentificationMethod("consistent", "linear", True,
                         "weighted least squares with physically consistent bodies, towards the nominal ones"),
    IdentificationMethod("sigmoid-friction", "sigmoid", True, "consistent bodies with the sigmoid friction law"),
):
    IDENTIFICATION_METHODS.register(_method)
