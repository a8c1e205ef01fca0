"""The seed-sim scenario: the reference study's own data conditions (its 3.1).

A 50 ms recording step over the 1 kHz simulation, q, qd and qdd exactly the
simulator's (no noise, no filter), no sensor noise or bias. Checked against the
instance's truth, against a re-simulation recorded at every step (DART's
semi-implicit Euler gives its acceleration), against DART's forward dynamics in
a fresh world, and against the analytic model (Pinocchio).
"""
import json

import numpy as np
import pytest

from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.generator import FIELDS, Simulator, generate_dataset, simulate_instance
from hybrid_dyn.sim.plant import DartPlant
from hybrid_dyn.sim.generator_config import ConfigError, GeneratorConfig, NoiseConfig, PulseConfig
from hybrid_dyn.sim.scenarios import scenario_config
from helpers.legacy_sensors import legacy

# One short instance whose bells surely act inside it (seconds to simulate).
TINY = dict(n_instances=1, trajectories=(1, 1), standstill=0.3, speed_scale=(0.5, 0.6), seed=2,
            pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


@pytest.fixture(scope="module")
def seed_sim(tmp_path_factory):
    cfg = scenario_config("seed-sim", "quick", **TINY)
    out = generate_dataset(cfg, tmp_path_factory.mktemp("seed") / "ds", workers=1, progress=False)
    ds = load_dataset(out)
    return cfg, ds, next(iter(ds.instances.values()))


def test_seed_sim_config_is_the_reference_studys_data_conditions():
    for profile in ("quick", "default", "paper"):
        cfg = scenario_config("seed-sim", profile)
        assert cfg.dt == 1e-3 and cfg.record_hz == 20.0 and cfg.decimation == 50  # 1 kHz sim, 50 ms record
        assert cfg.qdd_source == "exact" and cfg.noise == NoiseConfig.off()
        assert cfg.pulses == PulseConfig() and cfg.contact_steps is None  # the reference study's bells
        assert GeneratorConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    assert scenario_config("seed-sim", "default").trajectories == (5, 50)
    assert scenario_config("seed-sim", "paper").n_instances == 1000
    assert scenario_config("seed-sim", "paper").trajectories == (5, 50)


def test_existing_scenarios_keep_their_config_hashes():
    # qdd_source is left out of to_dict at its default: no existing dataset or report changes its name.
    assert scenario_config("paper-ext", "quick", **legacy("paper-ext")).config_hash() == "6ecc99774227f622"
    assert scenario_config("paper-ext", "default", **legacy("paper-ext")).config_hash() == "c6b41661db23d34c"
    assert scenario_config("contact-steps", "default", **legacy("contact-steps")).config_hash() == "08b5ac5828d75541"
    assert "qdd_source" not in scenario_config("mismatch-ext", "default").to_dict()


def test_unknown_qdd_source_is_refused_by_name():
    with pytest.raises(ConfigError, match="qdd_source.*'filtered'"):
        scenario_config("paper-ext", "quick", qdd_source="filtered")


def test_recording_step_is_50_ms(seed_sim):
    cfg, ds, inst = seed_sim
    assert ds.meta["record_hz"] == 20.0 and ds.meta["scenario"] == "seed-sim"
    np.testing.assert_allclose(np.diff(inst.t), 0.05, rtol=0, atol=1e-12)
    assert inst.t[0] == 0.0 and len(inst) > 20


def test_every_recorded_field_equals_its_truth(seed_sim):
    """No noise, no bias, no filter: the bytes of each field are those of its truth."""
    _, _, inst = seed_sim
    for name in FIELDS:
        np.testing.assert_array_equal(inst[name], inst.truth[name], err_msg=name)
    assert np.abs(inst.truth["tip_force"]).max() > 3.0, "the bells should act during this instance"
    assert np.abs(inst.qdd).max() > 0.5, "the arm should accelerate"


def test_recorded_states_are_the_simulators_every_50th_step(seed_sim):
    """An independent re-simulation recorded at every step: seed-sim keeps its steps 0, 50, 100, ...
    and its qdd is the acceleration DART integrated (semi-implicit Euler: qd[k+1] = qd[k] + dt qdd[k])."""
    cfg, _, inst = seed_sim
    fine_cfg = scenario_config("paper-ext", "quick", record_hz=1000.0, noise=NoiseConfig.off(), **TINY)
    fine, _ = simulate_instance(Simulator(fine_cfg), 0)
    tr = fine.truth
    rec = np.arange(0, len(tr["t"]), 50)
    assert len(rec) == len(inst)
    for name in ("q", "qd", "qdd", "base_wrench", "tau_J", "tip_force"):
        np.testing.assert_array_equal(inst[name], tr[name][rec], err_msg=name)
    rec = rec[rec + 1 < len(tr["t"])]
    np.testing.assert_allclose(inst.qdd[: len(rec)], (tr["qd"][rec + 1] - tr["qd"][rec]) / cfg.dt, rtol=0, atol=1e-9)


def test_recorded_qdd_is_darts_forward_dynamics_and_the_analytic_model(seed_sim):
    """In a fresh DART world, the recorded state under the recorded joint force and tip force
    accelerates as recorded; and Pinocchio's RNEA of that state gives the joint force back."""
    cfg, _, inst = seed_sim
    robot = cfg.plant_robot()
    plant = DartPlant(robot, cfg.dt)
    for j in range(0, len(inst), max(1, len(inst) // 8)):
        plant.set_state(inst.q[j], inst.qd[j])
        plant.skel.clearExternalForces()
        plant.apply_tip_force(inst.tip_force[j])
        np.testing.assert_allclose(plant.forward_dynamics(inst.tau_J[j]), inst.qdd[j], rtol=0, atol=1e-8)
    jv = robot.tip_jacobian(inst.q)[:, :3]
    expected = robot.inverse_dynamics(inst.q, inst.qd, inst.qdd) - np.einsum("nij,ni->nj", jv, inst.tip_force)
    np.testing.assert_allclose(inst.tau_J, expected, rtol=0, atol=1e-6)
