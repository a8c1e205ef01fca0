"""Error metrics of the benchmark (PROTOCOL 4), one definition for every model.

All take predictions and targets of shape (N, C) in physical units over the
same test samples. "All samples and components" is the reference study's RMSE:
sqrt(mean over N and C of e^2).

A refused sample is a prediction row of NaN on every component (an estimator that declines to answer, e.g.
before its start-up check passed): :class:`ErrorReport` scores the answered rows and reports the answered
share of the test samples beside them, so a method that declines is not scored as one that errs; the
refused-as-zero figure (each refusal read as a zero prediction, what the bench scored before) stays as a
labelled second figure. A row that answers under :data:`ANSWERED_FLOOR` is marked in the report's tables
and never headlined as a family's best.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CONTACT_THRESHOLD_N = 1.0  # |F_tip| above this is "in contact" (PROTOCOL 4)
ANSWERED_FLOOR = 0.95  # a row answering fewer of the test samples is marked and never a family's best


def answered(pred: np.ndarray) -> np.ndarray:
    """(N,) bool: the prediction rows that answer (every component finite); a row of NaN on every component
    is a refusal. A partial NaN row or an infinity is an error of the model, refused by name."""
    pred = np.asarray(pred, float)
    rows = pred.reshape(len(pred), -1)
    nan = np.isnan(rows)
    refused = nan.all(axis=1)
    partial = nan.any(axis=1) & ~refused
    if partial.any() or np.isinf(rows).any():
        raise ValueError(f"{int(partial.sum())} predictions are NaN on some components only and "
                         f"{int(np.isinf(rows).sum())} are inf: a refusal is NaN on every component")
    return ~refused


def rmse(pred: np.ndarray, target: np.ndarray) -> float:
    """Root mean square error over all samples and components."""
    e = np.asarray(pred, float) - np.asarray(target, float)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def rmse_per_component(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """RMSE per axis / per joint, shape (C,)."""
    e = np.asarray(pred, float) - np.asarray(target, float)
    return np.sqrt(np.mean(e**2, axis=0)) if len(e) else np.full(e.shape[1:], np.nan)


def zero_variance_components(target: np.ndarray) -> list[int]:
    """The components (0-based) whose target is constant over the samples: zero variance, no nMSE."""
    target = np.asarray(target, float)
    return [] if not len(target) else [int(j) for j in np.flatnonzero(~(target.var(axis=0) > 0))]


def nmse(pred: np.ndarray, target: np.ndarray) -> float:
    """Normalised MSE: per-component MSE / target variance, averaged over components.

    The figure SARCOS results are usually quoted in; 1.0 is predicting the mean. Undefined (NaN) when a
    component's target has zero variance (:func:`zero_variance_components`: a dead channel, a joint held
    still): averaged over the other components alone it ranked a row on a log whose joint 4 torque was 0
    throughout as the best; the bench writes the reason beside the row.
    """
    target = np.asarray(target, float)
    if not len(target):
        return float("nan")
    e = np.asarray(pred, float) - target
    var = target.var(axis=0)
    if not np.all(var > 0):
        return float("nan")
    return float(np.mean(np.mean(e**2, axis=0) / var))


def standardized_mse(pred: np.ndarray, target: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float:
    """MSE on targets standardised with the training split's statistics: the benchmark's "loss".

    Comparable across analytic and learned rows (the reference study's losses add a
    regularisation term; ours are the plain data term). Undefined (NaN) when a component's training std
    is 0 (a constant training target: divided by a floor it gave losses of 5e13).
    """
    std = np.asarray(std, float)
    if not np.all(std > 0):
        return float("nan")
    return float(np.mean(((np.asarray(pred) - np.asarray(target)) / std) ** 2))


def base_force_noise_rms(instances) -> float:
    """The base sensor's white-noise RMS per force axis [N]: the floor under every base-sensor estimate.

    Measured, not taken from the generator's config: the recorded base force
    minus its noise-free truth, each instance's straight line in time removed (the per-run bias a tare
    takes out, and a hardware sensor's linear bias drift, ``sim/sensors.py``), pooled over samples and the
    three axes. NaN when the data carry no truth (real logs).
    """
    sq, n = 0.0, 0
    for inst in instances:
        truth = inst.truth.get("base_wrench")
        if truth is None:
            return float("nan")
        e = inst["base_wrench"][:, :3] - truth[:, :3]
        s = np.arange(len(e), dtype=float)  # sample index: the drift is linear in time, the stamps jittered
        line = np.stack([np.ones_like(s), s], axis=1)
        e = e - line @ np.linalg.lstsq(line, e, rcond=None)[0]
        sq += float(np.sum(e**2))
        n += e.size
    return float(np.sqrt(sq / n)) if n else float("nan")


@dataclass
class ErrorReport:
    """Every error figure of one model on one split."""

    rmse: float
    nmse: float
    per_component: np.ndarray
    rmse_contact: float
    rmse_free: float
    max_error: float
    n_samples: int  # every test sample, answered or refused
    answered_share: float = 1.0  # of the n_samples, those the model answered (NaN: none to answer)
    rmse_refused_as_zero: float = float("nan")  # every refusal scored as a zero prediction

    @classmethod
    def compute(cls, pred: np.ndarray, target: np.ndarray, tip_force_truth: np.ndarray | None = None) -> "ErrorReport":
        """The figures over the answered samples (:func:`answered`); ``tip_force_truth`` (N, 3) splits them
        into contact (|F| > 1 N) and free motion."""
        pred = np.asarray(pred, float)
        target = np.asarray(target, float)
        if pred.shape != target.shape:
            raise ValueError(f"prediction shape {pred.shape} != target shape {target.shape}")
        ok = answered(pred)
        as_zero = rmse(np.where(ok[:, None], pred, 0.0), target) if pred.ndim == 2 else float("nan")
        n = len(pred)
        pred, target = pred[ok], target[ok]
        if tip_force_truth is not None:
            contact = np.linalg.norm(np.asarray(tip_force_truth, float)[ok], axis=1) > CONTACT_THRESHOLD_N
            rc, rf = rmse(pred[contact], target[contact]), rmse(pred[~contact], target[~contact])
        else:
            rc = rf = float("nan")
        return cls(
            rmse=rmse(pred, target),
            nmse=nmse(pred, target),
            per_component=rmse_per_component(pred, target),
            rmse_contact=rc,
            rmse_free=rf,
            max_error=float(np.abs(pred - target).max()) if pred.size else float("nan"),
            n_samples=n,
            answered_share=float(ok.mean()) if n else float("nan"),
            rmse_refused_as_zero=as_zero,
        )
