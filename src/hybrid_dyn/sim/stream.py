"""One closed-loop control stream at the control rate, read through hardware sensors.

The DART plant (Gaz friction in the joints, optionally a tool load the model does not know) under
joint PD control with gravity compensation; the set point switches between two poses every
``pose_period`` seconds through a first-order filter; contacts push on the tool point (step and
trapezoid contacts drawn as the ``contact-steps`` scenario draws them, plus any given explicitly, a
touch during start-up for instance). The true run is then read through :class:`HardwareSensors`
(``sim/sensors.py``): quantized encoders, the velocity the drive reports, noisy link-side torques, a
base F/T sensor with noise, bias, drift and delay, and jittered stamps.

This is the one stream the tests, ``checks/``, ``benchmarks/`` and ``examples/`` run the estimator on
(:func:`simulate_stream`). The generator's ``contact-steps-hardware`` scenario reads its runs (the
generator's own simulator, ``simulator.py``: random trajectories under computed torque) through the
same sensor model, ``read_sensors``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..analytic.robot import Robot, load_robot
from ..description.spec import resolve_encoder_resolution
from .plant import DartPlant
from .pulses import ContactSteps, sample_contact_steps
from .generator_config import ContactStepConfig
from .sensors import HardwareSensors, SensorReadings, read_sensors

# Joint PD gains of the stream's controller [Nm/rad, Nm s/rad] for a 7-joint arm (the Panda's
# impedance-controller scale); other arms take the first nv.
KP = np.array([400.0, 400.0, 400.0, 400.0, 60.0, 40.0, 15.0])
KD = np.array([40.0, 40.0, 40.0, 40.0, 5.0, 3.0, 1.0])


@dataclass(frozen=True)
class Touch:
    """One explicit contact: from ``start`` [s] the force ramps over ``rise`` [s] to ``amplitude`` [N]
    along ``direction`` (base axes), holds ``plateau`` [s], ramps back down over ``rise``."""

    start: float
    amplitude: float
    plateau: float
    rise: float = 1e-3
    direction: tuple = (0.0, 0.0, -1.0)


@dataclass(frozen=True)
class StreamConfig:
    """seconds [s] at period dt [s]. contacts: drawn step/trapezoid contacts (None: none); touches:
    explicit :class:`Touch` contacts on top. pose_period [s], pose_spread [rad], ref_time_constant [s]:
    the set point's motion. friction: the plant's joint friction law (None: frictionless). payload:
    (mass kg, (x, y, z) m in tool axes) in the plant. sensors: how the run is read."""

    seconds: float = 12.0
    dt: float = 1e-3
    contacts: ContactStepConfig | None = field(default_factory=ContactStepConfig)
    touches: tuple = ()
    pose_period: float = 2.5
    pose_spread: float = 0.4
    ref_time_constant: float = 0.2
    friction: str | None = "gaz2019"
    payload: tuple | None = None
    sensors: HardwareSensors = field(default_factory=HardwareSensors)


@dataclass
class ControlStream:
    """A simulated stream: ``readings`` as the sensors report them, and the truth: t [s] at the robot's
    exact period, q [rad], qd [rad/s], tip force [N] (n, 3) in base axes. encoder_resolution [rad]: what
    the encoders quantized q to (0: exact), the value to give the estimator (``EstimatorConfig``)."""

    readings: SensorReadings
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tip_force: np.ndarray
    encoder_resolution: float = 0.0


def contact_force(cfg: StreamConfig, contacts: ContactSteps | None, t: np.ndarray) -> np.ndarray:
    """The true tip force [N] (n, 3) at times t: the drawn contacts plus the explicit touches."""
    force = np.zeros((len(t), 3)) if contacts is None else contacts.force(t)
    for touch in cfg.touches:
        u = np.asarray(touch.direction, float)
        force += ContactSteps(np.array([touch.start]), np.array([max(touch.rise, cfg.dt)]),
                              np.array([touch.plateau]), np.array([touch.amplitude]),
                              (u / np.linalg.norm(u))[None]).force(t)
    return force


def simulate_stream(robot: Robot | str = "panda", cfg: StreamConfig = StreamConfig(), seed: int = 0) -> ControlStream:
    """Simulate one stream (deterministic given ``seed``); ``robot`` is the nominal model the controller
    uses (the plant adds ``cfg.payload``)."""
    if not isinstance(robot, Robot):
        robot = load_robot(robot, num_threads=1)
    import pinocchio as pin

    rng = np.random.default_rng(seed)
    plant_robot = robot if cfg.payload is None else load_robot(robot.name, params=robot.params_name,
                                                                payload=cfg.payload, num_threads=1)
    plant = DartPlant(plant_robot, dt=cfg.dt)
    friction = robot.spec.friction(cfg.friction) if cfg.friction else None
    n, nv = int(round(cfg.seconds / cfg.dt)), robot.nv
    t = np.arange(n) * cfg.dt
    contacts = sample_contact_steps(rng, cfg.contacts, cfg.dt) if cfg.contacts is not None else None
    force = contact_force(cfg, contacts, t)
    home = np.array(robot.spec.home)
    poses = [home, np.clip(home + rng.uniform(-cfg.pose_spread, cfg.pose_spread, nv),
                           robot.q_lower + 0.1, robot.q_upper - 0.1)]
    kp, kd = KP[:nv], KD[:nv]
    data = robot.model.createData()
    q, qd, ref = home.copy(), np.zeros(nv), home.copy()
    out_q, out_qd, out_tau, out_w = (np.empty((n, nv)), np.empty((n, nv)), np.empty((n, nv)), np.empty((n, 6)))
    for k in range(n):
        ref += (poses[int(t[k] // cfg.pose_period) % 2] - ref) * (cfg.dt / cfg.ref_time_constant)
        tau = pin.computeGeneralizedGravity(robot.model, data, q) + kp * (ref - q) - kd * qd
        tau_link = tau - friction(qd) if friction is not None else tau  # what the link-side sensor reads
        plant.set_state(q, qd)
        plant.apply_tip_force(force[k])
        plant.step(tau_link)
        out_q[k], out_qd[k], out_tau[k], out_w[k] = q, qd, tau_link, plant.base_wrench()
        q, qd = plant.q, plant.qd
    readings = read_sensors(robot, cfg.sensors, cfg.dt, out_q, out_qd, out_tau, out_w, rng)
    resolution = resolve_encoder_resolution(cfg.sensors.encoder.resolution, robot.spec)
    return ControlStream(readings, t, out_q, out_qd, force, resolution)


__all__ = ["ControlStream", "StreamConfig", "Touch", "contact_force", "simulate_stream"]
