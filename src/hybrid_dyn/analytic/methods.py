"""The analytic tip-force estimators, one definition each, in one registry.

A :class:`Method` says what an estimator reads (the sensors beyond q and qd, and
whether a call may bring any of them), whether it needs qdd, whether it reads the
base sensor tared, its bandwidth parameter (a declaration of ``bandwidth.BANDWIDTHS``:
its unit, its default, the values the bench's ``-val`` row chooses it from), whether
a residual network may sit on it (``residual_prior``), and how to build one stream of it
(:class:`MethodStream`): its rule for the bandwidth from a noise window
(``bandwidth.py``), its streaming step, its batch run and its settling time.

Everything else is built from :data:`REGISTRY` (a ``registry.Registry``):

- ``TipForceEstimator.analytic(robot, method=name)`` (``estimator/tip_force_estimator.py``),
  its bandwidth setting read from ``EstimatorConfig`` by the parameter's name;
- the bench's rows ``name`` (the bandwidth by the rule, what the estimator does)
  and ``name-val`` (chosen on validation, a labelled reference) (``bench/analytic_rows.py``);
- the estimators' one name (``method_names.ESTIMATOR_NAMES``), the residual priors
  (``learn/priors.py``) and ``StreamingModel`` (``learn/stream_predictor.py``).

Adding a method is one module: its :class:`MethodStream`, a ``BANDWIDTHS.register`` call if its
bandwidth parameter is new, and one :func:`register` call (``docs/extending.md``;
``tests/analytic/test_extending_method.py`` registers a toy one). :func:`run_batch` is what the
estimator does over a whole run, as a batch: the noise window (tare, measured noise, bandwidth by
the rule), then the method from the first sample after it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..deprecation import renamed_field
from ..description.sensor_noise import NoiseConfig
from ..errors import UsageError
from ..registry import Registry
from .acceleration import (causal_acceleration, cutoff_grid, cutoff_index, default_qdd_cutoff, filter_settle_calls,
                           qdd_noise_per_gain)
from .bandwidth import (BANDWIDTHS, BandwidthParameter, WindowNoise, measure_window, observer_gain,
                        observer_settle_calls)
from .base_momentum import BaseMomentumObserver
from .error_bar import ErrorBar, qdd_norm
from .method_names import ESTIMATOR_NAMES, EstimatorName
from .joint_state import joint_filter_for, with_joint_state_noise
from .kalman import (SENSORS, KalmanTipForce, channel_factors, increment_stats, window_fusion_noise)
from .momentum_observer import MomentumObserver
from .robot import Robot
from .tare import base_sensor_offset, held_tool_force, residual_change, tare_samples, window_force
from .tip_force import base_wrench_force_core, tip_force_from_base_wrench, tip_force_from_torques

SENSOR_NAMES = {"base_wrench": "base", "tau_J": "joint"}  # an input's name -> the Kalman filter's channel


class MethodStream:
    """One stream of a method on a robot at rate_hz [Hz]: its bandwidth ``value``, its state.

    Subclasses define ``choose`` (the rule), ``step``, ``batch`` and ``settle_calls``; those with
    state define ``reset``. ``configure`` sets the bandwidth without designing anything."""

    def __init__(self, robot: Robot, rate_hz: float):
        self.robot, self.rate_hz, self.dt = robot, float(rate_hz), 1.0 / float(rate_hz)
        self.value = None
        self.data = robot.model.createData()  # for the rule's Jacobians at the window's pose (made now)

    def choose(self, noise: WindowNoise) -> float:
        """The bandwidth rule on the window's measured noise."""
        raise NotImplementedError

    def configure(self, value: float) -> None:
        self.value = float(value)
        self.reset()

    def reset(self) -> None:
        """Forget the history (a start, a gap)."""

    def model_changed(self) -> None:
        """The robot's model changed in place (``Robot.set_payload``): refresh what was computed from it when
        the stream was made (a weight); the history goes on."""

    def window_step(self, q, qd, qdd, w_raw, tau) -> None:
        """One sample of the noise window (the raw base wrench): only methods that measure more than the
        window's arrays do anything here."""

    def close_window(self, noise: WindowNoise, tare_offset, fixed=None) -> float:
        """The window is over: configure the bandwidth (``fixed``, or the rule's) and return it."""
        self.configure(self.choose(noise) if fixed is None else fixed)
        return self.value

    def fit_window(self, q, qd, qdd, w_tared, tau, noise: WindowNoise, fixed=None) -> float:
        """``close_window`` from the window's arrays (the batch twin); base wrench already tared."""
        return self.close_window(noise, None, fixed)

    def step(self, q, qd, qdd, w, tau) -> np.ndarray:
        """One validated sample (w tared, or None; tau or None) -> the tip force (3,) [N]."""
        raise NotImplementedError

    def batch(self, q, qd, qdd, w, tau) -> np.ndarray:
        """``step`` over a run (N, ...) from a start: (N, 3) [N]."""
        raise NotImplementedError

    def settle_calls(self, sensors=()) -> int:
        """Calls from a start until its transient is below 1 % (with the sensors present)."""
        raise NotImplementedError


