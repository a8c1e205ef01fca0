"""What training reads from a dataset: its fields checked against its robot, their widths, the
normalization statistics, and the batches fed to the network (and the validation loss over a split).

Apart from the loop because these are properties of the data, checked before anything is written
and shared with the speed measurements (``speed.py``), while the loop only asks for a batch.
"""
from __future__ import annotations

import numpy as np
import torch

from ..data import Dataset
from ..data.input_windows import WindowedSplit
from .trained_model import HybridModel, ModelError

STD_FLOOR = 1e-6  # a (nearly) constant column is scaled by 1, not blown up


def field_widths(instance, names) -> dict:
    return {n: int(np.asarray(instance[n]).reshape(len(instance), -1).shape[1]) for n in names}


def _stats(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = a.astype(np.float64)
    mean, std = a.mean(0), a.std(0)
    return mean, np.where(std < STD_FLOOR, 1.0, std)


# Fields with one column per joint; the others have fixed widths.
JOINT_FIELDS = ("q", "qd", "qdd", "tau_m", "tau_J")
FIXED_WIDTHS = {"base_wrench": 6, "tip_force": 3}


def _check_robot_and_widths(ds: Dataset, widths: dict, robot) -> None:
    """The dataset's field widths fit its robot (nv columns per joint field), before any training.

    robot: the loaded Robot when the dataset's robot has a description, else None (a
    data-only arm: the joint fields need only agree with each other).
    """
    joint = {f: w for f, w in widths.items() if f in JOINT_FIELDS}
    nv = robot.nv if robot is not None else None
    for f, w in sorted(widths.items()):
        if f in FIXED_WIDTHS and w != FIXED_WIDTHS[f]:
            raise ModelError(f"dataset {ds.path}: field {f} has {w} columns, expected {FIXED_WIDTHS[f]}")
    if nv is not None and any(w != nv for w in joint.values()):
        raise ModelError(f"dataset {ds.path} is labelled robot {ds.meta['robot']!r} ({nv} joints), but its joint "
                         f"fields have {joint} columns: another robot's data, or the wrong robot name")
    if len(set(joint.values())) > 1:
        raise ModelError(f"dataset {ds.path}: joint fields disagree in width: {joint}")


def _batches(ws: WindowedSplit, idx: np.ndarray, device):
    x, y = ws[idx]
    p = ws.extra["prior"][idx] if "prior" in ws.extra else None
    to = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device)  # noqa: E731
    return to(x), to(y), (None if p is None else to(p))


def evaluate_split(module: HybridModel, ws: WindowedSplit, device, batch_size: int = 4096) -> float:
    """Standardized MSE over a whole split (every sample weighs the same)."""
    module.eval()
    total, n = 0.0, 0
    with torch.no_grad():
        for s in range(0, len(ws), batch_size):
            idx = np.arange(s, min(s + batch_size, len(ws)))
            x, y, p = _batches(ws, idx, device)
            total += float(module.standardized_loss(module(x, p), y)) * len(idx)
            n += len(idx)
    module.train()
    return total / max(n, 1)
