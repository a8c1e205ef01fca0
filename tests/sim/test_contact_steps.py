"""The contact-steps scenario: step and trapezoid contacts recorded at the 1 kHz control rate."""
import json

import h5py
import numpy as np
from hybrid_dyn.bench.plan import BenchPlan
from hybrid_dyn.data import load_dataset
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.pulses import ContactSteps, sample_contact_steps
from hybrid_dyn.sim.generator_config import ContactStepConfig, GeneratorConfig
from hybrid_dyn.sim.scenarios import scenario_config
from helpers.legacy_sensors import legacy


def test_trapezoid_shape_against_its_closed_form():
    # One contact: start 1 s, rise 10 ms, plateau 0.5 s, 8 N along y.
    c = ContactSteps(np.array([1.0]), np.array([0.01]), np.array([0.5]), np.array([8.0]), np.array([[0.0, 1.0, 0.0]]))
    t = np.array([0.5, 1.0, 1.005, 1.01, 1.3, 1.51, 1.515, 1.52, 2.0])
    expected = np.array([0.0, 0.0, 4.0, 8.0, 8.0, 8.0, 4.0, 0.0, 0.0])
    np.testing.assert_allclose(c.force(t)[:, 1], expected, atol=1e-12)
    assert np.all(c.force(t)[:, [0, 2]] == 0.0)


def test_drawn_contacts_respect_their_ranges():
    cfg = ContactStepConfig()
    c = sample_contact_steps(np.random.default_rng(3), cfg, dt=1e-3)
    assert cfg.count[0] <= len(c) <= cfg.count[1]
    assert np.all((c.amplitude >= 3.0) & (c.amplitude <= 25.0))
    assert np.all((c.plateau >= 0.3) & (c.plateau <= 1.5))
    assert np.all((c.rise >= 1e-3) & (c.rise <= 0.02))
    assert np.any(c.rise == 1e-3) and np.any(c.rise > 1e-3)  # steps and trapezoids
    assert c.start[0] >= cfg.first_after + cfg.gap[0]
    assert np.all(c.start[1:] - c.end[:-1] >= cfg.gap[0] - 1e-12)  # no overlap
    np.testing.assert_allclose(np.linalg.norm(c.direction, axis=1), 1.0)


def test_existing_scenarios_keep_their_config_hashes():
    # The legacy-sensor configs' hashes (the datasets cached before the hardware read); adding the contact
    # field must not move them.
    assert scenario_config("paper-ext", "default", **legacy("paper-ext")).config_hash() == "c6b41661db23d34c"
    assert scenario_config("mismatch-ext", "default", **legacy("mismatch-ext")).config_hash() == "59028684ff8f137c"
    assert scenario_config("paper-noext", "default", **legacy("paper-noext")).config_hash() == "88678398fd60a5a1"


def test_contact_steps_config_round_trips():
    cfg = scenario_config("contact-steps", "quick")
    assert cfg.record_hz == 1000.0 and cfg.pulses is None and cfg.contact_steps is not None
    assert GeneratorConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg


def test_generated_instance_records_the_drawn_contacts_at_1khz(tmp_path):
    cfg = scenario_config("contact-steps", "quick", n_instances=1, trajectories=(1, 1), standstill=0.2,
                          speed_scale=(0.5, 0.6), contact_steps=ContactStepConfig(count=(3, 3), gap=(0.2, 0.4),
                                                                                   plateau=(0.2, 0.3), first_after=0.5))
    generate_dataset(cfg, tmp_path / "cs", workers=1, progress=False)
    ds = load_dataset(tmp_path / "cs")
    inst = next(iter(ds.instances.values()))
    # Sampled every 1 ms; the stamps as a control PC puts them (jittered, at most 0.5 ms off).
    np.testing.assert_allclose(np.diff(inst.truth["t"]), 1e-3, atol=1e-12)
    assert np.abs(inst.t - inst.truth["t"]).max() <= 5e-4 + 1e-12
    with h5py.File(inst.path, "r") as f:
        attrs = json.loads(f.attrs["contact_steps"])
    drawn = ContactSteps(**{k: np.asarray(v) for k, v in attrs.items()})
    # The true tip force is the drawn contacts at the recorded times (the plant applies exactly these).
    np.testing.assert_allclose(inst.truth["tip_force"], drawn.force(inst.truth["t"]), atol=1e-9)
    assert np.max(np.linalg.norm(inst.truth["tip_force"], axis=1)) > 3.0


def test_default_profile_runs_only_the_analytic_rows_on_its_contact_step_scenario():
    from types import SimpleNamespace

    from hybrid_dyn.bench.profiles import PROFILES

    prof = PROFILES.lookup("default")
    cfg = scenario_config("contact-steps-hardware", "default")
    ds = SimpleNamespace(fields=["t", "q", "qd", "qdd", "tau_m", "tau_J", "base_wrench", "tip_force"],
                         meta={"scenario": "contact-steps-hardware", "robot": "panda", "config": cfg.to_dict(),
                               "generator_version": 1})
    applied = {s.family for s in BenchPlan(prof).selected_rows() if BenchPlan(prof).applies(s, ds)}
    assert applied == {"analytic"}
    tip_rows = {s.name for s in BenchPlan(prof).selected_rows() if BenchPlan(prof).applies(s, ds) and s.task == "tip_force"}
    assert "base-wrench-tared" in tip_rows  # the force exists: tip rows run although there are no bell pulses
