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
PAYLOAD_COM = (0.0, 0.0, 0.05)  # [m] in the tool frame
# Two poses near the stretched singularity of the Panda's J_v, on the line from home to a singular pose: its least
# singular value there is 0.031 and 0.016 m/rad.
NEAR_SINGULAR = ((-2.419, -0.13, -1.312, -0.447, 0.0, 2.728, 2.549), (-2.651, -0.067, -1.437, -0.264, 0.0, 2.839, 2.717))
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
    [rad] the per-joint sines' amplitudes are drawn from (``kinematics``). pose: the q [rad] the sines run about
    (() : the description's home); direction "weak": J_v's weakest direction there.
    The arm that makes the readings may differ from the model the estimator is given (the model's error):
    true_params (another parameter set of the description), true_scale (every link's inertials scaled),
    payload ((declared, true) [kg], a point mass PAYLOAD_COM [m] from the tool frame)."""

    seconds: float
    force: tuple = ()
    direction: tuple = (0.3, -0.2, -1.0)
    moving: tuple = ()
    sensors: HardwareSensors = field(default_factory=lambda: HARDWARE)
    fault: str | None = None
    fault_at: float = 0.0
    declared_resolution: float | str = "auto"
    amplitude: tuple = (0.05, 0.2)
    pose: tuple = ()
    true_params: str | None = None
    true_scale: float = 1.0
    payload: tuple | None = None


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
    # 13. the model's error: a payload declared 0.5 kg that is 1.2 kg (and the reverse), every link's inertials
    # 10 % off, the description's other parameter set; a 10 N contact held 4-8 s, the arm moving from 1 s.
    "payload-heavy": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), payload=(0.5, 1.2)),
    "payload-light": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), payload=(1.2, 0.5)),
    "masses-heavy": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), true_scale=1.1),
    "masses-light": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),), true_scale=0.9),
    "other-params": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), moving=((1.0, 10.0),),
                              true_params="franka_official"),
    # 14. near the stretched singularity, a 10 N contact along J_v's weak direction, the arm swaying a little.
    "singular-weak": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), direction="weak", moving=((1.0, 10.0),),
                               pose=NEAR_SINGULAR[0], amplitude=(0.005, 0.02)),
    "singular-weaker": TrustCase(10.0, _steps((4.0,), 10.0, 4.0, 10.0), direction="weak", moving=((1.0, 10.0),),
                                 pose=NEAR_SINGULAR[1], amplitude=(0.005, 0.02)),
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
    payload: tuple | None = None  # what the estimator is told the tool carries: (mass [kg], com [m])


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


def kinematics(robot, t, moving, rng, amplitude=(0.05, 0.2), pose=()):
    """Exact q, qd, qdd (n, nv): per-joint sines about pose (() : home) whose clock runs at the gate's rate
    (standing still outside)."""
    amp, w = rng.uniform(*amplitude, robot.nv), rng.uniform(0.5, 2.0, robot.nv)
    g, dg = _gate(t, moving) if moving else (np.zeros_like(t), np.zeros_like(t))
    tau = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(t))])  # the motion's own time
    ph = w * tau[:, None]
    q = np.array(pose or robot.spec.home) + amp * np.sin(ph)
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
    q, qd, qdd = kinematics(robot, t, c.moving, rng, c.amplitude, c.pose)
    bt, bf = np.array(c.force, float).reshape(-1, 2).T if c.force else (np.array([0.0]), np.array([0.0]))
    mag = np.interp(t, bt, bf)
    if isinstance(c.direction, str):  # "weak": the least singular direction of J_v at the first pose
        u = np.linalg.svd(robot.tip_jacobian(q[0])[:3])[0][:, -1]
    else:
        u = np.asarray(c.direction, float) / np.linalg.norm(c.direction)
    f = mag[:, None] * u
    robot = true_arm(robot, c)
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
    declared = None if c.payload is None else (c.payload[0], PAYLOAD_COM)
    return TrustStream(r.t, r.q, r.qd, bw, tj, truth, np.sort(changes), arrives, c.declared_resolution, declared)


def true_arm(robot, c: TrustCase):
    """The arm that makes the readings: ``robot`` (the model the estimator is told) unless the case names its
    error (another parameter set, scaled inertials, another payload)."""
    import pinocchio as pin

    from ..analytic.robot import load_robot

    if c.true_params is None and c.true_scale == 1.0 and c.payload is None:
        return robot
    arm = load_robot(robot.name, params=c.true_params, num_threads=1) if c.true_params else robot.copy()
    if c.true_scale != 1.0:
        for model in (arm.model, arm.model_ff):
            for i in range(1, model.njoints):
                inertia = model.inertias[i]
                model.inertias[i] = pin.Inertia(inertia.mass * c.true_scale, inertia.lever, inertia.inertia * c.true_scale)
    if c.payload is not None:
        arm.set_payload((c.payload[1], PAYLOAD_COM))
    return arm


__all__ = ["CASES", "CLIP_MARGIN", "HARDWARE", "NEAR_SINGULAR", "PAYLOAD_COM", "TAU_DRIFT", "TAU_OFFSET", "TrustCase",
           "TrustStream", "build", "kinematics", "true_arm"]
