"""Whether a default-report row's kept round is the budget patience's: retrain one learned row of the default
profile on its cached dataset with the profile's training config but ``budget_patience=None`` (the whole
budget), and print the round it keeps and its validation loss, to compare with the row in
``reports/default/curves.json`` (``best_epoch``, the history's val_loss).

Run (after the default bench, whose datasets it reads from data/):
    .venv/bin/python benchmarks/retrain_without_patience.py mismatch-ext seed-tau-conv --out /tmp/nopat
"""
from __future__ import annotations

import argparse
import dataclasses
import glob

from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.bench.profiles import PROFILES
from hybrid_dyn.bench.training_queue import set_torch_threads
from hybrid_dyn.data import load_dataset
from hybrid_dyn.learn import train_model


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("row")
    ap.add_argument("--data-root", default="data")
    ap.add_argument("--out", default="/tmp/nopat")
    args = ap.parse_args(argv)
    set_torch_threads(1)  # as the bench's workers train
    found = sorted(glob.glob(f"{args.data_root}/{args.scenario}-default-*"))
    if not found:
        raise SystemExit(f"no default-size dataset of {args.scenario} under {args.data_root}: run the default bench first")
    ds = load_dataset(found[0])
    ds.meta["robot"] = "panda"
    plan = BenchPlan(PROFILES.lookup("default"))
    cfg = dataclasses.replace(plan.train_config(), budget_patience=None, progress=False)
    model = train_model(ds, plan.preset(args.row), f"{args.out}/{args.scenario}-{args.row}", config=cfg)
    print(f"{args.scenario} {args.row}: whole budget, {len(model.config['history'])} rounds; kept round "
          f"{model.config['best_epoch']}, validation loss {model.val_loss:.6g}")


if __name__ == "__main__":
    main()
