"""CLI: train, predict, tune, and the list of presets."""
from __future__ import annotations

import json

from ..registry import help_listing


def _presets():  # the presets' module imports torch: only when the help is printed
    from .presets import PRESETS

    return PRESETS


def _recipes():
    from .recipes import RECIPES

    return RECIPES


# Help texts name {presets} and {recipes}: read from the registries when printed.
_HELP = help_listing(presets=_presets, recipes=_recipes)


def register(sub) -> None:
    p = sub.add_parser("presets")
    p.set_defaults(func=cmd_presets)

    p = sub.add_parser("train", formatter_class=_HELP)
    p.add_argument("--data", required=True, help="dataset directory")
    p.add_argument("--preset", required=True, help="a declared preset (hybrid-dyn presets): {presets}")
    p.add_argument("--out", required=True, help="model directory (a rerun resumes or reuses it)")
    _train_options(p)
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("predict")
    p.add_argument("--model", required=True, help="model directory")
    p.add_argument("--data", required=True, help="dataset directory")
    p.add_argument("--split", default="test", choices=["train", "val", "test"])
    p.add_argument("--save", default=None, help="write predictions to this HDF5 file (one array per instance)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --save file (only a predictions file written by hybrid-dyn predict)")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser("tune", formatter_class=_HELP)
    p.add_argument("--data", required=True)
    p.add_argument("--preset", required=True, help="base preset whose architecture is searched: {presets}")
    p.add_argument("--trials", type=int, required=True, help="number of trials to add to the study")
    p.add_argument("--out", default=None, help="directory for trial models (default runs/tune/<preset>)")
    p.add_argument("--storage", default=None,
                   help="Optuna RDB URL shared by all workers, e.g. postgresql://user@host/db (default: sqlite in --out)")
    p.add_argument("--study", default=None, help="study name (default: preset + dataset checksum)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes sharing the trials")
    p.add_argument("--heartbeat", type=int, default=None,
                   help="seconds between trial heartbeats; a trial silent for 3 of them is failed and retried "
                        "(default 10)")
    _train_options(p)
    p.set_defaults(func=cmd_tune)


def _train_options(p) -> None:
    p.add_argument("--recipe", default="plateau", help="training recipe: {recipes} (default plateau; what each "
                   "does: docs/models.md); the options below override it")
    p.add_argument("--seed", type=int, default=0, help="random seed of the weights and the shuffling")
    p.add_argument("--max-epochs", type=int, default=None,
                   help="maximum epochs (early stopping ends sooner; default 200)")
    p.add_argument("--patience", type=int, default=None, help="epochs without validation improvement before stopping")
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--lr", type=float, default=None, help="initial learning rate (default 1e-3)")
    p.add_argument("--lr-schedule", default=None, choices=["plateau", "none", "cosine"])
    p.add_argument("--budget-steps", type=int, default=None,
                   help="optimizer steps of a budgeted run (recipe budget; default: by network kind)")
    p.add_argument("--budget-patience", type=int, default=None,
                   help="validation rounds without improvement that end a budgeted run early (default: none)")
    p.add_argument("--weight-decay", type=float, default=None,
                   help="decoupled weight decay of the weight matrices (AdamW; default 0: plain Adam)")
    p.add_argument("--max-batches-per-epoch", type=int, default=None)
    p.add_argument("--train-instances", type=int, default=None,
                   help="learn from the first N train instances (val cut in proportion; default: all)")
    p.add_argument("--params", default=None, help="parameter set (a name such as franka_official) or parameter JSON "
                   "of the residual models' analytic part, as bench --params (default: the robot's nominal set)")
    p.add_argument("--device", default="auto", help="auto, cpu or cuda")
    p.add_argument("--threads", type=int, default=None, help="PyTorch CPU threads")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _config(args):
    from .recipes import TrainConfig

    given = {"max_epochs": args.max_epochs, "patience": args.patience, "batch_size": args.batch_size, "lr": args.lr,
             "lr_schedule": args.lr_schedule, "weight_decay": args.weight_decay, "budget_steps": args.budget_steps,
             "budget_patience": args.budget_patience, "train_instances": args.train_instances}
    return TrainConfig.recipe(args.recipe, seed=args.seed, max_batches_per_epoch=args.max_batches_per_epoch,
                              analytic_params=args.params, device=args.device, num_threads=args.threads,
                              progress=not args.quiet, **{k: v for k, v in given.items() if v is not None})


