"""Importing real robot logs into the toolkit's dataset format.

A log (CSV, npz, MATLAB .mat or Parquet) is described by a :class:`LogSpec`:
which file(s), which columns hold which signal, where time comes from, what a
trajectory is. The spec is given as keyword arguments of :func:`import_log` or as
a small TOML file (:func:`read_spec`; the format is in ``docs/bring_your_own_log.md``).
The importer then

1. reads the tables (:mod:`.log_readers`) and cuts them into trajectories
   (one per variable or file, per value of a trajectory-id column, or contiguous
   blocks of one table);
2. validates every row and reports what it finds *by row* in an
   :class:`ImportReport`: unreadable or NaN cells, time that does not increase,
   gaps in time, values out of range (degrees logged as radians), and, when the
   log carries the next sample of each row, rows whose successor is not the
   logged next sample. A bad row is dropped and counted; a gap splits the
   trajectory into segments (a derivative filter must not run across it);
   nothing is dropped without an entry in the report;
3. estimates velocities when missing and accelerations always (unless the log
   has them) with a zero-phase filter, segment by segment (:mod:`.derivatives`);
4. writes a dataset (instances = segments, splits by trajectory, so all segments
   of one trajectory are in one split: at random, in time order or as listed,
   :mod:`.splits`) with the report in the manifest.

Units after import are the toolkit's SI units (``FIELD_UNITS``): t [s], q [rad],
qd [rad/s], qdd [rad/s^2], torques [Nm]. ``tau_m`` is the logged joint torque.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .dataset import (
    FIELD_UNITS, DatasetError, package_versions, sha256_file, write_instance, write_manifest,
)
from .derivatives import DerivativeFilter, differentiate
from .log_readers import LogTable, natural_key, read_log
from ..input_checks import angle_unit_problems, empty_split_problems, split_problems
from .spec_checks import spec_type_problems
from .splits import SPLIT_NAMES, SplitSpec, split_trajectories
from ..outputs import output_lock, refuse_foreign, unique_temp

IMPORTER_VERSION = 1

# Signals a spec may map: the dataset fields (but t) and the next-sample columns.
SIGNALS = ("q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force", "q_next", "qd_next")
JOINT_SIGNALS = ("q", "qd", "qdd", "tau_m", "tau_J", "q_next", "qd_next")
ANGLE_SIGNALS = ("q", "qd", "qdd", "q_next", "qd_next")
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
TRAJECTORY_MODES = ("tables", "blocks", "column")
# Issue kinds; all but the last two drop the row.
DROP_KINDS = ("missing_cells", "nan", "time_order", "unit_range", "short_segment")
SPLIT_KINDS = ("time_jump", "discontinuity")


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
    between d(q)/dt and the logged qd that raises a warning.
    """

    q_abs_max: float = 2 * np.pi
    qd_abs_max: float = 20.0
    limit_margin: float = 0.2
    jump_factor: float = 3.0
    next_tol: float = 1e-6
    max_drop_fraction: float = 0.05
    timebase_tol: float = 0.05


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
    spec_file: str | None = None

    def __post_init__(self):
        from ..description import resolve_robot

        # The robot first, before anything is read: one RobotDescriptionError listing the names
        # accepted; a variant's name is made canonical ("panda[tool=hand]" is "panda").
        self.robot = resolve_robot(self.robot).name
        files = [self.files] if isinstance(self.files, (str, Path)) else self.files
        if not isinstance(files, list) or not all(isinstance(f, (str, Path)) for f in files):
            raise LogSpecError(f"invalid import spec: files must be a path or a list of paths, got {self.files!r}")
        self.files = [Path(f) for f in files]
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
        problems += split_problems(self.split_seed, self.test_frac, self.val_frac)  # issue 28: tracebacks before
        problems += self.split_spec.problems()
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", self.name or ""):
            problems.append(f"name {self.name!r} must be letters, digits, '_', '.', '-'")
        if problems:
            raise LogSpecError("invalid import spec: " + "; ".join(problems))

    @property
    def split_spec(self) -> SplitSpec:
        """The ``[split]`` section: how trajectories go to train, val and test (``splits.py``)."""
        return SplitSpec(self.split_by, self.split_seed, self.test_frac, self.val_frac, dict(self.split_lists))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["files"] = [str(f) for f in self.files]
        d["derivatives"] = self.derivatives.to_dict()
        return d


