"""ROS 1 and ROS 2 bags as one more log reader (``docs/from_a_ros_bag.md``).

The detail (what it computes, the equations, why each choice): docs/design/data.md, section ``data/logs/ros_bag.py``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bag_stream import CHUNK_ROWS, BagChunk, BagDamage, BagStats, bag_chunks, open_reader, resample  # noqa: F401
from .log_spec import RESAMPLE_RULES, WRENCH_TOPICS, LogImportError, RosTopics  # noqa: F401 (re-exported)
from .log_readers import LogReadError, LogTable

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH = "geometry_msgs/msg/WrenchStamped"

class RosBagError(LogImportError):
    """A bag does not hold what the spec's ``[ros]`` table names (a topic, a joint, a frame)."""


@dataclass
class RosTable(LogTable):
    """A bag as a log table, with each row's stamp [ns] (int64; ``t`` = stamp - ``t0_ns``, in s)."""

    stamps_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    t0_ns: int = 0
    absent: list = field(default_factory=list)  # signals the bag does not carry (every message's field empty)
    qd_missing: np.ndarray | None = None  # rows whose velocity is empty: qd is derived from q there


def read_bags(spec, report, keep_partial: bool = False) -> list[RosTable]:
    """One table per bag of ``spec.files``; the time-base notes go to ``report.warnings``. ``keep_partial``:
    a damaged bag keeps the rows read before the damage (else it is a one-line error)."""
    joints, frames = bag_names(spec)
    return [_read_bag(Path(f), spec.ros, joints, frames, spec.checks.jump_factor, report.warnings, keep_partial)
            for f in spec.files]


def bag_names(spec) -> tuple[list, set]:
    """The joint names to match (the robot's order) and the frame_ids a wrench topic may have."""
    joints, base_frame = _robot_names(spec)
    frames = {spec.ros.frame} if spec.ros.frame is not None else {base_frame}
    if frames == {None} and (spec.ros.base_wrench or spec.ros.tip_wrench):
        raise RosBagError(f"robot {spec.robot!r} has no description naming its base-sensor frame: give the "
                          "wrench topics' frame_id as [ros] frame = \"...\"")
    return joints, frames


def _robot_names(spec) -> tuple[list, str | None]:
    """The joint names to match (the robot's order) and the robot's base-sensor frame name."""
    from ...description import joint_limits, resolve_robot

    ref = resolve_robot(spec.robot)
    if not ref.described:
        if spec.ros.joints is None:
            raise RosBagError(f"robot {spec.robot!r} has no description to match joint names against: "
                              "give them in order as [ros] joints = [...]")
        return list(spec.ros.joints), None
    robot = joint_limits(ref.spec)
    joints = list(spec.ros.joints) if spec.ros.joints is not None else list(robot.names)
    if len(joints) != robot.nv:
        raise RosBagError(f"[ros] joints names {len(joints)} joints, robot {spec.robot!r} has {robot.nv}")
    return joints, ref.spec.base_sensor_frame


def check_topics(path: Path, ros: RosTopics) -> None:
    """Every topic the spec names is in the bag with its message type, else a one-line error."""
    reader = open_reader(path)
    try:
        topics = {t: info.msgtype for t, info in reader.topics.items()}
    finally:
        reader.close()
    wanted = {"joint_states": (ros.joint_states, JOINT_STATE)}
    wanted.update({k: (getattr(ros, k), WRENCH) for k in WRENCH_TOPICS if getattr(ros, k)})
    for key, (topic, msgtype) in wanted.items():
        if topic not in topics:
            raise RosBagError(f"{path.name}: no topic {topic} ([ros] {key}); the bag has {sorted(topics)}")
        if topics[topic] != msgtype:
            raise RosBagError(f"{path.name}: topic {topic} ([ros] {key}) is {topics[topic]}, not {msgtype}")


def read_chunks(path: Path, ros: RosTopics, joints: list, frames: set, jump_factor: float, stats: BagStats,
                keep_partial: bool = False, size: int = CHUNK_ROWS):
    """The bag's rows chunk by chunk (``bag_stream.bag_chunks``), its topics checked first; damage is a
    one-line error naming the file, the topic, the message and the last good stamp."""
    check_topics(path, ros)
    try:
        for chunk in bag_chunks(path, ros, joints, jump_factor, stats, keep_partial, size):
            _check_frames(path, stats, frames)
            yield chunk
    except BagDamage as dmg:
        raise LogReadError(f"{path}: damaged: {damage_text(dmg)}; --keep-partial keeps what was read before "
                           "it") from None
    _check_frames(path, stats, frames)
    if stats.messages == stats.skipped:
        if stats.damage is not None:  # --keep-partial, and nothing of the robot before the damage
            raise LogReadError(f"{path}: damaged before any row could be read: {damage_text(stats.damage)}")
        if not stats.messages:
            raise RosBagError(f"{path.name}: topic {ros.joint_states} has no messages")
        n, missing, names = stats.first_lacking
        raise RosBagError(f"{path.name}: no {ros.joint_states} message carries all the robot's joints: "
                          f"{ros.joint_states} message {n} lacks the robot's joints {missing}; it names {names}")
    for key in WRENCH_TOPICS:
        topic = getattr(ros, key)
        if topic and not stats.zero_stamps.get(topic, [0, 0, 0])[2] and stats.damage is None:
            raise RosBagError(f"{path.name}: topic {topic} has no messages")


def damage_text(dmg: BagDamage) -> str:
    """Where the damage is: the topic, the message, the last good stamp."""
    last = ("no message of it could be read" if dmg.last_ns is None else
            f"the last good stamp is {dmg.last_ns * 1e-9:.6f} s")
    return f"message {dmg.index + 1} of {dmg.topic} cannot be read ({dmg}); {last}"


