"""The streaming tip-force estimators on 1 kHz control streams read through hardware sensors.

Each pattern is one ``sim.stream.StreamConfig`` (a DART Panda under PD control, step and trapezoid
contacts, Gaz friction), read through ``sim.sensors.HardwareSensors``: q quantized to the Panda's
encoder resolution (1e-5 rad), qd the drive's difference of it, link-side joint torques with 0.05 Nm
noise, a base F/T sensor with 0.2 N / 0.01 Nm noise, a bias of up to 2 N and a drift. Every method
runs with ``TipForceEstimator.analytic(robot, method)`` defaults, fed every tick with its stamp
(and ``payload=`` where the pattern declares the tool's load). Per method and pattern:

- RMSE [N]: the 3-D error over every call after the 0.5 s noise window; steady RMSE [N]: the same outside
  100 ms of a contact change; 90 % rise [ms]: the median time from a contact change to the estimate
  covering 90 % of the step;
- edge share: the share of that squared error within 20 ms of a contact's onset or release;
- late bad ok: calls whose status is ``ok`` with an error over 2 N later than 100 ms after a
  contact's onset or release;
- ok: the share of calls after the window whose status is ``ok``;
- 2-sigma: the share of ``ok`` calls whose error lies within 2 ``last_sigma`` on every axis;
- accepted: the share of calls not refused by the input gate.

Patterns: ``hardware`` (the default stream: drift 0.3 N over 12 s), ``exact`` (ideal sensors but the
F/T noise of 0.05 N: the clean step stream), ``press-at-start`` (10 N pressing from t = 0 for 2 s),
``touch-in-window`` (6 N for 0.2 s inside the window), ``step-15`` (one 15 N step held 2 s),
``drift`` (0.05 N/s for 60 s), ``jitter`` (stamps jittering by 0.2 ms sigma) and ``payload``
(a 0.5 kg tool load the estimator is told of; ``payload-unknown``: not told).

Run: .venv/bin/python benchmarks/tip_force_stream.py [--patterns hardware,exact] [--streams 2]
     [--out reports/performance/tip-force-stream/README.md]
"""
from __future__ import annotations

import argparse
import platform
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.estimator import TipForceEstimator
from hybrid_dyn.sim.generator_config import ContactStepConfig
from hybrid_dyn.sim.sensors import ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors
from hybrid_dyn.sim.stream import StreamConfig, Touch, simulate_stream

METHODS = ("base-wrench", "base-momentum", "kalman-fusion", "torques-pinv", "momentum-observer")
HARDWARE = HardwareSensors(EncoderModel(1e-5, "difference"), ForceTorqueModel(force_drift=0.3 / 12, torque_drift=0.0))
PAYLOAD = (0.5, (0.0, 0.0, 0.05))
QUIET = {"contacts": None}
PATTERNS = {
    "hardware": StreamConfig(sensors=HARDWARE),
    "exact": StreamConfig(sensors=replace(HardwareSensors.exact(), base=ForceTorqueModel(0.05, 0.0025, 2.0, 0.1))),
    "press-at-start": StreamConfig(seconds=8.0, sensors=HARDWARE, **QUIET,
                                   touches=(Touch(0.0, 10.0, 2.0, direction=(0.3, 0.2, -1.0)),)),
    "touch-in-window": StreamConfig(seconds=8.0, sensors=HARDWARE, **QUIET,
                                    touches=(Touch(0.2, 6.0, 0.2, direction=(1.0, 0.0, -0.5)),
                                             Touch(4.0, 8.0, 1.0, rise=0.01))),
    "step-15": StreamConfig(seconds=8.0, sensors=HARDWARE, **QUIET,
                            touches=(Touch(3.0, 15.0, 2.0, direction=(0.0, 1.0, -1.0)),)),
    "drift": StreamConfig(seconds=60.0, sensors=replace(HARDWARE, base=ForceTorqueModel(force_drift=0.05)),
                          contacts=ContactStepConfig(count=(8, 12), gap=(3.0, 6.0))),
    "jitter": StreamConfig(sensors=replace(HARDWARE, clock=ClockModel(2e-4))),
    "payload": StreamConfig(sensors=HARDWARE, payload=PAYLOAD),
    "payload-unknown": StreamConfig(sensors=HARDWARE, payload=PAYLOAD),
}
DECLARED_PAYLOAD = {"payload": PAYLOAD}


def contact_edges(force: np.ndarray, dt: float) -> np.ndarray:
    """Times [s] where the true force starts or stops changing: onsets and releases of every contact."""
    moving = np.linalg.norm(np.diff(force, axis=0), axis=1) > 1e-9
    change = np.flatnonzero(np.diff(moving.astype(int)) != 0) + 1
    return np.r_[np.flatnonzero(moving[:1]), change] * dt


