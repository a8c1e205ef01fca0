"""Hyperparameter search with Optuna (standing in for the seed's Keras Tuner).

The search space is the seed's (3.3): the number of LSTM layers and their
units, the number of fully connected layers and their units, and the
activation. Conv presets search the conv width instead of the LSTM layers,
MLPs only the FC part; DeLaN searches the depth and width of its networks.
Each trial trains a full model with early stopping and reports its best
validation loss (standardized MSE).

Storage: a local SQLite file by default (``<out>/optuna.db``); any Optuna RDB
URL (``postgresql://...``, ``mysql://...``) works, so several machines can run
trials of one study at once. Re-running the same command continues the study.
A trial's model lives in a directory named after a digest of its architecture,
so a trial killed mid-training resumes from its checkpoint when the sampler
proposes it again, and finished architectures are not retrained.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import replace
from pathlib import Path

import optuna

from ..data import Dataset, load_dataset
from .model import canonical_json
from .presets import Preset, get_preset
from .train import TrainConfig, train_model

SPACE = {
    "lstm_layers": (1, 2, 3),
    "lstm_units": (8, 16, 32, 64),
    "conv_units": (8, 16, 32, 64),
    "fc_layers": (1, 2, 3),
    "fc_units": (8, 16, 32, 64),
    "activation": ("relu", "tanh"),
    "delan_layers": (1, 2, 3),
    "delan_units": (32, 64, 128),
}


def suggest_preset(trial: optuna.Trial, base: Preset) -> Preset:
    """The base preset with the searched hyperparameters replaced by the trial's choice."""
    p = {}
    if base.kind == "delan":
        depth = trial.suggest_categorical("delan_layers", SPACE["delan_layers"])
        width = trial.suggest_categorical("delan_units", SPACE["delan_units"])
        p["delan_hidden"] = (width,) * depth
    else:
        if base.kind == "lstm":
            n = trial.suggest_categorical("lstm_layers", SPACE["lstm_layers"])
            p["front_units"] = (trial.suggest_categorical("lstm_units", SPACE["lstm_units"]),) * n
        elif base.kind == "conv":
            p["front_units"] = (trial.suggest_categorical("conv_units", SPACE["conv_units"]),)
        p["fc_layers"] = trial.suggest_categorical("fc_layers", SPACE["fc_layers"])
        p["fc_units"] = trial.suggest_categorical("fc_units", SPACE["fc_units"])
        p["activation"] = trial.suggest_categorical("activation", SPACE["activation"])
    arch = replace(base, **p)
    digest = hashlib.sha256(canonical_json(arch.to_dict()).encode()).hexdigest()[:10]
    return replace(arch, name=f"{base.name}-tuned-{digest}", description=f"{base.name} tuned: {p}")


def tune(dataset, preset, out_dir, n_trials: int, storage: str | None = None, study_name: str | None = None,
         config: TrainConfig | None = None, seed: int = 0) -> optuna.Study:
    """Run ``n_trials`` more trials of the study for ``preset`` on ``dataset``; returns the study.

    Writes ``<out_dir>/best.json`` (best parameters, validation loss, model dir).
    """
    base = get_preset(preset)
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    config = config or TrainConfig(progress=False)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    storage = storage or f"sqlite:///{(out_dir / 'optuna.db').resolve()}"
    study_name = study_name or f"{base.name}-{ds.checksum[:12]}"
    study = optuna.create_study(study_name=study_name, storage=storage, direction="minimize",
                                sampler=optuna.samplers.TPESampler(seed=seed), load_if_exists=True)

    def objective(trial: optuna.Trial) -> float:
        arch = suggest_preset(trial, base)
        model_dir = out_dir / "trials" / arch.name
        trial.set_user_attr("model_dir", str(model_dir))
        trial.set_user_attr("preset", arch.to_dict())
        model = train_model(ds, arch, model_dir, config)
        trial.set_user_attr("n_params", model.n_params)
        trial.set_user_attr("train_seconds", model.train_seconds)
        return model.val_loss

    study.optimize(objective, n_trials=n_trials, catch=())
    best = study.best_trial
    doc = {"study": study_name, "storage": storage if storage.startswith("sqlite") else "(external RDB)",
           "base_preset": base.name, "best_val_loss": best.value, "best_params": best.params,
           "model_dir": best.user_attrs.get("model_dir"), "n_trials": len(study.trials)}
    tmp = out_dir / "best.json.partial"
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, out_dir / "best.json")
    return study
