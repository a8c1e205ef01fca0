"""Speed of the learned models: training throughput and inference latency.

Prints, for each preset: training samples/s on CPU (epochs of the real
training loop, validation pass included), inference us per sample in batches,
and us per single call (one window, ``predict_window``, torch on one thread) with
the PyTorch path beside it. Medians of repeated measurements in this one run.

Floor (issue 4): single-call seed-tip-11 and residual-basewrench <= 200 us median.

    .venv/bin/python benchmarks/learn_speed.py [--data DIR] [--threads 1]

``--sweep`` (issue 14, item 2): the batch-size sweep behind the training recipe's
batch size. One preset per trained family (MLP, conv, LSTM, residual LSTM, DeLaN),
each batch size, trained to convergence with the ``default`` recipe on one torch
thread, the same seeds (``--seeds``) for every run. Per (preset, batch, seed) it
prints the measured training throughput, epochs, why training stopped, the wall
time, the best validation loss (standardized MSE) and the test RMSE; then it applies
the choice rule (:func:`pick_batch`, on the loss averaged over the seeds) and states
the pick. Data: ``--data DIR``, or by default a ``seed-sim`` set (20 Hz, exact
states, noise-free) of 12 instances of 5-20 trajectories, generated once into
``--data-root``; ``--scenario``, ``--instances`` and ``--trajectories`` change it.
Each run trains into its own folder under ``--work``, so a killed sweep continues
where it stopped.

    taskset -c 1 .venv/bin/python benchmarks/learn_speed.py --sweep --seeds 0 1 --out runs/batch-sweep.md

``--loop`` (issue 26): per family, at the budgeted recipe's batch, the training loop's samples/s
(``train_model`` under the ``budget`` recipe, validation rounds at the recipe's spacing of
``BUDGET_STEPS / budget_evals`` steps included) beside the bare forward-backward-Adam step of the
same module on one batch already in memory; and DeLaN's forward-mode terms beside the
``torch.func`` oracle (``terms_autograd``) in the same bare step. One torch thread, medians of
``--repeats`` in one run (loop/bare: the median of the ratios of each loop run and the bare step timed
right after it). Floors: loop >= 0.7x bare for every family; DeLaN (with friction)
forward-mode >= 2x the oracle.

    nice .venv/bin/python benchmarks/learn_speed.py --loop
"""
from __future__ import annotations

import argparse
import datetime
import hashlib
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import hybrid_dyn as hd
from hybrid_dyn.data import DatasetError, load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.windows import concat_fields
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn.model import canonical_json
from hybrid_dyn.learn.presets import get_preset
from hybrid_dyn.learn.speed import bare_step, interleaved_rates, training_windows

PRESETS = ["seed-tip-1", "seed-tip-11", "seed-tau-lstm-opt", "residual-basewrench", "residual-rnea", "delan",
           "delan-friction"]
TRAIN_PRESETS = {"seed-tip-11": "LSTM", "seed-tau-lstm-opt": "LSTM", "delan": "DeLaN", "delan-friction": "DeLaN"}
FLOOR_US = {"seed-tip-11": 200.0, "residual-basewrench": 200.0}


def median_us(fn, n: int, warmup: int = 50) -> float:
    for _ in range(warmup):
        fn()
    ts = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return float(np.median(ts) * 1e6)


# --------------------------------------------------------------------------- batch-size sweep
# One preset of each family that trains (family: what the row's net is).
SWEEP_PRESETS = {"seed-tau-mlp": "MLP", "seed-tip-5": "conv", "seed-tip-7": "LSTM", "residual-rnea": "residual LSTM",
                 "delan-friction": "DeLaN"}
SWEEP_BATCHES = (64, 128, 256, 512, 1024)
# Sized so that the sweep (25 runs to convergence) takes about half an hour on one shared core
# (~20 min measured; DeLaN is half of it). seed-sim, not mismatch-ext, because it generates
# far faster here: ~10 s per instance against ~100 s for a mismatch-ext instance of 5-10
# trajectories (one worker, on the loaded machine).
SWEEP_DATA = dict(scenario="seed-sim", size="quick", n_instances=12, trajectories=(5, 20), seed=0)


