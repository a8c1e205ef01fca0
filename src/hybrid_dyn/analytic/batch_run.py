"""What ``TipForceEstimator`` gives over a whole run, as a batch (:func:`run_batch`): the noise window (tare,
measured noise, bandwidth by the rule), then the method from the first sample after it."""
from __future__ import annotations

import numpy as np

from ..description.spec import resolve_encoder_resolution
from .acceleration import causal_acceleration, default_qdd_cutoff
from .bandwidth import measure_window
from .error_bar import ErrorBar
from .joint_state import joint_filter_for, with_joint_state_noise
from .method_declaration import Method, MethodStream
from .methods import TIP_FORCE_METHODS
from .robot import Robot
from .tare import base_sensor_offset, held_tool_force, residual_change, tare_samples, window_force
from .tip_force import tip_force_from_torques


def run_batch(method: str | Method, robot: Robot, rate_hz: float, q, qd, base_wrench=None, tau_J=None,
              tare_seconds: float = 0.5, value=None, stream: MethodStream | None = None,
              encoder_resolution="auto", joint_filter_bandwidth="auto", with_sigma: bool = False,
              tare_contact_force: float = 1.0, error_bar=None, off_tool_moment: float = 1.0,
              tare_held_force: float = 3.0, _qdd_joint=None, _joint=None):
    """What ``TipForceEstimator`` gives over one run (N, ...) with every sample present, as a batch:
    (forces (N, 3) [N], the bandwidth used), and with ``with_sigma`` the error bar (N, 3) [N] too (inf
    where the estimator has no settled estimate; ``error_bar``: an ``error_bar.ErrorBar`` to
    use, else one with the estimator's defaults).

    The noise window is the first ``tare_seconds``, or, when a window saw a contact (the estimator's
    check, ``tare_contact_force`` [N]: a step in the base sensor's residual, a step of ``off_tool_moment``
    [Nm] in its moment residual or a force above ``tare_held_force`` [N] held at the tool while it moved, a force
    in the joint torques of a tared method that reads them), the next clean one; forces are 0 up to its end. On it the base
    sensor is tared (qdd: the filter that runs during the window, ``default_qdd_cutoff``), the noise is
    measured and the bandwidth chosen by the rule (``value``: fixed instead); then the method runs from
    the first sample after it (a qdd method on qdd filtered at its cutoff from the window's start, as
    the estimator replays the window through it). encoder_resolution [rad] ("auto": the robot
    description's): above 0, q and qd are the joint-state filter's estimates from q (``joint_state.py``),
    as in the estimator; 0 reads q and qd as given (exact encoders, or a dataset's white-noise sensor
    model). Not mirrored: the estimator's drift-following tare at a standstill (a sequential loop)."""
    m = TIP_FORCE_METHODS[method] if isinstance(method, str) else method
    stream = stream or m.make(robot, rate_hz)
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    res = resolve_encoder_resolution(encoder_resolution, robot.spec)
    joint = joint_filter_for(robot, rate_hz, res, joint_filter_bandwidth)
    qdd_joint = None
    if joint is not None:
        q, qd, qdd_joint = joint.run(q)
    w = None if base_wrench is None else np.asarray(base_wrench, float)
    tau = None if tau_J is None else np.asarray(tau_J, float)
    # The estimator's window waits for the joint-state filter to converge (a tare in motion): as it does.
    wait = joint.settle_calls() if joint is not None and m.tares and tare_seconds > 0 else 0
    if wait:
        head = run_batch(m, robot, rate_hz, q[wait:], qd[wait:], None if w is None else w[wait:],
                         None if tau is None else tau[wait:], tare_seconds, value, stream, 0.0,
                         joint_filter_bandwidth, with_sigma, tare_contact_force, error_bar, off_tool_moment,
                         tare_held_force, _qdd_joint=qdd_joint[wait:], _joint=joint)
        pad = lambda x, fill: np.concatenate([np.full((wait, 3), fill), x])  # noqa: E731
        return (pad(head[0], 0.0), head[1]) + ((pad(head[2], np.inf),) if with_sigma else ())
    qdd_joint = _qdd_joint if qdd_joint is None else qdd_joint
    joint = _joint if joint is None else joint  # (the recursion above: its noise, not its filtering)
    n, dt = tare_samples(rate_hz, tare_seconds), 1.0 / rate_hz
    out = np.zeros((len(q), 3))
    if n >= len(q) or n < 8:
        raise ValueError(f"run_batch needs a noise window of 8 samples or more inside the run, got {n} of {len(q)}")
    qdd_window = causal_acceleration(qd, dt, default_qdd_cutoff(rate_hz))
    s0 = _clean_window(m, robot, n, q, qd, qdd_window, w, tau, tare_contact_force, off_tool_moment, tare_held_force)
    if s0 is None:  # no clean window in the run: the estimator never gets going
        return (out, None, np.full_like(out, np.inf)) if with_sigma else (out, None)
    end = s0 + n
    win = lambda x: None if x is None else x[s0:end]  # noqa: E731
    w_tared = w
    if m.tares and w is not None:
        w_tared = w - base_sensor_offset(robot, q[s0:end], qd[s0:end], qdd_window[s0:end], w[s0:end])
    noise = with_joint_state_noise(measure_window(win(q), win(qd), win(w), win(tau)), joint)
    used = stream.fit_window(win(q), win(qd), win(qdd_window), win(w_tared), win(tau), noise, value)
    qdd = causal_acceleration(qd[s0:], dt, used)[n:] if m.needs_qdd else None
    after = lambda x: None if x is None else x[end:]  # noqa: E731
    out[end:] = stream.batch(q[end:], qd[end:], qdd, after(w_tared), after(tau))
    if not with_sigma:
        return out, used
    tared = m.tares and w is not None  # the estimator's drift term runs from the base sensor's tare
    return out, used, _batch_sigma(m, stream, out, end, rate_hz, qdd_joint, error_bar, tared)


