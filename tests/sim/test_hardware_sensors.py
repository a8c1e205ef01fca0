"""Sensors as hardware has them (``sim/sensors.py``), the stream simulator on them
(``sim/stream.py``) and the ``contact-steps-hardware`` scenario, each against a truth computed here."""
import json

import h5py
import numpy as np
import pinocchio as pin
import pytest
import scipy.stats

from hybrid_dyn.data import load_dataset
from hybrid_dyn.description import resolve_encoder_resolution
from hybrid_dyn.sim.executors import SerialExecutor
from hybrid_dyn.sim.generator import generate_dataset
from hybrid_dyn.sim.generator_config import SIZES, ConfigError, GeneratorConfig, NoiseConfig, StartTouchConfig
from hybrid_dyn.sim.scenarios import SCENARIOS, noise_free, scenario_config
from hybrid_dyn.sim.sensors import (
    ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors, causal_acceleration, read_sensors)
from hybrid_dyn.sim.stream import StreamConfig, Touch, simulate_stream
from helpers.legacy_sensors import legacy

DT = 1e-3
QUIET = ForceTorqueModel(0.0, 0.0, 0.0, 0.0)  # a base sensor without errors, for the encoder tests


def _read(panda, sensors, q, qd=None, seed=0):
    n, nv = q.shape
    return read_sensors(panda, sensors, DT, q, np.zeros((n, nv)) if qd is None else qd, np.zeros((n, nv)),
                        np.zeros((n, 6)), np.random.default_rng(seed))


def test_quantized_q_lies_on_the_grid_within_half_a_count(panda):
    # The Panda's description states 1e-5 rad (a 19-20 bit absolute encoder): the default takes it.
    assert resolve_encoder_resolution(EncoderModel().resolution, panda.spec) == 1e-5
    rng = np.random.default_rng(1)
    q = np.array(panda.spec.home) + rng.uniform(-1, 1, (5000, panda.nv))
    for res in ("auto", 1e-4):
        r = _read(panda, HardwareSensors(EncoderModel(res), QUIET, ClockModel(), 0.0), q)
        step = 1e-5 if res == "auto" else res
        assert np.abs(r.q - q).max() <= step / 2 * (1 + 1e-9)
        assert np.abs(r.q - q).max() > 0.45 * step  # it does quantize (uniform error over +-step/2)
        counts = r.q / step
        np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    exact = _read(panda, HardwareSensors.exact(), q)
    np.testing.assert_array_equal(exact.q, q)


def test_the_drives_velocity_is_the_difference_of_the_quantized_q(panda):
    t = np.arange(3000) * DT
    q = np.array(panda.spec.home) + 0.3 * np.sin(np.outer(t, np.linspace(0.5, 2.0, panda.nv)))
    r = _read(panda, HardwareSensors(EncoderModel(), QUIET, ClockModel(), 0.0), q)
    np.testing.assert_array_equal(r.qd[1:], np.diff(r.q, axis=0) / DT)
    assert np.all(r.qd[0] == 0.0)  # the first difference has no predecessor
    # Motion makes velocity noise of about a count per period (res / dt = 0.01 rad/s): not white noise
    # measured at standstill.
    qd_true = 0.3 * np.linspace(0.5, 2.0, panda.nv) * np.cos(np.outer(t, np.linspace(0.5, 2.0, panda.nv)))
    err = (r.qd - qd_true)[10:]
    assert 1e-3 < err.std() < 1e-5 / DT


