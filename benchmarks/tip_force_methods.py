"""The estimator methods' bench rows on small tip-force scenarios: the automatic bandwidth against the one
chosen on validation (issue 27), without the whole ``reports/default`` (>70 min of CPU).

Generates (or reuses, in --data) the tip-force scenarios of the default bench at a small size
(``--size quick``: 6 instances at 100 Hz, 4 at 1 kHz for the contact scenarios; ``default``: the
default bench's sizes), then runs the bench's own analytic rows on each (``bench/analytic_rows.py``:
``name`` = the estimator with its defaults, the bandwidth by the rule of analytic/bandwidth.py;
``name-val`` = the bandwidth chosen on the validation split) and prints the test RMSE [N] (the bench's
metric: sqrt of the mean over samples and axes) with the bandwidths used.

Run: .venv/bin/python benchmarks/tip_force_methods.py [--size quick] [--data /tmp/tipforce-data]
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.bench.catalog import ROWS
from hybrid_dyn.bench.metrics import rmse
from hybrid_dyn.bench.profiles import get_profile
from hybrid_dyn.deprecation import DeprecatedFlag
from hybrid_dyn.bench.rows import BenchContext
from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import scenario_config

SCENARIOS = ("paper-ext", "mismatch-ext", "contact-steps", "contact-steps-quiet")
ROW_NAMES = ("base-wrench-tared", "torques-pinv", "momentum-observer", "momentum-observer-val", "base-momentum",
             "base-momentum-val", "kalman-fusion", "kalman-fusion-val")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="quick", choices=("quick", "default"), help="the scenarios' generator size")
    ap.add_argument("--profile", dest="size", choices=("quick", "default"), action=DeprecatedFlag, new="--size",
                    help=argparse.SUPPRESS)  # its name until issue 30 (a size, not a bench profile)
    ap.add_argument("--data", default=str(Path(tempfile.gettempdir()) / "tipforce-data"))
    ap.add_argument("--scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    robot = hd.load_robot("panda", num_threads=1)
    table = {}
    for scenario in args.scenarios:
        # The default bench's sizes where it shrinks a scenario (40 instances of 5-10 trajectories).
        overrides = get_profile("default").scenario_overrides.get(scenario, {}) if args.size == "default" else {}
        cfg = scenario_config(scenario, args.size, **overrides)
        path = generate_dataset(cfg, Path(args.data) / f"{scenario}-{args.size}-{cfg.config_hash()}",
                                workers=args.workers, progress=False)
        ds = load_dataset(path)
        ctx = BenchContext(profile=None, scenario=scenario, dataset=ds, robot=robot, work_dir=Path(args.data),
                           log=lambda msg: print("   ", msg, flush=True))
        test = ds.split("test")
        target = np.concatenate([i["tip_force"] for i in test])
        print(f"{scenario}: {len(test)} test instances, {len(target)} samples at {ds.meta['record_hz']:g} Hz", flush=True)
        for name in ROW_NAMES:
            pred = ROWS[name].build(ds, ctx)
            table[scenario, name] = rmse(np.concatenate(pred.predict(test)), target)
            print(f"  {name:24s} RMSE {table[scenario, name]:.4f} N   [{pred.inputs}]", flush=True)
    print(f"\ntest RMSE [N] by row and scenario ({args.size} sizes); mean over the scenarios; in brackets the "
          "ratio to base-wrench-tared (issue 16's floors: <= 0.4 on paper-ext and mismatch-ext, <= 0.6 on contact-steps)")
    print(f"{'row':24s} " + " ".join(f"{s:>28s}" for s in args.scenarios) + f" {'mean':>8s}")
    for name in ROW_NAMES:
        cells = [f"{table[s, name]:.4f} ({table[s, name] / table[s, 'base-wrench-tared']:.2f}x)" for s in args.scenarios]
        mean = np.mean([table[s, name] for s in args.scenarios])
        print(f"{name:24s} " + " ".join(f"{c:>28s}" for c in cells) + f" {mean:8.4f}")


if __name__ == "__main__":
    main()