# ---------------------------------------------------------------------------
# The TOML spec

_SPEC_LAYOUT = {
    "": {"name", "robot", "tool", "payload", "notes", "source", "env_defaults", "time", "columns", "trajectories", "units",
         "derivatives", "checks", "split"},
    "source": {"files", "format", "variables", "delimiter"},
    "time": {"column", "unit", "sample_rate_hz"},
    "trajectories": {"from", "n_blocks", "column"},
    "units": {"angle"},
    "split": {"seed", "test_frac", "val_frac", "by", *SPLIT_NAMES},
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
        from ..description import resolve_robot

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
            # Lists of trajectories imply by = "list"; a "by" that contradicts them is refused (splits.py).
            split_by=split.get("by", "list" if lists else "random"), split_lists=lists,
            spec_file=str(spec_file) if spec_file else None,
        )
    except TypeError as err:  # unknown keys in [derivatives] or [checks]
        raise LogSpecError(f"invalid import spec{where}: {err}") from err


# ---------------------------------------------------------------------------
# The report


@dataclass
class RowIssue:
    """One problem found in one row (``row`` is 1-based within its table, as in
    MATLAB; for CSV, ``line`` is the file line). ``action``: "drop" (row removed),
    "split" (a new segment starts at this row)."""

    source: str
    table: str
    row: int
    kind: str
    detail: str
    action: str
    line: int | None = None
    n_rows: int = 1

    def text(self) -> str:
        at = f"row {self.row}" + (f" (line {self.line})" if self.line is not None else "")
        return f"{Path(self.source).name}:{self.table} {at}: {self.kind}: {self.detail} -> {self.action}"


@dataclass
class ImportReport:
    """What an import read, kept, dropped and why; ``path``: the dataset written."""

    name: str
    path: Path | None = None
    rows_read: int = 0
    rows_kept: int = 0
    trajectories: int = 0
    instances: int = 0
    issues: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def rows_dropped(self) -> int:
        return self.rows_read - self.rows_kept

    def dropped_by_kind(self) -> dict:
        out = {}
        for i in self.issues:
            if i.action == "drop":
                out[i.kind] = out.get(i.kind, 0) + i.n_rows
        return dict(sorted(out.items()))

    def issues_by_kind(self) -> dict:
        out = {}
        for i in self.issues:
            out[i.kind] = out.get(i.kind, 0) + 1
        return dict(sorted(out.items()))

    def rows(self, kind: str | None = None) -> list[int]:
        """The 1-based rows with an issue (of one kind)."""
        return [i.row for i in self.issues if kind is None or i.kind == kind]

    def summary(self) -> dict:
        return {"rows_read": self.rows_read, "rows_kept": self.rows_kept, "rows_dropped": self.rows_dropped,
                "dropped_by_kind": self.dropped_by_kind(), "issues_by_kind": self.issues_by_kind(),
                "n_issues": len(self.issues), "trajectories": self.trajectories, "instances": self.instances,
                "warnings": list(self.warnings)}

    def to_dict(self) -> dict:
        return {"name": self.name, **self.summary(), "issues": [asdict(i) for i in self.issues]}

    def text(self, max_per_kind: int = 20) -> str:
        by_kind = self.dropped_by_kind()
        lines = [f"import {self.name}: {self.rows_read} rows read, {self.rows_kept} kept, {self.rows_dropped} dropped"
                 f"{f' {by_kind}' if by_kind else ''}; {self.trajectories} trajectories, {self.instances} instances"]
        lines += [f"warning: {w}" for w in self.warnings]
        for kind, n in self.issues_by_kind().items():
            shown = [i for i in self.issues if i.kind == kind][:max_per_kind]
            lines.append(f"{kind}: {n} issues" + (f" (first {len(shown)})" if n > len(shown) else ""))
            lines += ["  " + i.text() for i in shown]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.text()


# ---------------------------------------------------------------------------
# Import


