"""Which runtime should a control loop use for a trained network? (issue 6)

Times one single-window call of the network part of a trained model through:
  pytorch       eager module, torch.inference_mode, one thread
  torch.export  the exported program's module (same kernels, traced graph)
  onnxruntime   the network exported to ONNX
  numba         hybrid_dyn.learn.fastpath.FastNet
(TipForceEstimator.load(runtime="auto") keeps whichever of numba and onnxruntime is faster in the loop)
and checks that each agrees with eager PyTorch. Medians of 2,000 calls, one core (``hybrid_dyn.timing``).

Run: .venv/bin/python benchmarks/export_speed.py runs/default/mismatch-ext/*/models/seed-tip-11
"""
from __future__ import annotations

import argparse
import io
import os

import numpy as np
import torch

from hybrid_dyn.learn import load_model
from hybrid_dyn.learn.fastpath import FastNet
from hybrid_dyn.timing import median_call_us


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model_dir")
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {0})
    torch.set_num_threads(1)
    model = load_model(args.model_dir)
    net = model.module.net.eval()
    x = np.random.default_rng(0).normal(size=(1, model.window, model.module.n_in)).astype(np.float32)
    xt = torch.from_numpy(x)
    with torch.inference_mode():
        ref = net(xt).numpy()[0]
    rows = []

    def eager():
        with torch.inference_mode():
            return net(xt)

    rows.append(("pytorch eager", median_call_us(eager, 2000), 0.0))
    exported = torch.export.export(net, (xt,)).module()

    def exp_call():
        with torch.inference_mode():
            return exported(xt)

    with torch.inference_mode():
        rows.append(("torch.export", median_call_us(exp_call, 2000), float(np.abs(exported(xt).numpy()[0] - ref).max())))
    try:
        import onnxruntime as ort

        buf = io.BytesIO()
        torch.onnx.export(net, (xt,), buf, input_names=["x"], output_names=["y"], dynamo=False)
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = opts.inter_op_num_threads = 1
        sess = ort.InferenceSession(buf.getvalue(), opts, providers=["CPUExecutionProvider"])
        rows.append(("onnxruntime", median_call_us(lambda: sess.run(None, {"x": x}), 2000),
                     float(np.abs(sess.run(None, {"x": x})[0][0] - ref).max())))
    except Exception as err:  # an exporter that refuses the graph: report it, keep the other rows
        rows.append((f"onnxruntime (unavailable: {type(err).__name__}: {str(err)[:60]})", float("nan"), float("nan")))
    fast = FastNet(net)
    x64 = x[0].astype(np.float64)
    rows.append(("numba FastNet", median_call_us(lambda: fast(x64), 2000),
                 float(np.abs(fast(x64) - ref).max())))
    print(f"model {args.model_dir} ({model.preset.name}: {model.preset.kind}, window {model.window})")
    print(f"{'runtime':58s} {'median us':>10s} {'max |diff| vs eager':>20s}")
    for name, us, diff in rows:
        print(f"{name:58s} {us:10.1f} {diff:20.2e}")
    best = min((r for r in rows if np.isfinite(r[1])), key=lambda r: r[1])
    print(f"fastest: {best[0]}")


if __name__ == "__main__":
    main()
