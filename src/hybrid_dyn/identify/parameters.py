"""Inertial parameters of rigid bodies: the forms identification needs.

Three views of one body's ten inertial parameters:

- *dynamic parameters* ``pi`` (10,), Pinocchio's order and the one the joint-torque
  regressor is linear in: ``[m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]``,
  mass [kg], first moment [kg m], inertia [kg m^2] about the *body frame origin*;
- *URDF form*: mass, COM [m], inertia about the COM ``[xx, xy, xz, yy, yz, zz]``
  (the order of :class:`~hybrid_dyn.description.LinkInertial`);
- the *pseudo-inertia* ``J = [[Sigma, h], [h^T, m]]`` (4x4) with
  ``Sigma = tr(I)/2 * 1 - I`` the second moment of the mass distribution.
  A body is physically consistent (some non-negative density realizes it) iff J is
  positive (semi)definite [Wensing, Kim, Slotine, RA-L 2018]. J > 0 implies m > 0,
  a positive-definite rotational inertia and the triangle inequalities.

The *log-Cholesky* map (Rucker and Wensing, RA-L 2022) writes J = U U^T with an
upper-triangular U of positive diagonal, parameterized by ten unconstrained
reals: every value of them is a physically consistent body, which is what lets an
unconstrained-looking NLP stay physical.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_BODY_PARAMS = 10
PARAM_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def inertia_matrix(pi: np.ndarray) -> np.ndarray:
    """The 3x3 inertia about the body origin [kg m^2] from dynamic parameters (..., 10)."""
    pi = np.asarray(pi, float)
    xx, xy, yy, xz, yz, zz = (pi[..., k] for k in range(4, 10))
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)


def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """The 4x4 pseudo-inertia matrix J of dynamic parameters (..., 10)."""
    pi = np.asarray(pi, float)
    inertia = inertia_matrix(pi)
    sigma = 0.5 * np.trace(inertia, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - inertia
    J = np.zeros(pi.shape[:-1] + (4, 4))
    J[..., :3, :3] = sigma
    J[..., :3, 3] = pi[..., 1:4]
    J[..., 3, :3] = pi[..., 1:4]
    J[..., 3, 3] = pi[..., 0]
    return J


def to_urdf_form(pi: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass [kg], com [m] (3,), inertia about the COM [xx, xy, xz, yy, yz, zz]) of one body.

    A body of (near) zero mass gets com = 0 and keeps its inertia about the origin.
    """
    pi = np.asarray(pi, float)
    m = float(pi[0])
    c = pi[1:4] / m if abs(m) > 1e-12 else np.zeros(3)
    i_com = inertia_matrix(pi) - m * (c @ c * np.eye(3) - np.outer(c, c))
    return m, c, np.array([i_com[0, 0], i_com[0, 1], i_com[0, 2], i_com[1, 1], i_com[1, 2], i_com[2, 2]])


def from_urdf_form(mass: float, com, inertia_com) -> np.ndarray:
    """Dynamic parameters (10,) from mass, COM and inertia about the COM (URDF order)."""
    c = np.asarray(com, float)
    xx, xy, xz, yy, yz, zz = (float(x) for x in inertia_com)
    i_com = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    i_o = i_com + mass * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([mass, *(mass * c), i_o[0, 0], i_o[0, 1], i_o[1, 1], i_o[0, 2], i_o[1, 2], i_o[2, 2]])


@dataclass(frozen=True)
class ConsistencyReport:
    """Physical validity of one body, each check computed independently of the others.

    mass [kg]; inertia_eigenvalues [kg m^2] of the rotational inertia about the COM;
    triangle_margin = min over the three principal moments of (I_a + I_b - I_c) [kg m^2];
    pseudo_inertia_min_eig: smallest eigenvalue of J.
    """

    mass: float
    inertia_eigenvalues: np.ndarray
    triangle_margin: float
    pseudo_inertia_min_eig: float
    com_in_box: bool | None = None

    @property
    def valid(self) -> bool:
        ok = self.mass > 0 and self.inertia_eigenvalues.min() > 0 and self.triangle_margin >= 0
        return bool(ok and (self.com_in_box is None or self.com_in_box))


