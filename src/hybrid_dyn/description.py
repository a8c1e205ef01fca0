"""Robot descriptions: which URDF, which frames, which parameter sets.

A robot is described by a small TOML file in the repository's ``robots/`` folder
(see ``robots/panda.toml``). This module reads those files, finds the URDF inside
the installed ``example-robot-data`` package, and rewrites the URDF text when a
different parameter set or a payload is asked for.

Both engines (Pinocchio for the analytic model, DART for the simulated plant)
are built from the *same* URDF string produced here, so a plant and a model can
only differ where a scenario says they should.
"""
from __future__ import annotations

from .errors import HybridDynError
from .input_checks import inertial_problems, urdf_tree_problems
import importlib.metadata
import dataclasses
import functools
import json
import math
import os
import re
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


class RobotDescriptionError(HybridDynError, ValueError):
    """A robot name, frame, URDF or parameter file is missing or inconsistent."""


def _checked_tree(root, what: str):
    """``root`` (a parsed URDF) if its links form a tree, else one error naming the problems: every walk of
    the tree below (chains, subtrees) assumes one (a joint cycle made them loop forever)."""
    problems = urdf_tree_problems(root)
    if problems:
        raise RobotDescriptionError(f"{what} is not a tree of links: {'; '.join(problems[:3])}")
    return root


# --------------------------------------------------------------------------- paths
def robots_dir() -> Path:
    """The folder holding ``<name>.toml`` robot descriptions.

    ``$HYBRID_DYN_ROBOTS`` wins; otherwise the ``robots/`` folder of the checkout
    this package was installed from (editable install, the documented path).
    """
    env = os.environ.get("HYBRID_DYN_ROBOTS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "robots"


def example_robot_data_dir() -> Path:
    """The ``robots/`` folder of the installed example-robot-data package.

    Version 6.x ships only data files (no Python module), so we ask the package
    metadata where its files went.
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as err:  # pragma: no cover
        raise RobotDescriptionError("example-robot-data is not installed (pip install example-robot-data)") from err
    for f in dist.files or []:
        parts = Path(str(f)).parts
        if "example-robot-data" in parts and "robots" in parts:
            i = parts.index("robots")
            return Path(dist.locate_file(Path(*parts[: i + 1])))
    raise RobotDescriptionError("could not find the robots/ folder of example-robot-data")  # pragma: no cover


# ------------------------------------------------------------------ parameter sets
@dataclass(frozen=True)
class LinkInertial:
    """Inertial parameters of one URDF link.

    mass [kg]; com [m] in the link frame; inertia [kg m^2] about the COM with
    axes parallel to the link frame, ordered (xx, xy, xz, yy, yz, zz).
    ``None`` in com keeps the URDF's value (not identifiable, e.g. Gaz link-1 c_z).
    """

    name: str
    mass: float
    com: tuple
    inertia: tuple


def read_param_file(path: Path) -> list[LinkInertial]:
    """Read a parameter-set JSON (``{"links": [{name, mass, com, inertia}, ...]}``).

    An entry may carry ``"absorbed_into": "<link>"`` with mass 0: identified sets
    give all links fixed to one joint (e.g. Panda link 7 + hand + fingers) to one.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError as err:
        raise RobotDescriptionError(f"parameter file not found: {path}") from err
    except json.JSONDecodeError as err:
        raise RobotDescriptionError(f"parameter file {path} is not valid JSON: {err}") from err
    links = doc.get("links") if isinstance(doc, dict) else None
    if not isinstance(links, list) or not links:
        raise RobotDescriptionError(f"parameter file {path} has no 'links' list")
    out = []
    for i, ln in enumerate(links):
        try:
            com = tuple(None if c is None else float(c) for c in ln["com"])
            inertia = tuple(float(x) for x in ln["inertia"])
            item = LinkInertial(str(ln["name"]), float(ln["mass"]), com, inertia)
        except (KeyError, TypeError, ValueError) as err:
            raise RobotDescriptionError(f"parameter file {path}, link #{i}: needs name, mass, com[3], inertia[6] ({err})") from err
        if len(com) != 3 or len(inertia) != 6:
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: com needs 3 values and inertia 6")
        # mass 0 is allowed for a link whose inertia an identified set gave to another
        # link of the same rigid body (``"absorbed_into": "<that link>"``).
        absorbed = item.mass == 0 and bool(ln.get("absorbed_into"))
        if not ((item.mass > 0 and math.isfinite(item.mass)) or absorbed):
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: mass must be positive, got {item.mass}")
        # A negative inertia was accepted before issue 28. A published set may break the triangle inequality
        # and say so on the link ("triangle_inequality": why it is kept), to be used as published.
        bad = inertial_problems(item.mass, item.inertia, triangle=not ln.get("triangle_inequality"))
        if bad:
            raise RobotDescriptionError(f"parameter file {path}, link {item.name}: not a rigid body: {'; '.join(bad)}")
        out.append(item)
    return out


@dataclass(frozen=True)
class GazFriction:
    """Gaz et al. 2019 sigmoid joint friction, per joint (arrays of length nv).

    tau_f(qd) = phi1 / (1 + exp(-phi2 (qd + phi3))) - phi1 / (1 + exp(-phi2 phi3))
    phi1 [Nm], phi2 [s/rad], phi3 [rad/s]. Zero at rest, saturates to about +-phi1.
    The torque is the one the friction *consumes*: tau_motor = tau_link + tau_f.
    """

    phi1: np.ndarray
    phi2: np.ndarray
    phi3: np.ndarray

    def __call__(self, qd: np.ndarray) -> np.ndarray:
        """Friction torque [Nm] at joint velocity qd [rad/s], any leading shape."""
        qd = np.asarray(qd, dtype=float)
        return self.phi1 * (_sigmoid(self.phi2 * (qd + self.phi3)) - _sigmoid(self.phi2 * self.phi3))

    @classmethod
    def from_json(cls, path: Path) -> "GazFriction":
        doc = json.loads(Path(path).read_text())
        try:
            joints = doc["friction"]["joints"]
            arr = {k: np.array([float(j[k]) for j in joints]) for k in ("phi1", "phi2", "phi3")}
        except (KeyError, TypeError) as err:
            raise RobotDescriptionError(f"{path} has no friction.joints[phi1, phi2, phi3] table") from err
        return cls(**arr)

    def to_dict(self) -> dict:
        return {k: getattr(self, k).tolist() for k in ("phi1", "phi2", "phi3")}


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))  # overflow-free logistic


