"""URDF surgery: the one URDF text both engines are built from, with a parameter set,
locked joints, a tool and a payload applied."""
from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .base import RobotDescriptionError, _checked_tree
from .params import LinkInertial, read_param_file
from .spec import Payload, RobotSpec
from .tools import _mount_tool


def build_urdf(spec: RobotSpec, params: str | os.PathLike | None = None, payload: Payload | None = None) -> str:
    """The URDF text for ``spec`` with a parameter set and a payload applied.

    Visual and collision geometry is removed (neither engine needs meshes for
    dynamics, and DART would otherwise try to resolve ``package://`` URIs), and
    URDF joint damping/friction is zeroed: Pinocchio ignores it while DART would
    apply it, so friction is modelled explicitly instead (``GazFriction``).
    """
    root = _checked_tree(ET.fromstring(spec.urdf_path.read_text()), f"URDF {spec.urdf_path}")
    # A variant's tool first, so that everything below treats its links like the arm's.
    removed_links, removed_joints = _mount_tool(root, spec) if spec.tool is not None else (set(), set())
    links = {ln.get("name"): ln for ln in root.findall("link")}
    for tag in ("visual", "collision"):
        for ln in links.values():
            for el in ln.findall(tag):
                ln.remove(el)
    # A link without <inertial> is massless to Pinocchio but gets a 1 kg default
    # in DART: write the zero explicitly so both engines read the same model.
    for ln in links.values():
        if ln.find("inertial") is None:
            _set_inertial(ln, LinkInertial(ln.get("name"), 0.0, (0.0, 0.0, 0.0), (0.0,) * 6))
    for tr in root.findall("transmission"):
        root.remove(tr)
    joints = {j.get("name"): j for j in root.findall("joint")}
    for j in joints.values():
        for dyn in j.findall("dynamics"):
            j.remove(dyn)
    for jname, value in spec.locked_joints.items():
        if jname in removed_joints:
            continue  # a joint of the tool taken off (the Panda's fingers)
        if jname not in joints:
            raise RobotDescriptionError(f"locked joint {jname!r} of robot {spec.name!r} is not in the URDF")
        _lock_joint(joints[jname], value)

    param_file = _resolve_params(spec, params)
    if param_file is not None:
        for li in read_param_file(param_file):
            if li.name in removed_links:
                continue  # the set's values for a tool that is not mounted
            if li.name not in links:
                raise RobotDescriptionError(
                    f"parameter file {param_file} names link {li.name!r}, which robot {spec.name!r} does not have "
                    f"(is it a file for another robot?)"
                )
            _set_inertial(links[li.name], li)

    if payload is not None and payload.mass > 0:
        if spec.tool_frame not in links:
            raise RobotDescriptionError(f"tool frame {spec.tool_frame!r} is not a link of the URDF")
        _append_payload(root, spec.tool_frame, payload)
    return ET.tostring(root, encoding="unicode")


def _append_payload(root, tool_frame: str, payload: Payload) -> None:
    """The payload as a massive link ``hd_payload`` fixed to the tool frame at its offset [m]."""
    pl = ET.SubElement(root, "link", name="hd_payload")
    _set_inertial(pl, LinkInertial("hd_payload", payload.mass, (0.0, 0.0, 0.0), (0.0,) * 6))
    jt = ET.SubElement(root, "joint", name="hd_payload_joint", type="fixed")
    ET.SubElement(jt, "parent", link=tool_frame)
    ET.SubElement(jt, "child", link="hd_payload")
    ET.SubElement(jt, "origin", xyz=" ".join(repr(float(x)) for x in payload.offset), rpy="0 0 0")


def urdf_with_payload(urdf_xml: str, tool_frame: str, payload: Payload | None) -> str:
    """A URDF text of ``build_urdf`` carrying ``payload`` (None: none) instead of its own."""
    root = ET.fromstring(urdf_xml)
    for tag, name in (("link", "hd_payload"), ("joint", "hd_payload_joint")):
        for el in root.findall(f"{tag}[@name='{name}']"):
            root.remove(el)
    if payload is not None and payload.mass > 0:
        _append_payload(root, tool_frame, payload)
    return ET.tostring(root, encoding="unicode")


def _lock_joint(joint_el, value: float) -> None:
    """Turn a revolute/prismatic joint into a fixed one at position ``value`` [rad or m].

    Done in the URDF so that both engines see the identical rigid tree.
    """
    from scipy.spatial.transform import Rotation

    jtype = joint_el.get("type")
    origin = joint_el.find("origin")
    xyz = np.array([float(x) for x in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()])
    rpy = np.array([float(x) for x in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()])
    axis_el = joint_el.find("axis")
    axis = np.array([float(x) for x in axis_el.get("xyz").split()]) if axis_el is not None else np.array([1.0, 0, 0])
    R = Rotation.from_euler("xyz", rpy)  # URDF rpy: extrinsic x-y-z
    if jtype == "prismatic":
        xyz = xyz + R.apply(axis * value)
    elif jtype in ("revolute", "continuous"):
        R = R * Rotation.from_rotvec(axis / np.linalg.norm(axis) * value)
        with warnings.catch_warnings():
            # At pitch +-90 deg (Baxter's wrist joints) roll and yaw are one angle: scipy warns, and
            # returns angles that still give the same rotation (a test loads Baxter and checks its chain).
            warnings.simplefilter("ignore", UserWarning)
            rpy = R.as_euler("xyz")
    else:
        raise RobotDescriptionError(f"cannot lock joint {joint_el.get('name')!r} of type {jtype!r}")
    for el in joint_el.findall("origin") + joint_el.findall("axis") + joint_el.findall("limit") + joint_el.findall("mimic"):
        joint_el.remove(el)
    joint_el.set("type", "fixed")
    ET.SubElement(joint_el, "origin", xyz=" ".join(repr(float(v)) for v in xyz), rpy=" ".join(repr(float(v)) for v in rpy))


def _resolve_params(spec: RobotSpec, params) -> Path | None:
    if params is None:
        params = spec.default_params
    if params is None:
        return None
    if isinstance(params, (str, os.PathLike)) and str(params) in spec.param_sets:
        return spec.param_sets[str(params)]
    p = Path(params)
    if p.suffix == ".json":
        if not p.is_file():
            raise RobotDescriptionError(f"parameter file not found: {p}")
        return p
    raise RobotDescriptionError(
        f"robot {spec.name!r} has no parameter set {str(params)!r}; known: {', '.join(spec.param_sets) or 'none'} "
        f"(or pass a path to a .json file)"
    )


def _set_inertial(link_el, li: LinkInertial) -> None:
    inertial = link_el.find("inertial")
    old_com = (0.0, 0.0, 0.0)
    if inertial is not None:
        origin = inertial.find("origin")
        if origin is not None and origin.get("xyz"):
            old_com = tuple(float(x) for x in origin.get("xyz").split())
        link_el.remove(inertial)
    com = tuple(o if c is None else c for c, o in zip(li.com, old_com))
    inertial = ET.SubElement(link_el, "inertial")
    ET.SubElement(inertial, "origin", xyz=" ".join(repr(float(c)) for c in com), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=repr(float(li.mass)))
    xx, xy, xz, yy, yz, zz = li.inertia
    ET.SubElement(inertial, "inertia", ixx=repr(xx), ixy=repr(xy), ixz=repr(xz), iyy=repr(yy), iyz=repr(yz), izz=repr(zz))
