"""What every part of a robot description shares: its error, and walks of a URDF's link tree."""
from __future__ import annotations

from ..errors import HybridDynError
from .physical_checks import urdf_tree_problems


class RobotDescriptionError(HybridDynError, ValueError):
    """A robot name, frame, URDF or parameter file is missing or inconsistent."""


def _checked_tree(root, what: str):
    """``root`` (a parsed URDF) if its links form a tree, else one error naming the problems: every walk of
    the tree below (chains, subtrees) assumes one (a joint cycle made them loop forever)."""
    problems = urdf_tree_problems(root)
    if problems:
        raise RobotDescriptionError(f"{what} is not a tree of links: {'; '.join(problems[:3])}")
    return root


def _subtree(root, link: str) -> tuple[set, set]:
    """Names of the links and joints strictly below ``link`` in a URDF tree."""
    below = {}
    for j in root.findall("joint"):
        below.setdefault(j.find("parent").get("link"), []).append(j)
    links, joints, todo = set(), set(), [link]
    while todo:
        for j in below.get(todo.pop(), []):
            child = j.find("child").get("link")
            joints.add(j.get("name"))
            links.add(child)
            todo.append(child)
    return links, joints