@renamed_field("prior", "residual_prior", why="'prior' also names a residual model's analytic part")
@dataclass(frozen=True)
class Method:
    """One analytic tip-force estimator: its declaration, read by every consumer of :data:`REGISTRY`.

    reads: the inputs beyond q, qd ("base_wrench", "tau_J"). any_of: a call may bring any non-empty
    subset of them (else all, every call). needs_qdd: the method reads qdd at every call. tares: it
    reads the base sensor tared on the noise window. parameter: the name of its bandwidth parameter,
    a declaration of ``bandwidth.BANDWIDTHS`` (its unit, default and the values the bench's ``-val``
    row chooses from: :attr:`bandwidth`). make(robot, rate_hz) -> :class:`MethodStream`.
    bench_rows: the bench declares its rows from here (False where ``analytic_rows`` declares them).
    residual_prior: a residual network may sit on it (``learn/priors.py``; formerly ``prior``)."""

    name: str
    summary: str
    reads: tuple
    any_of: bool
    needs_qdd: bool
    tares: bool
    parameter: str
    make: Callable[[Robot, float], MethodStream]
    bench_rows: bool = True
    residual_prior: bool = False

    @property
    def bandwidth(self) -> BandwidthParameter:
        """The declaration of its bandwidth parameter."""
        return BANDWIDTHS[self.parameter]

    @property
    def unit(self) -> str:
        """Its bandwidth parameter's unit."""
        return self.bandwidth.unit

    def val_grid(self, rate_hz: float) -> tuple:
        """The values of its bandwidth parameter the bench's ``-val`` row chooses from at rate_hz [Hz]."""
        return self.bandwidth.val_grid(rate_hz)

    @property
    def stateful(self) -> bool:
        """A filter (its value at a sample depends on the run before it), started after the noise window."""
        return not self.needs_qdd

    @property
    def fields(self) -> tuple:
        """The dataset fields a batch run reads (qdd: for the tare, or the method)."""
        return ("q", "qd") + (("qdd",) if self.needs_qdd or self.tares else ()) + self.reads


# The methods by name; a consumer that derives something per method (the bench's rows, the residual
# priors) reads the registry and listens to it (REGISTRY.listen, or add_listener) for later declarations.
REGISTRY = Registry("estimator method", UsageError)


def register(method: Method) -> Method:
    """Declare a method (after its bandwidth parameter, ``BANDWIDTHS.register``): from now on the estimator,
    ``run_batch``, the bench's rows and, with ``residual_prior``, the residual priors know it by its name."""
    if method.parameter not in BANDWIDTHS:
        raise UsageError(f"estimator method {method.name!r}: its bandwidth parameter {method.parameter!r} is not "
                         f"declared; declare it first (bandwidth.BANDWIDTHS.register(BandwidthParameter(...)))")
    # The estimators' one name: refuses a name any estimator (a torque model too) has taken.
    ESTIMATOR_NAMES.register(EstimatorName(method.name, "tip_force", method.residual_prior))
    return REGISTRY.register(method)


def unregister(name: str) -> None:
    """Remove a method (a test's toy) from the registry and from whatever was built from it."""
    REGISTRY.unregister(name)
    ESTIMATOR_NAMES.unregister(name)


def add_listener(on_register: Callable[[Method], None], on_unregister: Callable[[Method], None]) -> None:
    """Be told of every method registered or removed from now on (``REGISTRY.listen``)."""
    REGISTRY.listen(on_register, on_unregister)


# ----------------------------------------------------------- the methods
class _QddMethod(MethodStream):
    """A per-sample method whose bandwidth is the qdd filter's cutoff [Hz] (the estimator's filter)."""

    sensor_input = "base_wrench"  # the input whose noise the qdd estimate's noise is weighed against

    def sensor_noise(self, noise: WindowNoise) -> float:
        return noise.base_force

    def choose(self, noise):
        per_gain = qdd_noise_per_gain(self.robot, noise.q_mean, noise.qd, self.sensor_input, self.data)
        return float(cutoff_grid(self.rate_hz)[0][cutoff_index(self.rate_hz, per_gain, self.sensor_noise(noise))])

    def settle_calls(self, sensors=()) -> int:
        grid, _, _, settle = cutoff_grid(self.rate_hz)
        hit = np.flatnonzero(np.isclose(grid, self.value, rtol=1e-12))
        return int(settle[hit[0]]) if len(hit) else filter_settle_calls(self.rate_hz, self.value)


