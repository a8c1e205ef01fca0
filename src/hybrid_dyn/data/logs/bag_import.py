"""A ROS bag imported as it is read: checked chunks to scratch files, each segment to its instance in blocks.

The rows come chunk by chunk from ``bag_checks.checked_chunks`` (the import's row checks) and are
appended, field by field, to raw float64 files on disk beside the dataset being built; memory holds a
chunk, not the bag. When a bag ends, its trajectory's median step is known, so each segment is measured
against the derivative filter's minimum length (shorter: dropped and reported, as the whole-log import
does), then written to its instance a block of rows at a time (``dataset.write_instance_blocks``), qd
and qdd estimated block by block.

Derivatives in blocks: ``savgol`` and ``central`` are local, a sample's derivative depending on at most
``DerivativeFilter.reach`` samples on each side; qdd of a filled qd takes two such steps, so a block is
differentiated with twice that margin of the segment around it, at the segment's own median step, and
equals the whole segment's result. ``butter`` (filtfilt) reaches the whole segment: its segments are
differentiated whole, so their memory grows with the longest segment.

What differs from reading the bag whole (``log_validation.validate_log``): one trajectory per bag only
(``trajectories = "tables"``; the other modes read whole); gaps are measured against the median step of
each bag's first chunk; a bag whose first chunk carries no velocity imports without logged qd (qd is
estimated from q throughout), one without effort without torques.
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np

from ...outputs import unique_temp
from ..data_checks import channel_problems_of
from ..dataset import write_instance_blocks
from .bag_checks import checked_chunks
from .import_report import ImportReport, RowIssue
from .log_validation import (CHANNEL_SIGNALS, TORQUE_SIGNALS, _robot_names_and_effort, refuse_as_import,
                             timebase_text)
from .log_writer import _swap_in, derive_fields, instance_record, trajectory_split, write_manifest_files

BLOCK_ROWS = 65_536  # rows per block written and differentiated


class _Scratch:
    """One bag's kept rows, appended field by field to raw float64 files (on disk, not in memory)."""

    def __init__(self, folder: Path):
        folder.mkdir()
        self.folder, self.files, self.widths, self.n = folder, {}, {}, 0

    def append(self, fields: dict) -> None:
        for k, v in fields.items():
            v = np.ascontiguousarray(v, np.float64)
            if k not in self.files:
                self.widths[k] = None if v.ndim == 1 else v.shape[1]
                self.files[k] = open(self.folder / k, "wb")
            v.tofile(self.files[k])
        self.n += len(fields["t"])

    def close(self) -> None:
        for f in self.files.values():
            f.close()

    def read(self, key: str, a: int, b: int) -> np.ndarray:
        """Rows a..b-1 of a field, read into memory (not mapped: mapped pages would count as ours)."""
        w = self.widths[key] or 1
        x = np.fromfile(self.folder / key, np.float64, count=(b - a) * w, offset=a * w * 8)
        return x if self.widths[key] is None else x.reshape(b - a, w)


class _Sums:
    """What the whole-log checks need over all kept rows, added up block by block: each logged channel's
    first row, mean, spread and range (dead channels), and the time-base fit's two sums."""

    def __init__(self, spec):
        self.spec, self.ch, self.dq_vdt, self.vdt_vdt = spec, {}, 0.0, 0.0

    def channels(self, signal: str, x: np.ndarray) -> None:
        x = x[np.isfinite(x).all(axis=1)]  # a bag's rows without velocity: qd derived, not logged
        if not len(x):
            return
        n, mean, m2 = len(x), x.mean(axis=0), ((x - x.mean(axis=0)) ** 2).sum(axis=0)
        if signal not in self.ch:
            self.ch[signal] = [n, mean, m2, x.min(axis=0), x.max(axis=0), x[0]]
            return
        s = self.ch[signal]  # Chan et al.'s pairwise update of the mean and the squared deviations
        tot = s[0] + n
        delta = mean - s[1]
        s[2] = s[2] + m2 + delta**2 * s[0] * n / tot
        s[1] = s[1] + delta * n / tot
        s[0], s[3], s[4] = tot, np.minimum(s[3], x.min(axis=0)), np.maximum(s[4], x.max(axis=0))

    def timebase(self, q: np.ndarray, qd: np.ndarray, step: float) -> None:
        """Rows of one segment (with the row before the block): increments against qd x dt."""
        inc, v = np.diff(q, axis=0), 0.5 * (qd[1:] + qd[:-1]) * step
        ok = np.isfinite(v).all(axis=1)
        self.dq_vdt += float(inc[ok].ravel() @ v[ok].ravel())
        self.vdt_vdt += float(v[ok].ravel() @ v[ok].ravel())

    def warnings(self, nv: int) -> tuple[list, list]:
        """(dead-channel warnings, [the time-base warning] or [])."""
        names, effort = _robot_names_and_effort(self.spec, nv)
        dead = []
        for signal, unit in CHANNEL_SIGNALS.items():
            if signal not in self.spec.columns or signal not in self.ch:
                continue
            n, _, m2, lo, hi, first = self.ch[signal]
            scale = (effort if effort is not None else np.ones(len(lo))) if signal in TORQUE_SIGNALS else None
            dead += channel_problems_of(signal, n, first, np.sqrt(m2 / n), hi - lo == 0, unit, scale,
                                        self.spec.checks.channel_scale_factor, names)
        timebase = timebase_text(self.dq_vdt, self.vdt_vdt, self.spec) if "qdd" not in self.spec.columns else None
        return dead, [timebase] if timebase else []


