"""Robot variants (a tool taken off or mounted, a payload) and robot names.

References are independent of build_urdf: URDF XML edited here by hand and built
straight with Pinocchio, masses summed from the XML, a pendulum's gravity torque.
"""
import hashlib
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

import hybrid_dyn as hd
from hybrid_dyn.description import RobotDescriptionError, example_robot_data_dir, resolve_robot

G = 9.81  # Pinocchio's default gravity [m/s^2]
HAND = {"panda_hand", "panda_hand_tcp", "panda_leftfinger", "panda_rightfinger"}
# sha256 of load_robot("panda").urdf_xml as built before variants existed (commit 2b88fae);
# a running benchmark and every cached model depend on it staying byte-for-byte the same.
PANDA_URDF_SHA256 = "7f1bce1cfbacfabe3d661274a9b0a4ee237614e18babff9f44ef37e341ed3ce8"


def _erd_xml(rel: str) -> ET.Element:
    return ET.parse(example_robot_data_dir() / rel).getroot()


def _panda_without_hand() -> ET.Element:
    """example-robot-data's panda.urdf with the hand's links and the joints to them deleted."""
    root = _erd_xml("panda_description/urdf/panda.urdf")
    for el in list(root):
        if (el.tag == "link" and el.get("name") in HAND) or (el.tag == "joint" and el.find("child").get("link") in HAND):
            root.remove(el)
    return root


def _random_q(robot, n, seed):
    return np.random.default_rng(seed).uniform(np.maximum(robot.q_lower, -np.pi), np.minimum(robot.q_upper, np.pi),
                                               (n, robot.nv))


def test_default_panda_is_byte_for_byte_unchanged():
    robot = hd.load_robot("panda")
    assert hashlib.sha256(robot.urdf_xml.encode()).hexdigest() == PANDA_URDF_SHA256
    assert robot.name == "panda" and robot.spec.tool_frame == "panda_hand_tcp"
    # Naming the URDF's own tool is the default robot, under the default name.
    assert hd.load_robot("panda", tool="hand").urdf_xml == robot.urdf_xml
    assert resolve_robot("panda[tool=hand]").name == "panda"


def test_bare_flange_mass_matrix_equals_the_hand_removed_urdf():
    robot = hd.load_robot("panda", tool="none")
    ref = pin.buildModelFromXML(ET.tostring(_panda_without_hand(), encoding="unicode"))
    data = ref.createData()
    q = _random_q(robot, 10, seed=3)
    for qi, Mi in zip(q, robot.mass_matrix(q)):
        M = pin.crba(ref, data, qi)
        np.testing.assert_allclose(Mi, np.triu(M) + np.triu(M, 1).T, rtol=0, atol=1e-12)


def test_bare_flange_tool_frame_and_weight_at_rest():
    robot = hd.load_robot("panda[tool=none]")
    assert robot.spec.tool_frame == "panda_link8" and robot.model.frames[robot.tool_frame_id].name == "panda_link8"
    root = _panda_without_hand()
    mass = sum(float(m.get("value")) for m in root.iter("mass"))  # every link of the URDF but the hand's
    assert mass == pytest.approx(16.691901, abs=1e-9) and robot.total_mass == pytest.approx(mass, abs=1e-12)
    ref = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
    data = ref.createData()
    q, z = np.array(robot.spec.home), np.zeros(7)
    w = robot.base_wrench(q, z, z)
    # At rest the ground carries the weight, and its moment about the sensor origin is c x (m g);
    # Pinocchio's centerOfMass leaves out link 0 (the universe's body), so it is added here.
    c_moving = pin.centerOfMass(ref, data, q).copy()
    com = (data.mass[0] * c_moving + ref.inertias[0].mass * ref.inertias[0].lever) / mass
    np.testing.assert_allclose(w[:3], [0.0, 0.0, mass * G], atol=1e-9)
    np.testing.assert_allclose(w[3:], np.cross(com, [0.0, 0.0, mass * G]), atol=1e-9)
    pin.framesForwardKinematics(ref, data, q)
    np.testing.assert_allclose(robot.tip_position(q), data.oMf[ref.getFrameId("panda_link8")].translation, atol=1e-12)


