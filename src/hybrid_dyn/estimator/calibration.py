"""Error bars calibrated on the user's own log: what the torque model misses on this arm, as a force.

The sensor-noise error bar (``analytic/error_bar.py``) knows the sensors, not the model. On a real arm the
model is the larger error: a joint-torque method reads pinv(J_v^T) of every newton-metre the torque model
misses as force. A few minutes of free motion (nothing touches the tool, so the true tip force is zero) tell
how large that error is on this arm. :func:`calibrate` measures it on a log's validation part:

1. **The torque model's residual** e = tau_J - ID(q, qd, qdd) - (friction, springs, a learned correction),
   per joint j, grows with the joint's speed and acceleration:
   sigma_j^2 = a_j^2 + (b_j qd_j)^2 + (c_j qdd_j)^2 (non-negative least squares on e_j^2), and the joints'
   errors correlate (R, the correlation of e_j / sigma_j). Sigma_tau = D R D, D = diag(sigma_j).
2. **At each call** (:class:`ModelError`) Sigma_tau is mapped into force through the Jacobian:
   Sigma_F = s^2 P Sigma_tau P^T, P = pinv(J_v^T) (undamped: near a singular pose the weak direction's
   sigma grows without bound, and the call says ``uncertain``, never a shrunk force at ``ok``). The part of
   Sigma_tau outside range(J_v^T), (I - J_v^T P), bounds what the off-tool check may call model error.
3. **Each method's bandwidth** (observer gain, qdd cutoff, Kalman force rate) is chosen on the same log:
   the value of its ``-val`` grid with the least phantom force over the part, the model's error in motion,
   not the sensors' noise at rest.
4. **The scale s** makes the model term alone cover the phantom force on 99 % of the part's calls (|F| <= 2 |sigma|),
   and ``max_sigma`` (the bound above which a call is ``uncertain``) is 1.5 times the part's 99th percentile of
   sigma: a call whose error bar lies well beyond what this arm's model usually gives (a pose, a speed or a
   singularity the log did not show) is uncertain.

The result is stored as JSON beside the model (:meth:`Calibration.save`), with the digest of the parameter
file it was made for: the estimator refuses it for another model or robot. With no calibration, the error
bar is the sensors' alone, as before (the fallback; the simulator's trust bench runs there).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import nnls

from ..errors import UsageError
from .consistency import CHECK_EVERY  # the model term's Jacobian as often as the off-tool check's
from .torque_tare import pinv_jv_t
from ..outputs import unique_temp

FILE_FORMAT = "hybrid_dyn.estimator_calibration"
OFF_TOOL_SIGMAS = 4.0  # the off-tool bound: this many sigmas of the model error outside range(J_v^T)


class CalibrationError(UsageError):
    """A calibration file that is unreadable, or made for another robot or torque model."""


@dataclass
class MethodCalibration:
    """One method's calibrated settings: its bandwidth parameter's value, the torque error law it sees
    (``torque_sigma`` (nv, 3), ``correlation`` (nv, nv): through an observer's low-pass for an observer), the
    error bar's scale s, and max_sigma [N]; phantom_rms [N]: the phantom force over the calibration part at
    that bandwidth."""

    bandwidth: float
    torque_sigma: np.ndarray
    correlation: np.ndarray
    sigma_scale: float
    max_sigma: float
    phantom_rms: float

    def joint_sigma(self, qd, qdd) -> np.ndarray:
        """sigma_j (nv,) [Nm] at one sample (qdd None: 0), before the scale."""
        return joint_sigma(self.torque_sigma, qd, qdd)

    def to_dict(self) -> dict:
        return {"bandwidth": float(self.bandwidth), "torque_sigma": np.asarray(self.torque_sigma).tolist(),
                "correlation": np.asarray(self.correlation).tolist(), "sigma_scale": float(self.sigma_scale),
                "max_sigma": float(self.max_sigma), "phantom_rms": float(self.phantom_rms)}

    @classmethod
    def from_dict(cls, d: dict, nv: int) -> "MethodCalibration":
        """From a file's method section; ValueError naming what is wrong (the bandwidth's own range is its
        parameter's, checked where the estimator knows its rate)."""
        if not isinstance(d, dict):
            raise ValueError(f"a method's section must be a table, got {type(d).__name__}")
        missing = [k for k in ("bandwidth", "torque_sigma", "correlation", "sigma_scale", "max_sigma", "phantom_rms")
                   if k not in d]
        if missing:
            raise ValueError(f"a method's section lacks {missing}")
        sig, corr = np.array(d["torque_sigma"], float), np.array(d["correlation"], float)
        check_law(sig, corr, nv)
        values = {k: float(d[k]) for k in ("bandwidth", "sigma_scale", "max_sigma")}
        bad = [f"{k} = {v!r}" for k, v in values.items() if not (math.isfinite(v) and v > 0)]
        if bad:
            raise ValueError(f"{', '.join(bad)}: each must be a finite number > 0")
        return cls(values["bandwidth"], sig, corr, values["sigma_scale"], values["max_sigma"], float(d["phantom_rms"]))


def check_law(sig: np.ndarray, corr: np.ndarray, nv: int) -> None:
    """ValueError unless sig is (nv, 3) finite and non-negative and corr a correlation matrix (nv, nv): finite,
    symmetric, a unit diagonal, entries within [-1, 1]."""
    if sig.shape != (nv, 3) or not np.isfinite(sig).all() or (sig < 0).any():
        raise ValueError(f"torque_sigma must be ({nv}, 3) finite and non-negative, got shape {sig.shape}")
    if corr.shape != (nv, nv) or not np.isfinite(corr).all() or not np.allclose(corr, corr.T, atol=1e-9) \
            or not np.allclose(np.diag(corr), 1.0, atol=1e-9) or (np.abs(corr) > 1.0 + 1e-9).any():
        raise ValueError(f"correlation must be a ({nv}, {nv}) correlation matrix: symmetric, unit diagonal, "
                         "entries within [-1, 1]")


def joint_sigma(torque_sigma, qd, qdd) -> np.ndarray:
    """sigma_j (nv,) [Nm] of the law sigma_j^2 = a_j^2 + (b_j qd_j)^2 + (c_j qdd_j)^2 (qdd None: 0)."""
    a, b, c = np.asarray(torque_sigma).T
    var = a * a + (b * qd) ** 2
    if qdd is not None:
        var = var + (c * qdd) ** 2
    return np.sqrt(var)


@dataclass
class Calibration:
    """The torque model's error on one arm, and each method's settings calibrated on the same log.

    torque_sigma: (nv, 3) per joint [a_j (Nm), b_j (Nm s/rad), c_j (Nm s^2/rad)]; correlation: (nv, nv);
    params_digest: sha256 of the identified parameter file the model was read from (None: the description's
    own parameters); model: the torque model's name; source: where it was calibrated (log, split, samples)."""

    robot: str
    model: str
    params_digest: str | None
    torque_sigma: np.ndarray
    correlation: np.ndarray
    methods: dict = field(default_factory=dict)
    source: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"format": FILE_FORMAT, "version": 1, "robot": self.robot, "model": self.model,
                "params_digest": self.params_digest,
                "law": "sigma_j^2 = a_j^2 + (b_j qd_j)^2 + (c_j qdd_j)^2 [Nm]; Sigma_tau = D R D",
                "torque_sigma": self.torque_sigma.tolist(), "correlation": self.correlation.tolist(),
                "methods": {k: v.to_dict() for k, v in self.methods.items()}, "source": self.source}

    def save(self, path) -> Path:
        """Write the file atomically; an existing file is never overwritten (CalibrationError)."""
        path = Path(path)
        if path.exists():
            raise CalibrationError(f"{path} exists: calibrate to a new file")
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = unique_temp(path)
        try:
            tmp.write_text(json.dumps(self.to_dict(), indent=1))
            os.link(tmp, path)  # fails if another run wrote it meanwhile
        finally:
            tmp.unlink(missing_ok=True)
        return path

    @classmethod
    def load(cls, path) -> "Calibration":
        path = Path(path)
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError) as err:
            raise CalibrationError(f"cannot read calibration file {path}: {err}") from None
        if not isinstance(doc, dict) or doc.get("format") != FILE_FORMAT:
            raise CalibrationError(f"{path} is not an estimator calibration (format {FILE_FORMAT!r})")
        if doc.get("version") != 1:
            raise CalibrationError(f"{path}: calibration file version {doc.get('version')!r}; this toolkit reads version 1")
        missing = [k for k in ("robot", "model", "torque_sigma", "correlation", "methods") if k not in doc]
        if missing:
            raise CalibrationError(f"{path}: a calibration needs {missing}")
        if not isinstance(doc["methods"], dict) or not isinstance(doc.get("source", {}), dict) \
                or not isinstance(doc.get("source", {}).get("not_calibrated", {}), dict):
            raise CalibrationError(f"{path}: methods, source and source.not_calibrated must be tables")
        try:
            sig = np.array(doc["torque_sigma"], float)
            corr = np.array(doc["correlation"], float)
            check_law(sig, corr, len(sig))
            methods = {}
            for k, v in doc["methods"].items():
                try:
                    methods[k] = MethodCalibration.from_dict(v, len(sig))
                except (TypeError, ValueError) as err:
                    raise ValueError(f"method {k!r}: {err}") from None
            out = cls(str(doc["robot"]), str(doc["model"]), doc.get("params_digest"), sig, corr, methods,
                      dict(doc.get("source", {})))
        except (TypeError, ValueError) as err:
            raise CalibrationError(f"{path}: {err}") from None
        return out

    def check_for(self, robot, params_digest: str | None, method: str) -> MethodCalibration:
        """This calibration's settings of ``method`` on ``robot`` with the model of ``params_digest``, or
        CalibrationError naming the mismatch."""
        if self.robot != robot.name:
            raise CalibrationError(f"the calibration was made on robot {self.robot!r}, not {robot.name!r}")
        if len(self.torque_sigma) != robot.nv:
            raise CalibrationError(f"the calibration holds {len(self.torque_sigma)} joints, {robot.name!r} has {robot.nv}")
        if self.params_digest != params_digest:
            def named(digest):
                return "the description's own parameters" if digest is None else f"parameter file digest {digest[:12]}"
            raise CalibrationError(
                f"the calibration was made for another torque model ({self.model}, {named(self.params_digest)}), not "
                f"the one given ({named(params_digest)}): calibrate the model you run")
        if method not in self.methods:
            why = self.source.get("not_calibrated", {}).get(method)
            raise CalibrationError(f"the calibration has no settings for method {method!r} "
                                   + (f"({why})" if why else f"(it calibrated {', '.join(self.methods) or 'none'})"))
        return self.methods[method]