# --------------------------------------------------------------------- robot spec
@dataclass(frozen=True)
class Payload:
    """A point mass rigidly attached at the tool frame.

    mass [kg]; offset [m] from the tool frame origin, in tool-frame axes.
    """

    mass: float
    offset: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class RobotSpec:
    """What a ``robots/<name>.toml`` says about a robot."""

    name: str
    urdf_path: Path
    tool_frame: str
    base_sensor_frame: str
    locked_joints: dict = field(default_factory=dict)
    home: tuple = ()
    max_velocity: tuple = ()
    max_acceleration: tuple = ()
    max_jerk: tuple = ()
    param_sets: dict = field(default_factory=dict)  # name -> JSON path
    default_params: str | None = None
    friction_files: dict = field(default_factory=dict)  # name -> JSON path
    source: Path | None = None
    # The arm's last link, where a tool mounts, and the name of the tool the URDF
    # itself carries there ("none": the URDF ends at the flange).
    flange: str | None = None
    default_tool: str = "none"
    # The tool mounted instead of the URDF's own (a variant): None keeps the URDF's,
    # "none" is the bare flange, a Path a tool URDF (see ``with_tool``).
    tool: str | Path | None = None

    def friction(self, name: str = "gaz2019") -> GazFriction | None:
        """The named friction law, or None when this robot ships none."""
        path = self.friction_files.get(name)
        return GazFriction.from_json(path) if path else None


def available_robots() -> list[str]:
    """Robots with a full description (URDF, frames): every part of the toolkit applies."""
    return sorted(p.stem for p in robots_dir().glob("*.toml") if p.stem != "data_only")


