"""Momentum observer on a trajectory integrated independently of the observer.

The plant is M qdd + h = tau + J_v^T F with a constant tip force F, integrated by
scipy's RK45 (tight tolerances) on Pinocchio's ABA. The observer only sees q, qd
and tau sampled at 1 kHz. Theory: r' = K (tau_ext - r), so after 5/K seconds the
error is e^-5 = 0.7 % of F; we require under 1 %.
"""
import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from hybrid_dyn.analytic.momentum_observer import MomentumObserver


def simulate_with_tip_force(robot, force, duration, dt):
    model, data = robot.model, robot.model.createData()
    q0 = np.array(robot.spec.home)
    fid = robot.tool_frame_id

    def torque(t, q, qd):
        # A PD-stabilised arm that compensates gravity and the (known) load, plus a
        # smooth excitation: it moves by several hundredths of a radian at up to
        # 0.5 rad/s, so C^T qd matters, while tau_ext = J_v^T F changes slowly:
        # the observer's lag error, about |d tau_ext/dt| / K, stays well under 1 %.
        jv = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        pd = 20.0 * (q0 - q) - 3.0 * qd
        return pin.computeGeneralizedGravity(model, data, q) - jv.T @ force + pd + 2.0 * np.sin(2 * np.pi * 1.3 * t + np.arange(robot.nv))

    def rhs(t, x):
        q, qd = x[: robot.nv], x[robot.nv:]
        jv = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        qdd = pin.aba(model, data, q, qd, torque(t, q, qd) + jv.T @ force)
        return np.concatenate([qd, qdd])

    t = np.arange(0.0, duration, dt)
    sol = solve_ivp(rhs, (0.0, t[-1]), np.concatenate([q0, np.zeros(robot.nv)]), t_eval=t, rtol=1e-10, atol=1e-12)
    q, qd = sol.y[: robot.nv].T, sol.y[robot.nv:].T
    tau = np.stack([torque(ti, qi, qdi) for ti, qi, qdi in zip(t, q, qd)])
    return t, q, qd, tau


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
