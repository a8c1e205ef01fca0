"""The robot-name grammar: ``NAME[tool=...;payload=...]``, and what a name stands for (:func:`resolve_robot`)."""
from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

from .base import RobotDescriptionError
from .discovery import _example_robot_data_urdfs, describe_urdf, example_robot_data_arms
from .locations import example_robot_data_dir
from .robots import ROBOTS, shipped
from .spec import Payload, RobotSpec, load_spec
from .tools import with_tool


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
        f"unknown robot {base!r}. A robot name is: a declared description "
        f"({', '.join(ROBOTS.names(data_only=False)) or 'none'}); an arm of example-robot-data "
        f"({', '.join(example_robot_data_arms()) or 'none'}); a name known for data only "
        f"({', '.join(ROBOTS.names(data_only=True)) or 'none'}); or the path of a .urdf or .toml file. "
        f"A robot of your own is a NAME.toml in the folder $HYBRID_DYN_ROBOTS names (docs/extending.md, "
        f"\"A robot\"), or a plugin's. A variant: {ROBOT_NAME_HELP}"
    )


_SHADOWS_CHECKED: set[str] = set()


def _warn_if_shadowing(name: str, spec: RobotSpec) -> None:
    """A user's or a plugin's robot named as an arm of example-robot-data whose URDF is another: ``name`` then
    means that declaration's arm, not example-robot-data's, which may well be a mistake; warned once per name.
    A declaration of the same URDF (a description with frames, encoders and a rated payload) says nothing."""
    if name in _SHADOWS_CHECKED or ROBOTS[name].toml.parent == shipped():
        return
    _SHADOWS_CHECKED.add(name)
    root = example_robot_data_dir()
    theirs = [f for file in (f"{name}.urdf", f"{name}_robot.urdf") for f in sorted(root.rglob(file))]
    if theirs and spec.urdf_path.resolve() not in {f.resolve() for f in theirs}:
        warnings.warn(f"robot {name!r} ({ROBOTS[name].toml}) shadows example-robot-data's {name!r} "
                      f"({theirs[0]}): load_robot({name!r}) is the declared arm, on {spec.urdf_path}",
                      UserWarning, stacklevel=3)


def resolve_robot(name: str | os.PathLike, tool=None, payload=None) -> RobotRef:
    """What the robot name ``name`` stands for; raises RobotDescriptionError for a name
    the toolkit cannot serve, before any work. One answer for every caller.

    name: see :data:`ROBOT_NAME_HELP`; ``tool`` and ``payload`` give the variant as
    arguments instead (not both ways at once). The base name is looked up in this
    order: a described robot of ``ROBOTS``, a data-only one, an example-robot-data
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
    # Declared: by the shipped folder, $HYBRID_DYN_ROBOTS or an installed plugin (a miss loads the plugins).
    declared = p.suffix not in (".toml", ".urdf") and not ROBOTS.missing([base])
    if p.suffix == ".toml":
        source, spec = "robots", load_spec(p)
    elif p.suffix == ".urdf":
        if not p.is_file():
            raise RobotDescriptionError(f"robot URDF not found: {p.resolve()}")
        source, spec = "urdf", describe_urdf(p)
    elif declared and not ROBOTS[base].data_only:
        source, spec = "robots", load_spec(base)
        _warn_if_shadowing(base, spec)
    elif declared:
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
        for described in ROBOTS.where(data_only=False):
            if load_spec(described.name).urdf_path == files[0]:
                return resolve_robot(described.name, tool=tool, payload=payload)
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
