"""The simulated plant: a DART world holding the robot on a fixed base.

Built from the very URDF string of a :class:`~hybrid_dyn.analytic.Robot`, so a
plant differs from a nominal model only where a scenario makes it differ (other
inertials, a payload, a tilted sensor). DART and Pinocchio agree to ~1e-13 on
the same model; the tests hold them to that.

DART conventions handled here:
- spatial vectors are [angular; linear]; this module converts to [linear; angular];
- external forces accumulate until ``step()`` or ``clearExternalForces()``;
- ``getBodyForce()`` of the root body is the wrench its weld joint (the ground)
  transmits, in the body frame, moment about the body origin.
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np
import dartpy as dart

from ..analytic.robot import Robot


def load_skeleton(urdf_xml: str):
    """A DART skeleton from URDF text, root welded to the world."""
    loader = dart.utils.DartLoader()
    opts = dart.utils.DartLoader.Options()
    opts.mDefaultRootJointType = dart.utils.DartLoader.RootJointType.FIXED
    loader.setOptions(opts)
    # DART warns (on C++ stderr, once per plant) about every zero-mass body. Frame links welded to
    # their parent (panda_link8, panda_hand_tcp) are massless by design: drop those lines only.
    expected = tuple(f"is set to BodyNode [{name}]" for name in massless_frame_links(urdf_xml))
    with _stderr_without(lambda line: "zero mass" in line and any(e in line for e in expected)):
        skel = loader.parseSkeletonString(urdf_xml, "")
    if skel is None:
        raise ValueError("DART could not parse the URDF")
    return skel


def massless_frame_links(urdf_xml: str) -> list[str]:
    """Links of mass 0 attached by a fixed joint: pure frames (a tool point, a flange)."""
    root = ET.fromstring(urdf_xml)
    fixed_children = {j.find("child").get("link") for j in root.iter("joint") if j.get("type") == "fixed"}
    out = []
    for link in root.iter("link"):
        mass = link.find("inertial/mass")
        if link.get("name") in fixed_children and (mass is None or float(mass.get("value", 0.0)) == 0.0):
            out.append(link.get("name"))
    return out


_LIBC = ctypes.CDLL(None)


@contextlib.contextmanager
def _stderr_without(drop):
    """Run the block with the process's stderr (fd 2, where C++ logs) filtered: lines for which
    ``drop(line)`` is true are discarded, every other line is written on afterwards."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            _LIBC.fflush(None)  # DART's logger writes through C stdio: flush it into the file first
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            kept = [ln for ln in tmp.read().decode(errors="replace").splitlines(keepends=True) if not drop(ln)]
            if kept:
                sys.stderr.write("".join(kept))
                sys.stderr.flush()


class DartPlant:
    """A robot in a DART world, stepped at ``dt`` [s] under joint torques.

    Joint order follows the :class:`Robot` (Pinocchio) order.
    """

    def __init__(self, robot: Robot, dt: float = 1e-3):
        self.robot = robot
        self.dt = dt
        self.skel = load_skeleton(robot.urdf_xml)
        self.world = dart.simulation.World()
        self.world.addSkeleton(self.skel)
        self.world.setTimeStep(dt)
        self.world.setGravity(np.array([0.0, 0.0, -9.81]))
        self.dof_index = np.array([self.skel.getDof(n).getIndexInSkeleton() for n in robot.joint_names])
        self.tool = self.skel.getBodyNode(robot.spec.tool_frame)
        self.base = self.skel.getBodyNode(robot.spec.base_sensor_frame)
        if self.tool is None or self.base is None:
            raise ValueError("tool or base-sensor link is missing from the DART skeleton")
        # Maps a wrench in base-link coordinates to the (possibly tilted) sensor frame.
        self._sensor_from_base = robot._root_M_sensor.inverse().toDualActionMatrix()
        if self.skel.getRootBodyNode().getName() != robot.spec.base_sensor_frame:
            # The sensor frame is the root link in every shipped robot; anything else
            # would need the root-to-sensor transform here too.
            raise ValueError("the base-sensor link must be the root of the DART skeleton")

    # ---------------------------------------------------------------- state
    def _to_dart(self, x: np.ndarray) -> np.ndarray:
        out = np.empty(len(self.dof_index))
        out[self.dof_index] = x
        return out

    def _from_dart(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x)[self.dof_index]

    def set_state(self, q, qd) -> None:
        self.skel.setPositions(self._to_dart(np.asarray(q, float)))
        self.skel.setVelocities(self._to_dart(np.asarray(qd, float)))

    @property
    def q(self) -> np.ndarray:
        return self._from_dart(self.skel.getPositions())

    @property
    def qd(self) -> np.ndarray:
        return self._from_dart(self.skel.getVelocities())

    @property
    def qdd(self) -> np.ndarray:
        return self._from_dart(self.skel.getAccelerations())

    # ------------------------------------------------------------- physics
    def apply_tip_force(self, force) -> None:
        """Add a force [N] in world (= base) axes at the tool point until the next step."""
        self.tool.addExtForce(np.asarray(force, float), np.zeros(3), False, True)

    def base_wrench(self) -> np.ndarray:
        """Ground reaction on the robot [N, Nm] in the sensor frame, from the last dynamics pass."""
        bf = self.base.getBodyForce()  # [moment; force], base-link frame
        return self._sensor_from_base @ np.concatenate([bf[3:], bf[:3]])

    def inverse_dynamics(self, q, qd, qdd, tip_force=None) -> np.ndarray:
        """DART's joint torques [Nm] for (q, qd, qdd) with an optional tip force.

        Also updates the body forces, so ``base_wrench()`` then reads the ground
        reaction for this state.
        """
        self.set_state(q, qd)
        self.skel.setAccelerations(self._to_dart(np.asarray(qdd, float)))
        self.skel.clearExternalForces()
        if tip_force is not None:
            self.apply_tip_force(tip_force)
        self.skel.computeInverseDynamics(tip_force is not None, False, False)
        tau = self._from_dart(self.skel.getForces())
        return tau

    def mass_matrix(self, q) -> np.ndarray:
        self.skel.setPositions(self._to_dart(np.asarray(q, float)))
        M = self.skel.getMassMatrix()
        return M[np.ix_(self.dof_index, self.dof_index)]

    def forward_dynamics(self, tau) -> np.ndarray:
        """qdd [rad/s^2] under joint torques ``tau`` and the external forces applied so far."""
        self.skel.setForces(self._to_dart(np.asarray(tau, float)))
        self.skel.computeForwardDynamics()
        return self.qdd

    def step(self, tau) -> None:
        """Advance one time step under joint torques ``tau`` [Nm]; clears external forces."""
        self.skel.setForces(self._to_dart(np.asarray(tau, float)))
        self.world.step()
