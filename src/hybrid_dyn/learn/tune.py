"""Hyperparameter search with Optuna (standing in for the reference study's Keras Tuner).

The design in full: ``docs/design/learn.md`` (tune.py).
"""
from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import hashlib
import json
import multiprocessing as mp
import os
import time
import warnings
from dataclasses import replace
from pathlib import Path

import optuna

from ..data import Dataset, load_dataset
from ..errors import UsageError
from .trained_model import canonical_json
from .kinds import NETWORK_KINDS, SPACE  # noqa: F401  (SPACE re-exported: the searched values)
from .presets import PRESETS, Preset
from .recipes import TrainConfig
from .train import train_model

def suggest_preset(trial: optuna.Trial, base: Preset) -> Preset:
    """The base preset with the searched hyperparameters replaced by the trial's choice (the search
    space is its network kind's, declared with the kind: ``learn/kinds.py``, :data:`SPACE`)."""
    p = NETWORK_KINDS.lookup(base.kind).search(trial, base)
    arch = replace(base, **p)
    # The fingerprint's form (older prior spellings): the tuned preset's name, and so its trials, stay as before.
    digest = hashlib.sha256(canonical_json(arch.fingerprint_dict()).encode()).hexdigest()[:10]
    return replace(arch, name=f"{base.name}-tuned-{digest}", description=f"{base.name} tuned: {p}")


HEARTBEAT_S = 10  # seconds between a running trial's heartbeats; stale after 3 missed
MAX_RETRY = 2     # times a failed trial's parameters are tried again


def open_storage(url: str, heartbeat_s: int = HEARTBEAT_S) -> optuna.storages.RDBStorage:
    """An RDB storage (SQLite, PostgreSQL, MySQL) with heartbeats and retry of failed trials."""
    if not url.split(":", 1)[0].startswith(("sqlite", "postgresql", "mysql")):
        raise UsageError(f"storage must be an RDB URL (sqlite:///..., postgresql://..., mysql://...), got {url!r}; "
                         "the heartbeat that detects killed workers needs one")
    engine_kwargs = {"connect_args": {"timeout": 60}} if url.startswith("sqlite") else None  # writers wait, not fail
    with warnings.catch_warnings():  # Optuna labels heartbeats experimental; they are what we rely on
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return optuna.storages.RDBStorage(
            url, engine_kwargs=engine_kwargs, heartbeat_interval=heartbeat_s, grace_period=3 * heartbeat_s,
            heartbeat_stale_trial_callback=optuna.storages.RetryHeartbeatStaleTrialCallback(max_retry=MAX_RETRY))


def retry_interrupted(study: optuna.Study) -> list[int]:
    """Enqueue again every failed trial not yet retried (up to MAX_RETRY); returns their numbers.

    Covers trials failed by Ctrl-C or an error, which no heartbeat reports.
    Stale (killed) trials are also failed and enqueued here when their grace
    period has passed, so a lone restarted worker recovers them too.
    """
    with warnings.catch_warnings():  # experimental in Optuna's labels, stable in use since v2.9
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        optuna.storages.fail_stale_trials(study)  # with heartbeats on: enqueues its own retries through the callback
        trials = study.get_trials(deepcopy=False)
        # A retry's system attrs list the trials it repeats; the last is the one it replaced.
        retried = {t.system_attrs["retry_history"][-1] for t in trials if t.system_attrs.get("retry_history")}
        callback = optuna.storages.RetryHeartbeatStaleTrialCallback(max_retry=MAX_RETRY)  # stops after MAX_RETRY
        out = []
        for t in trials:
            if t.state == optuna.trial.TrialState.FAIL and t.number not in retried:
                callback(study, t)
                out.append(t.number)
    return out


