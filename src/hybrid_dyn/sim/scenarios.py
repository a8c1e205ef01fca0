"""Generator configurations: the named scenarios of PROTOCOL 2 at three sizes (:data:`SIZES`).

A :class:`GeneratorConfig` fixes everything that decides the bytes of a
dataset: the plant (which may differ from the nominal model), the trajectories,
the controller, friction, external pulses, sensor noise, rates and the seed.
Its :meth:`~GeneratorConfig.config_hash` is a stable digest of all of that (the
benchmark harness caches datasets by it).

Scenarios (PROTOCOL 2), each declared once as a :class:`Scenario` in :data:`SCENARIO_REGISTRY`
(its description, its config fields, its sizes; a new one is one :func:`register` call):

=============== ======================================================== ==============
name            plant                                                    external force
=============== ======================================================== ==============
``paper-noext`` URDF inertials (Gaz 2019) + Gaz sigmoid friction         none
``paper-ext``   same                                                     bell pulses
``paper-ext-ideal`` as paper-ext, read by the legacy ideal sensors       as paper-ext
                (:class:`NoiseConfig`): the control
``mismatch-ext``the robot's alternative inertials (the Panda: the        bell pulses
                manufacturer's) + 0.5 kg tool + Gaz friction, base
                sensor mounted 1 mm / 1 deg off its nominal pose
``contact-steps``as paper-ext, recorded at 1 kHz                         step and trapezoid
                                                                         contacts
``contact-steps-quiet`` as contact-steps, base sensor noise 0.05 N      as contact-steps
                (0.0025 Nm) instead of 0.2 N (0.01 Nm)
``contact-steps-hardware`` as contact-steps                              as contact-steps,
                                                                         a touch in the
                                                                         first 0.5 s in 1/3
``seed-sim``    as paper-ext, recorded as the seed's 3.1: every 50 ms,   bell pulses
                exact simulator states (qdd too), no noise or bias
=============== ======================================================== ==============

Sensors: every scenario but ``paper-ext-ideal`` and ``seed-sim`` is read as a real arm's sensors read
it (``GeneratorConfig.sensors``, :data:`HARDWARE_SENSORS`, ``sim/sensors.py``): the plant runs at 1 kHz
and the drive reads its encoders there, q quantized to the robot's encoder resolution (recorded in the
config: the Panda's 1e-5 rad) and qd the difference of it; the log keeps every n-th reading (a sample,
not an average); the base F/T sensor has white noise, a per-run bias and a bias drift, the link-side
torques white noise, the recorded stamps ``t`` a jitter. The controller reads the true state.
``paper-ext-ideal`` is ``paper-ext`` (the same trajectories and pulses: they depend on the seed alone)
read by the legacy :class:`NoiseConfig` (independent white noise on q and qd, a constant bias), the
sensors every scenario had before: the report's row-by-row control of what the hardware read costs.

``contact-steps`` is recorded at the control rate (1 kHz), because a 10 ms sample
step hides what a force step does to an estimator; its instances are fewer and
shorter than the other scenarios' (10x the samples per second).

``contact-steps-quiet`` is the same contacts under a quieter base sensor: the
estimators' bandwidth is chosen from the measured noise (``analytic/bandwidth.py``),
so this is where its answer must change.

``contact-steps-hardware`` adds to ``contact-steps`` a touch inside the tare window in a third of its
instances.

``seed-sim`` reproduces the seed's own data conditions (its section 3.1), so its
Tables 2 and 3 can be met on like data: the plant, controller, pulses and
trajectory rules of ``paper-ext`` still run at 1 kHz, but the recording keeps
every 50th step (20 Hz, the seed's 50 ms step), q, qd and qdd are the
simulator's own (``qdd_source="exact"``: DART's acceleration, no filter) and no
sensor carries noise or bias (``NoiseConfig.off()``), so every recorded field
equals its truth. Its instances hold the seed's 5-50 trajectories.

The controller always uses the nominal model (``load_robot(robot)``), so in
``mismatch-ext`` it is wrong and tracking errors grow: they are reported.

Sizes: ``quick`` (6 short instances, under a minute on 2 cores), ``default``
(40 instances, about 0.36 million samples at 100 Hz) and ``paper`` (the seed's
1000 instances of 5-50 trajectories). A size is not a bench profile (``bench/profiles.py``),
which names scenarios, rows and training; both were once called "profile", and the
old names (``PROFILES``, the ``profile`` keyword and field) still work with a warning. The
config's dictionary, and so its hash and every dataset cached by it, keeps the key ``profile``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from ..analytic.robot import Robot, SensorMount, load_robot
from ..deprecation import module_aliases, renamed_field, renamed_keyword
from ..description.sensor_noise import NoiseConfig  # the sensors' noise, below sim/ and analytic/
from ..errors import HybridDynError
from ..registry import Registry
from .sensors import ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors

# Bump when the generator's algorithm changes what a config produces.
GENERATOR_VERSION = 1

QUIET_BASE_NOISE = dict(force=0.05, torque=0.0025)  # contact-steps-quiet's base sensor [N, Nm]
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


@renamed_field("profile", "size", why="a generator size, not a bench profile")
@dataclass(frozen=True)
class GeneratorConfig:
    """Everything that determines a simulated dataset. Units SI unless noted.

    size: the scenario's size (:data:`SIZES`); stored as ``profile`` in :meth:`to_dict` (module docstring).
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

    @property
    def has_external_force(self) -> bool:
        return self.pulses is not None or self.contact_steps is not None

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


