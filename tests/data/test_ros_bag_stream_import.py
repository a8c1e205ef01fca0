"""A ROS bag imported as it is read (``bag_import.py``) and decoded in batches (``bag_decode.py``).

References: the whole-bag import of the same spec (``checked_segments`` + ``write_dataset``: the bag in one
table, each segment written in one piece), the derivative of the whole segment, and rosbags' own
deserializer for every message.
"""
import copy

import numpy as np
import pytest

from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.derivative_methods import DERIVATIVE_METHODS
from hybrid_dyn.data.logs import bag_stream
from hybrid_dyn.data.logs.bag_decode import JOINT_STATE, open_reader, topic_batches
from hybrid_dyn.data.logs.bag_import import _Scratch, _segment_fields
from hybrid_dyn.data.logs.importer import checked_segments
from hybrid_dyn.data.logs.log_spec import read_spec
from hybrid_dyn.data.logs.log_writer import derive_fields, write_dataset

from helpers.ros_bags import panda_signals, ros_spec, write_bag

N = 1500


@pytest.fixture(scope="module")
def sig(panda):
    return panda_signals(panda, n=N, seed=5)


def gapped_bag(sig, folder, **kw):
    """A bag with a 50 ms gap after row 700 (two segments) and no velocity in every 10th message."""
    stamps = sig["stamps"] + np.where(np.arange(N) > 700, 50_000_000, 0)
    return write_bag(folder, sig, js_stamps=stamps, wrench_stamps=stamps, receive_ns=stamps,
                     empty=lambda k: {"velocity"} if k % 10 == 3 else (), **kw)


@pytest.mark.parametrize("method", list(DERIVATIVE_METHODS))
def test_a_streamed_import_writes_what_the_whole_bag_import_writes(method, sig, tmp_path, monkeypatch):
    bag = gapped_bag(sig, tmp_path / "run")
    spec_path = ros_spec(tmp_path / "spec", bag, extra=f'[derivatives]\nmethod = "{method}"\n')
    spec = copy.copy(read_spec(spec_path))
    segments, report = checked_segments(spec)
    write_dataset(spec, segments, report, tmp_path / "whole", False)  # the bag in one table, segments whole
    monkeypatch.setattr(bag_stream, "CHUNK_ROWS", 97)  # the streamed one in chunks of 97 rows
    streamed = import_log(spec_path, tmp_path / "streamed")
    assert streamed.rows_kept == report.rows_kept == N and streamed.instances == report.instances == 2
    assert streamed.warnings == report.warnings
    a, b = load_dataset(tmp_path / "streamed"), load_dataset(tmp_path / "whole")  # checksums checked on load
    assert a.meta["splits"] == b.meta["splits"] and a.fields == b.fields
    assert a.meta["import"]["velocities"] == b.meta["import"]["velocities"] == "logged"
    for name, inst in a.instances.items():
        ref = b.instances[name]
        assert inst.n_samples == ref.n_samples
        for f in a.fields:
            np.testing.assert_array_equal(inst[f], ref[f], err_msg=f"{name} {f}")
    for rec in a.meta["instances"]:  # the manifest's checksum is the written file's
        from hybrid_dyn.data.dataset import sha256_file

        assert sha256_file(tmp_path / "streamed" / rec["file"]) == rec["sha256"]


@pytest.mark.parametrize("method", [m.name for m in DERIVATIVE_METHODS.where(local=True)])
def test_derivatives_in_blocks_with_the_filters_margin_equal_the_whole_segments(method, tmp_path):
    from hybrid_dyn.data.derivatives import DerivativeFilter

    assert all((DerivativeFilter(m.name).reach(1e-3) is not None) == m.local for m in DERIVATIVE_METHODS.values())

    rng = np.random.default_rng(0)
    n = 2000
    t = np.arange(n) * 1e-3 + rng.uniform(0, 1e-5, n)  # not exactly even: central uses the times
    q = np.cumsum(rng.normal(0, 1e-3, (n, 3)), axis=0)
    qd = np.gradient(q, t, axis=0) + rng.normal(0, 1e-4, (n, 3))
    qd[rng.random(n) < 0.05] = np.nan  # rows without velocity: filled from q
    scratch = _Scratch(tmp_path / "rows")
    scratch.append({"t": t, "q": q, "qd": qd})
    scratch.close()

    class Spec:
        derivatives = DerivativeFilter(method=method)
        columns = {"q": "q", "qd": "qd"}

    a, b = 100, 1900  # a segment inside the rows
    dt = float(np.median(np.diff(t[a:b])))
    whole = derive_fields(Spec, {"t": t[a:b], "q": q[a:b], "qd": qd[a:b]}, dt=dt)
    widths, block = _segment_fields(Spec, scratch, a, b, dt)
    assert widths == {"t": None, "q": 3, "qd": 3, "qdd": 3}
    for f in ("qd", "qdd"):
        got = np.concatenate([block(f, lo, min(lo + 173, b - a)) for lo in range(0, b - a, 173)])
        np.testing.assert_array_equal(got, whole[f])


@pytest.mark.parametrize("kind", ["mcap", "sqlite3", "ros1"])
def test_batches_decode_every_message_as_rosbags_deserializes_it(kind, panda, tmp_path):
    s = panda_signals(panda, n=300, seed=2)
    rng = np.random.default_rng(1)
    orders = [rng.permutation(7) if k % 50 == 7 else np.arange(7) for k in range(300)]  # a few other orders
    bag = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), s, kind=kind, gripper=True,
                    joint_order=lambda k: orders[k], extra_joints=("arm2_joint1",) if kind == "mcap" else (),
                    empty=lambda k: {"velocity"} if k % 9 == 0 else {"effort"} if k % 13 == 0 else ())
    for topic in ("/joint_states", "/ft_base", "/ft_tool"):
        want = []
        reader = open_reader(bag)
        try:
            for conn, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic == topic]):
                want.append(reader.deserialize(raw, conn.msgtype))
        finally:
            reader.close()
        got = {}  # message number -> (stamp, names, fields)
        base = 0
        for batch in topic_batches(bag, topic, {}, size=128):
            for g in batch.groups:
                for r, i in enumerate(g.at):
                    got[base + int(i)] = (int(batch.stamps[i]), g.names, {k: v[r] for k, v in g.fields.items()})
            base += len(batch)
        assert sorted(got) == list(range(len(want)))
        for k, m in enumerate(want):
            stamp, names, fields = got[k]
            assert stamp == m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
            if conn.msgtype == JOINT_STATE:
                assert names == tuple(m.name)
                for f in ("position", "velocity", "effort"):
                    np.testing.assert_array_equal(fields[f], np.asarray(getattr(m, f), float))
            else:
                w = m.wrench
                assert names == m.header.frame_id
                np.testing.assert_array_equal(fields["wrench"], [w.force.x, w.force.y, w.force.z,
                                                                 w.torque.x, w.torque.y, w.torque.z])
