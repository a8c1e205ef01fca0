"""How many inducing inputs does the residual GP need? Validation RMSE by M on a log (issue 29).

Fits the identified model (``--method``, default consistent) on ``--data``'s train + val splits, as
the bench's identified rows do, then the residual GP (``learn/gp_residual.py``, its default
candidates) on the train split with M inducing inputs for each M of ``--inducing``, and prints the
validation RMSE of the prior alone and of each fit (RMS over joints of the per-joint MSE) with its
fitting time. The kernel hyperparameters (marginal likelihood, the costly part) are fitted once and
shared by every M. Validation only: choose on it, the test split is never read.

Run (the choice of GPResidualConfig.inducing, on the real Panda's time-ordered split):
    .venv/bin/python benchmarks/gp_residual_control.py --data DIR_OF_REAL_PANDA --inducing 500,1000,2000,4000
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from hybrid_dyn.analytic.robot import load_robot
from hybrid_dyn.data import load_dataset
from hybrid_dyn.identify import identify
from hybrid_dyn.learn import gp_residual
from hybrid_dyn.learn.gp import fit_gp_hyperparameters


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="a dataset folder (an imported log with q, qd, qdd, tau_m)")
    ap.add_argument("--method", default="consistent", help="identification method of the prior")
    ap.add_argument("--inducing", default="500,1000,2000,4000", help="comma-separated inducing counts M")
    args = ap.parse_args(argv)
    ds = load_dataset(args.data)
    robot = load_robot(ds.meta["robot"])
    prior = identify(ds, args.method, robot, splits=("train", "val"), acceleration="measured")
    base = gp_residual.GPResidualConfig()
    (x, r), (xv, rv) = (gp_residual._residual_xy(prior, ds.split(s), base) for s in ("train", "val"))
    print(f"{ds.meta.get('scenario')}: {len(x)} training, {len(xv)} validation samples; prior "
          f"identified-{args.method} alone: validation RMSE {np.sqrt(np.mean(rv ** 2)):.4f} Nm", flush=True)
    t0 = time.perf_counter()
    hyper = fit_gp_hyperparameters(x, r, base.gp_config())
    print(f"hyperparameters by marginal likelihood on {base.hyper_rows} rows: {time.perf_counter() - t0:.0f} s",
          flush=True)
    for m in (int(v) for v in args.inducing.split(",")):
        config = dataclasses.replace(base, inducing=m)
        t0 = time.perf_counter()
        _, choice = gp_residual.fit_sparse_residual(x, r, xv, rv, config, hyper=hyper)
        val = np.sqrt(np.mean([c["val_mse"] for c in choice]))
        kept = [c["joint"] for c in choice if c["kept_prior"]]
        print(f"M = {m}: validation RMSE {val:.4f} Nm, fit {time.perf_counter() - t0:.0f} s, joints keeping the "
              f"prior: {kept or 'none'}", flush=True)


if __name__ == "__main__":
    main()
