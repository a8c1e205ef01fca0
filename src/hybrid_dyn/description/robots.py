"""The robot catalogue: every robot the toolkit knows by name, declared once in :data:`ROBOTS`."""
from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..registry import Registry
from ..resources import resource_dir
from .base import RobotDescriptionError
from .locations import robots_dir


@dataclass(frozen=True)
class RobotDeclaration:
    """A robot name: its description TOML (URDF, frames, parameter sets; see ``resources/robots/panda.toml``),
    or None for an arm known for data only (no URDF: only data-only models apply to it).

    summary: one line on the arm (what a data-only name stands for)."""

    name: str
    toml: Path | None = None
    summary: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise RobotDescriptionError(f"a robot's name is non-empty text, got {self.name!r}")
        if self.toml is not None:
            if Path(self.toml).suffix != ".toml":
                raise RobotDescriptionError(f"robot {self.name!r}: its description is a .toml file, got {self.toml}")
            object.__setattr__(self, "toml", Path(self.toml))

    @property
    def data_only(self) -> bool:
        """Whether the arm has no description: a model file may name it, no analytic model applies."""
        return self.toml is None


ROBOTS = Registry("robot", RobotDescriptionError)


def declare_robot_folder(folder: str | os.PathLike) -> list[RobotDeclaration]:
    """Declare a folder's robots: each ``<name>.toml`` a description, each name of its ``data_only.toml``
    (``[robots] name = "summary"``) a data-only arm. A name declared already (a shipped robot) is replaced by
    the folder's, so that a folder may hold a changed copy of a shipped description."""
    folder = Path(folder)
    found = [RobotDeclaration(p.stem, p) for p in sorted(folder.glob("*.toml")) if p.stem != "data_only"]
    listed = folder / "data_only.toml"
    if listed.is_file():
        try:
            names = tomllib.loads(listed.read_text()).get("robots", {})
        except tomllib.TOMLDecodeError as err:
            raise RobotDescriptionError(f"{listed} is not valid TOML: {err}") from err
        if not isinstance(names, dict):
            raise RobotDescriptionError(f"{listed}: [robots] is a table of name = \"what the arm is\"")
        found += [RobotDeclaration(name, None, str(summary)) for name, summary in names.items()]
    for robot in found:
        if robot.name in ROBOTS:
            ROBOTS.unregister(robot.name)
        ROBOTS.register(robot)
    return found


def shipped() -> Path:
    """The folder of the shipped robots (package data, ``hybrid_dyn/resources/robots``)."""
    return resource_dir("robots")


# The shipped robots: every TOML of their folder, by name (a new ``NAME.toml`` there is a robot, no list to edit).
declare_robot_folder(shipped())
ROBOTS.register(RobotDeclaration("sarcos", None, "SARCOS anthropomorphic arm, 7 joints: the real-sarcos import spec "
                                 "(resources/real/sarcos.toml); its kinematics are not published, so it stays "
                                 "data-only"))
ROBOTS.register(RobotDeclaration("unknown", None, "an arm the log does not name (the import spec's default robot)"))

# The folder ``$HYBRID_DYN_ROBOTS`` names (a user's own descriptions): read once, when the catalogue is first
# imported; a folder named later is declared with declare_robot_folder.
if robots_dir() != shipped():
    declare_robot_folder(robots_dir())
