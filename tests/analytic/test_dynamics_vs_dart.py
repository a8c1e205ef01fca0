"""The Pinocchio model against DART, an independent engine, on the same URDF.

Both implement exact rigid-body dynamics, so they must agree to round-off; the
brief's tolerance is 1e-8 (Nm, kg m^2, N) and we hold them to it.
"""
import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.analytic.tip_force import SINGULAR_REGION, tip_force_from_base_wrench, tip_force_from_torques
from hybrid_dyn.sim.plant import DartPlant

from helpers.states import random_states

N_STATES = 200


@pytest.fixture(scope="module")
def robot_and_plant(described_robot):
    """Every robot declared in robots/ (conftest.described_robot) and its DART twin on the same URDF."""
    return described_robot, DartPlant(described_robot)


def test_inverse_dynamics_mass_matrix_base_wrench_match_dart(robot_and_plant):
    robot, plant = robot_and_plant
    q, qd, qdd = random_states(robot, N_STATES, seed=1)
    tau = robot.inverse_dynamics(q, qd, qdd)  # batched path (rneaInParallel)
    M = robot.mass_matrix(q)
    W = robot.base_wrench(q, qd, qdd)
    for i in range(N_STATES):
        tau_dart = plant.inverse_dynamics(q[i], qd[i], qdd[i])
        np.testing.assert_allclose(tau[i], tau_dart, atol=1e-8, rtol=0)
        np.testing.assert_allclose(W[i], plant.base_wrench(), atol=1e-8, rtol=0)
        np.testing.assert_allclose(M[i], plant.mass_matrix(q[i]), atol=1e-8, rtol=0)


def test_single_sample_matches_batch(panda):
    q, qd, qdd = random_states(panda, 100, seed=3)
    batch = panda.inverse_dynamics(q, qd, qdd)
    single = np.stack([panda.inverse_dynamics(q[i], qd[i], qdd[i]) for i in range(5)])
    np.testing.assert_allclose(single, batch[:5], atol=1e-12)
    assert panda.base_wrench(q[0], qd[0], qdd[0]).shape == (6,)


def test_tip_force_effect_matches_dart(robot_and_plant):
    robot, plant = robot_and_plant
    q, qd, qdd = random_states(robot, N_STATES, seed=2)
    forces = np.random.default_rng(5).normal(0.0, 10.0, (N_STATES, 3))
    tau_model = robot.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", robot.tip_jacobian(q)[:, :3], forces)
    W_model = robot.base_wrench(q, qd, qdd, tip_force=forces)
    for i in range(N_STATES):
        tau_dart = plant.inverse_dynamics(q[i], qd[i], qdd[i], tip_force=forces[i])
        np.testing.assert_allclose(tau_model[i], tau_dart, atol=1e-8, rtol=0)
        np.testing.assert_allclose(W_model[i], plant.base_wrench(), atol=1e-8, rtol=0)


def test_both_baselines_recover_a_dart_tip_force(robot_and_plant):
    """Exact data from DART with a known tool-point force: both methods give it back to 1e-6 N."""
    robot, plant = robot_and_plant
    q, qd, qdd = random_states(robot, N_STATES, seed=4)
    sigma_min = np.linalg.svd(robot.tip_jacobian(q)[:, :3], compute_uv=False)[:, -1]
    q, qd, qdd = q[sigma_min > SINGULAR_REGION], qd[sigma_min > SINGULAR_REGION], qdd[sigma_min > SINGULAR_REGION]
    assert len(q) > 150
    forces = np.random.default_rng(6).uniform(-20.0, 20.0, (len(q), 3))
    tau = np.empty_like(q)
    wrench = np.empty((len(q), 6))
    for i in range(len(q)):
        tau[i] = plant.inverse_dynamics(q[i], qd[i], qdd[i], tip_force=forces[i])
        wrench[i] = plant.base_wrench()
    np.testing.assert_allclose(tip_force_from_torques(robot, q, qd, qdd, tau), forces, atol=1e-6, rtol=0)
    f_bw, residual = tip_force_from_base_wrench(robot, q, qd, qdd, wrench, return_residual=True)
    np.testing.assert_allclose(f_bw, forces, atol=1e-6, rtol=0)
    assert np.abs(residual).max() < 1e-6  # a pure tool-point force leaves no moment unexplained