def import_log(source, out, *, overwrite: bool = False, strict: bool = False, **spec_args) -> ImportReport:
    """Import a robot log into a dataset at ``out``; returns the :class:`ImportReport`.

    ``source``: a TOML spec path (``.toml``), a :class:`LogSpec`, or the log
    file(s), with the spec as keyword arguments (``columns=``, ``time=`` or
    ``sample_rate_hz=``, ... see :class:`LogSpec`), e.g.::

        import_log("run.csv", "data/run", name="my-arm", time="t",
                   columns={"q": ["q1", "q2", "q3"], "tau_m": ["tau1", "tau2", "tau3"]})

    The dataset is built beside ``out`` (under a name unique to this run) and
    renamed into place at the end, so an interrupted import leaves any previous
    dataset at ``out`` intact. An existing ``out`` is replaced only with
    ``overwrite``, and only when it is a hybrid-dyn dataset holding nothing but its
    own files (anything else is refused, named). One import per ``out`` at a time
    (``outputs.output_lock``). ``strict``: fail on any row issue.
    """
    is_spec = isinstance(source, LogSpec) or (isinstance(source, (str, Path)) and Path(source).suffix == ".toml")
    if is_spec and spec_args:
        raise LogSpecError(f"keyword arguments {sorted(spec_args)} cannot be combined with a spec; edit the spec")
    if isinstance(source, LogSpec):
        spec = source
    elif is_spec:
        spec = read_spec(source)
    else:
        files = [source] if isinstance(source, (str, Path)) else list(source)
        spec_args.setdefault("name", re.sub(r"[^A-Za-z0-9_.-]", "_", Path(files[0]).stem))
        spec = LogSpec(files=files, **spec_args)
    out = Path(out)
    with output_lock(out, "dataset"):
        return _import_locked(spec, out, overwrite, strict)


def _import_locked(spec: "LogSpec", out: Path, overwrite: bool, strict: bool) -> "ImportReport":
    _check_replaceable(out, overwrite)
    report = ImportReport(spec.name)
    segments, warnings = _validate(spec, report)
    report.warnings += warnings
    if strict and report.issues:
        raise StrictImportError(f"strict import of {spec.name} found row problems:\n{report.text()}")
    frac = report.rows_dropped / max(report.rows_read, 1)
    if frac > spec.checks.max_drop_fraction:
        by_kind = report.dropped_by_kind()
        hint = (" Most are out of range: is the log in degrees? Set [units] angle = \"deg\"."
                if by_kind and max(by_kind, key=by_kind.get) == "unit_range" else "")
        raise TooManyRowsDroppedError(
            f"{spec.name}: {report.rows_dropped} of {report.rows_read} rows ({100 * frac:.1f} %) failed validation, "
            f"more than max_drop_fraction = {spec.checks.max_drop_fraction}.{hint}\n{report.text(5)}")
    if not segments:
        raise LogImportError(f"{spec.name}: no usable rows\n{report.text(5)}")
    _write(spec, segments, report, out, overwrite)
    return report


@dataclass
class _Segment:
    trajectory: str
    table: LogTable
    rows: np.ndarray  # 0-based rows of the table
    fields: dict
    next_qd: np.ndarray | None = None


def _resolve(ref, table: LogTable, signal: str) -> list[int]:
    """Column indices (0-based) of a column reference."""
    refs = ref if isinstance(ref, list) else [ref]
    idx, missing = [], []
    for r in refs:
        if isinstance(r, bool) or not isinstance(r, (int, str)):
            raise LogSpecError(f"column reference {r!r} for {signal} must be a 1-based number, 'a-b' or a name")
        if isinstance(r, int):
            if 1 <= r <= len(table.columns):
                idx.append(r - 1)
            else:
                missing.append(str(r))
            continue
        if r in table.columns:
            idx.append(table.columns.index(r))
            continue
        group = [i for i, c in enumerate(table.columns) if c.startswith(r + "[")]
        m = re.fullmatch(r"\s*(\d+)\s*-\s*(\d+)\s*", r)
        if group:
            idx += group
        elif m:
            a, b = int(m.group(1)), int(m.group(2))
            if 1 <= a <= b <= len(table.columns):
                idx += list(range(a - 1, b))
            else:
                missing.append(r)
        else:
            missing.append(r)
    if missing:
        shown = table.columns if len(table.columns) <= 40 else table.columns[:40] + ["..."]
        raise MissingColumnError(f"{table.source.name}:{table.name}: columns {missing} for {signal} are not in the log "
                                 f"({len(table.columns)} columns: {shown})")
    return idx


