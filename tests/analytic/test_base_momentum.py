"""Base momentum observer (analytic/base_momentum.py) against DART and an independently integrated plant."""
import numpy as np

from hybrid_dyn.analytic.base_momentum import BaseMomentumObserver, wrench_to_tip_force
from hybrid_dyn.analytic.tip_force import SINGULAR_REGION, force_from_external_wrench, tip_force_from_base_wrench
from hybrid_dyn.sim.plant import DartPlant

from helpers.states import random_states


def test_momentum_law_equals_the_base_wrench_method_on_dart(panda):
    """Newton-Euler for the whole robot, d/dt [h; L_O] = W_ground + W_grav + W_ext, on DART's exact
    base wrench and acceleration: the external wrench it gives is [F; p x F], and its force equals
    the base-wrench method with the true acceleration, to 1e-6."""
    plant = DartPlant(panda)
    q, qd, qdd = random_states(panda, 60, seed=11)
    sigma_min = np.linalg.svd(panda.tip_jacobian(q)[:, :3], compute_uv=False)[:, -1]
    keep = sigma_min > SINGULAR_REGION
    q, qd, qdd = q[keep], qd[keep], qdd[keep]
    forces = np.random.default_rng(12).uniform(-20.0, 20.0, (len(q), 3))
    obs = BaseMomentumObserver(panda, dt=1e-3)
    w_ext, wrench = [], []
    for i in range(len(q)):
        plant.inverse_dynamics(q[i], qd[i], qdd[i], tip_force=forces[i])
        wrench.append(plant.base_wrench())
        _, w_grav = obs.momentum_and_gravity(q[i], qd[i])
        w_ext.append(obs.momentum_rate(q[i], qd[i], qdd[i]) - panda.base_wrench_to_root(wrench[-1][None])[0] - w_grav)
    w_ext, wrench = np.array(w_ext), np.array(wrench)
    p = panda.tip_position(q)
    np.testing.assert_allclose(w_ext[:, :3], forces, atol=1e-6, rtol=0)
    np.testing.assert_allclose(w_ext[:, 3:], np.cross(p, forces), atol=1e-6, rtol=0)
    np.testing.assert_allclose(w_ext[:, :3], tip_force_from_base_wrench(panda, q, qd, qdd, wrench), atol=1e-6, rtol=0)


def test_moment_weighted_force_matches_the_equal_weight_least_squares():
    rng = np.random.default_rng(3)
    p, w = rng.normal(size=(20, 3)), rng.normal(size=(20, 6))
    f_equal, _ = force_from_external_wrench(p, -w)  # it takes the ground's change, -W_ext
    np.testing.assert_allclose(wrench_to_tip_force(p, w, 1.0), f_equal, atol=1e-12)
    np.testing.assert_array_equal(wrench_to_tip_force(p, w, 0.0), w[:, :3])
    # A pure tool-point force is recovered exactly at any weight.
    f = rng.normal(size=(20, 3))
    np.testing.assert_allclose(wrench_to_tip_force(p, np.hstack([f, np.cross(p, f)]), 7.0), f, atol=1e-12)


def test_observer_converges_to_the_force_without_acceleration(panda, moving_arm):
    t, q, qd, wrench, force = moving_arm
    assert np.abs(qd).max() > 0.3  # the arm really moves: the momentum changes
    gain = 50.0
    f_hat, r = BaseMomentumObserver(panda, gain, 1e-3).run(q, qd, wrench)
    settled = t >= 5.0 / gain
    # After 5/K the first-order transient is e^-5 = 0.7 %; the trapezoid's error at 1 kHz is far below.
    assert np.abs(f_hat[settled] - force).max() < 0.01 * np.linalg.norm(force)
    assert np.abs(f_hat[-50:] - force).max() < 1e-3
    # All six rows: the moment rows carry p x F through the same filter, so they lag the moving tool
    # point by about |F| |p_dot| / K (here ~10 N x 0.15 m/s / 50/s = 0.03 N): close, not exact.
    f6, _ = BaseMomentumObserver(panda, gain, 1e-3, moment_weight=5.0).run(q, qd, wrench)
    assert 1e-3 < np.abs(f6[-50:] - force).max() < 0.1
    assert np.linalg.norm(f_hat[1] - force) > 0.5 * np.linalg.norm(force)  # a genuine transient first


def test_streaming_equals_batch_and_an_offset_passes_through(panda, moving_arm):
    t, q, qd, wrench, force = moving_arm
    for weight in (0.0, 2.0):
        obs = BaseMomentumObserver(panda, 30.0, 1e-3, moment_weight=weight)
        batch, r_batch = obs.run(q[:120], qd[:120], wrench[:120])
        obs.reset()
        stream = np.stack([obs.step_force(q[i], qd[i], wrench[i]) for i in range(120)])
        np.testing.assert_allclose(stream, batch, atol=1e-9, rtol=0)
    # A sensor offset is an external force to this law: why the bench feeds it a tared wrench.
    offset = np.array([1.5, -1.0, 0.5, 0.0, 0.0, 0.0])
    shifted, _ = BaseMomentumObserver(panda, 50.0, 1e-3).run(q, qd, wrench + offset)
    clean, _ = BaseMomentumObserver(panda, 50.0, 1e-3).run(q, qd, wrench)
    # (an extra ground reading reads as the environment pulling the other way)
    np.testing.assert_allclose((shifted - clean)[-1], -panda._root_from_sensor[:3, :3] @ offset[:3], atol=1e-3)
