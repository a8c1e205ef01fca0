"""The overrides that read a scenario by the legacy sensor model it had before the hardware sensors became
every simulated scenario's (white noise on q and qd, a constant bias): the configs whose hashes name the
datasets cached until then, which a new field must leave as they were."""
from hybrid_dyn.sim.generator_config import NoiseConfig
from hybrid_dyn.sim.scenarios import QUIET_BASE_NOISE

LEGACY = {"paper-noext", "paper-ext", "mismatch-ext", "contact-steps", "contact-steps-quiet"}


def legacy(name: str) -> dict:
    """``scenario_config(name, size, **legacy(name))`` is the config scenario ``name`` had then."""
    if name not in LEGACY:
        return {}
    noise = NoiseConfig(**QUIET_BASE_NOISE) if name == "contact-steps-quiet" else NoiseConfig()
    return {"noise": noise, "sensors": None}
