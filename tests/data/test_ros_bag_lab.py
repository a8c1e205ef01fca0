"""ROS bags as labs record them: franka_ros's gripper messages on /joint_states, a UR driver's joint order,
empty velocity or effort fields, stamps that jitter, damaged files, and bags read in chunks.

References: the signals the bags were written from (``helpers/ros_bags.py``: exact q, qd of per-joint
sines, the rigid-body base wrench), and for chunked reading, the same bag read as one chunk.
"""
import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.logs.bag_stream import BagStats
from hybrid_dyn.data.logs.log_spec import read_spec
from hybrid_dyn.data.logs.ros_bag import bag_names, read_chunks

from helpers.messages import says
from helpers.ros_bags import T0_NS, panda_signals, ros_spec, write_bag

N = 400


@pytest.fixture(scope="module")
def sig(panda):
    return panda_signals(panda, n=N)


def one_instance(ds):
    (inst,) = load_dataset(ds).split("train")
    return inst


def test_franka_ros_gripper_messages_are_skipped_and_counted_with_no_flag(sig, tmp_path, capsys):
    bag = write_bag(tmp_path / "run", sig, gripper=True, tip=False)  # one finger-only message after each
    spec = ros_spec(tmp_path / "spec", bag, tip=False)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    out = capsys.readouterr().out
    assert "400 of 800 messages lack the robot's joints" in out and "message 2" in out and "skipped" in out
    inst = one_instance(tmp_path / "ds")
    np.testing.assert_array_equal(inst.q, sig["q"])  # no finger value (9.9) in the robot's rows
    np.testing.assert_array_equal(inst["tau_m"], sig["tau"])


def test_a_bag_of_only_gripper_messages_is_refused_naming_what_they_carry(sig, tmp_path, capsys):
    bag = write_bag(tmp_path / "run", sig, joints=[f"x{j}" for j in range(7)], tip=False)
    spec = ros_spec(tmp_path / "spec", bag, tip=False)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err
    assert says(err, "no /joint_states message carries all the robot's joints", "panda_joint1", "x0"), err


def test_a_ur_driver_bag_in_its_alphabetical_joint_order_imports_by_name(tmp_path):
    from hybrid_dyn.analytic.robot import load_robot

    ur = load_robot("ur10")
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    s = panda_signals(ur, n=N, seed=2)
    order = np.argsort(names)  # ur_robot_driver publishes elbow_joint first
    bag = write_bag(tmp_path / "run", s, joints=names, joint_order=lambda k: order, tip=False, base=False)
    spec = ros_spec(tmp_path / "spec", bag, tip=False, base=False)
    spec.write_text(spec.read_text().replace('robot = "panda"', 'robot = "ur10"'))
    report = import_log(spec, tmp_path / "ds")
    inst = one_instance(tmp_path / "ds")
    assert report.rows_kept == N
    np.testing.assert_array_equal(inst.q, s["q"])
    np.testing.assert_array_equal(inst["tau_m"], s["tau"])


@pytest.mark.parametrize("every", [1, 10])
def test_an_empty_velocity_is_a_missing_one_qd_is_derived_from_q_and_the_report_says_so(every, sig, tmp_path):
    bag = write_bag(tmp_path / "run", sig, tip=False, empty=lambda k: {"velocity"} if k % every == 0 else ())
    report = import_log(ros_spec(tmp_path / "spec", bag, tip=False), tmp_path / "ds")
    assert report.rows_dropped == 0 and report.instances == 1
    said = "no message carries a velocity" if every == 1 else "40 of 400 rows have no velocity"
    assert any(said in w and "derived from q" in w for w in report.warnings), report.warnings
    inst = one_instance(tmp_path / "ds")
    derived = np.arange(N) % every == 0
    # Against the exact qd of the sines: the derivative filter's error at 1 kHz, far below 1e-3 rad/s.
    np.testing.assert_allclose(inst.qd[derived], sig["qd"][derived], atol=1e-4)
    np.testing.assert_array_equal(inst.qd[~derived], sig["qd"][~derived])  # the logged ones as logged


