"""A steady-state Kalman filter that fuses the base sensor and the joint torques into one tip force.

Both sensors see the tip force F through a momentum law that needs no joint
acceleration:

- base sensor (``base_momentum.py``): h' = f_ground + m g + F, h = m v_com [N s];
- joint torques (``momentum_observer.py``): p' = tau_J + C^T qd - g + J_v^T F,
  p = M(q) qd [N m s]; projected to the tool by pinv(J_v^T) increment by increment.

For each sensor c, the "unexplained momentum" y_c (3,) [N s] is what remains of
the measured momentum after the sensor's own integral:

    y_b,k = h_k - h_0 - sum_j dt (u_j + u_j-1) / 2,     u = f_ground + m g
    y_J,k = sum_j pinv(J_v,j^T) [p_j - p_j-1 - dt (beta_j + beta_j-1) / 2]

and the filter's model is, per Cartesian axis (the three axes are independent
and alike, so every matrix below is (n, n) with n = sensors + 1):

    s_c,k+1 = s_c,k + dt F_k + w_c      (w_c: the sensor's noise, integrated)
    F_k+1   = F_k + w_F                 (the force as a random walk)
    y_c,k   = s_c,k + v_c               (v_c: the velocity noise in the momentum)

The gain is the steady-state one (``scipy.linalg.solve_discrete_are``),
computed once per (dt, noise, sensors) and cached, so a call costs the dynamics
terms and a few 3x3 products. A sensor that is absent (``None``) at a call is
predicted, not updated, with the gain of the filter that lacks it: with one
sensor missing throughout, this *is* the single-sensor filter.

Noise covariances come from the sensors' specifications (``FusionNoise``, the
generator's ``NoiseConfig`` values), mapped through the arm's Jacobians at its
home pose (the isotropic mean over axes): see :func:`channel_covariances`.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from functools import lru_cache

import numpy as np
import pinocchio as pin
from numba import njit
from scipy.linalg import solve_discrete_are

from .base_momentum import BaseMomentumObserver
from .momentum_observer import MomentumObserver
from .robot import InputError, Robot, as_batch
from .tip_force import MAX_DAMPING, SINGULAR_REGION, damped_force_from_joint_torques

SENSORS = ("base", "joint")


@dataclass(frozen=True)
class FusionNoise:
    """1-sigma white noise per sample of each sensor, and how fast the tip force may change.

    base_force [N] per axis, joint_torque [Nm] per joint, joint_velocity [rad/s]
    per joint: the generator's ``NoiseConfig`` defaults (a mid-range 6-axis F/T
    sensor, the Panda's torque sensors and encoders). force_rate [N/sqrt(s)]:
    intensity of the random walk of F (its variance grows by force_rate^2 per
    second); it sets the filter's bandwidth. base_model / joint_model [N]: a
    model error per axis, as a force, added to that sensor's noise (how far the
    model behind the sensor can be trusted; 0 = exact).
    """

    base_force: float = 0.2
    joint_torque: float = 0.05
    joint_velocity: float = 5e-4
    force_rate: float = 0.6
    base_model: float = 0.0
    joint_model: float = 0.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"FusionNoise.{name} must be finite and >= 0, got {value}")
        if self.force_rate == 0:
            raise InputError("FusionNoise.force_rate must be > 0 [N/sqrt(s)] (a constant force needs no filter)")


@dataclass(frozen=True)
class SteadyStateKalman:
    """A time-invariant Kalman filter x+ = A x + w, y = H x + v at its steady state.

    P: prior (predicted) covariance from the DARE; K = P H^T (H P H^T + R)^-1;
    P_post = (I - K H) P. One step: x_pred = A x; x = x_pred + K (y - H x_pred).
    """

    A: np.ndarray
    H: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    P: np.ndarray
    K: np.ndarray
    P_post: np.ndarray

    @classmethod
    def solve(cls, A, H, Q, R) -> "SteadyStateKalman":
        A, H, Q, R = (np.atleast_2d(np.asarray(x, float)) for x in (A, H, Q, R))
        # The filter's Riccati equation is the control one for (A^T, H^T).
        P = solve_discrete_are(A.T, H.T, Q, R)
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        P_post = (np.eye(len(A)) - K @ H) @ P
        return cls(A, H, Q, R, P, K, P_post)

    @property
    def closed_loop(self) -> np.ndarray:
        """(I - K H) A: x_k = closed_loop x_k-1 + K y_k."""
        return (np.eye(len(self.A)) - self.K @ self.H) @ self.A

    def filter(self, y: np.ndarray) -> np.ndarray:
        """Posterior states (N, n) for measurements y (N, m), from x_-1 = 0: a linear
        time-invariant system, run by ``scipy.signal.dlsim`` (x_k = (I - K H) A x_k-1 + K y_k)."""
        from scipy.signal import dlsim

        Acl = self.closed_loop
        # dlsim's state is x_k-1; its output is Acl x_k-1 + K y_k = x_k.
        return dlsim((Acl, self.K, Acl, self.K, 1.0), np.asarray(y, float).reshape(len(y), -1))[1]


def momentum_filter(dt: float, q_sensors, r_sensors, force_rate: float) -> SteadyStateKalman:
    """The per-axis filter for the sensors whose process and measurement variances are given.

    q_sensors [N^2 s^2] and r_sensors [N^2 s^2]: one entry per sensor;
    force_rate [N/sqrt(s)]. States: one unexplained momentum per sensor, then F.
    """
    m = len(q_sensors)
    A = np.eye(m + 1)
    A[:m, m] = dt
    H = np.eye(m, m + 1)
    Q = np.diag(list(q_sensors) + [force_rate**2 * dt])
    R = np.diag(list(r_sensors))
    return SteadyStateKalman.solve(A, H, Q, R)


def channel_covariances(robot: Robot, dt: float, noise: FusionNoise) -> dict:
    """Per sensor (process variance q, measurement variance r) [N^2 s^2] from the specifications.

    At the home pose, averaged over the three axes:
    base   q = dt^2 (base_force^2 + base_model^2),  r = sigma_qd^2 tr(m^2 J_com J_com^T) / 3;
    joint  q = dt^2 (sigma_tau^2 tr((J_v J_v^T)^-1) / 3 + joint_model^2),
           r = sigma_qd^2 tr(P M M P^T) / 3 with P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v.
    """
    q0 = np.array(robot.spec.home, float)
    data = robot.model.createData()
    m = robot.total_mass
    jcom = pin.jacobianCenterOfMass(robot.model, data, q0)  # the fixed model holds link 0 in the universe
    jv = pin.computeFrameJacobian(robot.model, data, q0, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    M = robot.mass_matrix(q0)
    jjt_inv = np.linalg.inv(jv @ jv.T)
    P = jjt_inv @ jv
    sq = noise.joint_velocity**2
    return {
        "base": (dt**2 * (noise.base_force**2 + noise.base_model**2), sq * m**2 * np.trace(jcom @ jcom.T) / 3.0),
        "joint": (dt**2 * (noise.joint_torque**2 * np.trace(jjt_inv) / 3.0 + noise.joint_model**2),
                  sq * np.trace(P @ M @ M @ P.T) / 3.0),
    }


def tare_window_noise(robot: Robot, dt: float, q, qd, base_wrench=None, tau_J=None,
                      noise: FusionNoise | None = None) -> FusionNoise:
    """``noise`` with its model errors estimated on a contact-free window (the tare's first samples).

    With F = 0, each sensor's unexplained-momentum increments d_k / dt [N] are its
    noise alone. Their mean square per axis (the mean: the model's error at the
    window's poses, e.g. a wrong gravity torque; the scatter: noise the
    specification misses, such as control jitter between 100 Hz samples),
    beyond what the specification predicts (q + 2 r) / dt^2, is that sensor's
    model error [N]. A sensor not given keeps its model error.
    """
    noise = noise or FusionNoise()
    y = KalmanTipForce(robot, dt, noise).measurements(q, qd, base_wrench, tau_J)
    return noise_from_increments(robot, dt, {name: np.diff(v, axis=0) for name, v in y.items()}, noise)


def noise_from_increments(robot: Robot, dt: float, increments: dict, noise: FusionNoise | None = None) -> FusionNoise:
    """``tare_window_noise`` from the sensors' unexplained-momentum increments [N s] on the window,
    {"base" | "joint": (n, 3)}: what a stream accumulates call by call (``TipForceEstimator``)."""
    noise = noise or FusionNoise()
    cov = channel_covariances(robot, dt, noise)
    errors = {}
    for name, inc in increments.items():
        if len(inc) < 2:
            raise InputError(f"the tare window needs at least 3 samples, got {len(inc) + 1}")
        d = np.asarray(inc, float) / dt
        measured = float(np.mean(d.var(axis=0) + d.mean(axis=0) ** 2))
        q_c, r_c = cov[name]
        predicted = (q_c + 2.0 * r_c) / dt**2
        errors[f"{name}_model"] = math.sqrt(max(0.0, measured - predicted) + getattr(noise, f"{name}_model") ** 2)
    return replace(noise, **errors)


@lru_cache(maxsize=64)
def _filters(robot: Robot, dt: float, noise: FusionNoise) -> dict:
    """The steady-state filter of every non-empty sensor subset, solved once per configuration."""
    cov = channel_covariances(robot, dt, noise)
    out = {}
    for subset in (("base",), ("joint",), ("base", "joint")):
        out[subset] = momentum_filter(dt, [cov[c][0] for c in subset], [cov[c][1] for c in subset], noise.force_rate)
    return out


class KalmanTipForce:
    """Streaming tip-force estimate [N] fusing the base sensor and the joint torques.

    dt: sample time [s]. Inputs per call: q [rad], qd [rad/s] (nv,);
    base_wrench [N, Nm] (6,) in the base-sensor frame, tared (``analytic/tare.py``),
    or None; tau_J link-side joint torques [Nm] (nv,), or None.
    """

    def __init__(self, robot: Robot, dt: float = 1e-3, noise: FusionNoise | None = None):
        if not dt > 0:
            raise InputError(f"dt must be positive [s], got {dt}")
        self.robot = robot
        self.dt = float(dt)
        self.noise = noise or FusionNoise()
        self.filters = _filters(robot, self.dt, self.noise)
        self._base = BaseMomentumObserver(robot, dt=self.dt)    # h(q, qd) and the weight
        self._joint = MomentumObserver(robot, dt=self.dt)       # p = M qd and beta = C^T qd - g
        # With the joint torques, two passes give every term: computeAllTerms (M, g and, for the base
        # sensor, the momentum m v_com as its centroidal hg), and computeCoriolisMatrix (C, and the joint
        # Jacobians the tip Jacobian is read from), instead of five separate passes.
        self._all_data = robot.model.createData()
        self._coriolis_data = robot.model.createData()
        # Each subset's gain embedded in the full state (rows s_base, s_joint, F; columns: the two
        # sensors' innovations), zero for an absent sensor: one small product per call, no indexing.
        self._gains = {}
        for subset, f in self.filters.items():
            G = np.zeros((3, 2))
            rows = [SENSORS.index(c) for c in subset]
            G[np.ix_(rows + [2], rows)] = f.K
            self._gains[subset] = G
        # For the compiled step: the gains indexed by 1 (base), 2 (joint), 3 (both), and constants.
        self._gain_table = np.zeros((4, 3, 2))
        for code, subset in ((1, ("base",)), (2, ("joint",)), (3, ("base", "joint"))):
            self._gain_table[code] = self._gains[subset]
        self._R3 = np.ascontiguousarray(robot._root_from_sensor[:3])
        self._mg3 = robot.total_mass * np.asarray(robot.model_ff.gravity.linear, float)
        self._zero3, self._zero6, self._zero_nv = np.zeros(3), np.zeros(6), np.zeros(robot.nv)
        self._zero_jac = np.zeros((6, robot.nv))
        self._zero_c = np.zeros((robot.nv, robot.nv))
        self.reset()
        # Compile (or load from numba's cache) now, not in the first control cycle: one call on copies.
        _fusion_step(self.state.copy(), self._y.copy(), self._last_base.copy(), self._last_joint.copy(),
                     self._has_last.copy(), self._gain_table, True, self._zero3, self._R3, self._zero6, self._mg3,
                     True, self._zero_nv, self._zero_c, self._zero_nv, self._zero_c, self._zero_nv, self._zero_jac,
                     self.dt, SINGULAR_REGION, MAX_DAMPING)

    def reset(self) -> None:
        """Forget the history: F = 0 and both sensors re-anchor at their next sample."""
        self.state = np.zeros((3, 3))  # rows: s_base, s_joint, F; columns: x, y, z
        self._y = np.zeros((2, 3))
        self._last_base = np.zeros((2, 3))  # the compiled step's copy: h, u of the previous sample
        self._last_joint = np.zeros((2, self.robot.nv))  # p, tau + beta of the previous sample
        self._has_last = np.zeros(2, dtype=np.bool_)

    @property
    def force(self) -> np.ndarray:
        return self.state[2].copy()

    @property
    def sums(self) -> np.ndarray:
        """The sensors' unexplained momenta y (2, 3) [N s] (rows: base, joint): between two calls at
        which a sensor is present, its row grows by exactly that sensor's increment."""
        return self._y

    # ------------------------------------------------------- measurements
    def _base_terms(self, q, qd, w):
        """(h [N s], u = f_ground + m g [N]) in root axes."""
        H, w_grav = self._base.momentum_and_gravity(q, qd)
        return H[:3], (self.robot._root_from_sensor[:3] @ w) + w_grav[:3]

    def _joint_terms(self, q, qd, tau):
        """(p = M qd [N m s], beta = tau_J + C^T qd - g [Nm])."""
        beta, p = self._joint._beta_and_p(q, qd)
        return p, tau + beta

    # ------------------------------------------------------------ streaming
    def step(self, q, qd, base_wrench=None, tau_J=None) -> np.ndarray:
        """Advance one sample; returns the tip force estimate [N] (3,), base frame."""
        robot = self.robot
        q = robot._single(q, "q")
        qd = robot._single(qd, "qd")
        if base_wrench is not None:
            base_wrench = np.asarray(base_wrench, dtype=float)
            if base_wrench.shape != (6,) or not math.isfinite(base_wrench.dot(base_wrench)):
                raise InputError(f"base_wrench must be 6 finite values [N, Nm] or None, got {base_wrench!r}")
        if tau_J is not None:
            tau_J = robot._single(tau_J, "tau_J")
        return self.step_unchecked(q, qd, base_wrench, tau_J)

    def step_unchecked(self, q, qd, base_wrench, tau_J) -> np.ndarray:
        """``step`` for validated inputs (None for an absent sensor).

        The dynamics terms come from Pinocchio; everything after them (the increments,
        the damped projection, predict and update) is one compiled kernel, since at
        these sizes each numpy call would cost more than the arithmetic.
        """
        robot = self.robot
        has_base, has_joint = base_wrench is not None, tau_J is not None
        if has_joint:
            model = robot.model
            a = self._all_data
            pin.computeAllTerms(model, a, q, qd)
            C = pin.computeCoriolisMatrix(model, self._coriolis_data, q, qd)
            jv = pin.getFrameJacobian(model, self._coriolis_data, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)
            M_upper, g, tau = a.M, a.g, tau_J
            # The fixed model's centroidal linear momentum is the free-flyer one's with the base at rest.
            h = a.hg.linear if has_base else self._zero3
        else:
            if has_base:
                b = self._base
                b._qff[7:] = q
                b._vff[6:] = qd
                h = pin.computeCentroidalMomentum(robot.model_ff, b._data, b._qff, b._vff).linear
            else:
                h = self._zero3
            qd = g = tau = self._zero_nv
            C, jv, M_upper = self._zero_c, self._zero_jac, self._zero_c
        w = base_wrench if has_base else self._zero6
        _fusion_step(self.state, self._y, self._last_base, self._last_joint, self._has_last, self._gain_table,
                     has_base, h, self._R3, w, self._mg3, has_joint, qd, M_upper, g, C, tau, jv, self.dt,
                     SINGULAR_REGION, MAX_DAMPING)
        return self.state[2].copy()

    # ---------------------------------------------------------------- batch
    def measurements(self, q, qd, base_wrench=None, tau_J=None) -> dict:
        """The unexplained momenta y_c (N, 3) [N s] of the sensors given, over a trajectory."""
        robot = self.robot
        q, _ = as_batch(q, "q", robot.nv)
        qd, _ = as_batch(qd, "qd", robot.nv)
        n = len(q)
        out = {}
        if base_wrench is not None:
            w, _ = as_batch(base_wrench, "base_wrench", 6)
            terms = [self._base_terms(q[k], qd[k], w[k]) for k in range(n)]
            out["base"] = self._sum_increments(np.stack([t[0] for t in terms]), np.stack([t[1] for t in terms]))
        if tau_J is not None:
            tau, _ = as_batch(tau_J, "tau_J", robot.nv)
            terms = [self._joint_terms(q[k], qd[k], tau[k]) for k in range(n)]
            d = self._sum_increments(np.stack([t[0] for t in terms]), np.stack([t[1] for t in terms]), cumulative=False)
            jv = robot._tip_jacobians(q)[:, :3, :]
            z = damped_force_from_joint_torques(jv, d, SINGULAR_REGION, MAX_DAMPING)
            out["joint"] = np.cumsum(z, axis=0)
        for name, y in out.items():
            if len(y) != n:
                raise InputError(f"{name} sensor has {len(y)} samples, q has {n}")
        return out

    def _sum_increments(self, momentum, u, cumulative=True):
        d = np.zeros_like(momentum)
        d[1:] = momentum[1:] - momentum[:-1] - (u[1:] + u[:-1]) * (0.5 * self.dt)
        return np.cumsum(d, axis=0) if cumulative else d

    def run(self, q, qd, base_wrench=None, tau_J=None) -> np.ndarray:
        """Tip forces (N, 3) [N] over a trajectory sampled every ``dt``, from a reset.

        The steady-state filter is linear and time-invariant: x_k = (I - K H) A x_k-1 + K y_k
        from x_-1 = 0 (y_0 = 0), run for each axis by ``SteadyStateKalman.filter``.
        """
        return self.filter_measurements(self.measurements(q, qd, base_wrench, tau_J))

    def filter_measurements(self, y: dict) -> np.ndarray:
        """``run`` on measurements already computed (``measurements``): the filter alone, so that
        filters of other noise settings can share one pass over the dynamics."""
        if not y:
            raise InputError("KalmanTipForce.run needs base_wrench, tau_J or both")
        subset = tuple(c for c in SENSORS if c in y)
        f = self.filters[subset]
        self.reset()
        Y = np.stack([y[c] for c in subset], axis=1)  # (N, sensors, 3)
        return np.stack([f.filter(Y[:, :, axis])[:, -1] for axis in range(3)], axis=1)


@njit(cache=True)
def _fusion_step(x, y, last_base, last_joint, has_last, gain_table, has_base, h, R3, w, mg3,
                 has_joint, qd, M_upper, g, C, tau, jac, dt, singular_region, max_damping):  # pragma: no cover
    """One predict-update of ``KalmanTipForce`` after the dynamics terms (see ``step_unchecked``).

    x (3, 3): s_base, s_joint, F by axis; y (2, 3): the sensors' unexplained momenta.
    The joint terms come as Pinocchio gives them: the mass matrix's upper triangle M_upper (what
    computeAllTerms fills), the gravity torque g and the Coriolis matrix C, so p = M qd and
    beta = C^T qd - g are formed here.
    A sensor with no previous sample re-anchors (y = its prediction, no update from it).
    The joint increment is projected to the tool by the damped least squares of
    ``tip_force.damped_force_single``, written out here in the same closed form.
    """
    for j in range(3):
        x[0, j] += dt * x[2, j]
        x[1, j] += dt * x[2, j]
    code = 0
    if has_base:
        u = np.empty(3)
        for i in range(3):
            acc = mg3[i]
            for k in range(6):
                acc += R3[i, k] * w[k]
            u[i] = acc
        if has_last[0]:
            for i in range(3):
                y[0, i] += h[i] - last_base[0, i] - (u[i] + last_base[1, i]) * (0.5 * dt)
            code += 1
        else:
            for i in range(3):
                y[0, i] = x[0, i]
        for i in range(3):
            last_base[0, i] = h[i]
            last_base[1, i] = u[i]
        has_last[0] = True
    else:
        has_last[0] = False
    if has_joint:
        nv = qd.shape[0]
        p = np.empty(nv)
        beta = np.empty(nv)
        for k in range(nv):
            acc = 0.0
            for i in range(nv):
                acc += (M_upper[k, i] if i >= k else M_upper[i, k]) * qd[i]
            p[k] = acc
            acc = -g[k]
            for i in range(nv):
                acc += qd[i] * C[i, k]
            beta[k] = acc
        if has_last[1]:
            d = np.empty(nv)
            for k in range(nv):
                d[k] = p[k] - last_joint[0, k] - (tau[k] + beta[k] + last_joint[1, k]) * (0.5 * dt)
            a = np.zeros((3, 3))
            bvec = np.zeros(3)
            for i in range(3):
                for k in range(nv):
                    bvec[i] += jac[i, k] * d[k]
                for j in range(3):
                    acc = 0.0
                    for k in range(nv):
                        acc += jac[i, k] * jac[j, k]
                    a[i, j] = acc
            z = _damped_solve3(a, bvec, singular_region, max_damping)
            for i in range(3):
                y[1, i] += z[i]
            code += 2
        else:
            for i in range(3):
                y[1, i] = x[1, i]
        for k in range(nv):
            last_joint[0, k] = p[k]
            last_joint[1, k] = tau[k] + beta[k]
        has_last[1] = True
    else:
        has_last[1] = False
    if code > 0:
        G = gain_table[code]
        inn0 = np.empty(3)
        inn1 = np.empty(3)
        for j in range(3):
            inn0[j] = y[0, j] - x[0, j]
            inn1[j] = y[1, j] - x[1, j]
        for r in range(3):
            for j in range(3):
                x[r, j] += G[r, 0] * inn0[j] + G[r, 1] * inn1[j]


@njit(cache=True)
def _damped_solve3(a, b, singular_region, max_damping):  # pragma: no cover (compiled)
    """``damped_force_single``'s damping law and adjugate solve for a = J_v J_v^T, b = J_v tau."""
    a00, a01, a02, a11, a12, a22 = a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2]
    det0 = a00 * (a11 * a22 - a12 * a12) - a01 * (a01 * a22 - a12 * a02) + a02 * (a01 * a12 - a11 * a02)
    tr = a00 + a11 + a22
    lam_min = np.inf
    if det0 < singular_region**2 * tr * tr:
        lam_min = np.linalg.eigvalsh(a)[0]
    if lam_min < singular_region**2:
        dmp = max_damping**2 * (1.0 - max(lam_min, 0.0) / singular_region**2)
        a00 += dmp
        a11 += dmp
        a22 += dmp
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    out = np.empty(3)
    out[0] = (c00 * b[0] + c01 * b[1] + c02 * b[2]) / det
    out[1] = (c01 * b[0] + c11 * b[1] + c12 * b[2]) / det
    out[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det
    return out
