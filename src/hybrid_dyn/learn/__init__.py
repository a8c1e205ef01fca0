"""Learned models: the reference study's networks, residual nets on physics, DeLaN, tuning, and
Gaussian-process regression (scikit-learn; the one family that is not PyTorch).

Entry points: :func:`train_model`, :func:`load_model`, the preset registry
:data:`PRESETS`, :func:`train_gp`, :func:`load_gp`; see ``docs/models.md``.
"""
from .gp import GPConfig, GPModel, load_gp, train_gp
from .trained_model import HybridModel, ModelError, TrainedModel, load_model
from .presets import PRESETS, Preset
from .recipes import TrainConfig
from .train import train_model

__all__ = ["PRESETS", "GPConfig", "GPModel", "HybridModel", "ModelError", "Preset", "TrainConfig", "TrainedModel",
           "load_gp", "load_model", "train_gp", "train_model"]
