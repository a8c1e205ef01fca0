"""Sensor models: what a robot's sensors make of the simulated truth.

The detail (what it computes, the equations, why each choice): docs/design/sim.md, section ``sim/sensors.py``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..analytic.acceleration import causal_acceleration
from ..description.spec import resolve_encoder_resolution


@dataclass(frozen=True)
class EncoderModel:
    """Joint encoders. resolution [rad per count]: q is reported as round(q / resolution) * resolution;
    "auto" takes the robot description's ``encoder_resolution``; 0 reads q exactly.
    velocity: how the drive makes qd: "difference" (the backward difference of the quantized q over the
    nominal period, what libfranka's dq is), "filtered" (that difference through a first-order low-pass
    at ``velocity_cutoff_hz`` [Hz]) or "exact" (the simulator's velocity, an ideal tachometer).
    noise [rad], velocity_noise [rad/s]: white noise on q (before quantizing: an analog encoder's) and on
    the reported qd (a tachometer's); 0 for a digital encoder. The kinematic test streams state the
    white-noise levels their tests were designed on this way."""

    resolution: float | str = "auto"
    velocity: str = "difference"
    velocity_cutoff_hz: float = 0.0
    noise: float = 0.0
    velocity_noise: float = 0.0

    def __post_init__(self):
        if self.velocity not in ("difference", "filtered", "exact"):
            raise ValueError(f"EncoderModel.velocity must be 'difference', 'filtered' or 'exact', got {self.velocity!r}")
        if self.velocity == "filtered" and not self.velocity_cutoff_hz > 0:
            raise ValueError("EncoderModel.velocity='filtered' needs velocity_cutoff_hz > 0 [Hz]")
        if self.resolution != "auto" and not (isinstance(self.resolution, (int, float)) and self.resolution >= 0):
            raise ValueError(f"EncoderModel.resolution must be >= 0 [rad], got {self.resolution!r}")
        if not (self.noise >= 0 and self.velocity_noise >= 0):
            raise ValueError(f"EncoderModel noise levels must be >= 0, got {self.noise!r}, {self.velocity_noise!r}")


@dataclass(frozen=True)
class ForceTorqueModel:
    """The base 6-axis F/T sensor. force_noise [N] / torque_noise [Nm]: white, per axis. force_bias [N] /
    torque_bias [Nm]: a per-stream offset drawn uniformly in [-bias, bias] per axis. force_drift [N/s] /
    torque_drift [Nm/s]: a linear bias drift at that rate along a random direction. delay [s]: the
    sample reaches the controller this late (a whole number of logged periods)."""

    force_noise: float = 0.2
    torque_noise: float = 0.01
    force_bias: float = 2.0
    torque_bias: float = 0.1
    force_drift: float = 0.0
    torque_drift: float = 0.0
    delay: float = 0.0


@dataclass(frozen=True)
class ClockModel:
    """The control PC's timestamps. The robot samples at its own exact period; the stamp a sample gets
    is off by Gaussian jitter of ``jitter`` [s] (sigma), clipped to ``max_jitter`` [s]."""

    jitter: float = 0.0
    max_jitter: float = 5e-4


@dataclass(frozen=True)
class HardwareSensors:
    """Every sensor of a stream as hardware has it. tau_J_noise [Nm]: white noise of the link-side joint
    torque sensors."""

    encoder: EncoderModel = field(default_factory=EncoderModel)
    base: ForceTorqueModel = field(default_factory=ForceTorqueModel)
    clock: ClockModel = field(default_factory=ClockModel)
    tau_J_noise: float = 0.05

    @classmethod
    def exact(cls) -> "HardwareSensors":
        """Ideal sensors: exact q and qd, no noise, bias, drift, delay or jitter."""
        return cls(EncoderModel(0.0, "exact"), ForceTorqueModel(0, 0, 0, 0, 0, 0, 0), ClockModel(0.0), 0.0)

    def to_dict(self) -> dict:
        return {"model": "hardware", **asdict(self)}

    @classmethod
    def from_dict(cls, d: dict) -> "HardwareSensors":
        """The sensors of :meth:`to_dict` (a dataset manifest's ``config.sensors``)."""
        d = dict(d)
        if d.pop("model", "hardware") != "hardware":
            raise ValueError(f"not a hardware sensor model: {d!r}")
        return cls(EncoderModel(**d["encoder"]), ForceTorqueModel(**d["base"]), ClockModel(**d["clock"]),
                   float(d["tau_J_noise"]))


@dataclass
class SensorReadings:
    """A stream as its sensors report it, (n, ...) each: stamps t [s], q [rad], qd [rad/s], tau_J [Nm],
    base_wrench [N, Nm] in the sensor frame; and the base sensor's drawn errors, (6,) each: bias [N, Nm]
    (at t = 0) and drift [N/s, Nm/s] (the generator records them, tests fit against them)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau_J: np.ndarray
    base_wrench: np.ndarray
    bias: np.ndarray | None = None
    drift: np.ndarray | None = None


def read_sensors(robot, sensors: HardwareSensors, dt: float, q, qd, tau_J, base_wrench,
                 rng: np.random.Generator, every: int = 1) -> SensorReadings:
    """What ``sensors`` report of a true run: q, qd (n, nv) sampled every ``dt`` [s] (the control rate, where
    the drive reads its encoders and differences them), and a log that keeps every ``every``-th sample (a
    logger samples, it does not average): link-side joint torques tau_J (m, nv) and the base wrench (m, 6),
    all true, given at those m = ceil(n / every) logged samples. Returns the m logged readings, stamped on
    the logged period ``dt * every``. The draws come from ``rng`` in a fixed order (bias, drift direction,
    F/T noise, torque noise, jitter, then encoder noise where stated), so a seed fixes the stream (with
    ``every=1``, the order and draws of a stream read sample by sample)."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    every = int(every)
    if every < 1:
        raise ValueError(f"read_sensors: every must be a whole number of samples >= 1, got {every!r}")
    m = -(-len(q) // every)
    if len(tau_J) != m or len(base_wrench) != m:
        raise ValueError(f"read_sensors: tau_J and base_wrench need the {m} logged samples of {len(q)} read every "
                         f"{every}, got {len(tau_J)} and {len(base_wrench)}")
    period = dt * every
    b = sensors.base
    scale = np.r_[np.full(3, b.force_bias), np.full(3, b.torque_bias)]
    bias = rng.uniform(-1, 1, 6) * scale
    direction = rng.normal(size=(2, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    t_true = np.arange(m) * period
    drift = np.concatenate([b.force_drift * direction[0], b.torque_drift * direction[1]])
    noise = rng.normal(size=(m, 6)) * np.r_[np.full(3, b.force_noise), np.full(3, b.torque_noise)]
    w = np.asarray(base_wrench, float) + bias + t_true[:, None] * drift + noise
    lag = int(round(b.delay / period))
    if lag:
        w = np.concatenate([np.repeat(w[:1], lag, axis=0), w[:-lag]])
    tau = np.asarray(tau_J, float) + rng.normal(size=(m, q.shape[1])) * sensors.tau_J_noise
    c = sensors.clock
    jitter = np.clip(rng.normal(size=m) * c.jitter, -c.max_jitter, c.max_jitter) if c.jitter > 0 else np.zeros(m)
    q_read, qd_read = _read_encoders(robot, sensors.encoder, dt, q, qd, rng)
    return SensorReadings(t_true + jitter, q_read[::every], qd_read[::every], tau, w, bias, drift)


def _read_encoders(robot, enc: EncoderModel, dt: float, q, qd, rng) -> tuple:
    """(q, qd) as the encoders report them: white noise where stated (drawn last, so that streams without it
    keep their draws), quantized q, and qd exact, the difference, or the filtered difference."""
    n = len(q)
    if enc.noise > 0:
        q = q + rng.normal(size=q.shape) * enc.noise
    n_qd = rng.normal(size=qd.shape) * enc.velocity_noise if enc.velocity_noise > 0 else 0.0
    res = resolve_encoder_resolution(enc.resolution, robot.spec)
    q_read = np.round(q / res) * res if res > 0 else q.copy()
    if enc.velocity == "exact":
        qd_read = qd.copy()
    else:
        qd_read = np.empty_like(q_read)
        qd_read[0] = qd[0] if res == 0 else 0.0  # the drive's first difference has no predecessor
        qd_read[1:] = np.diff(q_read, axis=0) / dt
        if enc.velocity == "filtered":
            a = np.exp(-2 * np.pi * enc.velocity_cutoff_hz * dt)  # first-order low-pass, zero-order hold
            for k in range(1, n):
                qd_read[k] = a * qd_read[k - 1] + (1 - a) * qd_read[k]
    return q_read, qd_read + n_qd


__all__ = ["ClockModel", "EncoderModel", "ForceTorqueModel", "HardwareSensors", "SensorReadings",
           "causal_acceleration", "read_sensors"]
