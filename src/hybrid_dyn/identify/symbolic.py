"""Recursive Newton-Euler in CasADi, for optimization over trajectories.

Pinocchio's PyPI wheel has no CasADi bindings, so the few lines of RNEA that an
excitation-design NLP needs are written here on CasADi SX, from the kinematic
data of the Pinocchio model (joint placements and axes). Torques are linear in
the body parameters pi, so ``jacobian(tau, pi)`` is exactly the joint-torque
regressor; the tests hold it to Pinocchio's ``computeJointTorqueRegressor``.

Spatial conventions are Pinocchio's: motions (v, omega), forces (f, n), both in
the body (joint) frame, moments about its origin, gravity (0, 0, -9.81) m/s^2.
"""
from __future__ import annotations

import numpy as np

from ..analytic.robot import Robot
from .parameters import N_BODY_PARAMS

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}


def _joint_axis(joint) -> np.ndarray:
    name = joint.shortname()
    if name in _AXES:
        return np.array(_AXES[name])
    if name == "JointModelRevoluteUnaligned":
        a = np.asarray(joint.extract().axis, float)
        return a / np.linalg.norm(a)
    raise NotImplementedError(f"symbolic RNEA supports revolute joints only, not {name}")


def _rotation(axis: np.ndarray, q):
    """Rodrigues: rotation by q [rad] about a unit axis (CasADi SX 3x3)."""
    import casadi as ca

    K = ca.SX(np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]))
    return ca.SX.eye(3) + ca.sin(q) * K + (1 - ca.cos(q)) * (K @ K)


def rnea_function(robot: Robot, gravity=(0.0, 0.0, -9.81)):
    """CasADi Function (q, qd, qdd, pi) -> tau [Nm] for ``robot`` (revolute chains/trees)."""
    import casadi as ca

    model = robot.model
    nv = robot.nv
    q, qd, qdd = (ca.SX.sym(n, nv) for n in ("q", "qd", "qdd"))
    pi = ca.SX.sym("pi", N_BODY_PARAMS * nv)
    # Per joint i (1-based in the model): rotation/translation child -> parent, velocity, acceleration.
    R, p, v, w, a, al, S = {}, {}, {}, {}, {}, {}, {}
    v[0], w[0] = ca.SX.zeros(3), ca.SX.zeros(3)
    a[0], al[0] = -ca.SX(np.asarray(gravity, float)), ca.SX.zeros(3)  # gravity as a base acceleration
    for i in range(1, model.njoints):
        axis = _joint_axis(model.joints[i])
        k = model.joints[i].idx_v
        M = model.jointPlacements[i]
        R[i] = ca.SX(M.rotation) @ _rotation(axis, q[k])
        p[i] = ca.SX(M.translation)
        par = model.parents[i]
        s = ca.SX(axis)
        S[i] = s
        # actInv of the parent's motion, plus the joint's own
        w_par = R[i].T @ w[par]
        v_par = R[i].T @ (v[par] - ca.cross(p[i], w[par]))
        w[i] = w_par + s * qd[k]
        v[i] = v_par
        al_par = R[i].T @ al[par]
        a_par = R[i].T @ (a[par] - ca.cross(p[i], al[par]))
        # + S qdd + v_i x (S qd): motion cross product with the joint twist (0, s qd)
        al[i] = al_par + s * qdd[k] + ca.cross(w[i], s * qd[k])
        a[i] = a_par + ca.cross(v[i], s * qd[k])
    f, n = {}, {}
    for i in range(1, model.njoints):
        b = pi[N_BODY_PARAMS * (i - 1): N_BODY_PARAMS * i]
        m, h = b[0], b[1:4]
        inertia = ca.vertcat(ca.horzcat(b[4], b[5], b[7]), ca.horzcat(b[5], b[6], b[8]), ca.horzcat(b[7], b[8], b[9]))
        # momentum (I v) and its rate
        f_mom, n_mom = m * v[i] - ca.cross(h, w[i]), inertia @ w[i] + ca.cross(h, v[i])
        f_acc, n_acc = m * a[i] - ca.cross(h, al[i]), inertia @ al[i] + ca.cross(h, a[i])
        f[i] = f_acc + ca.cross(w[i], f_mom)
        n[i] = n_acc + ca.cross(w[i], n_mom) + ca.cross(v[i], f_mom)
    tau = [None] * nv
    for i in range(model.njoints - 1, 0, -1):
        tau[model.joints[i].idx_v] = ca.dot(S[i], n[i])
        par = model.parents[i]
        if par > 0:
            f_par = R[i] @ f[i]
            f[par] = f[par] + f_par
            n[par] = n[par] + R[i] @ n[i] + ca.cross(p[i], f_par)
    return ca.Function("rnea", [q, qd, qdd, pi], [ca.vertcat(*tau)], ["q", "qd", "qdd", "pi"], ["tau"])


def regressor_function(robot: Robot):
    """CasADi Function (q, qd, qdd) -> Y (nv x 10 nv), tau = Y pi."""
    import casadi as ca

    rnea = rnea_function(robot)
    q, qd, qdd = (ca.SX.sym(n, robot.nv) for n in ("q", "qd", "qdd"))
    pi = ca.SX.sym("pi", N_BODY_PARAMS * robot.nv)
    Y = ca.jacobian(rnea(q, qd, qdd, pi), pi)
    return ca.Function("regressor", [q, qd, qdd], [Y], ["q", "qd", "qdd"], ["Y"])
