"""A ROS bag's topics read in chunks of joint-state rows (``ros_bag.py`` states the time base).

:func:`bag_chunks` yields :class:`BagChunk` s of at most ``size`` rows: the joint states decoded into
numbers as they are read, each wrench topic put on their stamps from a sliding window of its own
messages (``resample``). Memory is bounded by a chunk, not by the bag: an hour at 1 kHz never sits in
memory as messages or as one table. What the reading found (skipped messages, missing fields, zero or
jittered stamps, where damage stopped it) is counted in a :class:`BagStats`.

Each topic is read by its own reader on the same file, so that the joint states and a wrench topic
advance side by side. A message that cannot be read or decoded (a truncated sqlite3 file, flipped bytes
in a ROS 1 chunk) raises :class:`BagDamage` with the last good stamp; with ``keep_partial`` the rows
read before it are kept and the stats say where the reading stopped.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bag_decode import BagDamage, open_reader, topic_batches  # noqa: F401 (re-exported)

CHUNK_ROWS = 65_536  # joint-state rows per chunk: ~15 MB of numbers for a 7-joint arm with two wrenches
_SLACK = 1024  # rows a chunk may grow by to close a run of jittered stamps at its end


@dataclass
class BagStats:
    """What reading one bag found, for the import report."""

    messages: int = 0  # joint-state messages read
    skipped: int = 0  # of them, without all the robot's joints
    skipped_first: tuple | None = None  # (message number, names) of the first skipped
    no_velocity: int = 0  # rows whose velocity is empty
    no_effort: int = 0
    jitter_rows: int = 0  # rows whose stamp ties or goes back within the jitter: re-timed, kept
    jitter_tol_ns: float = 0.0
    zero_stamps: dict = field(default_factory=dict)  # topic -> [count, first message (1-based), messages]
    wrench_back: dict = field(default_factory=dict)  # topic -> [count, first message (1-based), messages]
    frames: dict = field(default_factory=dict)  # topic -> set of frame_ids
    damage: BagDamage | None = None  # where a --keep-partial read stopped
    first_lacking: tuple | None = None  # (message number, missing joints, names) for the refusal


@dataclass
class BagChunk:
    """Rows ``first_row`` .. of one bag: header stamps [ns] (a zero stamp replaced by the receive time),
    times [ns] with jittered stamps re-timed (float), q, qd, effort (n, nv) with NaN where a message lacks
    the field (``time_ns`` from the bag's first row), the wrench topics (key -> (n, 6) [N, Nm], NaN rows where not interpolated) and the row
    problems (0-based row in the bag, why)."""

    first_row: int
    stamps_ns: np.ndarray
    time_ns: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    effort: np.ndarray
    wrenches: dict
    problems: list

    def __len__(self) -> int:
        return len(self.stamps_ns)


class _JointRows:
    """Joint-state batches turned into rows (matched to the robot's joints by name), pending until a
    chunk takes them."""

    def __init__(self, joints: list, stats: BagStats, batches, keep_partial: bool):
        self.joints, self.stats, self.nv = joints, stats, len(joints)
        self.batches, self.keep_partial, self.done = batches, keep_partial, False
        self.order_of, self.pending, self.n_pending, self.next_row = {}, [], 0, 0

    def chunk(self, size: int):
        """(stamps, q, qd, effort, problems) of about ``size`` rows: a chunk ends on a stamp that advances,
        so that a run of jittered stamps is re-timed whole (at most ``_SLACK`` rows more)."""
        while not self.done and self.n_pending < size + _SLACK:
            batch, _ = _next_batch(self.batches, self.stats, self.keep_partial)
            if batch is None:
                self.done = True
                break
            self._add(batch)
        if not self.pending:
            return np.zeros(0, np.int64), *(np.zeros((0, self.nv)) for _ in range(3)), []
        stamps, q, qd, eff = (np.concatenate([p[k] for p in self.pending]) for k in range(4))
        problems = [x for p in self.pending for x in p[4]]
        n = len(stamps)
        if n > size:  # the first length from ``size`` on whose last stamp advances past all before it
            last = min(n, size + _SLACK)
            ends = np.arange(max(size, 2), last + 1)
            ahead = stamps[ends - 1] > np.maximum.accumulate(stamps)[ends - 2]
            n = 1 if size < 2 else int(ends[np.argmax(ahead)]) if ahead.any() else last
        first = self.next_row - len(stamps)
        rest = [(stamps[n:], q[n:], qd[n:], eff[n:], [x for x in problems if x[0] >= first + n])]
        self.pending = rest if len(stamps) > n else []
        self.n_pending = len(stamps) - n
        return stamps[:n], q[:n], qd[:n], eff[:n], [x for x in problems if x[0] < first + n]

    def _add(self, batch) -> None:
        stats, nv, m = self.stats, self.nv, len(batch)
        q, qd, eff = (np.full((m, nv), np.nan) for _ in range(3))
        accept = np.zeros(m, bool)
        problems = {}
        for g in batch.groups:
            idx = self.order_of.get(g.names, False)
            if idx is False:  # one look-up per distinct joint order
                index = {name: i for i, name in enumerate(g.names)}
                missing = [j for j in self.joints if j not in index]
                idx = None if missing else np.array([index[j] for j in self.joints])
                self.order_of[g.names] = idx
            if idx is None:  # a gripper's own message: not a row of the robot
                first = stats.messages + int(g.at[0]) + 1
                if stats.skipped_first is None or first < stats.skipped_first[0]:
                    stats.skipped_first = (first, list(g.names))
                if stats.first_lacking is None or first < stats.first_lacking[0]:
                    missing = [j for j in self.joints if j not in g.names]
                    stats.first_lacking = (first, missing, list(g.names))
                continue
            accept[g.at] = True
            for out, fld in ((q, "position"), (qd, "velocity"), (eff, "effort")):
                arr = g.fields[fld]
                if arr.shape[1] == len(g.names):
                    out[g.at] = arr[:, idx]
                elif arr.shape[1] == 0 and fld != "position":  # an empty field is a missing field
                    if fld == "velocity":
                        stats.no_velocity += len(g.at)
                    else:
                        stats.no_effort += len(g.at)
                else:
                    for i in g.at:
                        problems.setdefault(int(i), []).append(
                            f"{fld} has {arr.shape[1]} values for {len(g.names)} joint names")
        stats.messages += m
        stats.skipped += int((~accept).sum())
        rows = np.cumsum(accept) - 1 + self.next_row  # each accepted message's row in the bag
        probs = [(int(rows[i]), why) for i in sorted(problems) for why in problems[i]]
        keep = np.flatnonzero(accept)
        self.pending.append((batch.stamps[keep], q[keep], qd[keep], eff[keep], probs))
        self.n_pending += len(keep)
        self.next_row += len(keep)


class _Retimer:
    """Stamps that tie or go back by at most half the stream's median step (its jitter) are kept in
    order and re-timed evenly between the advancing stamps around them; a stamp further back is left
    as it is (the importer's time_order rule drops its row)."""

    def __init__(self, stats: BagStats):
        self.ref, self.tol, self.stats, self.t0 = None, None, stats, None

    def __call__(self, stamps: np.ndarray) -> np.ndarray:
        """Times [ns] from the bag's first row's stamp (exact in float64 for 104 days)."""
        if not len(stamps):
            return np.zeros(0)
        if self.t0 is None:
            self.t0 = int(stamps[0])
        t = (stamps - self.t0).astype(np.float64)
        if self.tol is None:
            steps = np.diff(stamps)
            steps = steps[steps > 0]
            self.tol = 0.5 * float(np.median(steps)) if len(steps) else 0.0
            self.stats.jitter_tol_ns = self.tol
        prev = np.maximum.accumulate(np.r_[self.ref if self.ref is not None else stamps[0] - 1, stamps[:-1]])
        adv = stamps > prev
        jitter = ~adv & (stamps >= prev - self.tol)
        adv_idx = np.flatnonzero(adv)
        if jitter.any():
            for run in np.split(np.flatnonzero(~adv), np.flatnonzero(np.diff(np.flatnonzero(~adv)) > 1) + 1):
                after = adv_idx[np.searchsorted(adv_idx, run[-1])] if adv_idx.size and adv_idx[-1] > run[-1] else None
                if after is None:
                    continue  # nothing advances after them: left for the time_order rule
                lo, m = float(prev[run[0]] - self.t0), len(run)
                even = lo + (np.arange(1, m + 1) / (m + 1)) * (float(stamps[after] - self.t0) - lo)
                t[run] = np.where(jitter[run], even, t[run])
                self.stats.jitter_rows += int(jitter[run].sum())
        self.ref = max(int(prev[-1]), int(stamps[-1]))  # the running maximum
        return t


class _WrenchWindow:
    """One wrench topic's samples around the current chunk's stamps: pulled as far as needed, the ones
    before the chunk let go."""

    def __init__(self, path: Path, topic: str, counts: dict, stats: BagStats, keep_partial: bool):
        self.msgs = topic_batches(path, topic, counts)
        self.path, self.topic, self.stats, self.keep_partial = path, topic, stats, keep_partial
        self.ns = np.zeros(0, np.int64)
        self.x = np.zeros((0, 6))
        self.done, self.first_ns, self.max_step, self.n, self.last = False, None, None, 0, None
        self.stop_ns = None  # the last good stamp where damage stopped a --keep-partial read

    def pull(self, upto_ns: int) -> None:
        """Read until a sample past ``upto_ns`` (or the end)."""
        ns, xs = [self.ns], [self.x]
        frames = self.stats.frames.setdefault(self.topic, set())
        back = self.stats.wrench_back.setdefault(self.topic, [0, 0, 0])
        while not self.done and (self.last is None or self.last <= upto_ns):
            batch, dmg = _next_batch(self.msgs, self.stats, self.keep_partial)
            if batch is None:
                self.done = True
                if dmg is not None:
                    self.stop_ns = dmg.last_ns
                break
            x = np.full((len(batch), 6), np.nan)
            for g in batch.groups:
                frames.add(g.names)
                x[g.at] = g.fields["wrench"]
            stamps = batch.stamps
            before = np.maximum.accumulate(np.r_[self.last if self.last is not None else stamps[0] - 1, stamps[:-1]])
            ahead = stamps > before  # a stamp that does not advance cannot be interpolated between: left out
            if not ahead.all():
                back[0] += int((~ahead).sum())
                back[1] = back[1] or self.n + int(np.argmin(ahead)) + 1
            self.n += len(batch)
            back[2] = self.n
            self.last = max(int(before[-1]), int(stamps[-1]))
            ns.append(stamps[ahead])
            xs.append(x[ahead])
        if len(ns) > 1:
            self.ns, self.x = np.concatenate(ns), np.concatenate(xs)
            if self.first_ns is None and len(self.ns):
                self.first_ns = int(self.ns[0])
            if self.max_step is None and len(self.ns) > 1:  # the topic's median step, from its first samples
                self.max_step = float(np.median(np.diff(self.ns[:10_001])))

    def at(self, dst_ns: np.ndarray, rule: str, jump_factor: float):
        if not len(dst_ns):
            return np.zeros((0, 6)), []
        self.pull(int(dst_ns.max()))
        if not len(self.ns):
            return np.full((len(dst_ns), 6), np.nan), [(r, "the topic has no sample here (not extrapolated)")
                                                      for r in range(len(dst_ns))]
        span = (self.first_ns, int(self.ns[-1]) if self.done else None)
        values, bad = resample(self.ns, self.x, dst_ns, rule, jump_factor,
                               max_step=jump_factor * (self.max_step or 0.0), topic_span=span)
        keep_from = max(int(np.searchsorted(self.ns, dst_ns.min())) - 1, 0)  # the sample before the chunk stays
        self.ns, self.x = self.ns[keep_from:], self.x[keep_from:]
        return values, bad


def bag_chunks(path: Path, ros, joints: list, jump_factor: float, stats: BagStats, keep_partial: bool = False,
               size: int = CHUNK_ROWS):
    """The bag's rows in :class:`BagChunk` s of about ``size`` rows (see the module docstring)."""
    from .log_spec import WRENCH_TOPICS

    batches = topic_batches(path, ros.joint_states, stats.zero_stamps)
    rows, retime = _JointRows(joints, stats, batches, keep_partial), _Retimer(stats)
    windows = {k: _WrenchWindow(path, getattr(ros, k), stats.zero_stamps, stats, keep_partial)
               for k in WRENCH_TOPICS if getattr(ros, k)}
    try:
        yield from _chunks(rows, retime, windows, ros, jump_factor, size)
    finally:  # the readers of topics not read to their end
        for win in windows.values():
            win.msgs.close()
        batches.close()


def _chunks(rows, retime, windows, ros, jump_factor, size):
    first_row, stopped = 0, False
    while not stopped:
        stamps, q, qd, eff, problems = rows.chunk(size)
        if not len(stamps):
            return
        stopped = rows.done and not rows.n_pending
        wrenches = {}
        for key, win in windows.items():
            values, bad = win.at(stamps, ros.resample, jump_factor)
            wrenches[key] = values
            problems += [(first_row + r, f"{win.topic}: {why}") for r, why in bad]
        cut = [w.stop_ns for w in windows.values() if w.stop_ns is not None]
        if cut:  # a damaged wrench topic ends the rows at its last good stamp
            keep = stamps <= min(cut)
            n = int(np.argmin(keep)) if not keep.all() else len(stamps)
            stamps, q, qd, eff = stamps[:n], q[:n], qd[:n], eff[:n]
            wrenches = {k: v[:n] for k, v in wrenches.items()}
            problems = [p for p in problems if p[0] < first_row + n]
            stopped = stopped or n < len(keep)
        if not len(stamps):
            return
        yield BagChunk(first_row, stamps, retime(stamps), q, qd, eff, wrenches, sorted(problems))
        first_row += len(stamps)


def resample(src_ns: np.ndarray, src_x: np.ndarray, dst_ns: np.ndarray, rule: str, jump_factor: float,
             max_step: float | None = None, topic_span: tuple | None = None):
    """``src_x`` (stamps ``src_ns``, increasing [ns]) at the stamps ``dst_ns``: (values with NaN rows,
    [(row, why) for each NaN row]). A stamp outside the source's span or inside one of its gaps (a step
    over ``jump_factor`` median steps, or over ``max_step`` [ns] where given) is not extrapolated.
    ``topic_span``: the topic's (first, last) stamps [ns] when ``src_ns`` is a window of it (last None: not
    yet known), for the report."""
    values = np.full((len(dst_ns), src_x.shape[1]), np.nan)
    k = np.searchsorted(src_ns, dst_ns, side="left")  # src[k-1] < dst <= src[k]
    exact = (k < len(src_ns)) & (src_ns[np.minimum(k, len(src_ns) - 1)] == dst_ns)
    values[exact] = src_x[k[exact]]
    inside = ~exact & (k > 0) & (k < len(src_ns))
    lo, hi = k[inside] - 1, k[inside]
    span = (src_ns[hi] - src_ns[lo]).astype(np.float64)
    if max_step is None:
        max_step = jump_factor * float(np.median(np.diff(src_ns))) if len(src_ns) > 1 else 0.0
    gap = span > max_step
    w = (dst_ns[inside] - src_ns[lo]) / span
    if rule == "nearest":
        w = (w > 0.5).astype(np.float64)  # a tie goes to the earlier sample
    filled = src_x[lo] + w[:, None] * (src_x[hi] - src_x[lo])
    filled[gap] = np.nan
    values[inside] = filled
    bad = []
    first, last = topic_span if topic_span is not None else (int(src_ns[0]), int(src_ns[-1]))
    shown = f"[{first * 1e-9:.6f}, {last * 1e-9:.6f}] s" if last is not None else f"from {first * 1e-9:.6f} s"
    for r in np.flatnonzero(~exact & ~inside):
        side = "before" if k[r] == 0 else "after"
        bad.append((r, f"stamp {dst_ns[r] * 1e-9:.6f} s is {side} the topic's span {shown} (not extrapolated)"))
    rows = np.flatnonzero(inside)[gap]
    for r, s in zip(rows, span[gap]):
        bad.append((r, f"stamp {dst_ns[r] * 1e-9:.6f} s lies in a gap of {s * 1e-9:.4g} s of the topic "
                       f"(over {jump_factor:g} median steps: not interpolated)"))
    return values, bad


def _next_batch(batches, stats, keep_partial: bool):
    """(the topic's next batch, None) or, at its end, (None, None); at damage, with ``keep_partial``,
    (None, the damage), recorded in ``stats`` (the first damage is the one reported); without it, raise."""
    try:
        return next(batches), None
    except StopIteration:
        return None, None
    except BagDamage as dmg:
        if not keep_partial:
            raise
        stats.damage = stats.damage or dmg
        return None, dmg
