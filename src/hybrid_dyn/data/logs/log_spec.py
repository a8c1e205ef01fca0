"""A log import's spec: what a log holds and how to import it (``docs/bring_your_own_log.md``).

:class:`LogSpec` is given as keyword arguments of ``import_log`` or as a small TOML file
(:func:`read_spec`, :func:`spec_from_dict`); it is checked whole when it is made, before
any file is read. The importer's errors live here too (every step raises them).
"""
from __future__ import annotations

import os
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..data_checks import split_problems
from ..dataset import DatasetError
from ..derivatives import DerivativeFilter
from .spec_checks import spec_type_problems
from ..splits import SPLIT_NAMES, SplitSpec

# Signals a spec may map: the dataset fields (but t) and the next-sample columns.
SIGNALS = ("q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force", "q_next", "qd_next")
JOINT_SIGNALS = ("q", "qd", "qdd", "tau_m", "tau_J", "q_next", "qd_next")
ANGLE_SIGNALS = ("q", "qd", "qdd", "q_next", "qd_next")
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
TRAJECTORY_MODES = ("tables", "blocks", "column")


class LogImportError(DatasetError):
    """Importing a log failed; the message names the problem."""


class LogSpecError(LogImportError):
    """The import spec (TOML file or arguments) is invalid."""


class MissingColumnError(LogImportError):
    """A column that the spec maps is not in the log."""


class TooManyRowsDroppedError(LogImportError):
    """More rows failed validation than ``max_drop_fraction`` allows: a systematic problem."""


class StrictImportError(LogImportError):
    """``strict`` import and the log has row problems."""


@dataclass
class ValidationChecks:
    """Row checks and their thresholds.

    ``q_abs_max`` [rad]: a joint position beyond it is taken for a unit mistake
    (degrees logged as radians); when the robot has a description in
    ``robots/``, its joint limits + ``limit_margin`` [rad] are used instead.
    ``qd_abs_max`` [rad/s]: the same for velocities. ``jump_factor``: a time step
    longer than this many median steps is a gap. ``next_tol`` [rad, rad/s]: how
    far the logged next sample may be from the next row. ``max_drop_fraction``:
    above this fraction of dropped rows the import fails, since the log (or the
    spec) is systematically wrong. ``timebase_tol``: relative disagreement
    between d(q)/dt and the logged qd that raises a warning. ``channel_scale_factor``: a joint's torque
    channel whose spread, relative to its joint's effort limit, is below this fraction of the joints'
    median is warned of as dead (``data_checks.channel_problems``; a constant channel always is).
    """

    q_abs_max: float = 2 * np.pi
    qd_abs_max: float = 20.0
    limit_margin: float = 0.2
    jump_factor: float = 3.0
    next_tol: float = 1e-6
    max_drop_fraction: float = 0.05
    timebase_tol: float = 0.05
    channel_scale_factor: float = 1e-3


# A ROS bag's spec ([ros]): its resampling rules, and the wrench topics with the fields they fill.
RESAMPLE_RULES = ("linear", "nearest")
WRENCH_TOPICS = {"base_wrench": "base_wrench", "tip_wrench": "tip_force"}


