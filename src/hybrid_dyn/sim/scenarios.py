"""The named scenarios of PROTOCOL 2, one registry :data:`SCENARIOS` (a :class:`Scenario` each: its description,
its :class:`~.generator_config.GeneratorConfig` fields, its sizes), and :func:`scenario_config`, a scenario's
config at a size of :data:`SIZES`. What each scenario is and why: docs/scenarios.md.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..description.sensor_noise import NoiseConfig  # the sensors' noise, below sim/ and analytic/
from ..registry import Registry
from .generator_config import (SIZES, ConfigError, ContactStepConfig, GeneratorConfig, StartTouchConfig)
from .sensors import ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors

QUIET_BASE_NOISE = dict(force=0.05, torque=0.0025)  # contact-steps-quiet's base sensor [N, Nm]


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


# The scenarios by name, in declaration order: ``SCENARIOS.register(Scenario(...))`` declares one (scenario_config,
# the CLI and the bench know it from then on), ``SCENARIOS.lookup(name)`` refuses an unknown name, naming the known.
SCENARIOS = Registry("scenario", ConfigError)


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
    # Half the instances touched: at a third (10 instances) the test split held no touch.
    Scenario("contact-steps-hardware", "as contact-steps, a touch inside the first 0.5 s in half of the "
             "instances; hardware sensors (quantized encoders at the robot's resolution with qd their "
             "difference, F/T noise 0.2 N with a 0.025 N/s bias drift, 0.2 ms stamp jitter, tau_J 0.05 Nm)",
             overrides=dict(pulses=None, contact_steps=ContactStepConfig(), record_hz=1000.0,
                            start_touch=StartTouchConfig(share=0.5), **HARDWARE),
             sizes=CONTACT_STEPS_SIZES),
    # The seed's 3.1: a 50 ms step, the simulator's exact states, noise-free sensors.
    Scenario("seed-sim", "as paper-ext, recorded as the seed's 3.1: every 50 ms, exact simulator states "
             "(qdd too), no noise or bias",
             overrides=dict(record_hz=20.0, qdd_source="exact", noise=NoiseConfig.off()),
             sizes=SEED_SIM_SIZES, seed_dataset="sim-ext"),
):
    SCENARIOS.register(_scenario)


def noise_free(name: str) -> dict:
    """The overrides that make scenario ``name``'s sensors ideal (measured fields equal the truth; qdd stays
    an estimate): the legacy noise off, and a hardware sensor model, if it has one, exact."""
    has_hardware = SCENARIOS.lookup(name).overrides.get("sensors") is not None
    return {"noise": NoiseConfig.off(), **({"sensors": HardwareSensors.exact()} if has_hardware else {})}


def scenario_config(name: str, size: str = "quick", seed: int = 0, **overrides) -> GeneratorConfig:
    """The configuration of a named scenario (PROTOCOL 2) at a size (:data:`SIZES`).

    ``overrides`` replace any field, e.g. ``noise=NoiseConfig.off()``.
    """
    scenario = SCENARIOS.lookup(name)
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
