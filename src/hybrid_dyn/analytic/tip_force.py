"""Classic model-based tip-force estimators.

All return the force [N] that the environment exerts on the robot at the tool
point, in the base frame, shape (N, 3) (or (3,) for a single sample).

Two of them are algebraic, sample by sample:

- ``tip_force_from_torques``: tau = ID(q, qd, qdd) - J_v^T F, solved for F.
  Needs link-side joint torques (a torque-sensing arm like the Panda).
- ``tip_force_from_base_wrench``: the base sensor measures the ground reaction;
  the model predicts it for free motion; the difference is the external wrench,
  which for a pure force at the tool point is -[F; p x F].

The third, the momentum observer, is dynamic: see ``momentum_observer.py``.
"""
from __future__ import annotations

import numpy as np

from .robot import InputError, Robot, as_batch


# Damped least squares near singularities (Nakamura & Hanafusa 1986; Maciejewski 1988):
# no damping while the smallest singular value of J_v is above SINGULAR_REGION [m/rad],
# rising smoothly to MAX_DAMPING^2 at a singularity. Far from singularities the
# solution is the exact least-squares one.
SINGULAR_REGION = 0.05
MAX_DAMPING = 0.05


def damped_force_from_joint_torques(jv: np.ndarray, tau_ext: np.ndarray,
                                    singular_region: float = SINGULAR_REGION,
                                    max_damping: float = MAX_DAMPING) -> np.ndarray:
    """Solve J_v^T F = tau_ext for F by adaptively damped least squares.

    jv: (N, 3, nv) linear rows of the tool Jacobian; tau_ext: (N, nv) [Nm].
    F = (J_v J_v^T + lambda^2 I)^-1 J_v tau_ext with
    lambda^2 = max_damping^2 (1 - (sigma_min / singular_region)^2) inside the
    singular region and 0 outside it.
    """
    jjt = jv @ jv.transpose(0, 2, 1)
    sigma_min_sq = np.linalg.eigvalsh(jjt)[:, 0].clip(min=0.0)
    lam_sq = np.where(sigma_min_sq < singular_region**2,
                      max_damping**2 * (1.0 - sigma_min_sq / singular_region**2), 0.0)
    rhs = np.einsum("nij,nj->ni", jv, tau_ext)
    return np.linalg.solve(jjt + lam_sq[:, None, None] * np.eye(3), rhs[..., None])[..., 0]


def tip_force_from_torques(robot: Robot, q, qd, qdd, tau, singular_region: float = SINGULAR_REGION,
                           max_damping: float = MAX_DAMPING) -> np.ndarray:
    """F = pinv(J_v^T) (ID(q, qd, qdd) - tau), damped near singularities.

    tau: measured link-side joint torques [Nm] (N, nv). Motor torques work too
    if friction has been subtracted first; otherwise friction shows up as force.
    """
    q_, single = robot._q(q)
    tau_, _ = as_batch(tau, "tau", robot.nv)
    if len(tau_) != len(q_):
        raise InputError(f"tau has {len(tau_)} samples, q has {len(q_)}")
    tau_ext = robot.inverse_dynamics(q_, qd, qdd).reshape(len(q_), -1) - tau_
    jv = robot._tip_jacobians(q_)[:, :3, :]
    f = damped_force_from_joint_torques(jv, tau_ext, singular_region, max_damping)
    return f[0] if single else f


def force_from_external_wrench(p_tool: np.ndarray, dw_root: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares pure force at the tool point explaining a wrench change.

    The ground reaction changes by dW = -[F; p x F] when the environment pushes
    with F at p (root coordinates). With A = [I; [p]x], minimise |A F + dW|^2
    over all six components: (A^T A) F = -A^T dW, and A^T A = (1 + |p|^2) I - p p^T
    has the closed-form inverse (I + p p^T) / (1 + |p|^2).
    Returns F (N, 3) [N] and the residual moment dW_m + p x F (N, 3) [Nm], the
    part of the moment that no force at the tool point can explain.
    """
    df, dm = dw_root[:, :3], dw_root[:, 3:]
    b = -(df - np.cross(p_tool, dm))
    pp = np.einsum("ni,ni->n", p_tool, p_tool)
    f = (b + p_tool * np.einsum("ni,ni->n", p_tool, b)[:, None]) / (1.0 + pp)[:, None]
    residual_moment = dm + np.cross(p_tool, f)
    return f, residual_moment


def tip_force_from_base_wrench(robot: Robot, q, qd, qdd, base_wrench, return_residual: bool = False):
    """The base-wrench method: measured minus model-predicted ground reaction.

    base_wrench: measured ground reaction wrench (N, 6) [N, Nm] in the nominal
    base-sensor frame. Returns F (N, 3) [N]; with ``return_residual=True`` also
    the residual moment (N, 3) [Nm] as a consistency signal: large values mean
    the wrench change is not a pure force at the tool point (a model error, a
    contact elsewhere, or a sensor offset).
    """
    q_, qd_, qdd_, single = robot._state(q, qd, qdd)
    w, _ = as_batch(base_wrench, "base_wrench", 6)
    if len(w) != len(q_):
        raise InputError(f"base_wrench has {len(w)} samples, q has {len(q_)}")
    dw_root = robot.base_wrench_to_root(w - robot.base_wrench(q_, qd_, qdd_))
    f, res = force_from_external_wrench(robot._tip_positions(q_), dw_root)
    if single:
        f, res = f[0], res[0]
    return (f, res) if return_residual else f
