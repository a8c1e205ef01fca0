"""Robot descriptions, parameter sets, payloads, and the errors users see."""
import json
import warnings

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.robot import InputError, JointLimitWarning
from hybrid_dyn.description import RobotDescriptionError, robots_dir


def test_shipped_robots_load_with_their_joint_counts():
    assert hd.load_robot("panda").nv == 7
    assert hd.load_robot("ur5").nv == 6
    assert hd.load_robot("xarm7").nv == 7


def test_a_declared_robot_has_its_urdfs_moving_joints_and_a_home_inside_its_limits(described_robot):
    """Every robot of robots/: nv is the URDF's moving joints less the locked ones (read from the file
    itself), and the home pose and the motion limits give one value per joint, home inside the limits."""
    import xml.etree.ElementTree as ET

    robot = described_robot
    root = ET.parse(robot.spec.urdf_path).getroot()
    moving = {j.get("name") for j in root.iter("joint") if j.get("type") != "fixed"}
    assert robot.nv == len(moving - set(robot.spec.locked_joints))
    assert len(robot.spec.home) == robot.nv
    assert np.all(robot.q_lower <= robot.spec.home) and np.all(np.array(robot.spec.home) <= robot.q_upper)
    for limits in (robot.spec.max_velocity, robot.spec.max_acceleration, robot.spec.max_jerk):
        assert len(limits) in (0, robot.nv) and all(v > 0 for v in limits)


def test_panda_mass_matches_the_param_files():
    """Total mass = link 0 + hand + fingers (URDF) + links 1-7 (the JSON), read independently."""
    extra = 0.629769 + 0.73 + 2 * 0.015
    for params in ("gaz2019", "franka_official"):
        doc = json.loads((robots_dir() / f"params/panda_{'gaz2019_params' if params == 'gaz2019' else 'franka_official_inertials'}.json").read_text())
        arm = sum(ln["mass"] for ln in doc["links"] if ln["name"].startswith("panda_link"))
        hand_set = {ln["name"]: ln["mass"] for ln in doc["links"]}
        expected = arm + hand_set.get("panda_hand", 0.73) + hand_set.get("panda_leftfinger", 0.015) * 2 + 0.629769
        assert hd.load_robot("panda", params=params).total_mass == pytest.approx(expected, abs=1e-9)
    assert hd.load_robot("panda").total_mass == pytest.approx(16.062 + extra, abs=2e-3)


def test_payload_is_a_point_mass_at_the_tool(panda):
    """Static torque change = J_v(payload point)^T (m g): an independent Jacobian identity."""
    m, offset = 0.5, np.array([0.0, 0.0, 0.05])
    loaded = hd.load_robot("panda", payload=(m, offset))
    q = np.array(panda.spec.home)
    z = np.zeros(7)
    dtau = loaded.gravity(q) - panda.gravity(q)
    # Jacobian of the payload point = tool Jacobian shifted by the lever arm.
    import pinocchio as pin
    data = panda.model.createData()
    pin.framesForwardKinematics(panda.model, data, q)
    R = data.oMf[panda.tool_frame_id].rotation
    J = panda.tip_jacobian(q)
    Jp = J[:3] - pin.skew(R @ offset) @ J[3:]
    np.testing.assert_allclose(dtau, Jp.T @ np.array([0, 0, m * 9.81]), atol=1e-10)
    assert loaded.base_wrench(q, z, z)[2] == pytest.approx((panda.total_mass + m) * 9.81)


def test_unknown_robot_names_the_choices():
    with pytest.raises(RobotDescriptionError, match="unknown robot 'pandaa'.*panda"):
        hd.load_robot("pandaa")


def test_unknown_param_set():
    with pytest.raises(RobotDescriptionError, match="no parameter set 'gaz2020'"):
        hd.load_robot("panda", params="gaz2020")


def test_param_file_for_another_robot(tmp_path):
    bad = tmp_path / "ur5_params.json"
    bad.write_text(json.dumps({"links": [{"name": "shoulder_link", "mass": 3.7, "com": [0, 0, 0], "inertia": [0.01, 0, 0, 0.01, 0, 0.01]}]}))
    with pytest.raises(RobotDescriptionError, match="shoulder_link.*another robot"):
        hd.load_robot("panda", params=bad)


