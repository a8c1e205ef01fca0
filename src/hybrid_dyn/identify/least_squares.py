"""Estimators: from stacked regressors and measured torques to parameters.

Each takes the stacked data (``W`` (N, nv, p) regressor, ``tau`` (N, nv) [Nm]) and
returns arrays; :mod:`.model` wraps them into an :class:`IdentifiedModel`.

- :func:`fit_ols` / :func:`fit_wls`: least squares on the base regressor. WLS
  weights each joint's rows by 1/sigma_j, sigma_j^2 the joint's OLS residual
  variance (joints with quieter torques count more, as in Gautier's method).
- :func:`fit_consistent`: the full parameters through the log-Cholesky map
  (every iterate is a physically consistent body), the COM of each body held in a
  box around the link, linear friction with fv, fc >= 0, and a light pull towards
  the nominal parameters for directions the data cannot see. CasADi + IPOPT.
- :func:`fit_sigmoid_friction`: the same inertial model with the Gaz sigmoid
  friction law fitted jointly (nonlinear in its parameters). CasADi + IPOPT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analytic.robot import Robot
from ..errors import HybridDynError
from .parameters import N_BODY_PARAMS, dynamic_to_log_cholesky, log_cholesky_to_pseudo, pseudo_to_dynamic

# Typical sizes used to make parameter deviations comparable in the regularizer:
# mass [kg], first moment [kg m], inertia [kg m^2].
PARAM_SCALE = np.array([1.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01])


class IdentificationError(HybridDynError, ValueError):
    """The data cannot support the asked-for fit (too few samples, solver failure)."""


@dataclass(frozen=True)
class ConsistentConfig:
    """Settings of the physically consistent NLPs.

    regularization: weight of sum(((pi - pi_nominal) / PARAM_SCALE)^2) against the
      mean squared weighted residual (~1 at the optimum), i.e. light;
    com_margin [m]: the COM box is the hull of the link's joint origins and frames
      grown by this margin;
    min_radius [m]: lower bound on the log-Cholesky diagonal e^{d_i}, i.e. on the
      (conditional) standard deviations of the mass distribution about its COM.
      Without it the optimum often sits on the boundary of consistency (a body
      collapsed onto a line or plane: the triangle inequality met with equality);
      with it every body is strictly inside;
    max_iter: IPOPT iterations; print_level: IPOPT verbosity (0 = silent).
    """

    regularization: float = 1e-3
    com_margin: float = 0.05
    min_radius: float = 0.005
    max_iter: int = 300
    tol: float = 1e-9
    print_level: int = 0


def fit_ols(Wb: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """beta minimizing ||Wb beta - tau||^2; Wb (N, nv, r), tau (N, nv)."""
    A = Wb.reshape(-1, Wb.shape[-1])
    beta, *_ = np.linalg.lstsq(A, tau.reshape(-1), rcond=None)
    return beta


def joint_residual_std(Wb: np.ndarray, tau: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Per-joint residual standard deviation [Nm] (nv,), with the r fitted parameters' dof removed."""
    res = tau - Wb @ beta
    n, nv = tau.shape
    dof = max(n * nv - len(beta), 1)
    return np.sqrt(np.sum(res**2, axis=0) / (dof / nv))


