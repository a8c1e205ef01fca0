"""Excitation trajectories: finite Fourier series optimized for identification.

Each joint follows (Swevers et al., IEEE T-RA 1997)

    q_j(t) = q0_j + sum_l  a_jl / (l w) sin(l w t) - b_jl / (l w) cos(l w t),  l = 1..L,

a periodic signal with base frequency w = 2 pi f0, so a run can repeat it and
average out noise. The coefficients are chosen to make the base regressor well
conditioned (every base parameter excited, none drowned by another), subject to
the joint position, velocity and acceleration limits on a dense time grid, and
to rest at t = 0 (qd = qdd = 0, where the generator starts the arm).

The condition number itself is not smooth; the NLP minimizes the smooth bound
log tr(M) + log tr(M^-1) >= log cond(M), M = W_b^T W_b (W_b the base regressor
stacked over the grid), which is within a factor n_base^2 of cond(M) = cond(W_b)^2.
The exact cond(W_b) is reported before and after (from Pinocchio's regressor).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..analytic.robot import InputError, Robot
from .regressor import DEFAULT_COULOMB_EPS, BaseParameters, base_parameters, full_regressor


@dataclass(frozen=True)
class FourierTrajectory:
    """q0 [rad] (nv,), a [rad/s] and b [rad/s] (nv, L), base frequency f0 [Hz]."""

    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    f0: float

    @property
    def period(self) -> float:
        return 1.0 / self.f0

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q [rad], qd [rad/s], qdd [rad/s^2]), each (T, nv), at times t [s] (T,)."""
        t = np.asarray(t, float)[:, None, None]
        L = self.a.shape[1]
        wl = 2 * np.pi * self.f0 * np.arange(1, L + 1)  # (L,)
        s, c = np.sin(wl * t), np.cos(wl * t)  # (T, 1, L)
        q = self.q0 + np.sum(self.a / wl * s - self.b / wl * c, axis=-1)
        qd = np.sum(self.a * c + self.b * s, axis=-1)
        qdd = np.sum(-self.a * wl * s + self.b * wl * c, axis=-1)
        return q, qd, qdd

    def to_dict(self) -> dict:
        return {"q0": self.q0.tolist(), "a": self.a.tolist(), "b": self.b.tolist(), "f0": self.f0}


@dataclass(frozen=True)
class ExcitationConfig:
    """Design settings.

    harmonics L; f0 [Hz] base frequency (period 1/f0 s); n_grid: time points where
    the limits are enforced; n_objective: time points whose regressor enters the
    condition number; margin [rad] kept from each position limit; speed_fraction /
    accel_fraction of the robot's published velocity / acceleration limits;
    max_iter: IPOPT iterations (quasi-Newton).
    """

    harmonics: int = 5
    f0: float = 0.1
    n_grid: int = 200
    n_objective: int = 40
    margin: float = 0.15
    speed_fraction: float = 0.6
    accel_fraction: float = 0.5
    max_iter: int = 150
    seed: int = 0


def regressor_condition(robot: Robot, traj: FourierTrajectory, n_points: int = 200,
                        base: BaseParameters | None = None, eps: float = DEFAULT_COULOMB_EPS) -> float:
    """cond(W_b) of the base regressor (inertia and friction) over n_points of one period (Pinocchio)."""
    base = base or base_parameters(robot, eps=eps)
    t = np.linspace(0, traj.period, n_points, endpoint=False)
    W = base.reduce(full_regressor(robot, *traj.evaluate(t), eps=eps))
    return float(np.linalg.cond(W.reshape(-1, base.n_base)))


