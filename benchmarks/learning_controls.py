"""What limits the learned rows on a dataset: the recipe, the net's capacity or the data? (issue 14)

Each control retrains one preset of the bench with one thing changed and is compared, on the
validation loss (standardized MSE, what every choice is made on), with the preset trained by the
profile's own recipe:

- recipe: a longer plateau and early-stopping patience (does the schedule stop the net too early?),
  and decoupled weight decay (``TrainConfig.weight_decay``: does regularisation close a gap
  between training and validation loss?);
- capacity: wider or deeper fully connected layers (does the net underfit?);
- data: the same net on the first 6 and 13 of the 26 training instances (how fast does the
  validation loss fall with data? Validation and test instances are the same in every control).

On the ``default`` profile (paper-noext) it compares the bench's recipe with the ``long`` one
(``learn.train.RECIPES``) on the torque rows of the profile's floors.

The train-loss column is the epoch's running mean at the kept epoch. Test figures are printed for
reference only: nothing was chosen on them. Controls train into ``--work-root`` (one folder each)
and a rerun reuses every finished one; deterministic given the profile's seed; one torch thread each.

Run (after ``hybrid-dyn bench --profile seed-sim``, whose dataset it reads from the data cache):
    .venv/bin/python benchmarks/learning_controls.py --profile seed-sim --out reports/seed-sim/controls.md
    .venv/bin/python benchmarks/learning_controls.py --profile default --out reports/default/controls.md
    .venv/bin/python benchmarks/learning_controls.py --profile default-data --out reports/default/data_trade.md
"""
from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from recipe_control import run_control  # noqa: E402

from convergence import longer_run  # noqa: E402

from hybrid_dyn.bench.profiles import get_profile  # noqa: E402
from hybrid_dyn.learn.train import RECIPES, TrainConfig  # noqa: E402

LONG = RECIPES["long"]  # the longer patiences and weight decay 0.1
LONGER = {k: LONG[k] for k in ("lr_patience", "patience")}  # the longer patiences alone
# The convergence check of `long`, built as convergence.py builds it: 4x both patiences, the rate
# floor lowered so that patience, not the floor, ends the run.
_LONG_4X = longer_run(TrainConfig.recipe("long"), 4)
LONG_4X = {**LONG, **{k: getattr(_LONG_4X, k) for k in ("patience", "lr_patience", "min_lr")}}
LONG_CHECKED = ("seed-tau-mlp", "seed-tau-lstm-opt", "delan-friction")
# The default profile's torque rows on paper-noext, the scenario of its floors: the best row of each
# family in reports/default, and the other seed torque nets.
DEFAULT_ROWS = ("seed-tau-mlp", "seed-tau-conv", "seed-tau-lstm", "seed-tau-lstm-opt", "tau-mlp-wide",
                "residual-rnea-bw", "delan-friction")