def _trajectories(spec: LogSpec, tables: list[LogTable]) -> list[tuple[str, LogTable, np.ndarray]]:
    """(trajectory name, table, 0-based rows) for each trajectory."""
    out = []
    names = [t.name for t in tables]
    for table in tables:
        # The same variable name in several files: prefix the file's name.
        base = table.name if names.count(table.name) == 1 else f"{table.source.stem}_{table.name}"
        rows = np.arange(len(table))
        if spec.trajectories == "tables":
            out.append((base, table, rows))
        elif spec.trajectories == "blocks":
            if spec.n_blocks > len(rows):  # 1e9 blocks hung array_split (issue 28's fuzz)
                raise LogSpecError(f"n_blocks = {spec.n_blocks} is more than the {len(rows)} rows of "
                                   f"{table.source.name}:{table.name}")
            for k, block in enumerate(np.array_split(rows, spec.n_blocks)):
                if len(block):
                    out.append((f"{base}_b{k:02d}", table, block))
        else:
            col = _resolve(spec.trajectory_column, table, "trajectory_column")
            if len(col) != 1:
                raise LogSpecError(f"trajectory_column must be one column, got {len(col)}")
            ids = table.data[:, col[0]]
            for v in sorted(set(ids[np.isfinite(ids)].tolist())):
                out.append((f"{base}_{v:g}", table, rows[ids == v]))
    return [(re.sub(r"[^A-Za-z0-9_.-]", "_", n), t, r) for n, t, r in out]


def _robot_limits(spec: LogSpec, nv: int):
    """Per-joint (lower, upper) q bounds [rad]: the robot's limits widened by ``limit_margin`` if it has a
    description (both sides: the Panda's joint 4 lies in [-3.07, -0.07], not within +-3.07), else
    +-``q_abs_max``."""
    from ..description import resolve_robot

    if not resolve_robot(spec.robot).described:
        return np.full(nv, -spec.checks.q_abs_max), np.full(nv, spec.checks.q_abs_max)
    from ..analytic.robot import load_robot

    robot = load_robot(spec.robot)
    if robot.nv != nv:
        raise LogSpecError(f"robot {spec.robot!r} has {robot.nv} joints but the log maps {nv}")
    margin = spec.checks.limit_margin
    return np.maximum(robot.q_lower, -1e3) - margin, np.minimum(robot.q_upper, 1e3) + margin


def _validate(spec: LogSpec, report: ImportReport):
    """Read, check and cut the log into segments; every problem goes to ``report``."""
    tables = []
    for f in spec.files:
        tables += read_log(f, spec.format, spec.variables, spec.delimiter)
    segments, limits, q_peak = [], None, 0.0
    for traj, table, rows in _trajectories(spec, tables):
        data, t = _extract(spec, table, rows)
        if limits is None:
            limits = _robot_limits(spec, data["q"].shape[1])
        q_peak = max(q_peak, float(np.abs(data["q"][np.isfinite(data["q"])]).max(initial=0.0)))  # units check
        report.rows_read += len(rows)
        checks = _RowChecks(table, rows, report)
        checks.cells(data, t)
        checks.ranges(data, limits, spec.checks.qd_abs_max)
        checks.time(t, spec.checks.jump_factor)
        checks.next_samples(data, spec.checks.next_tol)
        if not checks.keep.any():
            continue
        report.trajectories += 1
        kept_t = t[checks.keep]
        dt = 1.0 / spec.sample_rate_hz if spec.sample_rate_hz else float(np.median(np.diff(kept_t))) if len(kept_t) > 1 else 1.0
        min_len = spec.derivatives.min_samples(dt) if "qdd" not in spec.columns else 1
        for seg in checks.segments(min_len):
            fields = {s: v[seg] for s, v in data.items() if s not in ("q_next", "qd_next")}
            fields["t"] = t[seg]
            nxt = data["qd_next"][seg[-1]] if "qd_next" in data and np.isfinite(data["qd_next"][seg[-1]]).all() else None
            segments.append(_Segment(traj, table, rows[seg], fields, nxt))
            report.rows_kept += len(seg)
    bad_unit = angle_unit_problems(spec.angle_unit, q_peak)
    if bad_unit:
        raise LogSpecError(f"{spec.name}: {bad_unit[0]}")
    warning = _timebase_warning(segments, spec) if "qdd" not in spec.columns else None
    return segments, [warning] if warning else []


