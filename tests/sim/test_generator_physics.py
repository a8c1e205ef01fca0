"""The generator's physics against independent references.

- logged base wrench and tau_J against the analytic core (Pinocchio) of the PLANT robot;
- the logged truth against DART's own integrator (semi-implicit Euler);
- the applied friction against the reference Gaz law in ``description/params.py``;
- sensor noise, the causal acceleration filter, pulses and trajectories against
  their specifications.
"""
import numpy as np
import pytest

from hybrid_dyn.analytic.robot import InputError
from hybrid_dyn.sim.collision import collision_checker
from hybrid_dyn.sim.generator import Simulator, simulate_instance, simulate_reference
from hybrid_dyn.sim.pulses import sample_pulses
from hybrid_dyn.sim.generator_config import ConfigError, GeneratorConfig, NoiseConfig, PulseConfig
from hybrid_dyn.sim.scenarios import noise_free, scenario_config
from hybrid_dyn.sim.sensors import causal_acceleration
from hybrid_dyn.sim.trajectories import motion_valid, random_reference, rrt_connect, time_segment

# Short instances whose pulses surely fall inside them.
SMALL = dict(trajectories=(2, 2), standstill=0.3, speed_scale=(0.4, 0.6),
             pulses=PulseConfig(gap=(0.5, 1.0), sigma=(0.2, 0.4)))


@pytest.fixture(scope="module", params=["paper-ext", "mismatch-ext"])
def noiseless_run(request):
    cfg = scenario_config(request.param, "quick", seed=3, **noise_free(request.param), **SMALL)
    sim = Simulator(cfg)
    run, info = simulate_instance(sim, 0)
    return sim, run, info


def test_logged_base_wrench_equals_analytic_model_of_the_plant(noiseless_run):
    sim, run, _ = noiseless_run
    tr = run.truth
    assert np.abs(tr["tip_force"]).max() > 3.0, "the pulses should act during this instance"
    expected = sim.plant_robot.base_wrench(tr["q"], tr["qd"], tr["qdd"], tip_force=tr["tip_force"])
    np.testing.assert_allclose(run.fields["base_wrench"], expected, atol=1e-6, rtol=0)


def test_logged_tau_J_equals_rnea_minus_jacobian_transpose_force(noiseless_run):
    sim, run, _ = noiseless_run
    tr, pr = run.truth, sim.plant_robot
    jv = pr.tip_jacobian(tr["q"])[:, :3]
    expected = pr.inverse_dynamics(tr["q"], tr["qd"], tr["qdd"]) - np.einsum("nij,ni->nj", jv, tr["tip_force"])
    np.testing.assert_allclose(run.fields["tau_J"], expected, atol=1e-6, rtol=0)


def test_mismatch_plant_differs_from_the_nominal_model(noiseless_run):
    sim, run, _ = noiseless_run
    tr = run.truth
    nominal = sim.nominal.base_wrench(tr["q"], tr["qd"], tr["qdd"], tip_force=tr["tip_force"])
    gap = np.abs(nominal - tr["base_wrench"]).max()
    if sim.config.scenario == "mismatch-ext":
        assert gap > 1.0  # 0.5 kg tool, other inertials, tilted sensor: newtons of difference
    else:
        assert gap < 1e-6


def test_applied_friction_is_the_gaz_law_at_the_logged_velocity(noiseless_run):
    sim, run, _ = noiseless_run
    tr = run.truth
    law = sim.plant_robot.spec.friction("gaz2019")  # the reference implementation
    tau_f = tr["tau_m"] - tr["tau_J"]
    np.testing.assert_allclose(tau_f, law(tr["qd"]), atol=1e-12, rtol=0)
    assert np.abs(tau_f).max() > 0.2  # it really acts


def test_truth_follows_dart_semi_implicit_euler():
    """Recording every step: qd[k+1] = qd[k] + dt qdd[k], q[k+1] = q[k] + dt qd[k+1]."""
    cfg = scenario_config("paper-ext", "quick", record_hz=1000.0, **noise_free("paper-ext"), **SMALL)
    run, _ = simulate_instance(Simulator(cfg), 1)
    tr, dt = run.truth, cfg.dt
    np.testing.assert_allclose(tr["qd"][1:], tr["qd"][:-1] + dt * tr["qdd"][:-1], atol=1e-12, rtol=0)
    np.testing.assert_allclose(tr["q"][1:], tr["q"][:-1] + dt * tr["qd"][1:], atol=1e-12, rtol=0)