@contextlib.contextmanager
def _architecture_lock(model_dir: Path):
    """One trainer per architecture directory at a time; the OS frees it if a worker dies."""
    model_dir.parent.mkdir(parents=True, exist_ok=True)
    with open(model_dir.with_name(model_dir.name + ".lock"), "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _objective(ds: Dataset, base: Preset, out_dir: Path, config: TrainConfig, worker: int):
    def objective(trial: optuna.Trial) -> float:
        arch = suggest_preset(trial, base)
        model_dir = out_dir / "trials" / arch.name
        trial.set_user_attr("model_dir", str(model_dir))
        trial.set_user_attr("preset", arch.to_dict())
        trial.set_user_attr("worker", worker)
        trial.set_user_attr("pid", os.getpid())
        with _architecture_lock(model_dir):
            model = train_model(ds, arch, model_dir, config)
        trial.set_user_attr("n_params", model.n_params)
        trial.set_user_attr("train_seconds", model.train_seconds)
        return model.val_loss

    return objective


def _run_worker(dataset_path: str, preset: str, out_dir: str, storage: str, study_name: str, config: dict,
                seed: int, n_trials: int, heartbeat_s: int, worker: int) -> None:
    """One worker process: its own sampler seed, its share of the trials, the shared storage."""
    import torch

    torch.set_num_threads(config.get("num_threads") or 1)  # N workers share the machine's cores
    study = optuna.load_study(study_name=study_name, storage=open_storage(storage, heartbeat_s),
                              sampler=optuna.samplers.TPESampler(seed=seed))
    base = PRESETS.lookup(preset) if isinstance(preset, str) else preset
    objective = _objective(load_dataset(dataset_path), base, Path(out_dir), TrainConfig(**config), worker)
    study.optimize(objective, n_trials=n_trials, catch=())


def tune(dataset, preset, out_dir, n_trials: int, storage: str | None = None, study_name: str | None = None,
         config: TrainConfig | None = None, seed: int = 0, workers: int = 1,
         heartbeat_s: int = HEARTBEAT_S) -> optuna.Study:
    """Run ``n_trials`` more trials of the study for ``preset`` on ``dataset``; returns the study.

    workers: local worker processes sharing the trials (1: in this process).
    Each uses sampler seed ``seed + worker``. Writes ``<out_dir>/best.json``
    (best parameters, validation loss, model dir).
    """
    if n_trials < 1 or workers < 1:
        raise UsageError(f"need n_trials >= 1 and workers >= 1, got {n_trials} and {workers}")
    base = PRESETS.lookup(preset) if isinstance(preset, str) else preset
    ds: Dataset = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
    config = config or TrainConfig(progress=False)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    storage = storage or f"sqlite:///{(out_dir / 'optuna.db').resolve()}"
    study_name = study_name or f"{base.name}-{ds.checksum[:12]}"
    # Created here, once, so that workers starting together do not race to create it.
    study = optuna.create_study(study_name=study_name, storage=open_storage(storage, heartbeat_s),
                                direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed),
                                load_if_exists=True)
    retry_interrupted(study)
    if workers == 1:
        study.optimize(_objective(ds, base, out_dir, config, 0), n_trials=n_trials, catch=())
    else:
        _run_workers(ds, base, out_dir, storage, study_name, config, seed, n_trials, heartbeat_s, workers)
    best = study.best_trial
    doc = {"study": study_name, "storage": storage if storage.startswith("sqlite") else "(external RDB)",
           "base_preset": base.name, "best_val_loss": best.value, "best_params": best.params,
           "model_dir": best.user_attrs.get("model_dir"), "n_trials": len(study.trials),
           "n_complete": len(study.get_trials(states=(optuna.trial.TrialState.COMPLETE,)))}
    tmp = out_dir / "best.json.partial"
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, out_dir / "best.json")
    return study


def _run_workers(ds, base, out_dir, storage, study_name, config, seed, n_trials, heartbeat_s, workers) -> None:
    """Start the worker processes (spawned: no forked library state) and wait for all of them."""
    shares = [n_trials // workers + (i < n_trials % workers) for i in range(workers)]
    cfg = dataclasses.asdict(config)
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_run_worker, name=f"tune-worker-{i}",
                         args=(str(ds.path), base.name, str(out_dir), storage, study_name, cfg, seed + i, n,
                               heartbeat_s, i))
             for i, n in enumerate(shares) if n > 0]
    for p in procs:
        p.start()
    try:
        while any(p.is_alive() for p in procs):
            time.sleep(0.2)
    finally:  # Ctrl-C: stop the workers; Optuna marks their trials failed, the next run retries them
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join()
    bad = [f"{p.name} (exit code {p.exitcode})" for p in procs if p.exitcode != 0]
    if bad:
        raise RuntimeError(f"tune workers failed: {', '.join(bad)}; the study is consistent and a rerun "
                           "retries their trials")
