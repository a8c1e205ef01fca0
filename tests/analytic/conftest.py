"""Fixtures of the analytic tests: an independently integrated moving arm (the observers' reference)."""
import numpy as np
import pytest

from helpers.motion import simulate_with_tip_force


@pytest.fixture(scope="module")
def moving_arm(panda):
    """A moving arm with a constant tip force, integrated by RK45 on ABA, sampled at 1 kHz;
    the ground wrench it needs (no noise) and the true acceleration, for the observer's inputs."""
    force = np.array([6.0, -4.0, 9.0])
    t, q, qd, tau = simulate_with_tip_force(panda, force, duration=0.3, dt=1e-3)
    qdd = np.gradient(qd, t, axis=0)  # only to build the sensor reading: the observer never sees it
    import pinocchio as pin

    data = panda.model.createData()
    qdd = np.stack([pin.aba(panda.model, data, q[i], qd[i], tau[i] + panda.tip_jacobian(q[i])[:3].T @ force)
                    for i in range(len(t))])
    wrench = panda.base_wrench(q, qd, qdd, tip_force=np.tile(force, (len(t), 1)))
    return t, q, qd, wrench, force