def test_white_encoder_noise_is_drawn_last_at_its_stated_levels(panda):
    """The kinematic test streams' encoders (white noise on q and qd, not quantized): the levels come back,
    and every other reading is the one the same seed gives without encoder noise."""
    n = 20_000
    q = np.tile(panda.spec.home, (n, 1))
    qd = np.full((n, panda.nv), 0.3)
    base = ForceTorqueModel(0.05, 0.0025, 2.0, 0.1)
    noisy = _read(panda, HardwareSensors(EncoderModel(0.0, "exact", noise=1e-5, velocity_noise=2e-4), base,
                                         ClockModel(1e-4), 0.02), q, qd, seed=6)
    clean = _read(panda, HardwareSensors(EncoderModel(0.0, "exact"), base, ClockModel(1e-4), 0.02), q, qd, seed=6)
    assert (noisy.q - q).std() == pytest.approx(1e-5, rel=0.02) and (noisy.qd - qd).std() == pytest.approx(2e-4, rel=0.02)
    for name in ("t", "tau_J", "base_wrench", "bias", "drift"):
        np.testing.assert_array_equal(getattr(noisy, name), getattr(clean, name))
    np.testing.assert_array_equal(clean.q, q)


def test_a_drift_is_recovered_by_a_least_squares_fit(panda):
    n = 12_000  # 12 s at 1 kHz: the 0.3 N over 12 s
    base = ForceTorqueModel(force_noise=0.2, torque_noise=0.01, force_bias=2.0, torque_bias=0.1,
                            force_drift=0.025, torque_drift=0.00125)
    r = _read(panda, HardwareSensors(EncoderModel(0.0, "exact"), base, ClockModel(), 0.0),
              np.tile(panda.spec.home, (n, 1)), seed=4)
    t = np.arange(n) * DT
    A = np.stack([np.ones(n), t], axis=1)
    (intercept, slope), *_ = np.linalg.lstsq(A, r.base_wrench, rcond=None)
    # Slope error per axis: sigma / sqrt(n var(t)) = 0.2 N / 379 s = 5e-4 N/s (force), 2.6e-5 Nm/s (moment).
    assert np.linalg.norm(slope[:3]) == pytest.approx(0.025, abs=2e-3)
    assert np.linalg.norm(slope[3:]) == pytest.approx(0.00125, abs=1.2e-4)
    assert np.all(np.abs(slope - r.drift) <= np.r_[np.full(3, 2e-3), np.full(3, 1.2e-4)])
    assert np.all(np.abs(intercept - r.bias) <= np.r_[np.full(3, 0.02), np.full(3, 1e-3)])
    assert np.all(np.abs(r.bias) <= np.r_[np.full(3, 2.0), np.full(3, 0.1)])
    residual = r.base_wrench - A @ np.stack([intercept, slope])
    np.testing.assert_allclose(residual.std(axis=0), np.r_[np.full(3, 0.2), np.full(3, 0.01)], rtol=0.05)


def test_stamps_jitter_within_their_clip(panda):
    n, sigma, clip = 100_000, 2e-4, 5e-4
    r = _read(panda, HardwareSensors(EncoderModel(0.0, "exact"), QUIET, ClockModel(sigma, clip), 0.0),
              np.tile(panda.spec.home, (n, 1)), seed=5)
    dev = r.t - np.arange(n) * DT
    assert np.abs(dev).max() <= clip + 1e-12 and np.isclose(np.abs(dev).max(), clip)  # some reach the clip
    assert np.diff(r.t).min() >= DT - 2 * clip - 1e-12  # stamps never go back (the clip is half a period)
    # A Gaussian clipped: inside, a truncated normal; outside (probability p), the clip itself.
    a = clip / sigma
    p = 2 * scipy.stats.norm.sf(a)
    expected = np.sqrt((1 - p) * scipy.stats.truncnorm(-a, a, scale=sigma).var() + p * clip**2)
    assert dev.std() == pytest.approx(expected, rel=0.01)
    assert np.mean(np.isclose(np.abs(dev), clip)) == pytest.approx(p, rel=0.15)


