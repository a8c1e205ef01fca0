"""The import's row checks on a ROS bag chunk by chunk, for a reader that streams (``hybrid-dyn estimate``).

:func:`checked_chunks` reads each bag of a spec in chunks (``ros_bag.read_chunks``) and runs the checks of
``log_validation._RowChecks`` on every chunk: cells, ranges, time order (against the last kept stamp,
carried from chunk to chunk) and gaps (over ``jump_factor`` times the median step of the bag's first
chunk). Each problem goes to the :class:`ImportReport` by row, as an import's would; the kept rows come
back with a flag where a new segment starts. Memory is bounded by a chunk.

What it leaves to the whole-log import (``log_validation.validate_log``): splits into trajectories other
than one per bag, the dead-channel and time-base warnings (they need the whole log), and the derivative
filter's minimum segment length (a replay runs no such filter).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data_checks import angle_unit_problems
from . import bag_stream
from .bag_stream import BagStats
from .import_report import ImportReport
from .log_spec import LogSpecError
from .log_validation import _extract, _robot_limits, _RowChecks
from .ros_bag import bag_names, bag_notes, chunk_table, read_chunks


@dataclass
class CheckedRows:
    """The kept rows of one chunk: ``source`` (the bag), header ``stamps_ns``, ``fields`` (t [s] from the
    bag's first stamp, q, qd, torques, wrenches, as an import's), ``starts`` (a new segment starts here),
    ``rows`` (0-based rows of the bag)."""

    source: Path
    stamps_ns: np.ndarray
    fields: dict
    starts: np.ndarray
    rows: np.ndarray | None = None


def checked_chunks(spec, report: ImportReport, keep_partial: bool = False, size: int | None = None):
    """:class:`CheckedRows` of every chunk of every bag of ``spec``, in order (module docstring); ``size``:
    rows per chunk (default ``bag_stream.CHUNK_ROWS``)."""
    size = size or bag_stream.CHUNK_ROWS
    joints, frames = bag_names(spec)
    limits, q_peak = _robot_limits(spec, len(joints)), 0.0
    for f in spec.files:
        path, stats = Path(f), BagStats()
        state = {"last": -np.inf, "last_row": None, "median": None, "prev_kept": None}
        report.trajectories += 1
        for chunk in read_chunks(path, spec.ros, joints, frames, spec.checks.jump_factor, stats, keep_partial, size):
            if "torque" not in state:  # a bag whose first chunk carries no effort has no joint torques
                state["torque"] = bool(np.isfinite(chunk.effort).any())
                if not state["torque"]:
                    spec.columns = {s: c for s, c in spec.columns.items() if s not in spec.ros.torque_fields()}
            table = chunk_table(path, chunk, spec.ros, joints, with_qd=True, torque=state["torque"])
            local = np.arange(len(chunk))
            data, t = _extract(spec, table, local)
            q_peak = max(q_peak, float(np.abs(data["q"][np.isfinite(data["q"])]).max(initial=0.0)))
            checks = _RowChecks(table, local + chunk.first_row, report)
            checks.cells(data, t, table.qd_missing)
            checks.ranges(data, limits, spec.checks.qd_abs_max)
            _time(checks, t, spec.checks.jump_factor, state)
            report.rows_read += len(chunk)
            keep = np.flatnonzero(checks.keep)
            if not len(keep):
                state["prev_kept"] = None
                continue
            rows = local[keep] + chunk.first_row
            starts = np.r_[True, (np.diff(rows) > 1)] | checks.split[keep]
            starts[0] = state["prev_kept"] is None or rows[0] != state["prev_kept"] + 1 or checks.split[keep[0]]
            state["prev_kept"] = rows[-1] if checks.keep[-1] else None
            report.rows_kept += len(keep)
            report.instances += int(starts.sum())
            fields = {s: v[keep] for s, v in data.items()}
            fields["t"] = t[keep]
            yield CheckedRows(path, chunk.stamps_ns[keep], fields, starts, rows)
        report.warnings += bag_notes(path, spec.ros, stats, stats.messages - stats.skipped)
    bad_unit = angle_unit_problems(spec.angle_unit, q_peak)
    if bad_unit:
        raise LogSpecError(f"{spec.name}: {bad_unit[0]}")


def _time(checks: _RowChecks, t: np.ndarray, jump_factor: float, state: dict) -> None:
    """``_RowChecks.time`` with the last kept time and the median step carried over from the chunks before."""
    tk = np.where(checks.keep, t, -np.inf)
    prev = np.maximum.accumulate(np.r_[state["last"], tk[:-1]])
    for i in np.flatnonzero(checks.keep & (t <= prev)):
        before = np.flatnonzero(tk[:i] == prev[i])
        row = checks.rows[before[-1]] + 1 if len(before) else state["last_row"]
        checks.flag(i, "time_order", f"t = {t[i]:.6g} s is not after t = {prev[i]:.6g} s of row {row}", "drop")
    kept = np.flatnonzero(checks.keep)
    if not len(kept):
        return
    kt = np.r_[state["last"], t[kept]] if np.isfinite(state["last"]) else t[kept]
    steps = np.diff(kt)
    if state["median"] is None and len(steps) > 1:
        state["median"] = float(np.median(steps))
    median = state["median"]
    if median is not None:
        offset = 1 if np.isfinite(state["last"]) else 0
        for k in np.flatnonzero(steps > jump_factor * median):
            i = kept[k + 1 - offset]
            after = checks.rows[kept[k - offset]] + 1 if k - offset >= 0 else state["last_row"]
            checks.flag(i, "time_jump", f"gap of {steps[k]:.4g} s after row {after} ({steps[k] / median:.1f} x the "
                        f"median step {median:.4g} s)", "split")
    state["last"], state["last_row"] = float(t[kept[-1]]), int(checks.rows[kept[-1]]) + 1