def trajectory_names(files: list) -> list[str]:
    """One trajectory per bag: its name (a file's stem, a folder's name; the same name twice: the stem of
    the file prefixed), as the whole-log import names it."""
    names = [Path(f).stem if Path(f).is_file() else Path(f).name for f in files]
    out = [n if names.count(n) == 1 else f"{Path(f).stem}_{n}" for f, n in zip(files, names)]
    return [re.sub(r"[^A-Za-z0-9_.-]", "_", n) for n in out]


def import_bags(spec, out: Path, overwrite: bool, strict: bool, keep_partial: bool) -> ImportReport:
    """Import the bags of ``spec`` (one trajectory each) into a dataset at ``out`` (module docstring); the
    report as ``importer.import_log`` returns it. ``spec`` is changed to what the bags hold."""
    report = ImportReport(spec.name)
    partial = unique_temp(out)  # this run's own build folder: never another's, never the user's
    partial.mkdir(parents=True)
    try:
        built = _Built(spec, report, partial)
        names = dict(zip(map(str, map(Path, spec.files)), trajectory_names(spec.files)))
        bag = None
        for rows in checked_chunks(spec, report, keep_partial):
            if bag is None or bag.source != rows.source:
                if bag is not None:
                    built.write_bag(bag)
                bag = _Bag(rows.source, names[str(rows.source)], partial / f".rows-{len(built.first_t)}")
                built.first_t[bag.traj] = float(rows.fields["t"][0])
            if "qd" in rows.fields and built.nv is None and not np.isfinite(rows.fields["qd"]).any():
                spec.columns = {s: c for s, c in spec.columns.items() if s != "qd"}  # no velocity: estimated
            if "qd" not in spec.columns:
                rows.fields.pop("qd", None)
            built.nv = rows.fields["q"].shape[1]
            bag.add(rows)
        if bag is not None:
            built.write_bag(bag)
        dead, timebase = built.sums.warnings(built.nv or 0)
        report.channel_warnings += dead
        report.warnings += dead + timebase
        refuse_as_import(spec, report, strict, len(built.records))
        traj_split = trajectory_split(spec, built.first_t)
        step = float(np.median(np.concatenate(built.steps))) if built.steps else None
        write_manifest_files(spec, report, partial, built.records, traj_split, step, built.fields)
        _swap_in(partial, out, overwrite)
    finally:
        if partial.exists():  # an error before the rename: leave nothing of this run behind
            shutil.rmtree(partial)
    report.path = out
    return report


class _Bag:
    """One bag's kept rows on disk and its segments: [first, end) rows of the scratch, the first and last
    0-based rows of the bag."""

    def __init__(self, source: Path, traj: str, folder: Path):
        self.source, self.traj, self.rows, self.segments = source, traj, _Scratch(folder), []
        self.table = source.stem if source.is_file() else source.name  # the whole-log import's table name
        self.last_row = None

    def add(self, rows) -> None:
        at = self.rows.n
        for i in np.flatnonzero(rows.starts):
            if self.segments:
                self.segments[-1][1], self.segments[-1][3] = at + int(i), int(rows.rows[i - 1]) if i else self.last_row
            self.segments.append([at + int(i), None, int(rows.rows[i]), None])
        self.rows.append(rows.fields)
        self.last_row = int(rows.rows[-1])
        self.segments[-1][1], self.segments[-1][3] = self.rows.n, self.last_row


