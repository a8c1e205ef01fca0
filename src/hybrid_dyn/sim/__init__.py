"""Simulation: the DART plant and the dataset generator."""
from .generator import SimulatedRun, Simulator, generate_dataset, simulate_instance, simulate_reference
from .scenarios import (
    PROFILES, SCENARIO_REGISTRY, SCENARIOS, ConfigError, GeneratorConfig, NoiseConfig, PulseConfig, Scenario,
    scenario_config,
)

__all__ = [
    "PROFILES", "SCENARIOS", "SCENARIO_REGISTRY", "ConfigError", "GeneratorConfig", "NoiseConfig", "PulseConfig",
    "Scenario", "SimulatedRun", "Simulator", "generate_dataset", "scenario_config", "simulate_instance",
    "simulate_reference",
]
