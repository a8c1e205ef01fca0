"""What a training run is: :class:`TrainConfig` (each field checked, named with its CLI flag), the
named recipes and the budgeted recipe's schedule.

The design in full: ``docs/design/learn.md`` (recipes.py).
"""
from __future__ import annotations

import math
import numbers
import os
import re
from dataclasses import asdict, dataclass, replace

from ..analytic.tare import TARE_SECONDS
from ..errors import UsageError
from .kinds import NETWORK_KINDS  # each kind declares its step budget
from .presets import Preset


@dataclass
class TrainConfig:
    """How to train: the ``plateau`` recipe (see the module docstring; ``TrainConfig.recipe("seed-study")``
    gives the seed study's).

    seed: weights and shuffling. batch_size: samples per Adam step.
    max_epochs: upper bound; early stopping usually ends sooner.
    patience: epochs without validation improvement before stopping (seed: 5).
    min_delta, min_rel_delta: an improvement must beat the best validation loss by
    max(min_delta, min_rel_delta x best) (:func:`improvement_needed`; seed: 0, 0).
    lr: Adam's initial learning rate. lr_schedule: "plateau" (cut the rate by
    lr_factor after lr_patience epochs without improvement, never below min_lr)
    or "none" (constant, the seed's).
    grad_clip: largest gradient norm of a net with an LSTM (None: no clipping).
    weight_decay: decoupled weight decay of the weight matrices, per step a
    fraction lr x weight_decay of each weight (AdamW, Loshchilov & Hutter 2019;
    0: plain Adam). The seed's nets carry an unspecified regularization term
    (its 3.2).
    max_batches_per_epoch: cap an epoch's batches (quick runs, tuning); None = all.
    budget_steps: optimizer steps of a budgeted run (lr_schedule "cosine"); None: the
    preset's network kind's ``budget_steps`` (resolved by :meth:`for_preset`).
    warmup_fraction: share of the budget over which the rate rises linearly to lr.
    budget_evals: validation rounds over the budget (each keeps the weights if best).
    budget_patience: validation rounds without improvement after which a budgeted run stops (its
    schedule stays that of the whole budget, so the rounds it ran are those of the whole run and its
    kept weights are the whole run's wherever the best round came before the stop); None: every round
    runs. Of the default bench's 93 learned rows (their curves in reports/default/curves.json at
    84c0303), one improved after 12 idle rounds, by 0.4 % of validation loss, and 41 % of their
    training CPU came after that point.
    train_instances: learn from the first N instances of the train split, and the first
    round(N x n_val / n_train) (at least 1) of the val split, so that train and val shrink
    together (the data-scaling study, ``bench/studies.py``); None: the whole splits.
    analytic_params: parameter set of the residual models' analytic part
    (None: the robot's nominal URDF; a set name or a JSON path, e.g. identified).
    observer_gain: momentum-observer bandwidth K [1/s] for the momentum prior.
    tare_seconds: base-wrench priors: each instance's contact-free start used to
    tare the base sensor [s] (``analytic/tare.py``); 0 = no tare.
    device: "auto" (CUDA when present, else CPU), "cpu" or "cuda".
    num_threads: CPU threads for PyTorch during training (None: PyTorch's default).
    Small batches on a shared machine often run faster on one thread.
    """

    seed: int = 0
    batch_size: int = 256
    max_epochs: int = 200
    patience: int = 10
    min_delta: float = 0.0
    min_rel_delta: float = 1e-4
    lr: float = 1e-3
    lr_schedule: str = "plateau"
    lr_factor: float = 0.3
    lr_patience: int = 3
    min_lr: float = 1e-5
    grad_clip: float | None = 1.0
    weight_decay: float = 0.0
    max_batches_per_epoch: int | None = None
    budget_steps: int | None = None
    warmup_fraction: float = 0.05
    budget_evals: int = 40
    budget_patience: int | None = None
    train_instances: int | None = None
    analytic_params: str | None = None
    observer_gain: float = 20.0
    tare_seconds: float = TARE_SECONDS
    device: str = "auto"
    progress: bool = True
    num_threads: int | None = None

    def __post_init__(self):
        self.validate()

    @classmethod
    def recipe(cls, name: str = "plateau", **overrides) -> "TrainConfig":
        """The named recipe of :data:`RECIPES` (an old name of :data:`RECIPE_ALIASES` warns), with any field overridden."""
        if name in RECIPE_ALIASES:
            from ..deprecation import warn_renamed

            warn_renamed("training recipe", name, RECIPE_ALIASES[name], stacklevel=2)
            name = RECIPE_ALIASES[name]
        if name not in RECIPES:
            raise UsageError(f"unknown training recipe {name!r}; known: {', '.join(RECIPES)}")
        return cls(**{**RECIPES[name], **overrides})

    def validate(self) -> None:
        """Refuse values out of range with a one-line UsageError naming the field and the CLI flag.

        Checked before any work: an epoch count of 0 or a negative batch size would
        otherwise save an untrained model, a bad device end in a traceback.
        """
        for name, least, optional in (("seed", 0, False), ("batch_size", 1, False), ("max_epochs", 1, False),
                                      ("patience", 1, False), ("lr_patience", 1, False),
                                      ("max_batches_per_epoch", 1, True), ("budget_steps", 1, True),
                                      ("budget_evals", 1, True), ("budget_patience", 1, True),
                                      ("train_instances", 1, True),
                                      ("num_threads", 1, True)):
            v = getattr(self, name)
            if v is None and optional:
                continue
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < least:
                raise UsageError(f"{_option(name)} must be an integer >= {least}{' or None' if optional else ''}, "
                                 f"got {v!r}")
            setattr(self, name, int(v))
        for name, positive in (("lr", True), ("min_delta", False), ("min_rel_delta", False), ("observer_gain", True), ("tare_seconds", False),
                               ("weight_decay", False)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v < 0 \
                    or (positive and v == 0):
                raise UsageError(f"{_option(name)} must be a finite number {'> 0' if positive else '>= 0'}, got {v!r}")
        if self.lr_schedule not in LR_SCHEDULES:
            raise UsageError(f"{_option('lr_schedule')} must be one of {', '.join(LR_SCHEDULES)}, "
                             f"got {self.lr_schedule!r}")
        for name in ("lr_factor", "min_lr") + (("grad_clip",) if self.grad_clip is not None else ()):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v <= 0:
                raise UsageError(f"{_option(name)} must be a finite number > 0, got {v!r}")
        if self.budgeted and self.max_batches_per_epoch is not None:  # it would be silently ignored
            raise UsageError(f"{_option('max_batches_per_epoch')} applies to the epoch recipes; a budgeted run "
                             f"(lr_schedule 'cosine') is sized by {_option('budget_steps')}")
        if isinstance(self.warmup_fraction, bool) or not isinstance(self.warmup_fraction, numbers.Real) \
                or not 0 <= self.warmup_fraction < 1:
            raise UsageError(f"{_option('warmup_fraction')} must be a number in [0, 1), got {self.warmup_fraction!r}")
        if not self.lr_factor < 1:
            raise UsageError(f"{_option('lr_factor')} must be < 1 (it cuts the rate), got {self.lr_factor!r}")
        if self.min_lr > self.lr:
            raise UsageError(f"{_option('min_lr')} ({self.min_lr}) must not exceed {_option('lr')} ({self.lr})")
        if not isinstance(self.device, str) or not re.fullmatch(r"auto|cpu|cuda(:\d+)?", self.device):
            raise UsageError(f"{_option('device')} must be auto, cpu, cuda or cuda:N, got {self.device!r}")
        if self.analytic_params is not None and not isinstance(self.analytic_params, (str, os.PathLike)):
            raise UsageError(f"{_option('analytic_params')} must be a parameter-set name or a JSON path, "
                             f"got {self.analytic_params!r}")

    @property
    def budgeted(self) -> bool:
        """Whether training runs a fixed budget of steps (the cosine schedule) instead of epochs to patience."""
        return self.lr_schedule == "cosine"

    def for_preset(self, preset: Preset) -> "TrainConfig":
        """This config with a budgeted run's step count resolved from the preset's network kind."""
        if not self.budgeted or self.budget_steps is not None:
            return self
        return replace(self, budget_steps=budget_steps_of(preset))

    def fingerprint_fields(self) -> dict:
        d = asdict(self)
        for k in ("device", "progress", "num_threads"):  # where and how loudly a run goes does not change its result
            d.pop(k)
        if not d["weight_decay"]:  # added later: a run without it keeps the fingerprint it always had
            d.pop("weight_decay")
        if self.train_instances is None:  # added later: a run on the whole splits keeps its fingerprint
            d.pop("train_instances")
        if self.budget_patience is None:  # added later: a run that spends its whole budget keeps its fingerprint
            d.pop("budget_patience")
        if not self.budgeted:  # added later, and meaningless without the budget: older runs keep their fingerprint
            for k in ("budget_steps", "warmup_fraction", "budget_evals", "budget_patience"):
                d.pop(k, None)
        return d


LR_SCHEDULES = ("plateau", "none", "cosine")

# Optimizer steps of the budgeted recipe per network kind: declared with each kind (learn/nets.py,
# where the budget study's numbers are explained, and learn/delan.py).


def budget_steps_of(preset: Preset) -> int:
    """The budgeted recipe's step count for ``preset``: its network kind's ``budget_steps``."""
    return NETWORK_KINDS.lookup(preset.kind).budget_steps


def budget_lr(config: TrainConfig, step: int) -> float:
    """The budgeted recipe's rate at optimizer step ``step`` (0-based) of ``config.budget_steps``.

    Linear warm-up to ``lr`` over the first ``warmup_fraction`` of the steps (lr / w at step 0),
    then lr x (1 + cos(pi x progress)) / 2, which reaches zero after the last step. A function of
    the step alone: a resumed run needs no scheduler state.
    """
    total = config.budget_steps
    warm = int(round(config.warmup_fraction * total))
    if step < warm:
        return config.lr * (step + 1) / warm
    progress = (step - warm) / max(total - warm, 1)
    return config.lr * 0.5 * (1.0 + math.cos(math.pi * progress))

# Named training recipes (TrainConfig fields). "seed-study": the seed's 3.2 exactly (constant rate,
# patience 5, no clipping); "plateau": the TrainConfig defaults; "long": module docstring.
RECIPES = {
    "plateau": {},
    # Trains further where "plateau" stops early (docs/models.md, reports/studies/controls-default): the
    # plateau waits 10 epochs, early stopping 20, weight matrices decay by 0.1. It cost 1.8-3.7x the
    # epochs on paper-noext's torque rows, which the default bench cannot afford in 120 minutes on 2 cores.
    "long": dict(patience=20, lr_patience=10, weight_decay=0.1),
    "seed-study": dict(lr_schedule="none", patience=5, grad_clip=None, min_rel_delta=0.0, batch_size=256, max_epochs=200),
    # A known cost per row (module docstring): steps by network kind, warm-up, cosine decay to zero.
    "budget": dict(lr_schedule="cosine", batch_size=1024, lr=2e-3),
}
# The recipes' former names ("default" was also a generator size and a bench profile, "seed"
# also the random seed): still accepted, with a warning. A recipe's name is in no fingerprint.
RECIPE_ALIASES = {"default": "plateau", "seed": "seed-study"}


def improvement_needed(config: TrainConfig, best_val: float) -> float:
    """How far below the best validation loss an epoch must land to count as an improvement.

    The larger of the absolute ``min_delta`` and ``min_rel_delta`` x the best loss: without the
    relative part a net that gains 1e-6 per epoch for ever (seen on seed-sim, residual-rnea-bw)
    resets patience every epoch and runs to the epoch cap on gains nobody can measure. 1e-4 is
    the threshold of PyTorch's ReduceLROnPlateau.
    """
    return max(config.min_delta, config.min_rel_delta * abs(best_val))


def _option(field: str) -> str:
    """A TrainConfig field as the user wrote it: the field and, where there is one, its CLI flag."""
    flag = _CLI_FLAGS.get(field)
    return f"TrainConfig.{field}" + (f" ({flag})" if flag else "")


_CLI_FLAGS = {"seed": "--seed", "batch_size": "--batch-size", "max_epochs": "--max-epochs", "patience": "--patience",
              "budget_patience": "--budget-patience",
              "max_batches_per_epoch": "--max-batches-per-epoch", "num_threads": "--threads",
              "device": "--device", "analytic_params": "--params", "lr": "--lr",
              "lr_schedule": "--lr-schedule", "grad_clip": "--grad-clip", "min_lr": "--min-lr",
              "weight_decay": "--weight-decay", "budget_steps": "--budget-steps",
              "train_instances": "--train-instances"}