def sweep_dataset(args):
    """The sweep's dataset: ``--data``, or a small simulated set generated once and cached by its
    config hash under ``--data-root`` (as the bench caches its scenarios)."""
    if args.data:
        return load_dataset(args.data)
    from hybrid_dyn.sim.generator import generate_dataset
    from hybrid_dyn.sim.scenarios import scenario_config

    cfg = scenario_config(args.scenario, SWEEP_DATA["size"], seed=args.data_seed,
                          n_instances=args.instances, trajectories=tuple(args.trajectories))
    path = Path(args.data_root) / f"{cfg.scenario}-{cfg.size}-{cfg.config_hash()}"
    try:
        return load_dataset(path)
    except DatasetError:
        print(f"[sweep] generating {cfg.scenario}: {cfg.n_instances} instances of {cfg.trajectories[0]}-"
              f"{cfg.trajectories[1]} trajectories into {path}", flush=True)
        generate_dataset(cfg, path, workers=1)  # byte-identical for any worker count; one core here
        return load_dataset(path)


def sweep_work_dir(work_root: Path, ds, config: TrainConfig) -> Path:
    """One folder per dataset and recipe (batch size aside: that is what varies inside), so a
    changed recipe or dataset never meets models of another sweep."""
    fields = {k: v for k, v in config.fingerprint_fields().items() if k != "batch_size"}
    recipe = hashlib.sha256(canonical_json(fields).encode()).hexdigest()[:8]
    return Path(work_root) / f"{ds.checksum[:12]}-train-{recipe}"


def sweep_row(ds, preset: str, batch: int, config: TrainConfig, work: Path) -> dict:
    """Train (or reuse) one (preset, batch) run to convergence and measure it.

    samples/s: training samples over the training loop's own time (``model.train_seconds``:
    every epoch, its validation pass included), so a resumed run is timed over all its epochs.
    """
    model = train_model(ds, preset, work / f"{preset}-b{batch}", config)
    n_train = model.config["train_samples"]
    epochs = model.config["epochs"]
    seconds = model.train_seconds
    test = model.evaluate(ds.split("test"))
    return {"preset": preset, "family": SWEEP_PRESETS.get(preset, get_preset(preset).kind), "batch": batch,
            "seed": config.seed,
            "samples_per_s": epochs * n_train / seconds, "epochs": epochs, "stopped_by": model.config["stopped_by"],
            "best_epoch": model.config["best_epoch"], "wall_s": seconds, "val_loss": model.val_loss,
            "test_rmse": test["rmse"], "unit": "N" if model.targets == ["tip_force"] else "Nm"}


def mean_over_seeds(rows: list[dict]) -> list[dict]:
    """One row per (preset, batch): the best validation loss averaged over the seeds that ran, the
    wall time summed (what training them all costs). Seed-to-seed spread of the loss is often as
    large as the batch size's effect, so the rule is applied to the mean."""
    keys = list(dict.fromkeys((r["preset"], r["batch"]) for r in rows))
    out = []
    for preset, batch in keys:
        mine = [r for r in rows if r["preset"] == preset and r["batch"] == batch]
        out.append({"preset": preset, "batch": batch, "n_seeds": len(mine),
                    "val_loss": float(np.mean([r["val_loss"] for r in mine])),
                    "wall_s": float(sum(r["wall_s"] for r in mine))})
    return out


