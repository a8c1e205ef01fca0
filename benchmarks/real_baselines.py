"""Baselines and diagnostics of the real-robot sets: why is nMSE where it is?

For each set (real-kuka, real-baxter, real-sarcos, real-panda; a set whose log is absent
is skipped, saying where to get it) this reports, with the bench's split (by trajectory;
SARCOS and the Panda by contiguous blocks) and nMSE = per-joint test MSE / per-joint
test-target variance, averaged over joints:

- predicting the training mean (nMSE ~ 1 by construction);
- a linear least-squares fit on [q, qd, qdd, sin q, cos q, 1] (rigid-body dynamics is
  linear in its parameters, not in these features: a rough check);
- a small MLP (2 x 64 tanh, Adam 1e-3, batch 256, early stop after 5 epochs without
  validation improvement);
- Gaussian-process regression (``hybrid_dyn.learn.gp``, fitted with scikit-learn; one GP
  per joint, ARD squared-exponential kernel plus white noise), the reference method of the
  SARCOS set (Rasmussen & Williams 2006, ch. 8). Its hyperparameters are fitted by marginal
  likelihood on ``--gp-hyper`` random training rows; it is then conditioned on at most
  ``--gp-rows`` random training rows (a subset-of-data GP, to bound the O(n^3) cost);
- the bench's ``tau-mlp-wide`` (its best model on KUKA), trained as the ``real``
  bench profile trains it;

and three diagnostics:

- **interpolation control**: the GP (same hyperparameters) and ``tau-mlp-wide`` again,
  on a second import of the same log whose instances are contiguous chunks of every
  trajectory (KUKA, Baxter: 4 per trajectory, about 5 s each; SARCOS: 40 blocks of
  about 111 rows; the Panda: 40 blocks of about 0.5 s) split 64/16/20 at random with the
  spec's seed. Test states then lie among training states of the same trajectories, and
  neighbouring chunks share their boundary states, so this control is optimistic by design. (The importer derives
  accelerations per instance, so a chunk's first and last samples carry the filter's
  edge effects; that part makes the control slightly harder, not easier.) It is NOT the benchmark's
  protocol: the gap between it and the trajectory split measures how much of the error
  is generalisation to unseen trajectories rather than model capacity or sensor noise;
- **torque content above 5 Hz** (KUKA, Baxter, the Panda: their rows are continuous in time): the
  test variance left after a zero-phase 4th-order Butterworth low-pass, as a fraction of
  the variance; an estimate of the measurement-noise share of nMSE;
- **coverage**: per joint, the share of test rows whose q lies outside the training
  split's range.

These are diagnostics, not benchmark rows: ``hybrid-dyn bench --profile real`` is the
benchmark. With ``--out FILE.json`` the numbers are also written as JSON, and as a
Markdown summary beside it (FILE.md); ``--render FILE.json`` only rewrites that summary.

    .venv/bin/python benchmarks/real_baselines.py [--cache DIR] [--epochs N] [--out reports/real/baselines.json]
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from hybrid_dyn.bench import get_profile
from hybrid_dyn.data import REAL_SETS, load_dataset, real_dataset
from hybrid_dyn.data.real import missing_real_log, nmse_per_joint, target_statistics
from hybrid_dyn.learn import TrainConfig, train_model
from hybrid_dyn.learn.gp import GPConfig, condition_gp, fit_gp_hyperparameters


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


def xy(insts):
    """Inputs [q, qd, qdd] and torque targets of a list of instances."""
    x = np.concatenate([np.concatenate([i.q, i.qd, i.qdd], axis=1) for i in insts])
    return x, np.concatenate([i.tau_m for i in insts])


def train_bench_model(ds, preset: str, out_dir):
    """``preset`` trained as the ``real`` bench profile trains it; predict(instances) -> rows."""
    model = train_model(ds, preset, out_dir, TrainConfig(**get_profile("real").train, progress=False, num_threads=1))
    return lambda insts: np.concatenate(model.predict(insts))


def high_frequency_share(insts, cutoff_hz=5.0):
    """Per joint: variance of tau_m above ``cutoff_hz`` (zero-phase 4th-order Butterworth)
    over the total variance, on the given (time-continuous) instances."""
    from scipy.signal import butter, filtfilt

    hf, y = [], []
    for inst in insts:
        fs = 1.0 / float(np.median(np.diff(inst.t)))
        b, a = butter(4, cutoff_hz / (fs / 2))
        hf.append(inst.tau_m - filtfilt(b, a, inst.tau_m, axis=0))
        y.append(inst.tau_m)
    return np.concatenate(hf).var(0) / np.concatenate(y).var(0)


def render_markdown(results: dict) -> str:
    """A Markdown summary of the JSON that :func:`main` writes."""
    fmt = lambda v: " ".join(f"{x:.3f}" for x in v)  # noqa: E731
    sets = results["sets"]
    labels = list(next(iter(sets.values()))["nmse"])
    control = list(next(iter(sets.values()))["control"]["nmse"])
    md = ["# Real-robot sets: baselines and diagnostics", "",
          f"Written by `{results['command']}` (its docstring describes every method). nMSE = per-joint test MSE / "
          "per-joint test-target variance, averaged over joints. Columns without *control* use the bench's split "
          "(by trajectory; SARCOS by contiguous blocks); *control* columns use the interpolation control (chunks of "
          "every trajectory split at random: not the benchmark's protocol, optimistic by design).", "",
          "| set | " + " | ".join(labels) + " | " + " | ".join(f"{c}, control" for c in control) + " |",
          "|---|" + "---|" * (len(labels) + len(control))]
    for name, r in sets.items():
        md.append(f"| {name} | " + " | ".join(f"{r['nmse'][k]:.3f}" for k in labels) + " | "
                  + " | ".join(f"{r['control']['nmse'][k]:.3f}" for k in control) + " |")
    md += ["", "Per joint (J1 ... J7):", ""]
    for name, r in sets.items():
        md += [f"**{name}** (trajectory split: {r['samples'][0]} / {r['samples'][1]} / {r['samples'][2]} train / val / "
               f"test samples; control: {r['control']['instances']} chunks, {r['control']['samples']} samples)", "",
               f"- test target std [Nm]: {fmt(r['test_std'])}"]
        md += [f"- nMSE, {k}: {fmt(r['nmse_per_joint'][k])}" for k in labels[2:]]
        md += [f"- nMSE, {k}, control: {fmt(r['control']['nmse_per_joint'][k])}" for k in control]
        if "torque_share_above_5hz" in r:
            md.append(f"- test torque variance above 5 Hz / total: {fmt(r['torque_share_above_5hz'])}")
        md += [f"- test rows with q outside the training range: {fmt(r['test_q_outside_train_range'])}", ""]
    return "\n".join(md)


# Sets whose rows are continuous in time (SARCOS's rows are not: benchmarks/real/sarcos.toml),
# and the chunks per trajectory of their interpolation control.
CONTINUOUS = {"real-kuka": True, "real-baxter": True, "real-sarcos": False, "real-panda": True}
CONTROL_BLOCKS = {"real-kuka": 4, "real-baxter": 4, "real-sarcos": 40, "real-panda": 40}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="/tmp/hybrid_dyn_real_cache")
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--gp-hyper", type=int, default=600, help="training rows for the GP hyperparameter fit")
    ap.add_argument("--gp-rows", type=int, default=8000, help="training rows the GP is conditioned on")
    ap.add_argument("--sets", nargs="*", default=list(REAL_SETS), choices=list(REAL_SETS))
    ap.add_argument("--out", help="also write the numbers as JSON here (and a Markdown summary beside it)")
    ap.add_argument("--render", help="only rewrite the Markdown summary of this JSON file")
    args = ap.parse_args(argv)
    if args.render:
        path = Path(args.render)
        path.with_suffix(".md").write_text(render_markdown(json.loads(path.read_text())) + "\n")
        print(f"wrote {path.with_suffix('.md')}")
        return 0
    np.set_printoptions(precision=4, suppress=True, linewidth=160)
    results = {"command": "benchmarks/real_baselines.py", "args": vars(args), "sets": {}}
    gp_config = GPConfig(hyper_rows=args.gp_hyper, rows=args.gp_rows)
    for name in args.sets:
        absent = missing_real_log(name)
        if absent:
            print(f"\n{name}: skipped: {absent}")
            continue
        ds = load_dataset(real_dataset(name, args.cache))
        stats = target_statistics(ds, "tau_m", "test")
        xtr, ytr = xy(ds.split("train"))
        xva, yva = xy(ds.split("val"))
        xte, yte = xy(ds.split("test"))
        nv = ytr.shape[1]
        var = np.asarray(stats["variance"])
        res = results["sets"][name] = {"samples": [len(xtr), len(xva), len(xte)], "test_std": np.sqrt(var).tolist(),
                                       "nmse": {}, "nmse_per_joint": {}}

        def record(label, pred, seconds=None, control=False):
            """nMSE of ``pred`` on the test targets of the trajectory split (or of the control)."""
            table, target = (res["control"], ty) if control else (res, yte)
            n = nmse_per_joint(pred, target)
            table["nmse"][label], table["nmse_per_joint"][label] = float(n.mean()), n.tolist()
            took = "" if seconds is None else f"  ({seconds:.0f} s)"
            print(f"  nMSE {label + (', control' if control else ''):<30}{n}  mean {n.mean():.4f}{took}", flush=True)

        print(f"\n{name}: train/val/test samples {len(xtr)}/{len(xva)}/{len(xte)}")
        print(f"  test target std per joint [Nm]  {np.sqrt(var)}")
        record("train mean", np.broadcast_to(ytr.mean(0), yte.shape))
        w, *_ = np.linalg.lstsq(features(xtr, nv), ytr, rcond=None)
        record("linear (q,qd,qdd,sin,cos)", features(xte, nv) @ w)
        t0 = time.perf_counter()
        record("MLP 2x64 tanh", fit_mlp(xtr, ytr, xva, yva, args.epochs)(xte), time.perf_counter() - t0)
        t0 = time.perf_counter()
        hyper = fit_gp_hyperparameters(xtr, ytr, gp_config)
        record("GP (trajectory split)", condition_gp(xtr, ytr, hyper, gp_config).predict_rows(xte),
               time.perf_counter() - t0)

        t0 = time.perf_counter()
        record("tau-mlp-wide (bench model)",
               train_bench_model(ds, "tau-mlp-wide", Path(args.cache) / "models" / name)(ds.split("test")),
               time.perf_counter() - t0)

        # Interpolation control: every trajectory contributes train, val and test chunks.
        # The importer's blocks mode cuts every trajectory into CONTROL_BLOCKS[name] contiguous chunks.
        ctrl = load_dataset(real_dataset(name, args.cache, name=f"{name}-chunks", trajectories="blocks",
                                         n_blocks=CONTROL_BLOCKS[name]))
        cx, cy = xy(ctrl.split("train"))
        tx, ty = xy(ctrl.split("test"))
        res["control"] = {"instances": [len(ctrl.split(k)) for k in ("train", "val", "test")],
                          "samples": [len(cx), len(xy(ctrl.split("val"))[0]), len(tx)], "nmse": {}, "nmse_per_joint": {}}
        print(f"  interpolation control (not the benchmark's split): {res['control']['instances']} chunks, "
              f"{res['control']['samples']} samples")

        t0 = time.perf_counter()
        # Conditioned on no more rows than the trajectory split's GP, so that only the split differs.
        control_config = GPConfig(hyper_rows=args.gp_hyper, rows=min(args.gp_rows, len(xtr)))
        record("GP", condition_gp(cx, cy, hyper, control_config).predict_rows(tx), time.perf_counter() - t0,
               control=True)
        t0 = time.perf_counter()
        record("tau-mlp-wide (bench model)",
               train_bench_model(ctrl, "tau-mlp-wide", Path(args.cache) / "models" / f"{name}-chunks")(
                   ctrl.split("test")), time.perf_counter() - t0, control=True)
        if CONTINUOUS[name]:
            share = high_frequency_share(ds.split("test"))
            res["torque_share_above_5hz"] = share.tolist()
            print(f"  torque variance > 5 Hz / total  {share}  mean {share.mean():.4f}")
        qtr, qte = xtr[:, :nv], xte[:, :nv]
        outside = ((qte < qtr.min(0)) | (qte > qtr.max(0))).mean(0)
        res["test_q_outside_train_range"] = outside.tolist()
        print(f"  test q outside training range   {outside}")
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(results, indent=1) + "\n")
        Path(args.out).with_suffix(".md").write_text(render_markdown(results) + "\n")
        print(f"wrote {args.out} and its .md summary")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
