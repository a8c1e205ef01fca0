"""The seed study's published figures (Kružić et al. 2021), for the report tables.

They come from CoppeliaSim/Newton at 50 ms steps and a real Panda, not from
this toolkit's data: every table labels them as figures from another simulator.
"""

# Table 2: tip-force nets (architectures of Table 1): validation loss, test loss, RMSE [N].
SEED_TABLE2 = {
    "seed-tip-1": (1.6544, 1.6629, 0.6871),
    "seed-tip-2": (0.9637, 0.9513, 0.5036),
    "seed-tip-3": (1.3130, 1.2956, 0.5440),
    "seed-tip-4": (1.1958, 1.1644, 0.4673),
    "seed-tip-5": (1.3665, 1.3101, 0.5047),
    "seed-tip-6": (0.9462, 0.9535, 0.4637),
    "seed-tip-7": (0.4790, 0.4590, 0.3204),
    "seed-tip-8": (0.4868, 0.4776, 0.2740),
    "seed-tip-9": (0.5422, 0.5100, 0.3224),
    "seed-tip-10": (0.1804, 0.1752, 0.1647),
    "seed-tip-11": (0.1788, 0.1649, 0.1533),
}

# Table 1: what each tip-force architecture is (for the table's description column).
SEED_TABLE1 = {
    "seed-tip-1": "MLP, no torques, FC 2x32",
    "seed-tip-2": "MLP, torques, FC 2x32",
    "seed-tip-3": "MLP, torques, FC 2x16",
    "seed-tip-4": "Conv, no torques, FC 2x16, L=10",
    "seed-tip-5": "Conv, no torques, FC 2x16, L=5",
    "seed-tip-6": "Conv, torques, FC 2x16, L=5",
    "seed-tip-7": "LSTM, no torques, FC 2x16, L=10",
    "seed-tip-8": "LSTM, torques, FC 2x16, L=10",
    "seed-tip-9": "LSTM, torques, FC 2x16, L=5",
    "seed-tip-10": "LSTM* 2x32, no torques, FC 2x16, L=10",
    "seed-tip-11": "LSTM* 2x32, torques, FC 2x8, L=10",
}

# Table 3: joint-torque nets. (model, data set) -> (validation loss, test loss, RMSE [Nm]).
SEED_TABLE3 = {
    ("delan", "sim-noext"): (0.6528, 0.6826, 0.5314),
    ("delan", "sim-ext"): (1.2333, 1.2137, 0.7475),
    ("seed-tau-mlp", "sim-ext"): (1.4070, 1.4076, 1.0287),
    ("seed-tau-conv", "sim-ext"): (1.1439, 1.1420, 0.9144),
    ("seed-tau-lstm", "sim-ext"): (0.6208, 0.6236, 0.6189),
    ("delan", "real"): (1.3198, 1.2398, 0.8468),
    ("seed-tau-mlp", "real"): (1.9336, 1.8995, 1.1567),
    ("seed-tau-conv", "real"): (1.4699, 1.4837, 0.9552),
    ("seed-tau-lstm", "real"): (1.1643, 1.0385, 0.7778),
    ("seed-tau-lstm-opt", "sim-ext"): (0.3171, 0.3186, 0.5115),
}

# Gaz et al. 2019: identified model on the real Panda, validation torque RMSE per joint [Nm].
GAZ2019_VALIDATION_RMSE = (0.64, 1.01, 0.77, 0.65, 0.42, 0.20, 0.16)


def seed_dataset_label(scenario: str) -> str | None:
    """Which seed data set a toolkit scenario mirrors (PROTOCOL 2): a simulated scenario's declared
    ``seed_dataset`` (``sim/scenarios.py``), "real" for the real-robot logs, else None."""
    from ..sim.scenarios import SCENARIO_REGISTRY

    if scenario in SCENARIO_REGISTRY:
        return SCENARIO_REGISTRY[scenario].seed_dataset
    if scenario.startswith("real"):
        return "real"
    return None