def check_consistency(pi: np.ndarray, com_box: tuple | None = None, tol: float = 0.0,
                      box_tol: float = 1e-6) -> ConsistencyReport:
    """Check one body's dynamic parameters (10,): mass, inertia eigenvalues, triangle inequalities.

    ``tol`` [kg m^2] absorbs round-off in the triangle margin. ``com_box`` = (lo (3,), hi (3,)) [m];
    ``box_tol`` [m]: a COM on the box face within the NLP's constraint tolerance counts as inside.
    """
    m, c, i_com_vec = to_urdf_form(pi)
    xx, xy, xz, yy, yz, zz = i_com_vec
    eig = np.linalg.eigvalsh(np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    triangle = min(eig[0] + eig[1] - eig[2], eig[1] + eig[2] - eig[0], eig[0] + eig[2] - eig[1]) + tol
    j_min = float(np.linalg.eigvalsh(pseudo_inertia(pi)).min())
    in_box = None
    if com_box is not None:
        lo, hi = (np.asarray(b, float) for b in com_box)
        in_box = bool(np.all(c >= lo - box_tol) and np.all(c <= hi + box_tol))
    return ConsistencyReport(m, eig, float(triangle), j_min, in_box)


# ------------------------------------------------------------------ log-Cholesky
def log_cholesky_to_pseudo(theta):
    """Pseudo-inertia J = U U^T from ten log-Cholesky coordinates (numpy or CasADi).

    theta = [alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3];
    U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]].
    Works on CasADi SX/MX vectors too (only exp, products and sums).
    """
    import casadi as ca

    a, d1, d2, d3, s12, s23, s13, t1, t2, t3 = (theta[k] for k in range(10))
    e = ca.exp(a)
    U = ca.vertcat(
        ca.horzcat(ca.exp(d1), s12, s13, t1),
        ca.horzcat(0, ca.exp(d2), s23, t2),
        ca.horzcat(0, 0, ca.exp(d3), t3),
        ca.horzcat(0, 0, 0, 1),
    ) * e
    return U @ U.T


def pseudo_to_dynamic(J):
    """Dynamic parameters (10,) from a pseudo-inertia (numpy or CasADi 4x4)."""
    import casadi as ca

    sigma = J[:3, :3]
    tr = sigma[0, 0] + sigma[1, 1] + sigma[2, 2]
    # I = tr(Sigma) 1 - Sigma
    return ca.vertcat(J[3, 3], J[0, 3], J[1, 3], J[2, 3],
                      tr - sigma[0, 0], -sigma[0, 1], tr - sigma[1, 1], -sigma[0, 2], -sigma[1, 2], tr - sigma[2, 2])


def dynamic_to_log_cholesky(pi: np.ndarray, floor: float = 1e-9) -> np.ndarray:
    """Log-Cholesky coordinates (10,) of a body, after pushing J to be positive definite.

    Used to start the consistent NLP from the nominal (or OLS) values: the
    eigenvalues of J are floored at ``floor`` times its largest one.
    """
    J = pseudo_inertia(pi)
    w, V = np.linalg.eigh(J)
    w = np.maximum(w, floor * max(w.max(), 1e-12))
    J = (V * w) @ V.T
    # Upper-triangular U with J = U U^T: reverse-order Cholesky.
    P = np.eye(4)[::-1]
    L = np.linalg.cholesky(P @ J @ P)
    U = P @ L @ P
    alpha = np.log(U[3, 3])
    U = U / U[3, 3]
    return np.array([alpha, np.log(U[0, 0]), np.log(U[1, 1]), np.log(U[2, 2]),
                     U[0, 1], U[1, 2], U[0, 2], U[0, 3], U[1, 3], U[2, 3]])