def test_ur10_from_example_robot_data_loads_by_name():
    robot = hd.load_robot("ur10")
    assert robot.name == "ur10" and robot.nv == 6 and robot.spec.tool_frame == "tool0"
    ref = pin.buildModelFromXML((example_robot_data_dir() / "ur_description/urdf/ur10_robot.urdf").read_text())
    data = ref.createData()
    rng = np.random.default_rng(5)
    q, qd, qdd = _random_q(robot, 8, 5), rng.normal(0, 1, (8, 6)), rng.normal(0, 3, (8, 6))
    expect = np.stack([pin.rnea(ref, data, q[i], qd[i], qdd[i]) for i in range(8)])
    np.testing.assert_allclose(robot.inverse_dynamics(q, qd, qdd), expect, rtol=0, atol=1e-9)
    assert resolve_robot("ur10_robot").name == "ur10"  # one name per arm


PENDULUM = """<robot name="pendulum">
  <link name="base"><inertial><mass value="2.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="arm"><inertial><origin xyz="{L} 0 0"/><mass value="{m}"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="50" velocity="2"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="arm"/><child link="tip"/><origin xyz="{tip} 0 0"/></joint>
</robot>"""


def test_a_user_urdf_path_loads(tmp_path):
    m, L = 1.5, 0.3
    path = tmp_path / "pendulum.urdf"
    path.write_text(PENDULUM.format(m=m, L=L, tip=2 * L))
    robot = hd.load_robot(str(path))
    assert robot.name == str(path.resolve()) and robot.nv == 1
    assert robot.spec.tool_frame == "tip" and robot.spec.base_sensor_frame == "base"
    # A point mass m at L on a joint about y: V = -m g L sin q, so g(q) = dV/dq = -m g L cos q.
    q = np.linspace(-1.0, 1.0, 5)[:, None]
    np.testing.assert_allclose(robot.gravity(q)[:, 0], -m * G * L * np.cos(q[:, 0]), atol=1e-12)
    np.testing.assert_allclose(robot.tip_position(np.zeros(1)), [2 * L, 0, 0], atol=1e-12)
    assert robot.base_wrench(np.zeros(1), np.zeros(1), np.zeros(1))[2] == pytest.approx((2.0 + m) * G)


def test_a_tool_urdf_mounts_on_the_flange(tmp_path):
    """A point-mass tool equals a payload at its centre of mass on the bare flange."""
    tool = tmp_path / "gripper.urdf"
    tool.write_text("""<robot name="gripper">
  <link name="g_body"><inertial><origin xyz="0 0 0.04"/><mass value="0.4"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="g_tcp"/>
  <joint name="g_tcp_joint" type="fixed"><parent link="g_body"/><child link="g_tcp"/><origin xyz="0 0 0.1"/></joint>
</robot>""")
    robot = hd.load_robot("panda", tool=tool)
    assert robot.name == f"panda[tool={tool.resolve()}]" and robot.spec.tool_frame == "g_tcp"
    same = hd.load_robot("panda[tool=none]", payload=(0.4, (0.0, 0.0, 0.04)))
    assert same.name == "panda[tool=none;payload=0.4@0.0,0.0,0.04]"
    assert robot.total_mass == pytest.approx(same.total_mass, abs=1e-12)
    q = _random_q(robot, 4, seed=8)
    np.testing.assert_allclose(robot.mass_matrix(q), same.mass_matrix(q), atol=1e-12)
    flange = hd.load_robot("panda[tool=none]")
    for qi in q:  # the tool point sits 0.1 m out along the flange's z axis (0.04 is the mass centre)
        pin.framesForwardKinematics(flange.model, flange.data, qi)
        M = flange.data.oMf[flange.tool_frame_id]
        np.testing.assert_allclose(robot.tip_position(qi), M.translation + M.rotation @ [0, 0, 0.1], atol=1e-12)


def test_the_variant_is_part_of_the_name_and_given_once():
    assert hd.load_robot("panda", tool="none").name == "panda[tool=none]"
    assert resolve_robot("panda", tool="none", payload={"mass": 0.5, "offset": [0, 0, 0.1]}).name == \
        resolve_robot("panda[tool=none;payload=0.5@0,0,0.1]").name == "panda[tool=none;payload=0.5@0.0,0.0,0.1]"
    assert resolve_robot("ur5[tool=none]").name == "ur5"  # the UR5's URDF ends at the flange already
    with pytest.raises(RobotDescriptionError, match="names tool 'none'"):
        resolve_robot("panda[tool=none]", tool="hand")
    with pytest.raises(RobotDescriptionError, match="no tool 'gripper'"):
        resolve_robot("panda", tool="gripper")
    with pytest.raises(RobotDescriptionError, match="unknown option"):
        resolve_robot("panda[tol=none]")


