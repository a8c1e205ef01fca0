"""Momentum observer on a trajectory integrated independently of the observer.

The plant is M qdd + h = tau + J_v^T F with a constant tip force F, integrated by
scipy's RK45 (tight tolerances) on Pinocchio's ABA. The observer only sees q, qd
and tau sampled at 1 kHz. Theory: r' = K (tau_ext - r), so after 5/K seconds the
error is e^-5 = 0.7 % of F; we require under 1 %.
"""
import numpy as np

from hybrid_dyn.analytic.momentum_observer import MomentumObserver

from helpers.motion import simulate_with_tip_force


def test_observer_converges_to_a_constant_tip_force(panda):
    gain, dt = 50.0, 1e-3
    force = np.array([8.0, -5.0, 12.0])
    t, q, qd, tau = simulate_with_tip_force(panda, force, duration=0.3, dt=dt)
    assert np.ptp(q, axis=0).max() > 0.05 and np.abs(qd).max() > 0.3  # the arm really moves
    f_hat, r = MomentumObserver(panda, gain=gain, dt=dt).run(q, qd, tau)
    # The defining property: r is tau_ext = J_v^T F through a first-order filter K/(s+K).
    tau_ext = np.einsum("nij,i->nj", panda.tip_jacobian(q)[:, :3], force)
    filtered = np.zeros_like(tau_ext)
    for k in range(1, len(t)):
        filtered[k] = filtered[k - 1] + (1 - np.exp(-gain * dt)) * (tau_ext[k - 1] - filtered[k - 1])
    assert np.abs(r - filtered).max() < 0.02 * np.abs(tau_ext).max()
    settled = t >= 5.0 / gain
    rel_err = np.linalg.norm(f_hat[settled] - force, axis=1) / np.linalg.norm(force)
    assert rel_err.max() < 0.01
    # ...and not before: the first samples are a genuine first-order transient.
    assert np.linalg.norm(f_hat[1] - force) / np.linalg.norm(force) > 0.5


def test_observer_streaming_equals_run(panda):
    force = np.array([0.0, 10.0, 0.0])
    _, q, qd, tau = simulate_with_tip_force(panda, force, duration=0.05, dt=1e-3)
    obs = MomentumObserver(panda, gain=30.0, dt=1e-3)
    batch, _ = obs.run(q, qd, tau)
    obs.reset()
    stream = np.stack([obs.step_force(q[i], qd[i], tau[i]) for i in range(len(q))])
    np.testing.assert_allclose(stream, batch, atol=1e-12)


def test_observer_subtracts_a_friction_model(panda):
    """Fed motor torques (link torque + friction), the friction model removes the friction."""
    friction = panda.spec.friction("gaz2019")
    force = np.array([5.0, 5.0, -10.0])
    _, q, qd, tau = simulate_with_tip_force(panda, force, duration=0.3, dt=1e-3)
    tau_motor = tau + friction(qd)
    with_model, _ = MomentumObserver(panda, gain=50.0, dt=1e-3, friction=friction).run(q, qd, tau_motor)
    without, _ = MomentumObserver(panda, gain=50.0, dt=1e-3).run(q, qd, tau_motor)
    assert np.linalg.norm(with_model[-1] - force) < 0.01 * np.linalg.norm(force)
    assert np.linalg.norm(without[-1] - force) > 0.1
