"""A simulated 1 kHz control loop that calls the tip-force estimator every tick.

The stream comes from the project's one stream simulator (``sim.stream.simulate_stream``): the DART
Panda (Gaz friction in the joints) under joint PD control with gravity compensation, moving between
two poses every 2.5 s, read through hardware sensors (``sim.sensors.HardwareSensors`` defaults: q
quantized to the Panda's 1e-5 rad encoder resolution, qd the drive's difference of it, link-side
joint torques with 0.05 Nm noise, a base F/T sensor with 0.2 N / 0.01 Nm noise and an offset of up
to 2 N). From t = 3 s someone pushes on the tool: 15 N, ramping up over 1 s, held 2 s, ramping down
over 1 s. Each tick the loop calls ``est.estimate_tip_force(q, qd, base_wrench=..., tau_J=..., t=...)``
with what the sensors read; the script prints the estimate against the true force and the per-tick
latency of that call. (The run is simulated first and then replayed tick by tick: the estimate does
not feed back into the controller, so the calls see exactly what they would inside the loop.)

    .venv/bin/python examples/control_loop.py                              # momentum-observer (the default)
    .venv/bin/python examples/control_loop.py --method base-momentum       # the base sensor only
    .venv/bin/python examples/control_loop.py --method kalman-fusion       # base sensor and joint torques fused
    .venv/bin/python examples/control_loop.py --model runs/.../models/residual-basewrench
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.analytic.methods import DEFAULT_METHOD, TIP_FORCE_METHODS
from hybrid_dyn.estimator import TipForceEstimator
from hybrid_dyn.sim.stream import StreamConfig, Touch, simulate_stream

DT = 1e-3
PUSH = Touch(start=3.0, amplitude=15.0, plateau=2.0, rise=1.0, direction=(0.0, 0.6, -0.8))  # N, s


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default=DEFAULT_METHOD, choices=list(TIP_FORCE_METHODS), help=", ".join(TIP_FORCE_METHODS))
    ap.add_argument("--model", default=None, help="a trained tip-force model directory instead of an analytic method")
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args(argv)

    robot = hd.load_robot("panda", num_threads=1)
    stream = simulate_stream(robot, StreamConfig(seconds=args.seconds, dt=DT, contacts=None, touches=(PUSH,)), seed=0)
    r = stream.readings
    # The estimator is told the encoders' resolution, so its joint-state filter makes q and qd from them.
    est = (TipForceEstimator.load(args.model, robot="panda", call_hz=1 / DT) if args.model
           else TipForceEstimator.analytic(robot, args.method, call_hz=1 / DT,
                                           encoder_resolution=stream.encoder_resolution))

    n = len(r.t)
    lat = np.empty(n)
    f_est_log = np.empty((n, 3))
    print(f"{'t [s]':>6s} {'F_true [N]':>24s} {'F_est [N]':>24s} {'|err| [N]':>9s} {'status':>14s}")
    for k in range(n):
        # The call under test, on what the sensors read at this tick.
        t0 = time.perf_counter()
        f_est = est.estimate_tip_force(r.q[k], r.qd[k], base_wrench=r.base_wrench[k], tau_J=r.tau_J[k], t=r.t[k])
        lat[k] = (time.perf_counter() - t0) * 1e6
        f_est_log[k] = f_est
        if k % 500 == 0:
            f_true = stream.tip_force[k]
            print(f"{stream.t[k]:6.2f} {np.array2string(f_true, precision=2, suppress_small=True):>24s} "
                  f"{np.array2string(f_est, precision=2, suppress_small=True):>24s} "
                  f"{np.linalg.norm(f_est - f_true):9.3f} {est.last_status.value:>14s}")

    err = np.linalg.norm(f_est_log - stream.tip_force, axis=1)
    contact = np.linalg.norm(stream.tip_force, axis=1) > 1.0
    print(f"\nestimator: {args.model or args.method}; {n} ticks at {1 / DT:.0f} Hz")
    print(f"tip-force error RMS: {np.sqrt(np.mean(err**2)):.3f} N overall, {np.sqrt(np.mean(err[contact]**2)):.3f} N in contact "
          f"(the base-wrench estimators tare the sensor's bias on the first 0.5 s, before the push)")
    print(f"latency per call [us]: median {np.median(lat):.1f}, p99 {np.percentile(lat, 99):.1f}, max {lat.max():.1f} "
          f"(budget for the whole controller at 1 kHz: 1000 us)")


if __name__ == "__main__":
    main()
