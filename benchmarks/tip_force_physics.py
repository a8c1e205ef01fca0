"""Tip-force accuracy of the physics estimators at the base sensor's limit (issue 16).

For each dataset given, on its test split: RMSE [N] (all samples and axes, as the
bench) of base-wrench-tared, momentum-observer, base-momentum (force rows, and
all six rows at a few moment weights), the Kalman filter with the base sensor
alone, the joint torques alone and both (model errors from each instance's tare
window, as the bench row; and from the specifications only); the base sensor's per-axis noise
RMS (``bench.metrics.base_force_noise_rms``). With --val, the validation split
(used to choose the settings; the test split only reports).

Run: .venv/bin/python benchmarks/tip_force_physics.py data/paper-ext-quick data/mismatch-ext-quick
     (make them with: hybrid-dyn generate --scenario paper-ext --profile quick --out data/paper-ext-quick)
"""
import argparse
import time

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.analytic.base_momentum import BaseMomentumObserver
from hybrid_dyn.analytic.kalman import FusionNoise, KalmanTipForce, tare_window_noise
from hybrid_dyn.analytic.momentum_observer import MomentumObserver
from hybrid_dyn.analytic.tare import TARE_SECONDS, tare_samples, tared_base_wrench
from hybrid_dyn.analytic.tip_force import tip_force_from_base_wrench
from hybrid_dyn.bench.metrics import base_force_noise_rms, rmse
from hybrid_dyn.data import load_dataset

GAIN = 20.0  # 1/s, the bench's observer bandwidth (K dt = 0.2 at 100 Hz)


def estimators(robot, dt, noise):
    def tared(inst):
        return tared_base_wrench(robot, inst.q, inst.qd, inst.qdd, inst.base_wrench, tare_samples(1 / dt, TARE_SECONDS))

    rows = {
        "base-wrench-tared": lambda i: tip_force_from_base_wrench(robot, i.q, i.qd, i.qdd, tared(i)),
        "momentum-observer": lambda i: MomentumObserver(robot, GAIN, dt).run(i.q, i.qd, i.tau_J)[0],
    }
    for w in (0.0, 1.0, 5.0, 20.0):
        name = "base-momentum" + ("" if w == 0 else f" (6 rows, moment weight {w:g}/m)")
        rows[name] = (lambda w: lambda i: BaseMomentumObserver(robot, GAIN, dt, w).run(i.q, i.qd, tared(i))[0])(w)
    n = tare_samples(1 / dt, TARE_SECONDS)

    def kalman(i, base=True, joint=True, window=True):
        w = tared(i)
        kn = tare_window_noise(robot, dt, i.q[:n], i.qd[:n], w[:n], i.tau_J[:n], noise) if window else noise
        return KalmanTipForce(robot, dt, kn).run(i.q, i.qd, w if base else None, i.tau_J if joint else None)

    rows["kalman base only"] = lambda i: kalman(i, joint=False)
    rows["kalman joint only"] = lambda i: kalman(i, base=False)
    rows["kalman-fusion (specifications only)"] = lambda i: kalman(i, window=False)
    rows["kalman-fusion"] = kalman
    return rows


def streaming_us(robot, dt, noise, inst, n=2000) -> dict:
    """Median cost of one streaming call [us] on this process's core."""
    w = inst.base_wrench
    out = {}
    for name, obj, call in [
        ("base-momentum", BaseMomentumObserver(robot, GAIN, dt), lambda o, k: o.step_force(inst.q[k], inst.qd[k], w[k])),
        ("kalman-fusion", KalmanTipForce(robot, dt, noise), lambda o, k: o.step(inst.q[k], inst.qd[k], w[k], inst.tau_J[k])),
    ]:
        times = []
        for k in range(min(n, len(inst))):
            t0 = time.perf_counter()
            call(obj, k)
            times.append(time.perf_counter() - t0)
        out[name] = float(np.median(times[10:]) * 1e6)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+")
    ap.add_argument("--val", action="store_true", help="score the validation split instead of the test split")
    ap.add_argument("--force-rate", type=float, default=FusionNoise().force_rate, help="N/sqrt(s)")
    args = ap.parse_args()
    robot = hd.load_robot("panda")
    noise = FusionNoise(force_rate=args.force_rate)
    split = "val" if args.val else "test"
    for path in args.datasets:
        ds = load_dataset(path)
        insts = ds.split(split)
        dt = 1.0 / ds.meta["record_hz"]
        truth = np.concatenate([i.truth["tip_force"] for i in insts])
        print(f"\n{path} ({ds.meta.get('scenario')}, {split} split: {len(insts)} instances, {len(truth)} samples)")
        print(f"  base sensor noise RMS per force axis: {base_force_noise_rms(insts):.4f} N")
        for name, fn in estimators(robot, dt, noise).items():
            pred = np.concatenate([fn(i) for i in insts])
            print(f"  {name:45s} RMSE {rmse(pred, truth):.4f} N")
        print("  streaming call, median [us]:", {k: round(v, 1) for k, v in streaming_us(robot, dt, noise, insts[0]).items()})


if __name__ == "__main__":
    main()
