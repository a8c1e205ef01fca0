"""A robot's description as its TOML file gives it (:class:`RobotSpec`), read by name (``ROBOTS``) or path."""
from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .base import RobotDescriptionError
from .locations import example_robot_data_dir
from .params import GazFriction
from .robots import ROBOTS


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
    # The joint encoders' resolution [rad per count], as the arm reports q (TOML ``encoder_resolution``);
    # 0.0 where the description states none. The streaming estimator's joint-state filter and the
    # simulator's hardware encoder read it (``sim/sensors.py``).
    encoder_resolution: float = 0.0
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
    # Joints with a gravity-assist spring the URDF lacks (TOML ``[identification] springs``): the
    # identified model gives each a torque k q_j [Nm] with k identified (Baxter's shoulder s1).
    springs: tuple = ()
    # The arm's rated payload [kg] (TOML ``rated_payload_kg``); None where the description states none.
    rated_payload_kg: float | None = None
    # The stated 1-sigma relative uncertainty of every link's inertial parameters (TOML ``inertial_uncertainty``),
    # the streaming estimator's model term where no calibration is given (``estimator/model_term.py``); None where
    # the description states none (the estimator then assumes an unidentified arm's).
    inertial_uncertainty: float | None = None

    def friction(self, name: str = "gaz2019") -> GazFriction | None:
        """The named friction law, or None when this robot ships none."""
        path = self.friction_files.get(name)
        return GazFriction.from_json(path) if path else None


def resolve_encoder_resolution(setting, spec: RobotSpec) -> float:
    """The joint-encoder resolution [rad per count] a setting means on the robot ``spec`` describes: "auto" is the
    description's ``encoder_resolution``, a number is itself (0: q read exactly). The one place "auto" is resolved:
    the estimator, the batch run, the simulator's encoders and the generator's config call it."""
    return float(spec.encoder_resolution if isinstance(setting, str) and setting == "auto" else setting)


def _description_file(name_or_path: str | os.PathLike) -> Path:
    """The TOML of a robot declared in ``ROBOTS``, or the ``.toml`` path given; refused where there is none."""
    p = Path(name_or_path)
    toml_path = p if p.suffix == ".toml" else ROBOTS.lookup(str(name_or_path)).toml
    if toml_path is None:
        raise RobotDescriptionError(f"robot {str(name_or_path)!r} is known for data only: it has no description")
    if not toml_path.is_file():
        raise RobotDescriptionError(f"robot {str(name_or_path)!r}: no description file {toml_path}")
    return toml_path


def load_spec(name_or_path: str | os.PathLike) -> RobotSpec:
    """Read a robot description by name (``"panda"``, declared in ``ROBOTS``) or TOML path."""
    toml_path = _description_file(name_or_path)
    try:
        doc = tomllib.loads(toml_path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise RobotDescriptionError(f"{toml_path} is not valid TOML: {err}") from err
    for key in ("name", "urdf", "tool_frame", "base_sensor_frame"):
        if key not in doc:
            raise RobotDescriptionError(f"{toml_path} lacks the key {key!r}")
    if Path(name_or_path).suffix != ".toml" and doc["name"] != str(name_or_path):  # a model file names the robot by its TOML's name
        raise RobotDescriptionError(f"robot {str(name_or_path)!r} is declared with {toml_path}, which describes "
                                    f"{doc['name']!r}: the two names must agree")
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
        encoder_resolution=float(doc.get("encoder_resolution", 0.0)),
        param_sets={k: here / v for k, v in params.items()},
        default_params=default_params,
        friction_files={k: here / v for k, v in doc.get("friction", {}).items()},
        source=toml_path,
        flange=doc.get("flange"),
        default_tool=str(doc.get("tool", "none")),
        springs=tuple(doc.get("identification", {}).get("springs", ())),
        rated_payload_kg=float(doc["rated_payload_kg"]) if "rated_payload_kg" in doc else None,
        inertial_uncertainty=float(doc["inertial_uncertainty"]) if "inertial_uncertainty" in doc else None,
    )
