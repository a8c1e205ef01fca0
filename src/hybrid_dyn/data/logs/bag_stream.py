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

CHUNK_ROWS = 65_536  # joint-state rows per chunk: ~15 MB of numbers for a 7-joint arm with two wrenches
_SLACK = 1024  # rows a chunk may grow by to close a run of jittered stamps at its end


class BagDamage(Exception):
    """A message of ``topic`` could not be read: ``index`` messages were read before it, the last with
    stamp ``last_ns`` (None before the first)."""

    def __init__(self, path: Path, topic: str, index: int, last_ns, err: Exception):
        self.path, self.topic, self.index, self.last_ns = path, topic, index, last_ns
        what = " ".join(f"{type(err).__name__}: {err}".split())  # one line, whatever the reader said
        super().__init__(what if str(err).strip() else f"{type(err).__name__} in the reader")


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


def open_reader(path: Path):
    """An opened ``rosbags`` AnyReader of one bag, or a one-line ``LogReadError``."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from .log_readers import LogReadError

    if not path.exists():
        raise LogReadError(f"bag {path} does not exist")
    if path.is_file() and path.suffix not in (".bag", ".mcap", ".db3"):
        raise LogReadError(f"{path}: not a ROS bag (a ROS 1 .bag, a ROS 2 .mcap or .db3 file, or a ROS 2 bag folder)")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise LogReadError(f"{path}: a folder without metadata.yaml is no ROS 2 bag; name its .mcap or .db3 file")
    # Bags that embed no message definitions (old ROS 2 sqlite3 bags) are read with the distribution's types.
    store = get_typestore(Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE)
    try:
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    except Exception as err:  # rosbags raises its own reader errors, and FileNotFoundError for a folder
        raise LogReadError(f"{path}: not a readable ROS bag: {' '.join(str(err).split())}") from None
    return reader


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def topic_messages(path: Path, topic: str, counts: dict):
    """(stamp [ns], message) of one topic in the bag's order, read by a reader of its own; a zero header
    stamp is replaced by the receive time and counted in ``counts`` [count, first, messages]. Damage
    raises :class:`BagDamage`."""
    reader = open_reader(path)
    last, n = None, 0
    count = counts.setdefault(topic, [0, 0, 0])
    try:
        it = reader.messages(connections=[c for c in reader.connections if c.topic == topic])
        while True:
            try:  # anything the reader or the decoder raises here is the file's damage, not ours
                conn, ts, raw = next(it)
                msg = reader.deserialize(raw, conn.msgtype)
                stamp = _stamp(msg)
            except StopIteration:
                break
            except Exception as err:
                raise BagDamage(path, topic, n, last, err) from None
            n += 1
            count[2] = n
            if stamp == 0:
                count[0] += 1
                count[1] = count[1] or n
                stamp = ts
            last = stamp
            yield stamp, msg
    finally:
        reader.close()


class _JointRows:
    """Decodes joint-state messages into preallocated rows, matched to the robot's joints by name."""

    def __init__(self, joints: list, stats: BagStats):
        self.joints, self.stats, self.nv = joints, stats, len(joints)
        self.order_of = {}

    def chunk(self, msgs, size: int, first_row: int, keep_partial: bool):
        """At most about ``size`` rows; with ``keep_partial``, damage ends the rows (``stats.damage``)."""
        out = ([], [], [], [], [])
        try:
            out = self._chunk(msgs, size, first_row)
        except BagDamage as dmg:
            if not keep_partial:
                raise
            self.stats.damage = self.stats.damage or dmg
            out = self.partial
        return out

    def _chunk(self, msgs, size: int, first_row: int):
        nv, stats = self.nv, self.stats
        cap = size + _SLACK
        stamps = np.zeros(cap, np.int64)
        q, qd, eff = (np.full((cap, nv), np.nan) for _ in range(3))
        problems, k, ref = [], 0, None
        self.partial = (stamps[:0], q[:0], qd[:0], eff[:0], problems)
        for stamp, m in msgs:
            stats.messages += 1
            names = tuple(m.name)
            idx = self.order_of.get(names, False)
            if idx is False:  # the order may change per message: one look-up per distinct order
                index = {name: i for i, name in enumerate(names)}
                missing = [j for j in self.joints if j not in index]
                idx = None if missing else np.array([index[j] for j in self.joints])
                self.order_of[names] = idx
                if missing and stats.first_lacking is None:
                    stats.first_lacking = (stats.messages, missing, list(names))
            if idx is None:  # a gripper's own message: not a row of the robot
                stats.skipped += 1
                if stats.skipped_first is None:
                    stats.skipped_first = (stats.messages, list(names))
                continue
            stamps[k] = stamp
            row = first_row + k
            for out, fld, arr in ((q, "position", m.position), (qd, "velocity", m.velocity), (eff, "effort", m.effort)):
                if len(arr) == len(names):
                    out[k] = np.asarray(arr, dtype=np.float64)[idx]
                elif len(arr) == 0 and fld != "position":  # an empty field is a missing field
                    if fld == "velocity":
                        stats.no_velocity += 1
                    else:
                        stats.no_effort += 1
                else:
                    problems.append((row, f"{fld} has {len(arr)} values for {len(names)} joint names"))
            k += 1
            self.partial = (stamps[:k], q[:k], qd[:k], eff[:k], problems)
            # A chunk ends on a stamp that advances, so that a run of jittered stamps is re-timed whole.
            if k >= size and (ref is None or stamp > ref or k == cap):
                break
            ref = stamp if ref is None else max(ref, stamp)
        return stamps[:k], q[:k], qd[:k], eff[:k], problems


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
        self.msgs = topic_messages(path, topic, counts)
        self.path, self.topic, self.stats, self.keep_partial = path, topic, stats, keep_partial
        self.ns = np.zeros(0, np.int64)
        self.x = np.zeros((0, 6))
        self.done, self.first_ns, self.max_step, self.n, self.last = False, None, None, 0, None
        self.stop_ns = None  # the last good stamp where damage stopped a --keep-partial read

    def pull(self, upto_ns: int) -> None:
        """Read until a sample past ``upto_ns`` (or the end)."""
        ns, xs = [], []
        frames = self.stats.frames.setdefault(self.topic, set())
        back = self.stats.wrench_back.setdefault(self.topic, [0, 0, 0])
        while not self.done and (self.last is None or self.last <= upto_ns):
            try:
                stamp, m = next(self.msgs)
            except StopIteration:
                self.done = True
                break
            except BagDamage as dmg:
                if not self.keep_partial:
                    raise
                self.done, self.stop_ns = True, dmg.last_ns
                self.stats.damage = self.stats.damage or dmg
                break
            self.n += 1
            back[2] = self.n
            frames.add(m.header.frame_id)
            if self.last is not None and stamp <= self.last:  # cannot be interpolated between: left out
                back[0] += 1
                back[1] = back[1] or self.n
                continue
            self.last = stamp
            f, tq = m.wrench.force, m.wrench.torque
            ns.append(stamp)
            xs.append((f.x, f.y, f.z, tq.x, tq.y, tq.z))
        if ns:
            self.ns = np.r_[self.ns, np.array(ns, np.int64)]
            self.x = np.concatenate([self.x, np.array(xs, np.float64)])
            if self.first_ns is None:
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

    rows, retime = _JointRows(joints, stats), _Retimer(stats)
    msgs = topic_messages(path, ros.joint_states, stats.zero_stamps)
    windows = {k: _WrenchWindow(path, getattr(ros, k), stats.zero_stamps, stats, keep_partial)
               for k in WRENCH_TOPICS if getattr(ros, k)}
    try:
        yield from _chunks(rows, retime, msgs, windows, ros, jump_factor, stats, keep_partial, size)
    finally:  # the readers of topics not read to their end
        for win in windows.values():
            win.msgs.close()
        msgs.close()


def _chunks(rows, retime, msgs, windows, ros, jump_factor, stats, keep_partial, size):
    first_row, stopped = 0, False
    while not stopped:
        stamps, q, qd, eff, problems = rows.chunk(msgs, size, first_row, keep_partial)
        if not len(stamps):
            return
        stopped = len(stamps) < size or stats.damage is not None
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
