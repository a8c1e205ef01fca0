"""Arm motions with a known tip force, built independently of the code under test.

- ``simulate_with_tip_force``: M qdd + h = tau + J_v^T F with a constant F, integrated by scipy's
  RK45 on Pinocchio's ABA (the momentum observers' reference);
- ``sine_motion`` and ``contact_stream``: exact rigid-body samples of per-joint sines and a constant
  contact, read through the project's one sensor model (``sim.sensors.read_sensors``: the streaming
  estimator's and the methods' streams).
"""
import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from hybrid_dyn.sim.sensors import ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors, read_sensors

HZ = 1000.0  # the streams' rate [Hz]


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


def sine_motion(robot, t, rng, amplitude):
    """Per-joint sines about home, amplitude drawn from ``amplitude`` [rad], 0.5-2 rad/s: exact q, qd, qdd."""
    amp, w = rng.uniform(*amplitude, robot.nv), rng.uniform(0.5, 2.0, robot.nv)
    q = np.array(robot.spec.home) + amp * np.sin(w * t[:, None])
    return q, amp * w * np.cos(w * t[:, None]), -amp * w**2 * np.sin(w * t[:, None])


CONTACT = np.array([0.5, -0.6, -0.8]) / np.linalg.norm([0.5, -0.6, -0.8]) * 15.0  # N, from CONTACT_AT
CONTACT_AT = 1.0  # s


# contact_stream's sensors, the levels its tests were designed on: encoders not quantized, with white noise
# of 1e-5 rad on q and 2e-4 rad/s on qd (its tests declare encoder_resolution=0: q and qd used as given), a
# base sensor with 0.05 N (0.0025 Nm) noise and up to 2 N (0.1 Nm) of offset, joint torques at 0.02 Nm.
CONTACT_SENSORS = HardwareSensors(EncoderModel(0.0, "exact", noise=1e-5, velocity_noise=2e-4),
                                  ForceTorqueModel(0.05, 0.0025, 2.0, 0.1), ClockModel(0.0), tau_J_noise=0.02)


def contact_stream(robot, n, hz=HZ, seed=0, contact_at=CONTACT_AT):
    """Rigid-body samples of a smooth motion and a constant 15 N contact from ``contact_at`` [s], read through
    CONTACT_SENSORS: (samples with the sensors' t, true forces)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / hz
    q, qd, qdd = sine_motion(robot, t, rng, (0.05, 0.25))
    f = np.where(t[:, None] >= contact_at, CONTACT, 0.0)
    jv = robot.tip_jacobian(q)[:, :3]
    tau = robot.inverse_dynamics(q, qd, qdd) - np.einsum("nij,ni->nj", jv, f)
    r = read_sensors(robot, CONTACT_SENSORS, 1.0 / hz, q, qd, tau, robot.base_wrench(q, qd, qdd, tip_force=f), rng)
    return [dict(q=r.q[k], qd=r.qd[k], base_wrench=r.base_wrench[k], tau_J=r.tau_J[k], t=r.t[k]) for k in range(n)], f