def pick_batch(rows: list[dict], tolerance: float) -> tuple[int | None, dict, float]:
    """The choice rule, quality first, then cost.

    ``rows``: one per (preset, batch), as :func:`mean_over_seeds` gives them. A size's *worst
    ratio* r(b) is the largest, over presets, of its best validation loss over that preset's best
    at any size (1: best for every family). r* = min_b r(b) is the best any
    one size can do for all families at once. A size is *admissible* when r(b) <= r* + tolerance:
    no family pays more than ``tolerance`` beyond what the best compromise costs it (when one size
    is best everywhere, r* = 1 and this is "within ``tolerance`` of the best for every family").
    Among the admissible sizes the pick is the one whose runs take the least wall time in total
    (the cost of training every family to convergence).

    Returns the pick (None: no size was run for every preset), per batch size its worst ratio,
    total wall time and admissibility, and r*.
    """
    presets = sorted({r["preset"] for r in rows})
    batches = sorted({r["batch"] for r in rows})
    best = {p: min(r["val_loss"] for r in rows if r["preset"] == p) for p in presets}
    summary = {}
    for b in batches:
        mine = [r for r in rows if r["batch"] == b]
        if {r["preset"] for r in mine} != set(presets):
            continue  # a batch size not run for every preset cannot be judged
        worst = max(r["val_loss"] / best[r["preset"]] for r in mine)
        summary[b] = {"worst_ratio": worst, "wall_s": sum(r["wall_s"] for r in mine)}
    if not summary:
        return None, summary, math.nan
    r_star = min(s["worst_ratio"] for s in summary.values())
    for s in summary.values():
        s["admissible"] = s["worst_ratio"] <= r_star + tolerance
    pick = min((b for b, s in summary.items() if s["admissible"]), key=lambda b: summary[b]["wall_s"])
    return pick, summary, r_star


def sweep_table(rows: list[dict], pick: int | None, summary: dict, r_star: float, tolerance: float,
                header: list[str]) -> str:
    best = {(p, sd): min(r["val_loss"] for r in rows if (r["preset"], r["seed"]) == (p, sd))
            for p, sd in {(r["preset"], r["seed"]) for r in rows}}
    lines = header + ["",
                      "| preset | family | seed | batch | train samples/s | epochs | stopped_by | best epoch | wall s "
                      "| best val loss | / preset's best (this seed) | test RMSE |",
                      "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['preset']} | {r['family']} | {r['seed']} | {r['batch']} | {r['samples_per_s']:.0f} "
                     f"| {r['epochs']} | {r['stopped_by']} | {r['best_epoch']} | {r['wall_s']:.1f} "
                     f"| {r['val_loss']:.5f} | {r['val_loss'] / best[(r['preset'], r['seed'])]:.3f} "
                     f"| {r['test_rmse']:.4f} {r['unit']} |")
    means = mean_over_seeds(rows)
    presets = list(dict.fromkeys(r["preset"] for r in means))
    batches = sorted({r["batch"] for r in means})
    mean_of = {(r["preset"], r["batch"]): r for r in means}
    lines += ["", "Best validation loss, mean over seeds (seeds run), and its ratio to the preset's best mean:", "",
              "| preset | " + " | ".join(str(b) for b in batches) + " |", "|---|" + "---|" * len(batches)]
    for p in presets:
        lo = min(r["val_loss"] for r in means if r["preset"] == p)
        cells = [f"{mean_of[p, b]['val_loss']:.4f} ({mean_of[p, b]['n_seeds']}) x{mean_of[p, b]['val_loss'] / lo:.3f}"
                 if (p, b) in mean_of else "-" for b in batches]
        lines.append(f"| {p} | " + " | ".join(cells) + " |")
    lines += ["", "| batch | worst mean val loss / preset's best | total wall s | admissible |", "|---|---|---|---|"]
    for b, s in summary.items():
        lines.append(f"| {b} | {s['worst_ratio']:.3f} | {s['wall_s']:.1f} | {'yes' if s['admissible'] else 'no'} |")
    largest = max((b for b, s in summary.items() if s["admissible"]), default=None)
    strict = [b for b, s in summary.items() if s["worst_ratio"] <= 1 + tolerance]
    lines += ["", f"Rule: worst ratio r(b) = the largest, over presets, of the mean best validation loss at batch "
                  f"b over that preset's best mean at any size; r* = min r(b) = {r_star:.3f}. Admissible: r(b) <= r* + "
                  f"{tolerance:.2f} (no family pays more than {tolerance:.0%} beyond the best compromise); the pick "
                  f"is the admissible size with the least total wall time.",
              f"Pick: **{pick}** (admissible: {', '.join(str(b) for b, s in summary.items() if s['admissible'])}; "
              f"largest admissible: {largest}; within {tolerance:.0%} of every preset's best: "
              f"{', '.join(map(str, strict)) or 'none'})."]
    return "\n".join(lines) + "\n"


