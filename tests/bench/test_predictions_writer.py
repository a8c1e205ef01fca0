"""predictions.h5 written in place, one row at a time: never a copy of the file per row, and a
write killed halfway leaves the rows before it readable and no half row to read."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from hybrid_dyn.bench.predictions import PARTIAL, PredictionWriter, Predictions


def _instances(n=2, length=5):
    return [SimpleNamespace(name=f"run{i}", t=np.arange(length) * 0.01, truth={},
                            **{"tau_m": np.full((length, 2), float(i))}) for i in range(n)]


class _Inst(SimpleNamespace):
    def __getitem__(self, key):
        return getattr(self, key)


def _test_data():
    return [_Inst(**vars(i)) for i in _instances()]


def test_rows_are_written_in_place_not_by_copying_the_file(tmp_path):
    path = tmp_path / "predictions.h5"
    w = PredictionWriter(path)
    insts = _test_data()
    w.test_data("s", insts, ["tau_m"])
    inode = os.stat(path).st_ino  # a copy renamed over the file would be a new inode
    for k, model in enumerate(["a", "b", "a"]):  # "a" again: replaced, as a resumed run re-scores a row
        w.row("s", "joint_torque", model, [i.name for i in insts], [np.full((5, 2), 10.0 * k + j) for j in range(2)])
        assert os.stat(path).st_ino == inode
    p = Predictions(path)
    np.testing.assert_array_equal(p.get("s", "joint_torque", "a")[1], np.full((5, 2), 21.0))
    np.testing.assert_array_equal(p.get("s", "joint_torque", "b")[0], np.full((5, 2), 10.0))
    with h5py.File(path, "r") as f:
        assert sorted(f["s"]["joint_torque"]) == ["a", "b"]  # no leftover temporary group


KILLED = textwrap.dedent("""
    import os, sys
    import numpy as np
    import h5py
    sys.path[:0] = [{tests!r}]
    from test_predictions_writer import _test_data
    from hybrid_dyn.bench import predictions

    w = predictions.PredictionWriter({path!r})
    insts = _test_data()
    w.test_data("s", insts, ["tau_m"])
    w.row("s", "joint_torque", "a", [i.name for i in insts], [np.ones((5, 2))] * 2)
    # The next row dies like a SIGKILL between its arrays and its rename: no close, no flush, no handler.
    h5py.Group.move = lambda self, a, b: os._exit(137)
    w.row("s", "joint_torque", "b", [i.name for i in insts], [np.full((5, 2), 2.0)] * 2)
""")


@pytest.mark.slow  # a Python process of its own that imports the bench: ~10 s on 2 busy cores
def test_a_write_killed_halfway_leaves_the_earlier_rows_and_no_half_row(tmp_path):
    path = tmp_path / "predictions.h5"
    script = KILLED.format(tests=str(Path(__file__).parent), path=str(path))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 137, run.stderr[-2000:]
    p = Predictions(path)  # readable, and the reader sees exactly the finished row
    np.testing.assert_array_equal(p.get("s", "joint_torque", "a")[0], np.ones((5, 2)))
    assert p.get("s", "joint_torque", "b") is None
    with h5py.File(path, "r") as f:
        assert any(PARTIAL in k for k in f["s"]["joint_torque"])  # the half row is there, unlisted
    # A resumed bench writes the row again; the killed write's leftover goes.
    w = PredictionWriter(path, resume=True)
    insts = _test_data()
    w.row("s", "joint_torque", "b", [i.name for i in insts], [np.full((5, 2), 2.0)] * 2)
    np.testing.assert_array_equal(Predictions(path).get("s", "joint_torque", "b")[1], np.full((5, 2), 2.0))
    with h5py.File(path, "r") as f:
        assert sorted(f["s"]["joint_torque"]) == ["a", "b"]
