"""Tip-force estimators on a held-out-like 1 kHz control stream (issue 27's floors), with their defaults.

Not the issue owner's held-out stream (that one is not in the repository), but one built to its
description: the DART Panda (Gaz friction in the joints) under joint PD control (gravity
compensated) that switches its set point between two poses every 2.5 s; pushes on the tool of
3-25 N, steps (1 ms rise) and trapezoids (1-20 ms rises), held 0.3-1.5 s, 1-3 s apart from t = 1 s
(``sim.pulses.sample_contact_steps``; the set point moves through a 0.2 s first-order filter); base sensor noise 0.05 N per force axis (0.0025 Nm per
moment axis) with a per-stream offset of up to 2 N; no tau_J. Every method that reads only q, qd
and the base sensor runs with ``TipForceEstimator.analytic(robot, method)`` defaults, fed each
tick with t; RMSE [N] (3-D error, all samples) after the 0.5 s noise window. Encoder noise:
``--qd-noise`` [rad/s] (q gets qd-noise / 25 rad): 0 by default, as the issue's numbers imply
(with the generator's 5e-4 rad/s the base-wrench row there could not reach 0.28 N).

Floors (issue 27): the README's recommended method <= 0.30 N; every base-sensor-only method <= 0.35 N.

An acceptance check (``checks/``), not a benchmark of speed: it prints each floor as met or NOT met.

Run: .venv/bin/python checks/tip_force_stream.py [--streams 3] [--seconds 12] [--qd-noise 0]
"""
from __future__ import annotations

import argparse

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.estimator import TipForceEstimator
from hybrid_dyn.sim.plant import DartPlant
from hybrid_dyn.sim.pulses import sample_contact_steps
from hybrid_dyn.sim.scenarios import ContactStepConfig

DT = 1e-3
BASE_ONLY = ("base-wrench", "base-momentum", "kalman-fusion")  # the methods that run on q, qd and the base sensor
RECOMMENDED = "base-momentum"  # the README's recommendation
FLOORS = {"recommended": 0.30, "base-only": 0.35}


def simulate(robot, seconds: float, seed: int, base_noise: float, qd_noise: float):
    """One stream: (t, q, qd, base wrench, true tip force), all (n, ...), as measured."""
    rng = np.random.default_rng(seed)
    plant = DartPlant(robot, dt=DT)
    friction = robot.spec.friction("gaz2019")
    n = int(round(seconds / DT))
    t = np.arange(n) * DT
    contacts = sample_contact_steps(rng, ContactStepConfig(), DT)
    force = contacts.force(t)
    home = np.array(robot.spec.home)
    poses = [home, np.clip(home + rng.uniform(-0.4, 0.4, robot.nv), robot.q_lower + 0.1, robot.q_upper - 0.1)]
    Kp, Kd = np.array([400, 400, 400, 400, 60, 40, 15.0]), np.array([40, 40, 40, 40, 5, 3, 1.0])
    bias = rng.uniform(-1, 1, 6) * np.r_[np.full(3, 2.0), np.full(3, 0.1)]
    q, qd = home.copy(), np.zeros(robot.nv)
    plant.set_state(q, qd)
    data = robot.model.createData()
    import pinocchio as pin

    out_q, out_qd, out_w = np.empty((n, robot.nv)), np.empty((n, robot.nv)), np.empty((n, 6))
    ref = home.copy()
    for k in range(n):
        # The set point moves to the other pose every 2.5 s through a 0.2 s first-order filter.
        ref += (poses[int(t[k] // 2.5) % 2] - ref) * (DT / 0.2)
        tau = pin.computeGeneralizedGravity(robot.model, data, q) + Kp * (ref - q) - Kd * qd
        plant.set_state(q, qd)
        plant.apply_tip_force(force[k])
        plant.step(tau - friction(qd))
        out_w[k] = plant.base_wrench() + bias + rng.normal(0, base_noise, 6) * np.r_[np.ones(3), np.full(3, 0.05)]
        out_q[k] = q + rng.normal(0, qd_noise / 25.0, robot.nv)
        out_qd[k] = qd + rng.normal(0, qd_noise, robot.nv)
        q, qd = plant.q, plant.qd
    return t, out_q, out_qd, out_w, force


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--streams", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=12.0)
    ap.add_argument("--base-noise", type=float, default=0.05, help="base sensor noise per force axis [N]")
    ap.add_argument("--qd-noise", type=float, default=0.0, help="encoder velocity noise [rad/s]")
    args = ap.parse_args(argv)
    robot = hd.load_robot("panda", num_threads=1)
    sq = {m: [] for m in BASE_ONLY}
    bands = {m: [] for m in BASE_ONLY}
    for seed in range(args.streams):
        t, q, qd, w, force = simulate(robot, args.seconds, 100 + seed, args.base_noise, args.qd_noise)
        for m in BASE_ONLY:
            est = TipForceEstimator.analytic(robot, m, call_hz=1 / DT)
            f = np.stack([est.estimate_tip_force(q[k], qd[k], base_wrench=w[k], t=t[k]) for k in range(len(t))])
            n0 = int(round(0.5 / DT))
            err = np.sum((f[n0:] - force[n0:]) ** 2, axis=1)
            sq[m].append(err)
            bands[m].append(est.bandwidth)
            print(f"stream {seed}: {m:15s} RMSE {np.sqrt(err.mean()):.3f} N  ({est.spec.parameter} "
                  f"{est.bandwidth:.4g} {est.spec.unit})", flush=True)
    print(f"\n{args.streams} streams x {args.seconds:g} s at 1 kHz, base noise {args.base_noise:g} N/axis, "
          f"qd noise {args.qd_noise:g} rad/s, no tau_J; RMSE after the 0.5 s window, defaults")
    for m in BASE_ONLY:
        rmse = float(np.sqrt(np.mean(np.concatenate(sq[m]))))
        floor = FLOORS["recommended"] if m == RECOMMENDED else FLOORS["base-only"]
        verdict = "met" if rmse <= floor else "NOT met"
        print(f"{m:15s} RMSE {rmse:.3f} N   floor <= {floor:.2f} N{' (recommended)' if m == RECOMMENDED else ''}: "
              f"{verdict}")


if __name__ == "__main__":
    main()
