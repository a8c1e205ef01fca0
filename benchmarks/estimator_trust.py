"""Can a control loop trust the estimator's status? Every method on the ground-truth streams of
``sim/trust_streams.py`` (slow contacts at standstill, the toolkit's jitter clock, drift over 120 s of
motion, sensor faults, a gap, a start in motion), fed every tick with its stamp, defaults otherwise
(``on_bad_input="raise"``, every refusal caught and counted). Per method and case:

- late bad ok: calls ``ok`` with a 3-D error over 2 N later than 100 ms after a contact change (the floor: 0);
- ok: the share of calls after the first 0.5 s that are ``ok`` (it must stay high where the case is decidable);
- 2-sigma: the share of ``ok`` calls within 2 ``last_sigma`` on every axis (floor on drift-motion: >= 90 %);
- refused: samples the input gate refused (floor on jitter: 0); worst ok [N]: the largest error of an ``ok`` call
  later than 100 ms after a change; statuses: the non-ok statuses seen, by count.

Run: .venv/bin/python benchmarks/estimator_trust.py [--cases slow-ramp,jitter] [--methods base-momentum]
     [--seeds 1] [--out reports/performance/estimator-trust/README.md]
"""
from __future__ import annotations

import argparse
import collections
import platform
from pathlib import Path

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.estimator import EstimatorInputError, TipForceEstimator
from hybrid_dyn.sim.trust_streams import CASES, build

METHODS = ("base-wrench", "base-momentum", "kalman-fusion", "torques-pinv", "momentum-observer")


def run(robot, method, s):
    """Feed stream s to a fresh estimator: forces, sigmas, statuses ('refused' for a refused sample)."""
    est = TipForceEstimator.analytic(robot, method, payload=s.payload, encoder_resolution=s.encoder_resolution)
    reads = est.spec.reads
    n = len(s.t)
    f, sig = np.full((n, 3), np.nan), np.full((n, 3), np.inf)
    status = np.full(n, "lost", dtype=object)
    for k in np.flatnonzero(s.arrives):
        try:
            f[k] = est.estimate_tip_force(s.q[k], s.qd[k], base_wrench=s.base_wrench[k] if "base_wrench" in reads else None,
                                          tau_J=s.tau_J[k] if "tau_J" in reads else None, t=s.t[k])
        except EstimatorInputError:
            status[k] = "refused"
            continue
        sig[k] = est.last_sigma
        status[k] = est.last_status.value
    return f, sig, status


def score(s, f, sig, status):
    t = np.arange(len(s.t)) * 1e-3
    since = np.full(len(t), np.inf)
    for e in s.changes:
        since = np.where(t >= e, np.minimum(since, t - e), since)
    err = f - s.force
    e3 = np.linalg.norm(err, axis=1)
    after = t >= 0.5
    ok = (status == "ok") & after
    late = ok & (since > 0.1)
    inside = np.all(np.abs(err) <= 2 * sig, axis=1)
    seen = collections.Counter(status[after & (status != "ok")])
    return {"late_bad_ok": int(np.sum(late & (e3 > 2.0))), "ok": float(ok.sum() / after.sum()),
            "cover": float(inside[ok].mean()) if ok.any() else float("nan"), "refused": int(np.sum(status == "refused")),
            "worst": float(e3[late].max()) if late.any() else float("nan"), "statuses": dict(seen)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="write the table here (Markdown)")
    args = ap.parse_args(argv)
    robot = hd.load_robot("panda", num_threads=1)
    lines = ["| case | method | late bad ok | ok | 2-sigma | refused | worst ok [N] | other statuses |",
             "|---|---|---|---|---|---|---|---|"]
    for case in args.cases.split(","):
        streams = [build(robot, case, seed=300 + i) for i in range(args.seeds)]
        for m in args.methods.split(","):
            rows = [score(s, *run(robot, m, s)) for s in streams]
            seen = collections.Counter()
            for r in rows:
                seen.update(r["statuses"])
            other = ", ".join(f"{k} {v}" for k, v in seen.most_common(4))
            line = (f"| {case} | {m} | {sum(r['late_bad_ok'] for r in rows)} | {np.mean([r['ok'] for r in rows]):.1%} "
                    f"| {np.nanmean([r['cover'] for r in rows]):.1%} | {sum(r['refused'] for r in rows)} "
                    f"| {np.nanmax([r['worst'] for r in rows]):.2f} | {other} |")
            print(line, flush=True)
            lines.append(line)
    head = (f"# The estimator's status on ground-truth streams\n\n`python benchmarks/estimator_trust.py --cases "
            f"{args.cases} --seeds {args.seeds}` on {platform.machine()} (seeds 300..).\n\n")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(head + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