class BaseWrench(_QddMethod):
    def step(self, q, qd, qdd, w, tau):
        return base_wrench_force_core(self.robot, q, qd, qdd, w)

    def batch(self, q, qd, qdd, w, tau):
        return tip_force_from_base_wrench(self.robot, q, qd, qdd, w)


class TorquesPinv(_QddMethod):
    sensor_input = "tau_J"

    def sensor_noise(self, noise):
        return noise.joint_torque_rms

    def step(self, q, qd, qdd, w, tau):
        return tip_force_from_torques(self.robot, q, qd, qdd, tau)

    def batch(self, q, qd, qdd, w, tau):
        return tip_force_from_torques(self.robot, q, qd, qdd, tau)


class _ObserverMethod(MethodStream):
    """A momentum observer (``cls``) stepped on one sensor (``sensor``: "w" or "tau"), gain K by the rule."""

    cls = sensor = None

    def __init__(self, robot, rate_hz):
        super().__init__(robot, rate_hz)
        self.observer = self.cls(robot, gain=1.0, dt=self.dt)

    def configure(self, value):
        self.observer.gain = np.broadcast_to(float(value), np.shape(self.observer.gain)).copy() \
            if np.ndim(self.observer.gain) else float(value)
        super().configure(value)

    def reset(self):
        self.observer.reset()

    def step(self, q, qd, qdd, w, tau):
        return self.observer.force(q, self.observer.step_unchecked(q, qd, w if self.sensor == "w" else tau))

    def batch(self, q, qd, qdd, w, tau):
        return self.cls(self.robot, gain=self.value, dt=self.dt).run(q, qd, w if self.sensor == "w" else tau)[0]

    def settle_calls(self, sensors=()):
        return observer_settle_calls(self.value, self.dt)


