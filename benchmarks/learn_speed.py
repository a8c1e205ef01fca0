"""Speed of the learned models: training throughput and inference latency.

Prints, for each preset: training samples/s on CPU (epochs of the real
training loop, validation pass included), inference us per sample in batches,
and us per single call (one window, ``predict_window``, torch on one thread) with
the PyTorch path beside it. Medians of repeated measurements in this one run.

Floor (issue 4): single-call seed-tip-11 and residual-basewrench <= 200 us median.

    .venv/bin/python benchmarks/learn_speed.py [--data DIR] [--threads 1]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

import hybrid_dyn as hd
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.data.windows import concat_fields
from hybrid_dyn.learn import TrainConfig, train_model

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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="dataset directory (default: a synthetic Panda set)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads for training and batched inference")
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--calls", type=int, default=2000, help="single calls timed per preset")
    args = ap.parse_args()

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
            x = concat_fields([inst], model.inputs).astype(np.float64)
            k = min(500, len(inst) - 1)
            window = x[np.clip(np.arange(k - model.window + 1, k + 1), 0, None)]
            fast = median_us(lambda: model.predict_window(window), args.calls)
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