# (what is asked, preset, TrainConfig changes, Preset changes, training instances). The first
# row of each preset is its bench run (the profile's recipe on all the training data).
CONTROLS = {
    "seed-sim": [
        ("bench recipe", "seed-tip-10", {}, {}, None),
        ("recipe: longer patience", "seed-tip-10", LONGER, {}, None),
        ("recipe: weight decay 0.1", "seed-tip-10", {"weight_decay": 0.1}, {}, None),
        ("recipe: weight decay 1", "seed-tip-10", {"weight_decay": 1.0}, {}, None),
        ("recipe: weight decay 3", "seed-tip-10", {"weight_decay": 3.0}, {}, None),
        ("data: 13 of 26 instances", "seed-tip-10", {}, {}, 13),
        ("data: 6 of 26 instances", "seed-tip-10", {}, {}, 6),
        ("bench recipe", "seed-tip-4", {}, {}, None),
        ("recipe: weight decay 0.1", "seed-tip-4", {"weight_decay": 0.1}, {}, None),
        ("data: 13 of 26 instances", "seed-tip-4", {}, {}, 13),
        ("data: 6 of 26 instances", "seed-tip-4", {}, {}, 6),
        ("bench recipe", "seed-tau-mlp", {}, {}, None),
        ("recipe: longer patience", "seed-tau-mlp", LONGER, {}, None),
        ("recipe: weight decay 0.1", "seed-tau-mlp", {"weight_decay": 0.1}, {}, None),
        ("recipe: weight decay 1", "seed-tau-mlp", {"weight_decay": 1.0}, {}, None),
        ("capacity: FC 2 x 256", "seed-tau-mlp", {}, {"fc_units": 256}, None),
        ("capacity: FC 3 x 256", "seed-tau-mlp", {}, {"fc_units": 256, "fc_layers": 3}, None),
        ("data: 13 of 26 instances", "seed-tau-mlp", {}, {}, 13),
        ("data: 6 of 26 instances", "seed-tau-mlp", {}, {}, 6),
        ("bench recipe", "delan-friction", {}, {}, None),
        ("recipe: longer patience", "delan-friction", LONGER, {}, None),
        ("recipe: weight decay 0.1", "delan-friction", {"weight_decay": 0.1}, {}, None),
    ],
    "default": [c for p in DEFAULT_ROWS for c in (("bench recipe", p, {}, {}, None),
                                                    ("recipe: long", p, LONG, {}, None))
                + ((("recipe: long, 4x patience", p, LONG_4X, {}, None),) if p in LONG_CHECKED else ())],
    # What fitting the default bench into its time limit by shrinking the data would cost (issue 14's
    # rule: shrink the data, never the training): long on all 26 training instances of paper-noext
    # against long on the first 13; validation and test instances are the same in both.
    "default-data": [c for p in ("seed-tau-mlp", "seed-tau-lstm", "seed-tau-lstm-opt", "residual-rnea-bw",
                                 "delan-friction")
                     for c in (("recipe: long", p, LONG, {}, None),
                               ("recipe: long, data 13 of 26 instances", p, LONG, {}, 13))],
}
PROFILE_OF = {"default-data": "default"}  # control sets named other than their bench profile


def control_dir(work_root: Path, preset: str, train: dict, arch: dict, n: int | None) -> Path:
    parts = [preset] + [f"{k}{v}" for k, v in sorted({**train, **arch}.items())] + ([f"k{n}"] if n else [])
    return work_root / "-".join(parts).replace(" ", "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="seed-sim", choices=sorted(CONTROLS))
    ap.add_argument("--scenario", default=None, help="the profile's scenario (default: its first)")
    ap.add_argument("--data-root", default="data")
    ap.add_argument("--work-root", default="runs/controls")
    ap.add_argument("--only", action="append", default=None, help="run only this preset's controls (repeat)")
    ap.add_argument("--out", default=None, help="write the table to this markdown file")
    args = ap.parse_args(argv)
    profile = get_profile(PROFILE_OF.get(args.profile, args.profile))
    scenario = args.scenario or profile.scenarios[0]
    data = profile.dataset(scenario, Path(args.data_root))
    root = Path(args.work_root) / args.profile / scenario
    lines = [f"# What limits the learned rows on `{scenario}`: recipe, capacity or data",
             "", f"`{' '.join(['benchmarks/learning_controls.py'] + (argv if argv is not None else sys.argv[1:]))}`, "
             f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; data `{data.path.name}`.", "",
             "Every control is chosen and read on the validation loss; test figures are for reference only.",
             "", "| preset | control | training instances | parameters | epochs (stop) | best epoch | "
             "train loss | val loss | val vs bench | test RMSE | test nMSE |", "|" + "---|" * 11]
    base, val_loss = {}, {}
    for label, preset, train, arch, n in CONTROLS[args.profile]:
        if args.only and preset not in args.only:
            continue
        out = control_dir(root, preset, train, arch, n)
        print(f"[controls] {preset}: {label} -> {out}", flush=True)
        r = run_control(data, preset, out, profile.name, train, arch, n)
        base.setdefault(preset, r["val_loss"])
        rel = r["val_loss"] / base[preset] - 1
        val_loss[(preset, label)] = r["val_loss"]
        if label == "recipe: long, 4x patience":  # the convergence check of long: its gain over long
            label += f" ({r['val_loss'] / val_loss[(preset, 'recipe: long')] - 1:+.1%} vs long)"
        row = (f"| {preset} | {label} | {r['n_train']} | {r['n_params']} | {r['epochs']} ({r['stopped_by']}) | "
               f"{r['best_epoch']} | {r['train_loss']:.4f} | {r['val_loss']:.4f} | {rel:+.1%} | "
               f"{r['test_rmse']:.4f} {r['unit']} | {r['test_nmse']:.4f} |")
        print(row, flush=True)
        lines.append(row)
        if args.out:  # written as controls finish, so an interrupted run keeps what it measured
            Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
