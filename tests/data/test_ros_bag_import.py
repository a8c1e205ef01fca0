"""ROS bags in: ``hybrid-dyn import`` of ROS 2 (MCAP, sqlite3) and ROS 1 bags named by a
``[ros]`` table, through the same checks as a CSV log.

References: the signals the bags were written from (``helpers/ros_bags.py``: a Panda motion, its
rigid-body base wrench, a tip force), and for the time base, wrenches that are linear in time, whose
linear interpolation at any stamp is known in closed form.
"""
import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import import_log, load_dataset
from hybrid_dyn.data.logs.log_spec import LogSpecError, read_spec
from hybrid_dyn.data.logs.ros_bag import RosBagError

from helpers.messages import says
from helpers.ros_bags import PANDA_JOINTS, panda_signals, ros_spec, write_bag

N = 400  # 0.4 s at 1 kHz: past the derivative filter's window, a few bags per second to write


@pytest.fixture(scope="module")
def sig(panda):
    force = np.where(np.arange(N)[:, None] >= 200, [3.0, -4.0, 5.0], 0.0)  # N, from 0.2 s
    return panda_signals(panda, n=N, force=force)


def imported(tmp_path, bag, **kw):
    report = import_log(ros_spec(tmp_path / "spec", bag, **kw), tmp_path / "ds")
    (inst,) = load_dataset(tmp_path / "ds").split("train")
    return report, inst


@pytest.mark.parametrize("kind", ["mcap", "sqlite3", "ros1"])
def test_a_bag_round_trips_its_signals_exactly(kind, sig, tmp_path):
    bag = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), sig, kind=kind)
    report, inst = imported(tmp_path, bag)
    assert report.rows_read == report.rows_kept == N and not report.issues
    np.testing.assert_array_equal(inst.q, sig["q"])
    np.testing.assert_array_equal(inst.qd, sig["qd"])
    np.testing.assert_array_equal(inst["tau_m"], sig["tau"])  # effort -> tau_m
    np.testing.assert_array_equal(inst["base_wrench"], sig["base_wrench"])  # same stamps: no interpolation
    np.testing.assert_array_equal(inst["tip_force"], sig["tip_force"])
    np.testing.assert_allclose(inst.t, sig["t"], rtol=0, atol=1e-12)  # seconds from the first stamp
    assert any(says(w, "header stamps of /joint_states", "/ft_base and /ft_tool", "linear interpolation")
               for w in report.warnings), report.warnings


def test_joints_are_matched_by_name_whatever_the_order_and_a_second_robots_joints_are_ignored(sig, tmp_path):
    rng = np.random.default_rng(1)
    orders = [rng.permutation(7) for _ in range(N)]  # another order in every message
    other = [f"fr3b_joint{j}" for j in range(1, 8)] + ["panda_finger_joint1"]
    bag = write_bag(tmp_path / "run", sig, joint_order=lambda k: orders[k], extra_joints=other)
    _, inst = imported(tmp_path, bag)
    np.testing.assert_array_equal(inst.q, sig["q"])
    np.testing.assert_array_equal(inst["tau_m"], sig["tau"])
    assert not np.any(inst.q == 9.9)  # the second arm's value never lands in the robot's columns


@pytest.mark.parametrize("effort, fields", [('"tau_J"', ["tau_J"]), ('["tau_m", "tau_J"]', ["tau_J", "tau_m"])])
def test_the_effort_fills_the_torque_fields_the_spec_names(effort, fields, sig, tmp_path):
    bag = write_bag(tmp_path / "run", sig, tip=False, base=False)
    _, inst = imported(tmp_path, bag, tip=False, base=False, extra=f"effort = {effort}\n")
    assert sorted(f for f in ("tau_m", "tau_J") if f in inst.fields) == fields
    for f in fields:
        np.testing.assert_array_equal(inst[f], sig["tau"])