class ModelError:
    """The model term of one stream's error bar (module docstring, step 2): ``update`` at each call. The interface
    of ``model_term.StatedModelError``, whose parts a calibration does not state: no weight sigma, no pose the
    torque tare took its error at, no weak-direction flag (its sigma grows there by itself)."""

    weak = False

    def __init__(self, robot, calibrated: MethodCalibration):
        self.robot, self.cal, self.scale = robot, calibrated, float(calibrated.sigma_scale)
        self._data = robot.model.createData()
        self._R = np.asarray(calibrated.correlation, float)
        self.sigma = np.full(3, np.inf)
        self.off_tool_bound = np.inf  # [Nm]
        self._k = CHECK_EVERY - 1

    def reset(self) -> None:
        self._k = CHECK_EVERY - 1

    def tare(self, q) -> None:
        """The torque tare took the offsets at pose q: a calibrated error is of the untared torques, kept."""

    def weight_sigma(self) -> float:
        """The arm's weight's 1-sigma [N] a base tare may absorb: a calibration states none."""
        return 0.0

    def update(self, q, qd, qdd) -> np.ndarray:
        """The model's 1-sigma error per axis (3,) [N] at this call (recomputed every CHECK_EVERY calls)."""
        self._k += 1
        if self._k < CHECK_EVERY:
            return self.sigma
        self._k = 0
        r = self.robot
        jv, p = pinv_jv_t(r, self._data, q)
        if not np.isfinite(p[0, 0]):  # J_v singular
            self.sigma = np.full(3, np.inf)
            return self.sigma
        d = self.cal.joint_sigma(qd, qdd) * self.scale
        cov = self._R * np.outer(d, d)
        self.sigma = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", p, cov, p), 0.0, None))
        n = np.eye(r.nv) - jv.T @ p
        self.off_tool_bound = OFF_TOOL_SIGMAS * float(np.sqrt(max(np.trace(n @ cov @ n.T), 0.0)))
        return self.sigma