def test_data_only_names_resolve_without_a_model():
    for name in ("sarcos", "unknown"):
        assert not resolve_robot(name).described
    with pytest.raises(RobotDescriptionError, match="known for data only"):
        hd.load_robot("sarcos")


def test_an_unknown_name_is_refused_before_any_data_is_read(tmp_path):
    with pytest.raises(RobotDescriptionError) as err:
        hd.load_robot("ur11")
    msg = str(err.value)
    for accepted in ("'ur11'", "panda", "ur10", "kuka-lwr", ".urdf", "[tool=none]"):
        assert accepted in msg
    from hybrid_dyn.data.logs.importer import import_log, read_spec

    # The log file does not exist: the robot is checked before it would be opened.
    with pytest.raises(RobotDescriptionError, match="unknown robot 'ur11'"):
        import_log(tmp_path / "missing.csv", tmp_path / "ds", columns={"q": "1-6", "tau_m": "7-12"},
                   sample_rate_hz=100.0, robot="ur11")
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "x"\nrobot = "ur11"\n[source]\nfiles = ["missing.csv"]\n[time]\nsample_rate_hz = 100.0\n'
                    '[columns]\nq = "1-6"\ntau_m = "7-12"\n')
    with pytest.raises(RobotDescriptionError, match="unknown robot 'ur11'"):
        read_spec(spec)
    assert not (tmp_path / "ds").exists()


def test_an_import_spec_chooses_the_variant(tmp_path):
    from hybrid_dyn.data.logs.importer import read_spec

    spec = tmp_path / "spec.toml"
    spec.write_text('name = "x"\nrobot = "panda"\ntool = "none"\npayload = { mass = 0.5, offset = [0, 0, 0.1] }\n'
                    '[source]\nfiles = ["log.csv"]\n[time]\nsample_rate_hz = 100.0\n[columns]\nq = "1-7"\n'
                    'tau_m = "8-14"\n')
    assert read_spec(spec).robot == "panda[tool=none;payload=0.5@0.0,0.0,0.1]"


def test_the_import_cli_chooses_the_tool(tmp_path):
    """hybrid-dyn import --tool none: the dataset is the bare-flange Panda's, whatever the spec says."""
    from hybrid_dyn.cli import main
    from hybrid_dyn.data import load_dataset

    t = np.arange(400) / 100.0
    q = 0.2 * np.sin(np.outer(t, np.arange(1, 8) * 0.5)) + np.array(hd.load_robot("panda").spec.home)
    tau = np.cos(np.outer(t, np.arange(1, 8)))
    header = "t," + ",".join(f"q{i}" for i in range(1, 8)) + "," + ",".join(f"tau{i}" for i in range(1, 8))
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, q, tau]), delimiter=",", header=header, comments="")
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "x"\nrobot = "panda"\n[source]\nfiles = ["log.csv"]\n[time]\ncolumn = "t"\n'
                    '[trajectories]\nfrom = "blocks"\nn_blocks = 4\n[columns]\nq = ["q1", "q2", "q3", "q4", "q5", '
                    '"q6", "q7"]\ntau_m = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6", "tau7"]\n')
    assert main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds"), "--tool", "none", "--json"]) == 0
    assert load_dataset(tmp_path / "ds").meta["robot"] == "panda[tool=none]"


def test_spec_paths_of_robot_and_tool_are_relative_to_the_spec(tmp_path):
    from hybrid_dyn.data.logs.importer import read_spec

    (tmp_path / "arm.urdf").write_text(PENDULUM.format(m=1.0, L=0.2, tip=0.4))
    (tmp_path / "tool.urdf").write_text('<robot name="t"><link name="t_body"/><link name="t_tcp"/><joint name="tj" '
                                        'type="fixed"><parent link="t_body"/><child link="t_tcp"/></joint></robot>')
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "x"\nrobot = "arm.urdf"\ntool = "tool.urdf"\n[source]\nfiles = ["log.csv"]\n[time]\n'
                    'sample_rate_hz = 100.0\n[columns]\nq = "1"\ntau_m = "2"\n')
    robot = read_spec(spec).robot
    assert robot == f"{tmp_path.resolve() / 'arm.urdf'}[tool={tmp_path.resolve() / 'tool.urdf'}]"
    assert hd.load_robot(robot).spec.tool_frame == "t_tcp"
