"""Error metrics of the benchmark (PROTOCOL 4), one definition for every model.

All take predictions and targets of shape (N, C) in physical units over the
same test samples. "All samples and components" is the seed's RMSE:
sqrt(mean over N and C of e^2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CONTACT_THRESHOLD_N = 1.0  # |F_tip| above this is "in contact" (PROTOCOL 4)


def rmse(pred: np.ndarray, target: np.ndarray) -> float:
    """Root mean square error over all samples and components."""
    e = np.asarray(pred, float) - np.asarray(target, float)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def rmse_per_component(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """RMSE per axis / per joint, shape (C,)."""
    e = np.asarray(pred, float) - np.asarray(target, float)
    return np.sqrt(np.mean(e**2, axis=0))


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
    e = np.asarray(pred, float) - target
    var = target.var(axis=0)
    if not len(target) or not np.all(var > 0):
        return float("nan")
    return float(np.mean(np.mean(e**2, axis=0) / var))


def standardized_mse(pred: np.ndarray, target: np.ndarray, mean: np.ndarray, std: np.ndarray) -> float:
    """MSE on targets standardised with the training split's statistics: the benchmark's "loss".

    Comparable across analytic and learned rows (the seed's losses add a
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
    minus its noise-free truth, each instance's mean removed (the per-run bias
    a tare takes out), pooled over samples and the three axes. NaN when the
    data carry no truth (real logs).
    """
    sq, n = 0.0, 0
    for inst in instances:
        truth = inst.truth.get("base_wrench")
        if truth is None:
            return float("nan")
        e = inst["base_wrench"][:, :3] - truth[:, :3]
        e = e - e.mean(axis=0)
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
    n_samples: int

    @classmethod
    def compute(cls, pred: np.ndarray, target: np.ndarray, tip_force_truth: np.ndarray | None = None) -> "ErrorReport":
        """``tip_force_truth`` (N, 3) splits samples into contact (|F| > 1 N) and free motion."""
        pred = np.asarray(pred, float)
        target = np.asarray(target, float)
        if pred.shape != target.shape:
            raise ValueError(f"prediction shape {pred.shape} != target shape {target.shape}")
        if not np.isfinite(pred).all():
            raise ValueError(f"{int((~np.isfinite(pred)).sum())} predictions are NaN or inf")
        if tip_force_truth is not None:
            contact = np.linalg.norm(tip_force_truth, axis=1) > CONTACT_THRESHOLD_N
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
            n_samples=len(pred),
        )
