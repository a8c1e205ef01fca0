"""The first calls of a new estimator cost what the others cost: each method built in a fresh process with an empty
numba cache (NUMBA_CACHE_DIR a new folder), then 1,500 calls at 1 kHz; prints the construction's CPU time and the
most CPU any one call took, and at which call (the window closes at call 500).

    python benchmarks/first_call.py [--methods torques-pinv,momentum-observer]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

CHILD = r"""
import sys, time, numpy as np, hybrid_dyn as hd
from hybrid_dyn.estimator import TipForceEstimator
p = hd.load_robot("panda"); m = sys.argv[1]
t0 = time.process_time(); est = TipForceEstimator.analytic(p, m, encoder_resolution=0.0); build = time.process_time() - t0
q = np.array(p.spec.home); qd = np.zeros(7); tau = p.inverse_dynamics(q, qd, qd); w = p.base_wrench(q, qd, qd)
worst = (0.0, -1)
for k in range(1500):
    t1 = time.process_time()
    est.estimate_tip_force(q, qd, base_wrench=w, tau_J=tau, t=k * 1e-3)
    worst = max(worst, (time.process_time() - t1, k))
print(f"| {m} | {build * 1e3:.0f} | {worst[0] * 1e3:.2f} | {worst[1]} |")
"""


def main() -> None:
    from hybrid_dyn.analytic.methods import TIP_FORCE_METHODS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", default=",".join(TIP_FORCE_METHODS.names()))
    args = ap.parse_args()
    print("| method | construction CPU [ms] | worst call CPU [ms] | at call |\n|---|---|---|---|")
    for m in args.methods.split(","):
        with tempfile.TemporaryDirectory() as cache:
            out = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, m], capture_output=True, text=True,
                                 env=dict(os.environ, NUMBA_CACHE_DIR=cache), check=True)
        print(out.stdout.strip())


if __name__ == "__main__":
    main()
