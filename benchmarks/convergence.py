"""Convergence check of a bench report's learned rows (issues 14, 26): does more training still pay?

Under the budgeted recipe (the bench's, issue 26) the longer run is the same preset at ``--factor``
(2) times its step budget, and a row counts as converged when the gain is below 3 %
(``--tolerance``). Under an epoch recipe it is the patience check below.

For the best row of each learned family and task (lowest test RMSE among the rows that
trained, reference rows aside) of every scenario of a report, retrain the same preset on
the same data with the same recipe but ``--factor`` (4) times both patiences, the early
stopping's and the learning-rate plateau's (and a rate floor low enough that patience, not the
floor, ends it: :func:`longer_run`), and compare the best validation loss (standardized MSE) of the two runs:

    gain = (val_loss(patience P) - val_loss(patience 4P)) / val_loss(patience P)

A row counts as converged when the gain is below ``--tolerance`` (5 %). The bench's own
model is reused from its cache (nothing is retrained for it); the longer runs train into
``<work dir>/convergence/<preset>-patience<4P>-lr<4P_lr>`` and are reused on a rerun, so a killed
check resumes. Deterministic given the profile's seed.

Run (after the bench, with the same data and model caches):
    .venv/bin/python benchmarks/convergence.py --report reports/seed-sim --out reports/seed-sim/convergence.md
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import sys
import time
from pathlib import Path

from hybrid_dyn.bench.integrity import recorded_profile
from hybrid_dyn.bench.profiles import BenchProfile, get_profile
from hybrid_dyn.bench.runner import read_results, work_dir
from hybrid_dyn.learn import PRESETS, TrainConfig, train_model

REFERENCE_SUFFIX = "-raw"  # labelled reference rows are not a family's best


def best_rows(rows: list[dict]) -> list[dict]:
    """The lowest-RMSE trained row per (scenario, task, family), among rows that are presets trained on
    the profile's config (a residual on an identified model trains on its own parameter file: not here)."""
    best: dict = {}
    for r in rows:
        if r.get("status") != "ok" or not r.get("stopped_by") or r["model"].endswith(REFERENCE_SUFFIX) \
                or r["model"] not in PRESETS:
            continue
        key = (r["scenario"], r["task"], r["family"])
        if key not in best or float(r["rmse"]) < float(best[key]["rmse"]):
            best[key] = r
    return [best[k] for k in sorted(best)]


def longer_run(config: TrainConfig, factor: int) -> TrainConfig:
    """The recipe with ``factor`` x both patiences (early stopping and the plateau schedule), and the
    learning-rate floor lowered so that the longer run ends by patience, not by the floor.

    Both, because with the plateau's patience left at 3 the longer run retraces the original one
    epoch for epoch (training is deterministic) and only adds epochs at ever smaller rates: every
    such check of stop 15 gained exactly 0.0 %, which tests the tail of the schedule, not whether
    the rate was cut too early. (KUKA's tau-mlp-wide under the real profile was: its validation
    loss falls only after ~100 epochs at 1e-3.) The floor is set one cut below what
    ``factor x patience`` bad epochs could reach."""
    patience = config.patience * factor
    lr_patience = config.lr_patience * factor
    cuts = math.ceil(patience / lr_patience) + 1
    return dataclasses.replace(config, patience=patience, lr_patience=lr_patience,
                               min_lr=config.min_lr * config.lr_factor ** cuts)


