"""The analytic joint-torque models (the bench's ``tau_m`` task), one registry: :data:`TORQUE_MODELS`.

They share the estimators' one namespace with the tip-force methods (``methods.TIP_FORCE_METHODS``): a
tip-force method may not take a torque model's name. A residual network may sit on each.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import UsageError
from ..registry import Registry


@dataclass(frozen=True)
class TorqueModel:
    """A joint-torque model tau_m [Nm] by its one name: the dataset fields it reads (``fields``, what a residual
    prior on it is given: ``learn/priors.PRIOR_FIELDS``), what it is (``summary``); residual_prior: a residual
    network may sit on it."""

    name: str
    fields: tuple
    summary: str
    residual_prior: bool = True


TORQUE_MODELS = Registry("joint-torque model", UsageError)
for _model in (TorqueModel("rnea", ("q", "qd", "qdd"), "inverse dynamics (+ friction on an identified set)"),
               TorqueModel("rnea-bw", ("q", "qd", "qdd", "base_wrench"), "RNEA - J_v^T F, F from base-wrench")):
    TORQUE_MODELS.register(_model)
TORQUE_MODELS.alias("rnea-basewrench", "rnea-bw")
