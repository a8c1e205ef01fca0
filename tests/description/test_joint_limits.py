"""The joints and limits the log checks read off a description are the analytic model's, exactly."""
import numpy as np
import pytest

from hybrid_dyn.analytic.robot import load_robot
from hybrid_dyn.description import joint_limits, resolve_robot


@pytest.mark.parametrize("name", ["panda", "panda[tool=none]", "panda[payload=0.5@0,0,0.05]", "ur5", "ur10"])
def test_joint_limits_are_the_analytic_models(name):
    robot = load_robot(name)
    joints = joint_limits(resolve_robot(name).spec)
    assert joints.names == robot.joint_names
    assert joints.nv == robot.nv
    np.testing.assert_array_equal(joints.lower, robot.q_lower)
    np.testing.assert_array_equal(joints.upper, robot.q_upper)
    np.testing.assert_array_equal(joints.effort, np.asarray(robot.model.effortLimit, float))