def test_a_bag_without_efforts_imports_without_torques_and_estimates_with_a_base_sensor_method(panda, tmp_path,
                                                                                               capsys):
    s = panda_signals(panda, n=1200, seed=5)
    bag = write_bag(tmp_path / "run", s, tip=False, empty=lambda k: {"effort"})
    spec = ros_spec(tmp_path / "spec", bag, tip=False)
    report = import_log(spec, tmp_path / "ds")
    assert "tau_m" not in one_instance(tmp_path / "ds").fields and report.rows_dropped == 0
    assert any("no message carries an effort" in w for w in report.warnings)
    out = tmp_path / "tip.csv"
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--out", str(out)]) == 0
    assert len(out.read_text().splitlines()) == 1200 + 1
    assert cli_main(["estimate", str(spec), "--method", "momentum-observer", "--out", str(tmp_path / "m.csv")]) == 2
    assert says(capsys.readouterr().err, "momentum-observer reads tau_J", "no tau_J")


def jittered(stamps, seed=0):
    """Stamps taken on arrival: +-0.5 ms of jitter at 1 kHz, on a 0.5 ms clock, so that some tie."""
    rng = np.random.default_rng(seed)
    return T0_NS + np.round((stamps - T0_NS + rng.uniform(-5e5, 5e5, len(stamps))) / 5e5).astype(np.int64) * 500_000


def test_stamps_that_tie_or_step_back_within_the_jitter_keep_the_log_whole_and_raise_no_false_warning(sig, tmp_path):
    stamps = jittered(sig["stamps"])
    stamps[300] = stamps[299] - 300_000  # 0.3 ms back: within half a step
    assert (np.diff(stamps) == 0).sum() > 10  # the case: ties
    bag = write_bag(tmp_path / "run", sig, js_stamps=stamps, tip=False, base=False)
    report = import_log(ros_spec(tmp_path / "spec", bag, tip=False, base=False), tmp_path / "ds")
    assert report.rows_kept == N and report.instances == 1 and not report.issues
    assert not any("time unit" in w or "sample rate" in w for w in report.warnings), report.warnings
    assert any("tie or go back within the stream's jitter" in w for w in report.warnings), report.warnings
    inst = one_instance(tmp_path / "ds")
    np.testing.assert_array_equal(inst.q, sig["q"])  # in message order
    assert np.all(np.diff(inst.t) > 0) and np.abs(inst.t - sig["t"]).max() < 1.5e-3


