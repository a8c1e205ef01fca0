"""Tiny synthetic datasets in the toolkit's format, for tests and examples.

The fields obey exact rigid-body physics on a :class:`Robot` (Pinocchio), with
optional Gaz friction, tip-force bells and white sensor noise, but no controller
or plant simulation: sinusoidal joint trajectories are prescribed and torques
and wrenches computed from them. Small, fast, and with a known ground truth.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .dataset import FIELD_UNITS, package_versions, split_by_instance, write_instance, write_manifest


def make_synthetic_dataset(path, robot, n_instances: int = 6, n_samples: int = 200, record_hz: float = 100.0,
                           seed: int = 0, friction=None, tip_forces: bool = True, noise: float = 0.0,
                           base_offset: float = 0.0, contact_free_s: float = 0.0) -> Path:
    """Write a dataset of ``n_instances`` sinusoidal runs to ``path`` and return it.

    base_offset: bound [N] of a per-instance base-sensor force offset, uniform
    per axis (a tenth of it in Nm on the moments), added to the measured wrench
    only, from a generator of its own: the same seed with and without an offset gives
    the same runs, the offset aside. contact_free_s: no tip force on [0, contact_free_s) [s]; the bell is centred
    3 sigma or more after it.
    """
    path = Path(path)
    rng = np.random.default_rng(seed)
    offset_rng = np.random.default_rng([seed, 1])
    nv = robot.nv
    lo = np.maximum(robot.q_lower, -np.pi) + 0.2
    hi = np.minimum(robot.q_upper, np.pi) - 0.2
    dt = 1.0 / record_hz
    t = np.arange(n_samples) * dt
    records = []
    for k in range(n_instances):
        centre = rng.uniform(lo, hi)
        amp = np.minimum(0.5 * (hi - lo), 0.6) * rng.uniform(0.3, 1.0, nv)
        amp = np.minimum(amp, np.minimum(centre - lo, hi - centre))
        freq = rng.uniform(0.1, 0.5, nv)
        phase = rng.uniform(0, 2 * np.pi, nv)
        w = 2 * np.pi * freq
        q = centre + amp * np.sin(w * t[:, None] + phase)
        qd = amp * w * np.cos(w * t[:, None] + phase)
        qdd = -amp * w**2 * np.sin(w * t[:, None] + phase)
        f = np.zeros((n_samples, 3))
        if tip_forces:
            sigma = 0.1 * t[-1]
            earliest = contact_free_s + 3 * sigma if contact_free_s > 0 else 0.2 * t[-1]
            centre_t = rng.uniform(earliest, 0.8 * t[-1])
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            f = rng.uniform(5, 20) * np.exp(-((t - centre_t) ** 2) / (2 * sigma**2))[:, None] * direction
            f[t < contact_free_s] = 0.0  # the bell's far tail (< 1 % of its peak) cut: truly contact-free
        jv = robot.tip_jacobian(q)[:, :3]
        tau_J = robot.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", jv, f)
        tau_m = tau_J + (friction(qd) if friction is not None else 0.0)
        wrench = robot.base_wrench(q, qd, qdd, tip_force=f)
        truth = {"t": t, "q": q, "qd": qd, "qdd": qdd, "tau_m": tau_m, "tau_J": tau_J, "base_wrench": wrench, "tip_force": f}
        fields = {k: (v + noise * rng.normal(size=v.shape) if (noise and k != "t") else v) for k, v in truth.items()}
        if base_offset:
            fields["base_wrench"] = fields["base_wrench"] + offset_rng.uniform(-1, 1, 6) * base_offset * np.repeat([1.0, 0.1], 3)
        name = f"inst_{k:05d}"
        sha = write_instance(path / "instances" / f"{name}.h5", fields, truth)
        records.append({"name": name, "file": f"instances/{name}.h5", "sha256": sha, "n_samples": n_samples})
    splits = split_by_instance([r["name"] for r in records], seed)
    write_manifest(path, {
        "robot": robot.name, "scenario": "synthetic", "seed": seed, "record_hz": record_hz,
        "config": {"generator": "synthetic", "n_instances": n_instances, "n_samples": n_samples, "noise": noise,
                   "friction": friction is not None, "tip_forces": tip_forces},
        "fields": {k: FIELD_UNITS[k] for k in truth}, "packages": package_versions(),
        "instances": records, "splits": splits,
    })
    return path
