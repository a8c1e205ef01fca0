"""A described robot's moving joints as its URDF states them: names, position limits, effort limits.

What a log check needs to know about the arm, read off the same URDF text both engines are built from
(:func:`~.urdf.build_urdf`), so that the data layer can check a log without building a dynamics model.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from .spec import RobotSpec
from .urdf import build_urdf


@dataclass(frozen=True)
class JointLimits:
    """The moving joints of a robot, in the analytic model's joint order.

    names: the joint names; lower, upper: position limits (nv,) [rad, or m for a prismatic joint];
    effort: effort limits (nv,) [Nm, or N].
    """

    names: list
    lower: np.ndarray
    upper: np.ndarray
    effort: np.ndarray

    @property
    def nv(self) -> int:
        """The number of moving joints."""
        return len(self.names)


def joint_limits(spec: RobotSpec) -> JointLimits:
    """The moving joints of ``spec`` (its variant's tool and locked joints applied), with their limits.

    The order is the one Pinocchio gives a URDF's joints: depth first from the root link, the joints
    below one link by name (urdfdom keeps them in a name-sorted map).
    """
    root = ET.fromstring(build_urdf(spec))
    below = {}
    for j in root.findall("joint"):
        below.setdefault(j.find("parent").get("link"), []).append(j)
    children = {j.find("child").get("link") for j in root.findall("joint")}
    (base,) = [ln.get("name") for ln in root.findall("link") if ln.get("name") not in children]
    moving = []

    def walk(link):
        for j in sorted(below.get(link, []), key=lambda j: j.get("name")):
            if j.get("type") != "fixed":
                moving.append(j)
            walk(j.find("child").get("link"))

    walk(base)
    limits = [_limit(j) for j in moving]
    return JointLimits([j.get("name") for j in moving], *(np.array(col, float) for col in zip(*limits)))


def _limit(joint) -> tuple[float, float, float]:
    """(lower, upper, effort) of one URDF joint; a joint without a ``<limit>`` is unbounded."""
    lim = joint.find("limit")
    if lim is None:
        return -math.inf, math.inf, math.inf
    return float(lim.get("lower", "0")), float(lim.get("upper", "0")), float(lim.get("effort", "0"))
