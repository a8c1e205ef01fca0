"""Simulation: the DART plant and the dataset generator."""
from .generator import SimulatedRun, Simulator, generate_dataset, simulate_instance, simulate_reference
from .scenarios import PROFILES, SCENARIOS, ConfigError, GeneratorConfig, NoiseConfig, PulseConfig, scenario_config

__all__ = [
    "PROFILES", "SCENARIOS", "ConfigError", "GeneratorConfig", "NoiseConfig", "PulseConfig", "SimulatedRun",
    "Simulator", "generate_dataset", "scenario_config", "simulate_instance", "simulate_reference",
]
