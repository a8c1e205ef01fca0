"""The analytic robot model: Pinocchio dynamics, batched over samples.

Conventions (PROTOCOL 1):
- Joint arrays have shape (N, nv); a single sample of shape (nv,) works too and
  returns arrays without the leading axis.
- The *base frame* is the URDF root link (``panda_link0`` for the Panda): tip
  positions, Jacobians and tip forces are expressed there.
- The *base wrench* is the wrench the ground exerts on the robot, link 0's own
  weight included, ``[fx, fy, fz, mx, my, mz]`` [N, Nm], in the base-sensor frame
  with the moment taken about that frame's origin.
- A *tip force* is the force the environment exerts on the robot at the tool
  point [N], in the base frame. With it, tau = ID(q, qd, qdd) - J_v^T F.
"""
from __future__ import annotations

import copy
import math
import os
import sys
import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..description import (Payload, RobotDescriptionError, RobotSpec, RobotVariant, as_payload, build_urdf,
                           resolve_robot, urdf_with_payload)
from ..errors import HybridDynError


class InputError(HybridDynError, ValueError):
    """An input array has the wrong shape or holds NaN/inf."""


class JointLimitWarning(UserWarning):
    """q lies outside the URDF joint limits (measured data may do so slightly)."""


def as_batch(x, name: str, width: int) -> tuple[np.ndarray, bool]:
    """(N, width) float64 view of ``x`` and whether the input was a single sample.

    Raises InputError naming ``name`` for a wrong width or non-finite values.
    """
    a = np.asarray(x, dtype=float)
    single = a.ndim == 1
    if single:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != width:
        raise InputError(f"{name} must have shape (N, {width}) or ({width},), got {np.shape(x)}")
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise InputError(f"{name} holds NaN or inf (first at sample {bad[0]}, column {bad[1]})")
    return a, single


def skew(v: np.ndarray) -> np.ndarray:
    """Batched cross-product matrices: (..., 3) -> (..., 3, 3), skew(a) @ b = a x b."""
    z = np.zeros_like(v[..., 0])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


@dataclass(frozen=True)
class SensorMount:
    """Where the base sensor really sits relative to its nominal frame.

    translation [m] and rotation as a rotation vector [rad], both in the nominal
    sensor frame. Zero for a perfectly mounted sensor.
    """

    translation: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = (0.0, 0.0, 0.0)

    def se3(self) -> pin.SE3:
        return pin.SE3(pin.exp3(np.asarray(self.rotation, float)), np.asarray(self.translation, float))