def test_the_dart_streams_base_wrench_at_rest_is_the_arms_weight(panda):
    """At rest under gravity compensation the ground carries the arm's weight: (0, 0, m g) and the moment
    c x m g about the base, summed here over Pinocchio's bodies (link 0 too), not by RNEA."""
    cfg = StreamConfig(seconds=0.2, contacts=None, pose_spread=0.0, friction=None, sensors=HardwareSensors.exact())
    s = simulate_stream(panda, cfg, seed=1)
    assert np.abs(s.qd).max() < 1e-9
    model, data = panda.model, panda.model.createData()
    pin.forwardKinematics(model, data, s.q[0])
    force, moment = np.zeros(3), np.zeros(3)
    for i in range(model.njoints):
        f = -model.inertias[i].mass * model.gravity.linear
        force += f
        moment += np.cross(data.oMi[i].act(model.inertias[i].lever), f)
    assert force[2] == pytest.approx(9.81 * sum(model.inertias[i].mass for i in range(model.njoints)))
    np.testing.assert_allclose(s.readings.base_wrench, np.tile(np.r_[force, moment], (len(s.t), 1)), atol=1e-9)


def test_a_touch_during_start_up_is_in_the_streams_force(panda):
    cfg = StreamConfig(seconds=0.6, contacts=None, touches=(Touch(0.1, 6.0, 0.2, rise=0.01),), friction=None)
    s = simulate_stream(panda, cfg, seed=2)
    f = s.tip_force[:, 2]
    np.testing.assert_allclose(f[(s.t > 0.1105) & (s.t < 0.3095)], -6.0)  # pressing down, 6 N
    assert np.all(f[s.t <= 0.1] == 0.0) and np.all(f[s.t >= 0.3205] == 0.0)
    assert np.abs(s.tip_force[:, :2]).max() == 0.0


# config_hash() of every scenario at every size at 9770868 (before the sensors field existed), read by the
# sensor model it had then (helpers.legacy_sensors): every dataset cached until the hardware read's key.
# A new field must leave them as they are.
PINNED_HASHES = {
    "paper-noext": ("75dbbf68f46447e6", "88678398fd60a5a1", "97e1f9b2fcf9f554"),
    "paper-ext": ("6ecc99774227f622", "c6b41661db23d34c", "fda7601b3c28435f"),
    "mismatch-ext": ("32987a0e15391d1d", "59028684ff8f137c", "f007aa9f9d8a0142"),
    "contact-steps": ("32e685f97c5f1394", "08b5ac5828d75541", "6bd82366d4ff6981"),
    "contact-steps-quiet": ("cdfdf267ffabf6f4", "ad4bed041bb9fed8", "b6fe82bba89bca67"),
    "seed-sim": ("9ffff7eaf7dc8e24", "810b0b412ca032f7", "dd419eedfcb86997"),
}
HARDWARE_READ = ("paper-noext", "paper-ext", "mismatch-ext", "contact-steps", "contact-steps-quiet",
                 "contact-steps-hardware")


def test_the_existing_scenarios_keep_their_hashes_at_every_size():
    assert set(PINNED_HASHES) | {"contact-steps-hardware", "paper-ext-ideal"} == set(SCENARIOS)
    for name, hashes in PINNED_HASHES.items():
        assert tuple(scenario_config(name, size, **legacy(name)).config_hash() for size in SIZES) == hashes, name
        assert "start_touch" not in scenario_config(name).to_dict()
    assert "sensors" not in scenario_config("seed-sim").to_dict()


def test_the_simulated_scenarios_are_read_by_hardware_sensors_at_the_robots_resolution():
    pinned = {h for hs in PINNED_HASHES.values() for h in hs}
    for name in HARDWARE_READ:
        cfg = scenario_config(name, "default")
        enc = cfg.to_dict()["sensors"]["encoder"]
        assert cfg.to_dict()["sensors"]["model"] == "hardware" and cfg.noise == NoiseConfig.off(), name
        # The number, not "the robot's": the Panda's description states 1e-5 rad.
        assert enc["resolution"] == 1e-5 and enc["velocity"] == "difference", name
        # A changed sensor model is another dataset: no hash of the legacy-sensor caches is reused.
        assert not {scenario_config(name, s).config_hash() for s in SIZES} & pinned, name
    quiet = scenario_config("contact-steps-quiet").sensors.base
    assert (quiet.force_noise, quiet.torque_noise) == (0.05, 0.0025)
    # The ideal-sensor reference: paper-ext's runs (the same seed and size fields) under the legacy sensors.
    ideal, ext = scenario_config("paper-ext-ideal", "default"), scenario_config("paper-ext", "default")
    assert ideal.sensors is None and ideal.noise == NoiseConfig() and ideal.encoder_resolution == 0.0
    same = {k: v for k, v in ext.to_dict().items() if k not in ("scenario", "noise", "sensors")}
    assert same == {k: v for k, v in ideal.to_dict().items() if k not in ("scenario", "noise")}


