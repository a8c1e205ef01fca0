"""A simulated 1 kHz impedance-control loop that calls the tip-force estimator every tick.

The plant is the DART Panda (Gaz friction in the joints, a noisy, biased base
force/torque sensor). A Cartesian impedance controller holds the tool at a
point while it sways slowly; from t = 3 s to 7 s someone pushes on the tool
(a bell-shaped contact force of 15 N). Each tick the controller calls
``est.estimate_tip_force(q, qd, base_wrench=...)``; the script prints the
estimate against the true force and the per-tick latency of that call.

    .venv/bin/python examples/control_loop.py                   # analytic base-wrench method
    .venv/bin/python examples/control_loop.py --method momentum # needs tau_J, given here
    .venv/bin/python examples/control_loop.py --method kalman_fusion  # base sensor and tau_J fused
    .venv/bin/python examples/control_loop.py --model runs/.../models/residual-basewrench
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

import hybrid_dyn as hd
from hybrid_dyn.estimator import METHOD_ALIASES, METHODS, TipForceEstimator
from hybrid_dyn.sim.plant import DartPlant

DT = 1e-3


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="base-wrench", choices=list(METHODS) + list(METHOD_ALIASES),
                    help=f"{', '.join(METHODS)} (older spellings accepted)")
    ap.add_argument("--model", default=None, help="a trained tip-force model directory instead of an analytic method")
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args(argv)

    robot = hd.load_robot("panda", num_threads=1)
    plant = DartPlant(robot, dt=DT)
    friction = robot.spec.friction("gaz2019")
    est = (TipForceEstimator.load(args.model, robot="panda", call_hz=1 / DT) if args.model
           else TipForceEstimator.analytic(robot, args.method, call_hz=1 / DT))
    rng = np.random.default_rng(0)
    wrench_bias = rng.normal(0, [0.5, 0.5, 0.5, 0.05, 0.05, 0.05])

    q = np.array(robot.spec.home)
    qd = np.zeros(7)
    plant.set_state(q, qd)
    model, data = robot.model, robot.model.createData()
    fid = robot.tool_frame_id
    pin.framesForwardKinematics(model, data, q)
    x0 = data.oMf[fid].translation.copy()
    K, D, D_null = 600.0, 60.0, 2.0  # N/m, N s/m, Nm s/rad

    n = int(round(args.seconds / DT))
    lat = np.empty(n)
    f_true_log, f_est_log = np.empty((n, 3)), np.empty((n, 3))
    print(f"{'t [s]':>6s} {'F_true [N]':>24s} {'F_est [N]':>24s} {'|err| [N]':>9s} {'status':>14s}")
    for k in range(n):
        t = k * DT
        # The world: a slow sway of the set point and a push on the tool from 3 s to 7 s.
        x_d = x0 + np.array([0.05 * np.sin(0.5 * t), 0.05 * np.sin(0.3 * t), 0.0])
        f_push = 15.0 * np.exp(-((t - 5.0) ** 2) / (2 * 0.6**2)) * np.array([0.0, 0.6, -0.8])
        # Impedance controller on the nominal model.
        pin.forwardKinematics(model, data, q, qd)
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        x = pin.updateFramePlacement(model, data, fid).translation
        v = J @ qd
        tau = pin.computeGeneralizedGravity(model, data, q) + J.T @ (K * (x_d - x) - D * v) - D_null * qd
        # Plant step: friction consumes part of the motor torque; the push acts at the tool.
        plant.set_state(q, qd)
        plant.apply_tip_force(f_push)
        plant.step(tau - friction(qd))
        w_meas = plant.base_wrench() + wrench_bias + rng.normal(0, [0.3, 0.3, 0.3, 0.03, 0.03, 0.03])
        tau_J = tau - friction(qd)  # what the link-side torque sensors read
        q_meas = q + rng.normal(0, 1e-5, 7)
        qd_meas = qd + rng.normal(0, 1e-3, 7)
        # The call under test.
        t0 = time.perf_counter()
        f_est = est.estimate_tip_force(q_meas, qd_meas, base_wrench=w_meas, tau_J=tau_J, t=t)
        lat[k] = (time.perf_counter() - t0) * 1e6
        f_true_log[k], f_est_log[k] = f_push, f_est
        q, qd = plant.q, plant.qd
        if k % 500 == 0:
            err = np.linalg.norm(f_est - f_push)
            print(f"{t:6.2f} {np.array2string(f_push, precision=2, suppress_small=True):>24s} "
                  f"{np.array2string(f_est, precision=2, suppress_small=True):>24s} {err:9.3f} {est.last_status.value:>14s}")

    err = np.linalg.norm(f_est_log - f_true_log, axis=1)
    contact = np.linalg.norm(f_true_log, axis=1) > 1.0
    print(f"\nestimator: {args.model or args.method}; {n} ticks at {1 / DT:.0f} Hz")
    print(f"tip-force error RMS: {np.sqrt(np.mean(err**2)):.3f} N overall, {np.sqrt(np.mean(err[contact]**2)):.3f} N in contact "
          f"(the base-wrench estimators tare the sensor's bias on the first 0.5 s, before the push)")
    print(f"latency per call [us]: median {np.median(lat):.1f}, p99 {np.percentile(lat, 99):.1f}, max {lat.max():.1f} "
          f"(budget for the whole controller at 1 kHz: 1000 us)")


if __name__ == "__main__":
    main()
