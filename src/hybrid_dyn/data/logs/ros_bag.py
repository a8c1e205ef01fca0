"""ROS 1 and ROS 2 bags as one more log reader (``docs/from_a_ros_bag.md``).

A spec's ``[ros]`` table (:class:`RosTopics`) names the topics; :func:`read_bags` turns each bag into
one :class:`RosTable` with the columns the spec maps (``t``, ``q[1..n]``, ``qd``, ``tau_m`` and/or
``tau_J`` (``effort``), ``base_wrench[1..6]``, ``tip_force[1..3]``), and the importer's own checks (``log_validation.py``) run
on it exactly as on a CSV file: a row is one ``/joint_states`` message (row 1 = the first).

The time base (stated in the import report):

- every message's time is its header stamp; a zero stamp (a driver that does not fill it) is replaced
  by the bag's receive time, and the report says how many messages of which topic got it;
- the rows are the joint-state messages; a wrench topic is put on their stamps by ``resample``:
  ``"linear"`` interpolation between the two wrench samples around a stamp, or the ``"nearest"`` of
  them. Never extrapolation: a stamp before the topic's first sample, after its last, or inside a gap
  of the topic (two samples more than ``jump_factor`` median steps apart) gets NaN cells listed by row,
  so the importer drops that row and reports why;
- a joint-state stamp that goes backwards is the CSV rule's (``time_order``: the row is dropped and
  named); a wrench message whose stamp does not advance is left out of the interpolation and counted
  in the report.

Joint names are matched to the robot description by name in every message (their order may change
from message to message); names the robot does not have (a second arm, the gripper's fingers) are
ignored; a robot joint that a message lacks is refused, named. A wrench whose ``frame_id`` is not the
robot's base-sensor frame is refused, named, unless the spec's ``frame`` says which frame_id the bag
uses for it. Bags are read with ``rosbags`` (pure Python, no ROS installation).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

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


def read_bags(spec, report) -> list[RosTable]:
    """One table per bag of ``spec.files``; the time-base notes go to ``report.warnings``."""
    joints, base_frame = _robot_names(spec)
    frames = {spec.ros.frame} if spec.ros.frame is not None else {base_frame}
    if frames == {None} and (spec.ros.base_wrench or spec.ros.tip_wrench):
        raise RosBagError(f"robot {spec.robot!r} has no description naming its base-sensor frame: give the "
                          "wrench topics' frame_id as [ros] frame = \"...\"")
    return [_read_bag(Path(f), spec.ros, joints, frames, spec.checks.jump_factor, report.warnings)
            for f in spec.files]


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


def _open(path: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

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
        raise LogReadError(f"{path}: not a readable ROS bag: {err}") from None
    return reader


def _read_bag(path: Path, ros: RosTopics, joints: list, frames: set, jump_factor: float, notes: list) -> RosTable:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error

    reader = _open(path)
    wanted = {"joint_states": (ros.joint_states, JOINT_STATE)}
    wanted.update({k: (getattr(ros, k), WRENCH) for k in WRENCH_TOPICS if getattr(ros, k)})
    try:
        topics = {t: info.msgtype for t, info in reader.topics.items()}
        for key, (topic, msgtype) in wanted.items():
            if topic not in topics:
                raise RosBagError(f"{path.name}: no topic {topic} ([ros] {key}); the bag has {sorted(topics)}")
            if topics[topic] != msgtype:
                raise RosBagError(f"{path.name}: topic {topic} ([ros] {key}) is {topics[topic]}, not {msgtype}")
        # Each topic is reduced to numbers as it is read: an hour at 1 kHz never sits in memory as messages.
        stamps, cols = _joint_states(path, ros.joint_states, _messages(reader, ros.joint_states), joints, notes)
        wrenches = {k: _wrenches(path, getattr(ros, k), _messages(reader, getattr(ros, k)), frames, notes)
                    for k in WRENCH_TOPICS if k in wanted}
    except (AnyReaderError, Reader1Error, Reader2Error) as err:  # a truncated or corrupt bag
        raise LogReadError(f"{path}: a message could not be read: {err}") from None
    finally:
        reader.close()
    problems = cols.pop("problems")
    t0 = int(stamps[0])
    data, names = [((stamps - t0) * 1e-9)[:, None]], ["t"]  # seconds from the first stamp
    for key, src in [("q", "q"), ("qd", "qd")] + [(f, "effort") for f in ros.torque_fields()]:
        data.append(cols[src])
        names += [f"{key}[{j + 1}]" for j in range(len(joints))]
    for key, (w_t, w_x) in wrenches.items():
        topic, fld = getattr(ros, key), WRENCH_TOPICS[key]
        values, bad = resample(w_t, w_x, stamps, ros.resample, jump_factor)
        width = 6 if fld == "base_wrench" else 3
        data.append(values[:, :width])
        names += [f"{fld}[{j + 1}]" for j in range(width)]
        problems += [(int(r), f"{topic}: {why}") for r, why in bad]
    if wrenches:  # the rule, stated once per bag
        topics = " and ".join(getattr(ros, k) for k in wrenches)
        notes.append(f"time base: {path.name}: the header stamps of {ros.joint_states}; {topics} at them by "
                     f"{'linear interpolation' if ros.resample == 'linear' else 'the nearest sample'} "
                     "(never extrapolated)")
    return RosTable(path.stem if path.is_file() else path.name, path, np.concatenate(data, axis=1), names,
                    sorted(problems), None, stamps_ns=stamps, t0_ns=t0)


def _messages(reader, topic: str):
    """(receive time [ns], message) of one topic, in the bag's order."""
    conns = [c for c in reader.connections if c.topic == topic]
    for c, ts, raw in reader.messages(connections=conns):
        yield ts, reader.deserialize(raw, c.msgtype)


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _stamps(path: Path, topic: str, header_ns: list, receive_ns: list, notes: list) -> np.ndarray:
    """Header stamps [ns]; a zero stamp is replaced by the receive time, and the report says so."""
    stamps = np.array(header_ns, np.int64)
    zero = stamps == 0
    if zero.any():
        stamps[zero] = np.array(receive_ns, np.int64)[zero]
        notes.append(f"time base: {path.name} {topic}: {int(zero.sum())} of {len(stamps)} messages have a zero header "
                     f"stamp (the first is message {int(np.flatnonzero(zero)[0]) + 1}); their receive time is used")
    return stamps


