"""The dataset generator: a torque-controlled arm in DART, with sensors.

The instances and the dataset writer: which instances to (re)make, each one's job on an executor,
and the manifest. One run is simulated in ``simulator.py`` (plant, controller, sensors: PROTOCOL 3).

Parallelism and restarts: each instance is a job for an executor (local
processes or a Ray cluster, ``executors.py``); it writes ``instances/<name>.h5``
to the dataset's store (a local directory or an fsspec URL, ``data/store.py``)
and then a small ``<name>.json`` completion record. A restart skips instances whose record and checksum agree and
regenerates (and names) missing, partial or corrupt ones; the manifest comes
last. Per-instance seeds derive from (seed, index) alone, so the bytes do not
depend on the worker count or on the order in which jobs finish.

Concurrent runs: a run holds ``outputs.output_lock`` on a local output for its
whole length, so a second run into the same folder is refused at once. Each
file is written under a temporary name unique to its writer and hashed before
the atomic rename, so a record only ever vouches for bytes its own job wrote
(this also holds for Ray workers on a shared folder, which the lock of the
driver does not cover). A folder is only written into if it is empty or was
started by the generator (its ``generator.json``).
"""
from __future__ import annotations

import contextlib
import functools
import json
import os
import sys
from pathlib import Path

import numpy as np

from ..data.dataset import (
    FIELD_UNITS, DatasetError, manifest_text, package_versions, read_manifest, split_by_instance, write_instance,
)
from ..data.store import DatasetStore
from ..errors import OutputPathError, UsageError
from ..outputs import output_lock, refuse_foreign
from .executors import make_executor
from .pulses import BellPulses, sample_contact_steps, sample_pulses
from .scenarios import GENERATOR_VERSION, GeneratorConfig
from .simulator import FIELDS, SimulatedRun, Simulator
from .simulator import simulate_reference  # noqa: F401  (re-exported: imported from here)
from .trajectories import random_reference


# ------------------------------------------------------------------ instances
def instance_name(index: int) -> str:
    return f"inst_{index:05d}"


