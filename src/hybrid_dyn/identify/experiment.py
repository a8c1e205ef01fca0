"""Identification experiments: an excitation trajectory run on the simulated plant.

The plant, controller and sensors are the dataset generator's
(:func:`hybrid_dyn.sim.simulator.simulate_reference`), so identification sees the
same kind of data as every other model: commanded motor torques, noisy q and qd,
a causal qdd estimate. No external force acts during identification (an
identification run is done free of contact); the config's pulses are ignored.
The runs are written as a dataset in the toolkit's format, which
``hybrid-dyn identify --data DIR`` reads.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from scipy import signal

from ..data.dataset import FIELD_UNITS, package_versions, write_instance, write_manifest
from .excitation import FourierTrajectory


def excitation_reference(traj: FourierTrajectory, periods: float, dt: float):
    """(t, q, qd, qdd) sampled every dt [s] over ``periods`` periods of ``traj``."""
    t = np.arange(int(round(periods * traj.period / dt)) + 1) * dt
    return (t, *traj.evaluate(t))


def record_excitation_dataset(path, config, traj: FourierTrajectory, n_instances: int = 2, periods: float = 2.0,
                              seed: int = 0, progress: bool = True) -> Path:
    """Simulate ``n_instances`` runs of ``traj`` (independent sensor noise) and write a dataset.

    config: a :class:`~hybrid_dyn.sim.generator_config.GeneratorConfig` (plant, controller,
    noise); its pulses are switched off. All runs go to the ``train`` split: an
    identification set is fitted whole and validated on other data.
    """
    from tqdm import tqdm

    from ..sim.simulator import Simulator, simulate_reference

    config = dataclasses.replace(config, pulses=None)
    path = Path(path)
    sim = Simulator(config)
    t, q, qd, qdd = excitation_reference(traj, periods, config.dt)
    records = []
    for k in tqdm(range(n_instances), desc="excitation runs", disable=not progress):
        run = simulate_reference(config, t, q, qd, qdd, seed=seed + k, simulator=sim)
        name = f"excite_{k:05d}"
        sha = write_instance(path / "instances" / f"{name}.h5", run.fields, run.truth)
        records.append({"name": name, "file": f"instances/{name}.h5", "sha256": sha, "n_samples": run.n_samples})
    write_manifest(path, {
        "robot": config.robot, "scenario": f"{config.scenario}/identification", "seed": seed,
        "record_hz": config.record_hz,
        "config": {"generator": config.to_dict(), "excitation": traj.to_dict(), "periods": periods},
        "fields": {k: FIELD_UNITS[k] for k in run.fields}, "packages": package_versions(),
        "instances": records, "splits": {"train": [r["name"] for r in records], "val": [], "test": []},
    })
    return path


def zero_phase_acceleration(qd: np.ndarray, dt: float, cutoff_hz: float = 15.0) -> np.ndarray:
    """qdd [rad/s^2] (T, nv) from qd [rad/s] (T, nv): central difference, then a zero-phase low-pass.

    Offline identification may look ahead: filtering forward and backward
    (``filtfilt``) removes the delay that the causal estimate of a live robot has,
    which would otherwise bias the inertial parameters.
    """
    qd = np.asarray(qd, float)
    qdd = np.gradient(qd, dt, axis=0)
    nyq = 0.5 / dt
    if cutoff_hz >= nyq:
        return qdd
    b, a = signal.butter(2, cutoff_hz, fs=1.0 / dt)
    return signal.filtfilt(b, a, qdd, axis=0)
