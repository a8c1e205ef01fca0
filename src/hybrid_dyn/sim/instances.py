"""One instance of a dataset: its seeds, its random reference and pulses, its simulation, and the
executor job that writes it and its completion record; and the check that a finished one is intact.

Apart from the dataset writer (``generator.py``) because this is what runs on a worker (a local
process or a Ray node): a job needs only a config, an index and the store's location, so its bytes
depend on (seed, index) alone, while the writer decides which instances to (re)make.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np

from ..data.dataset import write_instance
from ..data.store import DatasetStore
from .pulses import BellPulses, sample_contact_steps, sample_pulses, sample_start_touch
from .generator_config import GeneratorConfig
from .simulator import SimulatedRun, Simulator
from .trajectories import random_reference


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
    # The start-up touch draws after both (the scenarios without one keep their draws).
    touch = sample_start_touch(rng_pulse, cfg.start_touch) if cfg.start_touch is not None else None
    force = None
    for source in (pulses, contacts, touch):
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
    if touch is not None:
        info["start_touch"] = touch.to_dict()
        info["n_pulses_in_instance"] += len(touch)
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
    for key in ("contact_steps", "start_touch"):
        if key in info:
            attrs[key] = json.dumps(info[key])
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