class Robot:
    """A fixed-base arm with a tool frame and a base force/torque sensor.

    Build one with :func:`load_robot`. Holds two Pinocchio models of the same
    URDF: a fixed-base one for joint-space dynamics and one whose root is a
    free-flyer held still, whose RNEA base rows are exactly the ground reaction
    wrench. Both run batched through ``rneaInParallel``.
    """

    def __init__(self, spec: RobotSpec, urdf_xml: str, params_name: str | None = None,
                 payload: Payload | None = None, sensor_mount: SensorMount | None = None,
                 num_threads: int | None = None, name: str | None = None):
        self.spec = spec
        # The robot's identity, its variant included ("panda[tool=none]"): what datasets,
        # model files and caches key on. base_name is the description's ("panda").
        self.name = name or spec.name
        self.base_name = spec.name
        self.variant = RobotVariant(spec.tool, payload)
        self._urdf_xml = urdf_xml  # None after set_payload until read (``urdf_xml``)
        self.params_name = params_name
        self.payload = payload
        self.sensor_mount = sensor_mount or SensorMount()
        self.num_threads = num_threads or max(1, min(4, os.cpu_count() or 1))

        try:
            self.model = pin.buildModelFromXML(urdf_xml)
            self.model_ff = pin.buildModelFromXML(urdf_xml, pin.JointModelFreeFlyer())
        except (ValueError, RuntimeError) as err:  # urdfdom's parse errors (a bad number, an unknown joint type)
            where = spec.source or spec.urdf_path
            raise RobotDescriptionError(f"robot {self.name!r} ({where}): Pinocchio cannot build its URDF: "
                                        f"{str(err).strip().splitlines()[0]}") from None
        self.data = self.model.createData()
        self.data_ff = self.model_ff.createData()
        self.nq, self.nv = self.model.nq, self.model.nv
        if self.nq != self.nv:
            raise RobotDescriptionError(f"robot {self.name!r}: only revolute/prismatic joints are supported (nq != nv)")
        self.joint_names = [self.model.names[i] for i in range(1, self.model.njoints)]

        for frame in (spec.tool_frame, spec.base_sensor_frame):
            if not self.model.existFrame(frame):
                raise RobotDescriptionError(f"robot {self.name!r}: frame {frame!r} is not in the URDF")
        self.tool_frame_id = self.model.getFrameId(spec.tool_frame)

        # Sensor placement relative to the free-flyer (root link) frame.
        sid = self.model_ff.getFrameId(spec.base_sensor_frame)
        if self.model_ff.frames[sid].parentJoint != 1:
            raise RobotDescriptionError(
                f"robot {self.name!r}: base sensor frame {spec.base_sensor_frame!r} is not rigidly attached to the root link"
            )
        root_M_sensor = self.model_ff.frames[sid].placement * self.sensor_mount.se3()
        self._root_M_sensor = root_M_sensor
        # Dual adjoint that maps a wrench in root coordinates to sensor coordinates.
        self._sensor_from_root = root_M_sensor.inverse().toDualActionMatrix()
        self._root_from_sensor = root_M_sensor.toDualActionMatrix()

        self.q_lower = self.model.lowerPositionLimit.copy()
        self.q_upper = self.model.upperPositionLimit.copy()
        self._q_lower_list = (self.q_lower - 1e-6).tolist()
        self._q_upper_list = (self.q_upper + 1e-6).tolist()
        self._single_shape = (self.nv,)
        self.total_mass = float(sum(inertia.mass for inertia in self.model_ff.inertias))
        self._pool = None
        self._pool_ff = None
        self._q_ff_base = np.zeros(7)
        self._q_ff_base[6] = 1.0  # identity quaternion (x, y, z, w)
        # Single-sample fast path (control loops): preallocated free-flyer state.
        self._qff = np.concatenate([self._q_ff_base, np.zeros(self.nq)])
        self._vff = np.zeros(self.model_ff.nv)
        self._aff = np.zeros(self.model_ff.nv)

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nv={self.nv}, params={self.params_name!r}, payload={self.payload})"

    @property
    def urdf_xml(self) -> str:
        """The model's URDF text, its payload included (rebuilt on the first read after ``set_payload``)."""
        if self._urdf_xml is None:
            self._urdf_xml = urdf_with_payload(self._urdf_base, self.spec.tool_frame, self.payload)
        return self._urdf_xml

    def copy(self) -> "Robot":
        """An independent copy (its own Pinocchio models, data and buffers): one whose payload its owner
        may change (``set_payload``) without changing this one."""
        new = copy.copy(self)
        new.model, new.model_ff = self.model.copy(), self.model_ff.copy()
        new.data, new.data_ff = new.model.createData(), new.model_ff.createData()
        new._pool = new._pool_ff = None
        new._qff, new._vff, new._aff = self._qff.copy(), self._vff.copy(), self._aff.copy()
        return new

    def set_payload(self, payload) -> None:
        """Carry ``payload`` (a :class:`Payload`, ``(mass_kg, (x, y, z))`` [m] in the tool frame, or None) instead
        of the current one, in place and in microseconds: a point mass changes only the inertia of the body
        the tool frame is fixed to, in both models; a robot loaded with the payload has the same dynamics to
        round-off. Whoever holds this Robot sees the change (``copy`` first to keep the original)."""
        payload = as_payload(payload)
        if getattr(self, "_bare", None) is None:  # the inertias (and URDF) without a payload, once
            self._bare = tuple(self._point_mass(m, self.payload, -1.0, m.inertias[self._tool_joint(m)])
                               for m in (self.model, self.model_ff))
            self._urdf_base = self._urdf_xml
        for model, bare in zip((self.model, self.model_ff), self._bare):
            model.inertias[self._tool_joint(model)] = self._point_mass(model, payload, 1.0, bare)
        self._urdf_xml = None
        self.payload = payload
        self.variant = RobotVariant(self.variant.tool, payload)
        self.name = self.base_name + self.variant.suffix()
        self.total_mass = float(sum(inertia.mass for inertia in self.model_ff.inertias))

    def _tool_joint(self, model) -> int:
        return model.frames[model.getFrameId(self.spec.tool_frame)].parentJoint

    def _point_mass(self, model, payload, sign: float, inertia):
        """``inertia`` plus (sign 1) or minus (-1) the payload's point mass, in its joint's frame."""
        if payload is None or payload.mass == 0:
            return pin.Inertia(inertia)
        frame = model.frames[model.getFrameId(self.spec.tool_frame)]
        com = frame.placement.act(np.asarray(payload.offset, float))  # tool frame -> the joint's frame
        point = pin.Inertia(payload.mass, com, np.zeros((3, 3)))
        return inertia + point if sign > 0 else inertia - point

    # ---------------------------------------------------------------- checks
    def _joints(self, x, name: str) -> tuple[np.ndarray, bool]:
        return as_batch(x, name, self.nv)

    def _q(self, q) -> tuple[np.ndarray, bool]:
        """Validate q; warn (JointLimitWarning) when outside the URDF limits.

        A warning, not an error: measured positions can sit a hair past a limit
        and analytic models remain valid there.
        """
        q, single = self._joints(q, "q")
        tol = 1e-6
        out = (q < self.q_lower - tol) | (q > self.q_upper + tol)
        if out.any():
            i, j = np.argwhere(out)[0]
            warnings.warn(
                f"q[{i}, {j}] = {q[i, j]:.4f} rad is outside the limits of {self.joint_names[j]} "
                f"[{self.q_lower[j]:.4f}, {self.q_upper[j]:.4f}] ({int(out.any(1).sum())} samples affected)",
                JointLimitWarning,
                stacklevel=3,
            )
        return q, single

    def _single(self, x, name: str, limits: bool = False) -> np.ndarray:
        """Validate one sample of shape (nv,) with minimal overhead (no batching).

        A dot product is NaN/inf exactly when an entry is (or the values are
        absurd, > 1e154): one cheap test instead of an isfinite array.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != self._single_shape:
            raise InputError(f"{name} must have shape (N, {self.nv}) or ({self.nv},), got {x.shape}")
        if not math.isfinite(x.dot(x)):
            raise InputError(f"{name} holds NaN or inf: {x}")
        if limits:
            # Plain floats: for 7 values this beats two ufunc calls by ~3 us.
            for xi, lo, hi in zip(x.tolist(), self._q_lower_list, self._q_upper_list):
                if xi < lo or xi > hi:
                    self._q(x)  # the batch path words the warning
                    break
        return x

    def rnea_ff_single(self, q, qd, qdd) -> np.ndarray:
        """One free-flyer RNEA at a validated sample: (nv+6,) with the ground wrench in
        root coordinates first."""
        self._qff[7:] = q
        self._vff[6:] = qd
        self._aff[6:] = qdd
        return pin.rnea(self.model_ff, self.data_ff, self._qff, self._vff, self._aff)

    def base_wrench_single(self, q, qd, qdd) -> np.ndarray:
        """``base_wrench`` (6,) [N, Nm] of one validated sample, no tip force: the streaming path."""
        return self._sensor_from_root @ self.rnea_ff_single(q, qd, qdd)[:6]

    def tip_position_single(self, q: np.ndarray) -> np.ndarray:
        """Tool position [m] (3,) of one validated sample (RNEA does not update oMi)."""
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.tool_frame_id).translation

    def _state(self, q, qd, qdd):
        q, single = self._q(q)
        qd, _ = self._joints(qd, "qd")
        qdd, _ = self._joints(qdd, "qdd")
        if not (len(q) == len(qd) == len(qdd)):
            raise InputError(f"q, qd, qdd have different lengths: {len(q)}, {len(qd)}, {len(qdd)}")
        return q, qd, qdd, single

    @staticmethod
    def _out(x, single):
        return x[0] if single else x

    # ------------------------------------------------------------ dynamics
    def _rnea_batch(self, model, pool_attr, q, v, a) -> np.ndarray:
        """RNEA over a batch; a plain loop for tiny batches (thread start-up dominates)."""
        n = len(q)
        if n < 64:
            data = self.data if model is self.model else self.data_ff
            return np.stack([pin.rnea(model, data, q[i], v[i], a[i]) for i in range(n)])
        pool = getattr(self, pool_attr)
        if pool is None:
            pool = pin.ModelPool(model, self.num_threads)
            setattr(self, pool_attr, pool)
        tau = np.empty((model.nv, n), order="F")
        # rneaInParallel sets OpenMP's thread count for the whole process, and torch's count is
        # OpenMP's: put it back, or a net trained or timed after an analytic batch runs on this
        # pool's threads (a residual net's prior left the bench's one-thread workers on two, beside
        # the other worker: about 3x slower per epoch, docs/models.md "Training"). torch is not
        # imported here for it; where no one loaded it, there is nothing to restore.
        torch = sys.modules.get("torch")
        threads = torch.get_num_threads() if torch is not None else None
        pin.rneaInParallel(self.num_threads, pool, np.asfortranarray(q.T), np.asfortranarray(v.T),
                           np.asfortranarray(a.T), tau)
        if threads is not None:
            torch.set_num_threads(threads)
        return tau.T

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        """Joint torques [Nm] (N, nv) that produce qdd at (q, qd), rigid body only (no friction)."""
        if np.ndim(q) == 1:
            q, qd, qdd = self._single(q, "q", True), self._single(qd, "qd"), self._single(qdd, "qdd")
            return pin.rnea(self.model, self.data, q, qd, qdd).copy()
        q, qd, qdd, single = self._state(q, qd, qdd)
        return self._out(self._rnea_batch(self.model, "_pool", q, qd, qdd), single)

    def gravity(self, q) -> np.ndarray:
        """Gravity torques g(q) [Nm] (N, nv)."""
        q, single = self._q(q)
        z = np.zeros_like(q)
        return self._out(self._rnea_batch(self.model, "_pool", q, z, z), single)

    def mass_matrix(self, q) -> np.ndarray:
        """Joint-space inertia matrix M(q) [kg m^2] (N, nv, nv), symmetric."""
        q, single = self._q(q)
        out = np.empty((len(q), self.nv, self.nv))
        for i, qi in enumerate(q):
            M = pin.crba(self.model, self.data, qi)
            out[i] = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
        return self._out(out, single)

    def coriolis_matrix(self, q, qd) -> np.ndarray:
        """Coriolis matrix C(q, qd) (N, nv, nv) with M' - 2C skew-symmetric."""
        q, single = self._q(q)
        qd, _ = self._joints(qd, "qd")
        out = np.stack([pin.computeCoriolisMatrix(self.model, self.data, q[i], qd[i]).copy() for i in range(len(q))])
        return self._out(out, single)

    def tip_position(self, q) -> np.ndarray:
        """Tool-point position [m] (N, 3) in the base frame."""
        q, single = self._q(q)
        return self._out(self._tip_positions(q), single)

    def _tip_positions(self, q: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            pin.forwardKinematics(self.model, self.data, qi)
            out[i] = pin.updateFramePlacement(self.model, self.data, self.tool_frame_id).translation
        return out

    def tip_jacobian(self, q) -> np.ndarray:
        """Tool-point Jacobian (N, 6, nv) in base-frame axes, linear rows first.

        Maps qd to [v_tool; omega] with v_tool the tool point's velocity [m/s].
        """
        q, single = self._q(q)
        return self._out(self._tip_jacobians(q), single)

    def _tip_jacobians(self, q: np.ndarray) -> np.ndarray:
        out = np.empty((len(q), 6, self.nv))
        for i, qi in enumerate(q):
            out[i] = pin.computeFrameJacobian(self.model, self.data, qi, self.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)
        return out

    def base_wrench(self, q, qd, qdd, tip_force=None) -> np.ndarray:
        """Ground reaction wrench [N, Nm] (N, 6) in the base-sensor frame.

        Includes the weight of every link, link 0 too. ``tip_force`` (N, 3) [N] is
        the force the environment exerts at the tool point, in the base frame;
        it carries part of the load, so the ground carries less.
        """
        if np.ndim(q) == 1 and tip_force is None:
            q, qd, qdd = self._single(q, "q", True), self._single(qd, "qd"), self._single(qdd, "qdd")
            return self.base_wrench_single(q, qd, qdd)
        q, qd, qdd, single = self._state(q, qd, qdd)
        n = len(q)
        # The free-flyer base is held still: its RNEA rows are the wrench the
        # ground must supply, in root-link coordinates, moment about its origin.
        q_ff = np.concatenate([np.broadcast_to(self._q_ff_base, (n, 7)), q], axis=1)
        z6 = np.zeros((n, 6))
        tau_ff = self._rnea_batch(self.model_ff, "_pool_ff", q_ff, np.concatenate([z6, qd], 1), np.concatenate([z6, qdd], 1))
        w_root = tau_ff[:, :6]
        if tip_force is not None:
            f, _ = as_batch(tip_force, "tip_force", 3)
            if len(f) != n:
                raise InputError(f"tip_force has {len(f)} samples, q has {n}")
            p = self._tip_positions(q)
            w_root = w_root - np.concatenate([f, np.cross(p, f)], axis=1)
        return self._out(w_root @ self._sensor_from_root.T, single)

    def base_wrench_to_root(self, w_sensor: np.ndarray) -> np.ndarray:
        """Express sensor-frame wrenches (N, 6) in root-link coordinates."""
        return w_sensor @ self._root_from_sensor.T


def load_robot(name: str = "panda", params: str | os.PathLike | None = None, payload: Payload | tuple | None = None,
               sensor_mount: SensorMount | None = None, num_threads: int | None = None,
               tool: str | os.PathLike | None = None) -> Robot:
    """Load a robot by name; what a name may be is :func:`hybrid_dyn.description.resolve_robot`'s
    (``robots/<name>.toml``, an example-robot-data arm such as ``"ur10"``, a ``.urdf`` or
    ``.toml`` path, each with an optional variant: ``"panda[tool=none]"``).

    params: a named set of the robot (``"gaz2019"``, ``"franka_official"`` for the
    Panda), a path to a parameter JSON (``{"links": [...]}``, e.g. an identified
    set), or None for the robot's default (the URDF's own values).
    payload: a :class:`Payload` or ``(mass_kg, (dx, dy, dz))``: a point mass at an
    offset [m] from the tool frame, in tool-frame axes. Part of the robot's name.
    tool: ``"none"`` for the bare flange (the Panda without its hand), a tool
    ``.urdf`` path, or None / the URDF's own (``"hand"``). Part of the robot's name.
    sensor_mount: the base sensor's true pose relative to its nominal frame.
    """
    ref = resolve_robot(name, tool=tool, payload=payload)
    if not ref.described:
        raise RobotDescriptionError(f"robot {ref.name!r} is known for data only (no description in ROBOTS): it has no "
                                    f"URDF, so no analytic model; models that need none (seed nets, DeLaN) apply")
    spec, payload = ref.spec, ref.variant.payload
    urdf = build_urdf(spec, params=params, payload=payload)
    params_name = str(params) if params is not None else spec.default_params
    return Robot(spec, urdf, params_name=params_name, payload=payload, sensor_mount=sensor_mount,
                 num_threads=num_threads, name=ref.name)


def with_payload(robot: Robot, payload: Payload | tuple | None) -> Robot:
    """The same robot (description, parameters, tool, sensor mount) carrying ``payload`` instead of its own:
    a :class:`Payload` or ``(mass_kg, (x, y, z))``, a point mass at that offset [m] from the tool frame in
    its axes; None carries none."""
    from ..description.names import RobotVariant

    name = robot.base_name + RobotVariant(robot.variant.tool, None).suffix()
    return load_robot(name, params=robot.params_name, payload=payload, sensor_mount=robot.sensor_mount,
                      num_threads=robot.num_threads)
