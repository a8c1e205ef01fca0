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

Recomputed every ``CHECK_EVERY`` calls (a regressor and a Jacobian, ~10 us).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..analytic.tip_force import SINGULAR_REGION
from .calibration import OFF_TOOL_SIGMAS
from .consistency import CHECK_EVERY
from .torque_tare import pinv_jv_t

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
    kind: one of KINDS; inertial_sigma: relative 1-sigma of every link's inertials; payload_sigma [kg]."""

    def __init__(self, robot, kind: str, inertial_sigma: float, payload_sigma: float):
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, not {kind!r}")
        self.robot, self.kind = robot, kind
        self.inertial_sigma, self.payload_sigma = float(inertial_sigma), float(payload_sigma)
        self._data = robot.model.createData()
        self._data_j = robot.model.createData()
        model = robot.model
        self._tool_joint = model.frames[robot.tool_frame_id].parentJoint
        self._zero = np.zeros(robot.nv)
        self.sigma = np.zeros(3)
        self.off_tool_bound = 0.0  # [Nm]
        self.singular = False  # J_v singular at the last update: no finite sigma through the joint torques
        self.weak = False  # J_v's least singular value inside the damped solve's region at the last update
        self.reset()
        self.update(np.array(robot.spec.home, float), self._zero, self._zero)  # its first call's cost, now

    def reset(self) -> None:
        self._k = CHECK_EVERY - 1
        self._tared = None  # D_g at the torque tare's pose (nv, K) [Nm], once the tare absorbed it

    def tare(self, q) -> None:
        """The torque tare absorbed the offsets at pose q [rad] (None: it absorbed none): the gravity part of the
        error there went with them."""
        self._tared = None if q is None else self._torque_columns(q, self._zero, self._zero)

    def weight_sigma(self) -> float:
        """The 1-sigma of the arm's weight [N] by the stated uncertainty (the links' and the payload's): a base
        sensor's tare absorbs it with the sensor's offset (``CallStatus._judge``'s bound)."""
        masses = np.array([inertia.mass for inertia in self.robot.model.inertias[1:]])
        var = (self.inertial_sigma * masses) ** 2
        var = var.sum() + (self.inertial_sigma * masses.sum()) ** 2
        if self._payload_unit() is not None:
            var += self.payload_sigma ** 2
        return 9.81 * float(np.sqrt(var))

    def _payload_unit(self):
        """The payload's inertial parameters per kg (10,) in its joint's frame, or None without a payload."""
        payload = self.robot.payload
        if payload is None or payload.mass == 0 or self.payload_sigma == 0:
            return None
        frame = self.robot.model.frames[self.robot.tool_frame_id]
        com = frame.placement.act(np.asarray(payload.offset, float))
        return pin.Inertia(1.0, com, np.zeros((3, 3))).toDynamicParameters()

    def _torque_columns(self, q, qd, qdd) -> np.ndarray:
        """D (nv, K) [Nm]: each link's torques times its sigma, their sum (the common factor's), and the payload's
        per kg times its sigma."""
        model = self.robot.model
        y = pin.computeJointTorqueRegressor(model, self._data, q, qd, qdd).reshape(model.nv, model.njoints - 1, 10)
        theta = np.array([model.inertias[i].toDynamicParameters() for i in range(1, model.njoints)])
        own = self.inertial_sigma * np.einsum("jil,il->ji", y, theta)
        cols = [own, own.sum(axis=1, keepdims=True)]
        unit = self._payload_unit()
        if unit is not None:
            cols.append((self.payload_sigma * (y[:, self._tool_joint - 1] @ unit))[:, None])
        return np.hstack(cols)

    def _base_sigma(self, q, qd, qdd) -> np.ndarray:
        """The base methods' sigma (3,) [N]: each link's mass error times its centre of mass's acceleration."""
        model, data = self.robot.model, self._data
        pin.centerOfMass(model, data, q, qd, qdd, True)
        # the subtrees' (Pinocchio gives a subtree's in its joint's frame, the whole arm's, j = 0, in the world's)
        ma = np.array([data.mass[j] * (data.oMi[j].rotation @ data.acom[j]) for j in range(1, model.njoints)])
        own = ma - np.vstack([ma[1:], np.zeros((1, 3))])  # a chain: a link's own is its subtree's less the next one's
        var = np.vstack([(self.inertial_sigma * own) ** 2, (self.inertial_sigma * ma[0]) ** 2])  # and the common
        unit = self._payload_unit()
        if unit is not None:
            pin.updateFramePlacements(model, data)
            acc = pin.getFrameClassicalAcceleration(model, data, self.robot.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)
            var = np.vstack([var, (self.payload_sigma * acc.linear) ** 2])
        return np.sqrt(var.sum(axis=0))

    def _torque_sigma(self, q, qd, qdd) -> np.ndarray:
        """The joint-torque methods' sigma (3,) [N] (and the off-tool bound): D less the tare's, through pinv(J_v^T)."""
        d = self._torque_columns(q, qd, qdd)
        if self._tared is not None:
            k = min(d.shape[1], self._tared.shape[1])  # a payload declared since the tare: its column untared
            d[:, :k] -= self._tared[:, :k]
        jv, p = pinv_jv_t(self.robot, self._data_j, q)
        self.singular = not np.isfinite(p[0, 0])
        self.weak = self.singular or float(np.linalg.eigvalsh(jv @ jv.T)[0]) < SINGULAR_REGION ** 2
        if self.singular:
            self.off_tool_bound = np.inf
            return np.full(3, np.inf)
        pd = p @ d
        self.off_tool_bound = OFF_TOOL_SIGMAS * float(np.linalg.norm(d - jv.T @ pd))
        return np.sqrt((pd * pd).sum(axis=1))

    def update(self, q, qd, qdd) -> np.ndarray:
        """The model's 1-sigma error per axis (3,) [N] at this call (recomputed every CHECK_EVERY calls);
        qdd None: read as 0 (a method without the acceleration; its motion term carries the rest)."""
        self._k += 1
        if self._k < CHECK_EVERY:
            return self.sigma
        self._k = 0
        qdd = self._zero if qdd is None else qdd
        if self.kind == "base":
            self.sigma = self._base_sigma(q, qd, qdd)
        elif self.kind == "torques":
            self.sigma = self._torque_sigma(q, qd, qdd)
        else:
            self.sigma = np.maximum(self._base_sigma(q, qd, qdd), self._torque_sigma(q, qd, qdd))
        return self.sigma


__all__ = ["KINDS", "StatedModelError", "UNSTATED_INERTIAL_UNCERTAINTY", "inertial_uncertainty"]
