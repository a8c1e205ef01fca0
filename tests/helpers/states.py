"""Random robot states for the cross-checks."""
import numpy as np


def random_states(robot, n, seed=0, margin=0.05):
    """n random (q, qd, qdd) inside the joint limits (wide-limit joints clipped to +-pi)."""
    rng = np.random.default_rng(seed)
    lo = np.maximum(robot.q_lower, -np.pi) + margin
    hi = np.minimum(robot.q_upper, np.pi) - margin
    q = rng.uniform(lo, hi, (n, robot.nv))
    qd = rng.normal(0.0, 1.0, (n, robot.nv))
    qdd = rng.normal(0.0, 3.0, (n, robot.nv))
    return q, qd, qdd
