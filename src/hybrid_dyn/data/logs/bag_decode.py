"""A bag topic's messages read in batches and decoded into arrays (``bag_stream.py`` reads them).

rosbags deserializes one message into Python objects at ~20 us each: most of an hour's import. A
ROS 2 message is CDR bytes whose layout (offsets of the stamp and of the float64 arrays) depends only
on its strings and array lengths; so one message of each layout is deserialized by rosbags (the
reference), its layout computed from it, and every message of the batch whose structure bytes (string
lengths, strings, array counts) are the same is read with numpy at those offsets. Anything else (ROS 1
bags, big-endian CDR, a batch with too many layouts) is deserialized message by message.

A batch is a :class:`Decoded`: the header stamps [ns] (a zero stamp replaced by the receive time) and
groups of messages of one layout: their names (a JointState's joint names, a wrench's frame_id) and
the float64 fields (JointState: position, velocity, effort, each (m, length); WrenchStamped: wrench
(m, 6) force then torque).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

BATCH = 4096  # messages read and decoded at a time
_MAX_LAYOUTS = 32  # layouts tried per batch before the rest is deserialized one by one
JOINT_STATE = "sensor_msgs/msg/JointState"


class BagDamage(Exception):
    """A message of ``topic`` could not be read: ``index`` messages were read before it, the last with
    stamp ``last_ns`` (None before the first)."""

    def __init__(self, path: Path, topic: str, index: int, last_ns, err: Exception):
        self.path, self.topic, self.index, self.last_ns = path, topic, index, last_ns
        what = " ".join(f"{type(err).__name__}: {err}".split())  # one line, whatever the reader said
        super().__init__(what if str(err).strip() else f"{type(err).__name__} in the reader")


@dataclass
class Group:
    """Messages ``at`` (indices in the batch) of one layout: ``names`` and their float64 ``fields``."""

    at: np.ndarray
    names: tuple
    fields: dict


@dataclass
class Decoded:
    stamps: np.ndarray
    groups: list

    def __len__(self) -> int:
        return len(self.stamps)


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


def topic_batches(path: Path, topic: str, counts: dict, size: int = BATCH):
    """:class:`Decoded` batches of one topic in the bag's order, read by a reader of its own; zero header
    stamps are replaced by the receive time and counted in ``counts[topic]`` [count, first, messages].
    Damage raises :class:`BagDamage` after the batch of the messages before it."""
    reader = open_reader(path)
    count = counts.setdefault(topic, [0, 0, 0])
    last = None
    try:
        it = reader.messages(connections=[c for c in reader.connections if c.topic == topic])
        done = False
        while not done:
            raws, receive, err = [], [], None
            try:  # anything the reader or the decoder raises here is the file's damage, not ours
                for conn, ts, raw in it:
                    raws.append(raw)
                    receive.append(ts)
                    if len(raws) == size:
                        break
                else:
                    done = True
            except Exception as e:
                err, done = e, True
            batch, bad = decode(reader, conn if raws else None, raws)
            err = bad or err
            if len(batch):
                zero = np.flatnonzero(batch.stamps == 0)
                if len(zero):
                    count[1] = count[1] or count[2] + int(zero[0]) + 1
                    count[0] += len(zero)
                    batch.stamps[zero] = np.asarray(receive, np.int64)[zero]
                count[2] += len(batch)
                last = int(batch.stamps[-1])
                yield batch
            if err is not None:
                raise BagDamage(path, topic, count[2], last, err) from None
    finally:
        reader.close()


def decode(reader, conn, raws: list):
    """(:class:`Decoded` of the first messages of ``raws``, the error that stopped it or None)."""
    n = len(raws)
    stamps, groups = np.zeros(n, np.int64), []
    if not n:
        return Decoded(stamps, []), None
    msgtype, cdr = conn.msgtype, _is_cdr(raws[0])
    lens = np.fromiter(map(len, raws), np.int64, n)
    todo = np.ones(n, bool)
    stacked, layouts = {}, 0
    while todo.any():
        i = int(np.argmax(todo))
        try:
            msg = reader.deserialize(raws[i], msgtype)
        except Exception as err:
            return _before(stamps[:i], groups, i), err
        layout = _layout(msg, msgtype, raws[i]) if cdr and layouts < _MAX_LAYOUTS else None
        layouts += 1
        if layout is None:  # one message, as rosbags read it
            stamps[i] = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            groups.append(Group(np.array([i]), *_values(msg, msgtype)))
            todo[i] = False
            continue
        length, fixed, arrays, names = layout
        same = np.flatnonzero(todo & (lens == length))
        if length not in stacked:
            stacked[length] = (same, np.frombuffer(b"".join(bytes(raws[j]) for j in same), np.uint8).reshape(-1, length))
        rows_of, buf = stacked[length]
        sel = np.isin(rows_of, same)
        tmpl = np.frombuffer(bytes(raws[i]), np.uint8)
        match = (buf[sel][:, fixed] == tmpl[fixed]).all(axis=1)
        at = rows_of[sel][match]
        sub = buf[np.flatnonzero(sel)[match]]
        stamps[at] = (sub[:, 4:8].copy().view("<i4")[:, 0].astype(np.int64) * 1_000_000_000
                      + sub[:, 8:12].copy().view("<u4")[:, 0])
        fields = {k: sub[:, off:off + 8 * m].copy().view("<f8") for k, (off, m) in arrays.items()}
        groups.append(Group(at, names, fields))
        todo[at] = False
    return Decoded(stamps, groups), None


def _before(stamps, groups, i):
    """The groups cut to the messages before ``i`` (all decoded)."""
    out = []
    for g in groups:
        k = g.at < i
        if k.any():
            out.append(Group(g.at[k], g.names, {f: v[k] for f, v in g.fields.items()}))
    return Decoded(stamps, out)


def _is_cdr(raw) -> bool:
    """ROS 2 little-endian plain CDR (encapsulation 0x0001)."""
    return len(raw) >= 4 and bytes(raw[:2]) == b"\x00\x01"


def _values(msg, msgtype: str):
    if msgtype == JOINT_STATE:
        return tuple(msg.name), {k: np.asarray(getattr(msg, k), np.float64)[None, :]
                                 for k in ("position", "velocity", "effort")}
    f, t = msg.wrench.force, msg.wrench.torque
    return msg.header.frame_id, {"wrench": np.array([[f.x, f.y, f.z, t.x, t.y, t.z]])}


def _layout(msg, msgtype: str, raw):
    """(length, structure byte indices, {field: (offset, count)}, names) of ``msg``'s CDR bytes, computed
    from rosbags' reading of it and checked against its bytes; None where they disagree."""
    fixed, pos = [], 12  # encapsulation, then the stamp's sec and nanosec

    def align(p, a):
        return p + (-(p - 4)) % a  # CDR aligns relative to the end of the 4-byte encapsulation

    def string(p, s):
        b = s.encode() + b"\0"
        p = align(p, 4)
        fixed.extend(range(p, p + 4 + len(b)))
        return p + 4 + len(b)

    pos = string(pos, msg.header.frame_id)
    arrays = {}
    if msgtype == JOINT_STATE:
        pos = align(pos, 4)
        fixed.extend(range(pos, pos + 4))
        pos += 4
        for name in msg.name:
            pos = string(pos, name)
        for k in ("position", "velocity", "effort"):
            m = len(getattr(msg, k))
            pos = align(pos, 4)
            fixed.extend(range(pos, pos + 4))
            pos += 4
            if m:
                pos = align(pos, 8)
            arrays[k] = (pos, m)
            pos += 8 * m
    else:
        pos = align(pos, 8)
        arrays["wrench"] = (pos, 6)
        pos += 48
    if pos != len(raw):
        return None
    names, want = _values(msg, msgtype)
    got = np.frombuffer(bytes(raw), np.uint8)
    for k, (off, m) in arrays.items():
        if not np.array_equal(got[off:off + 8 * m].copy().view("<f8"), want[k][0], equal_nan=True):
            return None
    stamp = msg.header.stamp
    if int(got[4:8].copy().view("<i4")[0]) != stamp.sec or int(got[8:12].copy().view("<u4")[0]) != stamp.nanosec:
        return None
    return len(raw), np.array(fixed, np.int64), arrays, names
