"""The analytic part of a residual (hybrid) model: computed, cached, never trained.

The design in full: ``docs/design/learn.md`` (priors.py).
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import h5py
import numpy as np
import pinocchio as pin

from ..analytic.methods import TIP_FORCE_METHODS, estimator_name
from ..analytic.tare import tare_samples, tared_base_wrench
from ..analytic.tip_force import base_wrench_force_core, contact_joint_torques, tip_force_from_base_wrench
from ..analytic.torque_models import TORQUE_MODELS
from .presets import prior_fingerprint_spelling

# The fields each prior reads: the two torque models here, every tip-force method registered as a prior
# from its one definition (analytic/methods.py; base-momentum reads qdd only for the tare).
PRIOR_FIELDS = {m.name: m.fields for m in TORQUE_MODELS.values()}


def _on_register(method) -> None:
    if method.residual_prior:
        PRIOR_FIELDS[method.name] = method.fields


def _on_unregister(method) -> None:
    PRIOR_FIELDS.pop(method.name, None)


for _method in TIP_FORCE_METHODS.values():
    _on_register(_method)
TIP_FORCE_METHODS.listen(_on_register, _on_unregister)


class AnalyticPrior:
    """One analytic model, evaluated on instances or on a single sample.

    kind: the prior's estimator, a key of :data:`PRIOR_FIELDS` (or an older spelling of one). robot: the
    nominal :class:`Robot`.
    record_hz: the dataset's sample rate (the momentum observer's dt is 1/record_hz).
    observer_gain: the prior method's bandwidth, in its parameter's unit (a momentum observer's K [1/s]).
    tare_seconds: base-wrench priors only: the contact-free start of each
    instance used to tare the base sensor [s]; 0 = no tare.
    friction: the joint friction added to the torque priors (``rnea``,
    ``rnea-bw``), as a parameter file's ``friction`` section (dict) or None;
    ``"auto"``: the friction of the robot's parameter set when that is an identified
    file, else none (module docstring). A loaded model passes what its config holds.
    """

    def __init__(self, kind: str, robot, record_hz: float | None = None, observer_gain: float = 20.0,
                 tare_seconds: float = 0.0, friction: dict | str | None = "auto"):
        kind = estimator_name(kind, among=PRIOR_FIELDS, what="analytic prior")
        if kind in TIP_FORCE_METHODS and TIP_FORCE_METHODS[kind].stateful and not record_hz:  # a filter's dt
            raise ValueError(f"the {kind} prior needs the dataset's record_hz")
        self.tare_seconds = float(tare_seconds) if "base_wrench" in PRIOR_FIELDS[kind] else 0.0
        if self.tare_seconds > 0 and not record_hz:
            raise ValueError("a tared base-wrench prior needs the dataset's record_hz")
        self.kind = kind
        self.robot = robot
        self.record_hz = record_hz
        self.observer_gain = float(observer_gain)
        self.fields = PRIOR_FIELDS[kind]
        self._single = None
        from ..identify.identified_model import friction_from_dict, read_identified_file, springs_from_dict

        identified = None if str(robot.params_name) in robot.spec.param_sets else read_identified_file(robot.params_name)
        # The identified file's digest: its inertials are in the prior's values, and the path alone
        # would let a file rewritten in place serve a stale cache or a mismatched loaded model.
        self.params_sha256 = identified[1] if identified else None
        if isinstance(friction, str) and friction == "auto":
            friction = identified[0]["friction"] if identified and kind in TORQUE_MODELS else None
        if friction is not None and kind not in TORQUE_MODELS:  # a torque model: rigid body + friction
            raise ValueError(f"the {kind} prior takes no joint friction (only {', '.join(TORQUE_MODELS)} do)")
        if friction is not None and not isinstance(friction, dict):
            raise ValueError(f"friction must be a parameter file's friction section (dict), 'auto' or None, "
                             f"got {friction!r}")
        self.friction = friction
        self._friction = friction_from_dict(friction, f"the {kind} prior's friction") if friction else None
        # The identified file's declared springs (Baxter's shoulder), joint-local like its friction.
        self.springs = springs_from_dict(identified[0], robot.joint_names, str(robot.params_name)) \
            if identified and kind in TORQUE_MODELS else {}

    def describe(self) -> dict:
        """What identifies this prior's values (the model config; the cache key hashes it with the kind's
        fingerprint spelling, :meth:`cache_path`)."""
        return {"kind": self.kind, "robot": self.robot.name, "params": self.robot.params_name,
                "payload": repr(self.robot.payload), "sensor_mount": repr(self.robot.sensor_mount),
                "record_hz": self.record_hz, "observer_gain": self.observer_gain,
                "tare_seconds": self.tare_seconds,
                # Only where present, so that no cache key or config of a nominal prior moves.
                **({"params_sha256": self.params_sha256} if self.params_sha256 else {}),
                **({"friction": self.friction} if self.friction else {}),
                **({"springs": self.springs} if self.springs else {})}

    def friction_torque(self, qd) -> np.ndarray | float:
        """The prior's joint friction [Nm] at qd [rad/s] ((nv,) or (N, nv)); 0.0 without one."""
        return 0.0 if self._friction is None else self._friction(np.asarray(qd, float))

    def joint_terms(self, q, qd) -> np.ndarray | float:
        """Everything joint-local the prior adds to the rigid body [Nm]: friction at qd and the declared
        springs at q (``identify/extra_terms.py``); 0.0 without either."""
        from ..identify.identified_model import spring_torque

        return self.friction_torque(qd) + spring_torque(self.springs, self.robot.joint_names, q)

    # ------------------------------------------------------------ evaluation
    def compute(self, fields: dict) -> np.ndarray:
        """The prior over one instance: fields name -> (T, k) arrays; returns (T, n_out)."""
        r = self.robot
        q, qd = fields["q"], fields["qd"]
        qdd = fields.get("qdd")
        if self.kind == "rnea":
            return np.atleast_2d(r.inverse_dynamics(q, qd, qdd) + self.joint_terms(q, qd))
        w = fields.get("base_wrench")
        n_tare = tare_samples(self.record_hz, self.tare_seconds) if self.tare_seconds > 0 else 0
        if n_tare:
            w = tared_base_wrench(r, q, qd, qdd, w, n_tare)
        if self.kind in TIP_FORCE_METHODS:
            return self._method_run(TIP_FORCE_METHODS[self.kind], fields, w, n_tare)
        f_bw = np.atleast_2d(tip_force_from_base_wrench(r, q, qd, qdd, w))
        return np.atleast_2d(r.inverse_dynamics(q, qd, qdd) + self.joint_terms(q, qd)) \
            - contact_joint_torques(r, np.atleast_2d(q), f_bw)

    def _method_stream(self, method):
        """The method's stream at the data's rate with this prior's bandwidth (observer_gain)."""
        stream = method.make(self.robot, self.record_hz or 1.0)
        stream.configure(self.observer_gain)
        return stream

    def _method_run(self, method, fields: dict, w, n_tare: int) -> np.ndarray:
        """A registered method over one instance from its one definition: a filter starts after the tare
        window (0 there, so that no running offset lingers in it), a per-sample method runs throughout."""
        start = n_tare if method.stateful else 0
        cut = lambda x: None if x is None else np.asarray(x, float)[start:]  # noqa: E731
        out = np.zeros((len(fields["q"]), 3))
        if start < len(out):
            out[start:] = self._method_stream(method).batch(
                cut(fields["q"]), cut(fields["qd"]), cut(fields.get("qdd")), cut(w), cut(fields.get("tau_J")))
        return out

    def single(self, sample: dict) -> np.ndarray:
        """The prior at one sample (fields -> 1-D arrays); not for a stateful (filter) prior.

        A direct Pinocchio path for a control loop (no batching or validation
        overhead); it computes exactly what :meth:`compute` does (tested).
        A tared prior expects ``sample["base_wrench"]`` already tared.
        """
        if self.kind in TIP_FORCE_METHODS and TIP_FORCE_METHODS[self.kind].stateful:
            raise ValueError(f"the {self.kind} prior is a filter with state: pass its current estimate "
                             "(the observer's step_force) as `prior`")
        if self._single is None:
            self._single = _SingleSample(self.robot)
            if self.kind in TIP_FORCE_METHODS:
                self._single.stream = self._method_stream(TIP_FORCE_METHODS[self.kind])
        s = self._single
        q, qd, qdd = (np.asarray(sample[k], float) for k in ("q", "qd", "qdd"))
        if self.kind == "rnea":
            return pin.rnea(s.model, s.data, q, qd, qdd) + self.joint_terms(q, qd)
        if self.kind in TIP_FORCE_METHODS:
            get = lambda k: None if sample.get(k) is None else np.asarray(sample[k], float)  # noqa: E731
            return s.stream.step(q, qd, qdd, get("base_wrench"), get("tau_J"))
        f_bw = s.basewrench_force(q, qd, qdd, np.asarray(sample["base_wrench"], float))
        jv = pin.computeFrameJacobian(s.model, s.data, q, s.tool, pin.LOCAL_WORLD_ALIGNED)[:3]
        return pin.rnea(s.model, s.data, q, qd, qdd) + self.joint_terms(q, qd) - jv.T @ f_bw

    def cache_path(self, cache_dir, dataset_checksum: str) -> Path:
        """The cache file of this prior on a dataset: ``prior-<kind>-<key>.h5``, the key a digest of the
        dataset checksum and :meth:`describe` with the kind in its fingerprint spelling (the keys of every
        cache written before model format 3). A cache under the older file name (``prior-basewrench-<key>.h5``)
        is renamed to this one."""
        ident = {"dataset": dataset_checksum, **self.describe(), "kind": prior_fingerprint_spelling(self.kind)}
        key = hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:20]
        path = Path(cache_dir) / f"prior-{self.kind}-{key}.h5"
        older = Path(cache_dir) / f"prior-{prior_fingerprint_spelling(self.kind)}-{key}.h5"
        if older != path and older.is_file() and not path.exists():
            os.replace(older, path)  # the same values; the model folder's lock is held by its one training run
        return path

    def compute_instances(self, instances, cache_dir=None, dataset_checksum: str | None = None) -> list[np.ndarray]:
        """The prior for every instance; cached under ``cache_dir`` when a dataset checksum is given."""
        cache = None
        if cache_dir is not None and dataset_checksum:
            cache = self.cache_path(cache_dir, dataset_checksum)
        names = [inst.name for inst in instances]
        if cache is not None and cache.is_file():
            try:
                with h5py.File(cache, "r") as f:
                    if all(n in f for n in names):
                        return [f[n][()] for n in names]
            except OSError:
                pass  # an unreadable cache is recomputed and replaced
        out = [self.compute({k: inst[k] for k in self.fields}) for inst in instances]
        if cache is not None:
            _write_cache(cache, dict(zip(names, out)))
        return out


class _SingleSample:
    """Per-sample Pinocchio evaluation for a control loop (no batching or validation)."""

    def __init__(self, robot):
        self.robot = robot
        self.model, self.data = robot.model, robot.model.createData()
        self.tool = robot.tool_frame_id

    def basewrench_force(self, q, qd, qdd, w_sensor) -> np.ndarray:
        """The base-wrench method at one sample: the analytic layer's own single-sample core."""
        return base_wrench_force_core(self.robot, q, qd, qdd, w_sensor)


def _write_cache(path: Path, arrays: dict) -> None:
    """Merge ``arrays`` into the cache file atomically (temp file, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    merged = {}
    if path.is_file():
        try:
            with h5py.File(path, "r") as f:
                merged = {k: f[k][()] for k in f}
        except OSError:
            merged = {}
    merged.update(arrays)
    tmp = path.with_suffix(".h5.partial")
    with h5py.File(tmp, "w") as f:
        for k in sorted(merged):
            f.create_dataset(k, data=np.asarray(merged[k], np.float64), track_times=False)
    os.replace(tmp, path)
