"""The real Panda log as the ``real-panda`` set (hybrid_dyn/resources/real/panda.toml), on a tiny CSV made here.

The real file (../shared/data/real/panda_gaz_exciting_traj1.csv) is GPL-3.0 data and never enters
the repository; these tests write a 1.2 s log with its columns into a temporary folder and point
HYBRID_DYN_REAL_LOGS at it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hybrid_dyn.data import load_dataset, read_spec
from hybrid_dyn.data.logs.real_logs import RealLogMissingError, missing_real_log, real_dataset, real_spec_path

from helpers import REPO

LOG = "panda_gaz_exciting_traj1.csv"


def write_panda_log(folder: Path, n: int = 1200, hz: float = 1000.0) -> dict:
    """A log with the real file's header (t, q1..q7, qd1..qd7, tau1..tau7): slow sines about the
    Panda's home pose, their exact velocities and accelerations, and torques that are any numbers."""
    t = np.arange(n) / hz
    home = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    w = np.linspace(1.0, 2.5, 7)
    q = home + 0.2 * np.sin(w * t[:, None])
    qd = 0.2 * w * np.cos(w * t[:, None])
    qdd = -0.2 * w**2 * np.sin(w * t[:, None])
    tau = np.random.default_rng(0).normal(0, 5, (n, 7))
    header = ",".join(["t"] + [f"{k}{j}" for k in ("q", "qd", "tau") for j in range(1, 8)])
    folder.mkdir(parents=True, exist_ok=True)
    np.savetxt(folder / LOG, np.column_stack([t, q, qd, tau]), delimiter=",", header=header, comments="", fmt="%.17g")
    return {"t": t, "q": q, "qd": qd, "qdd": qdd, "tau": tau}


def test_real_panda_imports_a_log_with_the_real_files_columns(tmp_path, monkeypatch):
    logs = tmp_path / "logs"
    truth = write_panda_log(logs)
    monkeypatch.setenv("HYBRID_DYN_REAL_LOGS", str(logs))
    assert missing_real_log("real-panda") is None
    ds = load_dataset(real_dataset("real-panda", tmp_path / "cache"))
    assert ds.meta["scenario"] == "real-panda"
    assert ds.meta["robot"] == "panda[tool=none]"  # the bare flange: the arm carried no hand
    assert set(ds.fields) == {"t", "q", "qd", "qdd", "tau_m"}
    # Contiguous time blocks: 10 of 120 rows, in order, none lost, split 6 / 2 / 2.
    insts = sorted(ds.instances.values(), key=lambda i: i.t[0])
    assert [len(i) for i in insts] == [120] * 10
    assert [len(ds.split(s)) for s in ("train", "val", "test")] == [6, 2, 2]
    # In time order: the first 720 rows train, the next 240 validate, the last 240 test.
    span = {s: (min(i.t[0] for i in ds.split(s)), max(i.t[-1] for i in ds.split(s))) for s in ("train", "val", "test")}
    assert span["train"] == (truth["t"][0], truth["t"][719]) and span["val"] == (truth["t"][720], truth["t"][959])
    assert span["test"] == (truth["t"][960], truth["t"][-1])
    stack = lambda f: np.concatenate([np.asarray(i[f]) for i in insts])  # noqa: E731
    np.testing.assert_array_equal(stack("t"), truth["t"])
    np.testing.assert_array_equal(stack("q"), truth["q"])
    np.testing.assert_array_equal(stack("qd"), truth["qd"])  # the logged velocity is kept
    np.testing.assert_array_equal(stack("tau_m"), truth["tau"])  # the logged torque is the target
    # qdd: the spec's Savitzky-Golay derivative of the logged velocity, per block: close to the exact one.
    err = np.abs(stack("qdd") - truth["qdd"]).max(axis=0)
    assert np.all(err < 1e-3 * np.abs(truth["qdd"]).max(axis=0))


def test_an_absent_panda_log_says_where_to_get_it(tmp_path, monkeypatch):
    monkeypatch.setenv("HYBRID_DYN_REAL_LOGS", str(tmp_path))  # a folder without the log
    message = missing_real_log("real-panda")
    assert message is not None
    for part in (str(tmp_path / LOG), "GPL-3.0", "marcocognetti/FrankaEmikaPandaDynModel",
                 "../shared/data/real/", "HYBRID_DYN_REAL_LOGS"):
        assert part in message
    with pytest.raises(RealLogMissingError) as err:
        real_dataset("real-panda", tmp_path / "cache")
    assert str(err.value) == message and err.value.scenario == "real-panda"
    assert not (tmp_path / "cache").exists()  # nothing was written


def test_the_default_folder_is_shared_data_beside_the_repository(monkeypatch):
    monkeypatch.delenv("HYBRID_DYN_REAL_LOGS", raising=False)
    monkeypatch.delenv("HYBRID_DYN_REAL_SPECS", raising=False)
    assert read_spec(real_spec_path("real-panda")).files == [REPO.parent / "shared" / "data" / "real" / LOG]
    # GPL-3.0 data: never copied into the repository, nor into the package data beside the other logs
    assert not [p for d in ("src", "benchmarks", "tests") for p in (REPO / d).glob(f"**/{LOG}")]