@dataclass
class RosTopics:
    """A spec's ``[ros]`` table: which topics hold what.

    ``joint_states``: a ``sensor_msgs/JointState`` topic: q [rad] from position, qd [rad/s] from
    velocity, the joint torque [Nm] from effort, matched by joint name. ``effort``: which field the effort
    fills: "tau_m" (the logged joint torque: what the joint-torque rows predict; the default), "tau_J" (the
    link-side torque sensors, which the momentum observer and kalman-fusion read: franka_ros publishes
    the Panda's measured tau_J as effort) or both, ["tau_m", "tau_J"]. ``base_wrench``: a
    ``geometry_msgs/WrenchStamped`` topic of the base force/torque sensor [N, Nm] (the ground's wrench
    on the robot, in the base-sensor frame); optional. ``tip_wrench``: the same for a tip force sensor
    (ground truth: the force on the robot at the tool point, in the base-sensor frame [N]; its moment is
    not read); optional. ``frame``: the frame_id the bag uses for the robot's base-sensor frame, when
    it is not the description's name. ``resample``: "linear" or "nearest" (module docstring).
    ``joints``: the joint names in the robot's order; default the description's (needed for a robot
    without one).
    """

    joint_states: str
    base_wrench: str | None = None
    tip_wrench: str | None = None
    frame: str | None = None
    resample: str = "linear"
    joints: list | None = None
    effort: object = "tau_m"

    def problems(self) -> list[str]:
        out = []
        for key in ("base_wrench", "tip_wrench", "frame"):
            value = getattr(self, key)
            if value is not None and not isinstance(value, str):
                out.append(f"[ros] {key} must be text, got {value!r}")
        if not (isinstance(self.joint_states, str) and self.joint_states):
            out.append(f"[ros] joint_states must name a topic, got {self.joint_states!r}")
        if self.torque_fields() is None:
            out.append(f"[ros] effort must be \"tau_m\", \"tau_J\" or [\"tau_m\", \"tau_J\"], got {self.effort!r}")
        if self.resample not in RESAMPLE_RULES:
            out.append(f"[ros] resample must be one of {RESAMPLE_RULES}, got {self.resample!r}")
        if self.joints is not None and not (isinstance(self.joints, list) and self.joints
                                            and all(isinstance(j, str) for j in self.joints)):
            out.append(f"[ros] joints must be a list of joint names, got {self.joints!r}")
        return out

    def torque_fields(self) -> list | None:
        """The fields the effort fills, or None if ``effort`` names something else."""
        fields = [self.effort] if isinstance(self.effort, str) else self.effort
        ok = isinstance(fields, list) and fields and all(f in ("tau_m", "tau_J") for f in fields)
        return sorted(set(fields)) if ok else None

    def columns(self) -> dict:
        """The signal -> column map of the tables :func:`read_bags` makes."""
        cols = {"q": "q", "qd": "qd", **{k: k for k in self.torque_fields()}}
        cols.update({WRENCH_TOPICS[k]: WRENCH_TOPICS[k] for k in WRENCH_TOPICS if getattr(self, k)})
        return cols