# ------------------------------------------------------------------ the scenarios
# Generator sizes: instances and trajectories per instance, by size name (SIZES).
STANDARD_SIZES = {
    "quick": dict(n_instances=6, trajectories=(5, 5)),
    "default": dict(n_instances=40, trajectories=(5, 20)),
    "paper": dict(n_instances=1000, trajectories=(5, 50)),
}
# contact-steps records at 1 kHz: fewer, shorter instances (the default size is ~0.5 M samples).
CONTACT_STEPS_SIZES = {
    "quick": dict(n_instances=4, trajectories=(2, 2)),
    "default": dict(n_instances=10, trajectories=(3, 5)),
    "paper": dict(n_instances=100, trajectories=(5, 20)),
}
# seed-sim records at 20 Hz: the seed's 5-50 trajectories from `default` on (~200 s per instance,
# ~4.1 k samples; the seed: 3,919,800 / 1000). default: 40 instances, ~2.3 h simulated,
# ~0.16 M samples, ~5 min on 2 free cores (10 on a shared machine); paper: the seed's 1000 instances,
# ~4 M samples (the seed: 3.9 M). quick: 6 instances of 5 trajectories, ~4.6 k samples, seconds.
SEED_SIM_SIZES = {
    "quick": dict(n_instances=6, trajectories=(5, 5)),
    "default": dict(n_instances=40, trajectories=(5, 50)),
    "paper": dict(n_instances=1000, trajectories=(5, 50)),
}

# The simulated scenarios' sensors (all but paper-ext-ideal and seed-sim): the robot description's encoder
# resolution (the Panda: 1e-5 rad; GeneratorConfig writes the number into its config), qd the drive's
# difference of it, link-side torques at 0.05 Nm, the base F/T sensor at 0.2 N / 0.01 Nm white noise with a
# per-stream bias and a drift of 0.025 N/s (0.3 N over 12 s) and 0.00125 Nm/s, stamps jittered by 0.2 ms (sigma, clipped at 0.5 ms).
HARDWARE_SENSORS = HardwareSensors(
    encoder=EncoderModel(resolution="auto", velocity="difference"),
    base=ForceTorqueModel(force_noise=0.2, torque_noise=0.01, force_bias=2.0, torque_bias=0.1,
                          force_drift=0.025, torque_drift=0.00125),
    clock=ClockModel(jitter=2e-4, max_jitter=5e-4),
    tau_J_noise=0.05)
# contact-steps-quiet's: the same with the quieter base sensor.
QUIET_HARDWARE_SENSORS = dataclasses.replace(HARDWARE_SENSORS, base=dataclasses.replace(
    HARDWARE_SENSORS.base, force_noise=QUIET_BASE_NOISE["force"], torque_noise=QUIET_BASE_NOISE["torque"]))
HARDWARE = dict(noise=NoiseConfig.off(), sensors=HARDWARE_SENSORS)  # a scenario's overrides: read as hardware