def _extract(spec: LogSpec, table: LogTable, rows: np.ndarray):
    """The mapped signals of some rows of a table, in SI units, and their times t [s]."""
    cols = {s: _resolve(ref, table, s) for s, ref in spec.columns.items()}
    widths = {s: len(c) for s, c in cols.items() if s in JOINT_SIGNALS}
    if len(set(widths.values())) != 1:
        raise LogSpecError(f"joint signals must have one width (the number of joints), got {widths}")
    for s, w in (("base_wrench", 6), ("tip_force", 3)):
        if s in cols and len(cols[s]) != w:
            raise LogSpecError(f"{s} needs {w} columns, the spec maps {len(cols[s])}")
    deg = np.pi / 180 if spec.angle_unit == "deg" else 1.0
    data = {s: table.data[np.ix_(rows, c)] * (deg if s in ANGLE_SIGNALS else 1.0) for s, c in cols.items()}
    if spec.time is None:
        # Original row numbers: a dropped row leaves a gap of one step, as it would in time.
        return data, rows / spec.sample_rate_hz
    tcol = _resolve(spec.time, table, "time")
    if len(tcol) != 1:
        raise LogSpecError(f"time must be one column, got {len(tcol)}")
    return data, table.data[rows, tcol[0]] * TIME_UNITS[spec.time_unit]


