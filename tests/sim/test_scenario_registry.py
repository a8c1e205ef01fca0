"""Scenarios declared once: a registry entry is all a new scenario needs, and
mismatch-ext's plant comes from the robot's declared parameter sets."""
import shutil

import numpy as np
import pytest

from hybrid_dyn.description.locations import robots_dir

from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.executors import SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.generator_config import SIZES, ConfigError, NoiseConfig, PulseConfig
from hybrid_dyn.sim.scenarios import SCENARIOS, Scenario, alternative_params, scenario_config
from helpers.legacy_sensors import legacy

TINY_SIZES = {size: dict(n_instances=3, trajectories=(1, 1)) for size in SIZES}


@pytest.fixture
def toy_scenario():
    """A scenario declared in this one place: 50 Hz, no noise, short pulses."""
    toy = SCENARIOS.register(Scenario(
        "toy-50hz", "paper-ext at 50 Hz without noise (a test's toy)",
        overrides=dict(record_hz=50.0, noise=NoiseConfig.off(), standstill=0.2, speed_scale=(0.5, 0.6),
                       pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4))),
        sizes=TINY_SIZES))
    yield toy
    SCENARIOS.unregister(toy.name)


def test_a_declared_scenario_is_generated(toy_scenario, tmp_path):
    assert "toy-50hz" in SCENARIOS  # the names are the registry's, a later entry included
    cfg = scenario_config("toy-50hz", "default", seed=2)
    assert (cfg.record_hz, cfg.n_instances, cfg.trajectories) == (50.0, 3, (1, 1))
    out = generate_dataset(cfg, tmp_path / "toy", executor=SerialExecutor(), progress=False)
    ds = load_dataset(out)
    assert ds.meta["scenario"] == "toy-50hz" and ds.meta["config_hash"] == cfg.config_hash()
    inst = next(iter(ds.instances.values()))
    np.testing.assert_allclose(np.diff(inst.t), 0.02, atol=1e-9)  # the override's 50 Hz, not the default 100
    np.testing.assert_array_equal(inst.q, inst.truth["q"])  # NoiseConfig.off(): measured = true
    shutil.rmtree(out)


def test_a_scenario_missing_a_piece_is_refused_when_declared():
    with pytest.raises(ConfigError, match="no size for paper"):
        Scenario("x", "no paper size", sizes={"quick": TINY_SIZES["quick"], "default": TINY_SIZES["default"]})
    with pytest.raises(ConfigError, match="not_a_field"):
        Scenario("x", "a typo", overrides=dict(not_a_field=1))
    with pytest.raises(ConfigError, match="n_instances"):
        Scenario("x", "sizes belong in sizes", overrides=dict(n_instances=3))
    with pytest.raises(ConfigError, match="declared twice"):
        SCENARIOS.register(Scenario("paper-ext", "again"))


def test_mismatch_plant_is_the_robots_alternative_parameter_set(tmp_path):
    assert alternative_params("panda") == "franka_official"  # robots/panda.toml: default gaz2019
    assert scenario_config("mismatch-ext", robot="panda[tool=none]").plant_params == "franka_official"
    for robot in ("ur5", "xarm7"):  # no set besides the URDF's: refused, naming why
        with pytest.raises(ConfigError, match=f"robot '{robot}' needs exactly one parameter set besides"):
            scenario_config("mismatch-ext", robot=robot)
        # ...unless the plant is given
        assert scenario_config("mismatch-ext", robot=robot, plant_params="x.json").plant_params == "x.json"
    # Another robot's declared set: its own, not the Panda's.
    toml = robots_dir() / "ur5.toml"  # the shipped description (package data)
    own = tmp_path / "arm.toml"
    own.write_text(toml.read_text().replace('name = "ur5"', 'name = "arm"')
                   + '\n[params]\nheavy = "heavy.json"\n')
    assert scenario_config("mismatch-ext", robot=str(own)).plant_params == "heavy"
    two = tmp_path / "two.toml"
    two.write_text(own.read_text() + 'light = "light.json"\n')
    with pytest.raises(ConfigError, match="declares heavy, light"):
        scenario_config("mismatch-ext", robot=str(two))


def test_the_registry_entries_keep_their_hashes():
    """Cached datasets are keyed by these: the registry must produce the configs the if-chain did."""
    assert scenario_config("mismatch-ext", "quick", **legacy("mismatch-ext")).config_hash() == "32987a0e15391d1d"
    assert scenario_config("contact-steps-quiet", "default", **legacy("contact-steps-quiet")).config_hash() == "ad4bed041bb9fed8"
    assert scenario_config("seed-sim", "paper").config_hash() == "dd419eedfcb86997"
    assert scenario_config("paper-noext", "default", **legacy("paper-noext")).config_hash() == "88678398fd60a5a1"
