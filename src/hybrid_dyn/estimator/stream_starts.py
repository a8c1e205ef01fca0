"""How a stream (re)starts: the noise window's close (the bandwidth by the rule, the window replayed through the
chosen qdd filter), a window that saw a contact started over, and the restart after a gap.

:class:`StreamStarts` is a part of ``TipForceEstimator`` (``estimator/tip_force_estimator.py``) and works on its
state; nothing here runs in a steady control cycle.
"""
from __future__ import annotations

import math

import numpy as np

from ..analytic.acceleration import CausalAccelerationFilter, cutoff_grid
from ..analytic.bandwidth import QDD_CUTOFF
from .config import EstimatorStatus

_CONTACT_AT_START, _LOAD_MISMATCH = EstimatorStatus.CONTACT_AT_START, EstimatorStatus.LOAD_MISMATCH
# A force the joint torques saw held through the start-up window within this angle of the vertical is named a load
# other than the model's: a payload error's force is its weight, straight down or up.
VERTICAL_DEGREES = 10.0


class StreamStarts:
    """The estimator's start and restart steps (a mixin of ``TipForceEstimator``)."""

    def _end_window(self) -> None:
        """The window's last call: is it trusted (no contact in it), and its noise. A contact that began in the
        first window (its residual steps) leaves that window's first fifth as the documented contact-free start's
        level: a later window is trusted only at that level (to the stated drift since), so that one inside a
        contact held on does not tare it in. A window at that level that its moments refuse (a force held at the
        moving tool) shows the level was a contact's (a press from power-up): it is dropped."""
        c = self.config
        # The model's calibrated error is no contact: twice its sigma bounds what the torques may show. Not the
        # stated term's: on the Panda it allows ~10 N, and a press held that still would be tared in.
        model = None if self._model_sigma is None or self.calibration is None else \
            2.0 * float(np.linalg.norm(self._model_sigma))
        tare, self._windows = self._tare, self._windows + 1
        problem = self._window.contact(tare, c.tare_contact_force, c.off_tool_moment, c.tare_held_force,
                                       torque_limit=model)
        if tare is not None and tare.done and self._start_level is not None:
            level = np.median(tare.residuals, axis=0) - self._start_level
            allowed = c.tare_contact_force + c.base_drift_rate * self._windows * c.tare_seconds
            off = float(np.sqrt(level.dot(level)))
            if problem is None and off > allowed:
                problem = (f"the base sensor's residual lies {off:.2f} N from the contact-free start's (limit "
                           f"{allowed:.3g} N): the contact that began in the start-up window is still on")
            elif problem is not None and off <= allowed and tare.residual_change(c.tare_contact_force) is None:
                self._start_level = None
        elif tare is not None and tare.done and problem is not None and self._windows == 1 and \
                tare.residual_change(c.tare_contact_force):
            self._start_level = np.median(tare.residuals[:len(tare.residuals) // 5], axis=0)
        if problem is None and self._tau_tare is not None:
            problem = self._tau_tare.close(self._calls)
            if problem is None and self._model_error is not None:  # the model's error at its pose went with it
                self._model_error.tare(self._tau_tare.pose)
        if problem is not None:
            self._restart_window(problem, self._held_force())
        else:
            self.window_problem = None
            self._window_noise = self._window.measure(self._joint)

    def _held_force(self):
        """The force [N] the joint torques saw held through the window just refused, or None."""
        for force in (getattr(self._tau_tare, "held_force", None), self._window.held_force):
            if force is not None:
                return force
        return None

    def _restart_window(self, problem: str, held=None) -> None:
        """The window saw a contact: forget it (its tare and noise) and start a new one now. held: the force [N] the
        joint torques saw held through it; a vertical one (within VERTICAL_DEGREES) names a load other than the
        model's (``load mismatch``: a payload declared wrong, another arm's weight, or a vertical press)."""
        vertical = held is not None and abs(held[2]) >= math.cos(math.radians(VERTICAL_DEGREES)) * np.linalg.norm(held)
        if vertical:
            problem += (f"; it was vertical ({held[2]:+.2f} N along z): a load {-held[2] / 9.81:+.2f} kg from the "
                        "model's (payload= declared wrong, the arm's weight), or a vertical press")
        self.window_status = _LOAD_MISMATCH if vertical else _CONTACT_AT_START
        self.window_problem = problem
        if self._tare is not None:
            self._tare.reset()
        if self._tau_tare is not None:
            self._tau_tare.reset(keep_held=True)
        self._stream.reset()
        self._window.clear()
        self._calls = 0
        self._warmup_calls = self._window_calls + 1

    def _close_window(self, noise) -> None:
        """The first call after the noise window: set the bandwidth by the rule (or the config's) from the
        window's noise, replay the window through the chosen qdd filter, start the method at this call. No
        design happens here: the rule picks among designs made when the estimator was built (``cutoff_grid``)."""
        self._window_noise = None
        tare = self._tare
        offset = tare.offset if tare is not None and tare.done else None
        if offset is None and tare is not None:  # the base sensor did not fill the window: no model error from it
            self._stream_stats_drop_base()
        self.bandwidth = self._stream.close_window(noise, offset, self._fixed)
        self._use_bandwidth(replay=self._window.qd)
        self._base_tared = tare is None or tare.done
        if tare is not None and tare.done:
            self._tared_at = self._calls
        self._absent, self._active = [-1, -1], ()
        # A qdd method has no transient (its filter was replayed); an observer settles; kalman-fusion settles
        # for the sensors it gets (``_track_sensors``).
        self._warmup_calls = self._calls
        if not self._optional and not self.spec.needs_qdd:
            self._warmup_calls += self._stream.settle_calls(self.spec.reads)

    def _stream_stats_drop_base(self) -> None:
        kalman = getattr(self._stream, "kalman", None)
        if kalman is not None:
            kalman.stats[0] = 0.0

    def _use_bandwidth(self, replay=None):
        """Apply the chosen qdd cutoff (a precomputed design), replaying ``replay`` (n, nv) through it;
        returns the replay's last qdd (None without one)."""
        kalman = getattr(self._stream, "kalman", None)
        self.fusion_noise = None if kalman is None else kalman.noise
        if self.spec.parameter != QDD_CUTOFF.name:
            return None
        grid = cutoff_grid(float(self.config.call_hz))[0]
        hit = np.flatnonzero(np.isclose(grid, self.bandwidth, rtol=1e-12))
        self._qdd_filter = (CausalAccelerationFilter.from_design(self.robot.nv, self.config.call_hz, int(hit[0]))
                            if len(hit) else CausalAccelerationFilter(self.robot.nv, self.config.call_hz, self.bandwidth))
        self.qdd_cutoff_hz = self.bandwidth
        return None if replay is None else self._qdd_filter.replay(replay)

    def _restart_dynamics(self, gap_seconds: float) -> None:
        """After a gap of ``gap_seconds`` in a timed stream: the filter and the method restart (a finished
        tare and the bandwidth are kept), and it warms up for the method's settling time. The joint-state
        filter predicts across a short gap (its state stays the arm's) and starts over after a long one."""
        self._qdd_filter.reset()
        self._rate.reset()
        if self._joint is not None:
            self._joint.coast(int(round(gap_seconds * self.config.call_hz)) - 1)
        self._error_bar.reset()
        if self.model is not None:
            self.model.reset()
            self._warmup_calls = max(self._warmup_calls, self._calls + self.model.warmup_calls(self.config.call_hz))
            return
        if self._calls < self._window_calls:  # a gap inside the window: the window goes on (its noise is measured)
            return
        self._stream.reset()
        self._check.restart_observer()
        self._absent, self._active = [-1, -1], ()
        self._warmup_calls = max(self._warmup_calls, self._calls + 1 + self._stream.settle_calls(self.spec.reads))


__all__ = ["StreamStarts"]
