"""Distributed tuning: workers share one Optuna storage, a killed worker's trial is failed and
retried, an interrupted trial is retried by the next run, a storage without heartbeats is refused."""
import json
import os
import signal
import subprocess
import sys
import time

import optuna
import pytest

import hybrid_dyn as hd
from hybrid_dyn.data import load_dataset
from hybrid_dyn.data.synthetic import make_synthetic_dataset
from hybrid_dyn.learn import TrainConfig
from hybrid_dyn.learn import tune as tune_mod
from hybrid_dyn.learn.tune import tune


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
    # A constant rate: on a fast machine the plateau schedule reached its floor and ended the run by itself
    # ("lr-floor") before the kill, and the trial read COMPLETE.
    code = ("import sys; from hybrid_dyn.cli import main; sys.exit(main(sys.argv[1:]))")
    args = ["tune", "--data", str(tune_set.path), "--preset", "seed-tau-mlp", "--trials", "1", "--out",
            str(tmp_path / "t"), "--storage", storage, "--study", "s", "--heartbeat", "1", "--max-epochs", "100000",
            "--patience", "100000", "--lr-schedule", "none", "--batch-size", "8", "--quiet", "--threads", "1"]
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
