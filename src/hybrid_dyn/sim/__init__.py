"""Simulation: the DART plant and the dataset generator."""
from ..deprecation import module_aliases
from .generator import SimulatedRun, Simulator, generate_dataset, simulate_instance, simulate_reference
from .scenarios import SCENARIOS, SIZES, ConfigError, GeneratorConfig, NoiseConfig, PulseConfig, scenario_config

__all__ = [
    "SCENARIOS", "SIZES", "ConfigError", "GeneratorConfig", "NoiseConfig", "PulseConfig", "SimulatedRun",
    "Simulator", "generate_dataset", "scenario_config", "simulate_instance", "simulate_reference",
]

# PROFILES: the generator sizes' name until issue 30, served with a warning.
__getattr__ = module_aliases(__name__, {"PROFILES": "SIZES"}, globals(), why="generator sizes, not bench profiles")
