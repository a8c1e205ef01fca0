"""Calibrating the estimator on a free-motion log (``hybrid-dyn calibrate``): the steps of
``estimator/calibration.py``'s docstring, run on a log's validation part through the estimator itself.

    cal = calibrate(robot, ["momentum-observer"], dataset.split("val"), rate_hz, torque_model=model)
    cal.save("calibration.json")     # TipForceEstimator.analytic(..., params=..., calibration=that file)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UsageError
from .calibration import Calibration, CalibrationError, MethodCalibration, fit_torque_error, joint_sigma
from .config import EstimatorConfig
from .tip_force_estimator import TipForceEstimator

COVERAGE = 0.99       # the share of the calibration part's calls whose phantom |F| lies within 2 |sigma|
MAX_SIGMA_QUANTILE = 0.99  # max_sigma: MAX_SIGMA_MARGIN times this quantile of the part's largest per-axis sigma
MAX_SIGMA_MARGIN = 1.5  # a call whose error bar lies well beyond this arm's usual is "uncertain", not its usual
MIN_SETTLED = 0.9  # a bandwidth must leave at least this share of the calibration part's calls settled
UNSETTLED = ("warming up", "contact at start-up", "input rejected")  # the statuses of no settled estimate
PHANTOM_SLACK = 2.5  # a bandwidth whose error bar carries may cost this factor of phantom over the least
HELD_OUT_COVERAGE = 0.9  # a bandwidth's error bar, scaled on one half of the part, must cover this on the other
EFFECTIVE_GAINS = (100.0, 30.0, 10.0, 3.0, 1.0)  # [1/s] the low-passes a method's law is tried under (law_at)


def stream_instances(est, instances, tau_key: str = "tau_m", model_sigma: bool = False, lead_in=()):
    """Every sample of ``instances`` (a dataset split, with t) through estimator ``est``, in order: one stream
    while an instance starts where the last one ended (a log cut into blocks), a new one (``reset``) when
    its time starts anew. ``lead_in``: instances streamed first and not returned (the part of the log before
    ``instances``: the estimator there is as it will be in use, long settled). Returns (forces (N, 3) [N],
    sigma (N, 3) [N], statuses (N,) str), and with ``model_sigma`` the error bar's model term (N, 3) [N] (inf
    where there is none)."""
    forces, sigmas, statuses, models = [], [], [], []
    skip = {id(i) for i in lead_in}
    for inst in list(lead_in) + list(instances):
        q, qd, t = (np.asarray(inst[k], float) for k in ("q", "qd", "t"))
        tau = np.asarray(inst[tau_key], float)
        if not est.continues(t[0]):
            est.reset()
        if id(inst) in skip:
            for k in range(len(t)):
                est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k])
            continue
        for k in range(len(t)):
            forces.append(est.estimate_tip_force(q[k], qd[k], tau_J=tau[k], t=t[k]))
            sigmas.append(est.last_sigma.copy())
            statuses.append(est.last_status.value)
            if model_sigma:
                m = est._model_sigma
                models.append(np.full(3, np.inf) if m is None else m.copy())
    out = np.array(forces), np.array(sigmas), np.array(statuses)
    return out + (np.array(models),) if model_sigma else out


def lead_in(candidates, part, gap_seconds: float = 0.05) -> list:
    """The instances of ``candidates`` (a log's earlier split) that run straight into ``part``'s first one (each
    ending within ``gap_seconds`` [s] before the next begins), in time order: a log cut into time blocks."""
    chain, start = [], min(float(np.asarray(i["t"], float)[0]) for i in part) if part else None
    pool = sorted(candidates, key=lambda i: -float(np.asarray(i["t"], float)[-1]))
    for inst in pool:
        t = np.asarray(inst["t"], float)
        if start is not None and 0 < start - t[-1] <= gap_seconds:
            chain.insert(0, inst)
            start = float(t[0])
    return chain


def torque_residual(robot, torque_model, instances, tau_key: str = "tau_m", lowpass: float | None = None) -> tuple:
    """(residual, qd, qdd) (N, nv) of the torque model on ``instances`` (their logged qdd: the import's
    zero-phase derivative): tau - ID(q, qd, qdd) - the terms beyond the rigid body [Nm]. lowpass [1/s]: the
    residual as an observer of that gain sees it (a first-order low-pass per instance), else as it is."""
    return filtered(residual_parts(robot, torque_model, instances, tau_key), lowpass)


def residual_parts(robot, torque_model, instances, tau_key: str = "tau_m") -> list:
    """Per instance (residual, qd, qdd, steps [s]) of ``torque_residual``, unfiltered."""
    parts = []
    for inst in instances:
        q, qd, qdd, tau = (np.asarray(inst[k], float) for k in ("q", "qd", "qdd", tau_key))
        e = tau - robot.inverse_dynamics(q, qd, qdd)
        if torque_model is not None:
            e = e - np.array([torque_model.extra_torque(*x) for x in zip(q, qd, qdd)])
        parts.append((e, qd, qdd, np.diff(np.asarray(inst["t"], float))))
    return parts


def filtered(parts, lowpass: float | None) -> tuple:
    """(residual, qd, qdd) (N, nv) of ``residual_parts``, the residual low-passed at ``lowpass`` [1/s] (None: not)."""
    out = [(e if lowpass is None else first_order_lowpass(e, lowpass, steps), qd, qdd) for e, qd, qdd, steps in parts]
    return tuple(np.concatenate([p[i] for p in out]) for i in range(3))


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


def phantom(forces) -> np.ndarray:
    """|F| (N,) [N] of free-motion estimates: every newton is a phantom."""
    return np.linalg.norm(np.asarray(forces, float), axis=1)


def pinv_jt(robot, instances) -> np.ndarray:
    """pinv(J_v^T) = (J_v J_v^T)^-1 J_v (N, 3, nv) at every sample of ``instances``: a torque [Nm] to the tip force
    [N] that explains it (undamped)."""
    q = np.concatenate([np.asarray(i["q"], float) for i in instances])
    jv = robot._tip_jacobians(q)[:, :3, :]
    return np.linalg.solve(jv @ jv.transpose(0, 2, 1), jv)


def calibrate(robot, methods, instances, rate_hz: float, torque_model=None, tau_key: str = "tau_m",
              source: dict | None = None, progress=None, before=(), **config) -> Calibration:
    """The :class:`Calibration` of ``methods`` (joint-torque method names) on ``robot`` with ``torque_model``
    (None: the rigid body alone) from free-motion ``instances`` (a log's validation part, with q, qd, qdd, t
    and the joint torques ``tau_key``); the steps of the module docstring. config: other estimator settings
    (``encoder_resolution`` as the log's). progress(text): told each step. before: the log's instances
    before ``instances`` (its training part): those that run straight into it are streamed first, unscored
    (``lead_in``), so that the estimator meets the calibration part as it will in use, long settled."""
    from ..analytic.methods import TIP_FORCE_METHODS

    say = progress or (lambda text: None)
    specs = [TIP_FORCE_METHODS.lookup(m) for m in methods]
    not_torque = [s.name for s in specs if "tau_J" not in s.reads]
    if not_torque:  # before any work
        raise UsageError(f"calibrate: {not_torque} read no joint torques; a calibration is for the joint-torque methods")
    parts = residual_parts(robot, torque_model, instances, tau_key)  # once: every method's law reads them
    residual, qd, qdd = filtered(parts, None)
    sig, corr = fit_torque_error(residual, qd, qdd)
    pinv = pinv_jt(robot, instances)
    digest = None if torque_model is None else torque_model.digest
    name = "rigid body" if torque_model is None else torque_model.name
    cal = Calibration(robot.name, name, digest, sig, corr, {}, dict(source or {}, samples=int(len(residual)),
                                                                      rate_hz=float(rate_hz)))
    warm = lead_in(before, instances)
    for spec in specs:
        job = _MethodRun(robot, spec, instances, warm, torque_model, tau_key,
                         dict(config, call_hz=rate_hz, on_bad_input="hold"), (sig, corr), parts, pinv)
        best = job.choose_bandwidth(cal, say)
        if best is None:
            reason = (f"no bandwidth of {bandwidth_grid(spec, rate_hz)} settled on {100 * MIN_SETTLED:.0f} % of the "
                      "calibration part's calls: give a longer log")
            cal.source.setdefault("not_calibrated", {})[spec.name] = reason
            say(f"{spec.name}: not calibrated: {reason}")
            continue
        cal.methods[spec.name] = job.scaled(cal, *best)
        mc = cal.methods[spec.name]
        say(f"{spec.name}: {spec.parameter} = {mc.bandwidth:g}, sigma scale {mc.sigma_scale:.3g}, "
            f"max_sigma {mc.max_sigma:.3g} N")
    return cal


@dataclass
class _MethodRun:
    """One method's calibration runs on the part (``calibrate``'s steps 3 and 4)."""

    robot: object
    spec: object
    instances: list
    warm: list
    torque_model: object
    tau_key: str
    settings: dict
    raw_law: tuple
    parts: list  # residual_parts of the instances
    pinv: np.ndarray  # pinv_jt of the instances (N, 3, nv)

    def run(self, calibration, model_sigma: bool = False):
        est = TipForceEstimator(self.robot, self.spec.name, _config(self.settings, {}), torque_model=self.torque_model,
                                calibration=calibration)
        return stream_instances(est, self.instances, self.tau_key, model_sigma=model_sigma, lead_in=self.warm)

    def law_at(self, value, forces=None) -> tuple:
        """The torque error law the method sees: through an observer's low-pass at its gain; for another method,
        through the first-order low-pass (of EFFECTIVE_GAINS, or none) under which the law best explains the
        method's own phantom ``forces`` (N, 3) [N] on the part (NaN: unsettled; the least Gaussian negative
        log-likelihood of F ~ N(0, P Sigma_tau P^T)): a Kalman filter or a qdd filter passes the slow part of the
        model's error."""
        if self.spec.parameter == "momentum_gain":
            return fit_torque_error(*filtered(self.parts, value))
        if forces is None:
            return self.raw_law
        best = None
        for gain in (None,) + EFFECTIVE_GAINS:
            e, qd, qdd = filtered(self.parts, gain)
            law = fit_torque_error(e, qd, qdd)
            d = joint_sigma(law[0], qd, qdd)
            cov = np.einsum("nij,jk,nlk->nil", self.pinv * d[:, None, :], law[1], self.pinv * d[:, None, :])
            cov += 1e-9 * np.eye(3)
            use = np.isfinite(forces).all(axis=1)  # the settled calls
            cov, f = cov[use], forces[use][..., None]
            nll = float(np.mean(0.5 * (f.transpose(0, 2, 1) @ np.linalg.solve(cov, f))[:, 0, 0]
                                + 0.5 * np.linalg.slogdet(cov)[1]))
            if best is None or nll < best[0]:
                best = (nll, law)
        return best[1]

    def choose_bandwidth(self, cal: Calibration, say) -> tuple | None:
        """(value, phantom RMS [N]) of a bandwidth that settles on MIN_SETTLED of the calls: among those within
        PHANTOM_SLACK of the least phantom, the least phantom of those whose error bar carries from one half of
        the part to the other (``held_out_coverage`` at least HELD_OUT_COVERAGE), or of all of them where none
        does (a part whose halves differ, as Baxter's two validation trajectories); None where none settles."""
        name, candidates = self.spec.name, []
        self.forces = {}
        for value in bandwidth_grid(self.spec, self.settings["call_hz"]):  # the model's error in motion decides
            # The model term at scale 1 rides along: the start-up window then knows the model's error is no contact.
            cal.methods[name] = MethodCalibration(value, *self.law_at(value), 1.0, np.inf, np.nan)
            f, _, status = self.run(cal)
            settled = ~np.isin(status, UNSETTLED)
            self.forces[value] = np.where(settled[:, None], f, np.nan)
            rms = float(np.sqrt(np.mean(phantom(f[settled]) ** 2))) if settled.any() else np.inf
            # A bandwidth so slow that its warm-up takes much of the part is no answer: it would say nothing.
            carried = self.held_out_coverage(value) if settled.mean() >= MIN_SETTLED else 0.0
            say(f"{name}: {self.spec.parameter} = {value:g}: phantom {rms:.3f} N RMS on {100 * settled.mean():.0f} % "
                f"of the calls (the others warming up), error bar carried to the other half {100 * carried:.0f} %")
            if settled.mean() >= MIN_SETTLED:
                candidates.append((rms, carried, value))
        del cal.methods[name]
        if not candidates:
            return None
        least = min(c[0] for c in candidates)
        near = [c for c in candidates if c[0] <= PHANTOM_SLACK * least]
        carried = [c for c in near if c[1] >= HELD_OUT_COVERAGE] or near
        rms, _, value = min(carried)
        return value, rms

    def held_out_coverage(self, value) -> float:
        """Fit the error bar's scale on one half of the part's settled calls (in time), count how many calls
        of the other half it covers (|F| <= 2 |sigma|), both ways round: the lesser share. The slowest filters
        give the least phantom, a slowly wandering bias, and an error bar that holds on one stretch of a log
        and not the next (the real Panda's kalman-fusion at 0.3 N/sqrt(s): 99 % on its calibration part, 80 %
        on its test part)."""
        forces = self.forces[value]
        e, qd, qdd = filtered(self.parts, value if self.spec.parameter == "momentum_gain" else None)
        law = self.law_at(value, forces)
        d = joint_sigma(law[0], qd, qdd)
        pd = self.pinv * d[:, None, :]
        model = np.sqrt(np.clip(np.einsum("nij,jk,nik->ni", pd, law[1], pd), 0.0, None))
        use = np.flatnonzero(np.isfinite(forces).all(axis=1))
        if len(use) < 20:
            return 0.0
        size, bar = phantom(forces[use]), np.linalg.norm(model[use], axis=1)
        halves = (slice(0, len(use) // 2), slice(len(use) // 2, None))
        shares = []
        for fit, check in (halves, halves[::-1]):
            scale = cover_scale(size[fit], bar[fit])
            shares.append(float(np.mean(size[check] <= 2.0 * scale * bar[check])))
        return min(shares)

    def scaled(self, cal: Calibration, value: float, rms: float) -> MethodCalibration:
        """The method's calibration at ``value``: one run with the model term at scale 1 splits each call's sigma
        into the sensors' part and the model's; the scale is the least s whose model term alone covers the
        phantom on COVERAGE of the calls (the sensor terms covered a calibration part by chance and then missed
        the test part by a factor of four), max_sigma from the sigma at that scale."""
        law = self.law_at(value, self.forces.get(value))
        cal.methods[self.spec.name] = MethodCalibration(value, *law, 1.0, np.inf, rms)
        f, sigma, _, model = self.run(cal, model_sigma=True)
        keep = np.isfinite(sigma).all(axis=1) & np.isfinite(model).all(axis=1)
        if keep.sum() < 10:
            raise CalibrationError(f"calibrate {self.spec.name}: fewer than 10 settled calls with an error bar")
        hi = cover_scale(phantom(f[keep]), np.linalg.norm(model[keep], axis=1))
        per_axis = np.sqrt(np.clip(sigma[keep] ** 2 - model[keep] ** 2, 0.0, None) + hi * hi * model[keep] ** 2)
        max_sigma = MAX_SIGMA_MARGIN * float(np.quantile(per_axis.max(axis=1), MAX_SIGMA_QUANTILE))
        return MethodCalibration(value, *law, hi, max_sigma, rms)


def cover_scale(size, bar) -> float:
    """The least scale s (to 1 %, in [1e-3, 1e3]) with size <= 2 s bar on COVERAGE of the calls."""
    lo, hi = 1e-3, 1e3
    while hi / lo > 1.01:
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if np.mean(size <= 2.0 * mid * bar) >= COVERAGE else (mid, hi)
    return hi


def _config(settings: dict, extra: dict):
    return EstimatorConfig.from_settings(**dict(settings, **extra))




__all__ = ["COVERAGE", "calibrate", "pinv_jt", "first_order_lowpass", "lead_in", "stream_instances", "torque_residual"]