class _RowChecks:
    """The row checks of one trajectory. Each check reports what it finds by row and
    marks the row to drop (``keep`` false) or to start a new segment (``split``)."""

    def __init__(self, table: LogTable, rows: np.ndarray, report: ImportReport):
        self.table, self.rows, self.report = table, rows, report
        self.keep = np.ones(len(rows), bool)
        self.split = np.zeros(len(rows), bool)

    def flag(self, i: int, kind: str, detail: str, action: str, n_rows: int = 1) -> None:
        r = int(self.rows[i])
        line = None if self.table.first_line is None else self.table.first_line + r
        self.report.issues.append(RowIssue(str(self.table.source), self.table.name, r + 1, kind, detail, action,
                                           line, n_rows))
        if action == "drop":
            self.keep[i : i + n_rows] = False
        else:
            self.split[i] = True

    def cells(self, data: dict, t: np.ndarray) -> None:
        """Unreadable, empty or NaN cells in a mapped column or the time."""
        signals = {s: v for s, v in data.items() if s not in ("q_next", "qd_next")}
        finite = np.isfinite(np.concatenate(list(signals.values()) + [t[:, None]], axis=1)).all(axis=1)
        messages = {}
        for r, msg in self.table.cell_problems:
            messages.setdefault(r, []).append(msg)
        for i in np.flatnonzero(~finite):
            bad = [f"{s}[{j + 1}]" for s, v in signals.items() for j in np.flatnonzero(~np.isfinite(v[i]))]
            bad += ["t"] if not np.isfinite(t[i]) else []
            msgs = messages.get(int(self.rows[i]), [])
            kind = "missing_cells" if any("cells" in m for m in msgs) else "nan"
            self.flag(i, kind, "no value in " + ", ".join(bad) + (f" ({'; '.join(msgs)})" if msgs else ""), "drop")

    def ranges(self, data: dict, q_limits: tuple, qd_max: float) -> None:
        """Unit mistakes, by range: q outside the joint bounds (lower, upper), |qd| beyond qd_max."""
        lo, hi = q_limits
        for i in np.flatnonzero(self.keep):
            over = np.flatnonzero((data["q"][i] < lo) | (data["q"][i] > hi))
            if len(over):
                j = over[0]
                self.flag(i, "unit_range", f"q[{j + 1}] = {data['q'][i, j]:.4g} rad is outside [{lo[j]:.3g}, "
                          f"{hi[j]:.3g}] rad (degrees logged as radians?)", "drop")
                continue
            over = np.flatnonzero(np.abs(data["qd"][i]) > qd_max) if "qd" in data else []
            if len(over):
                j = over[0]
                self.flag(i, "unit_range", f"qd[{j + 1}] = {data['qd'][i, j]:.4g} rad/s is beyond +-{qd_max:.3g} rad/s "
                          f"(deg/s logged as rad/s?)", "drop")

    def time(self, t: np.ndarray, jump_factor: float) -> None:
        """Time that does not increase (row dropped) and gaps (a new segment)."""
        last, last_i = -np.inf, None
        for i in np.flatnonzero(self.keep):
            if t[i] <= last:
                self.flag(i, "time_order", f"t = {t[i]:.6g} s is not after t = {last:.6g} s of row "
                          f"{self.rows[last_i] + 1}", "drop")
            else:
                last, last_i = t[i], i
        kept = np.flatnonzero(self.keep)
        if len(kept) > 2:
            steps = np.diff(t[kept])
            median = float(np.median(steps))
            for k in np.flatnonzero(steps > jump_factor * median):
                self.flag(kept[k + 1], "time_jump", f"gap of {steps[k]:.4g} s after row {self.rows[kept[k]] + 1} "
                          f"({steps[k] / median:.1f} x the median step {median:.4g} s)", "split")

    def next_samples(self, data: dict, tol: float) -> None:
        """A row must be the previous row's logged next sample (q_next, qd_next), else samples are missing."""
        for s_next, s in (("q_next", "q"), ("qd_next", "qd")):
            if s_next not in data or s not in data:
                continue
            pairs = np.flatnonzero(self.keep[:-1] & self.keep[1:])
            err = np.abs(data[s_next][pairs] - data[s][pairs + 1]).max(axis=1)
            for k, e in zip(pairs[err > tol], err[err > tol]):
                if not self.split[k + 1]:
                    self.flag(k + 1, "discontinuity", f"{s} differs from the previous row's {s_next} by {e:.3g}: "
                              f"samples missing?", "split")

    def segments(self, min_len: int) -> list[np.ndarray]:
        """Runs of kept, consecutive rows without a split; shorter than ``min_len``: dropped and reported."""
        kept = np.flatnonzero(self.keep)
        breaks = np.flatnonzero((np.diff(kept) > 1) | self.split[kept[1:]]) + 1
        out = []
        for seg in np.split(kept, breaks):
            if len(seg) >= min_len:
                out.append(seg)
            else:
                self.flag(seg[0], "short_segment", f"segment of {len(seg)} rows (rows {self.rows[seg[0]] + 1}-"
                          f"{self.rows[seg[-1]] + 1}) is shorter than the {min_len} the derivative filter needs",
                          "drop", n_rows=len(seg))
        return out


def _timebase_warning(segments: list, spec: LogSpec) -> str | None:
    """Least-squares ratio of the position increments to qd x dt over all segments: 1 if the
    time base and the units of q and qd agree. Otherwise the warning names the time unit
    (or sample rate) whose scale makes the increments fit the logged velocities."""
    tol = spec.checks.timebase_tol
    dq, vdt = [], []
    for seg in segments:
        f = seg.fields
        if "qd" in f and len(f["t"]) > 1:
            dq.append(np.diff(f["q"], axis=0).ravel())
            vdt.append((0.5 * (f["qd"][1:] + f["qd"][:-1]) * np.diff(f["t"])[:, None]).ravel())
    if not dq:
        return None
    dq, vdt = np.concatenate(dq), np.concatenate(vdt)
    if not vdt @ vdt > 0:
        return None
    ratio = float(dq @ vdt / (vdt @ vdt))
    if abs(ratio - 1) <= tol:
        return None
    head = f"the position increments are {ratio:.4g} x the logged velocity times the time step"
    if spec.time is None:  # the time base is the declared rate: the fitting rate scales by 1 / ratio
        return (f"{head}: the velocities fit a sample rate of {spec.sample_rate_hz / ratio:.3g} Hz, "
                f"not the declared {spec.sample_rate_hz:g} Hz (or are q and qd in different units?)")
    # Seconds per logged time unit that make the increments fit; a unit fits within the tolerance.
    scale = TIME_UNITS[spec.time_unit] * ratio
    fits = [u for u, s in TIME_UNITS.items() if abs(scale / s - 1) <= tol]
    if fits:
        return (f"{head}: the time column fits the unit {fits[0]!r}, not the declared {spec.time_unit!r} "
                f"(set [time] unit = \"{fits[0]}\")")
    return (f"{head}: no time unit fits (one logged time unit would be {scale:.4g} s); a wrong time column, "
            f"or q and qd in different units?")