def budget_longer_run(config: TrainConfig, preset: str, factor: int) -> TrainConfig:
    """The budgeted recipe at ``factor`` x the preset's own step budget (the schedule stretched with it)."""
    from hybrid_dyn.learn.presets import get_preset

    own = config.for_preset(get_preset(preset))
    return dataclasses.replace(own, budget_steps=own.budget_steps * factor)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--report", required=True, help="a bench report folder (results.csv, run.json)")
    ap.add_argument("--data-root", default="data")
    ap.add_argument("--work-root", default="runs")
    ap.add_argument("--factor", type=int, default=None,
                    help="budget (default 2) or patience (default 4) multiple of the longer run")
    ap.add_argument("--tolerance", type=float, default=None,
                    help="largest relative val-loss gain that counts as converged (default: 3 %% budget, 5 %% epochs)")
    ap.add_argument("--scenario", action="append", default=None,
                    help="check only this scenario's rows (repeat for more; default: every scenario of the report)")
    ap.add_argument("--model", action="append", default=None,
                    help="check only this row (repeat for more; default: the best row of every family)")
    ap.add_argument("--out", default=None, help="write the table to this markdown file")
    ap.add_argument("--quiet", action="store_true", help="no per-batch progress bar (a log stays readable)")
    args = ap.parse_args()

    report = Path(args.report)
    run = json.loads((report / "run.json").read_text())
    profile = get_profile(run["profile"]["name"])
    recorded = recorded_profile(run["profile"])  # an old recipe name is the same recipe (issue 30)
    if profile.to_dict() != recorded:  # the report must be of this code's profile, or its models differ
        fields = {("generator_size" if k == "generator_profile" else k): v for k, v in recorded.items()}  # run.json's key
        profile = BenchProfile(**{k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()})
    # The bench's own thread count: torch's default (one thread per core) oversubscribes the cores
    # when two checks run side by side, and these tiny nets then train 10x slower (measured).
    config = dataclasses.replace(profile.train_config(), num_threads=profile.torch_threads, progress=not args.quiet)
    budgeted = config.budgeted
    args.factor = args.factor or (2 if budgeted else 4)
    args.tolerance = args.tolerance if args.tolerance is not None else (0.03 if budgeted else 0.05)
    longer = None if budgeted else longer_run(config, args.factor)
    lines = [f"# Convergence check of `{report}`", "",
             f"`{' '.join(sys.argv)}`, {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.", ""]
    if budgeted:
        lines += [f"The best trained row of each family and task (lowest test RMSE), retrained under recipe "
                  f"`{profile.recipe}` at {args.factor}x its step budget. Gain: the relative drop of the best "
                  f"validation loss; converged when below {args.tolerance:.0%}.", "",
                  "| scenario | task | family | model | steps | val loss | steps, longer | val loss | gain | converged |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
    else:
        lines += [
             f"The best trained row of each family and task (lowest test RMSE), retrained with patience "
             f"{longer.patience} instead of {config.patience}, the learning-rate plateau's patience {longer.lr_patience} "
             f"instead of {config.lr_patience} and its floor lowered from {config.min_lr:g} to "
             f"{longer.min_lr:.1e}, so that it ends by patience (recipe `{profile.recipe}` otherwise). "
             f"Gain: the relative drop of the best validation loss; converged when below {args.tolerance:.0%}.", "",
             "| scenario | task | family | model | epochs (stop) | val loss | epochs (stop), patience "
             f"{longer.patience} | val loss | gain | converged |", "|---|---|---|---|---|---|---|---|---|---|"]
    failures = 0
    datasets = {}
    for r in best_rows(read_results(report / "results.csv")):
        scenario = r["scenario"]
        if (args.scenario and scenario not in args.scenario) or (args.model and r["model"] not in args.model):
            continue
        if scenario not in datasets:
            datasets[scenario] = profile.dataset(scenario, Path(args.data_root))
        ds = datasets[scenario]
        wd = work_dir(profile, scenario, ds, Path(args.work_root))
        base = train_model(ds, r["model"], wd / "models" / r["model"], config)  # the bench's own model
        t0 = time.perf_counter()
        if budgeted:
            run_cfg = budget_longer_run(config, r["model"], args.factor)
            label = f"{run_cfg.budget_steps} steps"
            folder = f"{r['model']}-steps{run_cfg.budget_steps}"
        else:
            run_cfg, label = longer, f"patience {longer.patience}"
            folder = f"{r['model']}-patience{longer.patience}-lr{longer.lr_patience}"
        print(f"[convergence] {scenario} {r['family']} {r['model']}: {label}", flush=True)
        long = train_model(ds, r["model"], wd / "convergence" / folder, run_cfg)
        # A loss at round-off (physics exact on noise-free data) has nothing left to gain.
        gain = (base.val_loss - long.val_loss) / base.val_loss if base.val_loss > 1e-12 else 0.0
        ok = gain < args.tolerance
        failures += not ok
        if budgeted:
            lines.append(f"| {scenario} | {r['task']} | {r['family']} | {r['model']} | "
                         f"{base.config['train_config']['budget_steps']} | {base.val_loss:.5f} | {run_cfg.budget_steps} "
                         f"| {long.val_loss:.5f} | {gain:+.1%} | {'yes' if ok else 'NO'} |")
        else:
            lines.append(f"| {scenario} | {r['task']} | {r['family']} | {r['model']} | {base.config['epochs']} "
                         f"({base.config.get('stopped_by')}) | {base.val_loss:.5f} | {long.config['epochs']} "
                         f"({long.config.get('stopped_by')}) | {long.val_loss:.5f} | {gain:+.1%} | "
                         f"{'yes' if ok else 'NO'} |")
        print(lines[-1], f"({time.perf_counter() - t0:.0f} s)", flush=True)
        if args.out:  # after every row: an interrupted check keeps what it measured
            Path(args.out).write_text("\n".join(lines + ["", "(incomplete: the check is still running or was "
                                                          "interrupted)"]) + "\n")
    lines += ["", f"{failures} row(s) not converged by this test."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