def test_base_wrench_residual_flags_a_force_elsewhere(panda):
    """A force on link 4 is not a tool-point force: the residual moment says so."""
    plant = DartPlant(panda)
    q, qd, qdd = random_states(panda, 1, seed=7)
    plant.set_state(q[0], qd[0])
    plant.skel.setAccelerations(plant._to_dart(qdd[0]))
    plant.skel.clearExternalForces()
    plant.skel.getBodyNode("panda_link4").addExtForce(np.array([0.0, 15.0, 0.0]), np.zeros(3), False, True)
    plant.skel.computeInverseDynamics(True, False, False)
    _, residual = tip_force_from_base_wrench(panda, q, qd, qdd, plant.base_wrench()[None], return_residual=True)
    assert np.linalg.norm(residual) > 0.5


def test_static_base_wrench_is_total_weight(panda):
    """At rest the ground carries the whole weight: fz = m_total g, fx = fy = 0 (an identity)."""
    q, _, _ = random_states(panda, 10, seed=8)
    W = panda.base_wrench(q, np.zeros_like(q), np.zeros_like(q))
    np.testing.assert_allclose(W[:, 2], panda.total_mass * 9.81, rtol=1e-12)
    np.testing.assert_allclose(W[:, :2], 0.0, atol=1e-10)


def test_torques_method_is_damped_at_a_singularity(panda):
    """Near a singularity (J_v almost rank-deficient): the estimate stays bounded instead of blowing up."""
    # Found by random search over 20,000 poses: sigma_min(J_v) = 0.002 m/rad.
    q = np.array([1.873, -0.277, -2.231, -0.383, 1.791, 2.717, -1.306])
    jv = panda.tip_jacobian(q)[:3]
    assert np.linalg.svd(jv, compute_uv=False)[-1] < 0.1 * SINGULAR_REGION
    tau = panda.inverse_dynamics(q, np.zeros(7), np.zeros(7)) + 1e-3  # tiny torque noise
    f = tip_force_from_torques(panda, q, np.zeros(7), np.zeros(7), tau)
    assert np.all(np.isfinite(f)) and np.linalg.norm(f) < 1.0


def test_single_sample_fast_path_equals_batch_path():
    """The control-loop path (one sample) and the batch path agree, tilted sensor included."""
    robot = hd.load_robot("panda", sensor_mount=hd.SensorMount((0.001, 0.0, 0.0), (np.deg2rad(1.0), 0.0, 0.0)))
    q, qd, qdd = random_states(robot, 20, seed=9)
    f = np.random.default_rng(1).normal(0, 10, (20, 3))
    w = robot.base_wrench(q, qd, qdd, tip_force=f)
    batch, res_b = tip_force_from_base_wrench(robot, q, qd, qdd, w, return_residual=True)
    for i in range(20):
        single, res_s = tip_force_from_base_wrench(robot, q[i], qd[i], qdd[i], w[i], return_residual=True)
        np.testing.assert_allclose(single, batch[i], atol=1e-10)
        np.testing.assert_allclose(res_s, res_b[i], atol=1e-10)
        np.testing.assert_allclose(robot.base_wrench(q[i], qd[i], qdd[i]), robot.base_wrench(q, qd, qdd)[i], atol=1e-10)
    np.testing.assert_allclose(batch, f, atol=1e-9)


def test_single_sample_damped_solve_equals_lapack(panda):
    """The closed-form 3x3 path (control loops) against numpy's eigvalsh/solve, inside and outside
    the singular region."""
    from hybrid_dyn.analytic.tip_force import damped_force_from_joint_torques, damped_force_single
    q, _, _ = random_states(panda, 300, seed=12)
    jv = panda.tip_jacobian(q)[:, :3]
    tau = np.random.default_rng(2).normal(0, 5, (300, 7))
    batch = damped_force_from_joint_torques(jv, tau)
    sigma = np.linalg.svd(jv, compute_uv=False)[:, -1]
    assert (sigma < SINGULAR_REGION).any() and (sigma > SINGULAR_REGION).any()
    single = np.stack([damped_force_single(jv[i], tau[i]) for i in range(300)])
    np.testing.assert_allclose(single, batch, rtol=1e-8, atol=1e-8)
