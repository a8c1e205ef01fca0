"""Sliding input windows of length L over a split, for the sequence models: the history a network reads
per sample (its input window; the estimator's noise window is another thing, ``analytic/bandwidth.py``).

One window per sample: the window of sample k of an instance is samples
k-L+1 .. k of that instance. At the start of an instance (k < L-1) the missing
history is filled with the instance's first sample ("edge padding"), exactly as
a streaming estimator fills its buffer at start-up. So every model, sequence or
not, is scored on every sample, warm-up included, and no window crosses from one
instance into the next.

Memory: the split's fields are concatenated once (one copy of the split, not of
the windows); windows are gathered per batch with an index array, so a batch of
B windows costs B x L x F floats and the full (N, L, F) tensor never exists.
"""
from __future__ import annotations

import numpy as np


def concat_fields(instances, names: list[str]) -> np.ndarray:
    """(N_total, F) float32 array of the named fields side by side, instance after instance."""
    cols = []
    for inst in instances:
        parts = []
        for n in names:
            a = np.asarray(inst[n], dtype=np.float32)
            parts.append(a[:, None] if a.ndim == 1 else a)
        cols.append(np.concatenate(parts, axis=1) if parts else np.zeros((len(inst), 0), np.float32))
    return np.concatenate(cols, axis=0)


def window_index(lengths: list[int], length: int) -> np.ndarray:
    """(N_total, L) row indices into the concatenated split, edge-padded per instance."""
    rows = []
    start = 0
    offsets = np.arange(-length + 1, 1)
    for n in lengths:
        k = np.arange(n)[:, None] + offsets[None, :]
        rows.append(start + np.clip(k, 0, n - 1))
        start += n
    return np.concatenate(rows, axis=0) if rows else np.zeros((0, length), dtype=np.int64)


class WindowedSplit:
    """Windows of ``inputs`` and the current-sample ``targets`` of a list of instances.

    ``ws[idx]`` -> (x (B, L, F_in), y (B, F_out)) as float32.
    ``extra``: name -> list of per-instance arrays (e.g. a cached analytic
    estimate), returned as ``ws.extra[name][idx]`` aligned with the targets.
    """

    def __init__(self, instances, length: int, inputs: list[str], targets: list[str], extra: dict | None = None):
        if length < 1:
            raise ValueError(f"window length must be >= 1, got {length}")
        self.length = length
        self.inputs = list(inputs)
        self.targets = list(targets)
        self.lengths = [len(i) for i in instances]
        self.x = concat_fields(instances, self.inputs)
        self.y = concat_fields(instances, self.targets)
        self.index = window_index(self.lengths, length)
        self.extra = {k: np.concatenate([np.asarray(a, np.float32).reshape(len(a), -1) for a in v])
                      for k, v in (extra or {}).items()}
        # Which instance and position each sample is, for per-instance plots.
        self.instance_id = np.repeat(np.arange(len(self.lengths)), self.lengths)

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, idx):
        rows = self.index[idx]
        return self.x[rows], self.y[idx]
