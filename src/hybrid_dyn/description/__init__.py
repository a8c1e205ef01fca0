"""Robot descriptions: which URDF, which frames, which parameter sets.

A robot is described by a small TOML file in the ``robots/`` folder that ships inside
the package (``hybrid_dyn/resources/robots``, see its ``panda.toml``; ``$HYBRID_DYN_ROBOTS``
names another folder). This package reads those files, finds the URDF inside
the installed ``example-robot-data`` package, and rewrites the URDF text when a
different parameter set or a payload is asked for.

Both engines (Pinocchio for the analytic model, DART for the simulated plant)
are built from the *same* URDF string produced here, so a plant and a model can
only differ where a scenario says they should.

Modules, by concept: :mod:`.locations` (where descriptions are found),
:mod:`.params` (parameter sets and friction), :mod:`.spec` (a robot's TOML),
:mod:`.urdf` (the URDF text), :mod:`.tools` (tools on the flange),
:mod:`.discovery` (a URDF on its own, example-robot-data's arms), :mod:`.joints`
(the moving joints and their limits) and :mod:`.names` (the robot-name grammar). Every public name is importable from
here, as it was when this was one module.
"""
from __future__ import annotations

from .base import RobotDescriptionError
from .discovery import describe_urdf, example_robot_data_arms
from .joints import JointLimits, joint_limits
from .locations import example_robot_data_dir, robots_dir
from .names import (ROBOT_NAME_HELP, RobotRef, RobotVariant, as_payload, has_description, parse_robot_name,
                    resolve_robot)
from .params import GazFriction, LinkInertial, read_param_file
from .spec import (Payload, RobotSpec, available_robots, data_only_robots, known_robots, load_spec,
                   resolve_encoder_resolution)
from .tools import ToolUrdf, read_tool, with_tool
from .urdf import build_urdf, urdf_with_payload

__all__ = [
    "ROBOT_NAME_HELP", "GazFriction", "JointLimits", "LinkInertial", "Payload", "RobotDescriptionError",
    "RobotRef", "RobotSpec", "RobotVariant", "ToolUrdf", "as_payload", "available_robots", "build_urdf",
    "data_only_robots", "describe_urdf", "example_robot_data_arms", "example_robot_data_dir", "has_description",
    "joint_limits", "known_robots", "load_spec", "parse_robot_name", "read_param_file", "read_tool",
    "resolve_encoder_resolution", "resolve_robot", "robots_dir", "urdf_with_payload", "with_tool",
]