class MomentumObserverMethod(_ObserverMethod):
    """The joint-torque momentum observer: K by the rule on the torque sensors' and p = M qd's noise."""

    cls, sensor = MomentumObserver, "tau"

    def choose(self, noise):
        # The residual's joint-space noise mapped to the tip force by P = pinv(J_v^T) = (J_v J_v^T)^-1 J_v
        # at the window's pose: per axis, tr(P diag(s_tau^2) P^T) / 3 from the torque sensors and
        # tr(P M diag(s_qd^2) M P^T) / 3 from the momentum p = M qd.
        import pinocchio as pin

        r, data = self.robot, self.data
        jv = pin.computeFrameJacobian(r.model, data, noise.q_mean, r.tool_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
        P = np.linalg.solve(jv @ jv.T, jv)
        M = pin.crba(r.model, data, noise.q_mean)
        M = np.triu(M) + np.triu(M, 1).T
        s_in = np.sqrt(np.sum((P * noise.joint_torque) ** 2) / 3.0)
        s_mom = np.sqrt(np.sum((P @ M * noise.qd) ** 2) / 3.0)
        self.value, self.predicted_noise = observer_gain(self.rate_hz, s_in, s_mom)
        return self.value


class BaseMomentumMethod(_ObserverMethod):
    """The base momentum observer: K by the rule on the base sensor's and h = m J_com qd's noise."""

    cls, sensor = BaseMomentumObserver, "w"

    def model_changed(self):
        self.observer.model_changed()

    def choose(self, noise):
        self.value, self.predicted_noise = observer_gain(
            self.rate_hz, noise.base_force, qdd_noise_per_gain(self.robot, noise.q_mean, noise.qd, "base_wrench", self.data))
        return self.value


class KalmanFusionMethod(MethodStream):
    """Both sensors fused (``kalman.py``): the noise and the force rate measured on the window."""

    def __init__(self, robot, rate_hz):
        super().__init__(robot, rate_hz)
        self.kalman = KalmanTipForce(robot, self.dt)
        self._factors = channel_factors(robot)
        self._R3 = robot._root_from_sensor[:3]

    def _apply(self, noise, fixed):
        from dataclasses import replace

        self.kalman.configure(noise if fixed is None else replace(noise, force_rate=float(fixed)))
        self.value = self.kalman.noise.force_rate
        return self.value

    def choose(self, noise):  # the contact model's force rate (the measured noise sets the gain)
        return window_fusion_noise(self.robot, self.dt, noise, np.zeros((2, 8)), factors=self._factors).force_rate

    def configure(self, value):
        from dataclasses import replace

        self._apply(replace(self.kalman.noise, force_rate=float(value)), None)

    def reset(self):
        self.kalman.reset()

    def model_changed(self):
        self.kalman.model_changed()

    def window_step(self, q, qd, qdd, w_raw, tau):
        self.kalman.step_unchecked(q, qd, w_raw, tau)  # its increment sums measure the model errors

    def close_window(self, noise, tare_offset, fixed=None):
        shift = None if tare_offset is None else (self._R3 @ tare_offset) * self.dt
        return self._apply(window_fusion_noise(self.robot, self.dt, noise, self.kalman.stats.copy(), shift,
                                               self._factors), fixed)

    def fit_window(self, q, qd, qdd, w_tared, tau, noise, fixed=None):
        y = self.kalman.measurements(q, qd, w_tared, tau)
        stats = increment_stats({c: np.diff(v, axis=0) for c, v in y.items()})
        return self._apply(window_fusion_noise(self.robot, self.dt, noise, stats, None, self._factors), fixed)

    def step(self, q, qd, qdd, w, tau):
        return self.kalman.step_unchecked(q, qd, w, tau)

    def batch(self, q, qd, qdd, w, tau):
        return self.kalman.run(q, qd, w, tau)

    def settle_calls(self, sensors=SENSORS):
        return self.kalman.settle_calls(tuple(SENSOR_NAMES.get(s, s) for s in sensors))


register(Method("base-wrench", "the base sensor's wrench minus the model's (needs qdd)", ("base_wrench",), False,
                True, True, "qdd_cutoff_hz", BaseWrench, bench_rows=False, residual_prior=True))
register(Method("torques-pinv", "F = pinv(J_v^T) (ID(q, qd, qdd) - tau_J)", ("tau_J",), False, True, False,
                "qdd_cutoff_hz", TorquesPinv, bench_rows=False))
register(Method("momentum-observer", "the joint-torque momentum observer (no qdd)", ("tau_J",), False, False, False,
                "momentum_gain", MomentumObserverMethod, residual_prior=True))
register(Method("base-momentum", "the whole robot's momentum against the base sensor (no qdd)", ("base_wrench",),
                False, False, True, "momentum_gain", BaseMomentumMethod, residual_prior=True))
register(Method("kalman-fusion", "both sensors fused by a Kalman filter (a call may bring either or both)",
                ("base_wrench", "tau_J"), True, False, True, "fusion_force_rate", KalmanFusionMethod))


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
    [Nm] in its moment residual or a force above ``tare_held_force`` [N] held at the tool while it moved, a force in the joint torques
    of a tared method that reads them), the next clean one; forces are 0 up to its end. On it the base
    sensor is tared (qdd: the filter that runs during the window, ``default_qdd_cutoff``), the noise is
    measured and the bandwidth chosen by the rule (``value``: fixed instead); then the method runs from
    the first sample after it (a qdd method on qdd filtered at its cutoff from the window's start, as
    the estimator replays the window through it). encoder_resolution [rad] ("auto": the robot
    description's): above 0, q and qd are the joint-state filter's estimates from q (``joint_state.py``),
    as in the estimator; 0 reads q and qd as given (exact encoders, or a dataset's white-noise sensor
    model). Not mirrored: the estimator's drift-following tare at a standstill (a sequential loop)."""
    m = REGISTRY[method] if isinstance(method, str) else method
    stream = stream or m.make(robot, rate_hz)
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    res = robot.spec.encoder_resolution if encoder_resolution == "auto" else float(encoder_resolution)
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
        motion = 0.0 if qdd_joint is None else qdd_norm(qdd_joint[k])
        since = (k - start) / rate_hz if tared else None
        sigma[k] = error_bar.update(forces[k], motion, since)
    return sigma


def spec_noise(robot: Robot) -> WindowNoise:
    """The sensors' specifications as a window's noise (the generator's ``NoiseConfig`` defaults): what
    the rule uses when a stream has no noise window (tare_seconds = 0)."""
    c = NoiseConfig()
    return WindowNoise(np.full(robot.nv, c.qd), c.force, np.full(robot.nv, c.tau_J), np.array(robot.spec.home, float))


__all__ = ["BANDWIDTHS", "BandwidthParameter", "Method", "MethodStream", "REGISTRY", "add_listener", "register",
           "run_batch", "spec_noise", "unregister"]
