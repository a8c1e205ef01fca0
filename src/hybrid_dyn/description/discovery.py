"""A description read off a URDF alone, and the arms of example-robot-data loadable by name."""
from __future__ import annotations

import functools
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

from .base import RobotDescriptionError, _checked_tree
from .locations import example_robot_data_dir
from .robots import ROBOTS
from .spec import RobotSpec, load_spec


def describe_urdf(path: str | os.PathLike, name: str | None = None) -> RobotSpec:
    """A description read off a URDF alone, for a serial arm.

    The base sensor's frame is the root link, the tool frame (and flange) the
    arm's last link: ``tool0`` where the URDF has one (the ROS-Industrial flange
    frame), else the one leaf after the last moving joint. Home is q = 0 (clipped
    into the limits); velocity limits are the URDF's. An arm with a hand or
    several chains needs a ``robots/<name>.toml`` (its locked joints, frames).
    """
    path = Path(path).resolve()
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as err:
        raise RobotDescriptionError(f"URDF {path} cannot be read: {err}") from err
    _checked_tree(root, f"URDF {path}")
    links = [ln.get("name") for ln in root.findall("link")]
    joint_to = {j.find("child").get("link"): j for j in root.findall("joint")}
    roots = [n for n in links if n not in joint_to]
    if len(roots) != 1:
        raise RobotDescriptionError(f"URDF {path} has {len(roots)} root links {roots}, not one")

    def chain(link):  # the moving joints from the root down to ``link``, root first
        out = []
        while link in joint_to:
            j = joint_to[link]
            if j.get("type") != "fixed":
                out.append(j)
            link = j.find("parent").get("link")
        return out[::-1]

    moving = [j for j in joint_to.values() if j.get("type") != "fixed"]
    depth = {n: len(chain(n)) for n in links}
    deepest = max(links, key=depth.get)
    arm = chain(deepest)
    if not moving:
        raise RobotDescriptionError(f"URDF {path} has no moving joint")
    off = sorted(j.get("name") for j in moving if j not in arm)
    if off:
        raise RobotDescriptionError(f"URDF {path} is not a serial arm: joints {off} branch off the chain to "
                                    f"{deepest!r} (a hand, legs, a second arm?); describe it in a robots/<name>.toml "
                                    f"that locks them (locked_joints)")
    parents = {j.find("parent").get("link") for j in joint_to.values()}
    ends = [n for n in links if depth[n] == len(arm) and n not in parents]
    if "tool0" in ends:
        tool = "tool0"
    elif len(ends) == 1:
        tool = ends[0]
    else:
        raise RobotDescriptionError(f"URDF {path}: which of the last links {ends} is the tool frame? Say it in a "
                                    f"robots/<name>.toml (tool_frame)")
    home, vmax = [], []
    for j in arm:
        lim = j.find("limit")
        try:
            lo = float(lim.get("lower", "-inf")) if lim is not None and j.get("type") != "continuous" else -math.inf
            hi = float(lim.get("upper", "inf")) if lim is not None and j.get("type") != "continuous" else math.inf
            vmax.append(float(lim.get("velocity")) if lim is not None and lim.get("velocity") else None)
        except ValueError:
            raise RobotDescriptionError(f"URDF {path}: joint {j.get('name')!r} has a <limit> that is not numbers "
                                        f"({dict(lim.attrib)})") from None
        home.append(min(max(0.0, lo), hi))
    return RobotSpec(
        name=name or str(path), urdf_path=path, tool_frame=tool, base_sensor_frame=roots[0], home=tuple(home),
        max_velocity=tuple(vmax) if None not in vmax else (), flange=tool, source=None,
    )


@functools.cache
def _example_robot_data_urdfs() -> dict:
    """name -> URDF paths of example-robot-data: a file's name, and that name less
    ``_robot`` (``ur10`` is ``ur10_robot.urdf``). Files without links (ur3.urdf is an
    empty xacro output) are left out."""
    out = {}
    for f in sorted(example_robot_data_dir().rglob("*.urdf")):
        if "<link" not in f.read_text(errors="replace"):
            continue
        for name in {f.stem, f.stem.removesuffix("_robot")}:
            out.setdefault(name, []).append(f)
    return out


def example_robot_data_arms() -> list[str]:
    """The serial arms of example-robot-data that ``ROBOTS`` does not describe
    (loadable by name: ``load_robot("ur10")``)."""
    return list(_example_robot_data_arms())


@functools.cache
def _example_robot_data_arms() -> tuple:
    described = [robot.name for robot in ROBOTS.where(data_only=False)]
    arms = {load_spec(n).urdf_path: n for n in described}  # declared in ROBOTS: listed there
    for name, files in sorted(_example_robot_data_urdfs().items(), key=lambda kv: (len(kv[0]), kv[0])):
        if len(files) == 1 and files[0] not in arms:  # one name per file, the shortest
            try:
                describe_urdf(files[0], name)
            except RobotDescriptionError:
                continue
            arms[files[0]] = name
    return tuple(sorted(set(arms.values()) - set(described)))
