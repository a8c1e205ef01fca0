"""Declared joint terms a robot's URDF lacks, identified beside its inertials and friction.

A description may name joints that carry a spring (``[identification] springs`` in its TOML:
Baxter's shoulder s1 has a gravity-assist spring). Each adds one column to the regressor, acting
on its own joint only:

    tau_spring,j = k_j q_j        [Nm], k_j [Nm/rad]

(the constant part, k_j q_0, is the joint's friction offset column already). A linear law is the
first term of any smooth spring torque about the arm's working range; the per-joint test errors
(``benchmarks/real_robot_evidence.py``) say whether it is enough.
"""
from __future__ import annotations

import numpy as np

from ..analytic.robot import InputError


def spring_joints(spec, joint_names) -> list[int]:
    """Indices of the joints with a declared spring (in the robot's joint order)."""
    unknown = [j for j in spec.springs if j not in joint_names]
    if unknown:
        raise InputError(f"robot {spec.name!r} declares springs on {unknown}, which are not among its joints "
                         f"{list(joint_names)}")
    return [list(joint_names).index(j) for j in spec.springs]


def spring_regressor(joints: list[int], q: np.ndarray, nv: int) -> np.ndarray:
    """S(q) (N, nv, len(joints)): column i is q_j on row j = joints[i], zero elsewhere."""
    q = np.atleast_2d(np.asarray(q, float))
    out = np.zeros((len(q), nv, len(joints)))
    for i, j in enumerate(joints):
        out[:, j, i] = q[:, j]
    return out


def extra_regressor(spec, q, joint_names=None) -> np.ndarray | None:
    """The declared terms' columns (N, nv, n_terms), or None when the description declares none."""
    if not spec.springs:
        return None
    q = np.atleast_2d(np.asarray(q, float))
    names = joint_names if joint_names is not None else spec.springs
    return spring_regressor(spring_joints(spec, names), q, q.shape[1])