def test_sensor_noise_and_bias_match_the_configuration():
    noise = NoiseConfig(q=1e-3, qd=5e-3, tau_J=0.1, force=0.5, torque=0.02, force_bias=2.0, torque_bias=0.1)
    cfg = scenario_config("paper-ext-ideal", "quick", noise=noise, **SMALL)  # the legacy sensor model
    run, _ = simulate_instance(Simulator(cfg), 0)
    f, tr = run.fields, run.truth
    for key, std in (("q", noise.q), ("qd", noise.qd), ("tau_J", noise.tau_J)):
        assert np.std(f[key] - tr[key]) == pytest.approx(std, rel=0.1)
    err = f["base_wrench"] - tr["base_wrench"]
    np.testing.assert_allclose(err.mean(0), run.attrs["base_wrench_bias"], atol=4 * 0.5 / np.sqrt(len(err)))
    assert np.std(err[:, :3] - err[:, :3].mean(0)) == pytest.approx(noise.force, rel=0.1)
    assert np.all(np.abs(run.attrs["base_wrench_bias"][:3]) <= 2.0)
    np.testing.assert_array_equal(f["tau_m"], tr["tau_m"])  # the command is known exactly
    np.testing.assert_array_equal(f["tip_force"], tr["tip_force"])


def test_acceleration_estimate_is_causal_and_tracks_the_truth():
    dt, t = 1e-3, np.arange(4000) * 1e-3
    w = 2 * np.pi * 0.5
    qd = np.stack([np.sin(w * t), np.cos(w * t) - 1.0], 1)
    est = causal_acceleration(qd, dt, cutoff_hz=20.0)
    bumped = qd.copy()
    bumped[2500:] += 1.0
    est_bumped = causal_acceleration(bumped, dt, cutoff_hz=20.0)
    np.testing.assert_array_equal(est[:2500], est_bumped[:2500])  # the future does not leak into the past
    exact = np.stack([w * np.cos(w * t), -w * np.sin(w * t)], 1)
    # After the start transient, a 0.5 Hz signal passes a 20 Hz filter with a few ms of lag.
    assert np.abs(est[1000:] - exact[1000:]).max() < 0.05 * w


def test_estimated_qdd_is_not_the_simulator_acceleration():
    cfg = scenario_config("paper-ext", "quick", **noise_free("paper-ext"), **SMALL)
    run, _ = simulate_instance(Simulator(cfg), 0)
    diff = np.abs(run.fields["qdd"] - run.truth["qdd"])
    assert diff.max() > 1e-3  # a filtered estimate, lagging the truth
    assert np.sqrt(np.mean(diff**2)) < 0.5 * np.sqrt(np.mean(run.truth["qdd"] ** 2))  # but a useful one


def test_tracking_errors_are_physically_plausible():
    cfg = scenario_config("paper-ext", "quick", **SMALL)
    run, _ = simulate_instance(Simulator(cfg), 2)
    assert np.all(run.attrs["tracking_rms"] < 0.02)  # rad
    assert np.all(run.attrs["tracking_max"] < 0.1)
    assert np.all(run.attrs["tracking_max"] > 0)  # friction is not compensated: there is an error


