"""Reading a log's rows and checking them: trajectories, columns, the row checks, segments.

:func:`validate_log` reads the tables (``log_readers.py``), cuts them into
trajectories, extracts the mapped signals in SI units and checks every row
(:class:`_RowChecks`: cells, ranges, time, next samples); what it finds goes to the
:class:`~.import_report.ImportReport` by row. A bad row is dropped, a gap starts a new
segment, and the kept runs come back as :class:`Segment` s.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ...description import joint_limits, resolve_robot
from ..data_checks import angle_unit_problems, channel_problems
from .import_report import ImportReport, RowIssue
from .log_spec import (ANGLE_SIGNALS, JOINT_SIGNALS, TIME_UNITS, LogImportError, LogSpec, LogSpecError,
                       MissingColumnError, StrictImportError, TooManyRowsDroppedError)
from .log_readers import LogTable, read_log

@dataclass
class Segment:
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
            if spec.n_blocks > len(rows):  # 1e9 blocks hung array_split (found by fuzzing)
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


def _described_joints(spec: LogSpec):
    """The moving joints of the log's robot and their limits (:class:`~hybrid_dyn.description.JointLimits`),
    or None for a robot known for data only."""
    ref = resolve_robot(spec.robot)
    return joint_limits(ref.spec) if ref.described else None


def _robot_limits(spec: LogSpec, nv: int):
    """Per-joint (lower, upper) q bounds [rad]: the robot's limits widened by ``limit_margin`` if it has a
    description (both sides: the Panda's joint 4 lies in [-3.07, -0.07], not within +-3.07), else
    +-``q_abs_max``."""
    joints = _described_joints(spec)
    if joints is None:
        return np.full(nv, -spec.checks.q_abs_max), np.full(nv, spec.checks.q_abs_max)
    if joints.nv != nv:
        raise LogSpecError(f"robot {spec.robot!r} has {joints.nv} joints but the log maps {nv}")
    margin = spec.checks.limit_margin
    return np.maximum(joints.lower, -1e3) - margin, np.minimum(joints.upper, 1e3) + margin


def validate_log(spec: LogSpec, report: ImportReport, keep_partial: bool = False,
                 derivatives: bool = True) -> tuple[list, list]:
    """Read, check and cut the log into segments; every problem goes to ``report``. ``keep_partial``: a
    damaged bag keeps what was read before the damage. ``derivatives``: the kept segments go through the
    derivative filter (an import), so a segment shorter than its window is dropped; without (a replay)
    only a segment too short to difference q where qd is missing is.

    A signal a bag does not carry at all (every velocity or effort empty) leaves ``spec.columns``: the
    caller's spec is changed to what the log holds."""
    if spec.ros is not None:  # a ROS bag: its topics on one time base, one table per bag (ros_bag.py)
        from .ros_bag import read_bags

        tables = read_bags(spec, report, keep_partial)
        absent = set.intersection(*(set(t.absent) for t in tables))
        spec.columns = {s: c for s, c in spec.columns.items() if s not in absent}
        if any(t.absent for t in tables) and absent != set.union(*(set(t.absent) for t in tables)):
            raise LogSpecError(f"{spec.name}: some bags carry {sorted(set.union(*(set(t.absent) for t in tables)))}"
                               " and some do not; import them apart")
    else:
        tables = [t for f in spec.files for t in read_log(f, spec.format, spec.variables, spec.delimiter)]
    segments, limits, q_peak = [], None, 0.0
    for traj, table, rows in _trajectories(spec, tables):
        data, t = _extract(spec, table, rows)
        if limits is None:
            limits = _robot_limits(spec, data["q"].shape[1])
        q_peak = max(q_peak, float(np.abs(data["q"][np.isfinite(data["q"])]).max(initial=0.0)))  # units check
        report.rows_read += len(rows)
        checks = _RowChecks(table, rows, report)
        qd_missing = getattr(table, "qd_missing", None)
        checks.cells(data, t, None if qd_missing is None else qd_missing[rows])
        checks.ranges(data, limits, spec.checks.qd_abs_max)
        checks.time(t, spec.checks.jump_factor)
        checks.next_samples(data, spec.checks.next_tol)
        if not checks.keep.any():
            continue
        report.trajectories += 1
        kept_t = t[checks.keep]
        dt = 1.0 / spec.sample_rate_hz if spec.sample_rate_hz else float(np.median(np.diff(kept_t))) if len(kept_t) > 1 else 1.0
        qd_missing = getattr(table, "qd_missing", None)
        derive_qd = "qd" not in spec.columns or (qd_missing is not None and qd_missing[rows].any())
        if derivatives:
            min_len, why = (spec.derivatives.min_samples(dt) if "qdd" not in spec.columns else 1), "derivative filter"
        else:
            min_len, why = (2 if derive_qd else 1), "difference of q"
        for seg in checks.segments(min_len, why):
            fields = {s: v[seg] for s, v in data.items() if s not in ("q_next", "qd_next")}
            fields["t"] = t[seg]
            nxt = data["qd_next"][seg[-1]] if "qd_next" in data and np.isfinite(data["qd_next"][seg[-1]]).all() else None
            segments.append(Segment(traj, table, rows[seg], fields, nxt))
            report.rows_kept += len(seg)
    bad_unit = angle_unit_problems(spec.angle_unit, q_peak)
    if bad_unit:
        raise LogSpecError(f"{spec.name}: {bad_unit[0]}")
    warning = _timebase_warning(segments, spec) if "qdd" not in spec.columns else None
    dead = channel_warnings(segments, spec)
    report.channel_warnings += dead  # a strict import refuses them (importer.py)
    return segments, dead + ([warning] if warning else [])


def refuse_as_import(spec: LogSpec, report: ImportReport, strict: bool, n_segments: int) -> None:
    """An import's refusals after its rows were checked: a strict import that found problems, too many rows
    dropped, no segment kept."""
    if strict and (report.issues or report.channel_warnings):
        found = (("row problems", report.issues), ("dead channels", report.channel_warnings))
        what = " and ".join(w for w, b in found if b)
        raise StrictImportError(f"strict import of {spec.name} found {what}:\n{report.text()}")
    frac = report.rows_dropped / max(report.rows_read, 1)
    if frac > spec.checks.max_drop_fraction:
        by_kind = report.dropped_by_kind()
        hint = (" Most are out of range: is the log in degrees? Set [units] angle = \"deg\"."
                if by_kind and max(by_kind, key=by_kind.get) == "unit_range" else "")
        raise TooManyRowsDroppedError(
            f"{spec.name}: {report.rows_dropped} of {report.rows_read} rows ({100 * frac:.1f} %) failed validation, "
            f"more than max_drop_fraction = {spec.checks.max_drop_fraction}.{hint}\n{report.text(5)}")
    if not n_segments:
        raise LogImportError(f"{spec.name}: no usable rows\n{report.text(5)}")


# The logged signals whose channels are checked: a dead torque channel made the bench headline a
# row whose nMSE dropped that joint, and identification put 32 kg on a 0.65 kg link.
CHANNEL_SIGNALS = {"q": "rad", "qd": "rad/s", "tau_m": "Nm", "tau_J": "Nm"}
TORQUE_SIGNALS = ("tau_m", "tau_J")


def channel_warnings(segments: list, spec: LogSpec) -> list[str]:
    """One-line warnings naming each joint whose logged channel carries nothing over all kept rows: constant
    (q, qd, torques), or for a torque, far below its joint's scale (``[checks] channel_scale_factor`` times the
    joints' median; the scale is the robot's effort limit [Nm] when it has a description, else 1 Nm for every
    joint). ``data_checks.channel_problems`` says how."""
    if not segments:
        return []
    names, effort = _robot_names_and_effort(spec, segments[0].fields["q"].shape[1])
    out = []
    for signal, unit in CHANNEL_SIGNALS.items():
        if signal not in spec.columns:  # estimated by the import, not logged: nothing of the sensor to check
            continue
        x = np.concatenate([seg.fields[signal] for seg in segments])
        x = x[np.isfinite(x).all(axis=1)]  # a bag's rows without velocity: qd derived, not logged
        scale = (effort if effort is not None else np.ones(x.shape[1])) if signal in TORQUE_SIGNALS else None
        out += channel_problems(signal, x, unit, scale, spec.checks.channel_scale_factor, names)
    return out


def _robot_names_and_effort(spec: LogSpec, nv: int):
    """The robot's joint names and effort limits [Nm] (nv,) when it has a description, else (None, None)."""
    joints = _described_joints(spec)
    if joints is None:
        return None, None
    effort = joints.effort
    ok = joints.nv == nv and np.all(np.isfinite(effort) & (effort > 0))
    return (joints.names if joints.nv == nv else None), (effort if ok else None)


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

    def cells(self, data: dict, t: np.ndarray, qd_missing: np.ndarray | None = None) -> None:
        """Unreadable, empty or NaN cells in a mapped column or the time; ``qd_missing``: which of the
        checked rows have no velocity (derived from q later), which are no bad cells."""
        signals = {s: v for s, v in data.items() if s not in ("q_next", "qd_next")}
        if qd_missing is not None and "qd" in signals:
            qd = signals["qd"].copy()
            qd[qd_missing] = 0.0
            signals["qd"] = qd
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
        with np.errstate(invalid="ignore"):  # only the rows with a value out of range are looked at one by one
            out_q = ((data["q"] < lo) | (data["q"] > hi)).any(axis=1)
            out_qd = (np.abs(data["qd"]) > qd_max).any(axis=1) if "qd" in data else np.zeros(len(out_q), bool)
        for i in np.flatnonzero(self.keep & (out_q | out_qd)):
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

    def segments(self, min_len: int, why: str = "derivative filter") -> list[np.ndarray]:
        """Runs of kept, consecutive rows without a split; shorter than ``min_len``: dropped and reported."""
        kept = np.flatnonzero(self.keep)
        breaks = np.flatnonzero((np.diff(kept) > 1) | self.split[kept[1:]]) + 1
        out = []
        for seg in np.split(kept, breaks):
            if len(seg) >= min_len:
                out.append(seg)
            else:
                self.flag(seg[0], "short_segment", f"segment of {len(seg)} rows (rows {self.rows[seg[0]] + 1}-"
                          f"{self.rows[seg[-1]] + 1}) is shorter than the {min_len} the {why} needs",
                          "drop", n_rows=len(seg))
        return out


def _timebase_warning(segments: list, spec: LogSpec) -> str | None:
    """Least-squares ratio of the position increments to qd x dt over all segments: 1 if the
    time base and the units of q and qd agree. Otherwise the warning names the time unit
    (or sample rate) whose scale makes the increments fit the logged velocities.

    dt is each segment's clock (its span over its steps), not each interval: a stream stamped on
    arrival jitters interval by interval while its samples are evenly spaced, and per-interval steps
    biased the ratio (a false "no time unit fits")."""
    dq, vdt = [], []
    for seg in segments:
        f = seg.fields
        if "qd" in f and len(f["t"]) > 1:
            step = (f["t"][-1] - f["t"][0]) / (len(f["t"]) - 1)
            inc, v = np.diff(f["q"], axis=0), 0.5 * (f["qd"][1:] + f["qd"][:-1]) * step
            ok = np.isfinite(v).all(axis=1)  # rows whose qd is derived, not logged
            dq.append(inc[ok].ravel())
            vdt.append(v[ok].ravel())
    if not dq:
        return None
    dq, vdt = np.concatenate(dq), np.concatenate(vdt)
    return timebase_text(float(dq @ vdt), float(vdt @ vdt), spec)


def timebase_text(dq_vdt: float, vdt_vdt: float, spec: LogSpec) -> str | None:
    """The warning of :func:`_timebase_warning` from its two sums over the rows: the position increments
    times qd x dt [rad^2] and qd x dt squared [rad^2] (a log read in blocks adds them up)."""
    tol = spec.checks.timebase_tol
    if not vdt_vdt > 0:
        return None
    ratio = dq_vdt / vdt_vdt
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