# mismatch-ext: the unmodelled tool and the misaligned sensor.
MISMATCH_PAYLOAD = (0.5, (0.01, 0.0, -0.04))  # kg; m from panda_hand_tcp, between the fingers and the flange
MISMATCH_SENSOR_TRANSLATION = (0.001, 0.0, 0.0)  # 1 mm
MISMATCH_SENSOR_ROTATION = tuple(float(v) for v in np.deg2rad(1.0) * np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0))  # 1 deg tilt


@dataclass(frozen=True)
class Scenario:
    """One named scenario: everything that distinguishes it, declared in one place.

    name: what ``scenario_config``, the CLI and the bench call it. description: the plant
    and the external force, one line (what ``hybrid-dyn simulate --help`` and the docs say).
    overrides: :class:`GeneratorConfig` fields on top of the defaults. sizes: generator size
    (each of :data:`SIZES`) -> ``n_instances`` and ``trajectories``. seed_dataset: the
    seed study's data set it mirrors ("sim-noext", "sim-ext"; None: none), for the bench's
    comparison with the seed's published tables. alternative_plant: the plant's inertials
    are the robot's alternative parameter set (:func:`alternative_params`), not the nominal
    one the controller uses; a robot that declares none is refused.
    """

    name: str
    description: str
    overrides: dict = field(default_factory=dict)
    sizes: dict = field(default_factory=lambda: dict(STANDARD_SIZES))
    seed_dataset: str | None = None
    alternative_plant: bool = False

    def __post_init__(self):
        fields = {f.name for f in dataclasses.fields(GeneratorConfig)}
        # The name, the size and the seed are scenario_config's arguments, the sizes this entry's own.
        reserved = {"scenario", "size", "profile", "seed", "n_instances", "trajectories"}
        bad = sorted(set(self.overrides) - fields) + sorted(reserved & set(self.overrides))
        if bad:
            raise ConfigError(f"scenario {self.name!r}: overrides {bad} are not GeneratorConfig fields it may set")
        missing = [p for p in SIZES if p not in self.sizes]
        if missing:
            raise ConfigError(f"scenario {self.name!r}: no size for {', '.join(missing)} (sizes: {', '.join(SIZES)})")
        for size, kw in self.sizes.items():
            if set(kw) != {"n_instances", "trajectories"}:
                raise ConfigError(f"scenario {self.name!r}, size {size!r}: give n_instances and trajectories, got {sorted(kw)}")
        if self.alternative_plant and "plant_params" in self.overrides:
            raise ConfigError(f"scenario {self.name!r}: alternative_plant and a plant_params override contradict")


SCENARIO_REGISTRY = Registry("scenario", ConfigError)  # name -> Scenario
SCENARIOS = SCENARIO_REGISTRY.keys()  # the scenarios' names in declaration order, a live view
register = SCENARIO_REGISTRY.register  # declare a scenario: scenario_config, the CLI and the bench know it
unregister = SCENARIO_REGISTRY.unregister  # remove one (a test's toy)
get_scenario = SCENARIO_REGISTRY.lookup  # a scenario by name; an unknown one is refused, naming the known ones


def alternative_params(robot: str) -> str:
    """The name of ``robot``'s alternative parameter set: the one set its description
    (``robots/<name>.toml``, ``[params]``) declares besides its default. The Panda's is
    ``franka_official`` (the manufacturer's inertials; its default is Gaz et al. 2019's)."""
    from ..description import RobotDescriptionError, load_spec, parse_robot_name

    try:
        spec = load_spec(parse_robot_name(robot)[0])
    except RobotDescriptionError as err:
        raise ConfigError(f"a plant from an alternative parameter set needs a robot description: {err}") from err
    others = [name for name in spec.param_sets if name != spec.default_params]
    if len(others) != 1:
        found = f"declares {', '.join(others)}" if others else "declares none"
        raise ConfigError(f"robot {spec.name!r} needs exactly one parameter set besides its default "
                          f"({spec.default_params or 'the URDF'}) for a mismatched plant, and {found} "
                          f"({spec.source}, [params]); or give plant_params=NAME or a JSON path")
    return others[0]


