"""``hybrid-dyn estimate``: a recorded ROS 2 bag replayed through the streaming estimator, the
tip force written to an MCAP bag (or a CSV) at the input's stamps.

The reference: the tip force the bag was built with (``helpers/ros_bags.py``: the base wrench is the
rigid-body reaction of a Panda motion with that force, plus 0.1 N of sensor noise), read back from the
output with ``rosbags``, not with the code under test.
"""
import csv

import numpy as np
import pytest

from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.estimator.replay import Replay, write_estimate

from helpers.messages import says
from helpers.ros_bags import panda_signals, ros_spec, write_bag

N, HZ = 3000, 1000.0
DIRECTION = np.array([0.3, -0.5, -0.8]) / np.linalg.norm([0.3, -0.5, -0.8])


def known_force(n=N, hz=HZ):
    """No contact in the first second (the estimator's noise window needs none), then a 0.2 s ramp to a
    force of 4-8 N (6 + 2 sin) along a fixed direction [N]."""
    t = np.arange(n) / hz
    ramp = 0.5 - 0.5 * np.cos(np.pi * np.clip((t - 1.0) / 0.2, 0, 1))
    return (ramp * (6.0 + 2.0 * np.sin(2 * np.pi * 0.4 * (t - 1.0))))[:, None] * DIRECTION


@pytest.fixture(scope="module")
def recording(panda, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("estimate")
    sig = panda_signals(panda, n=N, hz=HZ, force=known_force(), base_noise=0.1, seed=3)
    bag = write_bag(tmp / "run", sig, kind="mcap")
    return tmp, sig, ros_spec(tmp / "spec", bag)


def read_topics(path):
    from rosbags.highlevel import AnyReader

    out = {}
    with AnyReader([path]) as reader:
        for conn, logged, raw in reader.messages():
            out.setdefault(conn.topic, []).append((logged, reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.mark.slow  # 3000 estimator calls and an MCAP bag: ~10 s on a busy core
@pytest.mark.parametrize("encoders", [["--encoder-resolution", "0"], []], ids=["declared-exact", "defaults"])
def test_the_tip_force_topic_is_within_half_a_newton_of_the_truth_at_the_inputs_stamps(recording, capsys, encoders):
    """The arm moves from the bag's first sample. Declared exact (a simulation's q), or with the defaults,
    which assume the Panda's encoders and filter q: the tare must wait for that filter, not take its
    start-up transient as the sensor's offset."""
    tmp, sig, spec = recording
    out = tmp / f"tip-{len(encoders)}.mcap"
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", *encoders, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    topics = read_topics(out)
    force, status = topics["/tip_force"], topics["/tip_force/status"]
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in force])
    np.testing.assert_array_equal(stamps, sig["stamps"])  # every input sample, at its own stamp
    np.testing.assert_array_equal([logged for logged, _ in force], sig["stamps"])
    np.testing.assert_array_equal([logged for logged, _ in status], sig["stamps"])
    assert {m.header.frame_id for _, m in force} == {"panda_link0"}  # the base frame
    f = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z] for _, m in force])
    states = [m.data for _, m in status]
    ok = np.array([s == "ok" for s in states])
    # The start-up window (0.5 s of noise window, then the observer's settling) is all it leaves out, but for
    # calls of the contact's 0.2 s onset ramp (from 1.0 s) whose error bar (the lag) says "uncertain".
    assert not ok[:500].any() and ok[700:1000].all() and ok[1200:].all(), sorted(set(states))
    assert set(states[1000:1200]) <= {"ok", "uncertain"}
    truth = sig["tip_force"]
    assert np.linalg.norm(truth[ok], axis=1).min() == 0 and np.linalg.norm(truth[1200:], axis=1).min() > 3.9
    rms = np.sqrt(np.mean(np.sum((f[ok] - truth[ok]) ** 2, axis=1)))
    assert rms < 0.5, rms
    assert np.sqrt(np.mean(np.sum(truth[ok] ** 2, axis=1))) > 10 * rms  # a zero estimate would fail by far
    assert f"{rms:.4f} N RMS" in printed  # the command prints the same figure
    png = out.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow  # 3000 estimator calls
def test_a_csv_out_holds_the_same_estimate_and_nothing_existing_is_overwritten(recording, capsys):
    tmp, sig, spec = recording
    out = tmp / "tip-csv.csv"  # its own stem: tip.png is the MCAP test's figure
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--encoder-resolution", "0", "--out", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [int(r["stamp_ns"]) for r in rows] == sig["stamps"].tolist()
    f = np.array([[float(r[k]) for k in ("fx", "fy", "fz")] for r in rows])
    ok = np.array([r["status"] == "ok" for r in rows])
    assert ok.sum() > 0.75 * N
    assert np.sqrt(np.mean(np.sum((f[ok] - sig["tip_force"][ok]) ** 2, axis=1))) < 0.5
    figure = tmp / "mine.png"  # a user's figure where the estimate would put its own
    figure.write_bytes(b"not ours")
    before = out.read_bytes()
    capsys.readouterr()
    for taken, out_arg in ((out, out), (figure, figure.with_suffix(".csv"))):
        assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--out", str(out_arg)]) == 2
        err = capsys.readouterr().err
        assert says(err, str(taken), "already exists"), err
    assert out.read_bytes() == before and figure.read_bytes() == b"not ours"
    assert not figure.with_suffix(".csv").exists()


