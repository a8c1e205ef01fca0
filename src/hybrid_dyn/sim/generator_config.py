"""What decides the bytes of a simulated dataset: :class:`GeneratorConfig` (the plant, which may differ from the
nominal model, the trajectories, the controller, friction, external forces, the sensors, rates and the seed).

Its :meth:`~GeneratorConfig.config_hash` is a stable digest of all of that (the benchmark harness caches
datasets by it). The named scenarios that fill it in, at the sizes of :data:`SIZES`: ``scenarios.py``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from ..analytic.robot import Robot, SensorMount, load_robot
from ..description.sensor_noise import NoiseConfig  # the sensors' noise, below sim/ and analytic/
from ..errors import HybridDynError
from .sensors import HardwareSensors

# Bump when the generator's algorithm changes what a config produces.
GENERATOR_VERSION = 1

SIZES = ("quick", "default", "paper")
QDD_SOURCES = ("filter", "exact")


class ConfigError(HybridDynError, ValueError):
    """A generator configuration is inconsistent or names an unknown scenario or size."""


@dataclass(frozen=True)
class PulseConfig:
    """The seed's bell pulses (PROTOCOL 3): ranges of the uniform draws."""

    count: tuple = (5, 15)          # integers, inclusive
    amplitude: tuple = (5.0, 20.0)  # N, with a random sign
    gap: tuple = (5.0, 10.0)        # s between bell centres (the first from t = 0)
    sigma: tuple = (0.5, 1.5)       # s, bell width


@dataclass(frozen=True)
class ContactStepConfig:
    """Step and trapezoid contacts: a force that ramps up in ``rise``, holds
    ``plateau``, ramps down in ``rise`` again, in a uniformly random direction.

    A contact is a step (rise of one control period, 1 ms) with probability
    ``step_fraction``, else a trapezoid with a rise drawn in ``rise``. The first
    contact starts one gap after ``first_after`` (so the tare window stays free).
    """

    count: tuple = (5, 15)           # contacts per instance, integers inclusive
    amplitude: tuple = (3.0, 25.0)   # N
    rise: tuple = (0.001, 0.020)     # s, ramp time of a trapezoid
    plateau: tuple = (0.3, 1.5)      # s
    gap: tuple = (1.0, 3.0)          # s between the end of one contact and the start of the next
    step_fraction: float = 0.5       # share of contacts that are steps (1 ms rise)
    first_after: float = 1.0         # s, no contact before this (the tare window is the first 0.5 s)


@dataclass(frozen=True)
class StartTouchConfig:
    """A touch inside the estimators' 0.5 s start-up (tare) window, in a share of the instances: the
    force ramps up in ``rise``, holds ``plateau``, ramps down, in a uniformly random direction, all
    before ``first_after`` of the contacts. Ranges of uniform draws; the defaults end by 0.49 s."""

    share: float = 1.0 / 3.0          # of the instances that get one
    start: tuple = (0.05, 0.25)       # s
    amplitude: tuple = (3.0, 10.0)    # N
    plateau: tuple = (0.05, 0.20)     # s
    rise: tuple = (0.001, 0.020)      # s