def test_the_encoder_resolution_is_the_robots_own():
    # Each robot's description states its own (robots/*.toml): the config records that number.
    for robot, res in (("panda", 1e-5), ("ur5", 2.4e-5), ("xarm7", 4.8e-5)):
        cfg = scenario_config("paper-ext", robot=robot)
        assert cfg.sensors.encoder.resolution == res and cfg.to_dict()["sensors"]["encoder"]["resolution"] == res
    assert scenario_config("paper-ext", robot="ur5").config_hash() != scenario_config("paper-ext").config_hash()
    # A resolution given explicitly is kept.
    given = scenario_config("paper-ext", sensors=HardwareSensors(EncoderModel(resolution=1e-4)))
    assert given.encoder_resolution == 1e-4


def test_the_config_records_its_sensor_model():
    cfg = scenario_config("contact-steps-hardware", "default")
    d = cfg.to_dict()
    assert d["sensors"]["model"] == "hardware" and d["sensors"]["clock"]["jitter"] == 2e-4
    assert cfg.encoder_resolution == 1e-5 and scenario_config("paper-ext-ideal").encoder_resolution == 0.0
    back = GeneratorConfig.from_dict(json.loads(json.dumps(d)))
    assert back == cfg and back.config_hash() == cfg.config_hash()
    with pytest.raises(ConfigError, match="noise must then be NoiseConfig.off"):
        scenario_config("contact-steps-hardware", noise=NoiseConfig())
    # --no-noise: the hardware model made exact (not dropped: the dataset still says which model read it).
    ideal = scenario_config("contact-steps-hardware", **noise_free("contact-steps-hardware"))
    assert ideal.sensors == HardwareSensors.exact() and ideal.to_dict()["sensors"]["model"] == "hardware"
    assert noise_free("paper-ext-ideal") == {"noise": NoiseConfig.off()}


def test_the_hardware_scenario_generates_a_dataset_its_sensors_read(tmp_path):
    # Every instance touched at start-up (share 1), two short instances.
    cfg = scenario_config("contact-steps-hardware", "quick", seed=3, n_instances=2, trajectories=(1, 1),
                          standstill=0.6, start_touch=StartTouchConfig(share=1.0))
    ds = load_dataset(generate_dataset(cfg, tmp_path / "hw", executor=SerialExecutor(), progress=False))
    assert ds.meta["config"]["sensors"]["model"] == "hardware" and ds.meta["config_hash"] == cfg.config_hash()
    for inst in ds.instances.values():
        truth, period = inst.truth, 1e-3
        assert np.abs(inst.q - truth["q"]).max() <= 0.5e-5 * (1 + 1e-9)
        np.testing.assert_allclose(inst.q / 1e-5, np.round(inst.q / 1e-5), rtol=0, atol=1e-6)
        np.testing.assert_array_equal(inst.qd[1:], np.diff(inst.q, axis=0) / period)
        dev = inst.t - truth["t"]
        assert np.abs(dev).max() <= 5e-4 + 1e-12 and dev.std() == pytest.approx(2e-4, rel=0.15)
        with h5py.File(inst.path, "r") as f:
            bias, drift = np.array(f.attrs["base_wrench_bias"]), np.array(f.attrs["base_wrench_drift"])
            touch = json.loads(f.attrs["start_touch"])
        assert np.linalg.norm(drift[:3]) == pytest.approx(0.025)
        noise = inst.base_wrench - truth["base_wrench"] - bias - truth["t"][:, None] * drift
        np.testing.assert_allclose(noise.std(axis=0), np.r_[np.full(3, 0.2), np.full(3, 0.01)], rtol=0.1)
        assert (inst.tau_J - truth["tau_J"]).std() == pytest.approx(0.05, rel=0.1)
        # The touch lies inside the 0.5 s window, the first contact after 1 s plus a gap.
        assert len(touch["start"]) == 1 and touch["start"][0] + 2 * touch["rise"][0] + touch["plateau"][0] < 0.5
        early = np.linalg.norm(inst.tip_force, axis=1)[truth["t"] < 0.5]
        assert early.max() == pytest.approx(touch["amplitude"][0], rel=1e-9)
        assert np.all(np.linalg.norm(inst.tip_force, axis=1)[(truth["t"] > 0.5) & (truth["t"] < 2.0)] == 0.0)