def _check_frames(path: Path, stats: BagStats, frames: set) -> None:
    for topic, seen in stats.frames.items():
        bad = sorted(seen - frames)
        if bad:
            raise RosBagError(f"{path.name}: {topic} is in frame {bad[0]!r}, not the robot's base-sensor frame "
                              f"{sorted(frames)[0]!r}; if that frame is the base sensor's, say so with [ros] frame = "
                              f"{bad[0]!r}")


def _read_bag(path: Path, ros: RosTopics, joints: list, frames: set, jump_factor: float, notes: list,
              keep_partial: bool) -> RosTable:
    stats = BagStats()
    chunks = list(read_chunks(path, ros, joints, frames, jump_factor, stats, keep_partial))
    if not chunks:  # damage before the first row of the robot (--keep-partial)
        raise LogReadError(f"{path}: damaged before any row could be read: {damage_text(stats.damage)}")
    cat = lambda key: np.concatenate([getattr(c, key) for c in chunks])  # noqa: E731
    whole = BagChunk(0, cat("stamps_ns"), cat("time_ns"), cat("q"), cat("qd"), cat("effort"),
                     {k: np.concatenate([c.wrenches[k] for c in chunks]) for k in chunks[0].wrenches},
                     [p for c in chunks for p in c.problems])
    chunks.clear()  # the chunks' memory goes before the table's is taken
    rows = len(whole)
    notes += bag_notes(path, ros, stats, rows)
    return chunk_table(path, whole, ros, joints, with_qd=stats.no_velocity < rows, torque=stats.no_effort < rows)


def chunk_table(path: Path, chunk: BagChunk, ros: RosTopics, joints: list, with_qd: bool, torque: bool) -> RosTable:
    """Rows of a bag as a log table: ``t`` [s] from the bag's first stamp, q, qd (``with_qd``; NaN rows
    where the velocity is empty, listed in ``qd_missing``), the torque fields (``torque``), the wrenches."""
    data, names = [(chunk.time_ns * 1e-9)[:, None]], ["t"]
    fields = ros.torque_fields() if torque else []
    for key, src in [("q", chunk.q)] + ([("qd", chunk.qd)] if with_qd else []) + [(f, chunk.effort) for f in fields]:
        data.append(src)
        names += [f"{key}[{j + 1}]" for j in range(len(joints))]
    for key in WRENCH_TOPICS:
        if getattr(ros, key):
            fld = WRENCH_TOPICS[key]
            width = 6 if fld == "base_wrench" else 3
            data.append(chunk.wrenches[key][:, :width])
            names += [f"{fld}[{j + 1}]" for j in range(width)]
    absent = ([] if with_qd else ["qd"]) + ([] if torque else ros.torque_fields())
    qd_missing = ~np.isfinite(chunk.qd).any(axis=1) if with_qd else None
    t0 = int(chunk.stamps_ns[0] - round(chunk.time_ns[0])) if len(chunk) else 0
    return RosTable(path.stem if path.is_file() else path.name, path, np.concatenate(data, axis=1), names,
                    sorted(chunk.problems), None, stamps_ns=chunk.stamps_ns, t0_ns=t0, absent=absent,
                    qd_missing=qd_missing)


def bag_notes(path: Path, ros: RosTopics, stats: BagStats, rows: int) -> list[str]:
    """The report's lines on what reading the bag found: the time base, skipped messages, missing fields,
    re-timed stamps, where damage stopped a partial read."""
    js = ros.joint_states
    out = []
    for topic, (n, first, total) in stats.zero_stamps.items():
        if n:
            out.append(f"time base: {path.name} {topic}: {n} of {total} messages have a zero header stamp (the "
                       f"first is message {first}); their receive time is used")
    for topic, (n, first, total) in stats.wrench_back.items():
        if n:
            out.append(f"time base: {path.name} {topic}: {n} of {total} messages have a stamp that does not "
                       f"advance (the first is message {first}); they are left out")
    if stats.jitter_rows:
        out.append(f"time base: {path.name} {js}: {stats.jitter_rows} stamps tie or go back within the stream's "
                   f"jitter (at most {stats.jitter_tol_ns * 1e-6:.4g} ms, half its median step); kept in message "
                   "order, re-timed evenly between the stamps around them")
    wrenches = [getattr(ros, k) for k in WRENCH_TOPICS if getattr(ros, k)]
    if wrenches:  # the rule, stated once per bag
        out.append(f"time base: {path.name}: the header stamps of {js}; {' and '.join(wrenches)} at them by "
                   f"{'linear interpolation' if ros.resample == 'linear' else 'the nearest sample'} "
                   "(never extrapolated)")
    if stats.skipped:
        n, names = stats.skipped_first
        out.append(f"{path.name} {js}: {stats.skipped} of {stats.messages} messages lack the robot's joints "
                   f"(the first is message {n}, naming {names}); skipped")
    if stats.no_velocity == rows:
        out.append(f"{path.name} {js}: no message carries a velocity; qd is derived from q")
    elif stats.no_velocity:
        out.append(f"{path.name} {js}: {stats.no_velocity} of {rows} rows have no velocity; their qd is derived "
                   "from q")
    if stats.no_effort == rows:
        out.append(f"{path.name} {js}: no message carries an effort: the log has no joint torques")
    if stats.damage is not None:
        out.append(f"{path.name}: damaged, read stopped: {damage_text(stats.damage)}; the {rows} rows before it "
                   "are kept (--keep-partial)")
    return out
