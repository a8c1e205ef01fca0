"""Base momentum observer: the tip force from Newton's law for the whole robot, no joint acceleration.

The detail (what it computes, the equations, why each choice): docs/design/analytic.md, section ``analytic/base_momentum.py``.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin
from numba import njit

from .robot import InputError, Robot, as_batch


def wrench_to_tip_force(p: np.ndarray, w_ext: np.ndarray, moment_weight: float = 0.0) -> np.ndarray:
    """Pure tool-point force F [N] explaining an external wrench [F; p x F] ~ w_ext, (N, 3) or (3,).

    Minimises |f - F|^2 + w^2 |m - p x F|^2 with w = moment_weight [1/m]. With
    A = [I; w [p]x], A^T A = (1 + w^2 |p|^2) I - w^2 p p^T has the inverse
    (I + w^2 p p^T) / (1 + w^2 |p|^2), and A^T [f; w m] = f - w^2 p x m.
    w = 1 is ``tip_force.force_from_external_wrench`` (equal weights); w = 0 the force rows.
    """
    f, m = w_ext[..., :3], w_ext[..., 3:]
    if moment_weight == 0.0:
        return f.copy()
    w2 = moment_weight * moment_weight
    b = f - w2 * np.cross(p, m)
    pb = np.sum(p * b, axis=-1, keepdims=True)
    return (b + w2 * p * pb) / (1.0 + w2 * np.sum(p * p, axis=-1, keepdims=True))


class BaseMomentumObserver:
    """Streaming observer of the external wrench from the base sensor and q, qd (no qdd).

    gain: K [1/s] (scalar). dt: sample time [s]. moment_weight: see
    :func:`wrench_to_tip_force` [1/m]; 0 uses the force rows only.
    Inputs: q [rad], qd [rad/s] (nv,), base_wrench [N, Nm] (6,) in the base-sensor
    frame, tared.
    """

    def __init__(self, robot: Robot, gain: float = 20.0, dt: float = 1e-3, moment_weight: float = 0.0):
        if dt <= 0:
            raise InputError(f"dt must be positive [s], got {dt}")
        if not gain > 0:
            raise InputError(f"gain must be positive [1/s], got {gain}")
        if not moment_weight >= 0:
            raise InputError(f"moment_weight must be >= 0 [1/m], got {moment_weight}")
        self.robot = robot
        self.gain = float(gain)
        self.dt = float(dt)
        self.moment_weight = float(moment_weight)
        self._data = robot.model_ff.createData()
        self._qff = robot._qff.copy()
        self._vff = np.zeros(robot.model_ff.nv)
        self._mg_list = (robot.total_mass * robot.model_ff.gravity.linear).tolist()  # weight [N], root axes
        self._mg = np.array(self._mg_list)
        self._R = np.ascontiguousarray(robot._root_from_sensor)  # sensor -> root wrench map (6, 6)
        self._state = np.zeros((4, 6))  # the compiled step's rows: H(0), integral, last u, wrench
        self._started = np.zeros(1, dtype=np.bool_)
        self.reset()
        # Compile (or load from numba's cache) now, not in the first control cycle.
        _observer_step(self._state.copy(), self._started.copy(), np.zeros(6), np.zeros(3), self._mg,
                       self._R, np.zeros(6), self.gain, self.dt)

    def model_changed(self) -> None:
        """The robot's model changed in place (``Robot.set_payload``): the weight m g [N] anew; the history stays."""
        self._mg[:] = self.robot.total_mass * self.robot.model_ff.gravity.linear
        self._mg_list = self._mg.tolist()

    def reset(self) -> None:
        """Forget the history; the next step re-initialises H(0)."""
        self._state[:] = 0.0
        self._started[0] = False
        self.wrench = np.zeros(6)

    # ------------------------------------------------------------- physics
    def momentum_and_gravity(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H = [h; L_O] [N s, N m s], W_grav = [m g; c x m g] [N, Nm]) at one validated sample, root axes."""
        self._qff[7:] = q
        self._vff[6:] = qd
        hg = pin.computeCentroidalMomentum(self.robot.model_ff, self._data, self._qff, self._vff)
        # Python floats: np.cross costs far more than the dynamics at this size.
        cx, cy, cz = self._data.com[0].tolist()
        hx, hy, hz = hg.linear.tolist()
        lx, ly, lz = hg.angular.tolist()
        gx, gy, gz = self._mg_list
        H = np.array([hx, hy, hz, lx + cy * hz - cz * hy, ly + cz * hx - cx * hz, lz + cx * hy - cy * hx])
        w_grav = np.array([gx, gy, gz, cy * gz - cz * gy, cz * gx - cx * gz, cx * gy - cy * gx])
        return H, w_grav

    def momentum_rate(self, q, qd, qdd) -> np.ndarray:
        """dH/dt [N, Nm] (6,) at one sample, from the acceleration: the quantity the observer
        reconstructs without it (used to verify (1), not by the observer)."""
        q, qd, qdd = (self.robot._single(x, n) for x, n in ((q, "q"), (qd, "qd"), (qdd, "qdd")))
        self._qff[7:] = q
        self._vff[6:] = qd
        aff = np.zeros_like(self._vff)
        aff[6:] = qdd
        dhg = pin.computeCentroidalMomentumTimeVariation(self.robot.model_ff, self._data, self._qff, self._vff, aff)
        c = self._data.com[0]
        # d/dt (L_com + c x h) = dL_com + c_dot x h + c x h_dot, and c_dot x h = 0 (h = m c_dot).
        return np.concatenate([dhg.linear, dhg.angular + np.cross(c, dhg.linear)])

    # ------------------------------------------------------------ streaming
    def step(self, q, qd, base_wrench) -> np.ndarray:
        """Advance one sample; returns the external wrench estimate r [N, Nm] (6,), root axes."""
        q = self.robot._single(q, "q")
        qd = self.robot._single(qd, "qd")
        w = np.asarray(base_wrench, dtype=float)
        if w.shape != (6,) or not np.isfinite(w.dot(w)):
            raise InputError(f"base_wrench must be 6 finite values [N, Nm], got {w!r}")
        return self.step_unchecked(q, qd, w)

    def step_unchecked(self, q: np.ndarray, qd: np.ndarray, base_wrench: np.ndarray) -> np.ndarray:
        """``step`` for inputs already validated as finite float arrays.

        Pinocchio gives the centroidal momentum; the rest (H about O, the weight's
        wrench, the trapezoid and the observer update) is one compiled kernel, the
        same arithmetic as ``run`` (tested: streaming equals batch to 1e-9).
        """
        self._qff[7:] = q
        self._vff[6:] = qd
        hg = pin.computeCentroidalMomentum(self.robot.model_ff, self._data, self._qff, self._vff)
        # hg.vector: [h; L_com] in one conversion (each attribute of a Pinocchio object costs ~0.5 us).
        _observer_step(self._state, self._started, hg.vector, self._data.com[0], self._mg, self._R,
                       base_wrench, self.gain, self.dt)
        self.wrench = self._state[3].copy()  # a fresh array: safe to hand out
        return self.wrench

    def force(self, q, wrench: np.ndarray | None = None) -> np.ndarray:
        """Tip force [N] (3,) from the wrench estimate (the last one by default)."""
        r = self.wrench if wrench is None else wrench
        if self.moment_weight == 0.0:
            return r[:3].copy()
        return wrench_to_tip_force(self.robot.tip_position_single(q), r, self.moment_weight)

    def step_force(self, q, qd, base_wrench) -> np.ndarray:
        """One step, returning the tip force estimate [N] (3,)."""
        r = self.step(q, qd, base_wrench)
        return self.force(q, r)

    # ---------------------------------------------------------------- batch
    def run(self, q, qd, base_wrench) -> tuple[np.ndarray, np.ndarray]:
        """Over a trajectory sampled every ``dt``: (tip forces (N, 3) [N], wrenches (N, 6) [N, Nm]).

        The same recursion as ``step`` from a reset, written as a linear filter:
        with a_k = H_k - H_0 - sum of trapezoids of u and S_k = r_0 + ... + r_k,
        r_k = K (a_k - dt S_{k-1}), i.e. S_k = (1 - K dt) S_{k-1} + K a_k.
        The first 5/K seconds are the filter's transient.
        """
        from scipy.signal import lfilter

        robot = self.robot
        q, _ = as_batch(q, "q", robot.nv)
        qd, _ = as_batch(qd, "qd", robot.nv)
        w, _ = as_batch(base_wrench, "base_wrench", 6)
        if not (len(q) == len(qd) == len(w)):
            raise InputError(f"q, qd, base_wrench have different lengths: {len(q)}, {len(qd)}, {len(w)}")
        self.reset()
        Hg = [self.momentum_and_gravity(q[k], qd[k]) for k in range(len(q))]
        H = np.stack([x[0] for x in Hg])
        u = robot.base_wrench_to_root(w) + np.stack([x[1] for x in Hg])
        trap = np.zeros_like(u)
        trap[1:] = np.cumsum((u[1:] + u[:-1]) * (0.5 * self.dt), axis=0)
        a = H - H[0] - trap
        K = self.gain
        S = lfilter([K], [1.0, -(1.0 - K * self.dt)], a, axis=0)
        r = np.diff(S, axis=0, prepend=0.0)
        if self.moment_weight == 0.0:
            f = r[:, :3].copy()
        else:
            f = wrench_to_tip_force(robot._tip_positions(q), r, self.moment_weight)
        return f, r


@njit(cache=True)
def momentum_and_weight(hg, c, mg):  # pragma: no cover (compiled)
    """About the root origin: the momentum H = [h; L_com + c x h] from Pinocchio's centroidal hg = [h; L_com],
    and the weight's wrench W_grav = [m g; c x m g]; c the centre of mass [m], mg the weight [N]."""
    H = np.empty(6)
    grav = np.empty(6)
    H[0], H[1], H[2] = hg[0], hg[1], hg[2]
    H[3] = hg[3] + c[1] * hg[2] - c[2] * hg[1]
    H[4] = hg[4] + c[2] * hg[0] - c[0] * hg[2]
    H[5] = hg[5] + c[0] * hg[1] - c[1] * hg[0]
    grav[0], grav[1], grav[2] = mg[0], mg[1], mg[2]
    grav[3] = c[1] * mg[2] - c[2] * mg[1]
    grav[4] = c[2] * mg[0] - c[0] * mg[2]
    grav[5] = c[0] * mg[1] - c[1] * mg[0]
    return H, grav


@njit(cache=True)
def _observer_step(state, started, hg, c, mg, R, w, gain, dt):  # pragma: no cover (compiled)
    """One observer update (``BaseMomentumObserver.step_unchecked``). state rows: H(0), the integral,
    the last u = R w + W_grav, the wrench estimate r; hg = [h; L_com] (Pinocchio's centroidal momentum),
    H = [h; L_com + c x h], W_grav = [m g; c x m g]."""
    u = np.empty(6)
    H, grav = momentum_and_weight(hg, c, mg)
    for i in range(6):
        acc = grav[i]
        for k in range(6):
            acc += R[i, k] * w[k]
        u[i] = acc
    if not started[0]:
        for i in range(6):
            state[0, i] = H[i]
            state[2, i] = u[i]
        started[0] = True
        return
    for i in range(6):
        state[1, i] += (u[i] + state[2, i]) * (0.5 * dt) + state[3, i] * dt
        state[2, i] = u[i]
        state[3, i] = gain * (H[i] - state[0, i] - state[1, i])
