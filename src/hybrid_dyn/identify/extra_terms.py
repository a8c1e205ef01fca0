"""Declared joint terms a robot's URDF lacks, identified beside its inertials and friction.

A description may name joints that carry a spring (``[identification] springs`` in its TOML:
Baxter's shoulder s1 has a gravity-assist spring). Each adds three columns to the regressor, acting
on its own joint only:

    tau_spring,j = k_lin q_j + k_sin sin(q_j) + k_cos cos(q_j)        [Nm], k_lin [Nm/rad], k_sin, k_cos [Nm]

(the constant part is the joint's friction offset column already). A spring stretched between two
links by a lever arm gives a torque that is a smooth function of the joint angle, neither linear nor
a pure harmonic; the linear term and the first harmonic are the first terms of it. With the linear term
alone, Baxter's least-squares fit made up the rest with a body of negative mass (-12.6 kg on e0), which
the physically consistent fit cannot: its s1 error stayed at 3.0 Nm (``docs/real_robots.md``).
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


SPRING_TERMS = ("k_lin", "k_sin", "k_cos")  # the columns of one spring, in this order


def spring_basis(qj: np.ndarray) -> np.ndarray:
    """(..., 3): q_j, sin(q_j), cos(q_j) [rad, 1, 1], the spring law's basis."""
    qj = np.asarray(qj, float)
    return np.stack([qj, np.sin(qj), np.cos(qj)], axis=-1)


def spring_regressor(joints: list[int], q: np.ndarray, nv: int) -> np.ndarray:
    """S(q) (N, nv, 3 len(joints)): spring i's three columns act on row j = joints[i], zero elsewhere."""
    q = np.atleast_2d(np.asarray(q, float))
    out = np.zeros((len(q), nv, len(SPRING_TERMS) * len(joints)))
    for i, j in enumerate(joints):
        out[:, j, 3 * i:3 * i + 3] = spring_basis(q[:, j])
    return out


def extra_regressor(spec, q, joint_names=None) -> np.ndarray | None:
    """The declared terms' columns (N, nv, n_terms), or None when the description declares none."""
    if not spec.springs:
        return None
    q = np.atleast_2d(np.asarray(q, float))
    names = joint_names if joint_names is not None else spec.springs
    return spring_regressor(spring_joints(spec, names), q, q.shape[1])
