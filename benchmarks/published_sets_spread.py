"""How far a robot's published parameter sets disagree, as the stated model term reads an inertial uncertainty
(``estimator/model_term.py``): the RMS of their gravity torques' difference over poses drawn uniformly in the joint
range, against the RMS gravity torque, per joint; and the relative 1-sigma that the term (a common factor and each
link's own) would need to predict that difference. The source of the Panda's ``inertial_uncertainty`` (10 %).

    python benchmarks/published_sets_spread.py [--robot panda] [--sets gaz2019,franka_official] [--poses 2000]
"""
from __future__ import annotations

import argparse

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.estimator.model_term import StatedModelError


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="panda")
    ap.add_argument("--sets", default="gaz2019,franka_official")
    ap.add_argument("--poses", type=int, default=2000)
    args = ap.parse_args()
    first, second = (hd.load_robot(args.robot, params=name, num_threads=1) for name in args.sets.split(","))
    lo, hi = first.model.lowerPositionLimit, first.model.upperPositionLimit
    q = np.random.default_rng(0).uniform(lo, hi, (args.poses, first.nv))
    g = first.gravity(q)
    diff = second.gravity(q) - g
    rms = lambda x: np.sqrt(np.mean(x ** 2, axis=0))  # noqa: E731
    term = StatedModelError(first, "torques", 1.0, 0.0)  # unit sigma: D's joint-torque rows per unit
    zero = np.zeros(first.nv)
    unit = np.array([np.sqrt((term._columns(p, zero, zero)[6:] ** 2).sum(axis=1)) for p in q])
    print(f"{args.robot}: {args.sets} over {args.poses} poses (seed 0)")
    print("joint | RMS gravity torque [Nm] | RMS difference [Nm] | ratio | sigma the term needs")
    for j in range(first.nv):
        need = rms(diff)[j] / max(rms(unit)[j], 1e-12)
        print(f"{j + 1} | {rms(g)[j]:.2f} | {rms(diff)[j]:.2f} | {rms(diff)[j] / max(rms(g)[j], 1e-12):.3f} | {need:.3f}")
    whole = np.sqrt(np.mean(np.sum(diff ** 2, axis=1)) / np.mean(np.sum(g ** 2, axis=1)))
    print(f"all joints: RMS difference / RMS gravity torque = {whole:.3f}")


if __name__ == "__main__":
    main()
