"""Learned models: the seed's networks, residual nets on physics, DeLaN, tuning.

Entry points: :func:`train_model`, :func:`load_model`, the preset registry
:data:`PRESETS`; see ``docs/models.md``.
"""
from .model import HybridModel, ModelError, TrainedModel, load_model
from .presets import PRESETS, Preset, get_preset
from .train import TrainConfig, train_model

__all__ = ["PRESETS", "HybridModel", "ModelError", "Preset", "TrainConfig", "TrainedModel", "get_preset",
           "load_model", "train_model"]
