"""``estimate_tip_force()`` for control code: a streaming estimator, and its batch twin.

Control engineers call :class:`TipForceEstimator` once per tick of a 1 kHz loop::

    est = TipForceEstimator.analytic("panda", method="base-momentum")
    F = est.estimate_tip_force(q, qd, base_wrench=w, t=t)   # (3,) N, base frame
    est.last_status                                         # EstimatorStatus.OK, ...

By concept:

- ``tip_force_estimator.py``: :class:`TipForceEstimator`, what one call does (its module
  docstring: the input rules, the noise window, the bandwidth, the statuses);
- ``config.py``: :class:`EstimatorConfig` (rate, bandwidths, bounds) and
  :class:`EstimatorStatus`;
- ``input.py``: the input gate (:class:`InputGate`, :class:`RateCheck`), which
  checks every sample before it touches any state;
- ``batch.py``: :func:`estimate_tip_force`, the stateless batch form.

The acceleration filter and the rule that picks its cutoff are the analytic
layer's (``analytic/acceleration.py``, the generator's filter too), re-exported here.
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
