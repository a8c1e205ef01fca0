"""One simulated run: a torque-controlled arm in DART, with sensors (the generator's simulator).

The detail (what it computes, the equations, why each choice): docs/design/sim.md, section ``sim/simulator.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..analytic.robot import InputError
from .collision import collision_checker
from .plant import DartPlant
from .generator_config import GeneratorConfig
from .sensors import causal_acceleration, read_sensors

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
        if cfg.sensors is not None:
            return self._hardware_sensors(truth, q_ref, Q, QD, rng)
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
        attrs = {**_tracking(q_ref, Q), "base_wrench_bias": bias, "duration_s": float(len(Q) * cfg.dt)}
        return SimulatedRun(fields, truth, attrs)

    def _hardware_sensors(self, truth, q_ref, Q, QD, rng) -> SimulatedRun:
        """The run read by ``config.sensors`` (``sim/sensors.read_sensors``, the one sensor model of the
        stream simulator too): the drive reads the encoders at the control rate, ``dt`` (quantized q of the
        true Q, QD at every step; qd the drive's difference of it), and the log keeps every ``decimation``-th
        reading, a sample, not an average; at the logged samples noisy tau_J, the base sensor with bias,
        drift and delay, jittered stamps ``t``. qdd is the causal estimate from the logged qd at the logged
        period (what an estimator reading the log computes), or DART's with ``qdd_source="exact"``."""
        cfg = self.config
        period = cfg.dt * cfg.decimation
        r = read_sensors(self.nominal, cfg.sensors, cfg.dt, Q, QD, truth["tau_J"], truth["base_wrench"], rng,
                         every=cfg.decimation)
        qdd = truth["qdd"] if cfg.qdd_source == "exact" else causal_acceleration(r.qd, period, cfg.qdd_cutoff_hz)
        fields = {"t": truth["t"] + (r.t - np.arange(len(r.t)) * period), "q": r.q, "qd": r.qd, "qdd": qdd,
                  "tau_m": truth["tau_m"], "tau_J": r.tau_J, "base_wrench": r.base_wrench,
                  "tip_force": truth["tip_force"]}
        # The base sensor's drawn bias [N, Nm] at t = 0 and drift [N/s, Nm/s].
        attrs = {**_tracking(q_ref, Q), "base_wrench_bias": r.bias, "base_wrench_drift": r.drift,
                 "duration_s": float(len(Q) * cfg.dt)}
        return SimulatedRun(fields, truth, attrs)


def _tracking(q_ref, Q) -> dict:
    """The run's tracking errors [rad] per joint at the control rate: RMS and largest, reference minus true."""
    err = q_ref - Q
    return {"tracking_rms": np.sqrt(np.mean(err**2, axis=0)), "tracking_max": np.max(np.abs(err), axis=0)}


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

    - ``q``, ``qd``: true state plus white noise (``config.noise``), or as ``config.sensors`` read them
      (quantized q, the drive's difference of it at the control rate, logged every n-th step);
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