def test_pulse_statistics_match_protocol_3():
    rng = np.random.default_rng(0)
    draws = [sample_pulses(rng) for _ in range(3000)]
    counts = np.array([len(p) for p in draws])
    assert counts.min() == 5 and counts.max() == 15 and set(counts) == set(range(5, 16))
    assert counts.mean() == pytest.approx(10.0, abs=0.2)
    amp = np.concatenate([p.amplitude for p in draws])
    assert np.abs(amp).min() >= 5.0 and np.abs(amp).max() <= 20.0
    assert np.abs(amp).mean() == pytest.approx(12.5, abs=0.15)
    assert np.mean(amp > 0) == pytest.approx(0.5, abs=0.02)
    gaps = np.concatenate([np.diff(np.concatenate([[0.0], p.centre])) for p in draws])
    assert gaps.min() >= 5.0 and gaps.max() <= 10.0 and gaps.mean() == pytest.approx(7.5, abs=0.05)
    sig = np.concatenate([p.sigma for p in draws])
    assert sig.min() >= 0.5 and sig.max() <= 1.5 and sig.mean() == pytest.approx(1.0, abs=0.02)
    u = np.concatenate([p.direction for p in draws])
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(u.mean(0), 0.0, atol=0.02)  # isotropic
    np.testing.assert_allclose(np.mean(u**2, 0), 1 / 3, atol=0.02)


def test_pulse_force_is_the_sum_of_bells():
    p = sample_pulses(np.random.default_rng(1), PulseConfig(count=(5, 5)))
    t = np.concatenate([p.centre, [0.0, p.centre[-1] + 30.0]])
    f = p.force(t)
    for i in range(5):  # at a centre, that bell is at its peak and the neighbours (>= 5 s away) far below
        assert np.linalg.norm(f[i]) == pytest.approx(abs(p.amplitude[i]), rel=1e-3)
        np.testing.assert_allclose(f[i] / p.amplitude[i], p.direction[i], atol=1e-3)
    assert np.abs(f[-1]).max() < 1e-12


