"""Ground-truth streams for the estimator's status: the cases where a control loop must not be told ``ok``.

Each stream is exact rigid-body kinematics (per-joint sines about the home pose, gated on and off
smoothly, so the arm stands still or moves on a schedule) and the robot's own model as the truth:
joint torques tau = ID(q, qd, qdd) - J_v^T F, the base wrench ``Robot.base_wrench(..., tip_force=F)``
(a force away from the tool: its own Jacobian and moment arm), read through ``sensors.read_sensors``
(q quantized to the description's resolution, qd its difference, F/T and torque noise, bias, drift,
stamp jitter). Faults are applied to the readings after that: a flipped sign, a frozen sensor, lost
samples, joint-torque sensor offsets and their drift. :data:`CASES` names them; ``benchmarks/estimator_trust.py`` scores every method on each, the
tests run short versions.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .sensors import ClockModel, EncoderModel, ForceTorqueModel, HardwareSensors, read_sensors

TAU_OFFSET = (0.3, 1.5)  # [Nm]: the per-joint torque-sensor offset's magnitude, drawn uniformly, random sign
TAU_DRIFT = 0.005  # [Nm/s]: the per-joint torque-sensor offset's drift rate, random sign
CLIP_MARGIN = 1.0  # [N]
HARDWARE = HardwareSensors(EncoderModel("auto", "difference"), ForceTorqueModel(force_drift=0.025, torque_drift=0.0))


@dataclass(frozen=True)
class TrustCase:
    """seconds [s] at 1 kHz. force: ((t [s], |F| [N]), ...) breakpoints of the contact's magnitude, linear
    between them (a step: two points 1 ms apart) along ``direction``; moving: ((start, stop) [s], ...) when
    the arm moves (0.2 s smooth ramps). fault: None, "flip-base", "freeze-base" (from fault_at [s]),
    "flip-tau", "elbow" (the force acts on the elbow, not the tool), "gap" (5 samples lost at fault_at),
    "tau-offset" (a per-joint torque-sensor offset, TAU_OFFSET), "tau-drift" (a per-joint offset drifting at
    TAU_DRIFT from 0), "clip-base" (the base sensor's Fz channel clipped at CLIP_MARGIN beyond the largest
    magnitude it reads without the contact: a range of +-that).
    declared_resolution: what the estimator is told [rad] ("auto": the description's). amplitude: the range
    [rad] the per-joint sines' amplitudes are drawn from (``kinematics``)."""

    seconds: float
    force: tuple = ()
    direction: tuple = (0.3, -0.2, -1.0)
    moving: tuple = ()
    sensors: HardwareSensors = field(default_factory=lambda: HARDWARE)
    fault: str | None = None
    fault_at: float = 0.0
    declared_resolution: float | str = "auto"
    amplitude: tuple = (0.05, 0.2)


def _ramp(t0, t1, top, hold, seconds):
    """0 -> top linearly over [t0, t1], held for ``hold`` [s], released in 1 ms."""
    return ((0.0, 0.0), (t0, 0.0), (t1, top), (t1 + hold, top), (t1 + hold + 1e-3, 0.0), (seconds, 0.0))


def _staircase(start, step, every, count, seconds):
    pts = [(0.0, 0.0), (start, 0.0)]
    for i in range(count):
        a = start + i * every
        pts += [(a + 1e-3, (i + 1) * step), (a + every, (i + 1) * step)]
    end = start + count * every
    return tuple(pts + [(end + 1e-3, 0.0), (seconds, 0.0)])


def _steps(times, amplitude, width, seconds):
    pts = [(0.0, 0.0)]
    for a in times:
        pts += [(a, 0.0), (a + 1e-3, amplitude), (a + width, amplitude), (a + width + 1e-3, 0.0)]
    return tuple(pts + [(seconds, 0.0)])


CASES = {
    # 1. a contact that builds slowly at standstill, held, released; the arm moves from 30 s.
    "slow-ramp": TrustCase(40.0, _ramp(2.0, 22.0, 6.0, 4.0, 40.0), moving=((30.0, 40.0),)),
    "staircase": TrustCase(30.0, _staircase(2.0, 0.8, 3.0, 6, 30.0), moving=((24.0, 30.0),)),
    # 2. the toolkit's own jitter clock: stamps about the robot's clock by 0.2 ms, up to 0.5 ms.
    "jitter": TrustCase(12.0, _steps((3.0, 7.0), 10.0, 2.0, 12.0), moving=((1.0, 12.0),),
                        sensors=replace(HARDWARE, clock=ClockModel(2e-4, 5e-4))),
    # 3. 120 s of motion with the base sensor drifting 0.025 N/s: no standstill, so no re-tare.
    "drift-motion": TrustCase(120.0, moving=((0.6, 120.0),)),
    # 4. sensor faults, with a 10 N contact held 4-8 s.
    "flip-base": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), fault="flip-base"),
    "freeze-base": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), fault="freeze-base",
                             fault_at=2.0),
    "flip-tau": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), fault="flip-tau"),
    "elbow-push": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), direction=(0.0, 1.0, 0.0), moving=((1.0, 10.0),),
                            fault="elbow"),
    # 5. five samples lost inside a contact, the arm moving.
    "gap": TrustCase(10.0, _steps((3.0,), 12.0, 4.0, 10.0), moving=((1.0, 10.0),), fault="gap", fault_at=4.0),
    # 6. moving from t = 0: a press through the start-up window, released at 3 s; a drift of 0.05 N/s.
    "press-moving": TrustCase(12.0, ((0.0, 10.0), (3.0, 10.0), (3.001, 0.0), (12.0, 0.0)), moving=((0.0, 12.0),)),
    "drift-fast": TrustCase(60.0, _steps((10.0, 30.0, 50.0), 8.0, 2.0, 60.0), moving=((0.0, 60.0),),
                            sensors=replace(HARDWARE, base=ForceTorqueModel(force_drift=0.05, torque_drift=0.0))),
    # 8. ten minutes at a standstill, nothing touching the tool, the base sensor drifting at its stated 0.025 N/s:
    # the drift follower's tare, and its error bar, over a long wait.
    "standstill-drift": TrustCase(600.0),
    # 7. exact q, moving from t = 0, the estimator's defaults (it assumes 1e-5 rad encoders).
    # 9. joint-torque sensor offsets: random ones (at rest in the window, moving from 1 s), and ones drifting for
    # 120 s (20 s at a standstill in between, a contact held there).
    "tau-offset": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), fault="tau-offset"),
    "tau-drift": TrustCase(120.0, _steps((20.0, 60.0, 100.0), 8.0, 4.0, 120.0), moving=((0.6, 50.0), (70.0, 120.0)),
                           fault="tau-drift"),
    # 10. the base sensor's Fz channel clipped at its range while a contact pushes it beyond, at a standstill.
    "clip-base": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), fault="clip-base"),
    # 11. moving from the first sample, nothing touching it in the documented first 0.5 s, a 3.9 N contact from
    # 0.501 s (inside the start-up window, which waits for the joint-state filter) to 4 s.
    "start-contact": TrustCase(8.0, ((0.0, 0.0), (0.501, 0.0), (0.502, 3.9), (4.0, 3.9), (4.001, 0.0), (8.0, 0.0)),
                               moving=((0.0, 8.0),)),
    # 12. fast starts and stops: up to ~1 rad/s per joint, five times 1 s of motion, no contact.
    "fast-starts": TrustCase(10.0, moving=((0.6, 1.6), (2.6, 3.6), (4.6, 5.6), (6.6, 7.6), (8.6, 9.6)),
                             amplitude=(0.3, 0.5)),
    "start-moving": TrustCase(10.0, _steps((4.0,), 10.0, 2.0, 10.0), moving=((0.0, 10.0),),
                              sensors=replace(HARDWARE, encoder=EncoderModel(0.0, "exact"))),
}