def _clean_window(m: Method, robot: Robot, n: int, q, qd, qdd, w, tau, limit: float,
                  moment_limit: float, held_limit: float) -> int | None:
    """The first sample of the first window of n samples that the estimator trusts (``TipForceEstimator``'s
    ``_window_contact``), windows following each other as the estimator starts them; None if none."""
    check_torques = m.tares and tau is not None and "tau_J" in m.reads
    for s0 in range(0, len(q) - n - 8 + 1, n):
        sl = slice(s0, s0 + n)
        if m.tares and w is not None:
            residual = w[sl] - robot.base_wrench(q[sl], qd[sl], qdd[sl])
            if residual_change(residual[:, :3], limit) is not None:
                continue
            # The streaming window's moment checks (``NoiseWindow.contact``): a force held at the tool
            # while it moved changes the moment residual with the tool's position.
            if residual_change(residual[:, 3:], moment_limit) is not None:
                continue
            root_moments = robot.base_wrench_to_root(residual)[:, 3:]
            if held_tool_force(robot.tip_position(q[sl]), root_moments, held_limit) is not None:
                continue
        seen = tip_force_from_torques(robot, q[sl], qd[sl], qdd[sl], tau[sl]) if check_torques else None
        if seen is not None and window_force(seen, limit) is not None:
            continue
        return s0
    return None


def _batch_sigma(m: Method, stream: MethodStream, forces, start: int, rate_hz: float, qdd_joint, error_bar,
                 tared: bool):
    """The estimator's error bar over a batch run whose method starts at sample ``start``: inf until its
    settling time has passed, then ``ErrorBar`` sample by sample (the same compiled step)."""
    error_bar = error_bar or ErrorBar(rate_hz)
    error_bar.reset()
    sigma = np.full_like(forces, np.inf)
    settle = 0 if m.needs_qdd else stream.settle_calls(m.reads)
    for k in range(start + settle, len(forces)):
        motion = 0.0 if qdd_joint is None else error_bar.motion(qdd_joint[k], m.needs_qdd)
        since = (k - start) / rate_hz if tared else None
        sigma[k] = error_bar.update(forces[k], motion, since)
    return sigma

