"""Per-step training cost of the DeLaN presets (issue 40): ``delan-residual`` against ``delan-friction``.

One optimizer step as the training loop takes it (``train._train_round``): the batch gathered from the
training windows (``training_data._batches``), forward, backward, Adam, at the budgeted recipe's batch of
1024, on one torch thread, on a synthetic Panda set. The steps of every preset are timed in turn within
each repeat (``timing.interleaved_rates``: load from other processes falls on all alike); medians of the
repeats, in ms per step, and each preset's ratio to ``delan-friction`` measured in the same run.

    PYTHONPATH=src nice .venv/bin/python benchmarks/delan_step.py [--repeats 5] [--steps 20]
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import torch

PRESETS = ("delan-friction", "delan-residual", "delan")


def steps_of(ds, names, batch: int):
    """{preset: (step, batch)}: one training step of a freshly initialised model of each preset."""
    from hybrid_dyn.data.input_windows import WindowedSplit
    from hybrid_dyn.learn.trained_model import HybridModel
    from hybrid_dyn.learn.presets import PRESETS
    from hybrid_dyn.learn.training_data import _batches, _stats, field_widths

    train = ds.split("train")
    out = {}
    for name in names:
        preset = PRESETS.lookup(name)
        ws = WindowedSplit(train, preset.window, list(preset.inputs), list(preset.targets))
        widths = field_widths(train[0], list(dict.fromkeys(preset.inputs + preset.targets)))
        torch.manual_seed(0)
        module = HybridModel(preset, widths)
        module.set_normalization(*_stats(ws.x), *_stats(ws.y))
        opt = torch.optim.Adam(module.parameters(), lr=1e-3)
        rng = np.random.default_rng(0)

        def step(module=module, opt=opt, ws=ws, rng=rng):
            idx = np.sort(rng.choice(len(ws), size=batch, replace=False))
            x, y, p = _batches(ws, idx, torch.device("cpu"))
            opt.zero_grad(set_to_none=True)
            loss = module.standardized_loss(module(x, p), y)
            loss.backward()
            opt.step()
        out[name] = (step, batch)
    return out


def main(argv=None) -> int:
    import hybrid_dyn as hd
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.timing import interleaved_rates

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=20, help="steps per preset per repeat")
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--out", type=Path, default=None, help="also write the table to this README.md")
    args = ap.parse_args(argv)
    import os

    load_before = os.getloadavg()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        robot = hd.load_robot("panda")
        ds = load_dataset(make_synthetic_dataset(Path(tmp) / "ds", robot, n_instances=10, n_samples=2000, seed=0,
                                                 friction=robot.spec.friction("gaz2019"), noise=0.01))
        steps = steps_of(ds, PRESETS, args.batch)
        rates = interleaved_rates(list(steps.values()), args.steps, args.repeats)
    ms = {name: args.batch / rate * 1e3 for name, rate in zip(steps, rates)}
    lines = [f"torch {torch.__version__}, 1 thread, batch {args.batch}; medians of {args.repeats} repeats of "
             f"{args.steps} steps each, interleaved; load average before {load_before}, after {os.getloadavg()}",
             "", f"{'preset':16s} {'ms/step':>8s} {'/ delan-friction':>17s}"]
    lines += [f"{name:16s} {v:8.2f} {v / ms['delan-friction']:17.2f}" for name, v in ms.items()]
    print("\n".join(lines))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("# DeLaN presets: one training step\n\nWritten by `python benchmarks/delan_step.py "
                            f"--repeats {args.repeats} --steps {args.steps} --out {args.out}`.\n\n```\n"
                            + "\n".join(lines) + "\n```\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
