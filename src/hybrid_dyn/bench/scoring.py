"""Scoring one row on one dataset: build its predictor (train or reuse), predict the validation and test splits,
and score every row with the same metrics (``metrics.py``) against the same logged targets.

Targets: tip force -> the logged ``tip_force``; joint torque -> the logged commanded motor torque ``tau_m``
(friction included), as PROTOCOL 4 says. Losses are MSE on targets standardised with the train split's
statistics, for analytic and learned rows alike. Sequence models are scored on every sample: their first L-1
windows of each instance are edge-padded (``data/input_windows.py``), exactly as a streaming estimator starts up.
"""
from __future__ import annotations

import time

import numpy as np

from ..data import Dataset
from ..timing import time_calls
from .metrics import ErrorReport, answered, base_force_noise_rms, standardized_mse
from .plan import BenchContext
from .row_checks import NOTE_SEPARATOR, review_row
from .rows import TASK_TARGET, Row


def _median_call_us(fn, inst, warmup_calls: int = 1, n_calls: int = 200) -> float:
    """The median time [us] of a row's single call on one run, fed its samples in order from the start
    (as a control loop feeds a stream); the first ``warmup_calls`` (at least one, at most all but the
    last sample) are not timed, then up to ``n_calls`` are (``timing.time_calls``)."""
    n = len(inst)
    warm = min(max(1, int(warmup_calls)), n - 1)
    for k in range(warm):
        fn(inst, k)
    wall, _ = time_calls(lambda k: fn(inst, k), range(warm, min(n, warm + n_calls)))
    return float(np.median(wall) * 1e6)


def score_row(spec: Row, ctx: BenchContext, norm: dict) -> dict:
    ds = ctx.dataset
    target = TASK_TARGET[spec.task]
    row = {"task": spec.task, "scenario": ctx.scenario, "model": spec.name, "family": spec.family}
    if target not in ds.fields:
        raise ValueError(f"the dataset has no {target!r} field")
    cpu0 = time.process_time()  # this process's CPU, every thread (BLAS, torch) included
    pred_obj = spec.build(ds, ctx)
    cpu1 = time.process_time()
    # A model trained elsewhere (a worker, an earlier invocation) brings its recorded CPU; else the build was the fit.
    train_cpu = cpu1 - cpu0 if pred_obj.train_cpu_seconds is None else pred_obj.train_cpu_seconds
    row.update(inputs=pred_obj.inputs, train_seconds=pred_obj.train_seconds, train_cpu_seconds=train_cpu,
               n_params=pred_obj.n_params)
    if pred_obj.prior_kept is not None:
        row["prior_kept"] = pred_obj.prior_kept
    if pred_obj.training is not None:
        t = pred_obj.training
        row.update(epochs=t["epochs"], stopped_by=t["stopped_by"], best_epoch=t["best_epoch"])
        row["curve"] = {"task": spec.task, **t}  # not a results.csv column: the runner keeps it in curves.json
    mean, std = norm[target]
    losses = {}
    for split in ("val", "test"):
        insts = ds.split(split)
        tgt = np.concatenate([i[target] for i in insts])  # also loads the files: I/O stays out of the timing
        t0 = time.perf_counter()
        preds = pred_obj.predict(insts)
        elapsed = time.perf_counter() - t0
        pred = np.concatenate(preds)
        ok = answered(pred)  # a refused sample (NaN) is no error: the answered share says how many there were
        losses[split] = standardized_mse(pred[ok], tgt[ok], mean, std)
        if split == "test":
            f_truth = (np.concatenate([i.truth.get("tip_force", i["tip_force"]) for i in insts])
                       if "tip_force" in ds.fields else None)
            report = ErrorReport.compute(pred, tgt, f_truth)
            if spec.task == "tip_force" and "base_wrench" in ds.fields:
                if "base-force-noise" not in ctx.cache:  # a property of the data: once per scenario
                    ctx.cache["base-force-noise"] = base_force_noise_rms(insts)
                row["noise_rms"] = ctx.cache["base-force-noise"]
            row["infer_us_per_sample"] = elapsed / len(pred) * 1e6
            ctx.cache[(spec.task, spec.name)] = preds
            test_target = tgt
    row.update(val_loss=losses["val"], test_loss=losses["test"], rmse=report.rmse, nmse=report.nmse,
               rmse_contact=report.rmse_contact, rmse_free=report.rmse_free, max_error=report.max_error,
               n_test_samples=report.n_samples, answered_share=report.answered_share,
               rmse_refused_as_zero=report.rmse_refused_as_zero)
    for j, v in enumerate(report.per_component):
        row[f"rmse_{j + 1}"] = float(v)
    if pred_obj.sigma_coverage is not None:
        row["sigma_coverage"] = pred_obj.sigma_coverage()
    if pred_obj.single_call is not None:
        row["infer_us_per_call"] = _median_call_us(pred_obj.single_call, ds.split("test")[0], pred_obj.warmup_calls)
    row["score_cpu_seconds"] = time.process_time() - cpu1  # val and test predictions, metrics, the timed calls
    # ok or implausible (identified parameters outside the robot's bounds), and what the numbers cannot show.
    row["status"], notes = review_row(spec, ctx, pred_obj, target, std, test_target)
    row["notes"] = NOTE_SEPARATOR.join(notes)
    return row


def train_split_stats(ds: Dataset) -> dict:
    """Per-component mean and std of each target over the train split (a std of 0, a constant training target,
    is kept: the losses standardised by it are undefined, ``metrics.standardized_mse``)."""
    out = {}
    for target in TASK_TARGET.values():
        if target in ds.fields:
            y = np.concatenate([i[target] for i in ds.split("train")])
            out[target] = (y.mean(0), y.std(0))
    return out