def data_only_robots() -> list[str]:
    """Arms known by name only (``robots/data_only.toml``): data-only models apply."""
    path = robots_dir() / "data_only.toml"
    if not path.is_file():
        return []
    return sorted(tomllib.loads(path.read_text()).get("robots", {}))


def known_robots() -> list[str]:
    """Every robot name a model file may carry."""
    return sorted(set(available_robots()) | set(data_only_robots()))


def load_spec(name_or_path: str | os.PathLike) -> RobotSpec:
    """Read a robot description by name (``"panda"``) or TOML path."""
    p = Path(name_or_path)
    if p.suffix == ".toml":
        toml_path = p
    else:
        toml_path = robots_dir() / f"{name_or_path}.toml"
    if not toml_path.is_file():
        raise RobotDescriptionError(
            f"unknown robot {str(name_or_path)!r}: no {toml_path}; available: {', '.join(available_robots()) or 'none'}"
        )
    try:
        doc = tomllib.loads(toml_path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise RobotDescriptionError(f"{toml_path} is not valid TOML: {err}") from err
    for key in ("name", "urdf", "tool_frame", "base_sensor_frame"):
        if key not in doc:
            raise RobotDescriptionError(f"{toml_path} lacks the key {key!r}")
    here = toml_path.parent
    # example-robot-data first (the shipped descriptions), then beside the TOML (a user's own URDF).
    urdf = example_robot_data_dir() / doc["urdf"]
    if not urdf.is_file() and (here / doc["urdf"]).is_file():
        urdf = here / doc["urdf"]
    if not urdf.is_file():
        raise RobotDescriptionError(f"{toml_path}: URDF {doc['urdf']!r} is neither in example-robot-data ({urdf}) "
                                    f"nor beside the TOML ({here / doc['urdf']})")
    params = dict(doc.get("params", {}))
    default_params = params.pop("default", None)
    return RobotSpec(
        name=doc["name"],
        urdf_path=urdf,
        tool_frame=doc["tool_frame"],
        base_sensor_frame=doc["base_sensor_frame"],
        locked_joints={k: float(v) for k, v in doc.get("locked_joints", {}).items()},
        home=tuple(doc.get("home", ())),
        max_velocity=tuple(doc.get("max_velocity", ())),
        max_acceleration=tuple(doc.get("max_acceleration", ())),
        max_jerk=tuple(doc.get("max_jerk", ())),
        param_sets={k: here / v for k, v in params.items()},
        default_params=default_params,
        friction_files={k: here / v for k, v in doc.get("friction", {}).items()},
        source=toml_path,
        flange=doc.get("flange"),
        default_tool=str(doc.get("tool", "none")),
    )


# ---------------------------------------------------------------------- URDF text
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
        pl = ET.SubElement(root, "link", name="hd_payload")
        _set_inertial(pl, LinkInertial("hd_payload", payload.mass, (0.0, 0.0, 0.0), (0.0,) * 6))
        jt = ET.SubElement(root, "joint", name="hd_payload_joint", type="fixed")
        ET.SubElement(jt, "parent", link=spec.tool_frame)
        ET.SubElement(jt, "child", link="hd_payload")
        ET.SubElement(jt, "origin", xyz=" ".join(repr(float(x)) for x in payload.offset), rpy="0 0 0")
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


# ------------------------------------------------------------ tools and variants
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


# --------------------------------------------------------- a URDF on its own
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
    """The serial arms of example-robot-data that ``robots/`` does not describe
    (loadable by name: ``load_robot("ur10")``)."""
    return list(_example_robot_data_arms())


@functools.cache
def _example_robot_data_arms() -> tuple:
    arms = {load_spec(n).urdf_path: n for n in available_robots()}  # described in robots/: listed there
    for name, files in sorted(_example_robot_data_urdfs().items(), key=lambda kv: (len(kv[0]), kv[0])):
        if len(files) == 1 and files[0] not in arms:  # one name per file, the shortest
            try:
                describe_urdf(files[0], name)
            except RobotDescriptionError:
                continue
            arms[files[0]] = name
    return tuple(sorted(set(arms.values()) - set(available_robots())))


# ------------------------------------------------------------------ robot names
@dataclass(frozen=True)
class RobotVariant:
    """What is mounted on the arm's flange: part of the robot's identity.

    tool: None (the one its URDF carries), ``"none"`` (the bare flange) or the
    absolute path of a tool URDF. payload: a point mass at the tool frame.
    """

    tool: str | None = None
    payload: Payload | None = None

    def suffix(self) -> str:
        """The variant as a robot-name suffix: ``""``, ``"[tool=none]"``, ``"[tool=none;payload=0.5@0.0,0.0,0.05]"``."""
        opts = []
        if self.tool is not None:
            opts.append(f"tool={self.tool}")
        if self.payload is not None:
            opts.append(f"payload={float(self.payload.mass)!r}@" + ",".join(repr(float(x)) for x in self.payload.offset))
        return f"[{';'.join(opts)}]" if opts else ""


@dataclass(frozen=True)
class RobotRef:
    """What a robot name stands for (:func:`resolve_robot`).

    name: the canonical name, the one datasets and model files carry; spec: the
    description with the variant's tool applied, or None for a name known for
    data only (no URDF: only models without physics apply); source: where the
    description comes from ("robots", "example-robot-data", "urdf", "data-only").
    """

    name: str
    variant: RobotVariant
    spec: RobotSpec | None
    source: str

    @property
    def described(self) -> bool:
        """True when the analytic model (and all that needs a URDF) applies."""
        return self.spec is not None


ROBOT_NAME_HELP = ("NAME, NAME[tool=none] (the bare flange), NAME[tool=/path/tool.urdf], NAME[payload=KG@X,Y,Z] "
                   "(a point mass at the tool frame, offset in m), or both joined by ';'")


def parse_robot_name(text: str) -> tuple[str, str | None, Payload | None]:
    """Split ``"panda[tool=none;payload=0.5@0,0,0.05]"`` into base, tool and payload."""
    m = re.fullmatch(r"([^\[\]]+?)(?:\[([^\[\]]*)\])?", str(text).strip())
    if not m:
        raise RobotDescriptionError(f"robot name {text!r} is not of the form {ROBOT_NAME_HELP}")
    base, opts = m.group(1), m.group(2)
    tool = payload = None
    for opt in filter(None, (opts or "").split(";")):
        key, eq, value = opt.partition("=")
        key, value = key.strip(), value.strip()
        if key == "tool" and eq:
            tool = value
        elif key == "payload" and eq:
            payload = _parse_payload(value, text)
        else:
            raise RobotDescriptionError(f"robot name {text!r}: unknown option {opt!r}; the form is {ROBOT_NAME_HELP}")
    return base, tool, payload


def _parse_payload(value: str, text: str) -> Payload:
    mass, _, offset = value.partition("@")
    try:
        xyz = tuple(float(x) for x in offset.split(",")) if offset else (0.0, 0.0, 0.0)
        return as_payload((float(mass), xyz))
    except ValueError as err:
        raise RobotDescriptionError(f"robot name {text!r}: payload {value!r} is not KG or KG@X,Y,Z ({err})") from err


def as_payload(payload) -> Payload | None:
    """A :class:`Payload` from itself, ``(mass_kg, (dx, dy, dz))``, ``{"mass": .., "offset": [..]}`` or None;
    None for zero mass (nothing mounted)."""
    if payload is None:
        return None
    if isinstance(payload, dict):
        unknown = sorted(set(payload) - {"mass", "offset"})
        if unknown or "mass" not in payload:
            raise RobotDescriptionError(f"payload {payload!r} needs mass [kg] and may have offset [m] (got {unknown})")
        payload = (payload["mass"], payload.get("offset", (0.0, 0.0, 0.0)))
    if not isinstance(payload, Payload):
        mass, offset = payload
        payload = Payload(float(mass), tuple(float(x) for x in offset))
    if len(payload.offset) != 3 or not all(math.isfinite(x) for x in (payload.mass, *payload.offset)):
        raise RobotDescriptionError(f"payload {payload}: mass [kg] and a 3-vector offset [m], all finite")
    if payload.mass < 0:
        raise RobotDescriptionError(f"payload mass must be >= 0 kg, got {payload.mass}")
    return payload if payload.mass > 0 else None


def _unknown_robot(base: str) -> RobotDescriptionError:
    return RobotDescriptionError(
        f"unknown robot {base!r}. A robot name is: a description in {robots_dir()} "
        f"({', '.join(available_robots()) or 'none'}); an arm of example-robot-data "
        f"({', '.join(example_robot_data_arms()) or 'none'}); a name known for data only "
        f"({', '.join(data_only_robots()) or 'none'}; add yours to robots/data_only.toml); or the path of a .urdf "
        f"or .toml file. A variant: {ROBOT_NAME_HELP}"
    )


def resolve_robot(name: str | os.PathLike, tool=None, payload=None) -> RobotRef:
    """What the robot name ``name`` stands for; raises RobotDescriptionError for a name
    the toolkit cannot serve, before any work. One answer for every caller.

    name: see :data:`ROBOT_NAME_HELP`; ``tool`` and ``payload`` give the variant as
    arguments instead (not both ways at once). The base name is looked up in this
    order: a ``robots/<name>.toml``, robots/data_only.toml, an example-robot-data
    URDF (``ur10``); a ``.toml`` or ``.urdf`` path is read as such.
    """
    if not isinstance(name, (str, os.PathLike)):
        raise RobotDescriptionError(f"a robot name is text, got {name!r}; the form is {ROBOT_NAME_HELP}")
    text = os.fspath(name)
    base, name_tool, name_payload = parse_robot_name(text)
    payload = as_payload(payload)
    if tool is not None and name_tool is not None and str(tool) != name_tool:
        raise RobotDescriptionError(f"robot {text!r} names tool {name_tool!r}, and tool={str(tool)!r} was given too")
    if payload is not None and name_payload is not None and payload != name_payload:
        raise RobotDescriptionError(f"robot {text!r} names a payload, and payload={payload} was given too")
    tool = tool if tool is not None else name_tool
    payload = payload if payload is not None else name_payload

    p = Path(base)
    if p.suffix == ".toml":
        source, spec = "robots", load_spec(p)
    elif p.suffix == ".urdf":
        if not p.is_file():
            raise RobotDescriptionError(f"robot URDF not found: {p.resolve()}")
        source, spec = "urdf", describe_urdf(p)
    elif base in available_robots():
        source, spec = "robots", load_spec(base)
    elif base in data_only_robots():
        if tool is not None or payload is not None:
            raise RobotDescriptionError(f"robot {base!r} is known for data only (no URDF): it takes no tool or payload")
        return RobotRef(base, RobotVariant(), None, "data-only")
    elif base in _example_robot_data_urdfs():
        files = _example_robot_data_urdfs()[base]
        if len(files) > 1:
            raise RobotDescriptionError(f"example-robot-data has {len(files)} URDFs named {base!r} "
                                        f"({', '.join(map(str, files))}): give the path of one")
        # One name per arm, so that its models and caches agree: the robots/ description of the
        # same URDF ("ur5_robot" is "ur5"), else the shortest ("ur10", not "ur10_robot").
        for described in available_robots():
            if load_spec(described).urdf_path == files[0]:
                return resolve_robot(described, tool=tool, payload=payload)
        short = min((n for n, fs in _example_robot_data_urdfs().items() if fs == files), key=lambda n: (len(n), n))
        source, spec = "example-robot-data", describe_urdf(files[0], short)
    else:
        raise _unknown_robot(base)
    spec = with_tool(spec, tool)
    variant = RobotVariant(spec.tool, payload)
    return RobotRef(spec.name + variant.suffix(), variant, spec, source)


def has_description(name) -> bool:
    """Whether robot ``name`` has a model (a URDF): what an analytic part or a base-sensor tare needs.
    A name the toolkit cannot resolve counts as a data-only arm (False), not as an error."""
    try:
        return resolve_robot(name).described
    except RobotDescriptionError:
        return False
