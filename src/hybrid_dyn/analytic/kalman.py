"""A Kalman filter that fuses the base sensor and the joint torques into one tip force.

The detail (what it computes, the equations, why each choice): docs/design/analytic.md, section ``analytic/kalman.py``.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
import pinocchio as pin
from scipy.linalg import solve_discrete_are

from .bandwidth import contact_rate, kalman_settle_calls, random_walk_gain
from .base_momentum import BaseMomentumObserver
from .kalman_kernels import _fusion_step, _kf_run
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
    second); it sets the filter's bandwidth. None (the default): the bandwidth
    rule's value (:func:`rule_force_rate`: the contact model of ``bandwidth.py``). base_model / joint_model [N]: a
    model error per axis, as a force, added to that sensor's noise (how far the
    model behind the sensor can be trusted; 0 = exact).
    """

    base_force: float = 0.2
    joint_torque: float = 0.05
    joint_velocity: float = 5e-4
    force_rate: float | None = None
    base_model: float = 0.0
    joint_model: float = 0.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if value is None and name == "force_rate":
                continue
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


def channel_factors(robot: Robot) -> tuple[float, float, float]:
    """The pose factors of the channel covariances at the home pose (the isotropic mean over axes):
    (m^2 tr(J_com J_com^T) / 3 [kg^2 m^2], tr((J_v J_v^T)^-1) / 3 [1/m^2], tr(P M M P^T) / 3 [kg^2 m^2])
    with P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v. Computed once per filter, when it is built."""
    q0 = np.array(robot.spec.home, float)
    data = robot.model.createData()
    m = robot.total_mass
    jcom = pin.jacobianCenterOfMass(robot.model, data, q0)  # the fixed model holds link 0 in the universe
    jv = pin.computeFrameJacobian(robot.model, data, q0, robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    M = robot.mass_matrix(q0)
    jjt_inv = np.linalg.inv(jv @ jv.T)
    P = jjt_inv @ jv
    return (float(m**2 * np.trace(jcom @ jcom.T) / 3.0), float(np.trace(jjt_inv) / 3.0),
            float(np.trace(P @ M @ M @ P.T) / 3.0))


def _covariances(factors, dt: float, noise: FusionNoise) -> dict:
    """``channel_covariances`` from precomputed pose factors (arithmetic only)."""
    f_base, f_jjt, f_pm = factors
    sq = noise.joint_velocity**2
    return {"base": (dt**2 * (noise.base_force**2 + noise.base_model**2), sq * f_base),
            "joint": (dt**2 * (noise.joint_torque**2 * f_jjt + noise.joint_model**2), sq * f_pm)}


def channel_covariances(robot: Robot, dt: float, noise: FusionNoise) -> dict:
    """Per sensor (process variance q, measurement variance r) [N^2 s^2] from the specifications.

    At the home pose, averaged over the three axes:
    base   q = dt^2 (base_force^2 + base_model^2),  r = sigma_qd^2 tr(m^2 J_com J_com^T) / 3;
    joint  q = dt^2 (sigma_tau^2 tr((J_v J_v^T)^-1) / 3 + joint_model^2),
           r = sigma_qd^2 tr(P M M P^T) / 3 with P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v.
    """
    return _covariances(channel_factors(robot), dt, noise)


def increment_stats(increments: dict) -> np.ndarray:
    """The sums the streaming filter keeps of each sensor's unexplained-momentum increments [N s],
    {"base" | "joint": (n, 3)} (consecutive samples): rows base, joint; columns sum d (3), sum d^2 (3),
    count, samples spanned (``KalmanTipForce.stats``)."""
    stats = np.zeros((2, 8))
    for row, name in enumerate(SENSORS):
        if name in increments:
            d = np.asarray(increments[name], float)
            stats[row] = np.r_[d.sum(axis=0), (d**2).sum(axis=0), len(d), len(d)]
    return stats


def noise_from_stats(factors, dt: float, stats: np.ndarray, noise: FusionNoise,
                     base_shift: np.ndarray | None = None) -> FusionNoise:
    """``noise`` with each sensor's model error from its increment sums (``increment_stats``).

    With F = 0, the increments d / dt [N] are the sensor's noise alone; their mean square per axis
    beyond what the noise predicts, (q + 2 r) / dt^2, is the model error [N]. base_shift (3,) [N s]:
    what the base sensor's tare adds to each of its increments per sample spanned (R o dt): the sums
    were taken on the raw wrench, and the shift enters them exactly (d + c m)^2 / m = d^2 / m + 2 c d + c^2 m.
    A sensor with fewer than 2 increments keeps its model error.
    """
    cov = _covariances(factors, dt, noise)
    errors = {}
    for row, name in enumerate(SENSORS):
        s_d, s_d2, n, steps = stats[row, :3], stats[row, 3:6], stats[row, 6], stats[row, 7]
        if n < 2:
            continue
        if name == "base" and base_shift is not None:
            s_d2 = s_d2 + 2.0 * base_shift * s_d + base_shift**2 * steps
        measured = float(np.mean(s_d2)) / n / dt**2
        q_c, r_c = cov[name]
        predicted = (q_c + 2.0 * r_c) / dt**2
        errors[f"{name}_model"] = math.sqrt(max(0.0, measured - predicted) + getattr(noise, f"{name}_model") ** 2)
    return replace(noise, **errors)


def noise_from_increments(robot: Robot, dt: float, increments: dict, noise: FusionNoise | None = None) -> FusionNoise:
    """``noise`` with its model errors from the sensors' unexplained-momentum increments [N s] on a
    contact-free window, {"base" | "joint": (n, 3)}."""
    for name, inc in increments.items():
        if len(inc) < 2:
            raise InputError(f"the tare window needs at least 3 samples, got {len(inc) + 1}")
    return noise_from_stats(channel_factors(robot), dt, increment_stats(increments), noise or FusionNoise())


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


def window_fusion_noise(robot: Robot, dt: float, window, stats: np.ndarray, base_shift=None,
                        factors=None) -> FusionNoise:
    """The fusion filter's noise from a window (``bandwidth.WindowNoise`` and the increment sums):
    the sensors' noise as measured, their model errors from the increments, and the force rate by the
    bandwidth rule (:func:`rule_force_rate`). The one definition the estimator and the bench share."""
    factors = factors or channel_factors(robot)
    floor = 1e-6  # a noise-free window (an exact simulation) still needs a positive variance
    spec = FusionNoise(
        base_force=max(floor, window.base_force if window.base_force is not None else FusionNoise.base_force),
        joint_torque=max(floor, window.joint_torque_rms if window.joint_torque is not None else FusionNoise.joint_torque),
        joint_velocity=max(floor, float(np.sqrt(np.mean(window.qd**2)))))
    noise = noise_from_stats(factors, dt, stats, spec, base_shift)
    return replace(noise, force_rate=rule_force_rate(dt))


def rule_force_rate(dt: float) -> float:
    """The bandwidth rule's force rate [N/sqrt(s)] at sample time dt [s]: the contact model's
    (``bandwidth.contact_rate``). The minimum of noise^2 + lag^2 for a random-walk force is the Kalman
    filter of that random walk, so the rule sets the force rate to the model's and the filter's gain
    follows from the measured noise."""
    return contact_rate(dt)


MAX_BRIDGE_CALLS = 5  # a sensor absent for up to this many calls is bridged; longer, it has left


class KalmanTipForce:
    """Streaming tip-force estimate [N] fusing the base sensor and the joint torques.

    dt: sample time [s]. Inputs per call: q [rad], qd [rad/s] (nv,);
    base_wrench [N, Nm] (6,) in the base-sensor frame, tared (``analytic/tare.py``),
    or None; tau_J link-side joint torques [Nm] (nv,), or None.

    The filter is the time-varying one: its covariance P is propagated every call
    (a few 3 x 3 operations, compiled), so it needs no Riccati solution, settles to
    the steady-state filter, and treats an absent sensor exactly (predicted, not
    updated). A sensor absent for up to MAX_BRIDGE_CALLS calls (one call of two,
    alternating) is bridged: its next increment spans the gap (the trapezoid over
    it); absent longer, it has left and re-anchors when it returns.
    """

    def __init__(self, robot: Robot, dt: float = 1e-3, noise: FusionNoise | None = None):
        if not dt > 0:
            raise InputError(f"dt must be positive [s], got {dt}")
        self.robot = robot
        self.dt = float(dt)
        self._factors = channel_factors(robot)
        self._base = BaseMomentumObserver(robot, dt=self.dt)    # h(q, qd) and the weight
        self._joint = MomentumObserver(robot, dt=self.dt)       # p = M qd and beta = C^T qd - g
        # With the joint torques, two passes give every term: computeAllTerms (M, g and, for the base
        # sensor, the momentum m v_com as its centroidal hg), and computeCoriolisMatrix (C, and the joint
        # Jacobians the tip Jacobian is read from), instead of five separate passes.
        self._all_data = robot.model.createData()
        self._coriolis_data = robot.model.createData()
        self._R3 = np.ascontiguousarray(robot._root_from_sensor[:3])
        self._mg3 = robot.total_mass * np.asarray(robot.model_ff.gravity.linear, float)
        self._zero3, self._zero6, self._zero_nv = np.zeros(3), np.zeros(6), np.zeros(robot.nv)
        self._zero_jac = np.zeros((6, robot.nv))
        self._zero_c = np.zeros((robot.nv, robot.nv))
        self.stats = np.zeros((2, 8))  # the increment sums (``increment_stats``), kept since the last reset
        self.configure(noise or FusionNoise())
        # Compile (or load from numba's cache) now, not in the first control cycle: one call on copies.
        _fusion_step(self.state.copy(), self.P.copy(), self._y.copy(), self._last_base.copy(),
                     self._last_joint.copy(), self._since.copy(), self.stats.copy(), self._qv, self._rv,
                     MAX_BRIDGE_CALLS, True, self._zero3, self._R3, self._zero6, self._mg3, True, self._zero_nv,
                     self._zero_c, self._zero_nv, self._zero_c, self._zero_nv, self._zero_jac, self.dt,
                     SINGULAR_REGION, MAX_DAMPING)
        _kf_run(np.zeros((1, 2, 3)), np.ones(2, np.bool_), self._P0(), self._qv, self._rv, self.dt)
        # ...and with the arrays Pinocchio hands the step (their memory layouts pick numba's specialization),
        # for every sensor subset: none is compiled (or loaded from the cache, ~10 ms) in a control call.
        home, zero = np.array(robot.spec.home, float), np.zeros(robot.nv)
        for w, tau in ((np.zeros(6), zero), (np.zeros(6), None), (None, zero)):
            self.step_unchecked(home, zero, w, tau)
        self.reset()

    def model_changed(self) -> None:
        """The robot's model changed in place (``Robot.set_payload``): the weight m g [N] anew; the filter's
        state and its tuning (the pose factors, a design choice) stay."""
        self._mg3[:] = self.robot.total_mass * np.asarray(self.robot.model_ff.gravity.linear, float)
        self._base.model_changed()

    def configure(self, noise: FusionNoise) -> None:
        """Use these noise intensities (arithmetic only: no design) and start afresh (``reset``)."""
        if noise.force_rate is None:
            noise = replace(noise, force_rate=rule_force_rate(self.dt))
        self.noise = noise
        cov = _covariances(self._factors, self.dt, noise)
        self._qv = np.array([cov["base"][0], cov["joint"][0], noise.force_rate**2 * self.dt])
        self._rv = np.array([max(cov["base"][1], 1e-300), max(cov["joint"][1], 1e-300)])
        # The force gain each sensor subset settles to (random-walk filter through the subset's
        # combined increment noise): the settling times of ``settle_calls``.
        s_e2 = {c: (cov[c][0] + 2.0 * cov[c][1]) / self.dt**2 for c in SENSORS}
        self.gains = {}
        for subset in (("base",), ("joint",), ("base", "joint")):
            combined = 1.0 / sum(1.0 / max(s_e2[c], 1e-300) for c in subset)
            self.gains[subset] = random_walk_gain(noise.force_rate, self.dt, combined)
        self.reset()

    def settle_calls(self, subset=SENSORS) -> int:
        """Calls until a start's transient has decayed below 1 % with the sensors ``subset``."""
        return kalman_settle_calls(self.gains[tuple(c for c in SENSORS if c in subset)])

    def _P0(self) -> np.ndarray:
        """The covariance at a start: each sensor anchors at its first sample; the force is unknown
        (a prior of (max 100 N)^2: the first increments decide it)."""
        return np.diag([self._rv[0], self._rv[1], 100.0**2])

    def reset(self) -> None:
        """Forget the history: F = 0 and both sensors re-anchor at their next sample."""
        self.state = np.zeros((3, 3))  # rows: s_base, s_joint, F; columns: x, y, z
        self.P = self._P0()
        self._y = np.zeros((2, 3))
        self._last_base = np.zeros((2, 3))  # the compiled step's copy: h, u of the previous sample
        self._last_joint = np.zeros((2, self.robot.nv))  # p, tau + beta of the previous sample
        self._since = np.full(2, -1, dtype=np.int64)  # calls each sensor has been absent (-1: never seen)
        self.stats[:] = 0.0

    @property
    def force(self) -> np.ndarray:
        return self.state[2].copy()

    @property
    def sums(self) -> np.ndarray:
        """The sensors' unexplained momenta y (2, 3) [N s] (rows: base, joint)."""
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
        _fusion_step(self.state, self.P, self._y, self._last_base, self._last_joint, self._since, self.stats,
                     self._qv, self._rv, MAX_BRIDGE_CALLS, has_base, h, self._R3, w, self._mg3, has_joint, qd,
                     M_upper, g, C, tau, jv, self.dt, SINGULAR_REGION, MAX_DAMPING)
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
        """Tip forces (N, 3) [N] over a trajectory sampled every ``dt``, from a reset (every sample
        brings the sensors given)."""
        return self.filter_measurements(self.measurements(q, qd, base_wrench, tau_J))

    def filter_measurements(self, y: dict) -> np.ndarray:
        """``run`` on measurements already computed (``measurements``): the filter alone, so that
        filters of other noise settings can share one pass over the dynamics."""
        if not y:
            raise InputError("KalmanTipForce.run needs base_wrench, tau_J or both")
        n = len(next(iter(y.values())))
        Y = np.zeros((n, 2, 3))
        present = np.zeros(2, np.bool_)
        for row, c in enumerate(SENSORS):
            if c in y:
                Y[:, row] = y[c]
                present[row] = True
        self.reset()
        return _kf_run(Y, present, self._P0(), self._qv, self._rv, self.dt)
