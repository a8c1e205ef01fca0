"""The start-up window's regression stream: the arm moves from the first sample, nothing touches it in the
documented first 0.5 s, and a 3.9 N contact starts at 0.501 s and is released at 4 s (read as hardware reads it,
``sim/trust_streams.py``). Prints, per seed and base-sensor method, the trust bench's scores (late bad ok, ok
share, 2-sigma share, statuses) and the steady RMSE [N] after the release (t > 5 s): a window that tared the
contact in keeps its 3.9 N there.

Run: .venv/bin/python benchmarks/start_contact_rmse.py [--seeds 300,301]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.sim.trust_streams import TrustCase, build

sys.path.insert(0, str(Path(__file__).parent))
from estimator_trust import run, score  # noqa: E402  (the trust bench's own call and scoring)

CONTACT_AFTER_WINDOW = TrustCase(8.0, ((0.0, 0.0), (0.501, 0.0), (0.502, 3.9), (4.0, 3.9), (4.001, 0.0), (8.0, 0.0)),
                                 moving=((0.0, 8.0),))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="300,301")
    args = ap.parse_args(argv)
    robot = hd.load_robot("panda", num_threads=1)
    for seed in (int(v) for v in args.seeds.split(",")):
        s = build(robot, CONTACT_AFTER_WINDOW, seed=seed)
        steady = s.t > 5.0
        for method in ("base-momentum", "base-wrench"):
            f, sig, st = run(robot, method, s)
            sc = score(s, f, sig, st)
            rmse = np.sqrt(np.nanmean(np.sum((f[steady] - s.force[steady]) ** 2, axis=1)))
            print(f"seed {seed} {method}: late bad ok {sc['late_bad_ok']}, ok {sc['ok']:.1%}, 2-sigma "
                  f"{sc['cover']:.1%}, steady RMSE {rmse:.3f} N; {sc['statuses']}")


if __name__ == "__main__":
    main()
