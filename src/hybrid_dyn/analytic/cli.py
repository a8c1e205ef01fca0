"""CLI: robot information and the analytic demo."""
from __future__ import annotations

import numpy as np


def register(sub) -> None:
    p = sub.add_parser("robots")
    p.set_defaults(func=cmd_robots)
    p = sub.add_parser("analytic-demo")
    p.set_defaults(func=cmd_demo)


def cmd_robots(args) -> int:
    from ..description import ROBOTS, load_spec
    from .robot import load_robot

    for name in sorted(robot.name for robot in ROBOTS.where(data_only=False)):
        spec = load_spec(name)
        robot = load_robot(name)
        print(f"{name:8s} nv={robot.nv} mass={robot.total_mass:.3f} kg tool={spec.tool_frame} "
              f"sensor={spec.base_sensor_frame} params={sorted(spec.param_sets) or '-'}")
    return 0


def cmd_demo(args) -> int:
    """Analytic tip-force baselines on a small synthetic set with sensor noise."""
    import tempfile

    from ..data import load_dataset
    from ..data.synthetic import make_synthetic_dataset
    from .robot import load_robot
    from .tip_force import tip_force_from_base_wrench, tip_force_from_torques

    robot = load_robot("panda")
    with tempfile.TemporaryDirectory() as tmp:
        ds = load_dataset(make_synthetic_dataset(f"{tmp}/demo", robot, n_instances=5, n_samples=500, noise=0.01))
        for method, fn in (("torques-pinv", lambda i: tip_force_from_torques(robot, i.q, i.qd, i.qdd, i.tau_J)),
                           ("base-wrench", lambda i: tip_force_from_base_wrench(robot, i.q, i.qd, i.qdd, i.base_wrench))):
            err = np.concatenate([fn(i) - i.truth["tip_force"] for i in ds.split("test")])
            print(f"{method:14s} tip-force RMSE {np.sqrt(np.mean(err**2)):.4f} N (synthetic, 0.01 noise)")
    return 0
