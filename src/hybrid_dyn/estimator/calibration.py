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
4. **The scale s** makes the error bar cover the phantom force on 99 % of the part's calls (|F| <= 2 |sigma|),
   and ``max_sigma`` (the bound above which a call is ``uncertain``) is 1.5 times the part's 99th percentile of
   sigma: a call whose error bar lies well beyond what this arm's model usually gives (a pose, a speed or a
   singularity the log did not show) is uncertain.

The result is stored as JSON beside the model (:meth:`Calibration.save`), with the digest of the parameter
file it was made for: the estimator refuses it for another model or robot. With no calibration, the error
bar is the sensors' alone, as before (the fallback; the simulator's trust bench runs there).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.optimize import nnls

from ..errors import UsageError
from ..outputs import unique_temp

FILE_FORMAT = "hybrid_dyn.estimator_calibration"
COVERAGE = 0.99       # the share of the calibration part's calls whose phantom |F| lies within 2 |sigma|
MAX_SIGMA_QUANTILE = 0.99  # max_sigma: MAX_SIGMA_MARGIN times this quantile of the part's largest per-axis sigma
MAX_SIGMA_MARGIN = 1.5  # a call whose error bar lies well beyond this arm's usual is "uncertain", not its usual
OFF_TOOL_SIGMAS = 4.0  # the off-tool bound: this many sigmas of the model error outside range(J_v^T)
MIN_SETTLED = 0.5  # a bandwidth must leave at least this share of the calibration part's calls settled
UNSETTLED = ("warming up", "contact at start-up", "input rejected")  # the statuses of no settled estimate
CHECK_EVERY = 8       # calls between two Jacobians of the model term (as the off-tool check)


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
        sig, corr = np.array(d["torque_sigma"], float), np.array(d["correlation"], float)
        if sig.shape != (nv, 3) or corr.shape != (nv, nv) or not (np.isfinite(sig).all() and np.isfinite(corr).all()) \
                or (sig < 0).any():
            raise ValueError("torque_sigma must be (nv, 3) non-negative and correlation (nv, nv), finite")
        return cls(float(d["bandwidth"]), sig, corr, float(d["sigma_scale"]), float(d["max_sigma"]),
                   float(d["phantom_rms"]))


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
        try:
            sig = np.array(doc["torque_sigma"], float)
            corr = np.array(doc["correlation"], float)
            methods = {k: MethodCalibration.from_dict(v, len(sig)) for k, v in doc["methods"].items()}
            out = cls(str(doc["robot"]), str(doc["model"]), doc.get("params_digest"), sig, corr, methods,
                      dict(doc.get("source", {})))
        except (KeyError, TypeError, ValueError) as err:
            raise CalibrationError(f"{path}: a calibration needs torque_sigma, correlation and methods ({err})") from None
        nv = len(sig)
        if sig.shape != (nv, 3) or corr.shape != (nv, nv) or not (np.isfinite(sig).all() and np.isfinite(corr).all()) \
                or (sig < 0).any():
            raise CalibrationError(f"{path}: torque_sigma must be (nv, 3) non-negative and correlation (nv, nv), finite")
        return out

    def check_for(self, robot, params_digest: str | None, method: str) -> MethodCalibration:
        """This calibration's settings of ``method`` on ``robot`` with the model of ``params_digest``, or
        CalibrationError naming the mismatch."""
        if self.robot != robot.name:
            raise CalibrationError(f"the calibration was made on robot {self.robot!r}, not {robot.name!r}")
        if len(self.torque_sigma) != robot.nv:
            raise CalibrationError(f"the calibration holds {len(self.torque_sigma)} joints, {robot.name!r} has {robot.nv}")
        if self.params_digest != params_digest:
            raise CalibrationError(
                f"the calibration was made for another torque model ({self.model}, parameter file digest "
                f"{str(self.params_digest)[:12]}), not the one given (digest {str(params_digest)[:12]}): calibrate "
                "the model you run")
        if method not in self.methods:
            raise CalibrationError(f"the calibration has no settings for method {method!r} "
                                   f"(it calibrated {', '.join(self.methods) or 'none'})")
        return self.methods[method]


