"""The error bar's model term where no calibration is given: what the description and the payload state.

A tip-force method subtracts the model's torques (or its base wrench) from the sensors', so the model's error
reads as a force at the tool. Without a calibration on the user's own log (``calibration.py``), the stated
uncertainty bounds it:

- **the links' inertials**: each link's ten inertial parameters theta_i are off by one factor (1 + e + e_i), e
  common to all links (a whole arm heavier or lighter than its description, the error that adds up) and the e_i
  independent, each with 1-sigma ``inertial_uncertainty`` (the description's ``inertial_uncertainty``, or the
  config's);
- **the payload's mass**: off by e_p [kg] with 1-sigma ``payload_uncertainty_kg``, where a payload is declared.

Both are linear in the parameters (tau = Y(q, qd, qdd) theta), so one call's error is D e with D's columns the
links' own torques Y_i theta_i times their sigma, and the payload's torque per kg Y_tool theta_unit times its
sigma. The methods read that error differently:

- **the joint torques** (``torques``): the torque tare (``torque_tare.py``) absorbed the gravity part at its
  window's pose q0 as offsets, so what is left is D(q, qd, qdd) - D_g(q0); it maps to the tool through
  pinv(J_v^T), so a pose near a singularity carries a large sigma on its weak direction (never a shrunk force
  at ``ok``), and its part outside range(J_v^T) widens the off-tool bound;
- **the base sensor** (``base``): its tare absorbed the weight's error (a force that does not depend on the pose),
  so what is left is each link's mass error times its centre of mass's acceleration, m_i a_i e_i;
- **both** (``fusion``, kalman-fusion): the filter's weights do not know these errors, so its estimate may carry
  either's: the larger sigma per axis.

Recomputed every ``CHECK_EVERY`` calls, in two halves on two calls (``StatedModelError.update``).
"""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numba import njit

from ..analytic.tip_force import SINGULAR_REGION, _min_eig_sym3, sym3_adjugate
from .calibration import OFF_TOOL_SIGMAS
from .consistency import CHECK_EVERY

KINDS = ("torques", "base", "fusion")
# The inertials' relative 1-sigma where the description states none: an arm nobody identified. On the real KUKA LWR
# and Baxter logs their descriptions' models leave 26-54 N of phantom force (reports/real): without a term the
# error bar said ok on them.
UNSTATED_INERTIAL_UNCERTAINTY = 0.10


def inertial_uncertainty(setting, spec) -> float:
    """The relative 1-sigma a setting ("auto" or a number) means for the robot ``spec`` describes."""
    if setting != "auto":
        return float(setting)
    stated = spec.inertial_uncertainty
    return UNSTATED_INERTIAL_UNCERTAINTY if stated is None else float(stated)


