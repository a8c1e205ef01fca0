"""Dataset generation: determinism across worker counts, resume, corrupt files."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hybrid_dyn.data import DatasetError, load_dataset
from hybrid_dyn.sim.executors import SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.generator_config import GeneratorConfig, PulseConfig
from hybrid_dyn.sim.scenarios import scenario_config

from helpers import REPO
from helpers.files import dir_bytes

HELPERS_ROOT = REPO / "tests"

TINY = dict(n_instances=4, trajectories=(1, 2), standstill=0.2, speed_scale=(0.5, 0.6),
            pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


def tiny_config(seed=0, **kw) -> GeneratorConfig:
    return scenario_config("paper-ext", "quick", seed=seed, **{**TINY, **kw})


@pytest.fixture(scope="module")
def reference_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "ref"
    generate_dataset(tiny_config(), out, workers=1, progress=False)
    return out


def test_dataset_loads_with_fields_splits_and_tracking(reference_dataset):
    ds = load_dataset(reference_dataset)
    meta = ds.meta
    assert meta["scenario"] == "paper-ext" and meta["config_hash"] == tiny_config().config_hash()
    assert sorted(sum((meta["splits"][s] for s in ("train", "val", "test")), [])) == [f"inst_{i:05d}" for i in range(4)]
    inst = ds.split("train")[0]
    for name in ("t", "q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force"):
        assert inst[name].shape[0] == len(inst) and name in inst.truth
    assert inst.q.shape[1] == 7 and inst.base_wrench.shape[1] == 6
    np.testing.assert_allclose(np.diff(inst.truth["t"]), 0.01, atol=1e-12)
    assert np.abs(inst.t - inst.truth["t"]).max() <= 5e-4 + 1e-12  # the stamps' jitter
    assert len(meta["tracking_error"]["rms_mean_per_joint"]) == 7
    assert {"numpy", "dartpy", "pin"} <= set(meta["packages"])
    assert meta["n_samples"] == sum(r["n_samples"] for r in meta["instances"])
    # Windows for the sequence models work on generated data.
    ws = ds.windows("train", 5, ["q", "qd", "qdd", "base_wrench"], ["tip_force"])
    x, y = ws[np.arange(3)]
    assert x.shape == (3, 5, 27) and y.shape == (3, 3)


def test_same_seed_same_bytes_whatever_the_worker_count(reference_dataset, tmp_path):
    out = tmp_path / "two_workers"
    generate_dataset(tiny_config(), out, workers=2, progress=False)
    assert dir_bytes(out) == dir_bytes(reference_dataset)
    other = tmp_path / "other_seed"
    generate_dataset(tiny_config(seed=1), other, workers=1, progress=False)
    assert dir_bytes(other)["instances/inst_00000.h5"] != dir_bytes(reference_dataset)["instances/inst_00000.h5"]


def _copy(src: Path, dst: Path) -> Path:
    for name, data in dir_bytes(src).items():
        (dst / name).parent.mkdir(parents=True, exist_ok=True)
        (dst / name).write_bytes(data)
    return dst


def test_corrupt_partial_and_missing_instances_are_named_and_regenerated(reference_dataset, tmp_path):
    out = _copy(reference_dataset, tmp_path / "damaged")
    inst = out / "instances"
    data = bytearray((inst / "inst_00001.h5").read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte: opens fine, checksum catches it
    (inst / "inst_00001.h5").write_bytes(bytes(data))
    (inst / "inst_00002.h5").write_bytes((inst / "inst_00002.h5").read_bytes()[:1000])  # truncated
    (inst / "inst_00003.h5").unlink()
    (inst / "inst_00000.h5.partial").write_bytes(b"half a file")
    with pytest.raises(DatasetError, match="inst_00001.*checksum"):
        load_dataset(out)  # the loader names the bad file too
    messages = []
    generate_dataset(tiny_config(), out, workers=1, progress=False, log=messages.append)
    text = "\n".join(messages)
    assert "inst_00001" in text and "inst_00002" in text and "checksum" in text
    assert "inst_00003: file is missing" in text and "inst_00000.h5.partial" in text
    assert "inst_00000" not in text.replace("inst_00000.h5.partial", "")  # the intact one was kept
    assert dir_bytes(out) == dir_bytes(reference_dataset)


class _InterruptAfter(SerialExecutor):
    """Simulates Ctrl-C after ``n`` finished instances."""

    def __init__(self, n):
        self.n = n

    def map_unordered(self, fn, jobs):
        for i, result in enumerate(super().map_unordered(fn, jobs)):
            if i == self.n:
                raise KeyboardInterrupt
            yield result


def test_resume_after_an_interrupt_gives_the_same_dataset(reference_dataset, tmp_path):
    out = tmp_path / "interrupted"
    with pytest.raises(KeyboardInterrupt):
        generate_dataset(tiny_config(), out, progress=False, executor=_InterruptAfter(2))
    assert not (out / "manifest.json").exists()  # the manifest only comes with complete data
    assert len(list((out / "instances").glob("*.h5"))) == 3  # the third finished before the "kill"
    messages = []
    generate_dataset(tiny_config(), out, workers=2, progress=False, log=messages.append)
    assert messages == []  # finished instances were verified, not regenerated
    assert dir_bytes(out) == dir_bytes(reference_dataset)


def test_another_config_in_the_same_directory_is_refused(reference_dataset, tmp_path):
    out = _copy(reference_dataset, tmp_path / "taken")
    with pytest.raises(DatasetError, match="another configuration"):
        generate_dataset(tiny_config(seed=5), out, progress=False)


@pytest.mark.slow
def test_resume_after_killing_the_process(reference_dataset, tmp_path):
    """SIGKILL a real generator process mid-run, restart, compare with an uninterrupted run."""
    out = tmp_path / "killed"
    script = (
        "import sys; sys.path[:0] = [%r, %r]\n"  # this file's folder and tests/ (the helpers it imports)
        "from test_generator_dataset import tiny_config\n"
        "from hybrid_dyn.sim.generator import generate_dataset\n"
        "generate_dataset(tiny_config(), %r, workers=1, progress=False)\n"
    ) % (str(Path(__file__).parent), str(HELPERS_ROOT), str(out))
    proc = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "instances" / "inst_00000.json").exists():
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (out / "manifest.json").exists(), "killed too late to test a resume"
    generate_dataset(tiny_config(), out, workers=1, progress=False, log=lambda m: None)
    assert dir_bytes(out) == dir_bytes(reference_dataset)


@pytest.mark.slow
def test_cli_generate_quick_profile(tmp_path):
    """The documented command on the quick profile, end to end."""
    out = tmp_path / "quick"
    res = subprocess.run([sys.executable, "-m", "hybrid_dyn.cli", "generate", "--scenario", "mismatch-ext",
                          "--size", "quick", "--out", str(out), "--workers", "2", "--quiet"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    meta = json.loads((out / "manifest.json").read_text())
    assert meta["scenario"] == "mismatch-ext" and len(meta["instances"]) == 6
    assert "tracking RMS" in res.stdout
    bad = subprocess.run([sys.executable, "-m", "hybrid_dyn.cli", "generate", "--scenario", "nope", "--out", str(out)],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and "invalid choice" in bad.stderr
