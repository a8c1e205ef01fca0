"""Tools on the flange: reading a tool URDF, swapping the URDF's own tool for another or for none."""
from __future__ import annotations

import dataclasses
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from .base import RobotDescriptionError, _checked_tree, _subtree
from .spec import RobotSpec


@dataclass(frozen=True)
class ToolUrdf:
    """A tool to mount on a flange, read from a small URDF file.

    Its links hang from one root link (mounted on the flange, frames aligned) by
    fixed joints only; its one leaf link is the tool frame (the tool point).
    """

    path: Path
    links: tuple
    joints: tuple
    root_link: str
    tool_frame: str


def read_tool(path: str | os.PathLike, arm_links=()) -> ToolUrdf:
    """Read and check a tool URDF; ``arm_links``: names its links must not reuse."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as err:
        raise RobotDescriptionError(f"tool URDF {path} cannot be read: {err}") from err
    _checked_tree(root, f"tool URDF {path}")
    links = root.findall("link")
    joints = root.findall("joint")
    names = [ln.get("name") for ln in links]
    moving = [j.get("name") for j in joints if j.get("type") != "fixed"]
    if moving:
        raise RobotDescriptionError(f"tool URDF {path}: joints {moving} are not fixed (a tool is one rigid body; "
                                    f"lock them at their positions)")
    children = {j.find("child").get("link") for j in joints}
    parents = {j.find("parent").get("link") for j in joints}
    roots = [n for n in names if n not in children]
    leaves = [n for n in names if n not in parents]
    if len(roots) != 1 or len(leaves) != 1:
        raise RobotDescriptionError(f"tool URDF {path} needs one root link (mounted on the flange) and one leaf link "
                                    f"(the tool point); it has roots {roots} and leaves {leaves}")
    clash = sorted(set(names) & set(arm_links))
    if clash:
        raise RobotDescriptionError(f"tool URDF {path} reuses the arm's link names {clash}: rename them")
    return ToolUrdf(path, tuple(links), tuple(joints), roots[0], leaves[0])


def _canonical_tool(spec: RobotSpec, tool) -> str | None:
    """None (the URDF's own tool), "none" (the bare flange) or the absolute path of a tool URDF."""
    if tool is None or str(tool) == spec.default_tool:
        return None
    if str(tool) == "none":
        return "none"
    if Path(tool).suffix == ".urdf":
        p = Path(tool).resolve()
        if not p.is_file():
            raise RobotDescriptionError(f"tool URDF not found: {p}")
        return str(p)
    raise RobotDescriptionError(f"robot {spec.name!r} has no tool {str(tool)!r}: give {spec.default_tool!r} (the one "
                                f"its URDF carries), 'none' (the bare flange) or the path of a tool .urdf")


def with_tool(spec: RobotSpec, tool) -> RobotSpec:
    """``spec`` with ``tool`` on its flange instead of the tool its URDF carries.

    tool: None or ``spec.default_tool`` keeps the URDF's own; ``"none"`` takes it
    off (the tool frame becomes the flange); a ``.urdf`` path mounts that tool
    (:func:`read_tool`; its leaf link becomes the tool frame).
    """
    tool = _canonical_tool(spec, tool)
    if tool is None:
        return spec
    where = spec.source or spec.urdf_path
    if spec.flange is None:
        raise RobotDescriptionError(f"robot {spec.name!r} names no flange, so a tool cannot be changed "
                                    f"(add flange = \"<its last link>\" to {where})")
    root = _checked_tree(ET.fromstring(spec.urdf_path.read_text()), f"URDF {spec.urdf_path}")
    arm_links = {ln.get("name") for ln in root.findall("link")}
    if spec.flange not in arm_links:
        raise RobotDescriptionError(f"robot {spec.name!r}: flange {spec.flange!r} ({where}) is not a link of its URDF")
    taken_links, taken_joints = _subtree(root, spec.flange)
    tool_frame = spec.flange if tool == "none" else read_tool(tool, arm_links - taken_links).tool_frame
    return dataclasses.replace(spec, tool=tool, tool_frame=tool_frame,
                               locked_joints={k: v for k, v in spec.locked_joints.items() if k not in taken_joints})


def _mount_tool(root, spec: RobotSpec) -> tuple[set, set]:
    """In the URDF tree ``root``: take the URDF's own tool off the flange and mount
    ``spec.tool`` there (see :func:`with_tool`). Returns the names of the links and
    joints taken off."""
    links, joints = _subtree(root, spec.flange)
    for el in list(root):
        if (el.tag == "link" and el.get("name") in links) or (el.tag == "joint" and el.get("name") in joints):
            root.remove(el)
    if spec.tool != "none":
        tool = read_tool(spec.tool, {ln.get("name") for ln in root.findall("link")})
        for el in tool.links + tool.joints:
            root.append(el)
        mount = ET.SubElement(root, "joint", name="hd_tool_mount", type="fixed")
        ET.SubElement(mount, "parent", link=spec.flange)
        ET.SubElement(mount, "child", link=tool.root_link)
        ET.SubElement(mount, "origin", xyz="0 0 0", rpy="0 0 0")
    return links, joints
