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
import importlib.metadata
import json
import math
import os
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


class RobotDescriptionError(HybridDynError, ValueError):
    """A robot name, frame, URDF or parameter file is missing or inconsistent."""


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
    urdf = example_robot_data_dir() / doc["urdf"]
    if not urdf.is_file():
        raise RobotDescriptionError(f"{toml_path}: URDF {doc['urdf']!r} is not in example-robot-data ({urdf})")
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
    )


# ---------------------------------------------------------------------- URDF text
def build_urdf(spec: RobotSpec, params: str | os.PathLike | None = None, payload: Payload | None = None) -> str:
    """The URDF text for ``spec`` with a parameter set and a payload applied.

    Visual and collision geometry is removed (neither engine needs meshes for
    dynamics, and DART would otherwise try to resolve ``package://`` URIs), and
    URDF joint damping/friction is zeroed: Pinocchio ignores it while DART would
    apply it, so friction is modelled explicitly instead (``GazFriction``).
    """
    root = ET.fromstring(spec.urdf_path.read_text())
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
        if jname not in joints:
            raise RobotDescriptionError(f"locked joint {jname!r} of robot {spec.name!r} is not in the URDF")
        _lock_joint(joints[jname], value)

    param_file = _resolve_params(spec, params)
    if param_file is not None:
        for li in read_param_file(param_file):
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