def _joint_states(path: Path, topic: str, msgs, joints: list, notes: list):
    """Stamps [ns] and the q, qd, effort matrices (n messages x n joints), by joint name."""
    nv = len(joints)
    missing_row = np.full(nv, np.nan)
    out = {k: [] for k in ("q", "qd", "effort")}
    header, receive, problems, order_of = [], [], [], {}
    seen = {"qd": False, "effort": False}
    for r, (ts, m) in enumerate(msgs):
        header.append(_stamp(m))
        receive.append(ts)
        names = tuple(m.name)
        if names not in order_of:  # the order may change per message: one look-up per distinct order
            index = {name: i for i, name in enumerate(names)}
            missing = [j for j in joints if j not in index]
            if missing:
                raise RosBagError(f"{path.name}: {topic} message {r + 1} lacks the robot's joints {missing}; "
                                  f"it names {list(names)}")
            order_of[names] = np.array([index[j] for j in joints])
        idx = order_of[names]
        for key, field_name, arr in (("q", "position", m.position), ("qd", "velocity", m.velocity),
                                     ("effort", "effort", m.effort)):
            arr = np.asarray(arr, dtype=np.float64)
            seen[key] = seen.get(key) or len(arr) > 0
            if len(arr) == len(names):
                out[key].append(arr[idx])
                continue
            out[key].append(missing_row)  # NaN cells: the row is dropped and named
            if len(arr) or key == "q":
                problems.append((r, f"{topic}: {field_name} has {len(arr)} values for {len(names)} joint names"))
    if not header:
        raise RosBagError(f"{path.name}: topic {topic} has no messages")
    for what, key in (("velocity", "qd"), ("effort", "effort")):
        if not seen[key]:
            raise RosBagError(f"{path.name}: no {topic} message carries a {what}; the import needs it")
    cols = {k: np.array(v) for k, v in out.items()}
    return _stamps(path, topic, header, receive, notes), {**cols, "problems": problems}


