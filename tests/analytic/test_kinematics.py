"""Finite-difference checks of the tool Jacobian and the tool position."""
import numpy as np
import pinocchio as pin

from helpers.states import random_states


def test_tip_jacobian_matches_central_differences(described_robot):
    robot = described_robot
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


def test_contact_joint_torques_do_the_work_of_the_tip_force(panda):
    """Virtual work: tau_c . dq = F . dp for a small joint step dq, with dp from tip positions
    (central difference), not from the Jacobian; batched and single-sample forms alike."""
    from hybrid_dyn.analytic.tip_force import contact_joint_torques

    rng = np.random.default_rng(5)
    q = np.clip(rng.uniform(-1.5, 1.5, (20, 7)), panda.q_lower + 0.1, panda.q_upper - 0.1)
    dq = 1e-6 * rng.standard_normal((20, 7))
    force = rng.uniform(-20, 20, (20, 3))
    dp = panda.tip_position(q + dq / 2) - panda.tip_position(q - dq / 2)
    tau_c = contact_joint_torques(panda, q, force)
    np.testing.assert_allclose(np.einsum("nj,nj->n", tau_c, dq), np.einsum("ni,ni->n", force, dp), rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(contact_joint_torques(panda, q[3], force[3]), tau_c[3], atol=1e-12)
