"""``hybrid-dyn identify``, ``calibrate`` and ``estimate --params --calibration`` end to end on a free-motion log
with a logging PC's stamps, written here in the real Panda log's columns (tests/data/test_real_panda.py): the
numbers through the CLI are the library's, nothing is refused but at most 1 %, and the warm-up is the start's."""
from __future__ import annotations

import csv

import numpy as np
import pytest

import hybrid_dyn as hd
from hybrid_dyn.bench.free_motion import score, rows_in_split
from hybrid_dyn.cli import main as cli_main
from hybrid_dyn.data import load_dataset, read_spec
from hybrid_dyn.data.logs.real_logs import real_spec_path
from hybrid_dyn.estimator.replay import replay_log

LOG = "panda_gaz_exciting_traj1.csv"


def write_free_motion_log(folder, n=8000):
    """Nothing touches the tool: tau = ID(q, qd, qdd) + a viscous and Coulomb friction, with 0.05 Nm of noise;
    stamps step 0.8-1.6 ms at random, with two gaps of 8.5 ms."""
    robot = hd.load_robot("panda[tool=none]")
    rng = np.random.default_rng(0)
    steps = rng.choice([0.8e-3, 0.9e-3, 1.0e-3, 1.1e-3, 1.3e-3, 1.6e-3], size=n, p=[0.2, 0.25, 0.25, 0.15, 0.1, 0.05])
    steps[[n // 4, 3 * n // 4]] = 8.5e-3
    t = np.cumsum(steps) - steps[0]
    w = np.linspace(0.8, 2.0, 7)
    q = np.array(robot.spec.home) + 0.4 * np.sin(w * t[:, None])
    qd, qdd = 0.4 * w * np.cos(w * t[:, None]), -0.4 * w * w * np.sin(w * t[:, None])
    tau = robot.inverse_dynamics(q, qd, qdd) + 0.8 * qd + 0.6 * np.tanh(qd / 0.01) + rng.normal(0, 0.05, (n, 7))
    header = ",".join(["t"] + [f"{k}{j}" for k in ("q", "qd", "tau") for j in range(1, 8)])
    folder.mkdir(parents=True, exist_ok=True)
    np.savetxt(folder / LOG, np.column_stack([t, q, qd, tau]), delimiter=",", header=header, comments="", fmt="%.17g")


@pytest.mark.slow
def test_identify_calibrate_estimate_through_the_cli(tmp_path, monkeypatch, capsys):
    write_free_motion_log(tmp_path / "logs")
    monkeypatch.setenv("HYBRID_DYN_REAL_LOGS", str(tmp_path / "logs"))
    data, params, cal, out = (tmp_path / x for x in ("data", "id.json", "cal.json", "tip.csv"))
    assert cli_main(["import", "--spec", "real-panda", "--out", str(data)]) == 0
    assert cli_main(["identify", "--data", str(data), "--splits", "train", "--out", str(params)]) == 0
    assert cli_main(["calibrate", str(data), "--params", str(params), "--methods", "momentum-observer",
                     "--out", str(cal)]) == 0
    assert cli_main(["calibrate", str(data), "--params", str(params), "--out", str(cal)]) == 2  # never overwritten
    spec = real_spec_path("real-panda")
    assert cli_main(["estimate", str(spec), "--params", str(params), "--calibration", str(cal),
                     "--out", str(out)]) == 0
    with out.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    status = [r["status"] for r in rows]
    assert sum(s.startswith("input rejected") for s in status) <= 0.01 * len(status)
    warm = [k for k, s in enumerate(status) if s == "warming up"]
    assert warm == list(range(len(warm))) and len(warm) < 1500  # the start's window and settling only
    # The CLI's numbers are the library's: the same replay, scored on the test part.
    ds = load_dataset(data)
    replay, _ = replay_log(read_spec(spec), "momentum-observer", params=params, calibration=cal)
    keep = rows_in_split(replay, ds.split("test"))
    lib = score(replay, keep)
    force = np.array([[float(r[k]) for k in ("fx", "fy", "fz")] for r in rows])
    np.testing.assert_array_equal(force[keep], replay.force[keep])
    assert lib["share_ok"] > 0.8 and lib["phantom_rms_N"] < 1.0, lib  # the friction is in the model, not read as force


def test_estimate_starts_a_new_stream_where_a_segments_time_starts_anew():
    """A block of three segments (as the import splits a file's trajectories), each with its time from 0: the
    replay restarts per segment instead of refusing every sample of the second and third; a short gap between
    segments goes on in the same stream."""
    from hybrid_dyn.estimator import TipForceEstimator
    from hybrid_dyn.estimator.replay import _run

    robot = hd.load_robot("panda")
    n = 1500
    t = np.arange(n) / 1000.0
    w = np.linspace(0.8, 2.0, 7)
    q = np.array(robot.spec.home) + 0.3 * np.sin(w * t[:, None])
    qd, qdd = 0.3 * w * np.cos(w * t[:, None]), -0.3 * w * w * np.sin(w * t[:, None])
    tau = robot.inverse_dynamics(q, qd, qdd)
    f = {"t": np.r_[t, t, t, t[-1] + 8.5e-3 + t], "q": np.tile(q, (4, 1)), "qd": np.tile(qd, (4, 1)),
         "tau_J": np.tile(tau, (4, 1))}
    starts = np.zeros(4 * n, bool)
    starts[::n] = True
    est = TipForceEstimator.analytic(robot, "momentum-observer", call_hz=1000.0, on_bad_input="hold",
                                     encoder_resolution=0.0)
    _, status, _ = _run(est, f, starts)
    status = np.array(status)
    assert not any(s.startswith("input rejected") for s in status)
    for part in np.split(status, 4)[:3]:  # each trajectory warms up at its own start, and only there
        warm = np.flatnonzero(part == "warming up")
        assert len(warm) and warm[0] == 0 and np.all(np.diff(warm) == 1)
    assert "warming up" not in set(np.split(status, 4)[3])  # after a short gap: the same stream, bridged