@dataclass
class LogSpec:
    """What a log holds and how to import it (see the module docstring).

    ``columns``: signal -> column reference: a 1-based column number, a range
    string ``"1-7"``, a column name, the name of a 2-D array (all its columns),
    or a list of those. ``time``: a time column reference, or ``None`` with
    ``sample_rate_hz``. ``trajectories``: ``"tables"`` (one per .mat/npz
    variable or file), ``"blocks"`` (``n_blocks`` contiguous blocks of each
    table) or ``"column"`` (one per value of ``trajectory_column``).
    """

    name: str
    files: list
    columns: dict
    robot: str = "unknown"
    format: str | None = None
    variables: str | None = None
    delimiter: str | None = None
    time: object = None
    time_unit: str = "s"
    sample_rate_hz: float | None = None
    trajectories: str = "tables"
    n_blocks: int = 10
    trajectory_column: object = None
    angle_unit: str = "rad"
    derivatives: DerivativeFilter = field(default_factory=DerivativeFilter)
    checks: ValidationChecks = field(default_factory=ValidationChecks)
    split_seed: int = 0
    test_frac: float = 0.2
    val_frac: float = 0.2
    split_by: str = "random"  # splits.SPLIT_MODES: "random", "time" (in time order) or "list"
    split_lists: dict = field(default_factory=dict)  # by = "list": split -> trajectory names
    notes: str = ""
    # How the arm's interface delivers q and qd, for the streaming estimator ([encoders] resolution): "auto" the
    # robot description's encoder model (q quantized, qd its difference); 0: q and qd as the arm gives them (a
    # Panda's libfranka dq, KUKA's FRI, Baxter's joint_states: the robot's own velocity, no difference of q).
    encoder_resolution: float | str = "auto"
    spec_file: str | None = None
    ros: object = None  # a ROS bag's topics (ros_bag.RosTopics, the TOML's [ros]): they set columns and time


    def __post_init__(self):
        from ...description import resolve_robot

        # The robot first, before anything is read: one RobotDescriptionError listing the names
        # accepted; a variant's name is made canonical ("panda[tool=hand]" is "panda").
        self.robot = resolve_robot(self.robot).name
        files = [self.files] if isinstance(self.files, (str, Path)) else self.files
        if not isinstance(files, list) or not all(isinstance(f, (str, Path)) for f in files):
            raise LogSpecError(f"invalid import spec: files must be a path or a list of paths, got {self.files!r}")
        self.files = [Path(f) for f in files]
        ros_problems = self._ros_columns()
        if ros_problems:  # alone: the column checks below would only repeat them
            raise LogSpecError("invalid import spec: " + "; ".join(ros_problems))
        try:
            if isinstance(self.derivatives, dict):
                self.derivatives = DerivativeFilter(**self.derivatives)
            if isinstance(self.checks, dict):
                self.checks = ValidationChecks(**self.checks)
        except TypeError as err:  # unknown keys in [derivatives] or [checks]
            raise LogSpecError(f"invalid import spec: {err}") from None
        problems = spec_type_problems(self)  # types first: the checks below compare values
        if problems:
            raise LogSpecError("invalid import spec: " + "; ".join(problems))
        if not self.files:
            problems.append("no log files given")
        unknown = sorted(set(self.columns) - set(SIGNALS))
        if unknown:
            problems.append(f"unknown signals {unknown} in columns (known: {list(SIGNALS)})")
        if "q" not in self.columns:
            problems.append("columns must map q (joint positions)")
        if not ({"tau_m", "tau_J"} & set(self.columns)):
            problems.append("columns must map a joint torque: tau_m (the logged torque) or tau_J")
        if (self.time is None) == (self.sample_rate_hz is None):
            problems.append("give exactly one of a time column (time) and a sample rate (sample_rate_hz)")
        if self.sample_rate_hz is not None and not self.sample_rate_hz > 0:
            problems.append(f"sample_rate_hz must be > 0, got {self.sample_rate_hz}")
        if self.time_unit not in TIME_UNITS:
            problems.append(f"time_unit must be one of {list(TIME_UNITS)}, got {self.time_unit!r}")
        if self.trajectories not in TRAJECTORY_MODES:
            problems.append(f"trajectories must be one of {TRAJECTORY_MODES}, got {self.trajectories!r}")
        if self.trajectories == "column" and self.trajectory_column is None:
            problems.append("trajectories = 'column' needs trajectory_column")
        if self.trajectories == "blocks" and self.n_blocks < 1:
            problems.append(f"n_blocks must be >= 1, got {self.n_blocks}")
        if self.angle_unit not in ("rad", "deg"):
            problems.append(f"angle_unit must be 'rad' or 'deg', got {self.angle_unit!r}")
        problems += split_problems(self.split_seed, self.test_frac, self.val_frac)  # types first: a bad value was a traceback
        problems += self.split_spec.problems()
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", self.name or ""):
            problems.append(f"name {self.name!r} must be letters, digits, '_', '.', '-'")
        if problems:
            raise LogSpecError("invalid import spec: " + "; ".join(problems))

    def _ros_columns(self) -> list[str]:
        """A bag's spec names topics, not columns: the columns and time are those of the table that
        ``ros_bag.read_bags`` makes. Returns the problems of the [ros] table."""
        if self.ros is None:
            return []
        if isinstance(self.ros, dict):
            try:
                self.ros = RosTopics(**self.ros)
            except TypeError as err:  # unknown or missing keys
                return [f"[ros]: {err}"]
        if not isinstance(self.ros, RosTopics):
            return [f"ros must be a [ros] table of topics, got {self.ros!r}"]
        problems = self.ros.problems()
        if self.columns or self.time is not None or self.sample_rate_hz is not None:
            problems.append("a ROS bag's spec names topics in [ros], not [columns] or [time]")
        if self.format not in (None, "ros"):
            problems.append(f"format must be 'ros' (or none) with a [ros] table, got {self.format!r}")
        if not problems:
            self.columns, self.time, self.format = self.ros.columns(), "t", "ros"
        return problems

    @property
    def split_spec(self) -> SplitSpec:
        """The ``[split]`` section: how trajectories go to train, val and test (``data/splits.py``)."""
        return SplitSpec(self.split_by, self.split_seed, self.test_frac, self.val_frac, dict(self.split_lists))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["files"] = [str(f) for f in self.files]
        d["derivatives"] = self.derivatives.to_dict()
        return d


# The TOML spec
_SPEC_LAYOUT = {
    "": {"name", "robot", "tool", "payload", "notes", "source", "env_defaults", "time", "columns", "trajectories", "units",
         "derivatives", "checks", "split", "ros", "encoders"},
    "encoders": {"resolution"},
    "source": {"files", "format", "variables", "delimiter"},
    "time": {"column", "unit", "sample_rate_hz"},
    "trajectories": {"from", "n_blocks", "column"},
    "units": {"angle"},
    "split": {"seed", "test_frac", "val_frac", "by", *SPLIT_NAMES},
    "ros": {"joint_states", "base_wrench", "tip_wrench", "frame", "resample", "joints", "effort"},
}


