"""Where descriptions are found: the robot TOML files and example-robot-data's URDFs."""
from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path

from ..resources import resource_dir
from .base import RobotDescriptionError


def robots_dir() -> Path:
    """The folder of ``<name>.toml`` robot descriptions: ``$HYBRID_DYN_ROBOTS`` (a user's own, which the
    catalogue ``robots.py`` declares beside the shipped ones), else the folder the shipped ones are in
    (``hybrid_dyn/resources/robots``, package data: an installed toolkit has them too).
    """
    env = os.environ.get("HYBRID_DYN_ROBOTS")
    if env:
        return Path(env)
    return resource_dir("robots")


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