@pytest.mark.parametrize("content, message", [
    ("{not json", "not valid JSON"),
    ('{"links": []}', "no 'links'"),
    ('{"links": [{"name": "panda_link1", "mass": -1, "com": [0,0,0], "inertia": [1,0,0,1,0,1]}]}', "mass must be positive"),
    ('{"links": [{"name": "panda_link1", "mass": 1}]}', "needs name, mass"),
])
def test_malformed_param_files(tmp_path, content, message):
    f = tmp_path / "p.json"
    f.write_text(content)
    with pytest.raises(RobotDescriptionError, match=message):
        hd.load_robot("panda", params=f)


def test_missing_frame(tmp_path):
    toml = (robots_dir() / "panda.toml").read_text().replace('tool_frame = "panda_hand_tcp"', 'tool_frame = "panda_gripper_tip"')
    (tmp_path / "panda_bad.toml").write_text(toml.replace("params/", str(robots_dir() / "params") + "/"))
    with pytest.raises(RobotDescriptionError, match="panda_gripper_tip"):
        hd.load_robot(tmp_path / "panda_bad.toml")


@pytest.mark.parametrize("bad, message", [
    (np.full(7, np.nan), "q holds NaN"),
    (np.zeros(6), r"q must have shape \(N, 7\)"),
    (np.zeros((3, 8)), r"q must have shape \(N, 7\)"),
    (np.full((2, 7), np.inf), "q holds NaN or inf"),
])
def test_bad_q_raises_input_error_naming_the_problem(panda, bad, message):
    with pytest.raises(InputError, match=message):
        panda.inverse_dynamics(bad, np.zeros_like(bad), np.zeros_like(bad))
    assert issubclass(InputError, ValueError)


def test_mismatched_lengths(panda):
    with pytest.raises(InputError, match="different lengths"):
        q = np.tile(panda.spec.home, (3, 1))
        panda.inverse_dynamics(q, np.zeros((2, 7)), q)


def test_q_outside_limits_warns_but_computes(panda):
    q = np.array(panda.spec.home)
    q[3] = 0.5  # joint 4's upper limit is -0.0698
    with pytest.warns(JointLimitWarning, match="panda_joint4"):
        tau = panda.gravity(q)
    assert np.isfinite(tau).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        panda.gravity(np.array(panda.spec.home))  # inside: silent


def test_the_parallel_rnea_leaves_torchs_thread_count_as_it_found_it():
    """Pinocchio's rneaInParallel sets OpenMP's thread count for the process, and torch's count is OpenMP's:
    a batch of analytic torques must not leave a one-thread trainer on the RNEA pool's threads. The batch
    itself still equals Pinocchio's per-sample RNEA."""
    import pinocchio as pin
    import torch

    robot = hd.load_robot("panda", num_threads=2)
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-1, 1, (200, robot.nv)) for _ in range(3))
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        tau = robot.inverse_dynamics(q, qd, qdd)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)
    ref = np.stack([pin.rnea(robot.model, robot.data, q[i], qd[i], qdd[i]) for i in range(len(q))])
    np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-9)


def test_auto_encoder_resolution_is_the_descriptions_number():
    """"auto" is what the robot's TOML states (read here from the file's text), a number is itself, on every
    shipped description that states one."""
    import tomllib

    from hybrid_dyn.description import load_spec, resolve_encoder_resolution, robots_dir

    stated = {p.stem: tomllib.loads(p.read_text())["encoder_resolution"] for p in sorted(robots_dir().glob("*.toml"))
              if "encoder_resolution" in tomllib.loads(p.read_text())}
    assert stated["panda"] == 1e-5 and len(stated) >= 2
    for name, value in stated.items():
        spec = load_spec(name)
        assert resolve_encoder_resolution("auto", spec) == value
        assert resolve_encoder_resolution(0.0, spec) == 0.0 and resolve_encoder_resolution(3e-4, spec) == 3e-4
