"""How much of a joint-torque target no model of (q, qd, qdd) can know: the tip force's torque J^T F.

On a scenario with external forces (seed-sim, paper-ext) the measured torque is the rigid-body torque
plus friction plus J(q)^T F_tip. A torque model that reads only the joint states (the reference study's torque
nets, DeLaN, RNEA, the identified model) cannot see F_tip, which is drawn independently of the motion,
so the RMS of J^T F_tip over the test split is a floor on its RMSE (issue 31: why the seed-sim torque
floor of 1.03 Nm is not met). The rows that read the base sensor see it and go below.

    .venv/bin/python checks/unobservable_torque.py data/seed-sim-paper-dd419eedfcb86997 [--report reports/seed-sim]
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.bench.results import read_results
from hybrid_dyn.data import load_dataset


def external_torque_rms(dataset, split: str = "test") -> tuple[float, np.ndarray, int]:
    """(RMS over joints and samples [Nm], per-joint RMS (nv,) [Nm], samples) of J(q)^T F_tip on ``split``."""
    robot = hd.load_robot(dataset.meta.get("robot", "panda"))
    sq, n = np.zeros(robot.nv), 0
    for inst in dataset.split(split):
        jac = robot.tip_jacobian(inst.q)[:, :3, :]  # (T, 3, nv): the tip force's linear rows
        tau = np.einsum("tkj,tk->tj", jac, np.asarray(inst.tip_force, float))
        sq += np.sum(tau ** 2, axis=0)
        n += len(tau)
    per_joint = np.sqrt(sq / n)
    return float(np.sqrt(np.mean(per_joint ** 2))), per_joint, n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a dataset folder with tip_force (e.g. data/seed-sim-paper-...)")
    ap.add_argument("--report", default=None, help="a bench report of that dataset: its torque rows beside the floor")
    args = ap.parse_args(argv)
    ds = load_dataset(args.dataset)
    if "tip_force" not in ds.fields:
        print(f"error: {args.dataset} has no tip_force: no external torque to measure", file=sys.stderr)
        return 2
    rms, per_joint, n = external_torque_rms(ds)
    print(f"J^T F_tip on the test split ({n:,} samples): RMS {rms:.4f} Nm; per joint "
          + ", ".join(f"{v:.3f}" for v in per_joint))
    if args.report:
        rows = [r for r in read_results(f"{args.report}/results.csv")
                if r["task"] == "joint_torque" and r.get("status") == "ok"]
        for r in sorted(rows, key=lambda r: float(r["rmse"])):
            print(f"  {r['model']:30s} {float(r['rmse']):.4f} Nm  ({float(r['rmse']) / rms:.2f}x the floor; "
                  f"inputs: {r.get('inputs', '')})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