class StatedModelError:
    """One stream's stated model term (module docstring); the interface of ``calibration.ModelError``:
    ``update`` each call, ``sigma`` (3,) [N], ``off_tool_bound`` [Nm], ``reset``, and ``tare`` from the torque tare.
    kind: one of KINDS; inertial_sigma: relative 1-sigma of every link's inertials; payload_sigma [kg].

    One regressor of the arm on its free-flyer root (``Robot.model_ff``, the base held still) gives both the base
    wrench's rows and the joint torques' rows of D at once."""

    def __init__(self, robot, kind: str, inertial_sigma: float, payload_sigma: float):
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, not {kind!r}")
        self.robot, self.kind = robot, kind
        self.inertial_sigma, self.payload_sigma = float(inertial_sigma), float(payload_sigma)
        model = robot.model_ff
        self._data, self._data_j = model.createData(), robot.model.createData()
        self._qff, self._vff, self._aff = robot._qff.copy(), np.zeros(model.nv), np.zeros(model.nv)
        self._tool_block = model.frames[model.getFrameId(robot.spec.tool_frame)].parentJoint - 2  # after the root's
        self._zero = np.zeros(robot.nv)
        self._no_tare = np.zeros((robot.nv, 0))
        self._theta_for = None  # the arm's mass the cached parameters are of (a payload changes it)
        self.sigma = np.zeros(3)
        self.off_tool_bound = 0.0  # [Nm]
        self.singular = False  # J_v singular at the last update: no finite sigma through the joint torques
        self.weak = False  # J_v's least singular value inside the damped solve's region at the last update
        self.reset()
        self.refresh(np.array(robot.spec.home, float), self._zero, self._zero)  # its first call's cost, now

    def reset(self) -> None:
        # Its halves fall between the consistency checks' and the torque tare's (every CHECK_EVERY calls from the
        # first): no call of the control loop pays for all of them.
        self._k = CHECK_EVERY // 2 - 1
        self._tared = None  # D's joint-torque rows at the torque tare's pose, still (nv, K) [Nm], once it took them

    def tare(self, q) -> None:
        """The torque tare absorbed the offsets at pose q [rad] (None: it absorbed none): the gravity part of the
        error there went with them."""
        self._tared = None if q is None else self._columns(q, self._zero, self._zero)[6:].copy()

    def weight_sigma(self) -> float:
        """The 1-sigma of the arm's weight [N] by the stated uncertainty (the links' and the payload's): a base
        sensor's tare absorbs it with the sensor's offset (``CallStatus._judge``'s bound)."""
        self._parameters()
        return float(np.linalg.norm(self._weight, axis=1).max())

    def _parameters(self) -> None:
        """The links' inertial parameters theta (nv, 10), the payload's per kg (10,) or None, and the weight's
        columns (3, K) [N]: read again when a payload changed them (``set_payload``)."""
        robot = self.robot
        if self._theta_for == robot.total_mass:
            return
        model = robot.model_ff
        self._theta = np.array([model.inertias[i].toDynamicParameters() for i in range(2, model.njoints)])
        payload, self._unit = robot.payload, None
        if payload is not None and payload.mass != 0 and self.payload_sigma != 0:
            com = model.frames[model.getFrameId(robot.spec.tool_frame)].placement.act(np.asarray(payload.offset, float))
            self._unit = pin.Inertia(1.0, com, np.zeros((3, 3))).toDynamicParameters()
        self._theta_for = robot.total_mass  # (set first: _columns reads the parameters back through here)
        self._weight = self._columns(np.array(robot.spec.home, float), self._zero, self._zero)[:3].copy()

    def _columns(self, q, qd, qdd) -> np.ndarray:
        """D (6 + nv, K): rows the base wrench [N, Nm] and the joint torques [Nm]; columns each link's part times
        its sigma, their sum (the common factor's), and the payload's per kg times its sigma."""
        self._parameters()
        model, nv = self.robot.model_ff, self.robot.nv
        self._qff[7:], self._vff[6:], self._aff[6:] = q, qd, qdd
        y = pin.computeJointTorqueRegressor(model, self._data, self._qff, self._vff, self._aff)
        y = y.reshape(6 + nv, model.njoints - 1, 10)[:, 1:]  # the root body's own block: still, no error to carry
        own = self.inertial_sigma * np.einsum("rjl,jl->rj", y, self._theta)
        cols = [own, own.sum(axis=1, keepdims=True)]
        if self._unit is not None:
            cols.append((self.payload_sigma * (y[:, self._tool_block] @ self._unit))[:, None])
        return np.hstack(cols)

    def _torque_sigma(self, d) -> np.ndarray:
        """The joint-torque methods' sigma (3,) [N] (and the off-tool bound) from D's joint-torque rows d less the
        tare's, through pinv(J_v^T) (``_torque_map``, compiled: this runs in a control cycle)."""
        robot = self.robot  # J_v at the pose the columns are of (``_columns`` left it in _qff)
        jv = pin.computeFrameJacobian(robot.model, self._data_j, self._qff[7:], robot.tool_frame_id,
                                      pin.LOCAL_WORLD_ALIGNED)[:3]
        tared = self._no_tare if self._tared is None else self._tared
        sigma = np.empty(3)
        # (a payload declared since the tare: its column untared)
        bound, least = _torque_map(np.ascontiguousarray(jv), d, tared, min(d.shape[1], tared.shape[1]), sigma)
        self.singular = not np.isfinite(bound)
        self.weak = self.singular or least < SINGULAR_REGION ** 2
        self.off_tool_bound = OFF_TOOL_SIGMAS * bound
        return sigma

    def _base_sigma(self, d) -> np.ndarray:
        """The base methods' sigma (3,) [N] from D's base-force rows d less the weight's (the tare took it): each
        link's mass error times its centre of mass's acceleration."""
        k = min(d.shape[1], self._weight.shape[1])
        d = d.copy()
        d[:, :k] -= self._weight[:, :k]
        return np.sqrt((d * d).sum(axis=1))

    def update(self, q, qd, qdd) -> np.ndarray:
        """The model's 1-sigma error per axis (3,) [N] at this call; qdd None: read as 0 (a method without the
        acceleration; its motion term carries the rest). Recomputed every CHECK_EVERY calls, in two halves on
        two calls (the regressor's columns at one call's state, then their map), so that no control cycle pays
        for both: the sigma is of the state one call (1 ms) before."""
        self._k += 1
        if self._k == CHECK_EVERY - 1:
            self._d = self._columns(q, qd, self._zero if qdd is None else qdd)
        elif self._k >= CHECK_EVERY:
            self._k = 0
            self._map()
        return self.sigma

    def refresh(self, q, qd, qdd) -> np.ndarray:
        """The sigma (3,) [N] at this state, both halves at once (a new state, a test)."""
        self._d = self._columns(q, qd, self._zero if qdd is None else qdd)
        self._map()
        return self.sigma

    def _map(self) -> None:
        """The second half: the columns of the first through what each kind of method reads."""
        d = self._d
        if self.kind == "base":
            self.sigma = self._base_sigma(d[:3])
        elif self.kind == "torques":
            self.sigma = self._torque_sigma(d[6:])
        else:
            self.sigma = np.maximum(self._base_sigma(d[:3]), self._torque_sigma(d[6:]))