@dataclass
class TrustStream:
    """The readings (t, q, qd, base_wrench, tau_J: (n, ...)), the true tip force (n, 3) [N] at the tool,
    the times of every contact change [s], and which samples arrive (False: lost)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    base_wrench: np.ndarray
    tau_J: np.ndarray
    force: np.ndarray
    changes: np.ndarray
    arrives: np.ndarray
    encoder_resolution: float | str = "auto"


def _gate(t, windows, ramp=0.2):
    """The motion's clock rate in [0, 1] and its derivative: 1 inside each window, cosine ramps at its ends."""
    g, dg = np.zeros_like(t), np.zeros_like(t)
    for a, b in windows:
        up = np.clip((t - a) / ramp, 0, 1)
        down = np.clip((b - t) / ramp, 0, 1) if b < t[-1] + 1 else np.ones_like(t)
        u = np.minimum(up, down)
        s = 0.5 - 0.5 * np.cos(np.pi * u)
        ds = 0.5 * np.pi * np.sin(np.pi * u) / ramp * np.where(up < down, 1.0, -1.0) * ((u > 0) & (u < 1))
        g, dg = np.maximum(g, s), np.where(s >= g, ds, dg)
    return g, dg


def kinematics(robot, t, moving, rng, amplitude=(0.05, 0.2)):
    """Exact q, qd, qdd (n, nv): per-joint sines whose clock runs at the gate's rate (standing still outside)."""
    amp, w = rng.uniform(*amplitude, robot.nv), rng.uniform(0.5, 2.0, robot.nv)
    g, dg = _gate(t, moving) if moving else (np.zeros_like(t), np.zeros_like(t))
    tau = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(t))])  # the motion's own time
    ph = w * tau[:, None]
    q = np.array(robot.spec.home) + amp * np.sin(ph)
    qd = amp * w * np.cos(ph) * g[:, None]
    qdd = -amp * w ** 2 * np.sin(ph) * (g ** 2)[:, None] + amp * w * np.cos(ph) * dg[:, None]
    return q, qd, qdd


