"""Does a profile's recipe, the net's capacity or the data end a learned row? Retrain one preset with overrides.

Trains ``--preset`` on ``--data`` with the ``--profile``'s recipe and the given TrainConfig
overrides (``--set lr_patience=8``), and prints how the run stopped, the kept epoch, the
validation loss and, on the preset's target (joint torque or tip force), the test RMSE and nMSE
(per-component test MSE / test-target variance, averaged), the bench's metrics. One thread,
deterministic given the profile's seed. Choose on the validation loss; the test figures are for
reference only.

Two more controls: ``--arch FIELD=VALUE`` changes the preset (a larger-capacity control, e.g.
``--arch fc_units=128``; the model is named ``<preset>+<changes>``), and ``--train-instances K``
trains on the first K training instances only (validation and test unchanged): a data-size
control without generating new data.

Run (the control of stop 15's note, KUKA's tau-mlp-wide under the real profile):
    .venv/bin/python benchmarks/recipe_control.py --data data/real-kuka-... --preset tau-mlp-wide \\
        --profile real --set lr_patience=8 --out /tmp/kuka-control
"""
from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from hybrid_dyn.bench.metrics import nmse, rmse
from hybrid_dyn.bench.profiles import get_profile
from hybrid_dyn.data.dataset import Dataset, load_dataset
from hybrid_dyn.learn import get_preset, train_model


def first_training_instances(ds: Dataset, k: int) -> Dataset:
    """``ds`` with only its first ``k`` training instances (validation and test as they are). The
    manifest's instance list shrinks with it, so the data checksum, and with it the training
    fingerprint, tells this subset from the whole set."""
    train = ds.meta["splits"]["train"]
    if not 1 <= k <= len(train):
        raise SystemExit(f"--train-instances must be in 1..{len(train)}, got {k}")
    keep = set(train[:k]) | set(ds.meta["splits"]["val"]) | set(ds.meta["splits"]["test"])
    meta = {**ds.meta, "splits": {**ds.meta["splits"], "train": train[:k]},
            "instances": [r for r in ds.meta["instances"] if r["name"] in keep]}
    return Dataset(ds.path, meta, {n: i for n, i in ds.instances.items() if n in keep})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="a dataset folder")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--profile", default="default", help="whose training recipe")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="a TrainConfig override, the value as JSON (repeat for more)")
    ap.add_argument("--arch", action="append", default=[], metavar="FIELD=VALUE",
                    help="a Preset override, the value as JSON (repeat for more), e.g. fc_units=128")
    ap.add_argument("--train-instances", type=int, default=None, metavar="K",
                    help="train on the first K training instances only")
    ap.add_argument("--out", required=True, help="model folder (a new one per control)")
    args = ap.parse_args(argv)
    overrides = {k: json.loads(v) for k, v in (s.split("=", 1) for s in args.set)}
    config = dataclasses.replace(get_profile(args.profile).train_config(), num_threads=1, progress=False, **overrides)
    ds = load_dataset(args.data)
    if args.train_instances is not None:
        ds = first_training_instances(ds, args.train_instances)
    preset = get_preset(args.preset)
    changes = {k: json.loads(v) for k, v in (s.split("=", 1) for s in args.arch)}
    if changes:
        changes = {k: tuple(v) if isinstance(v, list) else v for k, v in changes.items()}
        preset = preset.replace(name=preset.name + "+" + ",".join(f"{k}={v}" for k, v in changes.items()), **changes)
    model = train_model(ds, preset, Path(args.out), config)
    test = ds.split("test")
    pred = np.concatenate(model.predict(test))
    target, = preset.targets
    y = np.concatenate([getattr(i, target) for i in test])
    n_train = len(ds.split("train"))
    print(f"{preset.name} {overrides} ({n_train} training instances, {model.n_params} parameters): "
          f"{model.config['epochs']} epochs, stopped by {model.config['stopped_by']}, "
          f"best epoch {model.config['best_epoch']}, val loss {model.val_loss:.5f}, "
          f"test RMSE {rmse(pred, y):.4f}, test nMSE {nmse(pred, y):.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