def design_excitation(robot: Robot, config: ExcitationConfig = ExcitationConfig(),
                      base: BaseParameters | None = None, eps: float = DEFAULT_COULOMB_EPS,
                      verbose: bool = False) -> tuple[FourierTrajectory, dict]:
    """Optimize a Fourier trajectory for ``robot``; returns (trajectory, report).

    report: condition numbers of the random feasible start and of the optimum,
    IPOPT's status and iterations.
    """
    import casadi as ca

    cfg = config
    nv, L = robot.nv, cfg.harmonics
    if len(robot.spec.max_velocity) != nv or len(robot.spec.max_acceleration) != nv:
        raise InputError(f"robot {robot.name!r} lacks max_velocity/max_acceleration for its {nv} joints")
    base = base or base_parameters(robot, eps=eps)
    lo = np.maximum(robot.q_lower, -np.pi) + cfg.margin
    hi = np.minimum(robot.q_upper, np.pi) - cfg.margin
    vmax = cfg.speed_fraction * np.asarray(robot.spec.max_velocity, float)
    amax = cfg.accel_fraction * np.asarray(robot.spec.max_acceleration, float)
    w = 2 * np.pi * cfg.f0
    wl = w * np.arange(1, L + 1)

    # Decision vector x = [q0 (nv), a (nv L), b (nv L)]; q, qd, qdd are linear in x.
    x = ca.MX.sym("x", nv * (1 + 2 * L))
    grid = np.linspace(0, 1 / cfg.f0, cfg.n_grid, endpoint=False)
    g, lbg, ubg = _limit_constraints(x, grid, wl, nv, L, (lo, hi, vmax, amax))
    obj = _conditioning_objective(robot, x, cfg, wl, base, eps)
    x0, start = _feasible_start(cfg, grid, wl, nv, (lo, hi, vmax, amax))

    solver = ca.nlpsol("excitation", "ipopt", {"x": x, "f": obj, "g": g},
                       {"ipopt.print_level": 5 if verbose else 0, "print_time": 0, "ipopt.sb": "yes",
                        "ipopt.max_iter": cfg.max_iter, "ipopt.hessian_approximation": "limited-memory",
                        "ipopt.tol": 1e-6})
    sol = solver(x0=x0, lbg=lbg, ubg=ubg)
    xs = np.asarray(sol["x"]).ravel()
    traj = FourierTrajectory(xs[:nv], xs[nv: nv + nv * L].reshape(nv, L), xs[nv + nv * L:].reshape(nv, L), cfg.f0)
    stats = solver.stats()
    report = {"condition_start": regressor_condition(robot, start, base=base, eps=eps),
              "condition": regressor_condition(robot, traj, base=base, eps=eps),
              "ipopt_status": stats["return_status"], "iterations": stats["iter_count"]}
    return traj, report


def _basis(t, wl):
    """The Fourier terms at times t (T,) that multiply a and b in q, qd and qdd, each (T, L)."""
    t = np.asarray(t, float)[:, None]
    s, c = np.sin(wl * t), np.cos(wl * t)
    return s / wl, -c / wl, c, s, -s * wl, c * wl  # q: a, b; qd: a, b; qdd: a, b


def _linear_maps(t, wl, nv: int, L: int) -> dict:
    """Matrices P (T nv x n_x) with q = P_q x etc., rows time-major."""
    qa, qb, va, vb, aa, ab = _basis(t, wl)
    T = len(t)
    n_x = nv * (1 + 2 * L)
    P = {k: np.zeros((T * nv, n_x)) for k in ("q", "qd", "qdd")}
    for j in range(nv):
        rows = np.arange(T) * nv + j
        sa = slice(nv + j * L, nv + (j + 1) * L)
        sb = slice(nv + nv * L + j * L, nv + nv * L + (j + 1) * L)
        P["q"][rows, j] = 1.0
        for key, (ma, mb) in (("q", (qa, qb)), ("qd", (va, vb)), ("qdd", (aa, ab))):
            P[key][rows, sa] = ma
            P[key][rows, sb] = mb
    return P