def run_method(robot, method, stream, payload=None):
    """Feed one stream to one estimator, told the stream's encoder resolution (0 for exact encoders): forces,
    sigmas, statuses, accepted flags and CPU time per call."""
    r = stream.readings
    kwargs = {"encoder_resolution": stream.encoder_resolution}
    if payload is not None:
        kwargs["payload"] = payload
    est = TipForceEstimator.analytic(robot, method, call_hz=1000.0, on_bad_input="hold", **kwargs)
    n = len(r.t)
    f, sig = np.zeros((n, 3)), np.full((n, 3), np.inf)
    status, accepted = np.empty(n, dtype=object), np.ones(n, bool)
    wall = np.empty(n)
    reads = est.spec.reads
    for k in range(n):
        w = r.base_wrench[k] if "base_wrench" in reads else None
        tau = r.tau_J[k] if "tau_J" in reads else None
        t0 = time.thread_time()  # CPU time of this thread: the machine's other load does not count
        f[k] = est.estimate_tip_force(r.q[k], r.qd[k], base_wrench=w, tau_J=tau, t=r.t[k])
        wall[k] = time.thread_time() - t0
        s = getattr(est, "last_sigma", None)
        if s is not None:
            sig[k] = s
        status[k] = est.last_status.value
        accepted[k] = est.last_status.value != "input rejected"
    return f, sig, status, accepted, wall


def rise_time(truth, f, t, edges, share=0.9):
    """Median time [s] from each contact change to the estimate covering 90 % of the step (the change in the
    true force 50 ms after the edge against 10 ms before it); nan without a step of 1 N or more."""
    out = []
    for e in edges:
        k0, k1 = np.searchsorted(t, e - 0.01), np.searchsorted(t, e + 0.05)
        if k1 >= len(t):
            continue
        step = truth[k1] - truth[k0]
        size = np.linalg.norm(step)
        if size < 1.0:
            continue
        progress = (f[k0:k1] - truth[k0]) @ step / size ** 2
        hit = np.flatnonzero(progress >= share)
        out.append(t[k0 + hit[0]] - e if len(hit) else 0.05)
    return float(np.median(out)) if out else float("nan")


def score(stream, f, sig, status, accepted, dt=1e-3, window=0.5):
    truth, t = stream.tip_force, stream.t
    after = t >= window
    err = f - truth
    e3 = np.linalg.norm(err, axis=1)
    ok = (status == "ok") & after
    edges = contact_edges(truth, dt)
    since = np.full(len(t), np.inf)
    for e in edges:
        since = np.where(t >= e, np.minimum(since, t - e), since)
    late_bad = int(np.sum(ok & (e3 > 2.0) & (since > 0.1)))
    sq = e3[after] ** 2
    edge = float(sq[since[after] < 0.02].sum() / sq.sum()) if sq.sum() > 0 else float("nan")
    inside = np.all(np.abs(err) <= 2 * sig, axis=1)
    steady = after & (since > 0.1)
    return {"rmse": float(np.sqrt(np.mean(e3[after] ** 2))), "steady": float(np.sqrt(np.mean(e3[steady] ** 2))),
            "rise": rise_time(truth, f, t, edges), "late_bad_ok": late_bad, "edge": edge,
            "ok": float(ok.sum() / after.sum()), "cover": float(inside[ok].mean()) if ok.any() else float("nan"),
            "accepted": float(accepted.mean())}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--patterns", default=",".join(PATTERNS))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--streams", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="write the table here (Markdown)")
    args = ap.parse_args(argv)
    robot = hd.load_robot("panda", num_threads=1)
    lines = ["| pattern | method | RMSE [N] | steady RMSE [N] | 90 % rise [ms] | edge share | late bad ok | ok | 2-sigma | accepted | median call CPU [us] "
             "| max call CPU [us] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in args.patterns.split(","):
        cfg = PATTERNS[name]
        streams = [simulate_stream(robot, cfg, seed=100 + s) for s in range(args.streams)]
        for m in args.methods.split(","):
            runs = [run_method(robot, m, s, DECLARED_PAYLOAD.get(name)) for s in streams]
            rows = [score(s, *run[:4]) for s, run in zip(streams, runs)]
            walls = np.concatenate([run[4] for run in runs])
            agg = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
            agg["rmse"] = float(np.sqrt(np.mean([r["rmse"] ** 2 for r in rows])))
            agg["steady"] = float(np.sqrt(np.mean([r["steady"] ** 2 for r in rows])))
            agg["rise"] = float(np.nanmedian([r["rise"] for r in rows])) if any(np.isfinite(r["rise"]) for r in rows) else float("nan")
            agg["late_bad_ok"] = int(sum(r["late_bad_ok"] for r in rows))
            line = (f"| {name} | {m} | {agg['rmse']:.3f} | {agg['steady']:.3f} | {agg['rise'] * 1e3:.1f} "
                    f"| {agg['edge']:.0%} | {agg['late_bad_ok']} | {agg['ok']:.1%} | {agg['cover']:.1%} "
                    f"| {agg['accepted']:.2%} | {np.median(walls) * 1e6:.1f} | {walls.max() * 1e6:.0f} |")
            print(line, flush=True)
            lines.append(line)
    head = (f"# Tip force on hardware-like 1 kHz streams\n\n`python benchmarks/tip_force_stream.py "
            f"--patterns {args.patterns} --streams {args.streams}` on {platform.machine()}, "
            f"{args.streams} streams a pattern (seeds 100..). Call times are the calling thread's CPU time per "
            f"call (time.thread_time, whose resolution is the kernel's: 1 us or coarser).\n\n")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(head + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
