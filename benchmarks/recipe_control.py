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


def run_control(data, preset_name: str, out, profile: str = "default", train: dict | None = None,
                arch: dict | None = None, train_instances: int | None = None) -> dict:
    """Train (or reuse, when ``out`` holds this very run) one control and score it; returns how it stopped,
    its validation loss and its test RMSE and nMSE on the preset's target. ``data``: a dataset folder,
    or a loaded :class:`Dataset` (a caller running many controls verifies its files once)."""
    train = dict(train or {})
    config = dataclasses.replace(get_profile(profile).train_config(), num_threads=1, progress=False, **train)
    ds = data if isinstance(data, Dataset) else load_dataset(data)
    if train_instances is not None:
        ds = first_training_instances(ds, train_instances)
    preset = get_preset(preset_name)
    if arch:
        arch = {k: tuple(v) if isinstance(v, list) else v for k, v in arch.items()}
        preset = preset.replace(name=preset.name + "+" + ",".join(f"{k}={v}" for k, v in arch.items()), **arch)
    model = train_model(ds, preset, Path(out), config)
    test = ds.split("test")
    pred = np.concatenate(model.predict(test))
    target, = preset.targets
    y = np.concatenate([getattr(i, target) for i in test])
    h = model.config["history"]
    best = model.config["best_epoch"]
    return dict(model=preset.name, train=train, n_train=len(ds.split("train")), n_params=model.n_params,
                epochs=model.config["epochs"], stopped_by=model.config["stopped_by"], best_epoch=best,
                train_loss=h[best]["train_loss"] if best >= 0 else float("nan"), val_loss=model.val_loss,
                test_rmse=rmse(pred, y), test_nmse=nmse(pred, y), unit="N" if target == "tip_force" else "Nm")


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
    parse = lambda items: {k: json.loads(v) for k, v in (s.split("=", 1) for s in items)}  # noqa: E731
    r = run_control(args.data, args.preset, args.out, args.profile, parse(args.set), parse(args.arch),
                    args.train_instances)
    print(f"{r['model']} {r['train']} ({r['n_train']} training instances, {r['n_params']} parameters): "
          f"{r['epochs']} epochs, stopped by {r['stopped_by']}, best epoch {r['best_epoch']}, "
          f"train loss {r['train_loss']:.5f}, val loss {r['val_loss']:.5f}, "
          f"test RMSE {r['test_rmse']:.4f} {r['unit']}, test nMSE {r['test_nmse']:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
