"""Speed of the learned models: training throughput and inference latency.

Prints, for each preset: training samples/s on CPU (epochs of the real
training loop, validation pass included), inference us per sample in batches,
and us per single call (one window, ``predict_window``, torch on one thread) with
the PyTorch path beside it. Medians of repeated measurements in this one run (``hybrid_dyn.timing``).

The batch-size sweep that once lived here (``--sweep``, issue 14) is the study ``batch-size``
(``hybrid-dyn study batch-size``, ``bench/studies.py``).

Floor (issue 4): single-call seed-tip-11 and residual-basewrench <= 200 us median.

    .venv/bin/python benchmarks/learn_speed.py [--data DIR] [--threads 1]

``--loop`` (issue 26): per family, at the budgeted recipe's batch, the training loop's samples/s
(``train_model`` under the ``budget`` recipe, validation rounds at the recipe's spacing of
``budget_steps / budget_evals`` steps included) beside the bare forward-backward-Adam step of the
same module on one batch already in memory; and DeLaN's forward-mode terms beside the
``torch.func`` oracle (``terms_autograd``) in the same bare step. One torch thread, medians of
``--repeats`` in one run (loop/bare: the median of the ratios of each loop run and the bare step timed
right after it). Floors: loop >= 0.7x bare for every family; DeLaN (with friction)
forward-mode >= 2x the oracle.

    nice .venv/bin/python benchmarks/learn_speed.py --loop
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch

import hybrid_dyn as hd
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.input_windows import concat_fields
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn import presets as declared
from hybrid_dyn.learn.speed import bare_step, training_windows
from hybrid_dyn.timing import interleaved_rates, median_call_us, per_item_us

PRESETS = ["seed-tip-1", "seed-tip-11", "seed-tau-lstm-opt", "residual-basewrench", "residual-rnea", "delan",
           "delan-friction"]
TRAIN_PRESETS = {"seed-tip-11": "LSTM", "seed-tau-lstm-opt": "LSTM", "delan": "DeLaN", "delan-friction": "DeLaN"}
FLOOR_US = {"seed-tip-11": 200.0, "residual-basewrench": 200.0}


# ----------------------------------------------------------------- loop against bare step
LOOP_PRESETS = {"seed-tau-mlp": "MLP", "seed-tip-4": "conv", "seed-tau-lstm-opt": "LSTM",
                "residual-rnea": "residual", "delan-friction": "DeLaN"}
LOOP_FLOOR, DELAN_FLOOR = 0.7, 2.0


def loop_table(args) -> int:
    from hybrid_dyn.learn.kinds import NETWORK_KINDS

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
            kind = declared.PRESETS.lookup(name).kind
            evals = 2  # validation every budget/2 steps of this run = the recipe's spacing, BUDGET/40
            steps = max(2, 2 * NETWORK_KINDS[kind].budget_steps // recipe.budget_evals)
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
    ap.add_argument("--data", default=None, help="dataset directory (default: a synthetic Panda set)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads for training and batched inference")
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--calls", type=int, default=2000, help="single calls timed per preset")
    ap.add_argument("--loop", action="store_true", help="the training loop against the bare step, per family")
    ap.add_argument("--repeats", type=int, default=3, help="--loop: repeats per measurement (median)")
    args = ap.parse_args()
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
            batched = per_item_us(lambda: model.predict(test, priors=priors), per=n_test, repeat=3, number=1)

            torch.set_num_threads(1)
            inst = test[0]
            x = concat_fields(model.sensor_view([inst]), model.inputs).astype(np.float64)  # as the net sees it
            k = min(500, len(inst) - 1)
            window = x[np.clip(np.arange(k - model.window + 1, k + 1), 0, None)]
            prior_k = None if priors is None else priors[0][k]  # a tared or stateful prior is given, not recomputed
            fast = median_call_us(lambda: model.predict_window(window, prior=prior_k), args.calls)
            xt = torch.from_numpy(window[None]).float()
            p = None if priors is None else torch.from_numpy(priors[0][k][None]).float()

            def torch_call():
                with torch.no_grad():
                    model.module(xt, p)
            torch_us = median_call_us(torch_call, max(200, args.calls // 5))
            floor = ""
            if name in FLOOR_US:
                met = fast <= FLOOR_US[name]
                ok &= met
                floor = f"<= {FLOOR_US[name]:.0f} {'met' if met else 'NOT MET'}"
            tr = f"{train_sps:16.0f}" if name in TRAIN_PRESETS else f"{'-':>16s}"
            print(f"{name:22s} {tr} {batched:18.2f} {fast:17.1f} {torch_us:18.1f} {floor:>10s}", flush=True)
        print("floors:", "all met" if ok else "NOT all met")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