@njit(cache=True)
def _torque_map(jv, d, tared, k, sigma):  # pragma: no cover (compiled)
    """sigma (3,) [N] = the row norms of P (d - tared) with P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v, tared's first k
    columns subtracted; returns (|(I - J_v^T P)(d - tared)|_F [Nm], the least eigenvalue of J_v J_v^T); inf
    sigma and bound where J_v J_v^T is singular."""
    nv, ncol = d.shape
    a = jv @ jv.T
    a00, a01, a02, a11, a12, a22 = a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2]
    least = _min_eig_sym3(a00, a01, a02, a11, a12, a22)
    c00, c01, c02, c11, c12, c22, det = sym3_adjugate(a00, a01, a02, a11, a12, a22)
    if not abs(det) > 1e-18:
        sigma[:] = np.inf
        return np.inf, least
    inv = np.empty((3, 3))  # (a LAPACK solve here tripled the estimator's construction with an empty numba cache)
    inv[0, 0], inv[0, 1], inv[0, 2] = c00, c01, c02
    inv[1, 0], inv[1, 1], inv[1, 2] = c01, c11, c12
    inv[2, 0], inv[2, 1], inv[2, 2] = c02, c12, c22
    p = (inv / det) @ jv
    e = d.copy()
    for j in range(nv):
        for c in range(k):
            e[j, c] -= tared[j, c]
    pe = p @ e
    for i in range(3):
        acc = 0.0
        for c in range(ncol):
            acc += pe[i, c] * pe[i, c]
        sigma[i] = math.sqrt(acc)
    r = e - jv.T @ pe
    acc = 0.0
    for j in range(nv):
        for c in range(ncol):
            acc += r[j, c] * r[j, c]
    return math.sqrt(acc), least


__all__ = ["KINDS", "StatedModelError", "UNSTATED_INERTIAL_UNCERTAINTY", "inertial_uncertainty"]
