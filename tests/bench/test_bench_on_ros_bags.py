"""``hybrid-dyn bench --data`` on ROS bags: a ROS 2 MCAP bag and a ROS 1 ``.bag`` with
/joint_states and /ft_base at 1 kHz import with a ``[ros]`` spec and bench like any log.

References: the bags hold the exact rigid-body torques and base wrench of a Panda motion with a known
1-5 N tip force (plus 0.1 N of base-sensor noise), so the URDF's rows are known in advance: the RNEA row
(which knows no force) errs by exactly J^T F on the test block, computed here with Pinocchio; the
base-wrench row recovers the force to the sensor noise. A joint mismatched, a wrench misaligned in time or
a unit lost would show as newtons and newton-metres.
"""
import csv
import json

import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main

from helpers.ros_bags import panda_signals, ros_spec, write_bag


@pytest.mark.slow  # two bags imported and benched with the analytic rows: ~10 s
@pytest.mark.parametrize("kind", ["mcap", "ros1"])
def test_a_ros_bag_imports_and_benches_like_any_log(kind, panda, tmp_path, capsys):
    t = np.arange(4000) / 1000.0  # 4 s at 1 kHz: 5 blocks of 0.8 s
    force = (3.0 + 2.0 * np.sin(2 * np.pi * 0.3 * t))[:, None] * np.array([0.6, 0.0, -0.8])  # N, 1-5 N
    sig = panda_signals(panda, n=len(t), hz=1000.0, force=force, base_noise=0.1, seed=5)
    bag = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), sig, kind=kind)
    # The effort as both torques: the joint-torque rows' target and the torque sensors the observers read.
    spec = ros_spec(tmp_path / "spec", bag, name=f"bag-{kind}", blocks=5, extra='effort = ["tau_m", "tau_J"]\n')
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    out = tmp_path / "report"
    assert cli_main(["bench", "--data", str(tmp_path / "ds"), "--out", str(out), "--families", "analytic",
                     "--data-root", str(tmp_path / "data"), "--work-root", str(tmp_path / "runs")]) == 0
    rows = {(r["task"], r["model"]): r for r in csv.DictReader((out / "results.csv").open())}
    assert all(r["status"] == "ok" for r in rows.values()), {k: r["error"] for k, r in rows.items() if r["error"]}
    assert {r["scenario"] for r in rows.values()} == {f"bag-{kind}"}
    # Both tasks ran: the bag gave joint torques (as tau_m and tau_J), a base wrench and a tip force.
    assert {("joint_torque", "rnea"), ("tip_force", "base-wrench"), ("tip_force", "base-momentum"),
            ("tip_force", "momentum-observer"), ("tip_force", "kalman-fusion")} <= set(rows)
    # The URDF's rows against the bag's own physics: torques with the contact's J^T F in them, which RNEA
    # (no force) misses by about J^T F; the base-wrench method recovers the force to the sensor noise.
    assert float(rows["tip_force", "base-wrench"]["rmse"]) < 0.2  # N: 0.1 N of base noise, 1-5 N of force
    test = slice(3200, 4000)  # the last of 5 blocks: the test split in time order
    jtf = np.einsum("nij,ni->nj", panda.tip_jacobian(sig["q"][test])[:, :3], force[test])
    assert float(rows["joint_torque", "rnea"]["rmse"]) == pytest.approx(np.sqrt(np.mean(jtf**2)), rel=0.01)
    meta = json.loads((out / "run.json").read_text())
    assert meta["datasets"][f"bag-{kind}"]["robot"] == "panda"
    assert "time order" in (out / "README.md").read_text()