@pytest.fixture(scope="module")
def damaged(sig, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("damage")
    long = dict(sig, **{k: np.concatenate([v] * 8) for k, v in sig.items() if k not in ("stamps", "t")})
    long["t"] = np.arange(8 * N) / 1000.0
    long["stamps"] = T0_NS + np.round(long["t"] * 1e9).astype(np.int64)
    db = write_bag(tmp / "db", long, kind="sqlite3", tip=False)
    (db3,) = db.glob("*.db3")
    raw = db3.read_bytes()
    db3.write_bytes(raw[: len(raw) * 999 // 1000])  # a recorder killed in its last write
    ros1 = write_bag(tmp / "run.bag", long, kind="ros1", tip=False)
    raw = bytearray(ros1.read_bytes())
    # 200 flipped bytes in the second half of the messages (a ROS 1 bag's index is at its end: flips there
    # leave nothing readable, which is the one-line error without a partial read)
    for i in np.random.default_rng(0).choice(np.arange(len(raw) // 2, len(raw) * 8 // 10), 200, replace=False):
        raw[i] ^= 0xFF
    ros1.write_bytes(bytes(raw))
    return tmp, long, {"sqlite3": db, "ros1": ros1}


@pytest.mark.parametrize("kind", ["sqlite3", "ros1"])
@pytest.mark.parametrize("command", ["import", "estimate"])
def test_a_damaged_bag_is_one_line_and_keep_partial_keeps_what_came_before(kind, command, damaged, tmp_path, capsys):
    tmp, long, bags = damaged
    spec = ros_spec(tmp_path / "spec", bags[kind], tip=False)
    out = tmp_path / ("ds" if command == "import" else "tip.csv")
    args = ["import", "--spec", str(spec), "--out", str(out)] if command == "import" else \
        ["estimate", str(spec), "--method", "base-momentum", "--out", str(out)]
    assert cli_main(args) == 2
    err = capsys.readouterr().err
    assert says(err, str(bags[kind]), "damaged", "cannot be read", "--keep-partial"), err
    assert "Traceback" not in err and not out.exists()
    if kind == "ros1":  # rosbags reads the first message of every chunk up front: a damaged chunk stops it there
        assert cli_main(args + ["--keep-partial"]) == 2
        assert says(capsys.readouterr().err, str(bags[kind]), "damaged before any row could be read")
        return
    assert cli_main(args + ["--keep-partial"]) == 0
    printed = capsys.readouterr().out
    assert "read stopped" in printed and "rows before it are kept" in printed, printed
    if command == "import":
        insts = load_dataset(out).split("train")
        n = sum(len(i.t) for i in insts)
        q = np.concatenate([i.q for i in insts])
        assert 0 < n < len(long["t"])
        if kind == "sqlite3":  # the file's bytes up to the cut are intact: the rows read are the bag's own
            np.testing.assert_array_equal(q, long["q"][:n])


def test_reading_in_chunks_gives_what_reading_whole_gives(sig, tmp_path):
    stamps = jittered(sig["stamps"], seed=3)
    w_stamps = sig["stamps"] + 250_000  # the F/T on its own stamps
    bag = write_bag(tmp_path / "run", sig, js_stamps=stamps, wrench_stamps=w_stamps, gripper=True,
                    empty=lambda k: {"velocity"} if k % 7 == 0 else ())
    spec = read_spec(ros_spec(tmp_path / "spec", bag))
    joints, frames = bag_names(spec)

    def read(size):
        chunks = list(read_chunks(bag, spec.ros, joints, frames, 8.0, BagStats(), size=size))
        return chunks, {k: np.concatenate([getattr(c, k) for c in chunks]) for k in ("stamps_ns", "time_ns", "q", "qd")}

    whole, ref = read(10**6)
    small, got = read(37)
    assert len(whole) == 1 and len(small) > 10
    for k in ref:
        np.testing.assert_array_equal(got[k], ref[k])
    for key in ("base_wrench", "tip_wrench"):
        np.testing.assert_array_equal(np.concatenate([c.wrenches[key] for c in small]), whole[0].wrenches[key])
    assert [p for c in small for p in c.problems] == whole[0].problems


def test_an_estimate_streamed_in_chunks_is_the_estimate_of_the_whole_bag(panda, tmp_path, monkeypatch):
    from hybrid_dyn.data.logs import bag_stream
    from hybrid_dyn.estimator.replay import replay_log

    s = panda_signals(panda, n=1500, seed=8)
    bag = write_bag(tmp_path / "run", s, gripper=True, js_stamps=jittered(s["stamps"], seed=9),
                    empty=lambda k: {"velocity"} if k % 9 == 0 else ())
    spec = ros_spec(tmp_path / "spec", bag)
    whole, _ = replay_log(read_spec(spec), method="base-momentum")
    monkeypatch.setattr(bag_stream, "CHUNK_ROWS", 97)
    chunked, report = replay_log(read_spec(spec), method="base-momentum")
    assert report.rows_kept == 1500 and chunked.status == whole.status
    np.testing.assert_array_equal(chunked.stamps_ns, whole.stamps_ns)
    np.testing.assert_array_equal(chunked.force, whole.force)
    assert "ok" in whole.status


@pytest.mark.slow  # a 10-minute bag at 1 kHz: 600 000 joint states and wrenches written, imported, estimated
def test_a_ten_minute_bag_imports_and_estimates_in_chunks(panda, tmp_path, capsys):
    n = 600_000
    s = panda_signals(panda, n=n, seed=7)
    bag = write_bag(tmp_path / "run", s, tip=False, gripper=False)
    spec = ros_spec(tmp_path / "spec", bag, tip=False)
    report = import_log(spec, tmp_path / "ds")
    assert report.rows_kept == n and report.instances == 1
    inst = one_instance(tmp_path / "ds")
    np.testing.assert_array_equal(inst.q[[0, 65_535, 65_536, n - 1]], s["q"][[0, 65_535, 65_536, n - 1]])
    np.testing.assert_array_equal(inst["base_wrench"], s["base_wrench"])  # across every chunk boundary
    out = tmp_path / "tip.csv"
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--out", str(out)]) == 0
    with out.open() as fh:
        assert sum(1 for _ in fh) == n + 1