def _wrenches(path: Path, topic: str, msgs, frames: set, notes: list):
    """Advancing stamps [ns] and (n, 6) wrenches [N, Nm] of one topic, its frame checked."""
    header, receive, x, seen_frames = [], [], [], set()
    for ts, m in msgs:
        header.append(_stamp(m))
        receive.append(ts)
        seen_frames.add(m.header.frame_id)
        f, tq = m.wrench.force, m.wrench.torque
        x.append((f.x, f.y, f.z, tq.x, tq.y, tq.z))
    if not header:
        raise RosBagError(f"{path.name}: topic {topic} has no messages")
    bad_frames = sorted(seen_frames - frames)
    if bad_frames:
        raise RosBagError(f"{path.name}: {topic} is in frame {bad_frames[0]!r}, not the robot's base-sensor frame "
                          f"{sorted(frames)[0]!r}; if that frame is the base sensor's, say so with [ros] frame = "
                          f"{bad_frames[0]!r}")
    stamps, x = _stamps(path, topic, header, receive, notes), np.array(x, dtype=np.float64)
    # Stamps that do not advance cannot be interpolated between: left out, counted.
    keep = stamps > np.maximum.accumulate(np.r_[np.iinfo(np.int64).min, stamps[:-1]])
    if not keep.all():
        first = int(np.flatnonzero(~keep)[0])
        notes.append(f"time base: {path.name} {topic}: {int((~keep).sum())} of {len(stamps)} messages have a stamp "
                     f"that does not advance (the first is message {first + 1}); they are left out")
    return stamps[keep], x[keep]


def resample(src_ns: np.ndarray, src_x: np.ndarray, dst_ns: np.ndarray, rule: str, jump_factor: float):
    """``src_x`` (stamps ``src_ns``, increasing [ns]) at the stamps ``dst_ns``: (values with NaN rows,
    [(row, why) for each NaN row]). A stamp outside the source's span or inside one of its gaps (a step
    over ``jump_factor`` median steps) is not extrapolated."""
    values = np.full((len(dst_ns), src_x.shape[1]), np.nan)
    k = np.searchsorted(src_ns, dst_ns, side="left")  # src[k-1] < dst <= src[k]
    exact = (k < len(src_ns)) & (src_ns[np.minimum(k, len(src_ns) - 1)] == dst_ns)
    values[exact] = src_x[k[exact]]
    inside = ~exact & (k > 0) & (k < len(src_ns))
    lo, hi = k[inside] - 1, k[inside]
    span = (src_ns[hi] - src_ns[lo]).astype(np.float64)
    max_step = jump_factor * float(np.median(np.diff(src_ns))) if len(src_ns) > 1 else 0.0
    gap = span > max_step
    w = (dst_ns[inside] - src_ns[lo]) / span
    if rule == "nearest":
        w = (w > 0.5).astype(np.float64)  # a tie goes to the earlier sample
    filled = src_x[lo] + w[:, None] * (src_x[hi] - src_x[lo])
    filled[gap] = np.nan
    values[inside] = filled
    bad = []
    first, last = src_ns[0] * 1e-9, src_ns[-1] * 1e-9
    for r in np.flatnonzero(~exact & ~inside):
        side = "before" if k[r] == 0 else "after"
        bad.append((r, f"stamp {dst_ns[r] * 1e-9:.6f} s is {side} the topic's span [{first:.6f}, {last:.6f}] s "
                       "(not extrapolated)"))
    rows = np.flatnonzero(inside)[gap]
    for r, s in zip(rows, span[gap]):
        bad.append((r, f"stamp {dst_ns[r] * 1e-9:.6f} s lies in a gap of {s * 1e-9:.4g} s of the topic "
                       f"(over {jump_factor:g} median steps: not interpolated)"))
    return values, bad