def read_spec(path) -> LogSpec:
    """Read a TOML import spec. Relative file paths are relative to the spec file;
    ``${VAR}`` expands from the environment, else from the spec's ``[env_defaults]``
    (whose relative paths are also relative to the spec file)."""
    import tomllib  # Python >= 3.11

    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise LogSpecError(f"import spec {path} does not exist") from None
    except tomllib.TOMLDecodeError as err:
        raise LogSpecError(f"import spec {path} is not valid TOML: {err}") from err
    return spec_from_dict(doc, base_dir=path.parent, spec_file=path)


def spec_from_dict(doc: dict, base_dir=".", spec_file=None) -> LogSpec:
    base_dir = Path(base_dir)
    where = f" in {spec_file}" if spec_file else ""
    for section, allowed in _SPEC_LAYOUT.items():
        table = doc if section == "" else doc.get(section, {})
        if not isinstance(table, dict):
            raise LogSpecError(f"[{section}]{where} must be a table")
        unknown = sorted(set(table) - allowed)
        if unknown:
            raise LogSpecError(f"unknown keys {unknown} in [{section or 'top level'}]{where}; allowed: {sorted(allowed)}")
    for section in ("columns", "derivatives", "checks", "env_defaults"):  # tables with free keys
        if not isinstance(doc.get(section, {}), dict):
            raise LogSpecError(f"[{section}]{where} must be a table")
    env_defaults = doc.get("env_defaults", {})

    def expand(s: str) -> Path:
        def sub(m):
            var = m.group(1)
            if var in os.environ:
                return os.environ[var]
            if var in env_defaults:
                return str((base_dir / env_defaults[var]).resolve())
            raise LogSpecError(f"${{{var}}}{where} is neither set in the environment nor in [env_defaults]")

        p = Path(re.sub(r"\$\{(\w+)\}", sub, s))
        return p if p.is_absolute() else (base_dir / p).resolve()

    src, time, traj = doc.get("source", {}), doc.get("time", {}), doc.get("trajectories", {})
    files = src.get("files")
    if files is None:
        raise LogSpecError(f"[source] files is missing{where}")
    if not (isinstance(files, str) or (isinstance(files, list) and all(isinstance(f, str) for f in files))):
        raise LogSpecError(f"[source] files{where} must be a path or a list of paths, got {files!r}")
    if not isinstance(env_defaults, dict) or not all(isinstance(v, str) for v in env_defaults.values()):
        raise LogSpecError(f"[env_defaults]{where} must be a table of NAME = \"path\"")
    split = doc.get("split", {})
    lists = {k: split[k] for k in SPLIT_NAMES if k in split}
    robot, tool = doc.get("robot", "unknown"), doc.get("tool")
    # A robot's URDF and a tool's are files of the spec too: relative to it, ${VAR} expanded.
    if isinstance(robot, str) and Path(robot).suffix in (".urdf", ".toml"):
        robot = str(expand(robot))
    if isinstance(tool, str) and Path(tool).suffix == ".urdf":
        tool = str(expand(tool))
    if tool is not None or "payload" in doc:  # the variant, folded into the robot's name
        from ...description import resolve_robot

        robot = resolve_robot(robot, tool=tool, payload=doc.get("payload")).name
    try:
        return LogSpec(
            name=doc.get("name", ""), robot=robot, notes=doc.get("notes", ""),
            files=[expand(f) for f in ([files] if isinstance(files, str) else files)],
            format=src.get("format"), variables=src.get("variables"), delimiter=src.get("delimiter"),
            columns=dict(doc.get("columns", {})),
            time=time.get("column"), time_unit=time.get("unit", "s"), sample_rate_hz=time.get("sample_rate_hz"),
            trajectories=traj.get("from", "tables"), n_blocks=traj.get("n_blocks", 10),
            trajectory_column=traj.get("column"), angle_unit=doc.get("units", {}).get("angle", "rad"),
            derivatives=DerivativeFilter(**doc.get("derivatives", {})),
            checks=ValidationChecks(**doc.get("checks", {})),
            split_seed=split.get("seed", 0), test_frac=split.get("test_frac", 0.2), val_frac=split.get("val_frac", 0.2),
            # Lists of trajectories imply by = "list"; a "by" that contradicts them is refused (data/splits.py).
            split_by=split.get("by", "list" if lists else "random"), split_lists=lists,
            spec_file=str(spec_file) if spec_file else None,
            ros=dict(doc["ros"]) if "ros" in doc else None,
            encoder_resolution=doc.get("encoders", {}).get("resolution", "auto"),
        )
    except TypeError as err:  # unknown keys in [derivatives] or [checks]
        raise LogSpecError(f"invalid import spec{where}: {err}") from err