def test_reference_respects_limits_standstills_and_collisions(panda):
    checker = collision_checker(panda)
    scale = (0.5, 0.5)
    ref = random_reference(panda, np.random.default_rng(4), 3, dt=1e-3, speed_scale=scale, is_valid=checker)
    lim = lambda name: 0.5 * np.asarray(getattr(panda.spec, name))  # noqa: E731
    assert np.all(np.abs(ref.qd) <= lim("max_velocity") * (1 + 1e-6))
    assert np.all(np.abs(ref.qdd) <= lim("max_acceleration") * (1 + 1e-6))
    jerk = np.diff(ref.qdd, axis=0) / ref.dt  # finite differences, an independent measure
    assert np.all(np.abs(jerk) <= lim("max_jerk") * (1 + 1e-6))
    assert np.all(ref.q >= panda.q_lower) and np.all(ref.q <= panda.q_upper)
    assert all(checker(q) for q in ref.q[::20])
    np.testing.assert_allclose(ref.q[0], panda.spec.home)
    # Standstills: runs of >= 1 s at rest, one before, between and after the 3 trajectories.
    still = np.all(ref.qd == 0, axis=1) & np.all(ref.qdd == 0, axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    runs = edges[1::2] - edges[::2]
    assert np.sum(runs >= 1000) == 4
    # Continuity at the 1 kHz rate: no jumps larger than max velocity x dt.
    assert np.abs(np.diff(ref.q, axis=0)).max() <= 0.5 * 2.61 * 1e-3 + 1e-9


def test_time_segment_stays_on_the_straight_segment_within_limits(panda):
    rng = np.random.default_rng(7)
    V, A, J = (np.asarray(x) for x in (panda.spec.max_velocity, panda.spec.max_acceleration, panda.spec.max_jerk))
    for _ in range(20):
        a, b = rng.uniform(panda.q_lower, panda.q_upper, (2, 7))
        s = rng.uniform(0.1, 0.4)
        q, qd, qdd = time_segment(a, b, s * V, s * A, s * J, 1e-3)
        d = (b - a) / np.linalg.norm(b - a)
        off_line = (q - a) - np.outer((q - a) @ d, d)
        assert np.abs(off_line).max() < 1e-12  # the executed path is the collision-checked one
        assert np.all(np.abs(qd) <= s * V * (1 + 1e-9)) and np.all(np.abs(qdd) <= s * A * (1 + 1e-9))
        assert np.all(np.abs(np.diff(qdd, axis=0)) / 1e-3 <= s * J * (1 + 1e-6))
        np.testing.assert_allclose(q[0], a, atol=1e-15)
        np.testing.assert_allclose(q[-1] + 1e-3 * qd[-1], b, atol=1e-3)  # ends at b, arriving at rest
        # Velocity is the derivative of position (central differences, an independent check).
        np.testing.assert_allclose((q[2:] - q[:-2]) / 2e-3, qd[1:-1], atol=s * A.max() * 1e-3)


def test_rrt_connect_goes_around_an_obstacle():
    """2-D toy: a wall at x = 0 with a gap at y > 0.8; the straight line is blocked."""
    valid = lambda q: not (abs(q[0]) < 0.1 and q[1] < 0.8)  # noqa: E731
    start, goal = np.array([-1.0, -1.0]), np.array([1.0, -1.0])
    assert not motion_valid(start, goal, valid)
    path = rrt_connect(start, goal, valid, np.array([-1.5, -1.5]), np.array([1.5, 1.5]), np.random.default_rng(0))
    assert path is not None
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    for a, b in zip(path[:-1], path[1:]):  # check densely, independent of the planner's resolution
        assert all(valid(a + s * (b - a)) for s in np.linspace(0, 1, 400))


def test_simulate_reference_holds_a_pose_and_rejects_bad_input(panda):
    cfg = scenario_config("paper-noext", "quick", **noise_free("paper-noext"))
    T = 500
    t = np.arange(T) * cfg.dt
    q = np.tile(panda.spec.home, (T, 1))
    z = np.zeros_like(q)
    run = simulate_reference(cfg, t, q, z, z)
    assert run.n_samples == T // cfg.decimation
    # Computed torque on an exact model holds still: only gravity is commanded.
    np.testing.assert_allclose(run.truth["q"], q[::cfg.decimation], atol=1e-9)
    np.testing.assert_allclose(run.fields["tau_m"], panda.gravity(run.truth["q"]), atol=1e-6)
    bad = q.copy()
    bad[3, 2] = np.nan
    with pytest.raises(InputError, match="NaN"):
        simulate_reference(cfg, t, bad, z, z)
    with pytest.raises(InputError, match="shape"):
        simulate_reference(cfg, t, q[:, :6], z, z)
    with pytest.raises(InputError, match="uniformly"):
        simulate_reference(cfg, t * 2, q, z, z)


def test_config_hash_round_trip_and_errors():
    a = scenario_config("mismatch-ext", "default", seed=1)
    assert GeneratorConfig.from_dict(a.to_dict()) == a
    assert GeneratorConfig.from_dict(a.to_dict()).config_hash() == a.config_hash()
    assert scenario_config("mismatch-ext", "default", seed=2).config_hash() != a.config_hash()
    assert scenario_config("paper-ext", "default", seed=1).config_hash() != a.config_hash()
    assert scenario_config("paper-noext", "quick").pulses is None
    with pytest.raises(ConfigError, match="unknown scenario"):
        scenario_config("paper-extra")
    with pytest.raises(ConfigError, match="unknown size .huge.; known: quick, default, paper"):
        scenario_config("paper-ext", "huge")
    with pytest.raises(ConfigError, match="record_hz"):
        scenario_config("paper-ext", record_hz=300.0)
    with pytest.raises(ConfigError, match="override"):
        scenario_config("paper-ext", not_a_field=1)


@pytest.mark.parametrize("option", ["viscous", "coulomb"])
def test_dart_own_joint_friction_option(option):
    """DART's damping is implicit, d (qd + dt qdd); its Coulomb friction never exceeds its bound."""
    extra = {"dart_viscous": (0.5,) * 7} if option == "viscous" else {"dart_coulomb": (0.3,) * 7}
    cfg = scenario_config("paper-ext", "quick", **noise_free("paper-ext"), friction=None, record_hz=1000.0,
                          **SMALL, **extra)
    run, _ = simulate_instance(Simulator(cfg), 0)
    tr = run.truth
    dart_friction = tr["tau_m"] - tr["tau_J"]  # tau_J here is what the motion required (Pinocchio)
    if option == "viscous":
        np.testing.assert_allclose(dart_friction, 0.5 * (tr["qd"] + cfg.dt * tr["qdd"]), atol=1e-9, rtol=0)
    else:
        assert np.abs(dart_friction).max() <= 0.3 + 1e-9
        assert np.abs(dart_friction).max() > 0.29  # it acts, up to its bound
