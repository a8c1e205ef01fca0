"""The budget study behind the budgeted recipe's step counts (issue 26).

For one preset of each learned family, train under the ``budget`` recipe at a ladder of step
budgets (0.25x to 4x a base budget) on the same data, one torch thread, and print the best
validation loss (standardized MSE) against the budget, with the gain of each doubling. The
knee rule: the smallest budget whose doubling lowers the validation loss by less than
``--knee`` (3 %). The test split is never read.

Data: ``--data DIR``, or a simulated ``--scenario`` set generated once (resumable, byte-identical
for one machine) under ``--data-root``. Every run trains into its own folder under ``--work``, so
a killed study continues where it stopped, and a finished one prints again in seconds.

    nice .venv/bin/python benchmarks/budget_study.py --scenario seed-sim --instances 20 \\
        --out docs/figures/budget_study_seed-sim.md
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hybrid_dyn.data import DatasetError, load_dataset
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn.presets import get_preset

# One preset per family (the family's best row on seed-sim under the default recipe, where it has one).
STUDY_PRESETS = {"seed-tau-mlp": "MLP", "seed-tip-4": "conv", "seed-tau-lstm-opt": "LSTM",
                 "residual-rnea": "residual on RNEA", "delan-friction": "DeLaN"}
MULTIPLES = (0.25, 0.5, 1.0, 2.0, 4.0)


def study_dataset(args):
    if args.data:
        return load_dataset(args.data)
    from hybrid_dyn.sim.generator import generate_dataset
    from hybrid_dyn.sim.scenarios import scenario_config

    cfg = scenario_config(args.scenario, "quick", seed=args.data_seed, n_instances=args.instances,
                          trajectories=tuple(args.trajectories))
    path = Path(args.data_root) / f"{cfg.scenario}-{cfg.n_instances}-{cfg.config_hash()[:12]}"
    try:
        return load_dataset(path)
    except DatasetError:
        print(f"[budget] generating {cfg.scenario}: {cfg.n_instances} instances into {path}", flush=True)
        generate_dataset(cfg, path, workers=args.workers)
        return load_dataset(path)


def knee(budgets: list[int], losses: list[float], tolerance: float) -> int | None:
    """The smallest budget whose doubling (the next rung) lowers the loss by less than ``tolerance``."""
    for (b, l), l2 in zip(zip(budgets, losses), losses[1:]):
        if (l - l2) / l < tolerance:
            return b
    return None


def batch_sweep(ds, preset: str, batches: list[int], ref_steps: int, work: Path) -> list[str]:
    """Batch size against validation loss at equal wall time (issue 26): the rate scaled as the square
    root of the batch from 2e-3 at 1024 (Malladi et al. 2022, for Adam), and each batch given the steps
    that the bare step's measured throughput fits into the time of ``ref_steps`` at 1024.

    The throughputs are measured once (interleaved, one thread) and kept in ``work``, so a rerun reuses
    the same step counts, and with them its trained models.
    """
    import json
    import math

    from hybrid_dyn.learn.speed import bare_step, interleaved_rates, training_windows

    work.mkdir(parents=True, exist_ok=True)
    measured = work / f"{preset}-throughput.json"
    if measured.is_file():
        rates = json.loads(measured.read_text())
    else:
        probe = train_model(ds, preset, work / f"{preset}-probe",
                            TrainConfig.recipe("budget", budget_steps=1, budget_evals=1, progress=False, num_threads=1))
        ws = training_windows(probe, ds)
        rates = dict(zip(map(str, batches), interleaved_rates([bare_step(probe, ws, b) for b in batches], 10, 5)))
        measured.write_text(json.dumps(rates))
    out = []
    for b in batches:
        steps = max(1, round(ref_steps * rates[str(b)] / rates["1024"] * 1024 / b))
        lr = 2e-3 * math.sqrt(b / 1024)
        cfg = TrainConfig.recipe("budget", batch_size=b, lr=lr, budget_steps=steps, progress=False, num_threads=1)
        model = train_model(ds, preset, work / f"{preset}-b{b}-{steps}", cfg)
        out.append(f"| {preset} | {b} | {lr:.2e} | {rates[str(b)]:.0f} | {steps} | {model.train_seconds:.0f} "
                   f"| {model.val_loss:.5f} |")
        print(f"[batch] {out[-1]}", flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None)
    ap.add_argument("--scenario", default="seed-sim")
    ap.add_argument("--instances", type=int, default=20)
    ap.add_argument("--trajectories", type=int, nargs=2, default=[5, 20])
    ap.add_argument("--data-seed", type=int, default=0)
    ap.add_argument("--data-root", default="data")
    ap.add_argument("--workers", type=int, default=1, help="generation workers")
    ap.add_argument("--work", default="runs/budget-study")
    ap.add_argument("--presets", nargs="+", default=list(STUDY_PRESETS))
    ap.add_argument("--base-steps", type=int, default=2000, help="the 1x budget [optimizer steps]")
    ap.add_argument("--multiples", type=float, nargs="+", default=list(MULTIPLES))
    ap.add_argument("--cap", nargs="+", default=[], metavar="PRESET=STEPS",
                    help="train PRESET at no budget above STEPS (its dearer cells print '-')")
    ap.add_argument("--knee", type=float, default=0.03, help="a doubling that gains less than this is past the knee")
    ap.add_argument("--reference", default=None, metavar="RECIPE",
                    help="also train each preset under this epoch recipe (e.g. default) and print its loss and time")
    ap.add_argument("--batch-sweep", type=int, nargs="+", default=None, metavar="BATCH",
                    help="instead: batch sizes compared at equal wall time to --base-steps at batch 1024")
    ap.add_argument("--out", default=None, help="write the markdown table here (and a PNG beside it)")
    args = ap.parse_args()

    ds = study_dataset(args)
    if args.batch_sweep:
        batches = sorted(set(args.batch_sweep) | {1024})
        lines = [f"Batch size at equal wall time on `{ds.meta.get('scenario')}` ({len(ds.split('train'))} training "
                 f"instances): recipe `budget`, lr = 2e-3 x sqrt(batch / 1024), steps = {args.base_steps} at 1024 "
                 "scaled by the bare step's measured throughput; one torch thread; best validation loss.", "",
                 "| preset | batch | lr | bare samples/s | steps | train s | val loss |", "|---|---|---|---|---|---|---|"]
        for preset in args.presets:
            lines += batch_sweep(ds, preset, batches, args.base_steps,
                                 Path(args.work) / f"{ds.checksum[:12]}" / "batch-sweep")
        text = "\n".join(lines) + "\n"
        print(text)
        if args.out:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(text)
        return 0
    n_train = sum(len(i) for i in ds.split("train"))
    budgets = [int(round(m * args.base_steps)) for m in args.multiples]
    lines = [f"Budget study on `{ds.meta.get('scenario')}` ({len(ds.split('train'))} training instances, "
             f"{n_train} samples), recipe `budget` (batch 1024, lr 2e-3, 5 % warm-up, cosine to zero), "
             f"one torch thread; best validation loss (standardized MSE), seed 0.", "",
             "| family | preset | " + " | ".join(f"{b} steps" for b in budgets) + " | knee (< "
             f"{args.knee:.0%} per doubling) | s at knee |"
             + (f" recipe `{args.reference}`: val (epochs, s) |" if args.reference else ""),
             "|" + "---|" * (len(budgets) + 4 + bool(args.reference))]
    curves = {}
    caps = {k: int(v) for k, v in (c.split("=", 1) for c in args.cap)}
    for preset in args.presets:
        losses, secs = [], []
        for b in budgets:
            if b > caps.get(preset, b):
                continue
            cfg = TrainConfig.recipe("budget", budget_steps=b, progress=False, num_threads=1)
            t0 = time.perf_counter()
            model = train_model(ds, preset, Path(args.work) / f"{ds.checksum[:12]}" / f"{preset}-{b}", cfg)
            losses.append(model.val_loss)
            secs.append(model.train_seconds)
            print(f"[budget] {preset:20s} {b:6d} steps  val {model.val_loss:.5f}  train {model.train_seconds:7.1f} s"
                  f"  ({time.perf_counter() - t0:.1f} s this run)", flush=True)
        ran = budgets[:len(losses)]
        k = knee(ran, losses, args.knee)
        curves[preset] = (ran, losses)
        cells = [f"{l:.5f}" + ("" if i == 0 else f" ({(l - losses[i - 1]) / losses[i - 1]:+.1%})")
                 for i, l in enumerate(losses)] + ["-"] * (len(budgets) - len(losses))
        at = f"{secs[ran.index(k)]:.0f}" if k else "-"
        ref = ""
        if args.reference:
            cfg = TrainConfig.recipe(args.reference, progress=False, num_threads=1)
            model = train_model(ds, preset, Path(args.work) / f"{ds.checksum[:12]}" / f"{preset}-{args.reference}", cfg)
            ref = f" {model.val_loss:.5f} ({model.config['epochs']}, {model.train_seconds:.0f}) |"
            print(f"[budget] {preset:20s} recipe {args.reference}: val {model.val_loss:.5f}, {model.config['epochs']} "
                  f"epochs ({model.config['stopped_by']}), train {model.train_seconds:.1f} s", flush=True)
        lines.append(f"| {STUDY_PRESETS.get(preset, get_preset(preset).kind)} | {preset} | " + " | ".join(cells)
                     + f" | {k if k else 'not reached'} | {at} |" + ref)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4))
        for preset, (ran, losses) in curves.items():
            ax.loglog(ran, np.array(losses) / losses[0], "o-", label=f"{preset}")
        ax.set_xlabel("budget [optimizer steps, batch 1024]")
        ax.set_ylabel("best validation loss / loss at the smallest budget")
        ax.set_title(f"budget study, {ds.meta.get('scenario')}")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out.with_suffix(".png"), dpi=110)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