def test_a_robot_joint_missing_from_the_messages_is_refused_by_name(sig, tmp_path, capsys):
    joints = [j if j != "panda_joint4" else "arm_joint4" for j in PANDA_JOINTS]
    bag = write_bag(tmp_path / "run", sig, joints=joints)
    spec = ros_spec(tmp_path / "spec", bag)
    with pytest.raises(RosBagError) as err:
        import_log(spec, tmp_path / "ds")
    assert says(err.value, "/joint_states message 1", "'panda_joint4'", "arm_joint4")
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2
    out = capsys.readouterr().err
    assert out.startswith("error: ") and out.count("\n") == 1 and "panda_joint4" in out
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize("kind", ["mcap", "ros1"])
def test_a_truncated_bag_is_one_line_naming_it(kind, sig, tmp_path, capsys):
    bag = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), sig, kind=kind)
    cut = tmp_path / f"cut{bag.suffix}"
    cut.write_bytes(bag.read_bytes()[: len(bag.read_bytes()) * 9 // 10])  # a recorder killed before the end
    assert cli_main(["import", "--spec", str(ros_spec(tmp_path / "spec", cut)), "--out", str(tmp_path / "ds")]) == 2
    out = capsys.readouterr().err
    assert says(out, str(cut), "not a readable ROS bag"), out
    assert not (tmp_path / "ds").exists()


def test_a_missing_topic_is_refused_naming_it_and_the_topics_there(sig, tmp_path, capsys):
    bag = write_bag(tmp_path / "run", sig, tip=False)
    spec = ros_spec(tmp_path / "spec", bag)  # names /ft_tool, which the bag lacks
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2
    out = capsys.readouterr().err
    assert says(out, "no topic /ft_tool", "tip_wrench", "/ft_base", "/joint_states"), out
    assert "Traceback" not in out and not (tmp_path / "ds").exists()


def test_a_joint_stamp_going_backwards_drops_its_row_by_the_csv_rule_and_says_so(sig, tmp_path, capsys):
    stamps = sig["stamps"].copy()
    stamps[150] = stamps[149] - 3_000_000  # 3 ms before its predecessor
    bag = write_bag(tmp_path / "run", sig, js_stamps=stamps)
    spec = ros_spec(tmp_path / "spec", bag, tip=False, base=False)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 0
    out = capsys.readouterr().out
    assert "time_order" in out and "row 151" in out and "Traceback" not in out
    report = import_log(spec, tmp_path / "ds2")
    assert report.rows(kind="time_order") == [151] and report.rows_dropped == 1
    kept = np.concatenate([i.q for i in load_dataset(tmp_path / "ds2").split("train")])
    np.testing.assert_array_equal(kept, np.delete(sig["q"], 150, axis=0))


def test_a_wrench_stamp_going_backwards_is_left_out_of_the_interpolation_and_counted(sig, tmp_path):
    stamps = sig["stamps"].copy()
    stamps[200] = stamps[120]  # message 201 carries an old stamp
    bag = write_bag(tmp_path / "run", sig, wrench_stamps=stamps, tip=False)
    report, inst = imported(tmp_path, bag, tip=False)
    assert any(says(w, "/ft_base", "1 of 400 messages", "does not advance", "message 201") for w in report.warnings)
    w = sig["base_wrench"]
    np.testing.assert_allclose(inst["base_wrench"][200], 0.5 * (w[199] + w[201]), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.delete(inst["base_wrench"], 200, 0), np.delete(w, 200, 0))


@pytest.mark.parametrize("rule", ["linear", "nearest"])
def test_wrenches_are_put_on_the_joint_stamps_by_the_stated_rule_and_never_extrapolated(rule, sig, tmp_path):
    # Wrench samples 0.25 ms after each joint state, 20 ms late to start, with a 30 ms hole; each is linear
    # in its own stamp, so linear interpolation at a joint stamp is the same line there.
    shift = 250_000
    w_stamps = sig["stamps"] + shift
    line = lambda ns: np.outer((ns - sig["stamps"][0]) * 1e-9, [1.0, -2.0, 3.0, 0.1, 0.2, -0.3]) + 5.0  # noqa: E731
    data = dict(sig, base_wrench=line(w_stamps))
    keep = np.ones(N, bool)
    keep[:20] = False  # starts late
    keep[200:230] = False  # a hole: 31 steps from wrench 199 to wrench 230
    bag = _joint_states_and_wrench(tmp_path / "run", sig, data["base_wrench"][keep], w_stamps[keep])
    extra = f'resample = "{rule}"\n[checks]\nmax_drop_fraction = 0.2\n'  # 50 of 400 rows are dropped
    report = import_log(ros_spec(tmp_path / "spec", bag, tip=False, extra=extra), tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    insts = sorted(ds.split("train"), key=lambda i: i.t[0])
    got_t = np.concatenate([i.t for i in insts])
    got_w = np.concatenate([i["base_wrench"] for i in insts])
    rows = np.round(got_t * 1e3).astype(int)  # the joint-state rows kept
    # Dropped: the 21 rows before the topic's first sample (row 20 too: 0.25 ms before wrench 20), not
    # extrapolated, and the 31 inside the hole (between wrench 199 and 230, rows 200-230).
    dropped = sorted(set(range(N)) - set(rows.tolist()))
    assert dropped == list(range(21)) + list(range(200, 231)), dropped
    before = [i for i in report.issues if "before the topic's span" in i.detail]
    gap = [i for i in report.issues if "in a gap of" in i.detail]
    assert [i.row for i in before] == list(range(1, 22)) and [i.row for i in gap] == list(range(201, 232))
    ns = sig["stamps"][rows]
    expect = line(ns) if rule == "linear" else line(ns + shift)  # nearest: the sample 0.25 ms later
    np.testing.assert_allclose(got_w, expect, rtol=0, atol=1e-9)


def _joint_states_and_wrench(path, sig, wrench, wrench_stamps):
    """Every joint state, and wrench messages only at ``wrench_stamps``: two writes merged into one bag."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        js = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        ft = writer.add_connection("/ft_base", "geometry_msgs/msg/WrenchStamped", typestore=store)
        stamp = lambda ns, frame: T["std_msgs/msg/Header"](  # noqa: E731
            stamp=T["builtin_interfaces/msg/Time"](sec=int(ns) // 10**9, nanosec=int(ns) % 10**9), frame_id=frame)
        for k, ns in enumerate(sig["stamps"]):
            msg = T["sensor_msgs/msg/JointState"](header=stamp(ns, ""), name=PANDA_JOINTS, position=sig["q"][k],
                                                  velocity=sig["qd"][k], effort=sig["tau"][k])
            writer.write(js, int(ns), store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
        V = T["geometry_msgs/msg/Vector3"]
        for x, ns in zip(wrench, wrench_stamps):
            msg = T["geometry_msgs/msg/WrenchStamped"](header=stamp(ns, "panda_link0"), wrench=T["geometry_msgs/msg/Wrench"](
                force=V(x=x[0], y=x[1], z=x[2]), torque=V(x=x[3], y=x[4], z=x[5])))
            writer.write(ft, int(ns), store.serialize_cdr(msg, "geometry_msgs/msg/WrenchStamped"))
    return path


def test_a_wrench_in_another_frame_is_refused_by_name_unless_the_spec_names_it(sig, tmp_path, capsys):
    bag = write_bag(tmp_path / "run", sig, base_frame="ft_sensor_link")
    spec = ros_spec(tmp_path / "spec", bag)
    assert cli_main(["import", "--spec", str(spec), "--out", str(tmp_path / "ds")]) == 2
    out = capsys.readouterr().err
    assert says(out, "/ft_base", "'ft_sensor_link'", "'panda_link0'", 'frame = "ft_sensor_link"'.replace('"', "'")), out
    _, inst = imported(tmp_path, bag, extra='frame = "ft_sensor_link"\n')
    np.testing.assert_array_equal(inst["base_wrench"], sig["base_wrench"])


def test_a_zero_stamp_takes_the_receive_time_and_the_report_says_which(sig, tmp_path):
    stamps = sig["stamps"].copy()
    stamps[:10] = 0  # a driver that fills no stamp for its first messages
    bag = write_bag(tmp_path / "run", sig, js_stamps=stamps, receive_ns=sig["stamps"], tip=False, base=False)
    report, inst = imported(tmp_path, bag, tip=False, base=False)
    assert any(says(w, "/joint_states", "10 of 400 messages", "zero header stamp", "receive time") for w in
               report.warnings), report.warnings
    np.testing.assert_allclose(inst.t, sig["t"], rtol=0, atol=1e-12)


def test_the_csv_paths_checks_apply_a_joint_beyond_its_limit_is_a_dropped_row(sig, tmp_path):
    bad = dict(sig, q=sig["q"].copy())
    bad["q"][200, 3] = 0.5  # the Panda's joint 4 lies in [-3.07, -0.07] rad: a unit_range row
    bag = write_bag(tmp_path / "run", bad, tip=False, base=False)
    report = import_log(ros_spec(tmp_path / "spec", bag, tip=False, base=False), tmp_path / "ds")
    assert report.rows(kind="unit_range") == [201] and report.rows_dropped == 1


@pytest.mark.parametrize("extra, says_what", [
    ('resample = "cubic"\n', "resample must be one of"),
    ('topic = "/x"\n', "unknown keys ['topic'] in [ros]"),
    ('[columns]\nq = "1-7"\n', "names topics in [ros], not [columns]"),
])
def test_a_bad_ros_table_is_a_one_line_spec_error(extra, says_what, tmp_path):
    spec = ros_spec(tmp_path, tmp_path / "run", extra=extra)
    with pytest.raises(LogSpecError) as err:
        read_spec(spec)
    assert says(err.value, says_what), str(err.value)


ODD = [None, True, 0, 1.5, float("nan"), "", "abc", "/ft_base", [], ["panda_joint1"], {}, {"a": 1}]


def test_any_value_in_any_ros_key_ends_in_a_dataset_or_one_error(sig, tmp_path):
    """A small fuzz of the [ros] table (as the spec's own fuzz): never a traceback, never a partial output."""
    import tomllib

    from hybrid_dyn.data.logs.importer import spec_from_dict
    from hybrid_dyn.errors import HybridDynError

    bag = write_bag(tmp_path / "run", sig)
    base = tomllib.loads(ros_spec(tmp_path / "spec", bag).read_text())
    outcomes = {}
    for key in ("joint_states", "base_wrench", "tip_wrench", "frame", "resample", "joints"):
        for k, value in enumerate(ODD):
            doc = {**base, "ros": {**base["ros"], key: value}}
            out = tmp_path / f"ds-{key}-{k}"
            try:
                import_log(spec_from_dict(doc, base_dir=tmp_path), out)
                outcomes["dataset"] = outcomes.get("dataset", 0) + 1
                load_dataset(out)
            except HybridDynError as err:
                assert "\n" not in str(err).split("\nimport ")[0], (key, value, str(err))
                assert not out.exists(), (key, value)
                outcomes[type(err).__name__] = outcomes.get(type(err).__name__, 0) + 1
    assert outcomes.get("dataset", 0) >= 1 and outcomes.get("LogSpecError", 0) >= 10, outcomes
