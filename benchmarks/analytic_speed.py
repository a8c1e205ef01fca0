"""Per-sample cost of the analytic layer (issue 2).

Prints medians over repeated runs, measured in this one process (``hybrid_dyn.timing.per_item_us``):
  inverse_dynamics   single call, and batched at N=100k (rneaInParallel, all threads and 1 thread)
  base_wrench        single call and batched
  tip_force_from_base_wrench  single call
  tip_force_from_torques      single call
  MomentumObserver.step_force one step
Floors (issue 2): batched inverse dynamics <= 3 us/sample; single tip_force_from_base_wrench <= 30 us.

Run: .venv/bin/python benchmarks/analytic_speed.py
"""
import numpy as np

import hybrid_dyn as hd
from hybrid_dyn.analytic.momentum_observer import MomentumObserver
from hybrid_dyn.analytic.tip_force import tip_force_from_base_wrench, tip_force_from_torques
from hybrid_dyn.timing import per_item_us


def main() -> None:
    robot = hd.load_robot("panda")
    rng = np.random.default_rng(0)
    n = 100_000
    q = rng.uniform(robot.q_lower, robot.q_upper, (n, 7))
    qd, qdd = rng.normal(size=(n, 7)), rng.normal(size=(n, 7))
    w = robot.base_wrench(q[:1], qd[:1], qdd[:1])[0]
    tau = robot.inverse_dynamics(q[:1], qd[:1], qdd[:1])[0]
    q1, qd1, qdd1 = q[0], qd[0], qdd[0]
    single_robot = hd.load_robot("panda", num_threads=1)
    obs = MomentumObserver(robot, gain=50.0, dt=1e-3)
    obs.step(q1, qd1, tau)

    rows = [
        ("inverse_dynamics, single call", per_item_us(lambda: robot.inverse_dynamics(q1, qd1, qdd1))),
        (f"inverse_dynamics, batched N={n}, {robot.num_threads} threads",
         per_item_us(lambda: robot.inverse_dynamics(q, qd, qdd), per=n, repeat=5, number=1)),
        (f"inverse_dynamics, batched N={n}, 1 thread",
         per_item_us(lambda: single_robot.inverse_dynamics(q, qd, qdd), per=n, repeat=5, number=1)),
        ("base_wrench, single call", per_item_us(lambda: robot.base_wrench(q1, qd1, qdd1))),
        (f"base_wrench, batched N={n}, {robot.num_threads} threads",
         per_item_us(lambda: robot.base_wrench(q, qd, qdd), per=n, repeat=5, number=1)),
        ("tip_force_from_base_wrench, single call", per_item_us(lambda: tip_force_from_base_wrench(robot, q1, qd1, qdd1, w))),
        ("tip_force_from_torques, single call", per_item_us(lambda: tip_force_from_torques(robot, q1, qd1, qdd1, tau))),
        ("MomentumObserver.step_force, one step", per_item_us(lambda: obs.step_force(q1, qd1, tau))),
    ]
    print(f"{'operation':55s} {'median us/sample':>16s}")
    for name, us in rows:
        print(f"{name:55s} {us:16.2f}")
    print(f"floor: batched inverse_dynamics <= 3 us/sample -> {'met' if rows[1][1] <= 3 else 'NOT met'}")
    print(f"floor: single tip_force_from_base_wrench <= 30 us -> {'met' if rows[5][1] <= 30 else 'NOT met'}")


if __name__ == "__main__":
    main()
