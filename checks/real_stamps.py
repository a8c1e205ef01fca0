"""Issue 54's stamp floors on the real Panda log (its own PC stamps), through the library with the defaults
(``on_bad_input="raise"``: every refusal is an exception) and through ``hybrid-dyn estimate``'s replay (hold):
0 exceptions, at most 1 % ``input rejected``, ``warming up`` only in the first window.

    python checks/real_stamps.py [--method momentum-observer]
"""
from __future__ import annotations

import argparse
import collections
import sys

import numpy as np


def main() -> int:
    from hybrid_dyn.data import read_spec
    from hybrid_dyn.data.logs.importer import checked_segments
    from hybrid_dyn.data.logs.real_logs import real_spec_path
    from hybrid_dyn.estimator import EstimatorInputError, TipForceEstimator
    from hybrid_dyn.estimator.replay import replay_log

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="momentum-observer")
    args = ap.parse_args()
    spec = read_spec(real_spec_path("real-panda"))
    segments, _ = checked_segments(spec, derivatives=False)
    f = {k: np.concatenate([s.fields[k] for s in segments]) for k in ("t", "q", "qd", "tau_m")}
    est = TipForceEstimator.analytic(spec.robot, args.method, encoder_resolution=spec.encoder_resolution)
    raised, status = 0, []
    for k in range(len(f["t"])):
        try:
            est.estimate_tip_force(f["q"][k], f["qd"][k], tau_J=f["tau_m"][k], t=f["t"][k])
            status.append(est.last_status.value)
        except EstimatorInputError:
            raised += 1
            status.append("raised")
    warm = np.flatnonzero(np.array(status) == "warming up")
    lines = [f"library, defaults, {args.method}: {len(status)} samples, {raised} exceptions, statuses "
             f"{dict(collections.Counter(status))}; warming up on calls {warm.min() if len(warm) else '-'}-"
             f"{warm.max() if len(warm) else '-'} ({'one stretch' if len(warm) and np.all(np.diff(warm) == 1) else 'not one stretch'})"]
    rep, _ = replay_log(spec, args.method)
    st = np.array([s.split(":")[0] for s in rep.status])
    rejected = float(np.mean(st == "input rejected"))
    wr = np.flatnonzero(st == "warming up")
    lines.append(f"hybrid-dyn estimate's replay: {len(st)} samples, input rejected {100 * rejected:.2f} %, statuses "
                 f"{dict(collections.Counter(st))}; warming up in one stretch from the start: "
                 f"{bool(len(wr) and wr[0] == 0 and np.all(np.diff(wr) == 1))}")
    ok = raised == 0 and rejected <= 0.01 and len(wr) and wr[0] == 0 and np.all(np.diff(wr) == 1)
    print("\n".join(lines))
    print("met" if ok else "NOT met")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
