"""Scale-out (issue 9): generation on Ray and into fsspec stores, distributed tuning on one Optuna storage."""
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import fsspec
import optuna
import pytest

import hybrid_dyn as hd
from hybrid_dyn.data import DatasetError, load_dataset
from hybrid_dyn.data.store import fetch_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.learn import TrainConfig
from hybrid_dyn.learn import tune as tune_mod
from hybrid_dyn.learn.tune import tune
from hybrid_dyn.sim.executors import ProcessExecutor, RayExecutor, SerialExecutor, make_executor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.scenarios import PulseConfig, scenario_config

TINY = dict(n_instances=3, trajectories=(1, 1), standstill=0.2, speed_scale=(0.5, 0.6),
            pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


def dir_bytes(path: Path) -> dict:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(Path(path).rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def tiny_reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("ref") / "ds"
    generate_dataset(scenario_config("paper-ext", "quick", seed=1, **TINY), out, executor=SerialExecutor(), progress=False)
    return out


# ----------------------------------------------------------------- generation
@pytest.mark.slow
def test_ray_generation_equals_local(tmp_path):
    """A `quick` generation as Ray tasks on a local 2-CPU Ray instance: the same files, byte for byte."""
    cfg = scenario_config("paper-ext", "quick", seed=0)
    local = generate_dataset(cfg, tmp_path / "local", executor=ProcessExecutor(2), progress=False)
    ray_ex = RayExecutor(workers=2)
    on_ray = generate_dataset(cfg, tmp_path / "ray", executor=ray_ex, progress=False)
    assert ray_ex.workers == 2  # the cluster Ray reported: this ran on Ray, with 2 CPUs
    a, b = dir_bytes(local), dir_bytes(on_ray)
    assert sorted(a) == sorted(b) and len([k for k in a if k.endswith(".h5")]) == cfg.n_instances
    assert a == b
    assert load_dataset(on_ray).checksum == load_dataset(local).checksum


def test_file_url_store_with_processes_equals_local_directory(tiny_reference, tmp_path):
    """Through fsspec (file:// URL: the code path of any remote store) from two worker processes."""
    url = f"file://{tmp_path / 'remote'}"
    assert generate_dataset(scenario_config("paper-ext", "quick", seed=1, **TINY), url,
                            executor=ProcessExecutor(2), progress=False) == url
    assert dir_bytes(tmp_path / "remote") == dir_bytes(tiny_reference)


def test_memory_store_resume_and_fetch(tiny_reference, tmp_path):
    cfg = scenario_config("paper-ext", "quick", seed=1, **TINY)
    url = "memory://hybrid-dyn-test/ds"
    fs = fsspec.filesystem("memory")
    try:
        generate_dataset(cfg, url, executor=SerialExecutor(), progress=False)
        ref = dir_bytes(tiny_reference)
        for rel, data in ref.items():
            assert fs.cat_file(f"/hybrid-dyn-test/ds/{rel}") == data, rel
        # A corrupt instance in the store is named and regenerated; the others are kept.
        fs.pipe_file("/hybrid-dyn-test/ds/instances/inst_00001.h5", b"truncated")
        messages = []
        generate_dataset(cfg, url, executor=SerialExecutor(), progress=False, log=messages.append)
        assert messages == ["regenerating inst_00001: file does not match its checksum (corrupt or partial)"]
        assert fs.cat_file("/hybrid-dyn-test/ds/instances/inst_00001.h5") == ref["instances/inst_00001.h5"]
        # Training reads local files: a URL is refused by name, and fetch_dataset copies it.
        with pytest.raises(DatasetError, match="is a URL"):
            load_dataset(url)
        local = fetch_dataset(url, tmp_path / "copy")
        assert load_dataset(local).checksum == load_dataset(tiny_reference).checksum
    finally:
        fs.rm("/hybrid-dyn-test", recursive=True)


def test_executor_choice_errors():
    with pytest.raises(ValueError, match="--ray-address needs --executor ray"):
        make_executor(1, "local", address="auto")
    with pytest.raises(ValueError, match="executor must be one of"):
        make_executor(1, "dask")
    assert isinstance(make_executor(2, "ray"), RayExecutor)


# --------------------------------------------------------------------- tuning
@pytest.fixture(scope="module")
def tune_set(tmp_path_factory):
    p = hd.load_robot("panda")
    path = make_synthetic_dataset(tmp_path_factory.mktemp("tune") / "d", p, n_instances=6, n_samples=100, seed=1,
                                  friction=p.spec.friction())
    return load_dataset(path)


FAST = TrainConfig(max_epochs=2, max_batches_per_epoch=3, batch_size=64, progress=False, num_threads=1)


def _states(study):
    return [t.state.name for t in study.get_trials(deepcopy=False)]


@pytest.mark.slow
def test_two_workers_share_one_storage(tune_set, tmp_path):
    study = tune(tune_set, "seed-tau-mlp", tmp_path / "t", 4, config=FAST, workers=2, heartbeat_s=1)
    trials = study.get_trials()
    assert _states(study) == ["COMPLETE"] * 4
    by_worker = {w: [t.number for t in trials if t.user_attrs["worker"] == w] for w in (0, 1)}
    assert len(by_worker[0]) == len(by_worker[1]) == 2                 # each ran its share...
    assert sorted(by_worker[0] + by_worker[1]) == [0, 1, 2, 3]          # ...of disjoint trials that add up
    pids = {t.user_attrs["pid"] for t in trials}
    assert len(pids) == 2 and os.getpid() not in pids                   # two processes, not this one
    best = json.loads((tmp_path / "t" / "best.json").read_text())
    assert best["n_complete"] == 4 and best["best_val_loss"] == pytest.approx(study.best_value)


@pytest.mark.slow
def test_a_killed_worker_leaves_the_study_consistent(tune_set, tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    # A worker on a long training run, killed (SIGKILL: no chance to clean up) in the middle of its trial.
    code = ("import sys; from hybrid_dyn.cli import main; sys.exit(main(sys.argv[1:]))")
    args = ["tune", "--data", str(tune_set.path), "--preset", "seed-tau-mlp", "--trials", "1", "--out",
            str(tmp_path / "t"), "--storage", storage, "--study", "s", "--heartbeat", "1", "--max-epochs", "100000",
            "--patience", "100000", "--batch-size", "8", "--quiet", "--threads", "1"]
    proc = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        study = None
        while time.monotonic() < deadline:
            try:
                study = optuna.load_study(study_name="s", storage=storage)
                if _states(study) == ["RUNNING"] and (tmp_path / "t" / "trials").is_dir():
                    break
            except KeyError:
                pass  # the study is not created yet
            assert proc.poll() is None, "the worker ended before it could be killed"
            time.sleep(0.1)
        else:
            pytest.fail("the worker never started a trial")
        time.sleep(1.0)  # well inside training
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    killed = study.get_trials()[0]
    assert _states(study) == ["RUNNING"]  # a dead worker's trial: nobody will finish it
    # Past the grace period (3 heartbeats of 1 s). SQLite's CURRENT_TIMESTAMP, which Optuna's heartbeat
    # uses, has whole-second resolution, so a silence of 3.5 s can read as 3 s: wait 5 s.
    time.sleep(5.0)
    # A restarted (or any other) worker: the stale trial is failed, its parameters are tried again.
    # Its own --out: it trains with another config (FAST), and the killed run may have left a
    # checkpoint in its trial directory, which train_model rightly refuses to mix with another run.
    study = tune(tune_set, "seed-tau-mlp", tmp_path / "t2", 1, storage=storage, study_name="s", config=FAST,
                 heartbeat_s=1)
    trials = study.get_trials()
    assert _states(study) == ["FAIL", "COMPLETE"]
    assert trials[1].params == killed.params and trials[1].system_attrs["retry_history"] == [0]


def test_an_interrupted_trial_is_retried_by_the_next_run(tune_set, tmp_path, monkeypatch):
    real_train = tune_mod.train_model

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(tune_mod, "train_model", interrupted)
    with pytest.raises(KeyboardInterrupt):
        tune(tune_set, "seed-tau-mlp", tmp_path / "t", 2, config=FAST)
    monkeypatch.setattr(tune_mod, "train_model", real_train)
    study = tune(tune_set, "seed-tau-mlp", tmp_path / "t", 2, config=FAST)
    trials = study.get_trials()
    assert _states(study) == ["FAIL", "COMPLETE", "COMPLETE"]
    assert trials[1].params == trials[0].params and trials[1].system_attrs["retry_history"] == [0]
    # Already retried: a third run does not enqueue it again.
    study = tune(tune_set, "seed-tau-mlp", tmp_path / "t", 1, config=FAST)
    assert _states(study) == ["FAIL", "COMPLETE", "COMPLETE", "COMPLETE"]


def test_tune_refuses_a_storage_without_heartbeats(tune_set, tmp_path):
    with pytest.raises(ValueError, match="RDB URL"):
        tune(tune_set, "seed-tau-mlp", tmp_path / "t", 1, storage=f"journal:{tmp_path / 'j.log'}", config=FAST)


# -------------------------------------------------------- worker processes (issue 17)
def _session_processes(sid: int) -> dict:
    """pid -> command line of the live (not zombie) processes of session ``sid``, its leader excluded.

    The command runs as a session leader, so its workers and the multiprocessing resource
    tracker stay in its session even after they are re-parented to init.
    """
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == sid:
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
            cmd = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue  # exited meanwhile
        state, _ppid, _pgrp, session = stat.rsplit(")", 1)[1].split()[:4]
        if int(session) == sid and state != "Z":
            found[int(entry)] = cmd
    return found


def _ignores_sigint(pid: int) -> bool:
    """The worker initializer ignores SIGINT as its last step: set means parent-death handling is in place."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
    return False


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_generate_workers_die_with_their_parent(tmp_path, sig):
    """`generate --workers 2` killed while its workers run: no worker and no resource tracker survive it.

    SIGKILL runs no cleanup in the parent (the workers end by the parent-death signal);
    SIGTERM unwinds like Ctrl-C (exit 143) and stops the workers.
    """
    cmd = [sys.executable, "-m", "hybrid_dyn.cli", "generate", "--size", "quick", "--workers", "2",
           "--out", str(tmp_path / "ds"), "--quiet"]
    # SIGINT at its default, whatever the test runner's is: the workers' SigIgn is the readiness signal.
    with open(tmp_path / "stderr.txt", "wb") as err:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, start_new_session=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        # Workers running: both alive and one instance finished (4 or more of the 6 are still to do).
        deadline = time.monotonic() + 180
        while True:
            workers = [p for p, c in _session_processes(proc.pid).items() if "spawn_main" in c]
            if len(workers) == 2 and list((tmp_path / "ds" / "instances").glob("*.json")):
                break
            assert proc.poll() is None, (tmp_path / "stderr.txt").read_text()
            assert time.monotonic() < deadline, "no instance was finished within 180 s"
            time.sleep(0.2)
        # And past their initializer (its last step ignores SIGINT); code without one is killed after 10 s.
        deadline = time.monotonic() + 10
        while not all(_ignores_sigint(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        proc.send_signal(sig)
        rc = proc.wait(timeout=60)
        deadline = time.monotonic() + 10
        while _session_processes(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        left = _session_processes(proc.pid)
        assert not left, f"still alive after {signal.Signals(sig).name} of the parent: {left}"
        if sig == signal.SIGTERM:
            assert rc == 143, (tmp_path / "stderr.txt").read_text()
            assert "interrupted" in (tmp_path / "stderr.txt").read_text()
    finally:
        for pid in [proc.pid, *_session_processes(proc.pid)]:  # only what this test started
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        proc.wait()