def sweep(args) -> int:
    torch.set_num_threads(1)
    ds = sweep_dataset(args)
    sizes = {s: sum(len(i) for i in ds.split(s)) for s in ("train", "val", "test")}
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else "?"
    meta = ds.meta.get("config", {})
    data = (f"`{ds.path.name}`: scenario {ds.meta.get('scenario')}, {meta.get('n_instances', '?')} instances of "
            f"{meta.get('trajectories', '?')} trajectories, {ds.meta.get('record_hz')} Hz; samples train/val/test "
            f"{sizes['train']}/{sizes['val']}/{sizes['test']}")
    seeds = ", ".join(map(str, args.seeds))
    if args.one_seed:
        seeds += f" ({', '.join(args.one_seed)}: seed {args.seeds[0]} only)"
    header = ["# Batch-size sweep (`benchmarks/learn_speed.py --sweep`)", "",
              f"`{' '.join(sys.argv)}`, {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.", "",
              f"Data: {data}. Recipe `{args.recipe}` (batch size varied), seeds {seeds}, one torch thread, "
              f"torch {torch.__version__}, CPUs {cpus}. Models under `{args.work}` (one folder per dataset, "
              f"recipe and seed).",
              "Wall s: the training loop's time (every epoch with its validation pass), from which samples/s is "
              "derived. On a shared machine wall times and throughput are indicative (other jobs' load moves "
              "them several-fold); losses and epochs are deterministic for a given seed and machine."]
    print("\n".join(header), flush=True)
    rows = []
    for preset in args.presets:
        for batch in args.batch_sizes:
            seeds = args.seeds if preset not in args.one_seed else args.seeds[:1]
            for seed in seeds:
                t0 = time.perf_counter()
                config = TrainConfig.recipe(args.recipe, seed=seed, num_threads=1, progress=False, batch_size=batch)
                row = sweep_row(ds, preset, batch, config, sweep_work_dir(Path(args.work), ds, config))
                rows.append(row)
                print(f"[sweep] {preset:16s} batch {batch:5d} seed {seed}: {row['samples_per_s']:8.0f} samples/s, "
                      f"{row['epochs']:3d} epochs ({row['stopped_by']}, best {row['best_epoch']}), "
                      f"{row['wall_s']:7.1f} s, val {row['val_loss']:.5f}, test RMSE {row['test_rmse']:.4f} "
                      f"{row['unit']} ({time.perf_counter() - t0:.0f} s this call)", flush=True)
    pick, summary, r_star = pick_batch(mean_over_seeds(rows), args.tolerance)
    text = sweep_table(rows, pick, summary, r_star, args.tolerance, header)
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    return 0


# ----------------------------------------------------------------- loop against bare step
LOOP_PRESETS = {"seed-tau-mlp": "MLP", "seed-tip-4": "conv", "seed-tau-lstm-opt": "LSTM",
                "residual-rnea": "residual", "delan-friction": "DeLaN"}
LOOP_FLOOR, DELAN_FLOOR = 0.7, 2.0


