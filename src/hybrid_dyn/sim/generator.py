"""The dataset generator: a torque-controlled arm in DART, with sensors.

The detail (what it computes, the equations, why each choice): docs/design/sim.md, section ``sim/generator.py``.
"""
from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path

import numpy as np

from ..data.dataset import FIELD_UNITS, DatasetError, manifest_text, package_versions, split_by_instance
from ..data.store import DatasetStore
from ..errors import OutputPathError, UsageError
from ..outputs import output_lock, refuse_foreign
from .executors import make_executor
from .instances import _finished_record, _instance_job, instance_name
from .instances import instance_rngs, simulate_instance  # noqa: F401  (re-exported: imported from here)
from .generator_config import GENERATOR_VERSION, GeneratorConfig
from .simulator import FIELDS
from .simulator import SimulatedRun, Simulator, simulate_reference  # noqa: F401  (re-exported: imported from here)


def _tracking_summary(records: list[dict]) -> dict:
    rms = np.array([r["tracking_rms"] for r in records])
    mx = np.array([r["tracking_max"] for r in records])
    return {
        "unit": "rad (reference minus true joint position, at the control rate)",
        "rms_mean_per_joint": [round(float(x), 9) for x in rms.mean(0)],
        "rms_worst_per_joint": [round(float(x), 9) for x in rms.max(0)],
        "max_per_joint": [round(float(x), 9) for x in mx.max(0)],
    }


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr)


def generate_dataset(config: GeneratorConfig, out_dir, workers: int = 1, progress: bool = True,
                     executor=None, log=_stderr):
    """Generate (or resume) the dataset of ``config`` in ``out_dir``; returns where it is.

    ``out_dir``: a local directory (returned as a Path) or an fsspec URL
    (returned as given), see ``data/store.py``. Finished instances already
    there are verified and kept; missing, partial or corrupt ones are
    (re)generated and named through ``log``. The manifest is written last, so a
    dataset with a manifest is complete. ``executor``: anything with
    ``map_unordered(fn, jobs)`` (``executors.py``: local processes, Ray);
    default local processes (``workers``).
    """
    from tqdm import tqdm

    store = _checked_store(config, out_dir)
    lock_on = store.lock_target()
    # One run per output at a time (a second is refused, naming the lock); a remote
    # store cannot be locked and relies on per-writer temporaries and records.
    with output_lock(lock_on, "dataset") if lock_on is not None else contextlib.nullcontext():
        return _generate_locked(config, store, workers, progress, executor, log, tqdm, locked=lock_on is not None)


def _checked_store(config: GeneratorConfig, out_dir) -> DatasetStore:
    """The store of ``out_dir`` after the checks that must pass before anything is written."""
    if out_dir is None or not str(out_dir).strip():
        raise UsageError(f"output folder (--out) is empty ({out_dir!r}): give the dataset directory or an fsspec URL")
    if not isinstance(config.seed, (int, np.integer)) or config.seed < 0:
        raise UsageError(f"seed must be a non-negative integer, got {config.seed!r}")
    store = DatasetStore(out_dir)
    if store.local is not None:
        path = store.local
        if path.exists() and not path.is_dir():
            raise OutputPathError(f"--out {path} exists and is not a directory")
        parent = next((p for p in [path, *path.parents] if p.exists()), Path("."))
        if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
            raise OutputPathError(f"cannot write the dataset at {path}: {parent} is not a writable directory")
    return store


def _check_ours(store: DatasetStore, out_dir) -> None:
    """Refuse a non-empty folder that the generator did not start (e.g. an imported dataset): its
    generator.json must carry the generator's marker (a config hash), not merely exist."""
    if store.exists("generator.json"):
        try:
            doc = json.loads(store.read_text("generator.json"))
        except (OSError, ValueError):
            doc = None
        if not (isinstance(doc, dict) and isinstance(doc.get("config_hash"), str) and isinstance(doc.get("config"), dict)):
            refuse_foreign(out_dir, "generated dataset", "its generator.json lacks the generator's config_hash and config")
        return
    present = [e for e in store.entries() if not _is_temporary(e)]
    if present == ["instances"] and not [e for e in store.glob("instances/*") if not _is_temporary(e)]:
        return  # an earlier run stopped before writing generator.json
    if present:
        refuse_foreign(out_dir, "generated dataset",
                       f"it holds {', '.join(present[:5])}{' ...' if len(present) > 5 else ''} but no generator.json")


def _is_temporary(name: str) -> bool:
    """A temporary of an interrupted write: ``X.partial`` (older runs) or ``X.partial.<pid>.<hex>``."""
    name = name.rsplit("/", 1)[-1]
    return name.endswith(".partial") or ".partial." in name


def _generate_locked(config, store, workers, progress, executor, log, tqdm, locked: bool):
    out_dir = store.location
    _check_ours(store, out_dir)
    chash = config.config_hash()
    config_json = json.dumps(config.to_dict(), sort_keys=True)

    # One directory holds one configuration: refuse to mix.
    if store.exists("generator.json"):
        try:
            old = json.loads(store.read_text("generator.json")).get("config_hash")
        except json.JSONDecodeError:
            old = None
        if old != chash:
            raise DatasetError(f"{out_dir} holds a dataset of another configuration (hash {old}, this one {chash}); "
                               "choose another --out or delete it")
    else:
        store.makedirs()
        store.write_text("generator.json", json.dumps({"config_hash": chash, "config": config.to_dict()},
                                                      indent=1, sort_keys=True))
    store.makedirs("instances")

    # Under the lock no other run writes here, so every temporary is a dead run's
    # (a remote store has none: its writes go whole, committed by their record).
    for stale in [p for p in store.glob("instances/*") + store.glob("*") if locked and _is_temporary(p)]:
        log(f"removing {stale.rsplit('/', 1)[-1]}: an unfinished write from an interrupted run")
        store.remove(stale)

    names = [instance_name(i) for i in range(config.n_instances)]
    records: dict[int, dict] = {}
    todo = []
    for i, name in enumerate(names):
        rec, why = _finished_record(store, name, chash)
        if rec is not None:
            records[i] = rec
        else:
            todo.append(i)
            if why:
                log(f"regenerating {name}: {why}")
    if todo and store.exists("manifest.json"):
        store.remove("manifest.json")  # no longer describes complete data

    ex = executor or make_executor(workers)
    bar = tqdm(total=config.n_instances, initial=len(records), desc=f"generate {config.scenario}/{config.size}",
               unit="inst", disable=not progress)
    try:
        for rec in ex.map_unordered(_instance_job, [(config_json, i, store.location) for i in todo]):
            records[rec["index"]] = rec
            bar.update(1)
    finally:
        bar.close()

    ordered = [records[i] for i in range(config.n_instances)]
    store.write_text("manifest.json", manifest_text({
        # The size under the key the config stores it by (generator_config.GeneratorConfig.to_dict: hashes stay).
        "robot": config.robot, "scenario": config.scenario, "profile": config.size, "seed": config.seed,
        "record_hz": config.record_hz, "dt": config.dt, "generator_version": GENERATOR_VERSION,
        "config": config.to_dict(), "config_hash": chash,
        "fields": {k: FIELD_UNITS[k] for k in FIELDS},
        "packages": package_versions(),
        "n_samples": int(sum(r["n_samples"] for r in ordered)),
        "instances": ordered,
        "splits": split_by_instance(names, config.seed),
        "tracking_error": _tracking_summary(ordered),
    }))
    return store.local if store.local is not None else store.location
