"""What the start-up window's joint-torque check costs on a model that lacks the tool (mismatch-ext).

mismatch-ext's plant carries a 0.5 kg tool and other inertials than the model: kalman-fusion's joint
torques read that model error as a force at the tool, so its window check refuses the start-up windows
(a contact, or a load the model lacks) until a pose where the error happens to fall under
``tare_contact_force``. Until then the estimator gives no estimate ("contact at start-up"; the bench's
batch run scores 0 there). This prints kalman-fusion's test RMSE with the check (the default, 1 N) and
without it (the bar at 1e9 N, the behaviour before issue 38), and where each run's window landed.

Run: .venv/bin/python benchmarks/window_check_mismatch.py [--data DIR] [--size quick]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.analytic.batch_run import run_batch
from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import scenario_config


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path("data/window-check-mismatch-ext"))
    ap.add_argument("--size", default="quick")
    args = ap.parse_args(argv)
    try:
        ds = load_dataset(args.data)
    except Exception:  # not generated yet (or not complete): generate it (resumable)
        ds = load_dataset(generate_dataset(scenario_config("mismatch-ext", args.size), args.data, progress=False))
    robot = hd.load_robot(ds.meta["config"]["robot"], num_threads=1)
    hz = ds.meta["record_hz"]
    for label, limit in (("with the window check (1 N)", 1.0), ("without it (1e9 N)", 1e9)):
        sq, starts = [], []
        for inst in ds.split("test"):
            f, used = run_batch("kalman-fusion", robot, hz, inst.q, inst.qd, inst.base_wrench, inst.tau_J,
                                encoder_resolution=0.0, tare_contact_force=limit)
            sq.append(np.sum((f[50:] - inst["tip_force"][50:]) ** 2, axis=1))
            starts.append(int(np.flatnonzero(np.any(f != 0, axis=1))[0]) / hz if np.any(f != 0) else float("nan"))
        print(f"kalman-fusion on mismatch-ext ({args.size}), {label}: test RMSE "
              f"{np.sqrt(np.mean(np.concatenate(sq))):.4f} N; first estimate at {starts} s")


if __name__ == "__main__":
    main()
