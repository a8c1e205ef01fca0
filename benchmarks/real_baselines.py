"""Baseline statistics of the three real-robot sets, and two quick sanity fits.

For each set (real-kuka, real-baxter, real-sarcos) this prints the per-joint
variance of the test-split torque targets (the nMSE normaliser: nMSE = MSE / var)
and the test nMSE per joint of
- predicting the training mean (nMSE ~ 1 by construction),
- a linear least-squares fit on [q, qd, qdd, sin q, cos q, 1] (rigid-body dynamics is
  linear in its parameters, not in these features: a rough check),
- a small MLP (2 x 64 tanh, Adam 1e-3, batch 256, early stop after 5 epochs without
  validation improvement).
These only validate the import (sane, learnable data); they are not benchmark results.

    .venv/bin/python benchmarks/real_baselines.py [--cache DIR] [--epochs N]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from hybrid_dyn.data import REAL_SETS, load_dataset, real_dataset
from hybrid_dyn.data.real import nmse_per_joint, target_statistics


def stack(ds, split):
    insts = ds.split(split)
    x = np.concatenate([np.concatenate([i.q, i.qd, i.qdd], axis=1) for i in insts])
    y = np.concatenate([i.tau_m for i in insts])
    return x, y


def features(x, nv):
    q = x[:, :nv]
    return np.concatenate([x, np.sin(q), np.cos(q), np.ones((len(x), 1))], axis=1)


def fit_mlp(xtr, ytr, xva, yva, epochs, seed=0):
    import torch

    torch.manual_seed(seed)
    mx, sx, my, sy = xtr.mean(0), xtr.std(0) + 1e-9, ytr.mean(0), ytr.std(0) + 1e-9
    t = lambda a: torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
    Xtr, Ytr, Xva, Yva = t((xtr - mx) / sx), t((ytr - my) / sy), t((xva - mx) / sx), t((yva - my) / sy)
    net = torch.nn.Sequential(torch.nn.Linear(xtr.shape[1], 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, ytr.shape[1]))
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    gen = torch.Generator().manual_seed(seed)
    best, best_state, patience = np.inf, None, 0
    for _ in range(epochs):
        for idx in torch.randperm(len(Xtr), generator=gen).split(256):
            opt.zero_grad()
            loss = torch.mean((net(Xtr[idx]) - Ytr[idx]) ** 2)
            loss.backward()
            opt.step()
        with torch.no_grad():
            val = float(torch.mean((net(Xva) - Yva) ** 2))
        if val < best:
            best, best_state, patience = val, {k: v.clone() for k, v in net.state_dict().items()}, 0
        else:
            patience += 1
            if patience >= 5:
                break
    net.load_state_dict(best_state)

    def predict(x):
        with torch.no_grad():
            return net(t((x - mx) / sx)).numpy() * sy + my

    return predict


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="/tmp/hybrid_dyn_real_cache")
    ap.add_argument("--epochs", type=int, default=100)
    args = ap.parse_args(argv)
    np.set_printoptions(precision=4, suppress=True, linewidth=160)
    for name in REAL_SETS:
        ds = load_dataset(real_dataset(name, args.cache))
        stats = target_statistics(ds, "tau_m", "test")
        xtr, ytr = stack(ds, "train")
        xva, yva = stack(ds, "val")
        xte, yte = stack(ds, "test")
        nv = ytr.shape[1]
        var = np.asarray(stats["variance"])
        print(f"\n{name}: train/val/test samples {len(xtr)}/{len(xva)}/{len(xte)}")
        print(f"  test target std per joint [Nm]  {np.sqrt(var)}")
        print(f"  test target variance [Nm^2]     {var}")
        mean_pred = np.broadcast_to(ytr.mean(0), yte.shape)
        n = nmse_per_joint(mean_pred, yte, var)
        print(f"  nMSE train mean                 {n}  mean {n.mean():.4f}")
        w, *_ = np.linalg.lstsq(features(xtr, nv), ytr, rcond=None)
        n = nmse_per_joint(features(xte, nv) @ w, yte, var)
        print(f"  nMSE linear (q,qd,qdd,sin,cos)  {n}  mean {n.mean():.4f}")
        t0 = time.perf_counter()
        predict = fit_mlp(xtr, ytr, xva, yva, args.epochs)
        pred = predict(xte)
        n = nmse_per_joint(pred, yte, var)
        rmse = np.sqrt(np.mean((pred - yte) ** 2, axis=0))
        print(f"  nMSE MLP 2x64 tanh              {n}  mean {n.mean():.4f}  ({time.perf_counter() - t0:.1f} s)")
        print(f"  RMSE MLP per joint [Nm]         {rmse}  all {np.sqrt(np.mean((pred - yte) ** 2)):.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