for _scenario in (
    Scenario("paper-noext", "URDF inertials (Gaz 2019) + Gaz sigmoid friction; no external force; hardware sensors",
             overrides=dict(pulses=None, **HARDWARE), seed_dataset="sim-noext"),
    Scenario("paper-ext", "as paper-noext, with the seed's bell pulses at the tool", overrides=dict(HARDWARE),
             seed_dataset="sim-ext"),
    Scenario("paper-ext-ideal", "as paper-ext (the same runs), read by the legacy ideal sensors: white noise on q "
             "and qd, a constant base-sensor bias (the control of the hardware read)"),
    Scenario("mismatch-ext", "the robot's alternative inertials + a 0.5 kg tool + Gaz friction, the base sensor "
             "1 mm / 1 deg off its nominal pose; bell pulses; hardware sensors",
             overrides=dict(payload=MISMATCH_PAYLOAD, sensor_translation=MISMATCH_SENSOR_TRANSLATION,
                            sensor_rotation=MISMATCH_SENSOR_ROTATION, **HARDWARE),
             seed_dataset="sim-ext", alternative_plant=True),
    Scenario("contact-steps", "as paper-ext, recorded at 1 kHz; step and trapezoid contacts instead of pulses",
             overrides=dict(pulses=None, contact_steps=ContactStepConfig(), record_hz=1000.0, **HARDWARE),
             sizes=CONTACT_STEPS_SIZES),
    Scenario("contact-steps-quiet", "as contact-steps, the base sensor's noise 0.05 N (0.0025 Nm) instead of "
             "0.2 N (0.01 Nm)",
             overrides=dict(pulses=None, contact_steps=ContactStepConfig(), record_hz=1000.0,
                            noise=NoiseConfig.off(), sensors=QUIET_HARDWARE_SENSORS),
             sizes=CONTACT_STEPS_SIZES),
    Scenario("contact-steps-hardware", "as contact-steps, a touch inside the first 0.5 s in a third of the "
             "instances; hardware sensors (quantized encoders at the robot's resolution with qd their "
             "difference, F/T noise 0.2 N with a 0.025 N/s bias drift, 0.2 ms stamp jitter, tau_J 0.05 Nm)",
             overrides=dict(pulses=None, contact_steps=ContactStepConfig(), record_hz=1000.0,
                            start_touch=StartTouchConfig(), **HARDWARE),
             sizes=CONTACT_STEPS_SIZES),
    # The seed's 3.1: a 50 ms step, the simulator's exact states, noise-free sensors.
    Scenario("seed-sim", "as paper-ext, recorded as the seed's 3.1: every 50 ms, exact simulator states "
             "(qdd too), no noise or bias",
             overrides=dict(record_hz=20.0, qdd_source="exact", noise=NoiseConfig.off()),
             sizes=SEED_SIM_SIZES, seed_dataset="sim-ext"),
):
    register(_scenario)


def noise_free(name: str) -> dict:
    """The overrides that make scenario ``name``'s sensors ideal (measured fields equal the truth; qdd stays
    an estimate): the legacy noise off, and a hardware sensor model, if it has one, exact."""
    has_hardware = get_scenario(name).overrides.get("sensors") is not None
    return {"noise": NoiseConfig.off(), **({"sensors": HardwareSensors.exact()} if has_hardware else {})}


@renamed_keyword("profile", "size", why="a generator size, not a bench profile")
def scenario_config(name: str, size: str = "quick", seed: int = 0, **overrides) -> GeneratorConfig:
    """The configuration of a named scenario (PROTOCOL 2) at a size (:data:`SIZES`).

    ``overrides`` replace any field, e.g. ``noise=NoiseConfig.off()``.
    """
    scenario = get_scenario(name)
    if size not in SIZES:
        raise ConfigError(f"unknown size {size!r}; known: {', '.join(SIZES)}")
    kw = dict(scenario=name, size=size, seed=int(seed), **scenario.sizes[size], **scenario.overrides)
    # mismatch-ext's plant: the robot's own alternative set (a plant_params override wins).
    if scenario.alternative_plant and "plant_params" not in overrides:
        kw["plant_params"] = alternative_params(overrides.get("robot", GeneratorConfig.robot))
    kw.update(overrides)
    try:
        return GeneratorConfig(**kw)
    except TypeError as err:
        raise ConfigError(f"bad generator override: {err}") from err


# The old name of SIZES, served with a warning.
__getattr__ = module_aliases(__name__, {"PROFILES": "SIZES"}, globals(), why="generator sizes, not bench profiles")
