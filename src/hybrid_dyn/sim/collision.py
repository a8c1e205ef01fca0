"""Self- and floor-collision checking for path planning (Pinocchio + coal).

The dynamics URDF carries no geometry (``build_urdf`` strips it), so the checker
loads the robot's *collision* description from example-robot-data: for the
Panda, ``panda_collision.urdf`` (spheres and capsules, fast to check) and the
SRDF's list of link pairs that never or always touch. A floor plane (the table
the base sensor stands on) is added as a thin box under z = 0, checked against
every link but the first two.

Robots without a known collision model get no checker; their paths are then
straight lines in joint space (PROTOCOL 3 allows this).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..description import example_robot_data_dir

# robot name -> (collision URDF, SRDF) inside example-robot-data's robots/ folder.
COLLISION_MODELS = {
    "panda": ("panda_description/urdf/panda_collision.urdf", "panda_description/srdf/panda.srdf"),
}
FLOOR_FREE_LINKS = {"panda": ("panda_link0", "panda_link1")}  # links that stand on or near the floor


class SelfCollisionChecker:
    """``checker(q)`` -> True when configuration q (robot joint order) is collision-free."""

    def __init__(self, robot, floor: bool = True):
        urdf_rel, srdf_rel = COLLISION_MODELS[robot.name]
        root = example_robot_data_dir()
        urdf = (root / urdf_rel).read_text()
        self.model = pin.buildModelFromXML(urdf)
        self.geom = pin.buildGeomFromUrdfString(self.model, urdf, pin.COLLISION, package_dirs=[str(root)])
        self.geom.addAllCollisionPairs()
        pin.removeCollisionPairsFromXML(self.model, self.geom, (root / srdf_rel).read_text())
        if floor:
            self._add_floor(FLOOR_FREE_LINKS.get(robot.name, ()))
        self.data = self.model.createData()
        self.geom_data = self.geom.createData()
        # Map the robot's joints (and locked joints at their values) into this model's q.
        self._q = pin.neutral(self.model)
        self._idx = np.array([self.model.joints[self.model.getJointId(n)].idx_q for n in robot.joint_names])
        for name, value in robot.spec.locked_joints.items():
            if self.model.existJointName(name):
                self._q[self.model.joints[self.model.getJointId(name)].idx_q] = value

    def _add_floor(self, floor_free_links) -> None:
        import coal

        floor = pin.GeometryObject("floor", 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.011])), coal.Box(4.0, 4.0, 0.02))
        fid = self.geom.addGeometryObject(floor)
        for gid, g in enumerate(self.geom.geometryObjects):
            if gid == fid:
                continue
            link = self.model.frames[g.parentFrame].name
            if link not in floor_free_links:
                self.geom.addCollisionPair(pin.CollisionPair(gid, fid))

    def __call__(self, q: np.ndarray) -> bool:
        self._q[self._idx] = q
        return not pin.computeCollisions(self.model, self.data, self.geom, self.geom_data, self._q, True)


def collision_checker(robot, enabled: bool = True):
    """A :class:`SelfCollisionChecker` for ``robot``, or None where none is known or it is disabled."""
    if not enabled or robot.name not in COLLISION_MODELS:
        return None
    return SelfCollisionChecker(robot)
