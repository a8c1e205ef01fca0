"""Training throughput, measured the same way by every benchmark that quotes it.

:func:`bare_step` is the floor any training loop is judged against: forward, backward and an Adam
step of a model's module on one batch already in memory, nothing else. Steps are timed by the
toolkit's one timer, :func:`hybrid_dyn.timing.interleaved_rates` (several steps in turn within every
repeat, so that load from other processes on a shared machine falls on all of them alike; medians
[samples/s]), re-exported here.
"""
from __future__ import annotations

import copy

import numpy as np
import torch

from ..timing import interleaved_rates  # noqa: F401  (re-exported: the timer of every training throughput)
from .training_data import _batches


def bare_step(model, ws, batch: int, oracle: bool = False):
    """forward + backward + Adam step of a copy of ``model``'s module on one in-memory batch of ``ws``:
    (the step, samples per step). ``oracle``: a DeLaN's torques come from its ``torch.func`` oracle
    (``terms_autograd``) instead of its forward-mode terms."""
    module = copy.deepcopy(model.module).train()
    if oracle:
        delan = module.delan
        delan.tau = lambda q, qd, qdd: delan.terms_autograd(q, qd, qdd)["tau"]  # shadows the method
    opt = torch.optim.Adam(module.parameters(), lr=1e-4)
    idx = np.sort(np.random.default_rng(0).choice(len(ws), size=min(batch, len(ws)), replace=False))
    x, y, p = _batches(ws, idx, torch.device("cpu"))

    def step():
        opt.zero_grad(set_to_none=True)
        loss = module.standardized_loss(module(x, p), y)
        loss.backward()
        opt.step()
    return step, len(idx)


def training_windows(model, ds):
    """``ds``'s training split windowed as ``model``'s training loop sees it (tared sensor, prior)."""
    from ..data.input_windows import WindowedSplit

    train = ds.split("train")
    extra = {"prior": model.prior.compute_instances(train)} if model.prior else None
    return WindowedSplit(model.sensor_view(train), model.window, list(model.inputs), list(model.targets), extra=extra)