class ModelError:
    """The model term of one stream's error bar (module docstring, step 2): ``update`` at each call."""

    def __init__(self, robot, calibrated: MethodCalibration):
        self.robot, self.cal, self.scale = robot, calibrated, float(calibrated.sigma_scale)
        self._data = robot.model.createData()
        self._R = np.asarray(calibrated.correlation, float)
        self.sigma = np.full(3, np.inf)
        self.off_tool_bound = np.inf  # [Nm]
        self._k = CHECK_EVERY - 1

    def reset(self) -> None:
        self._k = CHECK_EVERY - 1

    def update(self, q, qd, qdd) -> np.ndarray:
        """The model's 1-sigma error per axis (3,) [N] at this call (recomputed every CHECK_EVERY calls)."""
        self._k += 1
        if self._k < CHECK_EVERY:
            return self.sigma
        self._k = 0
        r = self.robot
        jv = pin.computeFrameJacobian(r.model, self._data, q, r.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        d = self.cal.joint_sigma(qd, qdd) * self.scale
        cov = self._R * np.outer(d, d)
        try:
            p = np.linalg.solve(jv @ jv.T, jv)  # pinv(J_v^T) (3, nv)
        except np.linalg.LinAlgError:
            self.sigma = np.full(3, np.inf)
            return self.sigma
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
        coef, _ = nnls(basis / scale, residual[:, j] ** 2)
        sig[j] = np.sqrt(coef / scale)
    d = np.sqrt(np.clip((np.stack([np.ones_like(qd[:, 0])] * nv, 1) * sig[:, 0] ** 2
                         + (qd * sig[:, 1]) ** 2 + (qdd * sig[:, 2]) ** 2), 1e-12, None))
    z = residual / d
    corr = np.corrcoef(z, rowvar=False) if len(z) > 2 else np.eye(nv)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return sig, corr





def stream_instances(est, instances, tau_key: str = "tau_m", model_sigma: bool = False):
    """Every sample of ``instances`` (a dataset split, with t) through estimator ``est``, in order: one stream
    while an instance starts where the last one ended (a log cut into blocks), a new one (``reset``) when
    its time starts anew. Returns (forces (N, 3) [N], sigma (N, 3) [N], statuses (N,) str), and with
    ``model_sigma`` the error bar's model term (N, 3) [N] (inf where there is none)."""
    forces, sigmas, statuses, models = [], [], [], []
    end = None
    gap = est.config.bridge_seconds + 1.5 / est.config.call_hz
    for inst in instances:
        q, qd, t = (np.asarray(inst[k], float) for k in ("q", "qd", "t"))
        tau = np.asarray(inst[tau_key], float)
        if end is None or not (0 < t[0] - end <= gap):
            est.reset()
        for k in range(len(t)):
            forces.append(est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k]))
            sigmas.append(est.last_sigma.copy())
            statuses.append(est.last_status.value)
            if model_sigma:
                m = est._model_sigma
                models.append(np.full(3, np.inf) if m is None else m.copy())
        end = t[-1]
    out = np.array(forces), np.array(sigmas), np.array(statuses)
    return out + (np.array(models),) if model_sigma else out


def torque_residual(robot, torque_model, instances, tau_key: str = "tau_m", lowpass: float | None = None) -> tuple:
    """(residual, qd, qdd) (N, nv) of the torque model on ``instances`` (their logged qdd: the import's
    zero-phase derivative): tau - ID(q, qd, qdd) - the terms beyond the rigid body [Nm]. lowpass [1/s]: the
    residual as an observer of that gain sees it (a first-order low-pass per instance), else as it is."""
    parts = []
    for inst in instances:
        q, qd, qdd, tau = (np.asarray(inst[k], float) for k in ("q", "qd", "qdd", tau_key))
        e = tau - robot.inverse_dynamics(q, qd, qdd)
        if torque_model is not None:
            e = e - np.array([torque_model.extra_torque(*x) for x in zip(q, qd, qdd)])
        if lowpass is not None:
            e = first_order_lowpass(e, lowpass, np.diff(np.asarray(inst["t"], float)))
        parts.append((e, qd, qdd))
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(3))


def first_order_lowpass(x, gain: float, steps) -> np.ndarray:
    """y' = gain (x - y) from y(0) = 0, by the exact step of each interval ``steps`` [s]: what a momentum
    observer of that gain [1/s] makes of a torque error x (N, nv) (it starts from 0, as the observer)."""
    y, out = np.zeros(x.shape[1]), np.empty_like(x)
    out[0] = y
    for k in range(1, len(x)):
        a = 1.0 - np.exp(-gain * steps[k - 1])
        y = y + a * (x[k] - y)
        out[k] = y
    return out


def bandwidth_grid(method, rate_hz: float) -> tuple:
    """The values of ``method``'s bandwidth parameter a calibration chooses from at rate_hz [Hz]: its
    ``-val`` grid, or the qdd-filter designs where it has none."""
    grid = method.val_grid(rate_hz)
    if not grid:
        from ..analytic.acceleration import cutoff_grid

        designs = cutoff_grid(float(rate_hz))[0]
        grid = tuple(float(x) for x in designs[::6]) + (float(designs[-1]),)  # eight of its 48 designs
    return tuple(grid)


def phantom(forces, statuses=None) -> np.ndarray:
    """|F| (N,) [N] of free-motion estimates: every newton is a phantom."""
    return np.linalg.norm(np.asarray(forces, float), axis=1)