def fit_wls(Wb: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(beta, sigma): least squares with each joint's rows divided by its OLS residual std sigma_j [Nm]."""
    sigma = joint_residual_std(Wb, tau, fit_ols(Wb, tau))
    sigma = np.maximum(sigma, 1e-9 * max(sigma.max(), 1e-300))  # noise-free data: keep the weights finite
    beta = fit_ols(Wb / sigma[None, :, None], tau / sigma[None, :])
    return beta, sigma


def com_boxes(robot: Robot, margin: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """A box (lo, hi) [m] in each joint's frame that the body's COM must lie in.

    The hull of the points that belong to the body: its frame origin, the parent
    joint's origin, the child joints' origins and every frame fixed to it (hand,
    tool point), grown by ``margin``. A COM outside this is a fit artefact.
    """
    model = robot.model
    boxes = []
    for j in range(1, model.njoints):
        pts = [np.zeros(3), model.jointPlacements[j].inverse().translation]
        pts += [model.jointPlacements[k].translation for k in range(1, model.njoints) if model.parents[k] == j]
        pts += [f.placement.translation for f in model.frames if f.parentJoint == j]
        pts = np.array(pts)
        boxes.append((pts.min(0) - margin, pts.max(0) + margin))
    return boxes


def _solve(nlp: dict, x0, lbx, ubx, lbg, ubg, cfg: ConsistentConfig, extra_opts: dict | None = None):
    import casadi as ca

    opts = {"ipopt.print_level": cfg.print_level, "print_time": 0, "ipopt.max_iter": cfg.max_iter,
            "ipopt.tol": cfg.tol, "ipopt.sb": "yes"}
    opts.update(extra_opts or {})
    solver = ca.nlpsol("identify", "ipopt", nlp, opts)
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    if not stats["success"] and stats["return_status"] not in ("Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded"):
        raise IdentificationError(f"IPOPT failed: {stats['return_status']}")
    return np.asarray(sol["x"]).ravel(), stats


def _inertial_block(robot: Robot, pi_start: np.ndarray, boxes, pi_nominal, cfg: ConsistentConfig):
    """Decision variables, pi(theta) and COM constraints shared by both consistent fits."""
    import casadi as ca

    nv = robot.nv
    theta = ca.SX.sym("theta", N_BODY_PARAMS * nv)
    pis, g = [], []
    for j in range(nv):
        pj = pseudo_to_dynamic(log_cholesky_to_pseudo(theta[N_BODY_PARAMS * j: N_BODY_PARAMS * (j + 1)]))
        pis.append(pj)
        lo, hi = boxes[j]
        h, m = pj[1:4], pj[0]
        g += [h - m * lo, m * hi - h]  # m lo <= m c <= m hi, >= 0
    pi = ca.vertcat(*pis)
    theta0 = np.concatenate([dynamic_to_log_cholesky(pi_start[N_BODY_PARAMS * j: N_BODY_PARAMS * (j + 1)])
                             for j in range(nv)])
    # Bounds: d1, d2, d3 >= log(min_radius); alpha and the off-diagonals are free.
    lbt = np.tile([-np.inf] + [np.log(cfg.min_radius)] * 3 + [-np.inf] * 6, nv)
    theta0 = np.maximum(theta0, lbt + 1e-6)
    scale = np.tile(PARAM_SCALE, nv)
    reg = cfg.regularization * ca.sumsqr((pi - pi_nominal) / scale)
    return theta, pi, ca.vertcat(*g), theta0, lbt, reg


def _clip_into_boxes(pi: np.ndarray, boxes) -> np.ndarray:
    """Move each body's COM into its box (keeping mass and inertia about the COM): a feasible start."""
    from .parameters import from_urdf_form, to_urdf_form

    out = pi.copy()
    for j, (lo, hi) in enumerate(boxes):
        sl = slice(N_BODY_PARAMS * j, N_BODY_PARAMS * (j + 1))
        m, c, icom = to_urdf_form(pi[sl])
        if m <= 0:
            continue
        out[sl] = from_urdf_form(m, np.clip(c, lo + 1e-3, hi - 1e-3), icom)
    return out


def fit_consistent(robot: Robot, Y: np.ndarray, F: np.ndarray, tau: np.ndarray, sigma: np.ndarray,
                   pi_nominal: np.ndarray, phi_start: np.ndarray, cfg: ConsistentConfig = ConsistentConfig()):
    """Physically consistent inertial parameters and linear friction.

    Y (N, nv, 10 nv) inertial regressor, F (N, nv, 3 nv) friction regressor, tau (N, nv),
    sigma (nv,) per-joint weights [Nm]. Returns (pi (10 nv,), phi (3 nv,), ipopt stats).
    """
    import casadi as ca

    nv = robot.nv
    boxes = com_boxes(robot, cfg.com_margin)
    A = np.concatenate([Y, F], axis=-1) / sigma[None, :, None]
    b = (tau / sigma[None, :]).reshape(-1)
    A = A.reshape(-1, A.shape[-1])
    n_rows = len(b)
    # The data term through its normal equations: a (p x p) Gram instead of N rows.
    G, gvec, bb = A.T @ A / n_rows, A.T @ b / n_rows, b @ b / n_rows
    theta, pi, g, theta0, lbt, reg = _inertial_block(robot, _clip_into_boxes(pi_nominal, boxes), boxes, pi_nominal, cfg)
    phi = ca.SX.sym("phi", F.shape[-1])
    x = ca.vertcat(pi, phi)
    f = ca.bilin(ca.DM(G), x, x) - 2 * ca.dot(ca.DM(gvec), x) + bb + reg
    # fv >= 0, fc >= 0; the offset is free, and so are any declared terms' columns after them.
    lb_phi = np.concatenate([np.tile([0.0, 0.0, -np.inf], nv), np.full(F.shape[-1] - 3 * nv, -np.inf)])
    phi0 = np.maximum(phi_start, lb_phi)
    sol, stats = _solve({"x": ca.vertcat(theta, phi), "f": f, "g": g},
                        np.concatenate([theta0, phi0]), np.concatenate([lbt, lb_phi]),
                        np.inf, 0.0, np.inf, cfg)
    pi_fun = ca.Function("pi", [theta], [pi])
    pi_hat = np.asarray(pi_fun(sol[: len(theta0)])).ravel()
    return pi_hat, sol[len(theta0):], stats


# Bounds of the Gaz sigmoid parameters: phi1 [Nm] >= 0, phi2 [s/rad] in a range
# that spans the Panda's identified 5-17, phi3 [rad/s] a small velocity offset.
SIGMOID_BOUNDS = {"phi1": (0.0, 20.0), "phi2": (0.5, 100.0), "phi3": (-0.5, 0.5)}


def gaz_sigmoid(qd, phi1, phi2, phi3):
    """The Gaz law on numpy or CasADi arguments (see :class:`~hybrid_dyn.description.GazFriction`)."""
    import casadi as ca

    return phi1 / (1 + ca.exp(-phi2 * (qd + phi3))) - phi1 / (1 + ca.exp(-phi2 * phi3))


def fit_sigmoid_friction(robot: Robot, Y: np.ndarray, qd: np.ndarray, tau: np.ndarray, sigma: np.ndarray,
                         pi_nominal: np.ndarray, phi_start: np.ndarray, cfg: ConsistentConfig = ConsistentConfig()):
    """Consistent inertial parameters and the Gaz sigmoid friction law, fitted jointly.

    tau_f,j = phi1 / (1 + exp(-phi2 (qd + phi3))) - phi1 / (1 + exp(-phi2 phi3)).
    phi_start (nv, 3) [phi1, phi2, phi3]. Returns (pi (10 nv,), phi (nv, 3), ipopt stats).
    """
    import casadi as ca

    nv = robot.nv
    boxes = com_boxes(robot, cfg.com_margin)
    theta, pi, g, theta0, lbt, reg = _inertial_block(robot, _clip_into_boxes(pi_nominal, boxes), boxes, pi_nominal, cfg)
    # The data term sum_j ||Y_j pi + f_j(phi_j) - tau_j||^2 (rows divided by sigma_j), expanded:
    #   pi^T G pi - 2 g^T pi + |tau|^2 + sum_j [2 pi^T c_j - 2 tau_j^T f_j + |f_j|^2],  c_j = Y_j^T f_j:
    # pi enters through a small Gram; only the friction terms need the N samples.
    n = len(tau)
    scale = 1.0 / (n * nv)
    Yw = Y / sigma[None, :, None]
    tw = tau / sigma[None, :]
    G = np.einsum("njp,njq->pq", Yw, Yw)
    gvec = np.einsum("njp,nj->p", Yw, tw)
    n_th = len(theta0)
    theta_mx = ca.MX.sym("theta", n_th)
    phi_mx = ca.MX.sym("phi", 3 * nv)
    pi_of_theta = ca.Function("pi", [theta], [pi])
    pi_mx = pi_of_theta(theta_mx)

    # Per joint, SX functions of the three friction parameters over the N samples.
    phi_j, u_j = ca.SX.sym("phi_j", 3), ca.SX.sym("u_j", n)
    friction_fns = []
    for j in range(nv):
        fj = gaz_sigmoid(ca.DM(qd[:, j]), phi_j[0], phi_j[1], phi_j[2]) / sigma[j]
        hj = 2 * ca.dot(u_j, fj) + ca.sumsqr(fj)  # the phi_j-dependent part, u_j = Y_j pi - tau_j
        friction_fns.append((ca.Function(f"f{j}", [phi_j], [fj]), ca.Function(f"jf{j}", [phi_j], [ca.jacobian(fj, phi_j)]),
                             ca.Function(f"hh{j}", [phi_j, u_j], [ca.hessian(hj, phi_j)[0]])))
    c_mx, obj = 0, 0
    for j, (f_fn, _, _) in enumerate(friction_fns):
        fj = f_fn(phi_mx[3 * j: 3 * j + 3])
        c_mx = c_mx + ca.mtimes(ca.DM(Yw[:, j, :].T), fj)
        obj = obj - 2 * ca.dot(ca.DM(tw[:, j]), fj) + ca.sumsqr(fj)
    obj = obj + ca.bilin(ca.DM(G), pi_mx, pi_mx) - 2 * ca.dot(ca.DM(gvec), pi_mx) + 2 * ca.dot(pi_mx, c_mx)
    obj = obj + float(np.sum(tw**2))
    reg_fun = ca.Function("reg", [theta], [reg])
    g_fun = ca.Function("g", [theta], [g])
    f = obj * scale + reg_fun(theta_mx)

    # The exact Hessian of the Lagrangian, assembled by hand from its blocks. Left to
    # AD it re-runs the (N x 10 nv) products once per parameter (~100 passes); here
    # the friction parameters need three passes per joint and the inertial block none.
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.shape[0])
    c_sx, lf_sx, lg_sx = ca.SX.sym("c", pi.shape[0]), ca.SX.sym("lf"), ca.SX.sym("lg", g.shape[0])
    inertial_lag = lf_sx * (scale * (ca.bilin(ca.DM(G), pi, pi) - 2 * ca.dot(ca.DM(gvec), pi) + 2 * ca.dot(pi, c_sx)) + reg) \
        + ca.dot(lg_sx, g)
    h_tt = ca.Function("h_tt", [theta, c_sx, lf_sx, lg_sx], [ca.hessian(inertial_lag, theta)[0]])
    jac_pi = ca.Function("jac_pi", [theta], [ca.jacobian(pi, theta)])
    cross, diag = [], []
    for j, (_, jf_fn, hh_fn) in enumerate(friction_fns):
        pj = phi_mx[3 * j: 3 * j + 3]
        cross.append(ca.mtimes(ca.DM(Yw[:, j, :].T), jf_fn(pj)))  # d c_j / d phi_j (10 nv x 3)
        u = ca.mtimes(ca.DM(Yw[:, j, :]), pi_mx) - ca.DM(tw[:, j])
        diag.append(lam_f * scale * hh_fn(pj, u))
    h_tp = lam_f * scale * 2 * ca.mtimes(jac_pi(theta_mx).T, ca.horzcat(*cross))
    h_pp = ca.diagcat(*diag)
    hess = ca.blockcat([[h_tt(theta_mx, c_mx, lam_f, lam_g), h_tp], [h_tp.T, h_pp]])
    x = ca.vertcat(theta_mx, phi_mx)
    hess_fn = ca.Function("hess_lag", [x, ca.MX.sym("p", 0), lam_f, lam_g], [ca.triu(hess)],
                          ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])

    lo = np.tile([SIGMOID_BOUNDS[k][0] for k in ("phi1", "phi2", "phi3")], nv)
    hi = np.tile([SIGMOID_BOUNDS[k][1] for k in ("phi1", "phi2", "phi3")], nv)
    phi0 = np.clip(np.asarray(phi_start, float).reshape(-1), lo, hi)
    sol, stats = _solve({"x": x, "f": f, "g": g_fun(theta_mx)},
                        np.concatenate([theta0, phi0]), np.concatenate([lbt, lo]),
                        np.concatenate([np.inf * np.ones(n_th), hi]), 0.0, np.inf, cfg, {"hess_lag": hess_fn})
    pi_hat = np.asarray(pi_of_theta(sol[: len(theta0)])).ravel()
    return pi_hat, sol[len(theta0): len(theta0) + 3 * nv].reshape(nv, 3), stats