def test_the_log_keeps_every_nth_reading_of_the_drive(panda):
    # q read at 1 kHz, logged at 100 Hz: the log's q and qd are the drive's readings at every 10th step
    # (computed here by hand: round to counts, backward difference over 1 ms), not a difference over 10 ms.
    rng = np.random.default_rng(4)
    t = np.arange(1003) * DT
    q = np.array(panda.spec.home) + 0.3 * np.sin(2 * np.pi * 0.7 * t[:, None] + rng.uniform(0, 6, panda.nv))
    qd = 0.3 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t[:, None] + rng.uniform(0, 6, panda.nv))
    m = 101  # ceil(1003 / 10)
    r = read_sensors(panda, HardwareSensors(EncoderModel(1e-5), QUIET, ClockModel(), 0.0), DT, q, qd,
                     np.zeros((m, panda.nv)), np.zeros((m, 6)), np.random.default_rng(0), every=10)
    counts = np.round(q / 1e-5)
    np.testing.assert_array_equal(r.q, counts[::10] * 1e-5)
    np.testing.assert_allclose(r.qd[1:], (counts[10::10] - counts[9::10]) / DT * 1e-5, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.t, np.arange(m) * 10 * DT)
    assert np.abs(r.qd[1:] - np.diff(r.q, axis=0) / (10 * DT)).max() > 1e-3  # not the logged-rate difference
    with pytest.raises(ValueError, match="the 101 logged samples of 1003 read every 10"):
        read_sensors(panda, HardwareSensors(), DT, q, qd, np.zeros((1003, panda.nv)), np.zeros((1003, 6)),
                     np.random.default_rng(0), every=10)


def test_a_100_hz_scenario_logs_the_drives_readings_and_its_qdd_is_their_derivative(tmp_path):
    cfg = scenario_config("paper-ext", "quick", seed=2, n_instances=1, trajectories=(1, 1), standstill=0.3)
    assert cfg.record_hz == 100.0 and cfg.decimation == 10
    ds = load_dataset(generate_dataset(cfg, tmp_path / "pe", executor=SerialExecutor(), progress=False))
    assert ds.meta["config"]["sensors"]["encoder"]["resolution"] == 1e-5
    inst = next(iter(ds.instances.values()))
    truth, res = inst.truth, 1e-5
    np.testing.assert_allclose(inst.q / res, np.round(inst.q / res), rtol=0, atol=1e-6)  # on the encoder grid
    assert np.abs(inst.q - truth["q"]).max() <= res / 2 * (1 + 1e-9)
    # qd: a whole number of counts per 1 ms (the drive's difference at the control rate), within a count
    # per period plus the half-step lag of the true velocity.
    counts = inst.qd * DT / res
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    lag = 0.5 * DT * np.abs(truth["qdd"]).max() + 0.5 * DT**2 * 200.0  # a generous jerk bound [rad/s^3]
    assert np.abs(inst.qd - truth["qd"])[1:].max() <= res / DT + lag
    # qdd: the causal derivative of the logged qd at the logged period (the one every row reads), never DART's.
    np.testing.assert_allclose(inst.qdd, causal_acceleration(inst.qd, 0.01, cfg.qdd_cutoff_hz), rtol=1e-12, atol=1e-12)
    assert np.abs(inst.qdd - truth["qdd"]).max() > 1e-3
