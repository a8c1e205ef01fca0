"""The residual GP's fit before and after issue 40: time and validation accuracy, on the same rows.

For each dataset: the identified-consistent model (fitted on its train + val splits, as the bench fits an
imported log), the residual tau_m - prior on train (at most ``GPResidualConfig.max_rows`` rows, as
``train_gp_residual`` reads them) and val, then

- the hyperparameters by maximum marginal likelihood on the same ``hyper_rows`` seeded rows, by
  scikit-learn's ``GaussianProcessRegressor`` (before: the code of commit 9770868, BLAS threads as the
  process has them) and by ``learn/gp_marginal.py`` (after: the same objective, one BLAS thread);
  each joint's log marginal likelihood reached, the time [s wall, s CPU] of the 7 fits;
- the sparse fit and its choice on validation (``fit_sparse_residual``) from each set of hyperparameters,
  its time with the process's BLAS threads (before) and on one (after), and its validation RMSE [Nm]
  beside the prior alone.

    PYTHONPATH=src nice .venv/bin/python benchmarks/gp_hyper.py --real-panda --data /tmp/paper-noext-24

The numbers depend on the machine's load: the script prints the load average before and after.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def sklearn_hyperparameters(x, y, config):
    """fit_gp_hyperparameters as commit 9770868 had it (scikit-learn's fit, its BLAS threads)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor

    from hybrid_dyn.learn.gp import GPHyperparameters, _rows, _sklearn_kernel, _standardization

    mx, sx = _standardization(x)
    rows = _rows(len(x), config.hyper_rows, config.seed)
    z = (x[rows] - mx) / sx
    out = {"constant": [], "length_scale": [], "noise_level": [], "lml": []}
    for j in range(y.shape[1]):
        gp = GaussianProcessRegressor(_sklearn_kernel(config, x.shape[1]), normalize_y=True, random_state=config.seed)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", category=ConvergenceWarning)
            gp.fit(z, y[rows, j])
        k = gp.kernel_
        out["constant"].append(k.k1.k1.constant_value)
        out["length_scale"].append(np.broadcast_to(k.k1.k2.length_scale, (x.shape[1],)))
        out["noise_level"].append(k.k2.noise_level)
        out["lml"].append(float(gp.log_marginal_likelihood_value_))
    return GPHyperparameters(np.array(out["constant"]), np.array(out["length_scale"]), np.array(out["noise_level"]),
                             out["lml"])


def timed(fn):
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def residual_data(ds, tmp: Path, config):
    from hybrid_dyn.analytic.robot import load_robot
    from hybrid_dyn.identify.identified_model import IdentifiedModel, identify
    from hybrid_dyn.learn.gp import _rows
    from hybrid_dyn.learn.gp_residual import _residual_xy

    robot = load_robot(ds.meta["robot"])
    path = identify(ds, "consistent", robot, splits=("train", "val"), acceleration="measured").save(
        tmp / f"{ds.path.name}-consistent.json")
    prior = IdentifiedModel.load(path, robot=robot)
    (x, r), (xv, rv) = (_residual_xy(prior, ds.split(s), config) for s in ("train", "val"))
    if len(x) > config.max_rows:
        keep = _rows(len(x), config.max_rows, config.seed + 2)
        x, r = x[keep], r[keep]
    return x, r, xv, rv


def after_only(name, ds, tmp):
    """The "after" half alone (``--after-only``): its time and validation RMSE, for a rerun of the new fit
    without the scikit-learn fit, which is deterministic and costs 10-50x as much."""
    from hybrid_dyn.learn.gp import fit_gp_hyperparameters
    from hybrid_dyn.learn.gp_marginal import one_blas_thread
    from hybrid_dyn.learn.gp_residual import GPResidualConfig, fit_sparse_residual

    config = GPResidualConfig()
    x, r, xv, rv = residual_data(ds, tmp, config)
    print(f"\n## {name}: {len(x)} training rows (hyperparameters on {min(config.hyper_rows, len(x))}), "
          f"{len(xv)} validation rows, {config.inducing} inducing at most (after only)", flush=True)
    after, aw, ac = timed(lambda: fit_gp_hyperparameters(x, r, config.gp_config()))
    print(f"hyperparameters, 7 joints: after {aw:.1f} s wall / {ac:.1f} s CPU")
    print("log marginal likelihood per joint, after:  " + " ".join(f"{v:.1f}" for v in after.log_marginal_likelihood))

    def sparse_after():
        with one_blas_thread():
            return fit_sparse_residual(x, r, xv, rv, config, hyper=after)
    (_, choice), sw, sc = timed(sparse_after)
    rmse = lambda key: float(np.sqrt(np.mean([c[key] for c in choice])))  # noqa: E731
    print(f"sparse fit and choice: after {sw:.1f} s wall / {sc:.1f} s CPU")
    print(f"validation RMSE [Nm]: prior alone {rmse('val_mse_prior'):.4f}; after {rmse('val_mse'):.4f}")
    print("joints keeping the prior: after", [c["joint"] for c in choice if c["kept_prior"]], flush=True)


def compare(name, ds, tmp):
    from hybrid_dyn.learn.gp import fit_gp_hyperparameters
    from hybrid_dyn.learn.gp_marginal import one_blas_thread
    from hybrid_dyn.learn.gp_residual import GPResidualConfig, fit_sparse_residual

    config = GPResidualConfig()
    x, r, xv, rv = residual_data(ds, tmp, config)
    print(f"\n## {name}: {len(x)} training rows (hyperparameters on {min(config.hyper_rows, len(x))}), "
          f"{len(xv)} validation rows, {config.inducing} inducing at most", flush=True)
    before, bw, bc = timed(lambda: sklearn_hyperparameters(x, r, config.gp_config()))
    after, aw, ac = timed(lambda: fit_gp_hyperparameters(x, r, config.gp_config()))
    print(f"hyperparameters, 7 joints: before {bw:.1f} s wall / {bc:.1f} s CPU; after {aw:.1f} s wall / "
          f"{ac:.1f} s CPU; x{bw / aw:.1f} wall")
    print("log marginal likelihood per joint, before: " + " ".join(f"{v:.1f}" for v in before.log_marginal_likelihood))
    print("log marginal likelihood per joint, after:  " + " ".join(f"{v:.1f}" for v in after.log_marginal_likelihood))
    (tb, choice_b), sw_b, sc_b = timed(lambda: fit_sparse_residual(x, r, xv, rv, config, hyper=before))

    def sparse_after():
        with one_blas_thread():
            return fit_sparse_residual(x, r, xv, rv, config, hyper=after)
    (ta, choice_a), sw_a, sc_a = timed(sparse_after)
    rmse = lambda ch, key: float(np.sqrt(np.mean([c[key] for c in ch])))  # noqa: E731  (as train_gp_residual)
    print(f"sparse fit and choice: before {sw_b:.1f} s wall / {sc_b:.1f} s CPU; after {sw_a:.1f} s wall / "
          f"{sc_a:.1f} s CPU")
    print(f"validation RMSE [Nm]: prior alone {rmse(choice_b, 'val_mse_prior'):.4f}; before {rmse(choice_b, 'val_mse'):.4f}; "
          f"after {rmse(choice_a, 'val_mse'):.4f} (after / before {rmse(choice_a, 'val_mse') / rmse(choice_b, 'val_mse'):.4f})")
    print("joints keeping the prior: before", [c["joint"] for c in choice_b if c["kept_prior"]],
          "after", [c["joint"] for c in choice_a if c["kept_prior"]], flush=True)
    print(f"whole fit: before {bw + sw_b:.1f} s wall, after {aw + sw_a:.1f} s wall")


def main(argv=None) -> int:
    from hybrid_dyn.data import load_dataset

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real-panda", action="store_true", help="the real Panda log (../shared/data/real)")
    ap.add_argument("--data", action="append", default=[], help="a dataset folder (repeat)")
    ap.add_argument("--after-only", action="store_true", help="only the new fit (no scikit-learn fit)")
    args = ap.parse_args(argv)
    run = after_only if args.after_only else compare
    import torch  # the bench's process holds torch's thread pool beside the BLAS ones: measure in the same setting

    torch.set_num_threads(1)
    print(f"load average before: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.real_panda:
            from hybrid_dyn.data.logs.real_logs import real_dataset

            run("real-panda", load_dataset(real_dataset("real-panda", tmp / "data")), tmp)
        for d in args.data:
            run(Path(d).name, load_dataset(d), tmp)
    print(f"\nload average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