def instance_rngs(seed: int, index: int):
    """Independent generators for (trajectories, pulses, noise) of one instance."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence([seed, index]).spawn(3)]


def simulate_instance(sim: Simulator, index: int) -> tuple[SimulatedRun, dict]:
    """Instance ``index`` of a config: random reference, pulses, simulation."""
    cfg = sim.config
    rng_traj, rng_pulse, rng_noise = instance_rngs(cfg.seed, index)
    n_traj = int(rng_traj.integers(cfg.trajectories[0], cfg.trajectories[1] + 1))
    ref = random_reference(sim.nominal, rng_traj, n_traj, dt=cfg.dt, speed_scale=cfg.speed_scale,
                           margin=cfg.joint_margin, standstill=cfg.standstill, is_valid=sim.checker)
    pulses: BellPulses | None = sample_pulses(rng_pulse, cfg.pulses) if cfg.pulses is not None else None
    # Contacts draw from the pulse stream after the bells (a config has one or the other in the scenarios).
    contacts = sample_contact_steps(rng_pulse, cfg.contact_steps, cfg.dt) if cfg.contact_steps is not None else None
    force = None
    for source in (pulses, contacts):
        if source is not None:
            force = source.force(ref.t) if force is None else force + source.force(ref.t)
    run = sim.run(ref.q, ref.qd, ref.qdd, force, rng_noise)
    duration = len(ref) * cfg.dt
    info = {
        "n_trajectories": n_traj,
        "pulses": pulses.to_dict() if pulses is not None else None,
        "n_pulses_in_instance": int(np.sum(pulses.centre < duration)) if pulses is not None else 0,
    }
    if contacts is not None:
        info["contact_steps"] = contacts.to_dict()
        info["n_pulses_in_instance"] += int(np.sum(contacts.start < duration))
    return run, info


@functools.lru_cache(maxsize=2)
def _simulator_for(config_json: str) -> Simulator:
    """One Simulator per config and process (robots and collision model load once)."""
    return Simulator(GeneratorConfig.from_dict(json.loads(config_json)))


def _instance_job(config_json: str, index: int, out_location: str) -> dict:
    """Executor job: simulate one instance, write it to the store, then its completion record.

    Runs wherever the executor puts it (a local process, a Ray worker on
    another machine): it opens the store from its location string.
    """
    sim = _simulator_for(config_json)
    cfg = sim.config
    run, info = simulate_instance(sim, index)
    name = instance_name(index)
    attrs = {
        "name": name, "index": index, "scenario": cfg.scenario, "config_hash": cfg.config_hash(),
        "n_trajectories": info["n_trajectories"], "n_pulses_in_instance": info["n_pulses_in_instance"],
        "pulses": json.dumps(info["pulses"]), **run.attrs,
    }
    if "contact_steps" in info:
        attrs["contact_steps"] = json.dumps(info["contact_steps"])
    store = DatasetStore(out_location)
    rel = f"instances/{name}.h5"
    if store.local is not None:
        sha = write_instance(store.local_path(rel), run.fields, run.truth, attrs)
    else:  # h5py needs a seekable local file: write it whole, then upload the same bytes
        with store.scratch_dir() as scratch:
            local = Path(scratch) / f"{name}.h5"
            sha = write_instance(local, run.fields, run.truth, attrs)
            store.put_file(local, rel)
    record = {
        "name": name, "index": index, "file": rel, "sha256": sha, "n_samples": run.n_samples,
        "config_hash": cfg.config_hash(), "n_trajectories": info["n_trajectories"],
        "n_pulses_in_instance": info["n_pulses_in_instance"], "duration_s": run.attrs["duration_s"],
        "tracking_rms": [round(float(x), 9) for x in run.attrs["tracking_rms"]],
        "tracking_max": [round(float(x), 9) for x in run.attrs["tracking_max"]],
    }
    store.write_text(f"instances/{name}.json", json.dumps(record, indent=1, sort_keys=True))  # the commit
    return record


def _readable(path: Path) -> bool:
    """True when every dataset of an HDF5 instance decompresses: a checksum only proves the
    bytes are those recorded, and a record made before the per-run temporaries may vouch for
    a file two runs wrote over each other."""
    import h5py

    def read(_, obj):  # returns None: a value would stop visititems
        if isinstance(obj, h5py.Dataset):
            obj[()]

    try:
        with h5py.File(path, "r") as f:
            f.visititems(read)
        return True
    except (OSError, ValueError, RuntimeError, KeyError):
        return False


def _finished_record(store: DatasetStore, name: str, config_hash: str) -> tuple[dict | None, str | None]:
    """(record, None) for a verified finished instance, else (None, why it must be regenerated or None if never started)."""
    h5, rec_path = f"instances/{name}.h5", f"instances/{name}.json"
    if not store.exists(rec_path):
        return None, ("file present without a completion record (interrupted or partial)" if store.exists(h5) else None)
    try:
        rec = json.loads(store.read_text(rec_path))
    except (json.JSONDecodeError, OSError):
        return None, "completion record is corrupt"
    if rec.get("config_hash") != config_hash:
        return None, "made with another configuration"
    if not store.exists(h5):
        return None, "file is missing"
    if store.sha256(h5) != rec.get("sha256"):
        return None, "file does not match its checksum (corrupt or partial)"
    if store.local is not None and not _readable(store.local_path(h5)):
        return None, "file matches its checksum but does not read (corrupt HDF5)"
    return rec, None


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


# What the generator writes at a dataset's top level; a folder holding anything else
# before generator.json exists is not one of its datasets.
_OWN_ENTRIES = ("generator.json", "manifest.json", "instances")


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
        # The size under the key the config stores it by (scenarios.GeneratorConfig.to_dict: hashes stay).
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


def verify_dataset_config(out_dir, config: GeneratorConfig) -> bool:
    """True when ``out_dir`` holds a finished dataset of exactly ``config``."""
    try:
        return read_manifest(Path(out_dir)).get("config_hash") == config.config_hash()
    except DatasetError:
        return False
