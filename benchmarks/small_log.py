"""A user's small log, built as a user brings one: a 30 s, 7-joint Panda CSV at 100 Hz (3000 samples),
imported with the toolkit's importer (``data.import_log``), for timing ``hybrid-dyn bench --data`` on it
(issue 40's floor: <= 90 s wall on 2 cores with ``--families analytic,identified``).

The log: sums of three sines per joint within the Panda's limits (periods 2-10 s), and a motor torque
of the nominal ``panda[tool=none]`` with its inertials scaled by 1.1 on the last three links' masses (a
model the nominal one does not explain), Gaz et al.'s friction and white noise of 0.05 Nm. The import
cuts it into 10 contiguous blocks, split in time order 6/2/2 as the real Panda's spec does.

    PYTHONPATH=src .venv/bin/python benchmarks/small_log.py --out /tmp/small-log
    .venv/bin/hybrid-dyn bench --data /tmp/small-log/dataset --families analytic,identified --out /tmp/r
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

NV = 7


def write_log_csv(path: Path, seconds: float = 30.0, hz: float = 100.0, seed: int = 0, noise: float = 0.05) -> Path:
    """The CSV (t, q1..7, qd1..7, tau1..7) of the docstring's log [s, rad, rad/s, Nm]."""
    from hybrid_dyn.analytic.robot import load_robot

    robot = load_robot("panda[tool=none]")
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * hz))) / hz
    lo, hi = np.maximum(robot.q_lower, -np.pi) + 0.3, np.minimum(robot.q_upper, np.pi) - 0.3
    centre, span = (lo + hi) / 2, (hi - lo) / 2
    q, qd, qdd = (np.tile(centre, (len(t), 1)), np.zeros((len(t), NV)), np.zeros((len(t), NV)))
    for _ in range(3):  # three sines per joint, amplitudes summing to at most 0.8 of the half range
        a, w = span * rng.uniform(0.1, 0.27, NV), 2 * np.pi / rng.uniform(2.0, 10.0, NV)
        p = rng.uniform(0, 2 * np.pi, NV)
        arg = w * t[:, None] + p
        q, qd, qdd = q + a * np.sin(arg), qd + a * w * np.cos(arg), qdd - a * w**2 * np.sin(arg)
    heavier = load_robot("panda[tool=none]")
    for link in range(NV - 2, NV + 1):  # the last three bodies 10 % heavier than the nominal model says
        heavier.model.inertias[link].mass *= 1.1
    tau = heavier.inverse_dynamics(q, qd, qdd) + robot.spec.friction("gaz2019")(qd)
    tau += rng.normal(0.0, noise, tau.shape)
    names = ["t"] + [f"{k}{j}" for k in ("q", "qd", "tau") for j in range(1, NV + 1)]
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, np.column_stack([t, q, qd, tau]), delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")
    return path


def import_small_log(csv: Path, out: Path):
    """The CSV imported as the real Panda's spec imports its log (Savitzky-Golay qdd, 10 blocks in time order)."""
    from hybrid_dyn.data.logs.importer import import_log

    cols = {k: [f"{c}{j}" for j in range(1, NV + 1)] for k, c in (("q", "q"), ("qd", "qd"), ("tau_m", "tau"))}
    # qdd: the importer's default derivative, Savitzky-Golay (cubic, 0.11 s), as the real Panda's spec says
    return import_log(csv, out, name="small-log", robot="panda[tool=none]", time="t", columns=cols,
                      trajectories="blocks", n_blocks=10, split_by="time", test_frac=0.2, val_frac=0.25,
                      overwrite=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for log.csv and dataset/")
    ap.add_argument("--seconds", type=float, default=30.0)
    args = ap.parse_args(argv)
    csv = write_log_csv(args.out / "log.csv", args.seconds)
    report = import_small_log(csv, args.out / "dataset")
    print(f"wrote {csv} and the dataset {report.path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