class _Built:
    """The instances written so far, their records and steps, and the sums of the whole-log checks."""

    def __init__(self, spec, report: ImportReport, partial: Path):
        self.spec, self.report, self.partial = spec, report, partial
        self.records, self.steps, self.first_t, self.fields, self.nv = [], [], {}, None, None
        self.sums = _Sums(spec)

    def write_bag(self, bag: _Bag) -> None:
        scratch, spec = bag.rows, self.spec
        scratch.close()
        t = scratch.read("t", 0, scratch.n)
        traj_dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        min_len = spec.derivatives.min_samples(traj_dt) if "qdd" not in spec.columns else 1
        kept = []
        for a, b, first, last in bag.segments:
            if b - a >= min_len:
                kept.append((a, b, first, last))
                continue
            self.report.rows_kept -= b - a
            self.report.issues.append(RowIssue(str(bag.source), bag.table, first + 1, "short_segment",
                                               f"segment of {b - a} rows (rows {first + 1}-{last + 1}) is shorter "
                                               f"than the {min_len} the derivative filter needs", "drop", None, b - a))
        for k, (a, b, first, last) in enumerate(kept):
            steps = np.diff(t[a:b])
            self.steps.append(steps)
            dt = float(np.median(steps)) if len(steps) else 1.0
            name = bag.traj if len(kept) == 1 else f"{bag.traj}_s{k:02d}"
            attrs = {"source": bag.source.name, "table": bag.table, "trajectory": bag.traj,
                     "first_row": first + 1, "last_row": last + 1}
            self._segment_sums(scratch, a, b)
            widths, block = _segment_fields(spec, scratch, a, b, dt)
            sha = write_instance_blocks(self.partial / "instances" / f"{name}.h5", b - a, widths, block, attrs,
                                        BLOCK_ROWS)
            self.fields = sorted(widths)
            self.records.append(instance_record(name, sha, b - a, attrs))
        shutil.rmtree(scratch.folder)

    def _segment_sums(self, scratch: _Scratch, a: int, b: int) -> None:
        logged = [s for s in CHANNEL_SIGNALS if s in self.spec.columns and s in scratch.widths]
        step = (scratch.read("t", b - 1, b)[0] - scratch.read("t", a, a + 1)[0]) / max(b - a - 1, 1)
        for lo in range(a, b, BLOCK_ROWS):
            hi = min(lo + BLOCK_ROWS, b)
            for s in logged:
                self.sums.channels(s, scratch.read(s, lo, hi))
            if "qd" in logged and b - a > 1:
                back = max(lo - 1, a)  # the row before the block: its increment
                self.sums.timebase(scratch.read("q", back, hi), scratch.read("qd", back, hi), step)


def _segment_fields(spec, scratch: _Scratch, a: int, b: int, dt: float):
    """(field -> columns, block(field, lo, hi)) of the segment at rows a..b-1 of ``scratch``: its logged
    fields as read, qd and qdd estimated in blocks with the filter's margin (module docstring)."""
    widths = dict(scratch.widths)
    nv = widths["q"]
    # qd: estimated when not logged, and in the rows whose velocity is empty (filled from q)
    derived = {"qd"} | ({"qdd"} if "qdd" not in spec.columns else set())
    widths.update({k: nv for k in derived})
    reach = spec.derivatives.reach(dt)
    n, cache = b - a, {}

    def block(name: str, lo: int, hi: int) -> np.ndarray:
        if name not in derived:
            return scratch.read(name, a + lo, a + hi)
        wlo, whi = (0, n) if reach is None else (max(lo - 2 * reach, 0), min(hi + 2 * reach, n))
        if (wlo, whi) not in cache:
            cache.clear()  # qd and qdd of one block share a window; a whole segment (butter) stays
            win = {k: scratch.read(k, a + wlo, a + whi) for k in ("t", "q", "qd") if k in scratch.widths}
            cache[(wlo, whi)] = derive_fields(spec, win, dt=dt)
        return cache[(wlo, whi)][name][lo - wlo:hi - wlo]

    return widths, block