@dataclass(frozen=True)
class GeneratorConfig:
    """Everything that determines a simulated dataset. Units SI unless noted.

    size: the scenario's size (:data:`SIZES`); stored under the key ``profile`` in :meth:`to_dict` (the key every
    cached dataset's hash and manifest has: a file format, kept).
    """

    scenario: str = "paper-ext"
    size: str = "quick"
    robot: str = "panda"
    # Plant (the simulated robot); the controller always uses load_robot(robot).
    plant_params: str | None = None          # parameter set name or JSON path; None: nominal
    payload: tuple | None = None             # (mass kg, (dx, dy, dz) m in tool axes), unmodelled
    sensor_translation: tuple = (0.0, 0.0, 0.0)  # m, true sensor pose vs nominal
    sensor_rotation: tuple = (0.0, 0.0, 0.0)     # rad, rotation vector
    # Trajectories.
    n_instances: int = 6
    trajectories: tuple = (5, 5)             # per instance, uniform integers, inclusive
    # Fraction of the published vel/acc/jerk limits, per trajectory; (0.1, 0.4) makes the paper
    # size's instances ~200 s long on average, as the seed's (3,919,800 samples at 20 Hz / 1000).
    speed_scale: tuple = (0.1, 0.4)
    joint_margin: float = 0.1                # rad kept from each joint limit for goals
    standstill: float = 1.0                  # s at rest before, between and after trajectories
    collision_check: bool = True             # self-collision + floor checked RRT-Connect where a model exists
    # Simulation, control and recording.
    dt: float = 1e-3                         # s, simulation and control period
    record_hz: float = 100.0
    kp: float = 4900.0                       # 1/s^2, computed-torque position gain (omega_n = 70 rad/s)
    kd: float = 140.0                        # 1/s, velocity gain (critically damped)
    friction: str | None = "gaz2019"         # friction law applied in the plant; None: frictionless
    dart_coulomb: tuple | None = None        # Nm per joint: DART's own Coulomb stiction (extra)
    dart_viscous: tuple | None = None        # Nm s/rad per joint: DART's own viscous damping (extra)
    pulses: PulseConfig | None = field(default_factory=PulseConfig)  # None: no external force
    contact_steps: ContactStepConfig | None = None  # step/trapezoid contacts (contact-steps scenario)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    # The sensor model that reads the run: None is the legacy ``noise`` (independent white noise on q and
    # qd, the cached scenarios' model); HardwareSensors (sim/sensors.py) reads it as an arm's sensors do,
    # and then ``noise`` must be off (one sensor model per dataset; the controller reads the true state).
    sensors: HardwareSensors | None = None
    start_touch: StartTouchConfig | None = None  # a touch in the tare window in some instances
    qdd_cutoff_hz: float = 20.0              # low-pass of the causal acceleration estimate
    # Recorded qdd: "filter" (causal estimate from the measured qd, as on a real arm) or
    # "exact" (DART's acceleration at the recorded step, as the seed's simulated data).
    qdd_source: str = "filter"
    seed: int = 0

    def __post_init__(self):
        if self.record_hz <= 0 or self.dt <= 0:
            raise ConfigError("dt and record_hz must be positive")
        ratio = 1.0 / (self.dt * self.record_hz)
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ConfigError(f"record_hz={self.record_hz} must divide the simulation rate {1 / self.dt:g} Hz")
        lo, hi = self.trajectories
        if not (1 <= lo <= hi):
            raise ConfigError(f"trajectories per instance must be 1 <= lo <= hi, got {self.trajectories}")
        if self.n_instances < 1:
            raise ConfigError("n_instances must be >= 1")
        if not (0 < self.speed_scale[0] <= self.speed_scale[1] <= 1):
            raise ConfigError(f"speed_scale must lie in (0, 1], got {self.speed_scale}")
        if self.qdd_cutoff_hz >= 0.5 / self.dt:
            raise ConfigError("qdd_cutoff_hz must be below the Nyquist frequency of the simulation")
        if self.qdd_source not in QDD_SOURCES:
            raise ConfigError(f"qdd_source must be one of {', '.join(map(repr, QDD_SOURCES))}, got {self.qdd_source!r}")
        if self.sensors is not None and self.noise != NoiseConfig.off():
            raise ConfigError("sensors=HardwareSensors(...) reads the run; noise must then be NoiseConfig.off() "
                              "(one sensor model per dataset)")
        if self.sensors is not None and self.sensors.encoder.resolution == "auto":
            # The robot's own resolution, written into the config: its dict, hash and manifest name the number.
            enc = dataclasses.replace(self.sensors.encoder, resolution=_robot_encoder_resolution(self.robot))
            object.__setattr__(self, "sensors", dataclasses.replace(self.sensors, encoder=enc))

    @property
    def decimation(self) -> int:
        """Simulation steps per recorded sample."""
        return int(round(1.0 / (self.dt * self.record_hz)))

    # ------------------------------------------------------------- robots
    def nominal_robot(self) -> Robot:
        """The model the controller and every analytic baseline use."""
        return load_robot(self.robot, num_threads=1)

    def plant_robot(self) -> Robot:
        """The simulated robot, possibly different from the nominal model."""
        return load_robot(self.robot, params=self.plant_params, payload=self.payload,
                          sensor_mount=SensorMount(tuple(self.sensor_translation), tuple(self.sensor_rotation)),
                          num_threads=1)

    # -------------------------------------------------------- (de)serialise
    def to_dict(self) -> dict:
        # The size under its stored key, in its place: the dict is hashed (config_hash) and written to manifests.
        d = {("profile" if k == "size" else k): v for k, v in _jsonable(dataclasses.asdict(self)).items()}
        if d["contact_steps"] is None:
            del d["contact_steps"]  # configs without contacts keep the hashes they had before the field existed
        if d["qdd_source"] == "filter":
            del d["qdd_source"]  # likewise for the default acceleration source
        # Likewise the legacy sensor model and no start-up touch (the cached scenarios' hashes stay).
        for key in ("sensors", "start_touch"):
            if d[key] is None:
                del d[key]
        if self.sensors is not None:
            d["sensors"] = _jsonable(self.sensors.to_dict())  # names its model ("hardware")
        return d

    @property
    def encoder_resolution(self) -> float:
        """The recorded q's resolution [rad]: 0 for the legacy sensor model (q with white noise, not
        quantized), else the hardware encoder's (its own, or the robot description's, resolved when made)."""
        return 0.0 if self.sensors is None else float(self.sensors.encoder.resolution)

    @classmethod
    def from_dict(cls, d: dict) -> "GeneratorConfig":
        """The config of :meth:`to_dict` (a manifest's ``config``): the stored key ``profile`` is the size."""
        d = dict(d)
        if "profile" in d and "size" not in d:
            d["size"] = d.pop("profile")
        if d.get("pulses") is not None:
            d["pulses"] = PulseConfig(**{k: tuple(v) for k, v in d["pulses"].items()})
        if d.get("contact_steps") is not None:
            d["contact_steps"] = ContactStepConfig(**{k: tuple(v) if isinstance(v, list) else v
                                                      for k, v in d["contact_steps"].items()})
        if "noise" in d:
            d["noise"] = NoiseConfig(**d["noise"])
        if d.get("sensors") is not None:
            d["sensors"] = HardwareSensors.from_dict(d["sensors"])
        if d.get("start_touch") is not None:
            d["start_touch"] = StartTouchConfig(**{k: tuple(v) if isinstance(v, list) else v
                                                   for k, v in d["start_touch"].items()})
        for k in ("trajectories", "speed_scale", "sensor_translation", "sensor_rotation", "dart_coulomb", "dart_viscous"):
            if d.get(k) is not None:
                d[k] = tuple(d[k])
        if d.get("payload") is not None:
            d["payload"] = (float(d["payload"][0]), tuple(d["payload"][1]))
        return cls(**d)

    def config_hash(self) -> str:
        """A stable digest of everything that decides the generated bytes."""
        doc = json.dumps({"generator_version": GENERATOR_VERSION, "config": self.to_dict()}, sort_keys=True)
        return hashlib.sha256(doc.encode()).hexdigest()[:16]


def _robot_encoder_resolution(robot: str) -> float:
    """The encoder resolution [rad] the description of ``robot`` states (the hardware sensors' default)."""
    from ..description import RobotDescriptionError, load_spec, parse_robot_name, resolve_encoder_resolution

    try:
        return resolve_encoder_resolution("auto", load_spec(parse_robot_name(robot)[0]))
    except RobotDescriptionError as err:
        raise ConfigError(f"hardware sensors without an encoder resolution take the robot description's: {err}; "
                          "give EncoderModel(resolution=...)") from err


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x