def test_a_method_whose_sensor_the_log_lacks_is_refused_before_the_replay(panda, tmp_path, capsys):
    sig = panda_signals(panda, n=300, hz=HZ)
    bag = write_bag(tmp_path / "run", sig, base=False, tip=False)
    spec = ros_spec(tmp_path / "spec", bag, base=False, tip=False)
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--out", str(tmp_path / "f.csv")]) == 2
    assert says(capsys.readouterr().err, "base-momentum reads base_wrench", "no base_wrench")
    assert not (tmp_path / "f.csv").exists()


def test_a_bad_out_suffix_is_refused_before_the_log_is_read(tmp_path, capsys):
    assert cli_main(["estimate", str(tmp_path / "missing.toml"), "--out", str(tmp_path / "x.bag")]) == 2
    assert says(capsys.readouterr().err, "x.bag", ".mcap or .csv")


def test_an_error_bar_the_estimator_reports_becomes_csv_columns(tmp_path):
    n = 4
    replay = Replay(np.arange(n, dtype=np.int64) * 10**6, np.arange(n) * 1e-3, np.ones((n, 3)), ["ok"] * n,
                    np.full((n, 3), 0.25), None, "panda_link0", "kalman-fusion", 1000.0)
    (path,) = write_estimate(replay, tmp_path / "e.csv")  # no tip sensor: no figure
    rows = list(csv.DictReader(path.open()))
    assert list(rows[0]) == ["stamp_ns", "t", "fx", "fy", "fz", "status", "sigma1", "sigma2", "sigma3"]
    assert [float(r["sigma2"]) for r in rows] == [0.25] * n


@pytest.mark.slow  # trains a tiny net (1 epoch of 3 batches) and replays 600 samples through it
def test_a_trained_model_replays_the_bag_as_the_streaming_api_would(panda, tmp_path, capsys):
    from hybrid_dyn.data import load_dataset
    from hybrid_dyn.data.synthetic import make_synthetic_dataset
    from hybrid_dyn.estimator import TipForceEstimator
    from hybrid_dyn.learn import TrainConfig, train_model

    ds = load_dataset(make_synthetic_dataset(tmp_path / "d", panda, n_instances=4, n_samples=120, record_hz=100.0,
                                             noise=0.002, seed=2))
    train_model(ds, "seed-tip-11", tmp_path / "model", TrainConfig(max_epochs=1, max_batches_per_epoch=3,
                                                                   progress=False))
    sig = panda_signals(panda, n=600, hz=HZ, seed=4)
    spec = ros_spec(tmp_path / "spec", write_bag(tmp_path / "run", sig), extra='effort = "tau_J"\n')
    out = tmp_path / "tip.csv"
    assert cli_main(["estimate", str(spec), "--model", str(tmp_path / "model"), "--out", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert [int(r["stamp_ns"]) for r in rows] == sig["stamps"].tolist()
    # The reference: the streaming API called here on the signals the bag was written from.
    est = TipForceEstimator.load(tmp_path / "model", robot="panda", call_hz=HZ, runtime="numba")
    ref = np.array([est.estimate_tip_force(sig["q"][k], sig["qd"][k], base_wrench=sig["base_wrench"][k],
                                           tau_J=sig["tau"][k], t=sig["t"][k]) for k in range(600)])
    got = np.array([[float(r[k]) for k in ("fx", "fy", "fz")] for r in rows])
    np.testing.assert_allclose(got, ref, atol=1e-3)  # the CLI's runtime may be onnxruntime: float32
    assert {r["status"] for r in rows} <= {"warming up", "ok", "input out of training range"}


def test_a_bag_with_a_stamp_going_backwards_and_its_own_frame_name_replays_what_an_import_keeps(panda, tmp_path):
    sig = panda_signals(panda, n=800, hz=HZ, seed=6)
    stamps = sig["stamps"].copy()
    stamps[600] = stamps[598]  # message 601 goes back in time: the import's rule drops its row
    bag = write_bag(tmp_path / "run", sig, js_stamps=stamps, base_frame="ft_sensor_link")
    spec = ros_spec(tmp_path / "spec", bag, extra='frame = "ft_sensor_link"\n')
    assert cli_main(["estimate", str(spec), "--method", "base-momentum", "--out", str(tmp_path / "tip.mcap")]) == 0
    topics = read_topics(tmp_path / "tip.mcap")
    got = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in topics["/tip_force"]]
    assert got == np.delete(sig["stamps"], 600).tolist()  # every kept sample at its own stamp
    assert {m.header.frame_id for _, m in topics["/tip_force"]} == {"ft_sensor_link"}  # the bag's name for it
    states = [m.data for _, m in topics["/tip_force/status"]]
    # The hole the dropped row leaves is a short gap in the stream: bridged, no sample refused, no new warm-up.
    assert states[599] == "ok" and set(states[599:]) == {"ok"}