def _derive(spec: LogSpec, seg: _Segment) -> dict:
    f = dict(seg.fields)
    flt = spec.derivatives
    if "qdd" in f:
        if "qd" not in f:
            f["qd"] = differentiate(f["q"], f["t"], flt, 1)
        return f
    if "qd" not in f:
        f["qd"] = differentiate(f["q"], f["t"], flt, 1)
        f["qdd"] = differentiate(f["q"], f["t"], flt, 2)
    else:
        f["qdd"] = differentiate(f["qd"], f["t"], flt, 1, x_next=seg.next_qd)
    return f


# What a dataset folder of the toolkit holds at its top level (generated or imported).
_DATASET_ENTRIES = {"manifest.json", "instances", "import_report.json", "import_report.txt", "generator.json"}


def _check_replaceable(out: Path, overwrite: bool) -> None:
    """Refuse an existing ``out`` unless ``overwrite`` and it provably holds only a toolkit dataset.

    The proof is the dataset's own manifest: every file in the folder must be the
    manifest, an import report, or an instance file (or completion record) it lists.
    An empty folder holds nothing to lose.
    """
    if not out.exists() and not out.is_symlink():
        return
    if not overwrite:
        raise LogImportError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
    if out.is_symlink() or not out.is_dir():
        refuse_foreign(out, "dataset", "it is not a folder")
    entries = sorted(p.name for p in out.iterdir())
    if not entries:
        return
    try:
        meta = json.loads((out / "manifest.json").read_text())
        listed = {Path(r["file"]).name for r in meta["instances"]} | {f"{r['name']}.json" for r in meta["instances"]}
        ours = meta.get("format") == "hybrid_dyn.dataset"
    except (OSError, ValueError, KeyError, TypeError):
        ours = False
    if not ours:
        refuse_foreign(out, "dataset", "it has no readable hybrid-dyn manifest.json")
    foreign = [out / e for e in entries if e not in _DATASET_ENTRIES]
    if (out / "instances").is_dir():
        foreign += [p for p in sorted((out / "instances").iterdir()) if p.name not in listed]
    if foreign:
        refuse_foreign(out, "dataset", f"it holds {', '.join(map(str, foreign[:3]))}"
                                       f"{' ...' if len(foreign) > 3 else ''}, which its manifest does not list")


def _write(spec: LogSpec, segments: list, report: ImportReport, out: Path, overwrite: bool) -> None:
    partial = unique_temp(out)  # this run's own build folder: never another's, never the user's
    partial.mkdir(parents=True)
    try:
        _build(spec, segments, report, partial)
        _swap_in(partial, out, overwrite)
    finally:
        if partial.exists():  # an error before the rename: leave nothing of this run behind
            shutil.rmtree(partial)
    report.path = out


def _swap_in(partial: Path, out: Path, overwrite: bool) -> None:
    """Rename the finished ``partial`` to ``out``; a previous dataset there goes to a run-unique backup first."""
    _check_replaceable(out, overwrite)  # again: something may have appeared during the import
    if not out.exists():
        os.replace(partial, out)
        return
    old = unique_temp(out, ".old")
    os.replace(out, old)
    os.replace(partial, out)
    shutil.rmtree(old)


