"""Simulation: the DART plant and the dataset generator."""
from .generator import generate_dataset
from .instances import simulate_instance
from .generator_config import SIZES, ConfigError, GeneratorConfig, NoiseConfig, PulseConfig
from .scenarios import SCENARIOS, Scenario, scenario_config
from .simulator import SimulatedRun, Simulator, simulate_reference

__all__ = [
    "SCENARIOS", "SIZES", "ConfigError", "GeneratorConfig", "NoiseConfig", "PulseConfig",
    "Scenario", "SimulatedRun", "Simulator", "generate_dataset", "scenario_config", "simulate_instance",
    "simulate_reference",
]

