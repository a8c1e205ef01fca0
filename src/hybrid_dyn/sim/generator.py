"""The dataset generator: a torque-controlled arm in DART, with sensors.

One instance (PROTOCOL 3) is simulated at ``1/dt`` (1 kHz):

1. reference: standstill, then 5-50 random trajectories (``trajectories.py``);
2. controller, every step: computed torque on the NOMINAL model plus PD, one
   RNEA call ``tau_m = RNEA_nom(q_m, qd_m, qdd_ref + Kp e + Kd e_dot)`` on the
   measured (noisy) state; friction is not compensated;
3. plant, every step: DART, with joint force ``tau_m - tau_f(qd)`` (the Gaz
   friction law at the true velocity) and, in ``*-ext`` scenarios, the bell
   pulses at the tool point;
4. sensors at ``record_hz``: see :func:`simulate_reference`.

Every recorded sample k is the state *before* integration step k together with
what DART computed in that step: its acceleration and the ground reaction on
the base. So ``truth`` is one consistent rigid-body state per sample, which the
tests check against the analytic model.

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..analytic.robot import InputError
from ..data.dataset import (
    FIELD_UNITS, DatasetError, manifest_text, package_versions, read_manifest, split_by_instance, write_instance,
)
from ..data.store import DatasetStore
from ..errors import OutputPathError, UsageError
from ..outputs import output_lock, refuse_foreign
from .collision import collision_checker
from .executors import make_executor
from .plant import DartPlant
from .pulses import BellPulses, sample_contact_steps, sample_pulses
from .scenarios import GENERATOR_VERSION, GeneratorConfig
from .sensors import causal_acceleration
from .trajectories import random_reference

FIELDS = ("t", "q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force")


@dataclass
class SimulatedRun:
    """One simulated run: measured ``fields``, noise-free ``truth`` (same names), ``attrs``."""

    fields: dict
    truth: dict
    attrs: dict

    @property
    def n_samples(self) -> int:
        return len(self.fields["t"])


class _FastGaz:
    """The Gaz law rewritten with tanh for the 1 kHz loop (a few ufuncs, no temporaries kept).

    phi1 sigmoid(x) = phi1/2 (1 + tanh(x/2)), so
    tau_f = phi1/2 tanh(phi2/2 (qd + phi3)) + phi1/2 - phi1 sigmoid(phi2 phi3).
    """

    def __init__(self, law):
        self.half_phi1 = 0.5 * law.phi1
        self.half_phi2 = 0.5 * law.phi2
        self.phi3 = law.phi3
        self.offset = self.half_phi1 - law.phi1 / (1.0 + np.exp(-law.phi2 * law.phi3))

    def __call__(self, qd):
        return self.half_phi1 * np.tanh(self.half_phi2 * (qd + self.phi3)) + self.offset


class Simulator:
    """Plant, controller and sensors of a :class:`GeneratorConfig`; reusable across runs."""

    def __init__(self, config: GeneratorConfig):
        self.config = config
        self.nominal = config.nominal_robot()
        self.plant_robot = config.plant_robot()
        if self.plant_robot.joint_names != self.nominal.joint_names:
            raise ValueError("plant and nominal robot have different joints")
        self.nv = self.nominal.nv
        law = self.plant_robot.spec.friction(config.friction) if config.friction else None
        if config.friction and law is None:
            raise ValueError(f"robot {config.robot!r} has no friction law {config.friction!r}")
        self.friction_law = law
        self._friction = _FastGaz(law) if law is not None else None
        self.checker = collision_checker(self.nominal, config.collision_check)

    # ----------------------------------------------------------------- plant
    def _make_plant(self) -> DartPlant:
        """A fresh DART world per run: no solver state carries over between instances."""
        plant = DartPlant(self.plant_robot, self.config.dt)
        cfg = self.config
        for i, name in enumerate(self.plant_robot.joint_names):
            dof = plant.skel.getDof(name)
            if cfg.dart_coulomb is not None:
                dof.setCoulombFriction(float(cfg.dart_coulomb[i]))
            if cfg.dart_viscous is not None:
                dof.setDampingCoefficient(float(cfg.dart_viscous[i]))
        return plant

    # -------------------------------------------------------------- the loop
    def run(self, q_ref, qd_ref, qdd_ref, tip_force=None, rng: np.random.Generator | None = None) -> SimulatedRun:
        """Track a reference sampled every ``dt``; see :func:`simulate_reference`."""
        cfg, nv = self.config, self.nv
        q_ref, _ = _check(q_ref, "q_ref", nv)
        qd_ref, _ = _check(qd_ref, "qd_ref", nv)
        qdd_ref, _ = _check(qdd_ref, "qdd_ref", nv)
        T = len(q_ref)
        if not (len(qd_ref) == len(qdd_ref) == T) or T < 2:
            raise InputError(f"q_ref, qd_ref, qdd_ref need the same length >= 2, got {len(q_ref)}, {len(qd_ref)}, {len(qdd_ref)}")
        if tip_force is not None:
            tip_force, _ = _check(tip_force, "tip_force", 3)
            if len(tip_force) != T:
                raise InputError(f"tip_force has {len(tip_force)} samples, the reference {T}")
        rng = rng if rng is not None else np.random.default_rng(0)
        noise = cfg.noise
        # q and qd noise at the control rate: the controller sees it too.
        n_q = noise.q * rng.standard_normal((T, nv))
        n_qd = noise.qd * rng.standard_normal((T, nv))

        plant = self._make_plant()
        skel, world, tool = plant.skel, plant.world, plant.tool
        perm = plant.dof_index
        identity = bool(np.array_equal(perm, np.arange(nv)))
        inv = np.argsort(perm)
        plant.set_state(q_ref[0], qd_ref[0])
        skel.clearExternalForces()

        dec = cfg.decimation
        rec = np.arange(0, T, dec)
        Q, QD = np.empty((T, nv)), np.empty((T, nv))
        TAU, TF = np.empty((T, nv)), np.zeros((T, nv))
        QDD_rec, W_rec = np.empty((len(rec), nv)), np.empty((len(rec), 6))
        model, data, rnea = self.nominal.model, self.nominal.data, pin.rnea
        kp, kd = cfg.kp, cfg.kd
        # a = qdd_ref + kp (q_ref - q_m) + kd (qd_ref - qd_m) with q_m = q + n_q: the
        # reference and noise parts are known in advance.
        a_pre = qdd_ref + kp * (q_ref - n_q) + kd * (qd_ref - n_qd)
        friction = self._friction
        zero3 = np.zeros(3)
        r = 0
        for k in range(T):
            q = skel.getPositions()
            qd = skel.getVelocities()
            if not identity:
                q, qd = q[perm], qd[perm]
            Q[k] = q
            QD[k] = qd
            tau = rnea(model, data, q + n_q[k], qd + n_qd[k], a_pre[k] - kp * q - kd * qd)
            TAU[k] = tau
            if friction is not None:
                tf = friction(qd)
                TF[k] = tf
                tau = tau - tf
            if tip_force is not None:
                tool.addExtForce(tip_force[k], zero3, False, True)
            skel.setForces(tau if identity else tau[inv])
            world.step()  # forward dynamics at (q, qd), then semi-implicit Euler
            if k % dec == 0:
                acc = skel.getAccelerations()
                QDD_rec[r] = acc if identity else acc[perm]
                W_rec[r] = plant.base_wrench()
                r += 1
        return self._sensors(rec, q_ref, Q, QD, TAU, TF, QDD_rec, W_rec, tip_force, n_q, n_qd, rng)

    def _sensors(self, rec, q_ref, Q, QD, TAU, TF, QDD_rec, W_rec, tip_force, n_q, n_qd, rng) -> SimulatedRun:
        cfg, noise, nv = self.config, self.config.noise, self.nv
        R = len(rec)
        f_tip = tip_force[rec] if tip_force is not None else np.zeros((R, 3))
        if cfg.dart_coulomb is None and cfg.dart_viscous is None:
            tau_J = TAU[rec] - TF[rec]  # exactly the joint force DART received
        else:
            # DART's own stiction/damping acts inside the joints and is not reported
            # per step; the link-side torque is then what the motion required.
            jv = self.plant_robot.tip_jacobian(Q[rec])[:, :3]
            tau_J = self.plant_robot.inverse_dynamics(Q[rec], QD[rec], QDD_rec) - np.einsum("nij,ni->nj", jv, f_tip)
        truth = {
            "t": rec * cfg.dt, "q": Q[rec], "qd": QD[rec], "qdd": QDD_rec, "tau_m": TAU[rec],
            "tau_J": tau_J, "base_wrench": W_rec, "tip_force": f_tip,
        }
        qd_meas_fast = QD + n_qd
        if cfg.qdd_source == "exact":
            qdd = QDD_rec  # the seed's simulated data: the simulator's acceleration at the recorded step
        else:
            qdd = causal_acceleration(qd_meas_fast, cfg.dt, cfg.qdd_cutoff_hz)[rec]
        bias = np.concatenate([rng.uniform(-1, 1, 3) * noise.force_bias, rng.uniform(-1, 1, 3) * noise.torque_bias])
        w_std = np.array([noise.force] * 3 + [noise.torque] * 3)
        fields = {
            "t": truth["t"],
            "q": Q[rec] + n_q[rec],
            "qd": qd_meas_fast[rec],
            "qdd": qdd,
            "tau_m": TAU[rec],
            "tau_J": tau_J + noise.tau_J * rng.standard_normal((R, nv)),
            "base_wrench": W_rec + bias + w_std * rng.standard_normal((R, 6)),
            "tip_force": f_tip,
        }
        err = q_ref - Q
        attrs = {
            "tracking_rms": np.sqrt(np.mean(err**2, axis=0)),  # rad, per joint, at the control rate
            "tracking_max": np.max(np.abs(err), axis=0),      # rad
            "base_wrench_bias": bias,
            "duration_s": float(len(Q) * cfg.dt),
        }
        return SimulatedRun(fields, truth, attrs)


def _check(x, name, width):
    from ..analytic.robot import as_batch

    return as_batch(x, name, width)


def simulate_reference(config: GeneratorConfig, t, q_ref, qd_ref, qdd_ref, seed: int = 0, tip_force=None,
                       simulator: Simulator | None = None) -> SimulatedRun:
    """Run the plant, controller and sensors of ``config`` on a given reference.

    t [s] (T,) must be uniform at the simulation period ``config.dt``; q_ref
    [rad], qd_ref [rad/s], qdd_ref [rad/s^2] are (T, nv); tip_force [N] (T, 3)
    optional, in the base frame at the tool point. The arm starts on the
    reference at rest. Returns fields at ``config.record_hz``:

    - ``q``, ``qd``: true state plus white noise (``config.noise``);
    - ``qdd``: causal estimate from the measured qd (``sensors.py``), never DART's,
      unless ``config.qdd_source == "exact"`` (``seed-sim``): then DART's acceleration;
    - ``tau_m``: the commanded motor torque (friction included, noise-free: it is
      what the controller sent); ``tau_J = tau_m - tau_f`` link side, plus noise;
    - ``base_wrench``: ground reaction in the plant's (possibly tilted) sensor
      frame plus a per-instance bias and white noise;
    - ``tip_force``: the applied force (ground truth);

    and ``truth`` the noise-free copies (qdd: DART's acceleration).
    """
    sim = simulator or Simulator(config)
    t = np.asarray(t, float)
    if t.ndim != 1 or len(t) < 2 or not np.allclose(np.diff(t), config.dt, rtol=0, atol=1e-9):
        raise InputError(f"t must be uniformly sampled every config.dt = {config.dt} s")
    run = sim.run(q_ref, qd_ref, qdd_ref, tip_force, np.random.default_rng(np.random.SeedSequence([seed, 0x7E5])))
    run.fields["t"] = run.truth["t"] = run.truth["t"] + t[0]
    return run


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