def _limit_constraints(x, grid, wl, nv: int, L: int, limits):
    """The NLP's linear constraints (g, lbg, ubg): the position, velocity and acceleration limits
    (lo, hi, vmax, amax) at every grid point, and rest at t = 0 (qd = qdd = 0)."""
    import casadi as ca

    lo, hi, vmax, amax = limits
    Pg = _linear_maps(grid, wl, nv, L)
    P0 = _linear_maps(np.zeros(1), wl, nv, L)
    g = ca.vertcat(ca.mtimes(ca.DM(Pg["q"]), x), ca.mtimes(ca.DM(Pg["qd"]), x), ca.mtimes(ca.DM(Pg["qdd"]), x),
                   ca.mtimes(ca.DM(P0["qd"]), x), ca.mtimes(ca.DM(P0["qdd"]), x))
    T = len(grid)
    lbg = np.concatenate([np.tile(lo, T), np.tile(-vmax, T), np.tile(-amax, T), np.zeros(2 * nv)])
    ubg = np.concatenate([np.tile(hi, T), np.tile(vmax, T), np.tile(amax, T), np.zeros(2 * nv)])
    return g, lbg, ubg


def _conditioning_objective(robot: Robot, x, cfg: ExcitationConfig, wl, base: BaseParameters, eps: float):
    """log tr(M) + log tr(M^-1), M = W_b^T W_b / K over the objective points (the module docstring)."""
    import casadi as ca

    from .symbolic import regressor_function

    nv, L = robot.nv, cfg.harmonics
    # Regressor over the objective points: inertial (symbolic RNEA) + friction columns.
    t_obj = np.linspace(0, 1 / cfg.f0, cfg.n_objective, endpoint=False)
    Po = _linear_maps(t_obj, wl, nv, L)
    K = cfg.n_objective
    Q = ca.reshape(ca.mtimes(ca.DM(Po["q"]), x), nv, K)
    Qd = ca.reshape(ca.mtimes(ca.DM(Po["qd"]), x), nv, K)
    Qdd = ca.reshape(ca.mtimes(ca.DM(Po["qdd"]), x), nv, K)
    Yfun = regressor_function(robot).map(K)
    Y = Yfun(Q, Qd, Qdd)  # nv x (10 nv K), blocks per point
    blocks = []
    for k in range(K):
        Yk = Y[:, 10 * nv * k: 10 * nv * (k + 1)]
        qdk = Qd[:, k]
        Fk = ca.MX.zeros(nv, 3 * nv)
        for j in range(nv):
            Fk[j, 3 * j] = qdk[j]
            Fk[j, 3 * j + 1] = ca.tanh(qdk[j] / eps)
            Fk[j, 3 * j + 2] = 1.0
        blocks.append(ca.horzcat(Yk, Fk)[:, base.independent.tolist()])
    Wb = ca.vertcat(*blocks)
    M = ca.mtimes(Wb.T, Wb) / K
    return ca.log(ca.trace(M)) + ca.log(ca.trace(ca.solve(M, ca.DM.eye(base.n_base))))


def _feasible_start(cfg: ExcitationConfig, grid, wl, nv: int, limits) -> tuple[np.ndarray, FourierTrajectory]:
    """The NLP's start x0 and its trajectory: centred, small random coefficients (decaying with the
    harmonic), at rest at t = 0, scaled into the limits (lo, hi, vmax, amax) on the grid."""
    lo, hi, vmax, amax = limits
    L = cfg.harmonics
    rng = np.random.default_rng(cfg.seed)
    q0 = 0.5 * (lo + hi)
    a0 = rng.normal(size=(nv, L)) / np.arange(1, L + 1)
    b0 = rng.normal(size=(nv, L)) / np.arange(1, L + 1)
    a0 -= a0.mean(axis=1, keepdims=True)  # sum a = 0: qd(0) = 0
    b0 -= (b0 @ wl)[:, None] * wl / (wl @ wl)  # sum b l w = 0: qdd(0) = 0
    x0 = np.concatenate([q0, a0.ravel(), b0.ravel()])
    # Scale the start into the limits (all constraints are linear in the coefficients).
    start = FourierTrajectory(q0, a0, b0, cfg.f0)
    qg, vg, ag = start.evaluate(grid)
    ratio = max(np.max(np.abs(qg - q0) / (0.5 * (hi - lo))), np.max(np.abs(vg) / vmax), np.max(np.abs(ag) / amax))
    x0[nv:] *= 0.8 / ratio
    start = FourierTrajectory(q0, x0[nv: nv + nv * L].reshape(nv, L), x0[nv + nv * L:].reshape(nv, L), cfg.f0)
    return x0, start