def _elbow(robot):
    """The frame id of the elbow (the parent joint of the 4th link) where the off-tool push acts."""
    return robot.model.getFrameId(robot.model.names[4])


def build(robot, case: TrustCase | str, seed: int = 0) -> TrustStream:
    """One stream of ``case`` (a name of :data:`CASES`), deterministic given seed."""
    import pinocchio as pin

    c = CASES[case] if isinstance(case, str) else case
    rng = np.random.default_rng(seed)
    n = int(round(c.seconds * 1000))
    t = np.arange(n) * 1e-3
    q, qd, qdd = kinematics(robot, t, c.moving, rng, c.amplitude)
    bt, bf = np.array(c.force, float).reshape(-1, 2).T if c.force else (np.array([0.0]), np.array([0.0]))
    mag = np.interp(t, bt, bf)
    u = np.asarray(c.direction, float) / np.linalg.norm(c.direction)
    f = mag[:, None] * u
    tau = robot.inverse_dynamics(q, qd, qdd)
    if c.fault == "elbow":  # the push acts on the elbow: its own Jacobian and moment arm, and no tip force
        data, fid = robot.model.createData(), _elbow(robot)
        w = robot.base_wrench(q, qd, qdd)
        for k in np.flatnonzero(mag):
            pin.framesForwardKinematics(robot.model, data, q[k])
            jv = pin.computeFrameJacobian(robot.model, data, q[k], fid, pin.LOCAL_WORLD_ALIGNED)[:3]
            tau[k] -= jv.T @ f[k]
            p = data.oMf[fid].translation
            w[k] -= robot._sensor_from_root @ np.r_[f[k], np.cross(p, f[k])]
        truth = np.zeros_like(f)
    else:
        jv = robot.tip_jacobian(q)[:, :3]
        tau -= np.einsum("nij,ni->nj", jv, f)
        w = robot.base_wrench(q, qd, qdd, tip_force=f)
        truth = f
    r = read_sensors(robot, c.sensors, 1e-3, q, qd, tau, w, rng)
    bw, tj = r.base_wrench, r.tau_J
    if c.fault == "flip-base":
        bw = -bw
    elif c.fault == "flip-tau":
        tj = -tj
    elif c.fault == "clip-base":
        lim = np.abs(bw[mag == 0, 2]).max() + CLIP_MARGIN
        bw = bw.copy()
        bw[:, 2] = np.clip(bw[:, 2], -lim, lim)
    elif c.fault == "tau-offset":
        tj = tj + rng.choice([-1.0, 1.0], robot.nv) * rng.uniform(*TAU_OFFSET, robot.nv)
    elif c.fault == "tau-drift":
        tj = tj + t[:, None] * (TAU_DRIFT * rng.choice([-1.0, 1.0], robot.nv))
    elif c.fault == "freeze-base":
        k0 = int(c.fault_at * 1000)
        bw = bw.copy()
        bw[k0:] = bw[k0]
    arrives = np.ones(n, bool)
    if c.fault == "gap":
        k0 = int(c.fault_at * 1000)
        arrives[k0:k0 + 5] = False
    moving_f = np.linalg.norm(np.diff(truth if c.fault != "elbow" else f, axis=0), axis=1) > 1e-9
    edges = np.flatnonzero(np.diff(np.r_[0, moving_f.astype(int)]) != 0)
    changes = np.r_[edges * 1e-3, [c.fault_at] if c.fault == "gap" else []]
    return TrustStream(r.t, r.q, r.qd, bw, tj, truth, np.sort(changes), arrives, c.declared_resolution)


__all__ = ["CASES", "CLIP_MARGIN", "HARDWARE", "TAU_DRIFT", "TAU_OFFSET", "TrustCase", "TrustStream", "build", "kinematics"]
