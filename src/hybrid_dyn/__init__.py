"""hybrid_dyn: physics-informed dynamics modelling of robot arms.

The package's face is imported on first use (``hd.load_robot``, ``from hybrid_dyn import TipForceEstimator``):
importing a part of it, such as the command line's parser, then costs that part only, not Pinocchio, SciPy
and PyTorch (``hybrid-dyn --help`` starts in a fraction of a second).
"""
from __future__ import annotations

import importlib

# name -> the module it comes from
_FACE = {"InputError": ".analytic.robot", "Robot": ".analytic.robot", "SensorMount": ".analytic.robot",
         "load_robot": ".analytic.robot", "Payload": ".description", "RobotDescriptionError": ".description",
         "EstimatorStatus": ".estimator", "TipForceEstimator": ".estimator", "estimate_tip_force": ".estimator"}

__version__ = "0.1.0"
__all__ = sorted(_FACE)


def __getattr__(name: str):
    if name not in _FACE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_FACE[name], __name__), name)
    globals()[name] = value  # once: the next use is a plain attribute
    return value


def __dir__():
    return sorted(set(globals()) | set(_FACE))
