"""``estimate_tip_force()`` for control code: a streaming estimator, and its batch twin.

The detail (what it computes, the equations, why each choice): docs/estimator.md, section ``the package's modules``.
"""
from ..analytic.acceleration import (  # noqa: F401  (re-exported: the estimator's public names)
    DEFAULT_QDD_CUTOFF_HZ, CausalAccelerationFilter, auto_qdd_cutoff, cutoff_grid, qdd_noise_gain, white_noise_rms)
from .batch import estimate_tip_force
from .config import EstimatorConfig, EstimatorStatus
from .input import EstimatorInputError, InputGate, RateCheck
from .tip_force_estimator import TipForceEstimator


__all__ = ["DEFAULT_QDD_CUTOFF_HZ", "CausalAccelerationFilter", "EstimatorConfig",
           "EstimatorInputError", "EstimatorStatus", "InputGate", "RateCheck", "TipForceEstimator", "auto_qdd_cutoff",
           "cutoff_grid", "estimate_tip_force", "qdd_noise_gain", "white_noise_rms"]