def loop_table(args) -> int:
    from hybrid_dyn.learn.train import BUDGET_STEPS

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        robot = hd.load_robot("panda")
        ds = load_dataset(make_synthetic_dataset(Path(tmp) / "ds", robot, n_instances=10, n_samples=2000, seed=0,
                                                 friction=robot.spec.friction("gaz2019"), noise=0.01))
        recipe = TrainConfig.recipe("budget")
        batch = recipe.batch_size
        print(f"torch {torch.__version__}, 1 thread, batch {batch} (the budget recipe's); synthetic Panda set, "
              f"{sum(len(i) for i in ds.split('train'))} training samples; medians of {args.repeats}")
        print(f"{'family':9s} {'preset':18s} {'loop samples/s':>15s} {'bare samples/s':>15s} {'loop/bare':>9s}  floor")
        ok = True
        for name, family in LOOP_PRESETS.items():
            kind = get_preset(name).kind
            evals = 2  # validation every budget/2 steps of this run = the recipe's spacing, BUDGET/40
            steps = max(2, 2 * BUDGET_STEPS[kind] // recipe.budget_evals)
            # Each repeat times the loop, then the bare step right after it: a pair sees the same load
            # from other processes, and the ratio is the median over the pairs.
            loops, bares = [], []
            ws = step = None
            for r in range(args.repeats):
                cfg = TrainConfig.recipe("budget", budget_steps=steps, budget_evals=evals, seed=r, progress=False,
                                         num_threads=1)
                model = train_model(ds, name, Path(tmp) / f"{name}-{r}", cfg)
                loops.append(steps * batch / model.train_seconds)
                if ws is None:
                    ws = training_windows(model, ds)
                    step = bare_step(model, ws, batch)
                n_bare = max(5, int(0.5 * model.train_seconds * loops[-1] / batch))  # about half the loop's time
                bares.append(interleaved_rates([step], n_bare, 1)[0])
            loop, bare = float(np.median(loops)), float(np.median(bares))
            ratio = float(np.median(np.array(loops) / np.array(bares)))
            met = ratio >= LOOP_FLOOR
            ok &= met
            print(f"{family:9s} {name:18s} {loop:15.0f} {bare:15.0f} {ratio:9.2f}  >= {LOOP_FLOOR} "
                  f"{'met' if met else 'NOT MET'}", flush=True)
            if kind == "delan":
                fwd, oracle = interleaved_rates([bare_step(model, ws, batch), bare_step(model, ws, batch, oracle=True)],
                                                20, 2 * args.repeats + 1)
                met = fwd >= DELAN_FLOOR * oracle
                ok &= met
                print(f"{'':9s} {name:18s} forward-mode {fwd:.0f} samples/s, torch.func oracle {oracle:.0f} samples/s:"
                      f" {fwd / oracle:.2f}x  >= {DELAN_FLOOR} {'met' if met else 'NOT MET'}", flush=True)
        print("floors:", "all met" if ok else "NOT all met")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="dataset directory (default: a synthetic Panda set; "
                                                   "--sweep: a simulated set, generated once)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads for training and batched inference")
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--calls", type=int, default=2000, help="single calls timed per preset")
    ap.add_argument("--loop", action="store_true", help="the training loop against the bare step, per family")
    ap.add_argument("--repeats", type=int, default=3, help="--loop: repeats per measurement (median)")
    sw = ap.add_argument_group("batch-size sweep (--sweep)")
    sw.add_argument("--sweep", action="store_true", help="run the batch-size sweep instead of the speed table")
    sw.add_argument("--presets", nargs="+", default=list(SWEEP_PRESETS), metavar="PRESET")
    sw.add_argument("--batch-sizes", nargs="+", type=int, default=list(SWEEP_BATCHES), metavar="N")
    sw.add_argument("--recipe", default="plateau", help="training recipe (TrainConfig.recipe; 'default' until issue 30)")
    sw.add_argument("--seeds", type=int, nargs="+", default=[0], metavar="SEED",
                    help="training seeds (weights and shuffling); the rule uses the mean over them")
    sw.add_argument("--one-seed", nargs="+", default=[], metavar="PRESET",
                    help="presets trained on the first seed only (the costly ones, when time is short)")
    sw.add_argument("--data-seed", type=int, default=SWEEP_DATA["seed"], help="generated set: seed")
    sw.add_argument("--scenario", default=SWEEP_DATA["scenario"], help="generated set: scenario")
    sw.add_argument("--instances", type=int, default=SWEEP_DATA["n_instances"], help="generated set: instances")
    sw.add_argument("--trajectories", type=int, nargs=2, default=list(SWEEP_DATA["trajectories"]),
                    metavar=("LO", "HI"), help="generated set: trajectories per instance")
    sw.add_argument("--data-root", default="data", help="where the generated set is cached")
    sw.add_argument("--work", default="runs/batch-sweep", help="model folders, one per (preset, batch)")
    sw.add_argument("--tolerance", type=float, default=0.05, help="admissible worst-ratio excess over the best size's (pick_batch)")
    sw.add_argument("--out", default=None, help="write the sweep's markdown table to this file")
    args = ap.parse_args()
    if args.sweep:
        return sweep(args)
    if args.loop:
        return loop_table(args)

    with tempfile.TemporaryDirectory() as tmp:
        if args.data:
            ds = load_dataset(args.data)
        else:
            robot = hd.load_robot("panda")
            ds = load_dataset(make_synthetic_dataset(Path(tmp) / "ds", robot, n_instances=10, n_samples=1000, seed=0,
                                                     friction=robot.spec.friction("gaz2019"), noise=0.01))
        n_train = sum(len(i) for i in ds.split("train"))
        print(f"data: {ds.path.name if args.data else 'synthetic panda'}, {n_train} training samples; "
              f"torch {torch.__version__}, {args.threads} thread(s) for training/batched, 1 for single calls")
        print(f"{'preset':22s} {'train samples/s':>16s} {'batched us/sample':>18s} {'single us (fast)':>17s} "
              f"{'single us (torch)':>18s} {'floor':>10s}")
        ok = True
        for name in PRESETS:
            torch.set_num_threads(args.threads)
            cfg = TrainConfig(max_epochs=args.epochs, patience=args.epochs + 1, progress=False, num_threads=args.threads)
            model = train_model(ds, name, Path(tmp) / name, cfg)
            train_sps = len(model.history) * n_train / model.train_seconds  # every epoch sees every sample
            test = ds.split("test")
            n_test = sum(len(i) for i in test)
            priors = model.prior.compute_instances(test) if model.prior else None
            batched = []
            for _ in range(3):
                t0 = time.perf_counter()
                model.predict(test, priors=priors)
                batched.append((time.perf_counter() - t0) / n_test * 1e6)

            torch.set_num_threads(1)
            inst = test[0]
            x = concat_fields(model.sensor_view([inst]), model.inputs).astype(np.float64)  # as the net sees it
            k = min(500, len(inst) - 1)
            window = x[np.clip(np.arange(k - model.window + 1, k + 1), 0, None)]
            prior_k = None if priors is None else priors[0][k]  # a tared or stateful prior is given, not recomputed
            fast = median_us(lambda: model.predict_window(window, prior=prior_k), args.calls)
            xt = torch.from_numpy(window[None]).float()
            p = None if priors is None else torch.from_numpy(priors[0][k][None]).float()

            def torch_call():
                with torch.no_grad():
                    model.module(xt, p)
            torch_us = median_us(torch_call, max(200, args.calls // 5))
            floor = ""
            if name in FLOOR_US:
                met = fast <= FLOOR_US[name]
                ok &= met
                floor = f"<= {FLOOR_US[name]:.0f} {'met' if met else 'NOT MET'}"
            tr = f"{train_sps:16.0f}" if name in TRAIN_PRESETS else f"{'-':>16s}"
            print(f"{name:22s} {tr} {np.median(batched):18.2f} {fast:17.1f} {torch_us:18.1f} {floor:>10s}", flush=True)
        print("floors:", "all met" if ok else "NOT all met")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