def calibrate(robot, methods, instances, rate_hz: float, torque_model=None, tau_key: str = "tau_m",
              source: dict | None = None, progress=None, **config) -> Calibration:
    """The :class:`Calibration` of ``methods`` (joint-torque method names) on ``robot`` with ``torque_model``
    (None: the rigid body alone) from free-motion ``instances`` (a log's validation part, with q, qd, qdd, t
    and the joint torques ``tau_key``); the steps of the module docstring. config: other estimator settings
    (``encoder_resolution`` as the log's). progress(text): told each step."""
    from ..analytic.methods import TIP_FORCE_METHODS
    from .tip_force_estimator import TipForceEstimator

    say = progress or (lambda text: None)
    residual, qd, qdd = torque_residual(robot, torque_model, instances, tau_key)
    sig, corr = fit_torque_error(residual, qd, qdd)
    digest = None if torque_model is None else torque_model.digest
    name = "rigid body" if torque_model is None else torque_model.name
    cal = Calibration(robot.name, name, digest, sig, corr, {}, dict(source or {}, samples=int(len(residual)),
                                                                      rate_hz=float(rate_hz)))
    per_method = {}
    for m in methods:
        spec = TIP_FORCE_METHODS.lookup(m)
        if "tau_J" not in spec.reads:
            raise UsageError(f"calibrate: {spec.name!r} reads no joint torques; a calibration is for the "
                             "joint-torque methods")
        settings = dict(config, call_hz=rate_hz, on_bad_input="hold")

        def run(calibration=None, **extra):
            est = TipForceEstimator(robot, spec.name, _config(settings, extra), torque_model=torque_model,
                                    calibration=calibration)
            return stream_instances(est, instances, tau_key)

        best = None
        for value in bandwidth_grid(spec, rate_hz):  # the model's error in motion decides, not the sensors' noise
            f, _, status = run(**{spec.parameter: value})
            settled = ~np.isin(status, UNSETTLED)
            rms = float(np.sqrt(np.mean(phantom(f[settled]) ** 2))) if settled.any() else np.inf
            say(f"{spec.name}: {spec.parameter} = {value:g}: phantom {rms:.3f} N RMS on {100 * settled.mean():.0f} % "
                "of the calls (the others warming up)")
            # A bandwidth so slow that its warm-up takes half the part is no answer: it would say nothing.
            if settled.mean() >= MIN_SETTLED and (best is None or rms < best[1]):
                best = (value, rms)
        if best is None:
            raise CalibrationError(f"calibrate {spec.name}: no bandwidth of {bandwidth_grid(spec, rate_hz)} settled "
                                   f"on {100 * MIN_SETTLED:.0f} % of the log's calls: give a longer log")
        value, rms = best
        # An observer sees the model's error through its low-pass: the error law is fitted on what it sees.
        if spec.parameter == "momentum_gain":
            per_method[spec.name] = fit_torque_error(*torque_residual(robot, torque_model, instances, tau_key, value))
        else:
            per_method[spec.name] = (sig, corr)
        law = per_method[spec.name]
        # One run with the model term at scale 1 splits each call's sigma into the sensors' part and the
        # model's; the scale is then the least s whose error bar covers the phantom on COVERAGE of the calls.
        cal.methods[spec.name] = MethodCalibration(value, *law, 1.0, np.inf, rms)
        est = TipForceEstimator(robot, spec.name, _config(settings, {}), torque_model=torque_model, calibration=cal)
        f, sigma, status, model = stream_instances(est, instances, tau_key, model_sigma=True)
        keep = np.isfinite(sigma).all(axis=1) & np.isfinite(model).all(axis=1)
        if keep.sum() < 10:
            raise CalibrationError(f"calibrate {spec.name}: fewer than 10 settled calls with an error bar")
        size = phantom(f[keep])
        sensors2 = np.clip((sigma[keep] ** 2 - model[keep] ** 2).sum(axis=1), 0.0, None)
        model2 = (model[keep] ** 2).sum(axis=1)

        def covered(scale):
            return np.mean(size <= 2.0 * np.sqrt(sensors2 + scale * scale * model2))

        lo, hi = 1e-3, 1e3
        while hi / lo > 1.01:
            mid = np.sqrt(lo * hi)
            lo, hi = (lo, mid) if covered(mid) >= COVERAGE else (mid, hi)
        per_axis = np.sqrt(np.clip(sigma[keep] ** 2 - model[keep] ** 2, 0.0, None) + hi * hi * model[keep] ** 2)
        max_sigma = MAX_SIGMA_MARGIN * float(np.quantile(per_axis.max(axis=1), MAX_SIGMA_QUANTILE))
        cal.methods[spec.name] = MethodCalibration(value, *law, hi, max_sigma, rms)
        say(f"{spec.name}: {spec.parameter} = {value:g}, sigma scale {hi:.3g}, max_sigma {max_sigma:.3g} N")
    return cal


def _config(settings: dict, extra: dict):
    from .config import EstimatorConfig

    return EstimatorConfig.from_settings(**dict(settings, **extra))



__all__ = ["COVERAGE", "Calibration", "CalibrationError", "MethodCalibration", "ModelError", "calibrate",
           "fit_torque_error", "stream_instances", "torque_residual"]