# ------------------------------------------------------------------------------ calibrating
def fit_torque_error(residual, qd, qdd) -> tuple[np.ndarray, np.ndarray]:
    """(torque_sigma (nv, 3), correlation (nv, nv)) of residuals (N, nv) [Nm] at qd, qdd (N, nv)."""
    residual, qd, qdd = (np.asarray(x, float) for x in (residual, qd, qdd))
    nv = residual.shape[1]
    sig = np.zeros((nv, 3))
    for j in range(nv):
        basis = np.stack([np.ones(len(qd)), qd[:, j] ** 2, qdd[:, j] ** 2], axis=1)
        scale = np.sqrt((basis ** 2).mean(axis=0)) + 1e-12  # columns of one size: a well-posed NNLS
        e2, w = residual[:, j] ** 2, np.ones(len(qd))
        # e^2 scatters about its variance by its variance (a chi-square of one degree): least squares weighted by
        # 1 / the predicted variance, iterated, is the variance regression's efficient fit.
        for _ in range(4):
            coef, _ = nnls((basis / scale) * w[:, None], e2 * w)
            var = (basis / scale) @ coef
            w = 1.0 / np.maximum(var, 1e-3 * max(float(e2.mean()), 1e-12))
        sig[j] = np.sqrt(coef / scale)
    z = residual / np.maximum(joint_sigma(sig, qd, qdd), 1e-6)
    corr = np.corrcoef(z, rowvar=False) if len(z) > 2 else np.eye(nv)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return sig, corr


__all__ = ["Calibration", "CalibrationError", "MethodCalibration", "ModelError", "fit_torque_error",
           "joint_sigma"]
