"""Finite-difference checks of the tool Jacobian and the tool position."""
import numpy as np
import pinocchio as pin
import pytest

import hybrid_dyn as hd

from conftest import random_states


@pytest.mark.parametrize("name", ["panda", "ur5", "xarm7"])
def test_tip_jacobian_matches_central_differences(name):
    robot = hd.load_robot(name)
    q, _, _ = random_states(robot, 20, seed=11)
    J = robot.tip_jacobian(q)
    assert J.shape == (20, 6, robot.nv)
    h = 1e-6
    data = robot.model.createData()

    def rotation(qi):
        pin.framesForwardKinematics(robot.model, data, qi)
        return data.oMf[robot.tool_frame_id].rotation.copy()

    for i in range(len(q)):
        R0 = rotation(q[i])
        for j in range(robot.nv):
            dq = np.zeros(robot.nv)
            dq[j] = h
            dp = (robot.tip_position(q[i] + dq) - robot.tip_position(q[i] - dq)) / (2 * h)
            np.testing.assert_allclose(J[i, :3, j], dp, atol=1e-7)
            # Angular rows: world-frame rotation vector of R(q+h) R(q-h)^T over 2h.
            w = pin.log3(rotation(q[i] + dq) @ rotation(q[i] - dq).T) / (2 * h)
            np.testing.assert_allclose(J[i, 3:, j], w, atol=1e-7)
    _ = R0


def test_panda_tcp_is_10_34_cm_past_the_hand(panda):
    """URDF: panda_hand_tcp sits 0.1034 m along the hand z axis; the flange is 0.107 m past link 7."""
    q = np.array(panda.spec.home)
    data = panda.model.createData()
    pin.framesForwardKinematics(panda.model, data, q)
    hand = data.oMf[panda.model.getFrameId("panda_hand")]
    np.testing.assert_allclose(panda.tip_position(q), hand.act(np.array([0.0, 0.0, 0.1034])), atol=1e-12)