def cmd_presets(args) -> int:
    from .presets import PRESETS

    for name, p in PRESETS.items():
        print(f"{name:22s} {', '.join(p.inputs)} -> {', '.join(p.targets)}  {p.description}")
    return 0


def cmd_train(args) -> int:
    from .train import train_model

    model = train_model(args.data, args.preset, args.out, _config(args))
    print(f"{args.preset}: val loss {model.val_loss:.4f} (standardized MSE), {len(model.history)} epochs "
          f"(stopped by {model.config.get('stopped_by')}, best epoch {model.config.get('best_epoch')}), "
          f"{model.n_params} parameters, {model.train_seconds:.1f} s -> {args.out}")
    return 0


def cmd_predict(args) -> int:
    import numpy as np

    from ..data import load_dataset
    from ..data.input_windows import concat_fields
    from .trained_model import ModelError, load_model

    if args.save:
        _check_save_path(args.save, args.overwrite)  # before the work, not after it
    ds = load_dataset(args.data)
    model = load_model(args.model, robot=ds.meta.get("robot"))
    from ..analytic.methods import TIP_FORCE_METHODS

    prior = TIP_FORCE_METHODS.get(model.preset.prior)  # an observer's prior depends on the rate (dt = 1 / rate)
    if prior is not None and prior.stateful and ds.meta.get("record_hz") != model.config.get("record_hz"):
        raise ModelError(f"model was trained at {model.config.get('record_hz')} Hz, data is at {ds.meta.get('record_hz')} Hz")
    instances = ds.split(args.split)
    preds = model.predict(instances)
    y = concat_fields(instances, model.targets).astype(np.float64)
    err = np.concatenate(preds) - y
    y_std = model.module.y_std.double().numpy()
    result = {"model": str(args.model), "preset": model.preset.name, "split": args.split,
              "n_samples": int(len(y)), "loss": float(np.mean((err / y_std) ** 2)),
              "rmse": float(np.sqrt(np.mean(err ** 2))),
              "rmse_per_component": np.sqrt(np.mean(err ** 2, 0)).round(6).tolist()}
    print(json.dumps(result, indent=1))
    if args.save:
        import os

        import h5py

        from ..outputs import output_lock, unique_temp

        with output_lock(args.save, "predictions file"):
            _check_save_path(args.save, args.overwrite)  # again, under the lock
            tmp = unique_temp(args.save)
            with h5py.File(tmp, "w") as f:
                for inst, p in zip(instances, preds):
                    f.create_dataset(inst.name, data=p, track_times=False)
                f.attrs["model"] = str(args.model)
                f.attrs["targets"] = ",".join(model.targets)
                f.attrs[PREDICTIONS_MARKER] = 1
            os.replace(tmp, args.save)
    return 0


# The attribute that marks an HDF5 file as written by ``predict --save``.
PREDICTIONS_MARKER = "hybrid_dyn_predictions"


def _check_save_path(path, overwrite: bool) -> None:
    """Refuse to replace ``path`` unless ``overwrite`` and it is a predictions file of ours."""
    from pathlib import Path

    from ..errors import OutputPathError
    from ..outputs import refuse_foreign

    path = Path(path)
    if not path.parent.is_dir():
        raise OutputPathError(f"--save {path}: its folder {path.parent} does not exist")
    if not path.exists() and not path.is_symlink():
        return
    if not overwrite:
        raise OutputPathError(f"--save {path} already exists; pass --overwrite to replace it")
    import h5py

    try:
        with h5py.File(path, "r") as f:
            ours = bool(f.attrs.get(PREDICTIONS_MARKER, 0))
    except (OSError, ValueError):
        ours = False
    if path.is_symlink() or not ours:
        refuse_foreign(path, "predictions file", f"it lacks the {PREDICTIONS_MARKER!r} attribute")


def cmd_tune(args) -> int:
    from .tune import tune

    out = args.out or f"runs/tune/{args.preset}"
    config = _config(args)
    config.progress = False
    from .tune import HEARTBEAT_S

    study = tune(args.data, args.preset, out, args.trials, storage=args.storage, study_name=args.study,
                 config=config, seed=args.seed, workers=args.workers, heartbeat_s=args.heartbeat or HEARTBEAT_S)
    best = study.best_trial
    print(f"best of {len(study.trials)} trials: val loss {best.value:.4f} with {best.params} "
          f"-> {best.user_attrs.get('model_dir')}")
    return 0
