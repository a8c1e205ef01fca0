"""The linear-in-parameters form of the joint torques and its base parameters.

The detail (what it computes, the equations, why each choice): docs/design/identify.md, section ``identify/regressor.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import scipy.linalg

from ..analytic.robot import InputError, Robot, as_batch
from .parameters import N_BODY_PARAMS, PARAM_NAMES

FRICTION_NAMES = ("fv", "fc", "fo")
DEFAULT_COULOMB_EPS = 0.02  # rad/s: tanh(qd/eps) is within 1 % of sign(qd) beyond 0.05 rad/s


def nominal_body_parameters(robot: Robot) -> np.ndarray:
    """Dynamic parameters (10 nv,) of the robot's bodies (Pinocchio's merged per-joint inertias)."""
    return np.concatenate([robot.model.inertias[j].toDynamicParameters() for j in range(1, robot.model.njoints)])


def column_names(robot: Robot, friction: bool = True) -> list[str]:
    """Names of the regressor columns, e.g. ``panda_joint3.Izz``, ``panda_joint3.fv``."""
    names = [f"{j}.{p}" for j in robot.joint_names for p in PARAM_NAMES]
    if friction:
        names += [f"{j}.{p}" for j in robot.joint_names for p in FRICTION_NAMES]
    return names


def inertial_regressor(robot: Robot, q, qd, qdd) -> np.ndarray:
    """Y(q, qd, qdd) (N, nv, 10 nv) with Y @ pi = rigid-body torques [Nm]."""
    q, qd, qdd, single = robot._state(q, qd, qdd)
    model, data = robot.model, robot.data
    out = np.empty((len(q), robot.nv, N_BODY_PARAMS * robot.nv))
    for i in range(len(q)):
        out[i] = pin.computeJointTorqueRegressor(model, data, q[i], qd[i], qdd[i])
    return out[0] if single else out


def friction_regressor(qd, eps: float = DEFAULT_COULOMB_EPS) -> np.ndarray:
    """F(qd) (N, nv, 3 nv): per joint the viscous, smooth-Coulomb and offset columns."""
    qd, single = as_batch(qd, "qd", np.shape(qd)[-1])
    n, nv = qd.shape
    out = np.zeros((n, nv, 3 * nv))
    j = np.arange(nv)
    out[:, j, 3 * j] = qd
    out[:, j, 3 * j + 1] = np.tanh(qd / eps)
    out[:, j, 3 * j + 2] = 1.0
    return out[0] if single else out


def full_regressor(robot: Robot, q, qd, qdd, friction: bool = True, eps: float = DEFAULT_COULOMB_EPS) -> np.ndarray:
    """[Y | F] (N, nv, 13 nv) (or Y alone without friction)."""
    y = inertial_regressor(robot, q, qd, qdd)
    if not friction:
        return y
    qd_b, _ = as_batch(qd, "qd", robot.nv)
    f = friction_regressor(qd_b, eps)
    return np.concatenate([y, f[0] if y.ndim == 2 else f], axis=-1)


@dataclass(frozen=True)
class BaseParameters:
    """The identifiable combinations beta = K pi of the full parameters pi.

    independent: indices (r,) of the full columns kept as the base regressor, W_b = W[:, independent];
    K: (r, p) with W pi = W_b K pi for every state; tol: the relative rank tolerance used.
    """

    independent: np.ndarray
    K: np.ndarray
    tol: float
    names: tuple

    @property
    def n_base(self) -> int:
        return len(self.independent)

    def project(self, pi: np.ndarray) -> np.ndarray:
        """beta = K pi: base parameters of full parameters (p,) or (..., p)."""
        return np.asarray(pi) @ self.K.T

    def reduce(self, W: np.ndarray) -> np.ndarray:
        """The base regressor: the independent columns of W (..., p)."""
        return W[..., self.independent]

    def base_names(self) -> list[str]:
        """Name of each base parameter: its leading column plus the columns folded into it."""
        out = []
        for row, i in zip(self.K, self.independent):
            extra = [f"{c:+.3g}*{self.names[k]}" for k, c in enumerate(row) if k != i and abs(c) > 1e-9]
            out.append(self.names[i] + ("".join(" " + e for e in extra[:3]) + (" ..." if len(extra) > 3 else "")))
        return out


def base_parameters(robot: Robot, friction: bool = True, n_samples: int = 200, seed: int = 0,
                    tol: float = 1e-8, eps: float = DEFAULT_COULOMB_EPS) -> BaseParameters:
    """Structural base parameters of ``robot`` from QR with column pivoting (see module doc).

    The regressor is stacked over ``n_samples`` random states (uniform in the joint
    limits, normal velocities and accelerations), so the result is a property of
    the kinematics, not of any one data set.
    """
    rng = np.random.default_rng(seed)
    lo = np.maximum(robot.q_lower, -np.pi)
    hi = np.minimum(robot.q_upper, np.pi)
    q = rng.uniform(lo, hi, (n_samples, robot.nv))
    qd = rng.normal(0.0, 1.0, (n_samples, robot.nv))
    qdd = rng.normal(0.0, 3.0, (n_samples, robot.nv))
    W = full_regressor(robot, q, qd, qdd, friction, eps).reshape(n_samples * robot.nv, -1)
    _, R, perm = scipy.linalg.qr(W, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    r = int(np.sum(diag > tol * diag[0]))
    if r == 0:
        raise InputError("the regressor is identically zero: nothing is identifiable")
    K_perm = np.zeros((r, W.shape[1]))
    K_perm[:, :r] = np.eye(r)
    K_perm[:, r:] = scipy.linalg.solve_triangular(R[:r, :r], R[:r, r:])
    K = np.zeros_like(K_perm)
    K[:, perm] = K_perm
    K[np.abs(K) < 1e-12] = 0.0  # round-off in structurally zero couplings
    return BaseParameters(independent=perm[:r].copy(), K=K, tol=tol, names=tuple(column_names(robot, friction)))
