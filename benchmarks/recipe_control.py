"""Does a profile's stopping rule, not the data, end a learned row? Retrain one preset with overrides.

Trains ``--preset`` on ``--data`` with the ``--profile``'s recipe and the given TrainConfig
overrides (``--set lr_patience=8``), and prints how the run stopped, the kept epoch, the
validation loss and the test nMSE (per-joint test MSE / test-target variance, averaged), the
bench's metric. One thread, deterministic given the profile's seed.

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

from hybrid_dyn.bench.metrics import nmse
from hybrid_dyn.bench.profiles import get_profile
from hybrid_dyn.data.dataset import load_dataset
from hybrid_dyn.learn import train_model


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="a dataset folder")
    ap.add_argument("--preset", required=True)
    ap.add_argument("--profile", default="default", help="whose training recipe")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="a TrainConfig override, the value as JSON (repeat for more)")
    ap.add_argument("--out", required=True, help="model folder (a new one per control)")
    args = ap.parse_args(argv)
    overrides = {k: json.loads(v) for k, v in (s.split("=", 1) for s in args.set)}
    config = dataclasses.replace(get_profile(args.profile).train_config(), num_threads=1, progress=False, **overrides)
    ds = load_dataset(args.data)
    model = train_model(ds, args.preset, Path(args.out), config)
    test = ds.split("test")
    pred = np.concatenate(model.predict(test))
    y = np.concatenate([i.tau_m for i in test])
    score = nmse(pred, y)
    print(f"{args.preset} {overrides}: {model.config['epochs']} epochs, stopped by {model.config['stopped_by']}, "
          f"best epoch {model.config['best_epoch']}, val loss {model.val_loss:.4f}, test nMSE {score:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
