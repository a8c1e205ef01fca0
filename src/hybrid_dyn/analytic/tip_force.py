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

import math

import numpy as np
import pinocchio as pin
from numba import njit

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


def damped_force_single(jv: np.ndarray, tau_ext: np.ndarray, singular_region: float = SINGULAR_REGION,
                        max_damping: float = MAX_DAMPING) -> np.ndarray:
    """One-sample ``damped_force_from_joint_torques``: jv (3, nv), tau_ext (nv,) [Nm] -> F (3,) [N].

    Same damping law, in :func:`damped_solve3` (compiled; the Kalman fusion kernel runs it too).
    """
    jv = np.asarray(jv, dtype=float)
    return damped_solve3(jv @ jv.T, jv @ np.asarray(tau_ext, dtype=float), float(singular_region), float(max_damping))


@njit(cache=True)
def damped_solve3(a, b, singular_region, max_damping):  # pragma: no cover (compiled)
    """(a + lambda^2 I)^-1 b for a = J_v J_v^T (3, 3) and b = J_v tau (3,), lambda^2 by the damping law of
    :func:`damped_force_from_joint_torques` [m/rad, and F in N for tau in Nm].

    The smallest eigenvalue of the symmetric a in closed form (:func:`_min_eig_sym3`) and the solve by
    the adjugate: at 3 x 3 both cost a fraction of a LAPACK call, which matters once per control cycle.
    """
    a00, a01, a02, a11, a12, a22 = a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2]
    # lam_min >= det / trace^2 (the other two eigenvalues are each below the trace):
    # far from singularities that cheap bound settles it without the eigenvalue.
    det0 = a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02) + a02 * (a01 * a12 - a11 * a02)
    tr = a00 + a11 + a22
    lam_min = _min_eig_sym3(a00, a01, a02, a11, a12, a22) if det0 < singular_region**2 * tr * tr else math.inf
    if lam_min < singular_region**2:
        d = max_damping**2 * (1.0 - max(lam_min, 0.0) / singular_region**2)
        a00, a11, a22 = a00 + d, a11 + d, a22 + d
    c00, c01, c02, c11, c12, c22, det = sym3_adjugate(a00, a01, a02, a11, a12, a22)
    out = np.empty(3)
    out[0] = (c00 * b[0] + c01 * b[1] + c02 * b[2]) / det
    out[1] = (c01 * b[0] + c11 * b[1] + c12 * b[2]) / det
    out[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det
    return out


@njit(cache=True)
def sym3_adjugate(a00, a01, a02, a11, a12, a22):  # pragma: no cover (compiled)
    """The adjugate of a symmetric 3x3 matrix (its upper triangle c00, c01, c02, c11, c12, c22) and its
    determinant: the inverse is the adjugate over the determinant, at 3 x 3 a fraction of a LAPACK call."""
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    return c00, c01, c02, c11, c12, c22, a00 * c00 + a01 * c01 + a02 * c02


@njit(cache=True)
def _min_eig_sym3(a00, a01, a02, a11, a12, a22):  # pragma: no cover (compiled)
    """Smallest eigenvalue of a symmetric 3x3 matrix (Smith 1961)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    if p1 == 0.0:
        return min(a00, a11, a22)
    p2 = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02))
    phi = math.acos(min(1.0, max(-1.0, r))) / 3.0
    return q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)


def tip_force_from_torques(robot: Robot, q, qd, qdd, tau, singular_region: float = SINGULAR_REGION,
                           max_damping: float = MAX_DAMPING) -> np.ndarray:
    """F = pinv(J_v^T) (ID(q, qd, qdd) - tau), damped near singularities.

    tau: measured link-side joint torques [Nm] (N, nv). Motor torques work too
    if friction has been subtracted first; otherwise friction shows up as force.
    """
    if np.ndim(q) == 1:
        q = robot._single(q, "q", True)
        tau_ext = robot.inverse_dynamics(q, qd, qdd) - robot._single(tau, "tau")
        jv = pin.computeFrameJacobian(robot.model, robot.data, q, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        return damped_force_single(jv, tau_ext, singular_region, max_damping)
    q_, single = robot._q(q)
    tau_, _ = as_batch(tau, "tau", robot.nv)
    if len(tau_) != len(q_):
        raise InputError(f"tau has {len(tau_)} samples, q has {len(q_)}")
    tau_ext = robot.inverse_dynamics(q_, qd, qdd).reshape(len(q_), -1) - tau_
    jv = robot._tip_jacobians(q_)[:, :3, :]
    f = damped_force_from_joint_torques(jv, tau_ext, singular_region, max_damping)
    return f[0] if single else f


def contact_joint_torques(robot: Robot, q, force) -> np.ndarray:
    """tau_c = J_v(q)^T F [Nm]: the joint torques a force F [N] (base frame) at the tool point
    produces; q (nv,) with F (3,), or batches (N, nv) with (N, 3)."""
    jv = robot.tip_jacobian(q)[..., :3, :]
    return np.einsum("...ij,...i->...j", jv, force)


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
    if np.ndim(q) == 1:
        return _base_wrench_method_single(robot, q, qd, qdd, base_wrench, return_residual)
    q_, qd_, qdd_, single = robot._state(q, qd, qdd)
    w, _ = as_batch(base_wrench, "base_wrench", 6)
    if len(w) != len(q_):
        raise InputError(f"base_wrench has {len(w)} samples, q has {len(q_)}")
    dw_root = robot.base_wrench_to_root(w - robot.base_wrench(q_, qd_, qdd_))
    f, res = force_from_external_wrench(robot._tip_positions(q_), dw_root)
    if single:
        f, res = f[0], res[0]
    return (f, res) if return_residual else f


def _base_wrench_method_single(robot: Robot, q, qd, qdd, base_wrench, return_residual: bool):
    """One sample, for control loops: preallocated buffers, no batching, and the
    3x3 solve written out (np.cross costs more than the dynamics at this size)."""
    q = robot._single(q, "q", True)
    qd = robot._single(qd, "qd")
    qdd = robot._single(qdd, "qdd")
    w = np.asarray(base_wrench, dtype=float)
    if w.shape != (6,) or not math.isfinite(w.dot(w)):
        raise InputError(f"base_wrench must be 6 finite values, got shape {w.shape}")
    return base_wrench_force_core(robot, q, qd, qdd, w, return_residual)


def base_wrench_force_core(robot: Robot, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, w: np.ndarray,
                           return_residual: bool = False):
    """The base-wrench method on one already-validated sample (the streaming estimator's path)."""
    w_model_root = robot.rnea_ff_single(q, qd, qdd)[:6]
    # Python floats from here on: numpy scalars cost ~5x more per operation.
    dfx, dfy, dfz, dmx, dmy, dmz = (robot._root_from_sensor @ w - w_model_root).tolist()
    px, py, pz = robot.tip_position_single(q).tolist()
    # b = -(df - p x dm)
    bx = -(dfx - (py * dmz - pz * dmy))
    by = -(dfy - (pz * dmx - px * dmz))
    bz = -(dfz - (px * dmy - py * dmx))
    pb = px * bx + py * by + pz * bz
    inv = 1.0 / (1.0 + px * px + py * py + pz * pz)
    f = np.array([(bx + px * pb) * inv, (by + py * pb) * inv, (bz + pz * pb) * inv])
    if not return_residual:
        return f
    fx, fy, fz = f.tolist()
    res = np.array([dmx + py * fz - pz * fy, dmy + pz * fx - px * fz, dmz + px * fy - py * fx])
    return f, res