def _build(spec: LogSpec, segments: list, report: ImportReport, partial: Path) -> None:
    from tqdm import tqdm

    by_traj = {}
    for seg in segments:
        by_traj.setdefault(seg.trajectory, []).append(seg)
    # The split first: fractions that leave a split empty are refused before any instance is written.
    # Each trajectory's first sample time [s]: the order of a time split (splits.py).
    traj_split = split_trajectories(spec.split_spec, {k: min(float(s.fields["t"][0]) for s in v)
                                                      for k, v in by_traj.items()})
    empty = empty_split_problems(traj_split) if len(by_traj) >= 3 else []  # fewer: warned below
    if empty and spec.split_by == "list":
        raise LogSpecError(f"{spec.name}: {empty[0]}: [split] lists no trajectory for it")
    if empty:
        raise LogSpecError(f"{spec.name}: {empty[0]} ({len(by_traj)} trajectories, test_frac = {spec.test_frac}, "
                           f"val_frac = {spec.val_frac} of the rest); choose smaller fractions")
    records, steps = [], []
    fields_written = None
    for traj in sorted(by_traj, key=natural_key):
        segs = by_traj[traj]
        for k, seg in enumerate(tqdm(segs, desc=f"import {traj}", leave=False, disable=len(segments) < 50)):
            f = _derive(spec, seg)
            name = traj if len(segs) == 1 else f"{traj}_s{k:02d}"
            attrs = {"source": seg.table.source.name, "table": seg.table.name, "trajectory": traj,
                     "first_row": int(seg.rows[0]) + 1, "last_row": int(seg.rows[-1]) + 1}
            sha = write_instance(partial / "instances" / f"{name}.h5", f, attrs=attrs)
            fields_written = sorted(f)
            if len(f["t"]) > 1:
                steps.append(np.diff(f["t"]))
            records.append({"name": name, "file": f"instances/{name}.h5", "sha256": sha, "n_samples": len(f["t"]),
                            "trajectory": traj, "source": seg.table.source.name, "table": seg.table.name,
                            "rows": [attrs["first_row"], attrs["last_row"]]})
    report.instances = len(records)
    if len(by_traj) < 3:
        report.warnings.append(f"only {len(by_traj)} trajectories: all are in the train split "
                               f"(use trajectories from = \"blocks\" to cut one log into several)")
    splits = {s: sorted(r["name"] for r in records if r["trajectory"] in names) for s, names in traj_split.items()}
    step = float(np.median(np.concatenate(steps))) if steps else None
    estimated = "given" if "qdd" in spec.columns else spec.derivatives.to_dict()
    units = dict(FIELD_UNITS, tau_m="Nm (the logged joint torque)")
    full = report.to_dict()
    (partial / "import_report.json").write_text(json.dumps(full, indent=1))
    (partial / "import_report.txt").write_text(report.text(max_per_kind=10**9) + "\n")
    write_manifest(partial, {
        "robot": spec.robot, "scenario": spec.name, "seed": spec.split_seed,
        "record_hz": (1.0 / step) if step else None,
        "config": {"generator": "import_log", "importer_version": IMPORTER_VERSION, "spec": spec.to_dict(),
                   "notes": spec.notes},
        "fields": {k: units[k] for k in fields_written}, "packages": package_versions(),
        "instances": records, "splits": splits, "trajectory_splits": traj_split,
        "split": {**spec.split_spec.to_dict(), "text": spec.split_spec.describe(len(by_traj))},
        "import": {**report.summary(), "derivatives": estimated,
                   "velocities": "logged" if "qd" in spec.columns else "estimated",
                   "sources": [{"file": str(f), "sha256": sha256_file(f)} for f in spec.files],
                   "issues_first_100": full["issues"][:100], "report": "import_report.json"},
    })


def spec_checksum(spec: LogSpec) -> str:
    """A digest of the spec and its source files: identifies an import's input."""
    h = hashlib.sha256(f"importer-{IMPORTER_VERSION}".encode())
    h.update(json.dumps(spec.to_dict(), sort_keys=True, default=str).encode())
    for f in spec.files:
        h.update(sha256_file(f).encode() if Path(f).is_file() else b"missing")
    return h.hexdigest()
